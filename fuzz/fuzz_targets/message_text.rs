#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| peppy_fuzz::message_text(data));
