#[peppy::node("formats/reserved_field_name.json5")]
mod peppygen {}

fn main() {}
