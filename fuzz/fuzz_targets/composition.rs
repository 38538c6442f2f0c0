#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

static DIR: OnceLock<PathBuf> = OnceLock::new();

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    peppy_fuzz::composition(data, DIR.get_or_init(peppy_fuzz::scratch_dir));
});
