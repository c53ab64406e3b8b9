//! `tactus corpus merge`: the results files of a sharded corpus run (`tactus play CORPUS
//! --shard K/N`, one per task of a job array) gathered into the tables one machine's run
//! writes (`corpus.csv`, `corpus.json`: the same rows in the same order, by the same
//! writer), and the same verdict.
//!
//! A merge is refused rather than made wrong (cargo-mutants' issue 344 is the lesson: shards
//! without a merge step leave every user to write a fragile one): the shards must be one run
//! (the same manifest: version, options, sources, firmware, items), every shard of the run
//! there once, and every item of the manifest done once, by the shard its key hashes to.
//! Each refusal names what is wrong — the two files whose manifests differ and where, the
//! missing or duplicated shard, the missing items and the shard that owes them.

use crate::play::corpus::{self, PieceRow, Verdict};
use crate::play::results::{self, difference, Header, ItemLine, ResultsError};
use crate::play::shard::{ItemKey, Shard};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Most results files one merge reads.
pub const MAX_INPUTS: usize = 1 << 16;

/// Items a refusal names before it says how many more.
const NAMED: usize = 10;

/// Why shards cannot be merged. Every variant means "the run could not be done" (exit 2).
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    /// No results file among the inputs, an input that is neither a results file nor a
    /// directory holding some, or too many.
    #[error("{0}")]
    Inputs(String),
    /// A results file cannot be read.
    #[error(transparent)]
    Results(#[from] ResultsError),
    /// Two files are not shards of one run.
    #[error("`{first}` and `{second}` are not shards of one run: {difference}")]
    Manifests {
        /// The first file.
        first: PathBuf,
        /// The other.
        second: PathBuf,
        /// Where their headers differ ([`difference`]).
        difference: String,
    },
    /// A shard given twice.
    #[error("shard {shard} is given twice: `{first}` and `{second}`")]
    DuplicateShard {
        /// The shard.
        shard: Shard,
        /// One file.
        first: PathBuf,
        /// The other.
        second: PathBuf,
    },
    /// Shards of the run have no results file among the inputs.
    #[error("{} of {count} shards missing: {} (no results-K-of-{count}.jsonl among the inputs: run or finish those tasks)", missing.len(), show_shards(missing, *count))]
    MissingShards {
        /// The shards' indexes.
        missing: Vec<u32>,
        /// How many shards the run has.
        count: u32,
    },
    /// An item line that does not belong where it is.
    #[error("`{file}`: item {key} {why}")]
    StrayItem {
        /// The file.
        file: PathBuf,
        /// The item.
        key: Box<ItemKey>,
        /// Why it does not belong.
        why: String,
    },
    /// Items of the manifest that no shard has done.
    #[error("{} of {total} items missing: {} (their shards' tasks did not finish them: run those again with --resume)", missing.len(), show_items(missing))]
    MissingItems {
        /// Each missing item and the shard that owes it.
        missing: Vec<(ItemKey, Shard)>,
        /// How many items the run has.
        total: usize,
    },
    /// The tables cannot be written.
    #[error("{0}")]
    Tables(String),
}

fn show_shards(missing: &[u32], count: u32) -> String {
    named(missing.iter().map(|k| format!("{k}/{count}")))
}

fn show_items(missing: &[(ItemKey, Shard)]) -> String {
    named(missing.iter().map(|(k, sh)| format!("{k} (shard {sh})")))
}

/// The first [`NAMED`] of `all`, then how many more.
fn named(all: impl ExactSizeIterator<Item = String>) -> String {
    let n = all.len();
    let mut s: Vec<String> = all.take(NAMED).collect();
    if n > NAMED {
        s.push(format!("… {} more", n - NAMED));
    }
    s.join(", ")
}

/// What a merge produced.
#[derive(Debug)]
pub struct Merged {
    /// The results files read, by shard.
    pub inputs: Vec<PathBuf>,
    /// The run's manifest.
    pub header: Header,
    /// The rows, in the order of the manifest's items: the table.
    pub rows: Vec<PieceRow>,
    /// The tables written.
    pub written: Vec<PathBuf>,
    /// The verdict on the rows ([`corpus::verdict`], as one machine's run gives it).
    pub verdict: Verdict,
}

/// The results files among `inputs`: each a results file, or a directory whose
/// `results*.jsonl` files are taken (sorted); a file named twice (as itself and through its
/// directory) once.
///
/// Errors: [`MergeError::Inputs`] for an input that does not exist, a directory without
/// results files, no input, or more than [`MAX_INPUTS`] files.
pub fn results_files(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, MergeError> {
    let mut files: Vec<PathBuf> = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for a in inputs {
        let found: Vec<PathBuf> = if a.is_dir() {
            let entries = std::fs::read_dir(a)
                .map_err(|e| MergeError::Inputs(format!("cannot read `{}`: {e}", a.display())))?;
            let mut r: Vec<PathBuf> = entries
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| {
                    p.is_file()
                        && p.file_name()
                            .and_then(|n| n.to_str())
                            .is_some_and(|n| n.starts_with("results") && n.ends_with(".jsonl"))
                })
                .take(MAX_INPUTS + 1)
                .collect();
            r.sort();
            if r.is_empty() {
                return Err(MergeError::Inputs(format!(
                    "`{}` holds no results file (results.jsonl, results-K-of-N.jsonl: what `tactus play CORPUS --shard K/N` writes)",
                    a.display()
                )));
            }
            r
        } else if a.exists() {
            vec![a.clone()]
        } else {
            return Err(MergeError::Inputs(format!(
                "`{}` does not exist",
                a.display()
            )));
        };
        for f in found {
            if seen.insert(f.canonicalize().unwrap_or_else(|_| f.clone())) {
                files.push(f);
            }
        }
        if files.len() > MAX_INPUTS {
            return Err(MergeError::Inputs(format!(
                "at most {MAX_INPUTS} results files in one merge"
            )));
        }
    }
    if files.is_empty() {
        return Err(MergeError::Inputs(
            "no results file to merge: give the shards' results files or their directories".into(),
        ));
    }
    Ok(files)
}

/// Merges the results files of `inputs` ([`results_files`]) into `OUT/corpus.csv` and
/// `OUT/corpus.json` ([`corpus::write_tables`]), `out` created; see the module
/// documentation.
///
/// Errors: [`MergeError`]; its variants in the order they are checked: the inputs, each
/// file read, the manifests, the shards, each item's place, the missing items, the tables.
pub fn merge(inputs: &[PathBuf], out: &Path) -> Result<Merged, MergeError> {
    let files = results_files(inputs)?;
    let mut read: Vec<(PathBuf, Header, Vec<ItemLine>)> = Vec::with_capacity(files.len());
    for f in files {
        let (header, items) = results::read(&f)?;
        read.push((f, header, items));
    }
    // One run: every manifest as the first's (and the shard count with it).
    let json = |h: &Header| serde_json::to_value(&h.manifest).unwrap_or_default();
    let (first, head) = (&read[0].0, &read[0].1);
    for (f, h, _) in &read[1..] {
        let diff = match h.shard.count == head.shard.count {
            false => Some(format!(
                "one is shard {} of {}, the other of {}",
                head.shard.index, head.shard.count, h.shard.count
            )),
            true => difference(&json(head), &json(h)),
        };
        if let Some(difference) = diff {
            return Err(MergeError::Manifests {
                first: first.clone(),
                second: f.clone(),
                difference,
            });
        }
    }
    // Every shard once.
    let count = head.shard.count;
    let mut by_shard: BTreeMap<u32, usize> = BTreeMap::new();
    for (i, (f, h, _)) in read.iter().enumerate() {
        if let Some(&j) = by_shard.get(&h.shard.index) {
            return Err(MergeError::DuplicateShard {
                shard: h.shard,
                first: read[j].0.clone(),
                second: f.clone(),
            });
        }
        by_shard.insert(h.shard.index, i);
    }
    let missing: Vec<u32> = (1..=count).filter(|k| !by_shard.contains_key(k)).collect();
    if !missing.is_empty() {
        return Err(MergeError::MissingShards { missing, count });
    }
    // Every item of the manifest done once, by its own shard.
    let manifest = &head.manifest;
    let listed: std::collections::BTreeSet<&ItemKey> = manifest.items.iter().collect();
    let mut rows: BTreeMap<&ItemKey, &PieceRow> = BTreeMap::new();
    for (f, h, items) in &read {
        for line in items {
            let stray = |why: String| MergeError::StrayItem {
                file: f.clone(),
                key: Box::new(line.key.clone()),
                why,
            };
            if !listed.contains(&line.key) {
                return Err(stray("is not in the run's manifest".into()));
            }
            if !h.shard.holds(&line.key) {
                return Err(stray(format!(
                    "is shard {}/{count}'s, not this file's shard {}",
                    line.key.shard_of(count),
                    h.shard
                )));
            }
            rows.insert(&line.key, &line.row);
        }
    }
    let missing: Vec<(ItemKey, Shard)> = (manifest.items.iter())
        .filter(|k| !rows.contains_key(k))
        .map(|k| {
            (
                k.clone(),
                Shard {
                    index: k.shard_of(count),
                    count,
                },
            )
        })
        .collect();
    if !missing.is_empty() {
        return Err(MergeError::MissingItems {
            missing,
            total: manifest.items.len(),
        });
    }
    let table: Vec<PieceRow> = (manifest.items.iter())
        .filter_map(|k| rows.get(k).map(|r| (*r).clone()))
        .collect();
    let written = corpus::write_tables(out, &table).map_err(MergeError::Tables)?;
    let verdict = corpus::verdict(&table);
    let mut by_index: Vec<(u32, PathBuf)> = read
        .iter()
        .map(|(f, h, _)| (h.shard.index, f.clone()))
        .collect();
    by_index.sort();
    let header = read.swap_remove(0).1;
    Ok(Merged {
        inputs: by_index.into_iter().map(|(_, f)| f).collect(),
        header,
        rows: table,
        written,
        verdict,
    })
}
