//! Drives `tactus_lsp::serve` in process: frames in, frames and log lines out.
#![allow(dead_code)]

use serde_json::Value;
use std::io::Write;
use std::sync::{Arc, Mutex};

/// One message with its `Content-Length` header.
pub fn frame(body: &str) -> Vec<u8> {
    let mut v = format!("Content-Length: {}\r\n\r\n", body.len()).into_bytes();
    v.extend(body.as_bytes());
    v
}

#[derive(Clone, Default)]
pub struct Sink(pub Arc<Mutex<Vec<u8>>>);

impl Write for Sink {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// What a session wrote.
pub struct Session {
    pub outcome: tactus_lsp::Outcome,
    pub messages: Vec<Value>,
    pub log: Vec<String>,
}

impl Session {
    pub fn response(&self, id: u64) -> &Value {
        self.messages
            .iter()
            .find(|m| m["id"] == id && (m.get("result").is_some() || m.get("error").is_some()))
            .unwrap_or_else(|| panic!("no response {id} in {:#?}", self.messages))
    }
    pub fn result(&self, id: u64) -> Value {
        self.response(id)["result"].clone()
    }
    pub fn error(&self, id: u64) -> Value {
        self.response(id)["error"].clone()
    }
    pub fn notifications(&self, method: &str) -> Vec<Value> {
        self.messages
            .iter()
            .filter(|m| m["method"] == method)
            .map(|m| m["params"].clone())
            .collect()
    }
}

/// Splits the server's output into JSON values (every frame it writes must be one).
pub fn parse_frames(mut out: &[u8]) -> Vec<Value> {
    let mut v = Vec::new();
    while !out.is_empty() {
        let head_end = out
            .windows(4)
            .position(|w| w == b"\r\n\r\n")
            .expect("a header ends with a blank line");
        let head = std::str::from_utf8(&out[..head_end]).unwrap();
        let n: usize = head
            .strip_prefix("Content-Length: ")
            .expect("Content-Length")
            .parse()
            .unwrap();
        let body = &out[head_end + 4..head_end + 4 + n];
        v.push(serde_json::from_slice(body).expect("the server writes JSON"));
        out = &out[head_end + 4 + n..];
    }
    v
}

/// Runs a whole session on `input` (it must end, with `exit` or not).
pub fn run_session(input: Vec<u8>) -> Session {
    run_session_with(input, &tactus_lsp::Config::default())
}

/// [`run_session`] with a configuration.
pub fn run_session_with(input: Vec<u8>, config: &tactus_lsp::Config) -> Session {
    let sink = Sink::default();
    let mut log = Vec::new();
    let outcome = tactus_lsp::serve(
        std::io::BufReader::new(std::io::Cursor::new(input)),
        sink.clone(),
        config,
        &mut |l| log.push(l.to_string()),
    );
    let out = sink.0.lock().unwrap().clone();
    Session {
        outcome,
        messages: parse_frames(&out),
        log,
    }
}
