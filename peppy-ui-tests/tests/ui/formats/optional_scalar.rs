#[peppy::node("formats/optional_scalar.json5")]
mod peppygen {}

fn main() {}
