//! Node code written against every generated API shape, the way real nodes
//! (and the original PeppyOS's) write it: each case must compile without a
//! warning, and its test runs that code against nodes on a loopback hub (a
//! tool on the hub's session plays a side no generated node takes) and
//! checks what came back. The seeds' snippets only compile: they are the
//! seed pages' text. (The attribute's compile errors are checked through
//! rustc in trybuild cases of their own, `peppy-ui-tests/tests/ui`.)

mod actions;
mod conformance;
mod hygiene;
mod node_builder;
mod parameters;
mod peppylib_paths;
mod seeds;
mod services;
mod spawned_action;
mod topics;
mod video_reconstruction;
