//! The `#[peppy::node]` attribute's compile errors, through rustc: the
//! cases are this crate's `tests/ui` (trybuild). The library is empty; it
//! is here because a package needs a target.
