#[peppy::node("names/interface_module_clash.json5")]
mod peppygen {}

fn main() {}
