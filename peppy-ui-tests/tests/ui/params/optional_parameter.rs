#[peppy::node("params/optional_parameter.json5")]
mod peppygen {}

fn main() {}
