// Generated code uses absolute paths only: the enclosing module shadows
// the prelude and common names, and everything still compiles without a
// warning.
#![deny(warnings)]
#![allow(dead_code, non_camel_case_types)]

struct Result;
struct Ok;
struct Err;
struct Option;
struct Some;
struct None;
struct String;
struct Vec;
struct Box;
struct Send;
struct Future;
struct Clone;
struct Debug;
struct PartialEq;
struct Fn;
struct FnOnce;
struct ToString;
struct Copy;
struct Default;
struct u8;
struct bool;
mod core {}
mod std {}
mod peppy {}
mod serde {}

#[::peppy::node("pass/services.json5")]
mod peppygen {}

#[::peppy::node("pass/topics.json5")]
mod topics {}

#[::peppy::node("pass/parameters.json5")]
mod params {}

#[::peppy::node("pass/actions.json5")]
mod actions {}

#[::peppy::node("pass/conformance.json5")]
mod conformance {}

fn main() {}
