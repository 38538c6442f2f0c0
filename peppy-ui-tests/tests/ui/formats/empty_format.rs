#[peppy::node("formats/empty_format.json5")]
mod peppygen {}

fn main() {}
