//! Deterministic shards of a corpus run, for a cluster's job array: which items a task
//! plays.
//!
//! An item is one performance on one keyboard (a layout, or one instrument on every key) on
//! one board kind: an [`ItemKey`]. A task of `N` plays the items whose key hashes to its
//! shard `K` ([`Shard::holds`]): SHA3-256 of the key's canonical text ([`ItemKey::canonical`]),
//! its first eight bytes read big-endian, modulo `N`. The hash is a function of the key
//! alone — not of the order of the files listed, nor of how many there are, nor of the Rust
//! version or the platform (unlike `std`'s `DefaultHasher`) — so every task of an array
//! agrees on the assignment without talking to the others, and a file added to the corpus
//! moves no other item (as cargo-nextest's `--partition hash:K/N`, and unlike an
//! assignment by index).
//!
//! `K` counts from 1, as cargo-nextest's `--partition count:K/N` and cargo-mutants'
//! `--shard`'s successor conventions do: `1/2` and `2/2` are the two halves. A scheduler's
//! index is mapped onto it ([`Shard::from_env`]): Slurm's `SLURM_ARRAY_TASK_ID` from
//! `SLURM_ARRAY_TASK_MIN` (an array `--array=0-3` or `--array=1-4` alike gives shards 1/4 to
//! 4/4), Kubernetes' `JOB_COMPLETION_INDEX` (0-based) with the count given on the command
//! line.

use serde::{Deserialize, Serialize};
use sha3::{Digest, Sha3_256};
use std::fmt;
use std::path::Path;

/// Most shards a run may be split into (far beyond Slurm's default `MaxArraySize` of 1,001);
/// a bound on what the merge loops over when it names missing shards.
pub const MAX_SHARDS: u32 = 1 << 20;

/// One shard of `count`: the `index`-th, counting from 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Shard {
    /// Which shard, from 1 to `count`.
    pub index: u32,
    /// How many shards.
    pub count: u32,
}

/// Why a shard cannot be had: a bad `--shard`, or a scheduler's variables that do not
/// describe a dense array. The message names the argument or variable and says what to do.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ShardError(pub String);

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// The whole corpus: shard 1 of 1.
    pub const WHOLE: Shard = Shard { index: 1, count: 1 };

    /// A shard from `index` (from 1) and `count`.
    ///
    /// Errors: `count` 0 or above [`MAX_SHARDS`], `index` 0 or above `count`; each message
    /// shows the form it read as `K/N`.
    pub fn new(index: u32, count: u32) -> Result<Shard, ShardError> {
        let form = format!("{index}/{count}");
        if count == 0 {
            return Err(ShardError(format!(
                "shard {form}: N, the number of shards, must be at least 1"
            )));
        }
        if count > MAX_SHARDS {
            return Err(ShardError(format!(
                "shard {form}: at most {MAX_SHARDS} shards"
            )));
        }
        if index == 0 {
            return Err(ShardError(format!(
                "shard {form}: K counts from 1 (as cargo-nextest's --partition count:K/N): the first of {count} is 1/{count}"
            )));
        }
        if index > count {
            return Err(ShardError(format!(
                "shard {form}: K must be at most N, the number of shards (1/{count} … {count}/{count})"
            )));
        }
        Ok(Shard { index, count })
    }

    /// Reads `K/N` (`--shard 2/4`: the second of four shards).
    ///
    /// Errors: not two whole numbers around a `/` (`a/b`, `2`, `-1/2`), and what
    /// [`Shard::new`] refuses (`0/0`, `0/2`, `3/2`).
    pub fn parse(s: &str) -> Result<Shard, ShardError> {
        let bad = || {
            ShardError(format!(
                "`{s}` is not a shard: expected K/N, two whole numbers with 1 ≤ K ≤ N (2/4: the second of four shards)"
            ))
        };
        let (k, n) = s.trim().split_once('/').ok_or_else(bad)?;
        let number = |t: &str| {
            let t = t.trim();
            match t.chars().all(|c| c.is_ascii_digit()) && !t.is_empty() {
                true => t.parse::<u32>().map_err(|_| bad()),
                false => Err(bad()),
            }
        };
        Shard::new(number(k)?, number(n)?)
    }

    /// The shard a scheduler gives this process through its environment (`var` reads a
    /// variable), with `count` the number of shards from the command line (`--shard-count`):
    ///
    /// * Slurm: `SLURM_ARRAY_TASK_ID` is shard `ID − SLURM_ARRAY_TASK_MIN + 1` (MIN 0 when
    ///   unset) of `count`, else of `SLURM_ARRAY_TASK_COUNT`, else of
    ///   `SLURM_ARRAY_TASK_MAX − MIN + 1`;
    /// * Kubernetes (an Indexed Job): `JOB_COMPLETION_INDEX` is shard `index + 1` of `count`
    ///   (the Job's `completions`), which must then be given.
    ///
    /// Returns the shard and where it came from (the variables, for the run's report), or
    /// `None` when neither scheduler's index is set.
    ///
    /// Errors: a variable that is not a whole number; a Slurm array whose task IDs are not
    /// MIN, MIN + 1, …, MIN + N − 1 (a stepped or sparse `--array=0-8:2`, `--array=1,3,7`:
    /// COUNT and MAX − MIN + 1 disagree) or an ID outside them; `JOB_COMPLETION_INDEX`
    /// without `count`, or not below it; and what [`Shard::new`] refuses.
    pub fn from_env(
        var: &dyn Fn(&str) -> Option<String>,
        count: Option<u32>,
    ) -> Result<Option<(Shard, String)>, ShardError> {
        let number = |name: &str| -> Result<Option<u32>, ShardError> {
            match var(name) {
                None => Ok(None),
                Some(v) => v
                    .trim()
                    .parse::<u32>()
                    .map(Some)
                    .map_err(|_| ShardError(format!("{name}={v:?} is not a whole number"))),
            }
        };
        if let Some(id) = number("SLURM_ARRAY_TASK_ID")? {
            let min = number("SLURM_ARRAY_TASK_MIN")?;
            let (max, tasks) = (
                number("SLURM_ARRAY_TASK_MAX")?,
                number("SLURM_ARRAY_TASK_COUNT")?,
            );
            let from = min.unwrap_or(0);
            let span = max
                .and_then(|m| m.checked_sub(from))
                .map(|d| d.saturating_add(1));
            if let (Some(t), Some(s)) = (tasks, span) {
                if t != s {
                    return Err(ShardError(format!(
                        "SLURM_ARRAY_TASK_COUNT={t} but the task IDs run from {from} to {} ({s} IDs): a stepped or sparse array; give each task --shard K/N",
                        max.unwrap_or(0)
                    )));
                }
            }
            let Some(n) = count.or(tasks).or(span) else {
                return Err(ShardError(format!(
                    "SLURM_ARRAY_TASK_ID={id} but neither SLURM_ARRAY_TASK_COUNT nor SLURM_ARRAY_TASK_MAX is set: give --shard-count N"
                )));
            };
            let Some(k) = id.checked_sub(from).filter(|&k| k < n) else {
                return Err(ShardError(format!(
                    "SLURM_ARRAY_TASK_ID={id} is not one of the {n} task IDs from {from}"
                )));
            };
            let origin = format!(
                "SLURM_ARRAY_TASK_ID={id}, from {from}, of {n}{}",
                if count.is_some() {
                    " (--shard-count)"
                } else {
                    ""
                }
            );
            return Ok(Some((Shard::new(k + 1, n)?, origin)));
        }
        if let Some(i) = number("JOB_COMPLETION_INDEX")? {
            let Some(n) = count else {
                return Err(ShardError(format!(
                    "JOB_COMPLETION_INDEX={i} is set (a Kubernetes Indexed Job): give the Job's completions as --shard-count N"
                )));
            };
            if i >= n {
                return Err(ShardError(format!(
                    "JOB_COMPLETION_INDEX={i} is not below --shard-count {n} (indexes run from 0)"
                )));
            }
            return Ok(Some((
                Shard::new(i + 1, n)?,
                format!("JOB_COMPLETION_INDEX={i} of {n}"),
            )));
        }
        Ok(None)
    }

    /// Whether the item `key` is this shard's.
    pub fn holds(&self, key: &ItemKey) -> bool {
        key.shard_of(self.count) == self.index
    }

    /// The name of this shard's results file: `results.jsonl` for the whole corpus,
    /// `results-K-of-N.jsonl` for a shard (so that the tasks of an array may share one
    /// output directory).
    pub fn results_file(&self) -> String {
        match self.count {
            1 => "results.jsonl".to_string(),
            n => format!("results-{}-of-{n}.jsonl", self.index),
        }
    }
}

/// A keyboard on a board kind as the command line names them: a layout (`--layout`) or an
/// instrument on every key (`--instrument`) — neither for the default layout — and the
/// board kind (`--board`) if given, else the keyboard's own.
#[derive(Clone, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Setup {
    /// The layout (a file or a built-in name), if the keyboard is one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layout: Option<String>,
    /// The instrument on every key, if the keyboard is that.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub instrument: Option<String>,
    /// The board kind, if given; else the layout's `board_kind` or the default decides, as
    /// the manifest records.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board: Option<String>,
}

impl fmt::Display for Setup {
    /// `layout grand88 on board rp2040`, `instrument hammond`, `the default layout`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.layout, &self.instrument) {
            (Some(l), _) => write!(f, "layout {l}")?,
            (None, Some(i)) => write!(f, "instrument {i}")?,
            (None, None) => write!(f, "the default layout")?,
        }
        match &self.board {
            Some(b) => write!(f, " on board {b}"),
            None => Ok(()),
        }
    }
}

/// What identifies an item of a corpus run: the performance on a [`Setup`], as the command
/// line names them (so every task of an array, given the same arguments, names an item
/// alike). In JSON its fields are side by side: `{"piece": …, "layout": …, "board": …}`.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct ItemKey {
    /// The MIDI file as listed, its path normalised ([`piece_name`]).
    pub piece: String,
    /// The keyboard and board it is played on.
    #[serde(flatten)]
    pub on: Setup,
}

impl ItemKey {
    /// The text that is hashed: the four fields, each after a tag, one a line (an absent
    /// field an empty line). Stable: changing it would move items between shards.
    pub fn canonical(&self) -> String {
        let o = |v: &Option<String>| v.clone().unwrap_or_default();
        let on = &self.on;
        format!(
            "piece {}\nlayout {}\ninstrument {}\nboard {}\n",
            self.piece,
            o(&on.layout),
            o(&on.instrument),
            o(&on.board)
        )
    }

    /// The first eight bytes of the SHA3-256 of [`ItemKey::canonical`], big-endian.
    pub fn hash(&self) -> u64 {
        let digest = Sha3_256::digest(self.canonical().as_bytes());
        let mut first = [0u8; 8];
        first.copy_from_slice(&digest[..8]);
        u64::from_be_bytes(first)
    }

    /// The shard (from 1) of `count` this item belongs to; 1 when `count` is 0.
    pub fn shard_of(&self, count: u32) -> u32 {
        (self.hash() % u64::from(count.max(1))) as u32 + 1
    }
}

impl fmt::Display for ItemKey {
    /// The piece, and the setup when one is named: `a.mid on layout my.toml`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.on == Setup::default() {
            true => write!(f, "{}", self.piece),
            false => write!(f, "{} on {}", self.piece, self.on),
        }
    }
}

/// A performance's path as an item names it: its components joined by `/`, without `.`
/// components or a trailing `/` (`./corpus//a.mid` is `corpus/a.mid`), not resolved
/// against the file system (the tasks of an array may see it mounted in other places).
pub fn piece_name(path: &Path) -> String {
    use std::path::Component;
    let mut parts: Vec<String> = Vec::new();
    let mut root = false;
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::RootDir => root = true,
            c => parts.push(c.as_os_str().to_string_lossy().into_owned()),
        }
    }
    let joined = parts.join("/");
    match root {
        true => format!("/{joined}"),
        false => joined,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    #[test]
    fn good_and_bad_forms() {
        assert_eq!(Shard::parse("2/4"), Ok(Shard { index: 2, count: 4 }));
        assert_eq!(Shard::parse(" 1/1 "), Ok(Shard::WHOLE));
        for (bad, says) in [
            ("3/2", "K must be at most N"),
            ("0/0", "at least 1"),
            ("0/2", "counts from 1"),
            ("a/b", "expected K/N"),
            ("2", "expected K/N"),
            ("-1/2", "expected K/N"),
            ("1/2/3", "expected K/N"),
            ("1/99999999999", "expected K/N"),
            ("1/2000000", "at most"),
        ] {
            let e = Shard::parse(bad).unwrap_err().0;
            assert!(e.contains(says), "{bad}: {e}");
        }
    }

    /// The assignment is a function of the key alone, fixed for good: these values are
    /// SHA3-256's, on any platform and Rust version.
    #[test]
    fn the_hash_is_stable_and_spreads_items() {
        let key = |p: &str| ItemKey {
            piece: p.to_string(),
            on: Setup {
                layout: Some("grand88".into()),
                ..Setup::default()
            },
        };
        assert_eq!(
            key("corpus/a.mid").canonical(),
            "piece corpus/a.mid\nlayout grand88\ninstrument \nboard \n"
        );
        // `printf 'piece corpus/a.mid\nlayout grand88\ninstrument \nboard \n' | openssl dgst -sha3-256`
        assert_eq!(key("corpus/a.mid").hash(), 0x950d_348c_119f_4230);
        // 3,000 items over 3 shards: each within 10 % of a third.
        let mut counts = HashMap::new();
        for i in 0..3000 {
            *counts
                .entry(key(&format!("p{i}.mid")).shard_of(3))
                .or_insert(0) += 1;
        }
        assert_eq!(counts.len(), 3);
        assert!(
            counts.values().all(|&c| (900..=1100).contains(&c)),
            "{counts:?}"
        );
        // Every item in exactly one shard.
        let k = key("x.mid");
        let holders: Vec<u32> = (1..=5)
            .filter(|&i| Shard::new(i, 5).unwrap().holds(&k))
            .collect();
        assert_eq!(holders.len(), 1);
    }

    #[test]
    fn paths_are_normalised_without_the_file_system() {
        assert_eq!(piece_name(Path::new("./corpus//a.mid")), "corpus/a.mid");
        assert_eq!(piece_name(Path::new("corpus/a.mid")), "corpus/a.mid");
        assert_eq!(piece_name(Path::new("/data/./x.mid")), "/data/x.mid");
        assert_eq!(piece_name(Path::new("../shared/a.mid")), "../shared/a.mid");
    }

    #[test]
    fn schedulers_give_the_shard() {
        let env = |vars: &[(&str, &str)]| {
            let m: HashMap<String, String> = vars
                .iter()
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect();
            move |k: &str| m.get(k).cloned()
        };
        let shard = |vars: &[(&str, &str)], count| {
            Shard::from_env(&env(vars), count).map(|s| s.map(|s| s.0))
        };
        assert_eq!(shard(&[], None), Ok(None));
        // --array=0-3 and --array=1-4: the same four shards.
        let slurm = |id: &str, min: &str, max: &str| {
            shard(
                &[
                    ("SLURM_ARRAY_TASK_ID", id),
                    ("SLURM_ARRAY_TASK_MIN", min),
                    ("SLURM_ARRAY_TASK_MAX", max),
                    ("SLURM_ARRAY_TASK_COUNT", "4"),
                ],
                None,
            )
        };
        assert_eq!(slurm("0", "0", "3"), Ok(Some(Shard::new(1, 4).unwrap())));
        assert_eq!(slurm("4", "1", "4"), Ok(Some(Shard::new(4, 4).unwrap())));
        // A stepped array (--array=0-6:2: IDs 0, 2, 4, 6) is refused.
        assert!(slurm("2", "0", "6")
            .unwrap_err()
            .0
            .contains("stepped or sparse"));
        // Only the ID and the count: from 0.
        assert_eq!(
            shard(&[("SLURM_ARRAY_TASK_ID", "1")], Some(2)),
            Ok(Some(Shard::new(2, 2).unwrap()))
        );
        assert!(shard(&[("SLURM_ARRAY_TASK_ID", "1")], None)
            .unwrap_err()
            .0
            .contains("--shard-count"));
        assert!(shard(&[("SLURM_ARRAY_TASK_ID", "x")], Some(2))
            .unwrap_err()
            .0
            .contains("not a whole number"));
        // Kubernetes: 0-based, the count from the command line.
        assert_eq!(
            shard(&[("JOB_COMPLETION_INDEX", "2")], Some(3)),
            Ok(Some(Shard::new(3, 3).unwrap()))
        );
        assert!(shard(&[("JOB_COMPLETION_INDEX", "3")], Some(3))
            .unwrap_err()
            .0
            .contains("not below"));
        assert!(shard(&[("JOB_COMPLETION_INDEX", "0")], None)
            .unwrap_err()
            .0
            .contains("--shard-count"));
    }
}
