#[peppy::node("params/default_on_group.json5")]
mod peppygen {}

fn main() {}
