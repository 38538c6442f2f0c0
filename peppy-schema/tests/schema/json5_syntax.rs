//! JSON5 syntax that the underlying parser accepts but JSON5 does not:
//! unquoted keys that are not identifiers and raw line breaks in strings.
//! Both are located `Syntax` errors; what JSON5 allows stays accepted.

use peppy_schema::json::{Node, parse};
use peppy_schema::{Code, Diagnostics, SourceFile};

use crate::support::{all, help, lc, node_err, one, pos};

/// Every finding of parsing `text`, which must have errors.
fn json_errors(text: &str) -> Diagnostics {
    let diags = match parse(&SourceFile::new("t.json5", text)) {
        Ok((_, diags)) | Err(diags) => diags,
    };
    assert!(diags.has_errors(), "expected errors for:\n{text}");
    diags
}

/// The tree of `text`, which must parse without findings.
fn json_ok(text: &str) -> Node {
    match parse(&SourceFile::new("t.json5", text)) {
        Ok((node, diags)) if diags.is_empty() => node,
        Ok((_, diags)) | Err(diags) => panic!("expected {text:?} to parse, got:\n{diags}"),
    }
}

#[test]
fn unquoted_keys_must_be_identifiers() {
    // The first four the parser reads as keys; the rest stop it mid-key.
    for key in [
        "foo-bar", "123", "0x1F", "1.5", "a.b", "1abc", "-x", "a/b", "é-ü",
    ] {
        let text = format!("{{\n  ok: 1,\n  {key}: 2,\n}}");
        let errors = json_errors(&text);
        let d = one(&errors, Code::Syntax);
        assert_eq!(
            d.message,
            format!("invalid JSON5: `{key}` is not a valid unquoted key"),
            "{d}"
        );
        assert_eq!(lc(d), pos(&text, key), "{d}");
        let span = d.span().unwrap();
        assert_eq!(&text[span.start..span.end], key);
        assert!(
            help(d).contains(&format!("quote the key: `\"{key}\"`")),
            "{d}"
        );
    }
}

#[test]
fn identifier_and_quoted_keys_are_accepted() {
    let node = json_ok(
        r#"{ $type: 1, _x: 2, a1: 3, é: 4, Infinity: 5, true: 6, null: 7,
             "foo-bar": 8, 'a.b': 9, "123": 10, "x\ny": 11 }"#,
    );
    let peppy_schema::json::Value::Object(members) = &node.value else {
        panic!("object expected")
    };
    let keys: Vec<&str> = members.iter().map(|m| m.key.as_str()).collect();
    assert_eq!(
        keys,
        [
            "$type", "_x", "a1", "é", "Infinity", "true", "null", "foo-bar", "a.b", "123", "x\ny"
        ]
    );
}

#[test]
fn raw_line_breaks_in_strings_are_errors() {
    for (text, needle) in [
        ("{\n  a: \"one\ntwo\",\n}", "\"one"),
        ("{\n  a: 'one\r\ntwo',\n}", "'one"),
        ("{\n  a: \"esc\\\"aped\rtwo\",\n}", "\"esc"),
        ("{\n  \"key\nbroken\": 1,\n}", "\"key"),
        ("{\n  a: [\"ok\", \"x\\\ny\nz\"],\n}", "\"x"),
    ] {
        let errors = json_errors(text);
        let d = one(&errors, Code::Syntax);
        assert_eq!(
            d.message, "invalid JSON5: a line break inside a string",
            "{d}"
        );
        assert_eq!(lc(d), pos(text, needle), "{text:?}: {d}");
        assert!(help(d).contains("write `\\n`"), "{d}");
    }
}

#[test]
fn line_continuations_and_escaped_breaks_are_accepted() {
    let node = json_ok(
        "{ lf: \"a\\\nb\", crlf: 'a\\\r\nb', cr: \"a\\\rb\", esc: \"a\\nb\", ls: \"a\u{2028}b\" }",
    );
    assert_eq!(node.get("lf").unwrap().as_str(), Some("ab"));
    assert_eq!(node.get("crlf").unwrap().as_str(), Some("ab"));
    assert_eq!(node.get("cr").unwrap().as_str(), Some("ab"));
    assert_eq!(node.get("esc").unwrap().as_str(), Some("a\nb"));
    // JSON5 allows U+2028 and U+2029 in strings as they are.
    assert_eq!(node.get("ls").unwrap().as_str(), Some("a\u{2028}b"));
}

#[test]
fn a_node_document_reports_them_in_position_order() {
    let text = r#"{
  peppy_schema: "node_v1",
  manifest: { name: "cam", tag: "v1", frame-rate: 3 },
  interfaces: {},
  execution: { language: "rust", run_cmd: ["./cam
"] },
}"#;
    let errors = node_err(text);
    let syntax = all(&errors, Code::Syntax);
    assert_eq!(syntax.len(), 2, "{errors}");
    assert_eq!(lc(syntax[0]), pos(text, "frame-rate"));
    assert_eq!(lc(syntax[1]), pos(text, "\"./cam"));
}

#[test]
fn odd_input_around_keys_never_panics() {
    for text in [
        "{ ü.x",
        "{ a-",
        "{ é.ü: ",
        "{ :",
        "{ \"a\n",
        "{ a: 'b\\",
        "{ ü-\u{2028}: 1 }",
    ] {
        json_errors(text);
    }
}
