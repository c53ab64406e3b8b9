//! The host side of Tactus, between the command line and the libraries below it.
//!
//! * [`build`]: `tactus build`'s outputs: an instrument as C99 or a Thumb object, a
//!   keyboard as flashable firmware per board.
//! * [`catalogue`]: the instruments, layouts and boards built into the toolchain (so that
//!   `tactus play` and `tactus budget grand_piano` work on a fresh machine from any
//!   directory), and loading a source by path or built-in name.
//! * [`emu`]: `tactus emu run`'s reading, tracing and text, and firmware from `tactus build`
//!   driven by a stimulus through its key map.
//! * [`keyboard`]: **the** resolution and compilation of a keyboard — a layout file, a
//!   built-in layout, or one instrument on N keys, on a board kind — used by `tactus build`,
//!   `tactus budget` and `tactus play`, so that they see the same keys, the same programs
//!   and the same boards.
//! * [`play`]: one performance through a compiled keyboard as `tactus play` runs it (read,
//!   cut, keep the notes on the keyboard, play, write the strikes and traces), a row of the
//!   corpus table.
//! * [`sim`]: one instrument over a stimulus on the host (`tactus sim`): the stimulus
//!   resolved, the requested columns and WAV outputs checked, the run, the WAV mix.
//!
//! * [`plot`]: SVG plots of traces, of a run's cycles per sample and of curves, in the
//!   units an instrument maker reads.
//! * [`regulate`]: the regulation sheet of a key instrument (`tactus regulate`) on an
//!   arithmetic and engine, as text, with a spec's verdicts.
//!
//! This crate never prints: diagnostics go to a caller's reporter, errors are values.

pub mod build;
pub mod catalogue;
pub mod emu;
pub mod keyboard;
pub mod play;
pub mod plot;
pub mod regulate;
pub mod sim;
