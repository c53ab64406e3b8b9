//! The host side of Tactus, between the command line and the libraries below it.
//!
//! * [`budget`]: `tactus budget`'s run: a compiled keyboard's plan, costs and verdict, and
//!   the plan written as a layout file.
//! * [`build`]: `tactus build`'s outputs: an instrument as C99 or a Thumb object, a
//!   keyboard as flashable firmware per board.
//! * [`catalogue`]: the instruments, layouts and boards built into the toolchain (so that
//!   `tactus play` and `tactus budget grand_piano` work on a fresh machine from any
//!   directory), and loading a source by path or built-in name.
//! * [`check`]: `tactus check`'s summary of an instrument and its precision report.
//! * [`corpus_run`]: `tactus play`'s corpus mode: the items (performances × keyboards ×
//!   boards), the shard a task plays, its results file written item by item, the tables.
//! * [`corpus_merge`]: `tactus corpus merge`: shards' results gathered into the tables one
//!   machine writes, refused when they are not one whole run.
//! * [`emu`]: `tactus emu run`'s reading, tracing and text, and firmware from `tactus build`
//!   driven by a stimulus through its key map.
//! * [`fault`]: the `--fault` syntax of `play` and `emu run`, resolved to a board's injection;
//!   the boards' fault records read and reported after a run.
//! * [`fault_corpus`]: the budget corpus through every board of a keyboard, its trips.
//! * [`keyboard`]: **the** resolution and compilation of a keyboard — a layout file, a
//!   built-in layout, or one instrument on N keys, on a board kind — used by `tactus build`,
//!   `tactus budget` and `tactus play`, so that they see the same keys, the same programs
//!   and the same boards.
//! * [`play`]: a recorded performance played through an instrument: the players, the one
//!   play loop over the one engine trait (the host engines, and `play::emulated` the
//!   firmware of every board on emulated RP2040s), the strike rule, the output files (CSV,
//!   MIDI, WAV) and the corpus table.
//! * [`plot`]: SVG plots of traces and curves, in the units an instrument maker reads.
//! * [`regulate`]: the regulation sheet of a key instrument, measured with the closed-loop
//!   key model, a spec's verdict, and (`regulate::sheet`) `tactus regulate`'s run and text.
//! * [`session`]: `tactus play`'s run: a keyboard compiled once for a corpus, each piece
//!   read, checked, played and written, what to print.
//! * [`sim`]: one instrument over a stimulus on the host (`tactus sim`): the stimulus
//!   resolved, the requested columns and WAV outputs checked, the run, the files, the text.
//!
//! This crate never prints: diagnostics go to a caller's reporter, errors are values.

pub mod budget;
pub mod build;
pub mod catalogue;
pub mod check;
pub mod corpus_merge;
pub mod corpus_run;
pub mod emu;
pub mod fault;
pub mod fault_corpus;
pub mod keyboard;
pub mod play;
pub mod plot;
pub mod regulate;
pub mod session;
pub mod sim;
