#[peppy::node("resolution/interface_not_found.json5")]
mod peppygen {}

fn main() {}
