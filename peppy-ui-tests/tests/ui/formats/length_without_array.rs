#[peppy::node("formats/length_without_array.json5")]
mod peppygen {}

fn main() {}
