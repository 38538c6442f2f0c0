#[peppy::node("params/bad_default.json5")]
mod peppygen {}

fn main() {}
