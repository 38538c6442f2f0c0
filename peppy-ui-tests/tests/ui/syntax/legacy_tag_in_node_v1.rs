#[peppy::node("syntax/legacy_tag_in_node_v1.json5")]
mod peppygen {}

fn main() {}
