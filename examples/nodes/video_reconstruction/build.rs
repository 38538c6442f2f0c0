//! Generates the typed API from peppy.json5 (and the documents it depends on)
//! into OUT_DIR; schema errors are printed like compiler errors.
fn main() {
    peppy_build::sync();
}
