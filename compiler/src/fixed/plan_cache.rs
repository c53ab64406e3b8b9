//! The on-disk cache of the planner's simulated search
//! (`FixedProgram::spend_by_simulation`): the product forms it chose for a program, so that
//! the next process planning the same program (every `tactus play`, `budget` or `build` of a
//! piano) reads them instead of simulating again (≈ 15 CPU-s for the piano in a debug
//! build, ≈ 3 × that for grand88's shared program).
//!
//! **Key.** SHA3-256 of the planner's inputs (the plan configuration and the whole IR
//! program, as printed by `Debug`) and of every source of this crate and of the runtime
//! (`TACTUS_PLANNER_SOURCE_SHA3`, computed by `build.rs`), so a changed compiler never reads
//! an older compiler's choice. The entry is only a memo of a deterministic computation: with
//! or without it the plan is the same.
//!
//! **Where.** `$TACTUS_CACHE_DIR`, else `$XDG_CACHE_HOME/tactus`, else `$HOME/.cache/tactus`,
//! in `plans/`. `TACTUS_CACHE_DIR=off` turns the cache off.
//!
//! **Failures.** None is an error: an unreadable, malformed or mismatched entry is a miss
//! (the search runs and rewrites it); a directory that cannot be written leaves the plan
//! uncached. An entry is written to a temporary file and renamed into place, so processes
//! running at once never read half an entry.

use super::{Cut, MulKind};
use sha3::{Digest, Sha3_256};
use std::path::{Path, PathBuf};

/// First line of an entry: the format's version.
const MAGIC: &str = "tactus-plan-forms 1";

/// The cache directory, or `None` when turned off or when no home is known.
fn dir() -> Option<PathBuf> {
    let base = match std::env::var_os("TACTUS_CACHE_DIR") {
        Some(d) if d == "off" => return None,
        Some(d) if !d.is_empty() => PathBuf::from(d),
        _ => match std::env::var_os("XDG_CACHE_HOME") {
            Some(d) if !d.is_empty() => PathBuf::from(d).join("tactus"),
            _ => PathBuf::from(std::env::var_os("HOME")?).join(".cache/tactus"),
        },
    };
    Some(base.join("plans"))
}

/// The entry's file name for the planner's input `key` (hex SHA3-256, see the module doc).
fn file_name(key: &str) -> String {
    let mut h = Sha3_256::new();
    h.update(env!("TACTUS_PLANNER_SOURCE_SHA3").as_bytes());
    h.update(key.as_bytes());
    let hex: String = h.finalize().iter().map(|b| format!("{b:02x}")).collect();
    format!("{hex}.forms")
}

/// One value's form as a token: `-` (not a product), `m A B`, `t C B K` (32×16: `C` the
/// cut operand, 1 or 2), `h K`, `w`.
fn encode(k: &Option<MulKind>) -> String {
    match k {
        None => "-".into(),
        Some(MulKind::Muls(a, b)) => format!("m {a} {b}"),
        Some(MulKind::Mul32x16 { cut, b, k }) => {
            let c = match cut {
                Cut::First => 1,
                Cut::Second => 2,
            };
            format!("t {c} {b} {k}")
        }
        Some(MulKind::High(k)) => format!("h {k}"),
        Some(MulKind::Wide) => "w".into(),
    }
}

fn decode(line: &str) -> Option<Option<MulKind>> {
    let mut t = line.split(' ');
    let k = match t.next()? {
        "-" => None,
        "m" => Some(MulKind::Muls(
            t.next()?.parse().ok()?,
            t.next()?.parse().ok()?,
        )),
        "t" => {
            let cut = match t.next()? {
                "1" => Cut::First,
                "2" => Cut::Second,
                _ => return None,
            };
            Some(MulKind::Mul32x16 {
                cut,
                b: t.next()?.parse().ok()?,
                k: t.next()?.parse().ok()?,
            })
        }
        "h" => Some(MulKind::High(t.next()?.parse().ok()?)),
        "w" => Some(MulKind::Wide),
        _ => return None,
    };
    t.next().is_none().then_some(k)
}

/// The forms cached for `key`, if an entry exists with one form per value of `like` and a
/// product exactly where `like` has one; otherwise `None`.
pub(crate) fn load(key: &str, like: &[Option<MulKind>]) -> Option<Vec<Option<MulKind>>> {
    load_in(&dir()?, key, like)
}

fn load_in(dir: &Path, key: &str, like: &[Option<MulKind>]) -> Option<Vec<Option<MulKind>>> {
    let text = std::fs::read_to_string(dir.join(file_name(key))).ok()?;
    let mut lines = text.lines();
    if lines.next()? != MAGIC {
        return None;
    }
    let kinds: Vec<Option<MulKind>> = lines.map(decode).collect::<Option<_>>()?;
    let same_shape = kinds.len() == like.len()
        && kinds
            .iter()
            .zip(like)
            .all(|(a, b)| a.is_some() == b.is_some());
    same_shape.then_some(kinds)
}

/// Stores `kinds` for `key`; silently does nothing when the directory cannot be written.
pub(crate) fn store(key: &str, kinds: &[Option<MulKind>]) {
    if let Some(dir) = dir() {
        store_in(&dir, key, kinds);
    }
}

fn store_in(dir: &Path, key: &str, kinds: &[Option<MulKind>]) {
    if std::fs::create_dir_all(dir).is_err() {
        return;
    }
    let mut text = String::from(MAGIC);
    for k in kinds {
        text.push('\n');
        text.push_str(&encode(k));
    }
    let name = file_name(key);
    let tmp = dir.join(format!("{name}.{}.tmp", std::process::id()));
    if std::fs::write(&tmp, text).is_ok() && std::fs::rename(&tmp, dir.join(&name)).is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_form_round_trips_and_garbage_is_a_miss() {
        let kinds = [
            None,
            Some(MulKind::Muls(3, 15)),
            Some(MulKind::High(17)),
            Some(MulKind::Mul32x16 {
                cut: Cut::First,
                b: 16,
                k: 9,
            }),
            Some(MulKind::Mul32x16 {
                cut: Cut::Second,
                b: 0,
                k: 16,
            }),
            Some(MulKind::Wide),
        ];
        for k in &kinds {
            assert_eq!(decode(&encode(k)), Some(*k));
        }
        for bad in [
            "",
            "x",
            "m 1",
            "m 1 2 3",
            "h 300",
            "w 1",
            "t 3 1 1",
            "t 1 1",
            "t 2 1 1 1",
        ] {
            assert_eq!(decode(bad), None, "{bad:?}");
        }
    }

    #[test]
    fn an_entry_is_read_back_only_for_its_key_and_shape() {
        let dir = std::env::temp_dir().join(format!("tactus-plan-cache-{}", std::process::id()));
        let kinds = vec![None, Some(MulKind::High(16)), Some(MulKind::Wide)];
        store_in(&dir, "program A", &kinds);
        assert_eq!(load_in(&dir, "program A", &kinds), Some(kinds.clone()));
        assert_eq!(load_in(&dir, "program B", &kinds), None);
        assert_eq!(load_in(&dir, "program A", &kinds[..2]), None);
        let shifted = vec![Some(MulKind::Wide), None, Some(MulKind::Wide)];
        assert_eq!(load_in(&dir, "program A", &shifted), None);
        std::fs::write(dir.join(file_name("program C")), "junk").unwrap();
        assert_eq!(load_in(&dir, "program C", &kinds), None);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
