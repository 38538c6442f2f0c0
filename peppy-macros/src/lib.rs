//! # peppy-macros
//!
//! The `#[peppy::node("peppy.json5")]` attribute: a thin front end over
//! `peppy-build`'s generator that turns schema errors into compile errors at
//! the right line of the JSON5 file.
//!
//! Status: not implemented yet; no macro is exported until the generator
//! exists, so nothing here can be mistaken for working code generation.
