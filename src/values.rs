//! The command line's value enums (`--engine`, `--player`, `--emu`, `--numeric`): clap's
//! view of the libraries' enums, each with its help text and its conversion.

use tactus_host::play;

/// Engines of `tactus play`: what computes a key's instrument each sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum PlayEngine {
    /// Cranelift JIT (f64).
    Jit,
    /// The f64 reference interpreter.
    Interp,
    /// Cranelift JIT of the fixed-point program: the bits the firmware computes (the Thumb
    /// code in the emulator equals it bit for bit).
    Fixed,
    /// The firmware of every board of the keyboard (`tactus_firmware::image`: Thumb updates,
    /// the safety limiter, a timer interrupt per core) on emulated RP2040s, every key every
    /// sample; reports cycles per core and deadline misses.
    Emu,
}

impl From<PlayEngine> for play::PlayEngine {
    fn from(e: PlayEngine) -> Self {
        match e {
            PlayEngine::Jit => play::PlayEngine::Jit,
            PlayEngine::Interp => play::PlayEngine::Interp,
            PlayEngine::Fixed => play::PlayEngine::Fixed,
            PlayEngine::Emu => play::PlayEngine::Emu,
        }
    }
}

/// Players of `tactus play`: what moves the keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Player {
    /// Key trajectories prescribed by the key-motion model (open loop).
    Position,
    /// A finger force profile against the instrument's force (closed loop).
    Force,
}

impl From<Player> for play::Player {
    fn from(p: Player) -> Self {
        match p {
            Player::Position => play::Player::Position,
            Player::Force => play::Player::Force,
        }
    }
}

/// The emulator's engine (`--emu`): all are exact; the block engine is the fastest, the
/// lock-step machine the reference the others are checked against.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum EmuEngine {
    /// The lock-step machine alone: every instruction decoded from memory as it runs.
    LockStep,
    /// One pre-decoded instruction at a time.
    Interp,
    /// Code regions compiled to native code (the default).
    #[default]
    Block,
}

impl From<EmuEngine> for tactus_emulator::Engine {
    fn from(e: EmuEngine) -> Self {
        match e {
            EmuEngine::LockStep => tactus_emulator::Engine::LockStep,
            EmuEngine::Interp => tactus_emulator::Engine::Interp,
            EmuEngine::Block => tactus_emulator::Engine::Block,
        }
    }
}

/// Arithmetic of `tactus sim`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Numeric {
    /// Double precision, the reference semantics.
    F64,
    /// 32-bit fixed point with the compiler's formats.
    Fixed,
}

/// Engine of `tactus sim`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum EngineKind {
    /// The reference interpreters.
    Interp,
    /// Cranelift JIT.
    Jit,
}

impl From<Numeric> for tactus_host::sim::Numeric {
    fn from(n: Numeric) -> Self {
        match n {
            Numeric::F64 => tactus_host::sim::Numeric::F64,
            Numeric::Fixed => tactus_host::sim::Numeric::Fixed,
        }
    }
}

impl From<EngineKind> for tactus_host::sim::Engine {
    fn from(e: EngineKind) -> Self {
        match e {
            EngineKind::Interp => tactus_host::sim::Engine::Interp,
            EngineKind::Jit => tactus_host::sim::Engine::Jit,
        }
    }
}
