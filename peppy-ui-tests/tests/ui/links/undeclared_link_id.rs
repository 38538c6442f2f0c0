#[peppy::node("links/undeclared_link_id.json5")]
mod peppygen {}

fn main() {}
