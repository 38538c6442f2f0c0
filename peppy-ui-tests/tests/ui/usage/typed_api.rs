// A valid document: a call with the wrong field types is an ordinary,
// precise type error.
#[peppy::node("usage/typed_api.json5")]
mod peppygen {}

async fn send(runner: &peppygen::NodeRunner) -> peppygen::Result<()> {
    peppygen::emitted_topics::frames::emit(runner, "wide", vec![1, 2]).await
}

fn main() {
    let _ = send;
}
