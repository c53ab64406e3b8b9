//! `tactus play`'s corpus mode: many items — each performance on each keyboard (a layout,
//! or one instrument on every key) on each board kind — played in turn, one shard of them
//! when a cluster splits the run ([`crate::play::shard`]), every item's row written to the
//! shard's results file as it is done ([`crate::play::results`]), and with the whole corpus
//! the tables (`OUT/corpus.csv`, `OUT/corpus.json`).
//!
//! The items are in the order of the table: keyboard by keyboard (the `--layout`s, then the
//! `--instrument`s, in the order given), board by board, and within each the files as listed
//! (a directory's sorted). With more than one keyboard or board, each item's own files go
//! to a folder of its own (`OUT/KEYBOARD-BOARD/`, [`Combo::folder`]); with one, to `OUT`.
//!
//! The caller compiles a [`Session`] per combination ([`Corpus::combos`]) and plays each
//! item ([`CorpusRun::todo`]) with it, printing as it goes; this module keeps the books.

use crate::play::corpus::{self, PieceRow, Verdict};
use crate::play::results::{Header, ItemLine, Manifest, ResultsError, ResultsFile};
use crate::play::shard::{piece_name, ItemKey, Setup, Shard};
use crate::session::{PlayError, Session};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// What a corpus run plays, as the command line gives it.
#[derive(Clone, Debug, Default)]
pub struct CorpusSpec {
    /// MIDI files and directories of them.
    pub performances: Vec<PathBuf>,
    /// Layouts (`--layout`, files or built-in names), in order.
    pub layouts: Vec<String>,
    /// Instruments on every key (`--instrument`), in order.
    pub instruments: Vec<String>,
    /// Board kinds (`--board`), in order; none: each keyboard's own.
    pub boards: Vec<String>,
}

/// One keyboard on one board kind, as the command line names them, and where its items'
/// files go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Combo {
    /// The keyboard and the board.
    pub on: Setup,
    /// The folder under `OUT` its items' files go to (`None`: `OUT` itself, with one
    /// combination).
    pub folder: Option<String>,
}

/// One item: a performance on a combination.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Item {
    /// Its key (what shards and results name).
    pub key: ItemKey,
    /// The MIDI file.
    pub file: PathBuf,
    /// Its combination, an index into [`Corpus::combos`].
    pub combo: usize,
}

/// The items of a corpus run, in the order of its table.
#[derive(Clone, Debug)]
pub struct Corpus {
    /// The keyboard × board combinations.
    pub combos: Vec<Combo>,
    /// Every item.
    pub items: Vec<Item>,
}

/// The file stem of a layout, instrument or board as given (`layouts/my.toml` → `my`).
fn stem(s: &str) -> String {
    Path::new(s)
        .file_stem()
        .map_or_else(|| s.to_string(), |x| x.to_string_lossy().into_owned())
}

impl Corpus {
    /// The items of `spec`: its files ([`corpus::expand`]) on every combination of its
    /// keyboards (none given: the default layout) and boards (none given: each keyboard's
    /// own).
    ///
    /// Errors: what [`corpus::expand`] refuses; a file listed twice (naming it); two
    /// combinations whose folders would have one name; more than [`corpus::MAX_PIECES`]
    /// items.
    pub fn new(spec: &CorpusSpec) -> Result<Corpus, String> {
        let files = corpus::expand(&spec.performances)?;
        let keyboards: Vec<Setup> = (spec.layouts.iter())
            .map(|l| Setup {
                layout: Some(l.clone()),
                ..Setup::default()
            })
            .chain(spec.instruments.iter().map(|i| Setup {
                instrument: Some(i.clone()),
                ..Setup::default()
            }))
            .collect();
        let keyboards = match keyboards.is_empty() {
            true => vec![Setup::default()],
            false => keyboards,
        };
        let boards: Vec<Option<String>> = match spec.boards.is_empty() {
            true => vec![None],
            false => spec.boards.iter().cloned().map(Some).collect(),
        };
        let several = keyboards.len() * boards.len() > 1;
        let mut combos = Vec::new();
        for kb in &keyboards {
            for board in &boards {
                let on = Setup {
                    board: board.clone(),
                    ..kb.clone()
                };
                let folder = several.then(|| {
                    let name = (on.layout.as_deref().or(on.instrument.as_deref()))
                        .map_or_else(|| crate::catalogue::DEFAULT_LAYOUT.to_string(), stem);
                    format!(
                        "{name}-{}",
                        board.as_deref().map_or_else(|| "default".to_string(), stem)
                    )
                });
                if let Some(same) =
                    (combos.iter()).find(|c: &&Combo| c.folder.is_some() && c.folder == folder)
                {
                    return Err(format!(
                        "two keyboard and board pairs would write to one folder `{}` ({} and {on}): give files of other names",
                        folder.unwrap_or_default(),
                        same.on,
                    ));
                }
                combos.push(Combo { on, folder });
            }
        }
        if files.len().saturating_mul(combos.len()) > corpus::MAX_PIECES {
            return Err(format!(
                "a corpus run holds at most {} items; {} files on {} keyboard and board pairs are more",
                corpus::MAX_PIECES,
                files.len(),
                combos.len()
            ));
        }
        let mut items = Vec::new();
        let mut seen: BTreeMap<ItemKey, &Path> = BTreeMap::new();
        for (ci, c) in combos.iter().enumerate() {
            for f in &files {
                let key = ItemKey {
                    piece: piece_name(f),
                    on: c.on.clone(),
                };
                if let Some(first) = seen.insert(key.clone(), f) {
                    return Err(format!(
                        "`{}` is listed twice (also as `{}`): each performance once",
                        f.display(),
                        first.display()
                    ));
                }
                items.push(Item {
                    key,
                    file: f.clone(),
                    combo: ci,
                });
            }
        }
        Ok(Corpus { combos, items })
    }
}

/// Why a corpus run cannot go on: the run could not be done (exit 2).
#[derive(Debug, thiserror::Error)]
pub enum CorpusError {
    /// A keyboard cannot be compiled, or its manifest entry made.
    #[error(transparent)]
    Session(#[from] PlayError),
    /// The results file cannot be read, resumed or written.
    #[error(transparent)]
    Results(#[from] ResultsError),
    /// The tables cannot be written.
    #[error("{0}")]
    Tables(String),
}

/// A corpus run under way: the corpus, the sessions it plays on, the shard, its results.
pub struct CorpusRun {
    /// The items.
    pub corpus: Corpus,
    /// One session per combination, in order.
    pub sessions: Vec<Session>,
    /// The shard this process plays.
    pub shard: Shard,
    /// Its results file.
    pub results: ResultsFile,
}

impl CorpusRun {
    /// Starts (or with `resume` goes on with) the run of `shard` of `corpus` on `sessions`
    /// (one per [`Corpus::combos`], in order), its results in `out`: the manifest is made
    /// (each session's firmware compiled, to be hashed) and the results file written, or
    /// read back when resuming.
    ///
    /// Errors: [`CorpusError::Session`] when a keyboard's manifest entry cannot be made
    /// (a file that cannot be read again); [`CorpusError::Results`] when the results file
    /// cannot be written, or on `resume`, read or is another run's.
    pub fn start(
        corpus: Corpus,
        sessions: Vec<Session>,
        shard: Shard,
        out: &Path,
        resume: bool,
    ) -> Result<CorpusRun, CorpusError> {
        let keyboards = (corpus.combos.iter().zip(&sessions))
            .map(|(c, s)| s.manifest(&c.on))
            .collect::<Result<Vec<_>, _>>()?;
        let options = sessions
            .first()
            .map(Session::run_options)
            .ok_or_else(|| CorpusError::Tables("no keyboard to play on".into()))?;
        let header = Header {
            shard,
            manifest: Manifest {
                tactus: env!("CARGO_PKG_VERSION").to_string(),
                options,
                keyboards,
                items: corpus.items.iter().map(|i| i.key.clone()).collect(),
            },
        };
        let results = match resume {
            true => ResultsFile::resume(out, header)?,
            false => ResultsFile::create(out, header)?,
        };
        Ok(CorpusRun {
            corpus,
            sessions,
            shard,
            results,
        })
    }

    /// This shard's items, as indexes into the corpus's items.
    pub fn mine(&self) -> Vec<usize> {
        (0..self.corpus.items.len())
            .filter(|&i| self.shard.holds(&self.corpus.items[i].key))
            .collect()
    }

    /// This shard's items not yet done (all of them, unless resuming).
    pub fn todo(&self) -> Vec<usize> {
        (self.mine().into_iter())
            .filter(|&i| !self.results.done(&self.corpus.items[i].key))
            .collect()
    }

    /// The session item `i` plays on.
    pub fn session(&self, i: usize) -> &Session {
        &self.sessions[self.corpus.items[i].combo]
    }

    /// Records item `i` done: its row (or the error that kept it from being played, as a
    /// row with that error), named with its keyboard and board, written to the results
    /// file at once.
    ///
    /// Errors: [`ResultsError::Io`] when the file cannot be written.
    pub fn record(
        &mut self,
        i: usize,
        played: Result<PieceRow, String>,
    ) -> Result<(), ResultsError> {
        let item = &self.corpus.items[i];
        let kb = &self.sessions[item.combo].kb;
        let mut row = played.unwrap_or_else(|e| PieceRow::failed(&item.file, e));
        row.file = item.file.clone();
        row.keyboard = kb.name.clone();
        row.board = kb.board.name.clone();
        self.results.push(ItemLine {
            key: item.key.clone(),
            row,
        })
    }

    /// The rows of this shard's items done, in the order of the table.
    pub fn rows(&self) -> Vec<PieceRow> {
        let by_key: BTreeMap<&ItemKey, &PieceRow> = (self.results.items.iter())
            .map(|l| (&l.key, &l.row))
            .collect();
        (self.corpus.items.iter())
            .filter_map(|i| by_key.get(&i.key).map(|r| (*r).clone()))
            .collect()
    }

    /// Ends the run: with the whole corpus (shard 1/1) the tables written to `out`
    /// ([`corpus::write_tables`]: `corpus.csv`, `corpus.json`); a shard's tables are the
    /// merge's (`tactus corpus merge`). Returns the rows, the files written and the
    /// verdict on the rows.
    ///
    /// Errors: [`CorpusError::Tables`] when a table cannot be written.
    pub fn finish(
        &self,
        out: &Path,
    ) -> Result<(Vec<PieceRow>, Vec<PathBuf>, Verdict), CorpusError> {
        let rows = self.rows();
        let mut written = vec![self.results.path.clone()];
        if self.shard.count == 1 {
            written.extend(corpus::write_tables(out, &rows).map_err(CorpusError::Tables)?);
        }
        let verdict = corpus::verdict(&rows);
        Ok((rows, written, verdict))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn items_are_every_file_on_every_combination_in_table_order() {
        let dir = std::env::temp_dir().join(format!("tactus-corpus-run-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for f in ["b.mid", "a.mid"] {
            std::fs::write(dir.join(f), b"").unwrap();
        }
        let spec = CorpusSpec {
            performances: vec![dir.clone()],
            layouts: vec!["grand88".into()],
            instruments: vec!["hammond".into()],
            boards: vec!["rp2040".into(), "boards/my_board.toml".into()],
        };
        let c = Corpus::new(&spec).unwrap();
        assert_eq!(c.combos.len(), 4);
        assert_eq!(c.items.len(), 8);
        let folders: Vec<_> = c.combos.iter().map(|c| c.folder.clone().unwrap()).collect();
        assert_eq!(
            folders,
            [
                "grand88-rp2040",
                "grand88-my_board",
                "hammond-rp2040",
                "hammond-my_board"
            ]
        );
        assert!(c.items[0].key.piece.ends_with("/a.mid"));
        assert!(c.items[1].key.piece.ends_with("/b.mid"));
        assert_eq!(c.items[2].combo, 1);
        // One combination: no folders.
        let one = Corpus::new(&CorpusSpec {
            performances: vec![dir.clone()],
            ..CorpusSpec::default()
        })
        .unwrap();
        assert_eq!(one.combos[0].folder, None);
        // A file twice is refused; two folders of one name too.
        let twice = Corpus::new(&CorpusSpec {
            performances: vec![dir.clone(), dir.join("a.mid")],
            ..CorpusSpec::default()
        });
        assert!(twice.unwrap_err().contains("listed twice"));
        let clash = Corpus::new(&CorpusSpec {
            performances: vec![dir.clone()],
            layouts: vec!["x/grand.toml".into(), "y/grand.toml".into()],
            ..CorpusSpec::default()
        });
        assert!(clash.unwrap_err().contains("one folder `grand-default`"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
