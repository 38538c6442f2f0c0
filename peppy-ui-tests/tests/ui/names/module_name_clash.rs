#[peppy::node("names/module_name_clash.json5")]
mod peppygen {}

fn main() {}
