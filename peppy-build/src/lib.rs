//! # peppy-build
//!
//! Turns a node's `peppy.json5` into a typed Rust API at compile time.
//!
//! ## Walkthrough
//!
//! `Cargo.toml`:
//!
//! ```toml
//! [dependencies]
//! peppy = "0.1"
//!
//! [build-dependencies]
//! peppy-build = "0.1"
//! ```
//!
//! `build.rs` (reads `peppy.json5` next to `Cargo.toml`, writes
//! `OUT_DIR/peppygen.rs`, tells cargo to rebuild when the document, an
//! interface it uses or a dependency node's document changes):
//!
//! ```ignore
//! fn main() {
//!     peppy_build::sync();
//! }
//! ```
//!
//! `src/main.rs`:
//!
//! ```ignore
//! peppy::include_generated!(); // declares `pub mod peppygen { ... }`
//!
//! use peppygen::emitted_topics::joint_states;
//! use peppygen::{NodeBuilder, Parameters, Result};
//!
//! fn main() -> Result<()> {
//!     NodeBuilder::new().run(|_params: Parameters, runner| async move {
//!         joint_states::emit(&runner, [0.0; 3], [0.0; 3], std::time::SystemTime::now()).await?;
//!         Ok(())
//!     })
//! }
//! ```
//!
//! Without a build script, `#[peppy::node("peppy.json5")] mod peppygen {}`
//! generates the same items inline (the `peppy-macros` crate calls
//! [`generate`] too).
//!
//! A schema error fails the build (the build script exits with status 1, no
//! panic) with every problem located, the way cargo prints errors:
//!
//! ```text
//! error[UnknownType]: unknown type `u322`
//!  --> peppy.json5:9:41
//!   |
//! 9 |           message_format: { width: "u322" },
//!   |                                    ^^^^^^
//!   = help: did you mean `u32`? ...
//! ```
//!
//! ## Other settings
//!
//! ```no_run
//! peppy_build::Config::new()
//!     .manifest("config/peppy.json5") // relative to CARGO_MANIFEST_DIR
//!     .repository("../interfaces")    // searched before PEPPY_REPOSITORIES
//!     .sync();
//! ```
//!
//! [`try_sync`] and [`Config::try_sync`] return the [`Error`] instead of
//! ending the build script.
//!
//! ## The generated module
//!
//! SPEC section 4: `emitted_topics::<topic>` (`Message`, `emit`),
//! `consumed_topics::<link_id>_<topic>` and `consumed_topics::<topic>`
//! (external) with `on_next_message_received`, `exposed_services::<service>`
//! (`Request`, `Response`, `handle_next_request`),
//! `consumed_services::<link_id>_<service>` (`Request`, `Response`, `poll`),
//! `parameters` (`Parameters`), and the re-exports `NodeBuilder`,
//! `NodeRunner`, `Parameters`, `Result`, `Error`, `QoSProfile`,
//! `StandaloneConfig`. Entries inherited from a conformed interface are under
//! `<interface>::<tag>::<name>` and, when no other entry has that name, under
//! their own name too. Generated code reaches the runtime only through
//! `::peppy::codegen`, by absolute paths.
//!
//! The peppylib node API is generated beside the emit API
//! (`declare_publisher` and `build_message`, `subscribe`); where the two
//! name one thing differently, a `node/v1` document gets the peppylib form
//! (`poll` and `fire_goal` to an explicit target, `GoalDecision`) and nests
//! its entries under slot and `implements` link_ids. [`rust_libs`] writes
//! the same items as the `.peppy/libs` crates that `node/v1` node crates
//! depend on (docs/MOVING.md).

mod actions;
mod config;
mod docs;
mod generate;
mod libs;
#[doc(hidden)]
pub mod macro_support;
mod naming;
mod pairings;
mod params;
mod python;
mod testing;
mod types;

pub use config::{
    Config, Error, GENERATED_HEADER, Generated, OUTPUT_FILE, Synced, pretty, render, sync, try_sync,
};
pub use generate::{generate, stub};
pub use libs::{LIBS_DIR, LibFile, rust_libs};
pub use python::{PythonFile, python_package};
