#[peppy::node("pass/topics.json5")]
fn peppygen() {}

fn main() {}
