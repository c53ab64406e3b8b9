//! A whole session in process: open a profile, read its diagnostics, hover, go to
//! definition, find references, complete, outline; malformed frames on the way. The
//! end-to-end test with a real client is `tests/lsp_client.rs` at the root.

mod common;

use common::{frame, run_session, Session};
use serde_json::{json, Value};

const HARPSICHORD_FILE: &str = include_str!("../../instruments/harpsichord.tactus");

/// The harpsichord as one file, its plectrum written in it instead of imported from the
/// library (as it was before the library): the features within one file.
fn harpsichord() -> String {
    let lib = tactus_compiler::library::file("action.tactus").unwrap();
    let start = lib.find("// A plectrum").unwrap();
    let end = start + lib[start..].find("\n}\n").unwrap() + 3;
    let one = HARPSICHORD_FILE.replace("import \"action.tactus\" { plectrum }\n", &lib[start..end]);
    assert_ne!(one, HARPSICHORD_FILE);
    one
}

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
    let bad = harpsichord().replace("force viscous = B * d(key)", "force viscous = B * key + G");
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
    let text = &harpsichord();
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

/// Reads files from disk, as the command line's loader does (the language server gets it
/// from the binary; this crate cannot depend on the host).
struct Disk;

impl tactus_compiler::imports::Loader for Disk {
    fn read(
        &mut self,
        path: &std::path::Path,
        _: u64,
    ) -> Result<tactus_compiler::imports::Loaded, tactus_compiler::imports::LoadError> {
        match std::fs::read_to_string(path) {
            Ok(text) => Ok(tactus_compiler::imports::Loaded {
                key: std::fs::canonicalize(path).unwrap(),
                text,
            }),
            Err(_) => Err(tactus_compiler::imports::LoadError::NotFound),
        }
    }
}

fn temp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("tactus-lsp-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    std::fs::canonicalize(d).unwrap()
}

fn file_uri(p: &std::path::Path) -> String {
    tactus_lsp::files::path_to_uri(p)
        .unwrap()
        .as_str()
        .to_string()
}

#[test]
fn definition_hover_and_members_follow_an_import_into_the_library() {
    let lib = temp("lib");
    let config = tactus_lsp::Config {
        library_dir: Some(lib.clone()),
        ..tactus_lsp::Config::default()
    };
    let text = HARPSICHORD_FILE;
    let mut msgs = vec![
        json!({"jsonrpc":"2.0","id":1,"method":"initialize","params":{"capabilities":{}}}),
        json!({"jsonrpc":"2.0","method":"textDocument/didOpen","params":{"textDocument":{
            "uri": uri(), "languageId":"tactus","version":1,"text": text}}}),
    ];
    let at = |needle: &str, delta: usize| pos(text, needle, 0, delta);
    for (id, method, params) in [
        (
            100,
            "textDocument/definition",
            json!({"textDocument": td(), "position": at("plectrum(x = key", 2)}),
        ),
        (
            101,
            "textDocument/hover",
            json!({"textDocument": td(), "position": at("plectrum(x = key", 2)}),
        ),
        (
            102,
            "textDocument/completion",
            json!({"textDocument": td(), "position": at("jack.f", 5)}),
        ),
        (
            103,
            "textDocument/references",
            json!({"textDocument": td(), "position": at("plectrum(x = key", 2),
            "context": {"includeDeclaration": true}}),
        ),
    ] {
        msgs.push(json!({"jsonrpc":"2.0","id": id,"method": method,"params": params}));
    }
    msgs.push(json!({"jsonrpc":"2.0","id":2,"method":"shutdown"}));
    msgs.push(json!({"jsonrpc":"2.0","method":"exit"}));
    let input: Vec<u8> = msgs.iter().flat_map(|m| frame(&m.to_string())).collect();
    let s = common::run_session_with(input, &config);
    assert_eq!(s.outcome.panics, 0);
    let diags = &s.notifications("textDocument/publishDiagnostics")[0]["diagnostics"];
    assert_eq!(diags.as_array().unwrap().len(), 0, "{diags}");
    // The definition is the library file's copy, at `plectrum` in `component plectrum {`.
    let def = s.result(100);
    let uri = def["uri"].as_str().unwrap();
    assert!(
        uri.starts_with(&file_uri(&lib)) && uri.ends_with("/action.tactus"),
        "{def}"
    );
    let path = tactus_lsp::files::uri_to_path(uri).unwrap();
    let lib_text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(
        lib_text,
        tactus_compiler::library::file("action.tactus").unwrap()
    );
    assert_eq!(def["range"]["start"], pos(&lib_text, "plectrum {", 0, 0));
    // Hover names the component, where it comes from, its interface and its documentation.
    let hover = s.result(101)["contents"]["value"]
        .as_str()
        .unwrap()
        .to_string();
    for want in [
        "component `plectrum`",
        "from: builtin:lib/action.tactus",
        "inputs: `x`: m, `v`: m/s",
        "A plectrum: the quill bends against the string",
    ] {
        assert!(hover.contains(want), "`{want}` not in {hover}");
    }
    // `jack.` completes the imported component's members.
    let members: Vec<String> = s
        .result(102)
        .as_array()
        .unwrap()
        .iter()
        .map(|i| i["label"].as_str().unwrap().to_string())
        .collect();
    assert!(
        members.contains(&"f".into()) && members.contains(&"phase".into()),
        "{members:?}"
    );
    // References: the declaration in the library and the use in the document.
    let refs = s.result(103);
    let uris: Vec<&str> = refs
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["uri"].as_str().unwrap())
        .collect();
    assert!(
        uris.contains(&self::uri()) && uris.iter().any(|u| u.ends_with("/action.tactus")),
        "{uris:?}"
    );
    let _ = std::fs::remove_dir_all(&lib);
}

#[test]
fn an_error_in_an_imported_file_is_shown_at_the_import_and_goes_when_it_is_fixed() {
    let dir = temp("import");
    let bad =
        "component spring {\n    param k = 100 N/m\n    input x: m\n    output f = k * x + x\n}\n";
    std::fs::write(dir.join("springs.tactus"), bad).unwrap();
    let main = "import \"springs.tactus\"\n\ninstrument main {\n    sensor key: m in [0 mm, 10 mm]\n    use s = spring(x = key)\n    force f = s.f\n}\n";
    let main_uri = file_uri(&dir.join("main.tactus"));
    let springs_uri = file_uri(&dir.join("springs.tactus"));
    let config = tactus_lsp::Config {
        disk: Some(|| Box::new(Disk)),
        plans: false,
        ..tactus_lsp::Config::default()
    };
    let msgs = [
        json!({"jsonrpc":"2.0","id":1,"method":"initialize","params":{"capabilities":{}}}),
        json!({"jsonrpc":"2.0","method":"textDocument/didOpen","params":{"textDocument":{
            "uri": main_uri, "languageId":"tactus","version":1,"text": main}}}),
        // The user opens the imported file and fixes it, without saving: the open text wins.
        json!({"jsonrpc":"2.0","method":"textDocument/didOpen","params":{"textDocument":{
            "uri": springs_uri, "languageId":"tactus","version":1,"text": bad}}}),
        json!({"jsonrpc":"2.0","method":"textDocument/didChange","params":{
            "textDocument": {"uri": springs_uri, "version": 2},
            "contentChanges": [{"text": bad.replace("k * x + x", "k * x")}]}}),
        json!({"jsonrpc":"2.0","id":2,"method":"shutdown"}),
        json!({"jsonrpc":"2.0","method":"exit"}),
    ];
    let input: Vec<u8> = msgs.iter().flat_map(|m| frame(&m.to_string())).collect();
    let s = common::run_session_with(input, &config);
    assert_eq!(s.outcome.panics, 0);
    let published = s.notifications("textDocument/publishDiagnostics");
    let of = |u: &str| -> Vec<&Value> { published.iter().filter(|p| p["uri"] == u).collect() };
    // First: the main file's E0202, at its import line, naming the place in springs.tactus.
    let first = &of(&main_uri)[0]["diagnostics"][0];
    assert_eq!(first["code"], "E0202", "{first}");
    assert_eq!(
        first["range"]["start"],
        json!({"line": 0, "character": 0}),
        "{first}"
    );
    let msg = first["message"].as_str().unwrap();
    assert!(
        msg.contains("springs.tactus:4:16: dimension mismatch"),
        "{msg}"
    );
    let related = first["relatedInformation"].as_array().unwrap();
    assert!(
        related
            .iter()
            .any(|r| r["location"]["uri"] == springs_uri.as_str()
                && r["location"]["range"]["start"] == json!({"line": 3, "character": 15})),
        "{related:?}"
    );
    // The imported file, open, is a library file: no "no instrument" for it.
    let springs = &of(&springs_uri)[0]["diagnostics"];
    assert_eq!(springs.as_array().unwrap().len(), 0, "{springs}");
    // Fixed in the editor: the main file is analysed again, clean.
    let last = of(&main_uri).last().unwrap()["diagnostics"].clone();
    assert_eq!(last.as_array().unwrap().len(), 0, "{last}");
    assert!(of(&main_uri).len() >= 2);
    let _ = std::fs::remove_dir_all(&dir);
}
