//! The generator without rustc: snapshots of the generated code for every
//! fixture, the build-script and macro front ends compared token for token,
//! `sync()`'s files and cargo lines, and located generator errors.

mod equivalence;
mod errors;
mod pairings;
mod scale;
mod slash_ids;
mod snapshots;
mod support;
mod sync;
