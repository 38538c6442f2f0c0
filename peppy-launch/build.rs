//! Nothing to build: this script exists for its build dependency (see
//! Cargo.toml), which lines the launcher's host-side crates up with a
//! node's so `up` reuses the launcher's zenoh when it builds a node.

fn main() {
    println!("cargo::rerun-if-changed=build.rs");
}
