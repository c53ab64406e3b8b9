//! The base protocol: `Content-Length` framed JSON-RPC messages over a byte stream.
//!
//! `lsp-server`'s own stdio transport ends the session at the first malformed frame and
//! allocates whatever `Content-Length` says; a language server is fed by editors, plugins
//! and people typing into a pipe, so this one reads frames itself: a header it cannot read
//! is skipped to the next blank line, a body over [`MAX_MESSAGE_BYTES`] is discarded as it
//! arrives, a body that is not a JSON-RPC message is answered with a parse error (JSON-RPC
//! 2.0 §5.1, id `null`). Each is logged to stderr; none ends the session. The end of the
//! input (the client went away) does.

use lsp_server::Message;
use serde_json::Value;
use std::io::{BufRead, Read, Write};

/// The largest message body read, bytes. A 10,000-line profile sent whole is about 400 kB.
pub const MAX_MESSAGE_BYTES: usize = 64 << 20;

/// The longest header line read, bytes.
pub const MAX_HEADER_LINE: usize = 4096;

/// What one read from the stream gave.
#[derive(Debug)]
pub enum Frame {
    /// A message.
    Message(Message),
    /// A frame that could not be read, and why; the stream goes on after it. `reply` is
    /// the answer owed to the client (a JSON-RPC parse error), if any.
    Bad {
        /// What was wrong, for the log.
        why: String,
        /// An error response to send (raw JSON: its id is `null`, which `lsp-server`'s
        /// request ids cannot hold).
        reply: Option<Value>,
    },
    /// The input ended.
    End,
}

/// Reads one header line of at most [`MAX_HEADER_LINE`] bytes (the rest of a longer line is
/// discarded); `None` at the end of input.
fn header_line(inp: &mut dyn BufRead) -> std::io::Result<Option<(String, bool)>> {
    let mut line = Vec::new();
    let n = inp
        .take(MAX_HEADER_LINE as u64)
        .read_until(b'\n', &mut line)?;
    if n == 0 {
        return Ok(None);
    }
    let mut too_long = false;
    if !line.ends_with(b"\n") && n == MAX_HEADER_LINE {
        too_long = true;
        // Skip to the end of the line.
        let mut sink = Vec::new();
        loop {
            sink.clear();
            let m = inp
                .take(MAX_HEADER_LINE as u64)
                .read_until(b'\n', &mut sink)?;
            if m == 0 || sink.ends_with(b"\n") {
                break;
            }
        }
    }
    Ok(Some((
        String::from_utf8_lossy(&line).into_owned(),
        too_long,
    )))
}

/// Reads the next frame. I/O errors of the stream are the end of input.
pub fn read_frame(inp: &mut dyn BufRead) -> Frame {
    let mut length: Option<usize> = None;
    let mut problem: Option<String> = None;
    let mut any = false;
    loop {
        let line = match header_line(inp) {
            Ok(Some(l)) => l,
            Ok(None) | Err(_) => return Frame::End,
        };
        let (text, too_long) = line;
        let text = text.trim_end_matches(['\r', '\n']);
        if too_long {
            problem.get_or_insert(format!("a header line longer than {MAX_HEADER_LINE} bytes"));
            any = true;
            continue;
        }
        if text.is_empty() {
            if any {
                break;
            }
            continue; // blank lines between frames
        }
        any = true;
        match text.split_once(':') {
            Some((name, value)) if name.trim().eq_ignore_ascii_case("Content-Length") => {
                match value.trim().parse::<usize>() {
                    Ok(n) => length = Some(n),
                    Err(_) => {
                        problem.get_or_insert(format!("bad Content-Length `{}`", value.trim()));
                    }
                }
            }
            Some(_) => {} // Content-Type and others
            None => {
                problem.get_or_insert(format!("not a header line: {:?}", truncate(text)));
            }
        }
    }
    let Some(n) = length else {
        return Frame::Bad {
            why: problem.unwrap_or_else(|| "a header without Content-Length".into()),
            reply: None,
        };
    };
    if n > MAX_MESSAGE_BYTES {
        // Discard the body as it arrives; never allocate for it.
        let _ = std::io::copy(&mut inp.take(n as u64), &mut std::io::sink());
        return Frame::Bad {
            why: format!("a message of {n} bytes (at most {MAX_MESSAGE_BYTES}): discarded"),
            reply: Some(parse_error("message too large")),
        };
    }
    let mut body = vec![0; n];
    if inp.read_exact(&mut body).is_err() {
        return Frame::End;
    }
    match serde_json::from_slice::<Message>(&body) {
        Ok(m) => Frame::Message(m),
        Err(e) => Frame::Bad {
            why: format!(
                "not a JSON-RPC message ({e}): {:?}",
                truncate(&String::from_utf8_lossy(&body))
            ),
            reply: Some(parse_error(&e.to_string())),
        },
    }
}

fn truncate(s: &str) -> String {
    s.chars().take(120).collect()
}

/// A JSON-RPC "Parse error" (-32700) response with id `null`.
fn parse_error(message: &str) -> Value {
    serde_json::json!({
        "jsonrpc": "2.0",
        "id": null,
        "error": { "code": -32700, "message": format!("parse error: {message}") },
    })
}

/// Writes one message (any JSON-RPC value) with its header.
pub fn write_message(out: &mut dyn Write, msg: &Value) -> std::io::Result<()> {
    let text = serde_json::to_string(msg).map_err(std::io::Error::other)?;
    write!(out, "Content-Length: {}\r\n\r\n", text.len())?;
    out.write_all(text.as_bytes())?;
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames(input: &[u8]) -> Vec<String> {
        let mut r = std::io::BufReader::new(input);
        let mut out = Vec::new();
        loop {
            match read_frame(&mut r) {
                Frame::End => return out,
                Frame::Message(m) => {
                    out.push(format!("msg {}", serde_json::to_string(&m).unwrap()))
                }
                Frame::Bad { why, reply } => out.push(format!(
                    "bad {} {}",
                    reply.is_some(),
                    why.split(' ').next().unwrap()
                )),
            }
        }
    }

    #[test]
    fn good_bad_and_oversized_frames() {
        let good = r#"{"jsonrpc":"2.0","method":"initialized","params":{}}"#;
        let mut input = format!("Content-Length: {}\r\n\r\n{good}", good.len()).into_bytes();
        input.extend(b"Content-Length: 5\r\n\r\n{{{{{");
        input.extend(b"garbage line\r\n\r\n");
        input.extend(format!("Content-Length: {}\r\n\r\n", MAX_MESSAGE_BYTES + 1).as_bytes());
        input.extend(vec![b'x'; 100]);
        let f = frames(&input);
        assert!(f[0].starts_with("msg "), "{f:?}");
        assert_eq!(f[1], "bad true not");
        assert_eq!(f[2], "bad false not");
        assert_eq!(f[3], "bad true a");
        assert_eq!(f.len(), 4);
    }

    #[test]
    fn parse_errors_have_a_null_id() {
        let r = parse_error("x");
        let v = r;
        assert_eq!(v["id"], serde_json::Value::Null);
        assert_eq!(v["error"]["code"], -32700);
    }
}
