//! Parameter schemas (`execution.parameters`) and filling in values. The
//! schema and the values side need no document parser (a node binary uses
//! them); reading a schema from a document is in `parse`.
//!
//! One implementation checks `$default`s at parse time and launcher
//! `arguments` / runtime values later: everything goes through
//! [`check_leaf`] on a `serde_json::Value`.

use serde::{Deserialize, Serialize};
use serde_json::{Map, Value as Json};

use crate::diag::{Code, did_you_mean, list};
use crate::loc::Loc;
use crate::primitive::Primitive;

#[cfg(feature = "documents")]
mod parse;
#[cfg(feature = "documents")]
pub(crate) use parse::parse_parameters;

/// The parameters a node takes: the root group's fields, in order.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct ParameterSchema {
    /// Root parameters and groups.
    pub fields: Vec<ParamField>,
}

/// One parameter or group.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ParamField {
    /// Its key.
    pub name: String,
    /// What it holds.
    pub kind: ParamKind,
    /// Where it is declared (not carried into a compiled model).
    #[serde(skip)]
    pub loc: Loc,
}

/// What a parameter holds.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamKind {
    /// A primitive value.
    Leaf {
        /// Its type.
        ty: Primitive,
        /// `$default`, already checked against the type.
        default: Option<Json>,
    },
    /// An array.
    Array {
        /// Item type.
        items: ParamItem,
        /// `$length`.
        length: Option<u32>,
        /// `$default` (primitive items only), already checked.
        default: Option<Json>,
    },
    /// A nested group of parameters.
    Group(Vec<ParamField>),
}

/// The items of an array parameter.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ParamItem {
    /// Primitive items.
    Primitive(Primitive),
    /// Object items, each with these fields (no defaults inside).
    Object(Vec<ParamField>),
}

/// Why a parameter value was refused.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParamError {
    /// Dot-path of the parameter (`video.fps`, `limits[2]`).
    pub path: String,
    /// What went wrong.
    pub kind: ParamErrorKind,
}

/// What went wrong with a parameter value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ParamErrorKind {
    /// A required parameter (no `$default`) was not given.
    Missing {
        /// The expected type.
        expected: String,
    },
    /// A key the schema does not declare.
    Unknown {
        /// A close declared name, if any.
        suggestion: Option<String>,
        /// Declared names at that level.
        accepted: Vec<String>,
    },
    /// A value of the wrong type or out of range.
    TypeMismatch {
        /// What was expected.
        expected: String,
        /// What was given.
        found: String,
    },
}

impl ParamError {
    /// The diagnostic code for this error.
    pub fn code(&self) -> Code {
        match self.kind {
            ParamErrorKind::Missing { .. } => Code::MissingParameter,
            ParamErrorKind::Unknown { .. } => Code::UnknownParameter,
            ParamErrorKind::TypeMismatch { .. } => Code::ParameterTypeMismatch,
        }
    }

    /// What would be accepted.
    pub fn help(&self) -> Option<String> {
        match &self.kind {
            ParamErrorKind::Missing { .. } => Some(format!(
                "pass it (`{}=...` on the command line, or under `arguments` in a launcher) or give it a `$default`",
                self.path
            )),
            ParamErrorKind::Unknown {
                suggestion,
                accepted,
            } => Some(match suggestion {
                Some(s) => format!(
                    "did you mean `{s}`? parameters here: {}",
                    list(accepted.iter().map(String::as_str))
                ),
                None => format!(
                    "parameters here: {}",
                    list(accepted.iter().map(String::as_str))
                ),
            }),
            ParamErrorKind::TypeMismatch { .. } => None,
        }
    }
}

impl std::fmt::Display for ParamError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.kind {
            ParamErrorKind::Missing { expected } => {
                write!(f, "missing required parameter `{}` ({expected})", self.path)
            }
            ParamErrorKind::Unknown { .. } => write!(f, "unknown parameter `{}`", self.path),
            ParamErrorKind::TypeMismatch { expected, found } => write!(
                f,
                "parameter `{}` expects {expected}, found {found}",
                self.path
            ),
        }
    }
}

impl std::error::Error for ParamError {}

/// Human description of a primitive's accepted values.
pub fn describe(ty: Primitive) -> String {
    match ty {
        Primitive::Bool => "a `bool` (true or false)".into(),
        Primitive::F32 => "an `f32` (a finite number)".into(),
        Primitive::F64 => "an `f64` (a number)".into(),
        Primitive::String => "a `string`".into(),
        Primitive::Bytes => "`bytes` (a string or an array of 0..=255)".into(),
        Primitive::Time => "a `time` (seconds since the Unix epoch)".into(),
        p => {
            let (lo, hi) = p.int_range().expect("integer type");
            format!("a `{}` (an integer from {lo} to {hi})", p.name())
        }
    }
}

pub(super) fn describe_found(v: &Json) -> String {
    match v {
        Json::Null => "null".into(),
        Json::Bool(b) => format!("`{b}`"),
        Json::Number(n) => format!("`{n}`"),
        Json::String(s) => format!("the string {s:?}"),
        Json::Array(_) => "an array".into(),
        Json::Object(_) => "an object".into(),
    }
}

/// Checks one primitive value; returns it normalised (`bytes` as an array).
pub fn check_leaf(ty: Primitive, v: &Json) -> Result<Json, String> {
    let mismatch = || {
        Err(format!(
            "expects {}, found {}",
            describe(ty),
            describe_found(v)
        ))
    };
    match ty {
        Primitive::Bool => match v {
            Json::Bool(_) => Ok(v.clone()),
            _ => mismatch(),
        },
        Primitive::F32 => match v.as_f64() {
            Some(f) if f.is_finite() && f.abs() <= f32::MAX as f64 => Ok(v.clone()),
            _ => mismatch(),
        },
        Primitive::F64 => match v.as_f64() {
            Some(_) => Ok(v.clone()),
            None => mismatch(),
        },
        Primitive::Time => match v.as_f64() {
            Some(f) if f.is_finite() => Ok(v.clone()),
            _ => mismatch(),
        },
        Primitive::String => match v {
            Json::String(_) => Ok(v.clone()),
            _ => mismatch(),
        },
        Primitive::Bytes => match v {
            Json::String(s) => Ok(s.bytes().map(Json::from).collect()),
            Json::Array(items) if items.iter().all(|i| i.as_u64().is_some_and(|b| b <= 255)) => {
                Ok(v.clone())
            }
            _ => mismatch(),
        },
        int => {
            let (lo, hi) = int.int_range().expect("integer type");
            let value = v
                .as_i64()
                .map(i128::from)
                .or_else(|| v.as_u64().map(i128::from));
            match value {
                Some(i) if i >= lo && i <= hi => Ok(v.clone()),
                _ => mismatch(),
            }
        }
    }
}

impl ParameterSchema {
    /// Whether the node takes no parameters.
    pub fn is_empty(&self) -> bool {
        self.fields.is_empty()
    }

    /// Checks `provided` (an object, or `null` for none) against the schema
    /// and fills in defaults, including whole groups whose leaves all have
    /// defaults. Every problem is returned, each naming its dot-path.
    pub fn resolve(&self, provided: &Json) -> Result<Json, Vec<ParamError>> {
        let mut errors = Vec::new();
        let map = match provided {
            Json::Null => None,
            Json::Object(m) => Some(m),
            other => {
                errors.push(ParamError {
                    path: String::new(),
                    kind: ParamErrorKind::TypeMismatch {
                        expected: "an object of parameters".into(),
                        found: describe_found(other),
                    },
                });
                return Err(errors);
            }
        };
        let out = resolve_group(&self.fields, map, "", &mut errors);
        if errors.is_empty() {
            Ok(Json::Object(out))
        } else {
            Err(errors)
        }
    }
}

pub(super) fn dot(parent: &str, key: &str) -> String {
    if parent.is_empty() {
        key.to_string()
    } else {
        format!("{parent}.{key}")
    }
}

fn resolve_group(
    fields: &[ParamField],
    provided: Option<&Map<String, Json>>,
    path: &str,
    errors: &mut Vec<ParamError>,
) -> Map<String, Json> {
    let mut out = Map::new();
    if let Some(map) = provided {
        for key in map.keys() {
            if !fields.iter().any(|f| &f.name == key) {
                let accepted: Vec<String> = fields.iter().map(|f| f.name.clone()).collect();
                errors.push(ParamError {
                    path: dot(path, key),
                    kind: ParamErrorKind::Unknown {
                        suggestion: did_you_mean(key, accepted.iter().map(String::as_str))
                            .map(str::to_string),
                        accepted,
                    },
                });
            }
        }
    }
    for f in fields {
        let fpath = dot(path, &f.name);
        let given = provided.and_then(|m| m.get(&f.name));
        if let Some(v) = resolve_field(&f.kind, given, &fpath, errors) {
            out.insert(f.name.clone(), v);
        }
    }
    out
}

pub(super) fn resolve_field(
    kind: &ParamKind,
    given: Option<&Json>,
    path: &str,
    errors: &mut Vec<ParamError>,
) -> Option<Json> {
    let mismatch = |errors: &mut Vec<ParamError>, expected: String, found: &Json| {
        errors.push(ParamError {
            path: path.to_string(),
            kind: ParamErrorKind::TypeMismatch {
                expected,
                found: describe_found(found),
            },
        });
    };
    match (kind, given) {
        (ParamKind::Leaf { ty, .. }, Some(v)) => match check_leaf(*ty, v) {
            Ok(v) => Some(v),
            Err(_) => {
                mismatch(errors, describe(*ty), v);
                None
            }
        },
        (
            ParamKind::Leaf {
                default: Some(d), ..
            },
            None,
        ) => Some(d.clone()),
        (ParamKind::Leaf { ty, default: None }, None) => {
            errors.push(ParamError {
                path: path.to_string(),
                kind: ParamErrorKind::Missing {
                    expected: describe(*ty),
                },
            });
            None
        }
        (ParamKind::Array { items, length, .. }, Some(v)) => {
            let Json::Array(values) = v else {
                mismatch(errors, describe_array(items, *length), v);
                return None;
            };
            if let Some(n) = length
                && values.len() != *n as usize
            {
                mismatch(errors, describe_array(items, *length), v);
                return None;
            }
            let mut out = Vec::with_capacity(values.len());
            for (i, item) in values.iter().enumerate() {
                let ipath = format!("{path}[{i}]");
                match items {
                    ParamItem::Primitive(p) => match check_leaf(*p, item) {
                        Ok(v) => out.push(v),
                        Err(_) => mismatch_at(errors, &ipath, describe(*p), item),
                    },
                    ParamItem::Object(fields) => match item {
                        Json::Object(m) => {
                            out.push(Json::Object(resolve_group(fields, Some(m), &ipath, errors)))
                        }
                        other => mismatch_at(errors, &ipath, "an object".into(), other),
                    },
                }
            }
            Some(Json::Array(out))
        }
        (
            ParamKind::Array {
                default: Some(d), ..
            },
            None,
        ) => Some(d.clone()),
        (
            ParamKind::Array {
                items,
                length,
                default: None,
            },
            None,
        ) => {
            errors.push(ParamError {
                path: path.to_string(),
                kind: ParamErrorKind::Missing {
                    expected: describe_array(items, *length),
                },
            });
            None
        }
        (ParamKind::Group(fields), Some(Json::Object(m))) => {
            Some(Json::Object(resolve_group(fields, Some(m), path, errors)))
        }
        (ParamKind::Group(_), Some(other)) => {
            mismatch(errors, "an object (a parameter group)".into(), other);
            None
        }
        (ParamKind::Group(fields), None) => {
            Some(Json::Object(resolve_group(fields, None, path, errors)))
        }
    }
}

pub(super) fn mismatch_at(
    errors: &mut Vec<ParamError>,
    path: &str,
    expected: String,
    found: &Json,
) {
    errors.push(ParamError {
        path: path.to_string(),
        kind: ParamErrorKind::TypeMismatch {
            expected,
            found: describe_found(found),
        },
    });
}

pub(super) fn describe_array(items: &ParamItem, length: Option<u32>) -> String {
    let item = match items {
        ParamItem::Primitive(p) => p.name().to_string(),
        ParamItem::Object(_) => "object".to_string(),
    };
    match length {
        Some(n) => format!("an array of exactly {n} `{item}`"),
        None => format!("an array of `{item}`"),
    }
}
