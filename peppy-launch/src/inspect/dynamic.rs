//! Messages without generated code: decoding and encoding a payload from a
//! format's canonical text.
