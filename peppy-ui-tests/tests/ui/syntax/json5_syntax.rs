#[peppy::node("syntax/json5_syntax.json5")]
mod peppygen {}

fn main() {}
