#[peppy::node("formats/length_on_strings.json5")]
mod peppygen {}

fn main() {}
