//! # peppy-build
//!
//! Code generation for peppy nodes: `peppy_build::sync()` in a node's
//! `build.rs` reads its `peppy.json5` (through `peppy-schema`) and writes the
//! typed API to `OUT_DIR/peppygen.rs`.
//!
//! Status: not implemented yet; the document model it builds on lives in
//! `peppy-schema` and is complete.
