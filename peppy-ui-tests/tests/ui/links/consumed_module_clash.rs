#[peppy::node("links/consumed_module_clash.json5")]
mod peppygen {}

fn main() {}
