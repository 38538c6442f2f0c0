//! Generates the typed API from peppy.json5 (and the interfaces it conforms
//! to) into OUT_DIR; schema errors are printed like compiler errors.
fn main() {
    if peppy_build::sync().is_err() {
        std::process::exit(1);
    }
}
