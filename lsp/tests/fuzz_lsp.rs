//! Fuzz: random and truncated LSP traffic against `tactus_lsp::serve`. Each case is a
//! session — initialize, a profile opened (a shipped one, edited), requests at random
//! places with random parameters, shutdown, exit — whose bytes are then edited (bytes
//! set, cut, repeated, truncated; headers and JSON fragments inserted). The server must
//! end every session within its time bound, never panic, and write only well-formed
//! frames. `TACTUS_FUZZ_CASES=100000` for a long run.

mod common;
#[path = "../../tests/common/fuzz.rs"]
mod fuzz;

use proptest::prelude::*;
use serde_json::{json, Value};
use std::time::Duration;

const SEEDS: [&str; 3] = [
    include_str!("../../instruments/hammond.tactus"),
    include_str!("../../instruments/harpsichord.tactus"),
    include_str!("../../instruments/grand_piano.tactus"),
];

const METHODS: [&str; 9] = [
    "textDocument/hover",
    "textDocument/definition",
    "textDocument/references",
    "textDocument/completion",
    "textDocument/documentSymbol",
    "textDocument/didChange",
    "textDocument/didClose",
    "initialize",
    "workspace/symbol",
];

/// Byte strings worth inserting into a stream of frames.
const TOKENS: &[&[u8]] = &[
    b"Content-Length: 99999999999999\r\n\r\n",
    b"Content-Length: 18446744073709551616\r\n\r\n",
    b"Content-Length: -1\r\n\r\n",
    b"Content-Length: 2\r\n\r\n{}",
    b"Content-Length: 4\r\n\r\nnull",
    b"\r\n\r\n",
    b"{\"jsonrpc\":\"2.0\",\"id\":null,\"method\":\"shutdown\"}",
    b"\"position\":{\"line\":-1,\"character\":99999999999}",
    b"{\"uri\":\"file:///x\"}",
    b"\xff\xfe\x00",
    b"[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[",
];

/// Tokens for the profile's text.
const SOURCE_TOKENS: &[&[u8]] = &[
    b"component",
    b"use q = nothing()",
    b"state",
    b"in [",
    b"1e308 N",
    b"{",
    b"}",
    b"\xce\xb8",
    b"esc.",
    b"for i in 0..100000 {",
    b"\n",
    b"mode m { a, a }",
];

fn frame(v: &Value) -> Vec<u8> {
    common::frame(&v.to_string())
}

fn session(text: &str, requests: &[(usize, u32, u32, bool)], edits_after: &[u8]) -> Vec<u8> {
    let uri = "file:///tmp/fuzz.tactus";
    let mut out = Vec::new();
    out.extend(frame(
        &json!({"jsonrpc":"2.0","id":1,"method":"initialize","params":{"capabilities":{}}}),
    ));
    out.extend(frame(
        &json!({"jsonrpc":"2.0","method":"initialized","params":{}}),
    ));
    out.extend(frame(
        &json!({"jsonrpc":"2.0","method":"textDocument/didOpen","params":{"textDocument":{
        "uri": uri, "languageId":"tactus","version":1,"text": text}}}),
    ));
    for (i, &(m, line, character, decl)) in requests.iter().enumerate() {
        let method = METHODS[m % METHODS.len()];
        let position = json!({"line": line, "character": character});
        let params = match method {
            "textDocument/didChange" => json!({"textDocument":{"uri":uri,"version":2 + i},
                "contentChanges":[{"range":{"start":position,"end":{"line":line / 2,"character":0}},
                                   "text": String::from_utf8_lossy(edits_after)}]}),
            "textDocument/didClose" | "textDocument/documentSymbol" => {
                json!({"textDocument":{"uri":uri}})
            }
            "textDocument/references" => json!({"textDocument":{"uri":uri},"position":position,
                "context":{"includeDeclaration":decl}}),
            _ => json!({"textDocument":{"uri":uri},"position":position}),
        };
        let is_note = matches!(method, "textDocument/didChange" | "textDocument/didClose");
        let msg = if is_note {
            json!({"jsonrpc":"2.0","method":method,"params":params})
        } else {
            json!({"jsonrpc":"2.0","id":10 + i,"method":method,"params":params})
        };
        out.extend(frame(&msg));
    }
    out.extend(frame(&json!({"jsonrpc":"2.0","id":2,"method":"shutdown"})));
    out.extend(frame(&json!({"jsonrpc":"2.0","method":"exit"})));
    out
}

/// The most a session may take, with a profile of a few hundred lines and a dozen
/// requests (the worst seen is well under a second).
const SESSION_BOUND: Duration = Duration::from_secs(30);

#[test]
fn random_and_truncated_lsp_traffic_never_panics_or_hangs() {
    let (mut runner, cases) = fuzz::runner(48);
    let strategy = (
        0usize..SEEDS.len(),
        fuzz::edits(SOURCE_TOKENS),
        prop::collection::vec((0usize..32, 0u32..400, 0u32..120, any::<bool>()), 0..12),
        fuzz::edits(TOKENS),
        0u32..8,
    );
    let worst = std::cell::Cell::new(Duration::ZERO);
    let frames_bad = std::cell::Cell::new(0usize);
    runner
        .run(
            &strategy,
            |(seed, source_edits, requests, stream_edits, plan_roll)| {
                let text = fuzz::apply(SEEDS[seed].as_bytes(), &source_edits);
                let text = String::from_utf8_lossy(&text).into_owned();
                let clean = session(&text, &requests, b"force extra = 1 N\n");
                let bytes = if stream_edits.len() % 3 == 0 {
                    clean // a third of the sessions arrive intact
                } else {
                    fuzz::apply(&clean, &stream_edits)
                };
                let config = tactus_lsp::Config {
                    hover_wait: Duration::from_millis(50),
                    // Plans run (in the background) in one case of eight: every variant that
                    // compiles would otherwise start a plan search of its own.
                    plans: plan_roll == 0,
                    ..tactus_lsp::Config::default()
                };
                let (tx, rx) = std::sync::mpsc::channel();
                std::thread::spawn(move || {
                    let t = std::time::Instant::now();
                    let s = common::run_session_with(bytes, &config);
                    let _ = tx.send((s, t.elapsed()));
                });
                let (s, dt) = rx.recv_timeout(SESSION_BOUND).map_err(|e| {
                    TestCaseError::fail(match e {
                        std::sync::mpsc::RecvTimeoutError::Timeout => {
                            "the session did not end within its bound"
                        }
                        _ => "the session panicked (or wrote a frame that is not JSON)",
                    })
                })?;
                worst.set(worst.get().max(dt));
                frames_bad.set(frames_bad.get() + s.outcome.bad_frames);
                prop_assert_eq!(s.outcome.panics, 0, "log: {:?}", s.log);
                Ok(())
            },
        )
        .unwrap();
    println!(
        "{cases} sessions, {} bad frames answered or dropped, slowest {:?}",
        frames_bad.get(),
        worst.get()
    );
}
