#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| peppy_fuzz::payload(data));
