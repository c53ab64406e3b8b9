//! `docs/tutorial.md` runs as written: its files are written (each block marked
//! ```` ```LANG file=NAME ```` replaces `NAME`), its commands (`$ tactus …` lines of the
//! ```` ```console ```` blocks) run in order in a fresh directory, and each command's
//! output (stdout and stderr, as a terminal shows them) must match the lines shown under it.
//! A line `…` stands for any lines, a `…` within a line for any text (timings, memory).
//! Its plots (`![…](img/NAME.svg)`) must be the SVGs its commands write, and its last
//! `clavichord.tactus` the one every engine's equivalence suite runs
//! (`instruments/examples/clavichord.tactus`). `TACTUS_BLESS=1` writes the outputs that no
//! longer match (in full: put the `…` back where a line varies) and the plots into the
//! document.

mod common;

use std::path::Path;

/// A block of the document: a file to write, or commands with their outputs.
#[derive(Debug)]
enum Block {
    File {
        name: String,
        text: String,
    },
    Console {
        /// (command, the output lines shown under it)
        commands: Vec<(String, Vec<String>)>,
        /// The lines of the document the block's body spans.
        lines: std::ops::Range<usize>,
    },
}

fn blocks(doc: &str) -> Vec<Block> {
    let lines: Vec<&str> = doc.lines().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        let Some(info) = lines[i].strip_prefix("```") else {
            i += 1;
            continue;
        };
        let start = i + 1;
        let end = start
            + lines[start..]
                .iter()
                .position(|l| l.starts_with("```"))
                .expect("an unclosed code block");
        let body = &lines[start..end];
        let mut words = info.split_whitespace();
        let lang = words.next().unwrap_or("");
        let file = words.find_map(|w| w.strip_prefix("file="));
        if let Some(name) = file {
            out.push(Block::File {
                name: name.to_string(),
                text: body.iter().map(|l| format!("{l}\n")).collect(),
            });
        } else if lang == "console" {
            let mut commands: Vec<(String, Vec<String>)> = Vec::new();
            for l in body {
                match l.strip_prefix("$ ") {
                    Some(cmd) => commands.push((cmd.to_string(), Vec::new())),
                    None => commands
                        .last_mut()
                        .expect("output before a command")
                        .1
                        .push(l.to_string()),
                }
            }
            out.push(Block::Console {
                commands,
                lines: start..end,
            });
        }
        i = end + 1;
    }
    out
}

/// Whether `line` matches `pattern`, where `…` stands for any text.
fn line_matches(pattern: &str, line: &str) -> bool {
    let parts: Vec<&str> = pattern.split('…').collect();
    if parts.len() == 1 {
        return pattern.trim_end() == line.trim_end();
    }
    let line = line.trim_end();
    let (first, last) = (parts[0], parts[parts.len() - 1].trim_end());
    if !line.starts_with(first) || !line[first.len()..].ends_with(last) {
        return false;
    }
    let mut rest = &line[first.len()..line.len() - last.len()];
    for p in &parts[1..parts.len() - 1] {
        match rest.find(p) {
            Some(i) => rest = &rest[i + p.len()..],
            None => return false,
        }
    }
    true
}

/// Whether `lines` match `expected`, where a line `…` stands for any lines.
fn matches(expected: &[String], lines: &[&str]) -> bool {
    match expected.first() {
        None => lines.is_empty(),
        Some(e) if e.trim() == "…" => {
            (0..=lines.len()).any(|k| matches(&expected[1..], &lines[k..]))
        }
        Some(e) => {
            !lines.is_empty() && line_matches(e, lines[0]) && matches(&expected[1..], &lines[1..])
        }
    }
}

fn run(dir: &Path, cmd: &str) -> (bool, String) {
    let rest = cmd
        .strip_prefix("tactus ")
        .unwrap_or_else(|| panic!("a command that is not `tactus …`: {cmd}"));
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg(format!("exec \"$0\" {rest} 2>&1"))
        .arg(env!("CARGO_BIN_EXE_tactus"))
        .current_dir(dir)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

#[test]
fn the_tutorial_runs_as_written() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc_path = root.join("docs/tutorial.md");
    let doc = std::fs::read_to_string(&doc_path).unwrap();
    let bless = std::env::var_os("TACTUS_BLESS").is_some();
    let dir = common::temp_dir("tutorial");
    let mut doc_lines: Vec<String> = doc.lines().map(String::from).collect();
    // Blessed blocks, replaced from the last so that earlier line numbers hold.
    let mut blessed: Vec<(std::ops::Range<usize>, Vec<String>)> = Vec::new();
    let mut stale = Vec::new();
    let mut last: LastText = LastText::default();
    let all = blocks(&doc);
    assert!(
        all.iter()
            .filter(|b| matches!(b, Block::Console { .. }))
            .count()
            >= 6
    );
    for block in &all {
        match block {
            Block::File { name, text } => {
                std::fs::write(dir.join(name), text).unwrap();
                last.set(name, text);
            }
            Block::Console { commands, lines } => {
                let mut body = Vec::new();
                let mut block_ok = true;
                for (cmd, expected) in commands {
                    let (ok, output) = run(&dir, cmd);
                    let got: Vec<&str> = output.lines().collect();
                    let wants_error = expected.iter().any(|l| l.starts_with("error"));
                    let fits = matches(expected, &got) && ok != wants_error;
                    body.push(format!("$ {cmd}"));
                    if fits {
                        body.extend(expected.iter().cloned());
                    } else {
                        block_ok = false;
                        body.extend(got.iter().map(|l| l.trim_end().to_string()));
                        stale.push(format!(
                            "`{cmd}` (exit {}) printed:\n{output}\nthe tutorial shows:\n{}",
                            if ok { "0" } else { "≠ 0" },
                            expected.join("\n")
                        ));
                    }
                }
                if !block_ok {
                    blessed.push((lines.clone(), body));
                }
            }
        }
    }
    // The plots shown are the ones the commands wrote.
    let mut plots = Vec::new();
    for part in doc.split("](img/").skip(1) {
        let name = &part[..part.find(')').unwrap()];
        let written = dir.join("out").join(name);
        let shown = root.join("docs/img").join(name);
        let a = std::fs::read(&written).unwrap_or_else(|e| panic!("{}: {e}", written.display()));
        if std::fs::read(&shown).ok().as_deref() != Some(&a[..]) {
            stale.push(format!(
                "docs/img/{name} is not the plot the tutorial's command writes"
            ));
            plots.push((written, shown));
        }
    }
    if bless && !stale.is_empty() {
        for (range, body) in blessed.into_iter().rev() {
            doc_lines.splice(range, body);
        }
        std::fs::write(&doc_path, doc_lines.join("\n") + "\n").unwrap();
        for (from, to) in plots {
            std::fs::copy(from, to).unwrap();
        }
    }
    assert!(
        stale.is_empty(),
        "docs/tutorial.md is stale (TACTUS_BLESS=1 rewrites it):\n{}",
        stale.join("\n---\n")
    );
    // Its instrument, as it ends, is the one the equivalence suites run.
    let example = root.join("instruments/examples/clavichord.tactus");
    assert_eq!(
        last.get("clavichord.tactus"),
        std::fs::read_to_string(&example).ok(),
        "the tutorial's last clavichord.tactus differs from {}",
        example.display()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The last text written to each file of the tutorial.
#[derive(Default)]
struct LastText(Vec<(String, String)>);

impl LastText {
    fn set(&mut self, name: &str, text: &str) {
        self.0.retain(|(n, _)| n != name);
        self.0.push((name.to_string(), text.to_string()));
    }
    fn get(&self, name: &str) -> Option<String> {
        self.0
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, t)| t.clone())
    }
}

#[test]
fn patterns() {
    assert!(line_matches("a … b", "a 12 s b"));
    assert!(!line_matches("a … b", "a 12 s c"));
    assert!(line_matches("x", "x  "));
    let e: Vec<String> = ["one", "…", "four"].iter().map(|s| s.to_string()).collect();
    assert!(matches(&e, &["one", "two", "three", "four"]));
    assert!(matches(&e, &["one", "four"]));
    assert!(!matches(&e, &["one", "two"]));
}
