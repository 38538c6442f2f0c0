#[peppy::node("formats/nested_array.json5")]
mod peppygen {}

fn main() {}
