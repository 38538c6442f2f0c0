#[peppy::node("syntax/wrong_document_kind.json5")]
mod peppygen {}

fn main() {}
