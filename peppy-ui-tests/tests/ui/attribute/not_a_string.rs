#[peppy::node(peppy_json5)]
mod peppygen {}

fn main() {}
