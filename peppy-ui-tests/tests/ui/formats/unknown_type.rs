#[peppy::node("formats/unknown_type.json5")]
mod peppygen {}

fn main() {}
