#[peppy::node("resolution/dependency_not_found.json5")]
mod peppygen {}

fn main() {}
