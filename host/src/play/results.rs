//! A corpus run's results as a cluster's engine gathers them: one file per shard
//! (`OUT/results.jsonl`, or `OUT/results-K-of-N.jsonl` for shard K of N), JSON lines.
//!
//! The first line is the [`Header`]: the shard, and the [`Manifest`] — what every shard of
//! one run must share for their rows to belong in one table (the Tactus version, the options
//! that change results, per keyboard the SHA3-256 of its layout, board file, instrument
//! sources and compiled firmware, and the whole corpus's items in order). Each further line
//! is one item done ([`ItemLine`]: its key and its row of the corpus table).
//!
//! The file is rewritten whole after each item, into a temporary file renamed over it
//! ([`crate::play::corpus::write_atomic`]): a task killed at any moment leaves the file as
//! it was after its last item, never half a line, and `--resume` ([`ResultsFile::resume`])
//! goes on from there. An item is minutes of emulation; rewriting a file of a few hundred
//! bytes per item done costs nothing beside it.

use super::corpus::{write_atomic, PieceRow};
use super::shard::{ItemKey, Setup, Shard};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The largest results file read (a line per item: a corpus of [`super::corpus::MAX_PIECES`]
/// pieces on a few keyboards is a few MB).
pub const MAX_RESULTS_BYTES: u64 = 256 << 20;

/// The options of a run that change its results: shards that differ in them are not one
/// run. (`--emu`, `--no-rest-replay`, `--no-wav`, traces and the output directory change
/// no figure of the table and are left out.)
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunOptions {
    /// The engine (`emu`, `fixed`, `jit`, `interp`).
    pub engine: String,
    /// The player (`position`, `force`).
    pub player: String,
    /// `--seconds`: the first seconds played, or the whole piece.
    pub seconds: Option<f64>,
    /// `--param` overrides, in order.
    pub params: Vec<(String, String)>,
    /// Whether the firmware guards quiescent keys (the same strikes, other cycles).
    pub quiescent_guard: bool,
    /// `--sensor-check`: the firmware's sensor check forced on or off (other cycles and
    /// boards, the fault words); `None`: the programs' default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor_check: Option<bool>,
    /// `--watchdog`: the firmware's watchdog forced on or off (other cycles and boards, the
    /// resets of a hung core); `None`: the programs' default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub watchdog: Option<bool>,
}

/// A source's name and the SHA3-256 of its text, hex.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SourceHash {
    /// `builtin:NAME` or the file as given.
    pub name: String,
    /// SHA3-256 of its bytes, lowercase hex.
    pub sha3: String,
}

/// One keyboard on one board kind of a run, as compiled.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct KeyboardManifest {
    /// The keyboard and board as the command line names them.
    #[serde(flatten)]
    pub on: Setup,
    /// The keyboard's name (the layout's, or `INSTRUMENT × N`).
    pub name: String,
    /// The layout's text, hashed (none for one instrument).
    pub layout_sha3: Option<SourceHash>,
    /// The board file's text, hashed (a built-in board's too).
    pub board_sha3: SourceHash,
    /// Every instrument source the keyboard compiles, hashed, in order of first key.
    pub instruments: Vec<SourceHash>,
    /// The firmware's programs (each distinct program's Thumb code and param block, in
    /// order), hashed; `None` for a host engine that runs none, or the reason it does not
    /// compile.
    pub firmware_sha3: Option<Result<String, String>>,
}

/// What the shards of one run share; see the module documentation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// The Tactus version that wrote it.
    pub tactus: String,
    /// The options that change results.
    pub options: RunOptions,
    /// The keyboards × boards, in the order items use them.
    pub keyboards: Vec<KeyboardManifest>,
    /// Every item of the corpus (every shard's), in the order of the table.
    pub items: Vec<ItemKey>,
}

/// The first line of a results file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// Which shard wrote the file.
    pub shard: Shard,
    /// What the run was.
    pub manifest: Manifest,
}

/// One item done: a line of a results file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ItemLine {
    /// Which item.
    pub key: ItemKey,
    /// Its row of the corpus table.
    pub row: PieceRow,
}

/// Why a results file cannot be read or written. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum ResultsError {
    /// The file cannot be read (or is over [`MAX_RESULTS_BYTES`], or not UTF-8).
    #[error(transparent)]
    Read(#[from] tactus_runtime::files::ReadError),
    /// The file (or its directory) cannot be written.
    #[error("`{path}`: {message}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
    /// A line is not what a results file holds.
    #[error("`{path}` line {line}: {message}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// The line, from 1.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// `--resume` on a file another run wrote.
    #[error("`{path}` holds the results of another run ({difference}): run without --resume to start over, or give another --out")]
    OtherRun {
        /// The file.
        path: PathBuf,
        /// The first difference ([`difference`]).
        difference: String,
    },
}

/// The SHA3-256 of `bytes`, lowercase hex.
pub fn sha3_hex(bytes: &[u8]) -> String {
    use sha3::{Digest, Sha3_256};
    Sha3_256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The first place two JSON values differ, as `path: a ≠ b` (long values shortened), or
/// `None` when they are equal.
pub fn difference(a: &serde_json::Value, b: &serde_json::Value) -> Option<String> {
    use serde_json::Value;
    fn walk(a: &Value, b: &Value, path: &str) -> Option<String> {
        match (a, b) {
            (Value::Object(x), Value::Object(y)) => {
                let keys: std::collections::BTreeSet<&String> = x.keys().chain(y.keys()).collect();
                keys.into_iter().find_map(|k| {
                    let p = format!("{path}.{k}");
                    match (x.get(k), y.get(k)) {
                        (Some(u), Some(v)) => walk(u, v, &p),
                        (u, v) => Some(format!(
                            "{p}: {} ≠ {}",
                            show(u.unwrap_or(&Value::Null)),
                            show(v.unwrap_or(&Value::Null))
                        )),
                    }
                })
            }
            (Value::Array(x), Value::Array(y)) => {
                let found = (x.iter().zip(y))
                    .enumerate()
                    .find_map(|(i, (u, v))| walk(u, v, &format!("{path}[{i}]")));
                found.or_else(|| {
                    (x.len() != y.len())
                        .then(|| format!("{path}: {} ≠ {} entries", x.len(), y.len()))
                })
            }
            _ => (a != b).then(|| format!("{path}: {} ≠ {}", show(a), show(b))),
        }
    }
    fn show(v: &Value) -> String {
        let s = v.to_string();
        match s.chars().count() > 60 {
            true => format!("{}…", s.chars().take(60).collect::<String>()),
            false => s,
        }
    }
    walk(a, b, "manifest")
}

/// Reads a results file: its header and its item lines.
///
/// Errors: [`ResultsError::Read`] when it cannot be read, is over [`MAX_RESULTS_BYTES`] or
/// is not UTF-8; [`ResultsError::Malformed`] for an empty file, a first line that is no header, a line
/// that is no item, or an item twice.
pub fn read(path: &Path) -> Result<(Header, Vec<ItemLine>), ResultsError> {
    let text = tactus_runtime::files::read_text_bounded(path, MAX_RESULTS_BYTES, "a results file")?;
    let bad = |line: usize, message: String| ResultsError::Malformed {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let Some((_, first)) = lines.next() else {
        return Err(bad(1, "empty: no header line".into()));
    };
    let header: Header = serde_json::from_str(first).map_err(|e| {
        bad(
            1,
            format!("not a results header ({{\"shard\", \"manifest\"}}): {e}"),
        )
    })?;
    let mut items: Vec<ItemLine> = Vec::new();
    let mut seen = std::collections::BTreeMap::new();
    for (i, l) in lines {
        let item: ItemLine = serde_json::from_str(l).map_err(|e| {
            bad(
                i + 1,
                format!("not an item line ({{\"key\", \"row\"}}): {e}"),
            )
        })?;
        if let Some(first) = seen.insert(item.key.clone(), i + 1) {
            return Err(bad(
                i + 1,
                format!("item {} again (first on line {first})", item.key),
            ));
        }
        items.push(item);
    }
    Ok((header, items))
}

/// A shard's results file being written: its header and the items done so far.
#[derive(Debug)]
pub struct ResultsFile {
    /// The file.
    pub path: PathBuf,
    /// Its first line.
    pub header: Header,
    /// The items done, in the order they were done.
    pub items: Vec<ItemLine>,
}

impl ResultsFile {
    /// Starts the results of `header`'s shard in `dir` (created), replacing a file of a
    /// former run: the header alone, written at once (so a task killed before its first
    /// item leaves a file that says so).
    ///
    /// Errors: [`ResultsError::Io`] when the directory or the file cannot be written.
    pub fn create(dir: &Path, header: Header) -> Result<ResultsFile, ResultsError> {
        let file = ResultsFile {
            path: dir.join(header.shard.results_file()),
            header,
            items: Vec::new(),
        };
        std::fs::create_dir_all(dir).map_err(|e| ResultsError::Io {
            path: dir.to_path_buf(),
            message: e.to_string(),
        })?;
        file.write()?;
        Ok(file)
    }

    /// Goes on with the results of `header`'s shard in `dir`: the items its file holds are
    /// done. No file yet: [`ResultsFile::create`].
    ///
    /// Errors: what [`read`] refuses; [`ResultsError::OtherRun`] when the file's header is
    /// not `header` (another shard, another manifest: the first difference named);
    /// [`ResultsError::Malformed`] for an item that is not this shard's.
    pub fn resume(dir: &Path, header: Header) -> Result<ResultsFile, ResultsError> {
        let path = dir.join(header.shard.results_file());
        if !path.exists() {
            return ResultsFile::create(dir, header);
        }
        let (found, items) = read(&path)?;
        if found != header {
            let json = |h: &Header| serde_json::to_value(h).unwrap_or_default();
            let difference = difference(&json(&found), &json(&header))
                .unwrap_or_else(|| "a header that reads differently".into())
                .replacen("manifest", "header", 1);
            return Err(ResultsError::OtherRun { path, difference });
        }
        let listed: std::collections::BTreeSet<&ItemKey> = header.manifest.items.iter().collect();
        if let Some(stray) = items
            .iter()
            .find(|i| !listed.contains(&i.key) || !header.shard.holds(&i.key))
        {
            return Err(ResultsError::Malformed {
                path,
                line: 0,
                message: format!("item {} is not one of shard {}'s", stray.key, header.shard),
            });
        }
        Ok(ResultsFile {
            path,
            header,
            items,
        })
    }

    /// Whether `key` is done.
    pub fn done(&self, key: &ItemKey) -> bool {
        self.items.iter().any(|i| &i.key == key)
    }

    /// Adds an item done and rewrites the file atomically.
    ///
    /// Errors: [`ResultsError::Io`] when the file cannot be written (the item is kept in
    /// memory all the same).
    pub fn push(&mut self, line: ItemLine) -> Result<(), ResultsError> {
        self.items.push(line);
        self.write()
    }

    /// The file's text: the header, then each item, a line each.
    pub fn text(&self) -> String {
        let mut s = serde_json::to_string(&self.header).unwrap_or_default();
        s.push('\n');
        for i in &self.items {
            s.push_str(&serde_json::to_string(i).unwrap_or_default());
            s.push('\n');
        }
        s
    }

    fn write(&self) -> Result<(), ResultsError> {
        write_atomic(&self.path, self.text().as_bytes()).map_err(|e| ResultsError::Io {
            path: self.path.clone(),
            message: format!("cannot write: {e}"),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(shard: Shard, seconds: Option<f64>) -> Header {
        Header {
            shard,
            manifest: Manifest {
                tactus: "0.1.0".into(),
                options: RunOptions {
                    engine: "emu".into(),
                    player: "position".into(),
                    seconds,
                    params: vec![],
                    quiescent_guard: true,
                    sensor_check: None,
                    watchdog: None,
                },
                keyboards: vec![],
                items: (0..6)
                    .map(|i| ItemKey {
                        piece: format!("p{i}.mid"),
                        on: Setup::default(),
                    })
                    .collect(),
            },
        }
    }

    /// Lines go in and come back whole, figures exactly (f64s round-trip); a resumed file
    /// keeps its items; another run's file is refused naming the difference.
    #[test]
    fn a_file_is_written_whole_and_resumed() {
        let dir = std::env::temp_dir().join(format!("tactus-results-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let shard = Shard::new(2, 3).unwrap();
        let h = header(shard, Some(0.1 + 0.2));
        let mut f = ResultsFile::create(&dir, h.clone()).unwrap();
        assert!(f.path.ends_with("results-2-of-3.jsonl"));
        let key = h
            .manifest
            .items
            .iter()
            .find(|k| shard.holds(k))
            .unwrap()
            .clone();
        let row = PieceRow {
            file: key.piece.clone().into(),
            music_s: 1.0 / 3.0,
            rtf: 2.0f64.sqrt(),
            misses_per_board: vec![0, 3],
            worst_core_cycles: Some(2985),
            ..PieceRow::default()
        };
        f.push(ItemLine {
            key: key.clone(),
            row: row.clone(),
        })
        .unwrap();
        let (back, items) = read(&f.path).unwrap();
        assert_eq!(back, h);
        assert_eq!(items[0].row, row);
        let again = ResultsFile::resume(&dir, h.clone()).unwrap();
        assert!(again.done(&key));
        // No temporary file left behind.
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        // Another --seconds: another run.
        let e = ResultsFile::resume(&dir, header(shard, Some(2.0)))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("header.manifest.options.seconds: 0.30000000000000004 ≠ 2.0"),
            "{e}"
        );
        // A half line (what a non-atomic writer killed mid-line would leave) is refused.
        std::fs::write(&f.path, f.text() + "{\"key\": {\"pie").unwrap();
        let e = read(&f.path).unwrap_err().to_string();
        assert!(e.contains("line 3"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn differences_are_named() {
        let a = serde_json::json!({"a": [1, {"b": "x"}], "c": 1});
        let b = serde_json::json!({"a": [1, {"b": "y"}], "c": 1});
        assert_eq!(difference(&a, &a), None);
        assert_eq!(
            difference(&a, &b).unwrap(),
            "manifest.a[1].b: \"x\" ≠ \"y\""
        );
        let c = serde_json::json!({"a": [1], "c": 1});
        assert_eq!(difference(&a, &c).unwrap(), "manifest.a: 2 ≠ 1 entries");
    }
}
