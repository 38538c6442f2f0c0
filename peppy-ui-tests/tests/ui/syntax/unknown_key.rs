#[peppy::node("syntax/unknown_key.json5")]
mod peppygen {}

fn main() {}
