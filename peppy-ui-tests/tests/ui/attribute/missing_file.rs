#[peppy::node("attribute/no_such_file.json5")]
mod peppygen {}

fn main() {}
