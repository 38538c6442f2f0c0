#[peppy::node("formats/optional_nested.json5")]
mod peppygen {}

fn main() {}
