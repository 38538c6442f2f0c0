#[peppy::node("usage/typed_api.json5")]
fn peppygen() {}

fn main() {}
