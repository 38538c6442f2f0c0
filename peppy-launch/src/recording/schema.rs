//! The JSON Schema a recording's channel carries for a peppy format, so
//! that Foxglove and the MCAP tools read its JSON messages without peppy.
//!
//! The schema describes the JSON [`to_recording_json`] writes: fields in
//! format order, integers with their ranges, `bytes` and `[u8]` as base64
//! strings, `time` as `{sec, nsec}` (what Foxglove takes for a time).
//!
//! [`to_recording_json`]: crate::inspect::dynamic::to_recording_json

use peppy_schema::{Field, FieldType, MessageFormat, Primitive};
use serde_json::{Map, Value, json};

/// The schema of messages of `format`; `title` names it for people.
pub(crate) fn json_schema(format: &MessageFormat, title: &str, fingerprint: u64) -> Value {
    let mut schema = object(&format.fields);
    if let Value::Object(map) = &mut schema {
        let mut head = Map::new();
        head.insert(
            "$schema".into(),
            "https://json-schema.org/draft/2020-12/schema".into(),
        );
        head.insert("title".into(), title.into());
        head.insert(
            "description".into(),
            format!("peppy format {fingerprint:016x}").into(),
        );
        head.append(map);
        *map = head;
    }
    schema
}

fn object(fields: &[Field]) -> Value {
    let properties: Map<String, Value> = fields
        .iter()
        .map(|f| (f.name.clone(), of_type(&f.ty)))
        .collect();
    let required: Vec<&str> = fields
        .iter()
        .filter(|f| !f.optional)
        .map(|f| f.name.as_str())
        .collect();
    json!({
        "type": "object",
        "properties": properties,
        "required": required,
        "additionalProperties": false,
    })
}

fn of_type(ty: &FieldType) -> Value {
    match ty {
        FieldType::Primitive(p) => primitive(*p),
        FieldType::Object(fields) => object(fields),
        FieldType::Array { items, length, .. } => {
            if **items == FieldType::Primitive(Primitive::U8) {
                let mut bytes = primitive(Primitive::Bytes);
                if let (Some(n), Value::Object(map)) = (length, &mut bytes) {
                    map.insert(
                        "description".into(),
                        format!("exactly {n} bytes, in base64").into(),
                    );
                }
                return bytes;
            }
            let mut array = json!({ "type": "array", "items": of_type(items) });
            if let (Some(n), Value::Object(map)) = (length, &mut array) {
                map.insert("minItems".into(), (*n).into());
                map.insert("maxItems".into(), (*n).into());
            }
            array
        }
    }
}

fn primitive(p: Primitive) -> Value {
    match p {
        Primitive::Bool => json!({ "type": "boolean" }),
        // JSON has no NaN or infinity: a recording writes them as words.
        Primitive::F32 | Primitive::F64 => json!({
            "anyOf": [
                { "type": "number" },
                { "enum": ["NaN", "Infinity", "-Infinity"] },
            ],
        }),
        Primitive::String => json!({ "type": "string" }),
        Primitive::Bytes => json!({ "type": "string", "contentEncoding": "base64" }),
        Primitive::Time => json!({
            "type": "object",
            "properties": {
                "sec": { "type": "integer" },
                "nsec": { "type": "integer", "minimum": 0, "maximum": 999_999_999 },
            },
            "required": ["sec", "nsec"],
            "additionalProperties": false,
        }),
        int => {
            let (lo, hi) = int
                .int_range()
                .unwrap_or((i128::from(i64::MIN), i128::from(u64::MAX)));
            json!({ "type": "integer", "minimum": number(lo), "maximum": number(hi) })
        }
    }
}

/// An integer bound as a JSON number (every bound fits an `i64` or a `u64`).
fn number(n: i128) -> Value {
    i64::try_from(n)
        .map(Value::from)
        .or_else(|_| u64::try_from(n).map(Value::from))
        .unwrap_or(Value::Null)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_camera_frame_reads_as_foxglove_expects() {
        let format = MessageFormat::from_canonical(
            "{header:{stamp:time,frame_id:u32},encoding:string,width:u32,height:u32,frame:[u8],note:string?}",
        )
        .unwrap();
        let schema = json_schema(
            &format,
            "depth_camera:v1/video_stream",
            format.fingerprint(),
        );
        assert_eq!(schema["title"], "depth_camera:v1/video_stream");
        assert_eq!(
            schema["properties"]["width"]["maximum"],
            u64::from(u32::MAX)
        );
        assert_eq!(schema["properties"]["frame"]["contentEncoding"], "base64");
        assert_eq!(
            schema["properties"]["header"]["properties"]["stamp"]["required"],
            json!(["sec", "nsec"])
        );
        assert!(
            !schema["required"]
                .as_array()
                .unwrap()
                .contains(&json!("note"))
        );
    }

    #[test]
    fn floats_may_be_the_words_json_has_for_non_finite_numbers() {
        let format = MessageFormat::from_canonical("{x:f64,y:[f32;3]}").unwrap();
        let schema = json_schema(&format, "t", 0);
        let words = json!({ "enum": ["NaN", "Infinity", "-Infinity"] });
        assert_eq!(schema["properties"]["x"]["anyOf"][1], words);
        assert_eq!(schema["properties"]["y"]["items"]["anyOf"][1], words);
        assert_eq!(schema["properties"]["y"]["minItems"], 3);
    }
}
