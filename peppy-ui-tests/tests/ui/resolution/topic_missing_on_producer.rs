#[peppy::node("resolution/topic_missing_on_producer.json5")]
mod peppygen {}

fn main() {}
