#[peppy::node("names/type_name_collision.json5")]
mod peppygen {}

fn main() {}
