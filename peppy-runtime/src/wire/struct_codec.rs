//! The macro with which generated code implements a message struct's
//! [`Encode`](super::codec::Encode) and [`Decode`](super::codec::Decode):
//! the fields in declaration order, from the struct's name and its field
//! names alone.
//!
//! Generated code used to spell the two impls out for every struct, and
//! they were most of a node's generated tokens: a build script parses and
//! formats every one of them (`syn` + `prettyplease`), and the
//! `#[peppy::node]` attribute hands every one to the compiler. Written once
//! here, a message costs its struct declaration and one line.

/// A message struct generated from a format (every struct `codec!`
/// implements), as opposed to `()`, which stands for "no payload" where a
/// service or action declares none. Test mocks take their shapes from it:
/// `respond(response)` where a response is declared, `respond()` where not.
/// Defined here, not beside `Encode` in `peppy-wire`: the mocks' two
/// shapes (`impl<T: MessageData>` and `impl ... <()>`) may coexist only
/// while the trait is this crate's, so that no other crate can implement
/// it for `()`.
pub trait MessageData: super::codec::Encode + super::codec::Decode {}

/// The fewest bytes a field of type `T` takes, named through an accessor
/// (`|m: &Message| &m.header`) so that the codec macro needs no field
/// types. Never calls the accessor.
#[doc(hidden)]
pub const fn min_size_of<S, T: super::codec::Decode>(_field: fn(&S) -> &T) -> usize {
    T::MIN_SIZE
}

/// The fewest bytes a `refine`-pinned field takes (see
/// [`Counted`](super::codec::Counted)).
#[doc(hidden)]
pub const fn min_counted_size_of<S, T: super::codec::Counted>(_field: fn(&S) -> &T) -> usize {
    T::MIN_COUNTED_SIZE
}

/// Implements `Encode` and `Decode` for a struct whose fields are all
/// message values: `codec!(Message { header, data, note })`, every field
/// in declaration order. A field written `name as counted` is a
/// fixed-size array a node pins with `refine`: it travels as the open
/// array its document declares ([`Counted`](super::codec::Counted)).
///
/// Generated code calls it as `::peppy::codegen::codec!`.
#[doc(hidden)]
#[macro_export]
macro_rules! __peppy_codec {
    ($name:ident { $($field:ident $(as $mode:ident)?),* $(,)? }) => {
        impl $crate::codegen::MessageData for $name {}

        impl $crate::codegen::Encode for $name {
            fn encode(&self, out: &mut $crate::codegen::Writer<'_>) {
                // A struct without fields writes nothing.
                let _ = &out;
                $($crate::__peppy_codec_field!(encode &self.$field, out $(, $mode)?);)*
            }
        }

        impl $crate::codegen::Decode for $name {
            const MIN_SIZE: usize =
                0 $(+ $crate::__peppy_codec_field!(min $name, $field $(, $mode)?))*;

            fn decode(
                decoder: &mut $crate::codegen::Decoder<'_>,
            ) -> ::core::result::Result<Self, $crate::codegen::DecodeError> {
                // A struct without fields reads nothing.
                let _ = &decoder;
                ::core::result::Result::Ok(Self {
                    $($field: $crate::__peppy_codec_field!(decode decoder $(, $mode)?)?,)*
                })
            }
        }
    };
}

/// One field of [`__peppy_codec`]: plain, or `counted`.
#[doc(hidden)]
#[macro_export]
macro_rules! __peppy_codec_field {
    (encode $value:expr, $out:ident) => {
        $crate::codegen::Encode::encode($value, $out)
    };
    (encode $value:expr, $out:ident, counted) => {
        $crate::codegen::Counted::encode_counted($value, $out)
    };
    (min $name:ident, $field:ident) => {
        $crate::codegen::min_size_of(|m: &$name| &m.$field)
    };
    (min $name:ident, $field:ident, counted) => {
        $crate::codegen::min_counted_size_of(|m: &$name| &m.$field)
    };
    (decode $decoder:ident) => {
        $crate::codegen::Decode::decode($decoder)
    };
    (decode $decoder:ident, counted) => {
        $crate::codegen::Counted::decode_counted($decoder)
    };
}

#[cfg(test)]
mod tests {
    use crate::codegen::Decode;
    use crate::wire::codec::{from_bytes, to_bytes};

    /// The trait is named where it always was, beside the codec it marks.
    #[expect(dead_code, reason = "compiling it is the test")]
    fn message_data_keeps_its_path<T: crate::wire::codec::MessageData>() {}

    #[derive(Debug, PartialEq)]
    struct MessageHeader {
        frame_id: u32,
    }
    crate::__peppy_codec!(MessageHeader { frame_id });

    #[derive(Debug, PartialEq)]
    #[allow(non_snake_case)]
    struct Message {
        header: MessageHeader,
        r#type: String,
        samples: [u16; 3],
        fooBar: Option<u8>,
    }
    crate::__peppy_codec!(Message {
        header,
        r#type,
        samples,
        fooBar
    });

    /// A field pinned with `refine` travels as a counted array.
    #[derive(Debug, PartialEq)]
    struct Pinned {
        joints: [f64; 2],
        maybe: Option<[u8; 1]>,
        tail: u8,
    }
    crate::__peppy_codec!(Pinned {
        joints as counted,
        maybe as counted,
        tail
    });

    #[test]
    fn pinned_fields_travel_as_open_arrays_of_their_length() {
        let m = Pinned {
            joints: [1.5, -2.0],
            maybe: Some([7]),
            tail: 9,
        };
        let bytes = to_bytes(&m);
        let open = to_bytes(&(vec![1.5f64, -2.0], (Some(vec![7u8]), 9u8)));
        assert_eq!(bytes, open);
        assert_eq!(from_bytes::<Pinned>(&bytes).unwrap(), m);
        assert_eq!(Pinned::MIN_SIZE, (4 + 16) + 1 + 1);
        // Another length is refused, not cut or padded.
        let three = to_bytes(&(vec![1.0f64, 2.0, 3.0], (None::<Vec<u8>>, 9u8)));
        let err = from_bytes::<Pinned>(&three).unwrap_err();
        assert!(
            err.to_string()
                .contains("3 items where this node's `refine` pins 2"),
            "{err}"
        );
    }

    #[derive(Debug, PartialEq)]
    struct Empty {}
    crate::__peppy_codec!(Empty {});

    #[derive(Debug, PartialEq)]
    struct Unit;
    crate::__peppy_codec!(Unit {});

    #[test]
    fn fields_go_in_declaration_order_and_come_back() {
        let m = Message {
            header: MessageHeader { frame_id: 7 },
            r#type: "hi".into(),
            samples: [1, 2, 3],
            fooBar: Some(9),
        };
        let bytes = to_bytes(&m);
        assert_eq!(
            bytes,
            [7, 0, 0, 0, 2, 0, 0, 0, b'h', b'i', 1, 0, 2, 0, 3, 0, 1, 9]
        );
        assert_eq!(from_bytes::<Message>(&bytes).unwrap(), m);
        // u32 + string length + three u16 + option tag.
        assert_eq!(Message::MIN_SIZE, 4 + 4 + 6 + 1);
        assert_eq!(Empty::MIN_SIZE, 0);
        assert_eq!(to_bytes(&Empty {}), Vec::<u8>::new());
        assert_eq!(from_bytes::<Empty>(&[]).unwrap(), Empty {});
        assert_eq!(from_bytes::<Unit>(&[]).unwrap(), Unit);
        assert!(from_bytes::<Unit>(&[0]).is_err());
    }
}
