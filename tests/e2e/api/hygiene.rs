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

#[::peppy::node("tests/e2e/api/services.json5")]
mod peppygen {}

#[::peppy::node("tests/e2e/api/topics.json5")]
mod topics {}

#[::peppy::node("tests/e2e/api/parameters.json5")]
mod params {}

#[::peppy::node("tests/e2e/api/actions.json5")]
mod actions {}

#[::peppy::node("tests/e2e/api/conformance.json5")]
mod conformance {}
