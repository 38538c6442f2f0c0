#[peppy::node("links/service_without_link_id.json5")]
mod peppygen {}

fn main() {}
