//! End-to-end tests of the `peppy-launch` binary: real files, real process,
//! exit codes and output as users see them.

mod check;
mod clock;
mod composed;
mod detached;
mod faults;
mod inspect;
mod machines;
mod migrate;
mod netns;
mod node_deps;
mod node_init;
mod one_engine;
mod pairs;
mod placement;
mod python;
mod recording;
mod repo_index;
mod repositories;
mod security;
mod seeds;
mod slash_ids;
mod sources;
mod support;
mod up;
mod validate;
