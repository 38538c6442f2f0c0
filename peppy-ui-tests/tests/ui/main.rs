//! The `#[peppy::node]` attribute through rustc (trybuild): every compile
//! error a schema mistake produces, located in the JSON5 file. Node code
//! that must compile (and run) against every generated API shape lives in
//! the facade's e2e tests (`tests/e2e/api`): with no passing case here,
//! trybuild only checks, which spares CI a second full build and link of
//! every dependency.
//!
//! Cases live in `tests/ui/<category>/<case>.rs` with their document in
//! `<case>.json5` and the expected compiler output in `<case>.stderr`
//! (regenerate with `TRYBUILD=overwrite cargo test -p peppy-ui-tests` and
//! review the diff). Document paths in the cases are relative to this
//! directory, through `PEPPY_MACRO_MANIFEST_DIR`.

/// Where the attribute reads documents from instead of the crate's own
/// directory (`peppy_build::macro_support::MANIFEST_DIR_OVERRIDE`: trybuild
/// compiles each case away from its document). Copied, not imported: a
/// dev-dependency on peppy-build would add the generator's tree to what
/// trybuild checks. A wrong name here fails every case that names a
/// document.
const MANIFEST_DIR_OVERRIDE: &str = "PEPPY_MACRO_MANIFEST_DIR";

#[test]
fn ui() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/ui");
    // SAFETY: this binary has this one test, so no other thread reads the
    // environment while it is set; trybuild's cargo inherits it.
    unsafe { std::env::set_var(MANIFEST_DIR_OVERRIDE, &dir) };
    // CI lints this workspace by making clippy its members' compiler
    // (`.ci/run`); trybuild's project would inherit that, and the cases'
    // expected output is rustc's alone.
    for lint_gate in ["RUSTC_WORKSPACE_WRAPPER", "CLIPPY_ARGS"] {
        // SAFETY: as above.
        unsafe { std::env::remove_var(lint_gate) };
    }
    if std::env::var_os("CARGO_ENCODED_RUSTFLAGS").is_none() {
        // SAFETY: as above.
        unsafe { std::env::set_var("CARGO_ENCODED_RUSTFLAGS", case_rustflags().join("\x1f")) };
    }
    let t = trybuild::TestCases::new();
    for category in [
        "attribute",
        "formats",
        "links",
        "names",
        "params",
        "resolution",
        "syntax",
        "usage",
    ] {
        t.compile_fail(format!("tests/ui/{category}/*.rs"));
    }
}

/// The flags trybuild (1.0.122) gives rustc for the cases, for every crate
/// it checks.
///
/// trybuild checks the dependencies first with its flags, then the cases
/// with `--diagnostic-width=140` added; rustflags are part of cargo's
/// fingerprint, so every dependency (the runtime and Zenoh among them) was
/// checked a second time: the test took 264 s on two cores, 170 s without.
/// Cargo takes `CARGO_ENCODED_RUSTFLAGS` before the `--config` flags
/// trybuild passes, so with the cases' flags there both passes use them
/// and each dependency is checked once. A caller's own
/// `CARGO_ENCODED_RUSTFLAGS` is left as it is (it already won both). The
/// price: rustflags from the caller's cargo configuration, which trybuild
/// would have merged with its own, are not given to the cases.
fn case_rustflags() -> Vec<&'static str> {
    let mut flags = vec!["--cfg", "trybuild", "--verbose", "-A", "dead_code"];
    // trybuild's own exception: a coverage build stays one.
    if std::env::var("RUSTFLAGS").is_ok_and(|f| f.contains("-C instrument-coverage")) {
        flags.extend(["-C", "instrument-coverage"]);
    }
    flags.push("--diagnostic-width=140");
    flags
}
