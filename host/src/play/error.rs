//! Why the play loop refuses a keyboard or stops: [`RunError`], the one error type of
//! [`crate::play`] (the loop, its engines, the force player's calibration and the emulated
//! boards).

use tactus_firmware::boards::BoardsError;
use tactus_firmware::image::ImageError;

/// Why [`crate::play::play`] (or one of its parts) cannot play a keyboard. Every message
/// names the program, key, board or sample it is about.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A `--fault` names what the keyboard does not have (`crate::fault`).
    #[error("{0}")]
    Fault(#[from] crate::fault::FaultError),
    /// A program is compiled for another sample rate than the board's.
    #[error(
        "`{program}` is compiled for {program_hz} Hz, the board `{board}` samples at {board_hz} Hz"
    )]
    SampleRate {
        /// The program's name.
        program: String,
        /// Its sample rate, Hz.
        program_hz: f64,
        /// The board's name.
        board: String,
        /// The board's sample rate, Hz.
        board_hz: f64,
    },
    /// The firmware's programs handed to the loop do not match the keyboard (a caller's
    /// mistake: [`crate::keyboard::Keyboard::played`] makes them match).
    #[error("firmware: {0}")]
    FirmwareMismatch(String),
    /// A program does not compile for a host JIT (`engine`: `JIT` or `fixed JIT`).
    #[error("{engine}: {message}")]
    Jit {
        /// Which JIT.
        engine: &'static str,
        /// The JIT's message.
        message: String,
    },
    /// No calibration stroke of the force player struck the string: the finger cannot play
    /// this instrument.
    #[error("instrument `{instrument}`: no calibration stroke of {levels:?} N struck; the force player cannot play it")]
    Calibration {
        /// The program's name.
        instrument: String,
        /// The finger forces tried, N.
        levels: Vec<f64>,
    },
    /// The piece is longer than an emulated run may cover (`super::MAX_EMU_SAMPLES`).
    #[error("--engine emu: the piece is {:.1} h long, more than the {:.1} h ({max_samples} samples, the range of the firmware's 32-bit sample counter) an emulated run may cover; play a part of it with --seconds", seconds / 3600.0, max_seconds / 3600.0)]
    TooLong {
        /// The piece's length, s.
        seconds: f64,
        /// The longest run, s.
        max_seconds: f64,
        /// The longest run, samples.
        max_samples: u64,
    },
    /// `--io-trace` on a board without converters: there are no frames to write.
    #[error("--io-trace: the board `{board}` has no converters (its file names no `[converters]`; the reference board with them is `rp2040_io`)")]
    NoConverters {
        /// The board kind's name.
        board: String,
    },
    /// The boards of the keyboard cannot be costed or planned.
    #[error("firmware: {0}")]
    Boards(#[from] BoardsError),
    /// A key fits no board of the kind (the budget's reason).
    #[error("firmware: key {key} fits no {board} board: {why} (`tactus budget` says the same)")]
    Unfit {
        /// The key (MIDI number).
        key: u8,
        /// The board kind's name.
        board: String,
        /// Why, as `tactus budget` says it.
        why: String,
    },
    /// One board's image cannot be built, booted or run.
    #[error("firmware: board {board} ({keys}): {source}")]
    Board {
        /// The board's number, from 1.
        board: usize,
        /// Its keys, as ranges (`21-28`).
        keys: String,
        /// What went wrong on it.
        source: BoardError,
    },
    /// An engine computed a non-finite force or strike speed.
    #[error("key {key}: the simulation computed a non-finite value at sample {sample} (t = {time_s:.6} s): force {force_n} N, strike speed {strike_mps:?} m/s")]
    NonFinite {
        /// The key (MIDI number).
        key: u8,
        /// The run's sample index (from the start of a lead-in).
        sample: usize,
        /// Its time in the performance's time, s.
        time_s: f64,
        /// The force, N.
        force_n: f64,
        /// The strike speed, m/s, if the sample struck.
        strike_mps: Option<f64>,
    },
    /// A span of the play loop that does not start where the last one ended
    /// (`run::KeysLoop::run`: a caller's bug).
    #[error(
        "a span of the play loop starts at sample {start}, not where the last ended ({expected})"
    )]
    Span {
        /// Where it starts.
        start: usize,
        /// Where the last ended.
        expected: usize,
    },
    /// An emulated board stopped at a sample (a fault, or the image's own check).
    #[error("sample {sample}: {source}")]
    Sample {
        /// The sample index.
        sample: usize,
        /// The image run's error.
        source: ImageError,
    },
}

/// What went wrong on one emulated board ([`RunError::Board`]).
#[derive(Debug, thiserror::Error)]
pub enum BoardError {
    /// Its keys cannot be placed on cores.
    #[error("{0}")]
    Plan(#[from] BoardsError),
    /// Its image cannot be built or booted.
    #[error("{0}")]
    Image(#[from] ImageError),
    /// Its run stopped (a fault at a sample, a non-finite value).
    #[error("{0}")]
    Run(Box<RunError>),
    /// Its I/O trace (`--io-trace`) could not be written.
    #[error("I/O trace {path}: {message}")]
    Trace {
        /// The file.
        path: String,
        /// The system's message.
        message: String,
    },
}

impl From<RunError> for BoardError {
    fn from(e: RunError) -> Self {
        BoardError::Run(Box::new(e))
    }
}
