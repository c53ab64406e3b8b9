//! A whole session in process: open a profile, read its diagnostics, hover, go to
//! definition, find references, complete, outline; malformed frames on the way. The
//! end-to-end test with a real client is `tests/lsp_client.rs` at the root.

mod common;

use common::{frame, run_session, Session};
use serde_json::{json, Value};

const HARPSICHORD: &str = include_str!("../../instruments/harpsichord.tactus");

fn pos(text: &str, needle: &str, nth: usize, delta: usize) -> Value {
    let at = text.match_indices(needle).nth(nth).expect("needle").0 + delta;
    let line = text[..at].matches('\n').count();
    let col = at - text[..at].rfind('\n').map_or(0, |i| i + 1);
    json!({ "line": line, "character": col })
}

fn uri() -> &'static str {
    "file:///tmp/harpsichord.tactus"
}

fn session(text: &str, requests: Vec<(&str, Value)>) -> Session {
    let mut msgs = vec![
        json!({"jsonrpc":"2.0","id":1,"method":"initialize","params":{"capabilities":{}}}),
        json!({"jsonrpc":"2.0","method":"initialized","params":{}}),
        json!({"jsonrpc":"2.0","method":"textDocument/didOpen","params":{"textDocument":{
            "uri": uri(), "languageId":"tactus","version":1,"text": text}}}),
    ];
    for (i, (method, params)) in requests.into_iter().enumerate() {
        msgs.push(json!({"jsonrpc":"2.0","id": 100 + i,"method": method,"params": params}));
    }
    msgs.push(json!({"jsonrpc":"2.0","id":2,"method":"shutdown"}));
    msgs.push(json!({"jsonrpc":"2.0","method":"exit"}));
    let input: Vec<u8> = msgs.iter().flat_map(|m| frame(&m.to_string())).collect();
    run_session(input)
}

fn td() -> Value {
    json!({ "uri": uri() })
}

#[test]
fn a_unit_error_is_a_diagnostic_at_its_span() {
    // `B * d(key)` is N; `B * key` is N·s: adding it to newtons is E0202.
    let bad = HARPSICHORD.replace("force viscous = B * d(key)", "force viscous = B * key + G");
    let s = session(&bad, vec![]);
    assert!(s.outcome.clean_exit);
    let diags = &s.notifications("textDocument/publishDiagnostics")[0]["diagnostics"];
    let d = diags
        .as_array()
        .unwrap()
        .iter()
        .find(|d| d["code"] == "E0202")
        .unwrap_or_else(|| panic!("no E0202 in {diags}"));
    assert_eq!(d["severity"], 1);
    assert!(d["message"]
        .as_str()
        .unwrap()
        .starts_with("dimension mismatch"));
    // The range is the sum `B * key + G` on its line.
    let start = pos(&bad, "B * key + G", 0, 0);
    assert_eq!(d["range"]["start"], start);
    assert_eq!(
        d["range"]["end"]["character"].as_u64().unwrap(),
        start["character"].as_u64().unwrap() + "B * key + G".len() as u64
    );
    assert_eq!(d["relatedInformation"].as_array().unwrap().len(), 2);
}

#[test]
fn hover_definition_references_completion_outline() {
    let text = HARPSICHORD;
    let s = session(
        text,
        vec![
            // 100: hover on `B` in the viscous term: a param in N·s/m, with its format.
            (
                "textDocument/hover",
                json!({"textDocument": td(), "position": pos(text, "B * d(key)", 0, 0)}),
            ),
            // 101: hover on the component's state `xmax` where it is read.
            (
                "textDocument/hover",
                json!({"textDocument": td(), "position": pos(text, "x > xmax", 0, 5)}),
            ),
            // 102: definition of the component named in `use`.
            (
                "textDocument/definition",
                json!({"textDocument": td(), "position": pos(text, "plectrum(x = key", 0, 2)}),
            ),
            // 103: references of `touch`.
            (
                "textDocument/references",
                json!({"textDocument": td(), "position": pos(text, "param touch", 0, 7),
                       "context": {"includeDeclaration": true}}),
            ),
            // 104: completion in the instrument's body.
            (
                "textDocument/completion",
                json!({"textDocument": td(), "position": pos(text, "force weight = G", 0, 15)}),
            ),
            // 105: the outline.
            ("textDocument/documentSymbol", json!({"textDocument": td()})),
            // 106: completion after `jack.`.
            (
                "textDocument/completion",
                json!({"textDocument": td(), "position": pos(text, "jack.f", 0, 5)}),
            ),
            // 107: a method we do not serve.
            ("textDocument/formatting", json!({"textDocument": td()})),
        ],
    );
    assert_eq!(s.outcome.panics, 0);
    let hover = s.result(100)["contents"]["value"]
        .as_str()
        .unwrap()
        .to_string();
    println!("{hover}");
    assert!(hover.contains("param `B`"), "{hover}");
    assert!(hover.contains("unit: N*s/m"), "{hover}");
    assert!(hover.contains("format: Q"), "{hover}");
    let hover = s.result(101)["contents"]["value"]
        .as_str()
        .unwrap()
        .to_string();
    println!("{hover}");
    assert!(hover.contains("state `xmax`"), "{hover}");
    assert!(hover.contains("declared range: [0, 0.02] m"), "{hover}");
    assert!(hover.contains("error bound"), "{hover}");
    let def = s.result(102);
    assert_eq!(def["range"]["start"], pos(text, "plectrum {", 0, 0));
    let refs = s.result(103);
    let refs = refs.as_array().unwrap();
    // The declaration and its uses (`bend`, two conditions, `fhold`, `f`).
    assert!(refs.len() >= 5, "{refs:?}");
    assert_eq!(refs[0]["range"]["start"], pos(text, "touch = 4.0", 0, 0));
    let labels: Vec<String> = s
        .result(104)
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["label"].as_str().unwrap().to_string())
        .collect();
    for want in ["B", "G", "key", "jack", "viscous", "d", "sqrt"] {
        assert!(
            labels.contains(&want.to_string()),
            "{want} not in {labels:?}"
        );
    }
    assert!(
        !labels.contains(&"xmax".to_string()),
        "a component's state completed outside it"
    );
    let outline = s.result(105);
    let names: Vec<&str> = outline
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["plectrum", "harpsichord"]);
    let members: Vec<String> = s
        .result(106)
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["label"].as_str().unwrap().to_string())
        .collect();
    assert!(
        members.contains(&"f".into()) && members.contains(&"phase".into()),
        "{members:?}"
    );
    assert!(
        !members.contains(&"bend".into()),
        "a let is not visible outside: {members:?}"
    );
    assert_eq!(s.error(107)["code"], -32601);
}

#[test]
fn bad_frames_are_answered_and_the_session_goes_on() {
    let mut input = Vec::new();
    input.extend(frame(
        r#"{"jsonrpc":"2.0","id":1,"method":"initialize","params":{"capabilities":{}}}"#,
    ));
    input.extend(frame("{not json"));
    input.extend(b"Content-Length: nope\r\n\r\n");
    input.extend(frame(
        r#"{"jsonrpc":"2.0","id":3,"method":"textDocument/hover","params":{"bogus":1}}"#,
    ));
    input.extend(frame(r#"{"jsonrpc":"2.0","id":4,"method":"textDocument/hover","params":{"textDocument":{"uri":"file:///nope"},"position":{"line":4000000000,"character":7}}}"#));
    input.extend(frame(r#"{"jsonrpc":"2.0","id":2,"method":"shutdown"}"#));
    input.extend(frame(r#"{"jsonrpc":"2.0","method":"exit"}"#));
    let s = run_session(input);
    assert!(s.outcome.clean_exit);
    assert_eq!(s.outcome.bad_frames, 2);
    assert_eq!(s.outcome.panics, 0);
    assert!(s
        .messages
        .iter()
        .any(|m| m["error"]["code"] == -32700 && m["id"].is_null()));
    assert_eq!(s.error(3)["code"], -32602);
    assert!(s.result(4).is_null());
    assert!(s.log.iter().any(|l| l.contains("bad frame")), "{:?}", s.log);
}

#[test]
fn a_client_that_goes_away_ends_the_session() {
    let mut input = Vec::new();
    input.extend(frame(
        r#"{"jsonrpc":"2.0","id":1,"method":"initialize","params":{"capabilities":{}}}"#,
    ));
    input.extend(b"Content-Length: 100\r\n\r\n{\"jsonrpc\"");
    let s = run_session(input);
    assert!(!s.outcome.clean_exit);
    assert!(s.log.iter().any(|l| l.contains("went away")), "{:?}", s.log);
}
