#[peppy::node("resolution/sha256_pin_mismatch.json5")]
mod peppygen {}

fn main() {}
