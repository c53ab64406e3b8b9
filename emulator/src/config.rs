//! How a board is configured ([`Config`]): what the machine needs of it (its clock, which
//! events stop a run) and which engine the accelerator runs it with ([`Engine`], the cores'
//! own banks). A leaf both the machine ([`crate::machine`]) and the accelerator
//! ([`crate::accel`]) read, so that neither names the façade ([`crate::board`]) that holds
//! it. Results never depend on the engine or the banks, only speed.

/// Board configuration.
#[derive(Clone, Debug)]
pub struct Config {
    /// System clock in Hz (RP2040: 133 MHz); drives the microsecond timer.
    pub clock_hz: u64,
    /// Stop [`crate::Board::run_until`] at every SVC with [`crate::StopReason::Svc`] (for host calls such as a
    /// test harness's `write`/`exit`) instead of taking the SVCall exception.
    pub svc_halts: bool,
    /// Stop [`crate::Board::run_until`] with [`crate::StopReason::Fault`] after a core takes a HardFault, instead
    /// of running the firmware's HardFault handler.
    pub stop_on_fault: bool,
    /// Which engine runs the fast path of [`crate::Board::run_until`] / [`crate::Board::run_for`]
    /// (default [`Engine::Block`], the faster: see BENCHMARKS.md, "the block compiler").
    /// Both give the same cycles, registers and memory; [`crate::Board::step`] is always the
    /// general path.
    pub engine: Engine,
    /// Each core's own SRAM banks (bit per bank: 0-3 SRAM0-3, 4 SRAM4, 5 SRAM5). When
    /// they are disjoint and both set, [`Engine::Block`] runs the two cores as independent
    /// machines over whole windows of cycles, each confined to its own banks and private
    /// registers, undoing a window in which either touches anything else (`accel/window.rs`;
    /// the firmware images lay each core out in its own banks,
    /// `tactus_firmware::FirmwareImage::own_banks`). Default `[0, 0]`: the two cores in lock-step. Results never
    /// depend on it, only speed.
    pub own_banks: [u8; 2],
}

/// The engine behind [`crate::Board::run_until`] and [`crate::Board::step`]: every one gives
/// the same cycles, registers, memory and I/O; they differ only in speed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Engine {
    /// No accelerator: the lock-step machine alone ([`crate::machine::Machine::run_lock_step`]),
    /// one instruction at a time, each decoded from memory as it runs
    /// ([`crate::machine::Fetch`]). The definition the other engines are checked against
    /// (`firmware/tests/keyboard_exact.rs`); the slowest.
    LockStep,
    /// The interpreter: one instruction at a time from the decode cache (module `fast`).
    Interp,
    /// The block engine (module [`crate::accel::block`]): code regions compiled to native code
    /// with cranelift (module `jit`) once warm, pre-decoded basic blocks otherwise, the
    /// same cycles and results as [`Engine::Interp`]. It runs one core at a time; with both
    /// cores running and [`Config::own_banks`] set, the core behind runs ahead in its own
    /// banks ([`crate::accel`], "Windows") and the interpreter's lock-step turns run where
    /// that is not possible, as while functions are profiled with [`crate::Board::profile_addr`].
    #[default]
    Block,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            clock_hz: 133_000_000,
            svc_halts: false,
            stop_on_fault: true,
            engine: Engine::default(),
            own_banks: [0, 0],
        }
    }
}
