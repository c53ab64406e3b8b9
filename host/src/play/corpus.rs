//! Corpus mode of `tactus play`: the performances of a list or a directory, each played in
//! turn, summarised one row per piece in one table — CSV for a spreadsheet, JSON for a
//! script — so that a firmware change is validated over many performances at once.
//!
//! A piece that cannot be played (an unreadable or malformed MIDI file, no note on the
//! layout, …) is a row with its error, not the end of the run.
//!
//! The same rows come back from a cluster's shards (`crate::play::results`, one JSON line
//! each) and are merged into these same tables (`crate::corpus_merge`): the tables are
//! written by one function ([`write_tables`]) and judged by one ([`verdict`]) either way.

use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Most files a corpus may hold: a bound on what a directory or a list can make the run
/// loop over (each piece is a whole emulated performance).
pub const MAX_PIECES: usize = 10_000;

/// One piece of a corpus run: what was played and how.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PieceRow {
    /// The MIDI file.
    pub file: PathBuf,
    /// The keyboard it was played on: the layout's name, or `INSTRUMENT × N`.
    pub keyboard: String,
    /// The board kind's name.
    pub board: String,
    /// Music played, seconds (after `--seconds`).
    pub music_s: f64,
    /// Notes on the layout's keys.
    pub notes: usize,
    /// Strikes (or plucks) the instruments emitted.
    pub strikes: usize,
    /// Strikes that answer a note within 50 ms.
    pub answering: usize,
    /// Notes no strike answers.
    pub silent: usize,
    /// Per board of the keyboard, in key order: deadline misses summed over its cores
    /// (`--engine emu`; empty on a host engine).
    pub misses_per_board: Vec<u64>,
    /// Most cycles any core of any board took for one sample (`--engine emu`), and the
    /// deadline in cycles per sample; `None` on a host engine.
    pub worst_core_cycles: Option<u64>,
    /// Cycles per sample per core available (`--engine emu`).
    pub deadline_cycles: Option<u64>,
    /// Trips of the firmware's fault checks over every core of every board
    /// (`--engine emu`: the fault words' counts, `crate::fault`); `None` on a host engine
    /// or in rows written before the count was kept.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fault_trips: Option<u64>,
    /// Faults injected (`--fault`): with none, a trip is a false alarm.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub faults_injected: usize,
    /// Wall-clock seconds of the run.
    pub wall_s: f64,
    /// Real-time factor: music seconds per wall second.
    pub rtf: f64,
    /// Why the piece was not played (then the figures above are zero).
    pub error: Option<String>,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// What a corpus's rows say of the firmware, and the exit status that tells it
/// ([`Verdict::exit_code`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Every piece played without a deadline miss, every note struck: exit 0.
    Passed,
    /// The firmware failed validation: some piece missed a deadline or left a note without
    /// a strike (whatever else happened): exit 1. The message counts them.
    Failed(String),
    /// No piece failed, but some could not be played (an unreadable file, no note on the
    /// keyboard, …), or some expected item has no row: the run could not be done; exit 2.
    Incomplete(String),
}

impl Verdict {
    /// 0, 1 or 2, as the variants say.
    pub fn exit_code(&self) -> u8 {
        match self {
            Verdict::Passed => 0,
            Verdict::Failed(_) => 1,
            Verdict::Incomplete(_) => 2,
        }
    }

    /// The message, if the verdict is not a pass.
    pub fn message(&self) -> Option<&str> {
        match self {
            Verdict::Passed => None,
            Verdict::Failed(m) | Verdict::Incomplete(m) => Some(m),
        }
    }
}

/// The verdict on `rows`: [`Verdict::Failed`] when a row missed a deadline, left notes
/// without a strike or tripped a fault check with no fault injected (a false alarm), else [`Verdict::Incomplete`] when a row has an error, else
/// [`Verdict::Passed`].
pub fn verdict(rows: &[PieceRow]) -> Verdict {
    let missed = rows
        .iter()
        .filter(|r| r.misses_per_board.iter().any(|&m| m > 0))
        .count();
    let silent = rows.iter().filter(|r| r.silent > 0).count();
    let alarms = (rows.iter())
        .filter(|r| r.faults_injected == 0 && r.fault_trips.is_some_and(|t| t > 0))
        .count();
    let errors = rows.iter().filter(|r| r.error.is_some()).count();
    let n = rows.len();
    let also = match errors {
        0 => String::new(),
        e => format!("; {e} could not be played"),
    };
    if missed + silent + alarms > 0 {
        let alarms = match alarms {
            0 => String::new(),
            a => format!(", {a} tripped fault checks with no fault injected"),
        };
        return Verdict::Failed(format!(
            "the firmware failed validation: {missed} of {n} performances missed deadlines, {silent} left notes without a strike{alarms}{also} (see the table)"
        ));
    }
    match errors {
        0 => Verdict::Passed,
        e => Verdict::Incomplete(format!(
            "{e} of {n} performances could not be played (see the table's errors)"
        )),
    }
}

impl PieceRow {
    /// A row for a piece that could not be played.
    pub fn failed(file: &Path, error: String) -> PieceRow {
        PieceRow {
            file: file.to_path_buf(),
            error: Some(error),
            ..PieceRow::default()
        }
    }
}

/// The files of a corpus: each argument a MIDI file, or a directory whose `*.mid` and
/// `*.midi` files (sorted by name, not recursing) are taken.
///
/// Errors: a directory that cannot be read (naming it), or more than [`MAX_PIECES`] files.
/// A file that does not exist is kept: playing it fails, and its row says so.
pub fn expand(args: &[PathBuf]) -> Result<Vec<PathBuf>, String> {
    let mut files = Vec::new();
    for a in args {
        if a.is_dir() {
            let entries =
                std::fs::read_dir(a).map_err(|e| format!("cannot read `{}`: {e}", a.display()))?;
            let mut mids: Vec<PathBuf> = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.is_file()
                        && p.extension().is_some_and(|x| {
                            x.eq_ignore_ascii_case("mid") || x.eq_ignore_ascii_case("midi")
                        })
                })
                .take(MAX_PIECES + 1)
                .collect();
            mids.sort();
            if mids.is_empty() {
                return Err(format!(
                    "`{}` holds no MIDI file (*.mid, *.midi)",
                    a.display()
                ));
            }
            files.extend(mids);
        } else {
            files.push(a.clone());
        }
        if files.len() > MAX_PIECES {
            return Err(format!(
                "a corpus holds at most {MAX_PIECES} performances; these arguments name more"
            ));
        }
    }
    Ok(files)
}

/// What `tactus play` prints after a corpus: a line naming how many performances and on
/// what (`emulated`: the firmware of every board; else a host engine, no deadlines), the
/// [`table_text`], and the run's peak memory `peak_kb` (kB) when known
/// (`crate::session::peak_memory_kb`).
pub fn summary_text(rows: &[PieceRow], emulated: bool, peak_kb: Option<u64>) -> String {
    let mut t = format!(
        "corpus: {} performances ({})\n",
        rows.len(),
        match emulated {
            true => "the firmware of every board, emulated",
            false => "host engine; no deadlines checked",
        }
    );
    t.push_str(&table_text(rows));
    if let Some(kb) = peak_kb {
        t.push_str(&format!(
            "  peak memory of the run: {:.1} MB\n",
            kb as f64 / 1024.0
        ));
    }
    t
}

/// The summary table as text, one line per piece after a header line, each indented two
/// spaces: piece (file name), music s, notes, strikes, silent notes, misses (all boards),
/// worst core cycles / deadline (`—` on a host engine), fault trips (all boards; `—` on a
/// host engine), RTF, error.
pub fn table_text(rows: &[PieceRow]) -> String {
    use std::fmt::Write;
    // Several keyboards or boards: each piece named with the one it was played on.
    let on = |r: &PieceRow| format!("{} on {}", r.keyboard, r.board);
    let several = rows
        .iter()
        .any(|r| on(r) != rows.first().map(on).unwrap_or_default());
    let mut t = format!(
        "  {:<32} {:>8} {:>6} {:>7} {:>7} {:>7} {:>12} {:>6} {:>6}  error\n",
        "piece", "music s", "notes", "strikes", "silent", "misses", "worst cycles", "trips", "RTF"
    );
    for r in rows {
        let mut name = r.file.file_name().map_or_else(
            || r.file.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        );
        if several {
            name = format!("{name} ({})", on(r));
        }
        // Writing to a String cannot fail.
        let _ = writeln!(
            t,
            "  {:<32} {:>8.1} {:>6} {:>7} {:>7} {:>7} {:>12} {:>6} {:>6.2}  {}",
            name,
            r.music_s,
            r.notes,
            r.strikes,
            r.silent,
            r.misses_per_board.iter().sum::<u64>(),
            r.worst_core_cycles.map_or("—".to_string(), |c| format!(
                "{c}/{}",
                r.deadline_cycles.unwrap_or(0)
            )),
            r.fault_trips.map_or("—".to_string(), |t| t.to_string()),
            r.rtf,
            r.error.as_deref().unwrap_or("")
        );
    }
    t
}

/// Writes the rows as CSV (header first; `misses_per_board` as `;`-separated counts).
///
/// Errors: the file cannot be written (naming it).
pub fn write_csv(path: &Path, rows: &[PieceRow]) -> Result<(), String> {
    let mut s = String::from(
        "file,keyboard,board,music_s,notes,strikes,answering,silent,misses_per_board,misses,worst_core_cycles,deadline_cycles,fault_trips,wall_s,rtf,error\n",
    );
    for r in rows {
        let misses: Vec<String> = r.misses_per_board.iter().map(u64::to_string).collect();
        let opt = |v: Option<u64>| v.map_or(String::new(), |v| v.to_string());
        s.push_str(&format!(
            "{},{},{},{:.3},{},{},{},{},{},{},{},{},{},{:.3},{:.3},{}\n",
            csv_field(&r.file.display().to_string()),
            csv_field(&r.keyboard),
            csv_field(&r.board),
            r.music_s,
            r.notes,
            r.strikes,
            r.answering,
            r.silent,
            misses.join(";"),
            r.misses_per_board.iter().sum::<u64>(),
            opt(r.worst_core_cycles),
            opt(r.deadline_cycles),
            opt(r.fault_trips),
            r.wall_s,
            r.rtf,
            csv_field(r.error.as_deref().unwrap_or("")),
        ));
    }
    write(path, s.as_bytes())
}

/// Writes the rows as one JSON array of objects (the fields of [`PieceRow`]).
///
/// Errors: the file cannot be written (naming it).
pub fn write_json(path: &Path, rows: &[PieceRow]) -> Result<(), String> {
    let text = serde_json::to_string_pretty(rows).map_err(|e| e.to_string())?;
    write(path, text.as_bytes())
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), String> {
    write_atomic(path, bytes).map_err(|e| format!("cannot write `{}`: {e}", path.display()))
}

/// Writes `bytes` to `path` atomically: into a temporary file beside it (`.NAME.tmp-PID`),
/// flushed to the disk, then renamed over `path` — a process killed at any moment leaves
/// the old file or the new one whole, never a part.
///
/// Errors: the temporary file cannot be written or renamed (it is removed).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let name = path
        .file_name()
        .map_or_else(|| "out".to_string(), |n| n.to_string_lossy().into_owned());
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let written = std::fs::File::create(&tmp).and_then(|mut f| {
        f.write_all(bytes)?;
        f.sync_all()
    });
    match written.and_then(|()| std::fs::rename(&tmp, path)) {
        Ok(()) => Ok(()),
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// A CSV field, quoted when it holds a comma, a quote or a line break (RFC 4180).
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// Writes `DIR/corpus.csv` ([`write_csv`]) and `DIR/corpus.json` ([`write_json`]),
/// creating `dir`; returns their paths.
///
/// Errors: a message naming the directory or file that cannot be written.
pub fn write_tables(dir: &Path, rows: &[PieceRow]) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("cannot create `{}`: {e}", dir.display()))?;
    let (csv, json) = (dir.join("corpus.csv"), dir.join("corpus.json"));
    write_csv(&csv, rows)?;
    write_json(&json, rows)?;
    Ok(vec![csv, json])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_field_with_a_comma_or_a_quote_is_quoted() {
        assert_eq!(csv_field("a.mid"), "a.mid");
        assert_eq!(csv_field("bad, \"file\""), "\"bad, \"\"file\"\"\"");
    }

    #[test]
    fn a_directory_gives_its_midi_files_sorted_and_a_missing_file_is_kept() {
        let dir = std::env::temp_dir().join(format!("tactus-corpus-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for f in ["b.mid", "a.MID", "notes.txt"] {
            std::fs::write(dir.join(f), b"").unwrap();
        }
        let files = expand(&[dir.clone(), PathBuf::from("/nonexistent/x.mid")]).unwrap();
        assert_eq!(
            files,
            vec![
                dir.join("a.MID"),
                dir.join("b.mid"),
                PathBuf::from("/nonexistent/x.mid")
            ]
        );
        let empty = dir.join("empty");
        std::fs::create_dir_all(&empty).unwrap();
        assert!(expand(&[empty]).unwrap_err().contains("no MIDI file"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
