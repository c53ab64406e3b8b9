//! The RP2040 board: two cores and the system, run in lock-step, plus the host API (load,
//! run for N cycles, read/write memory, feed sensors, read forces, count cycles per function).
//!
//! **Lock-step.** Each core has its own cycle counter; the board always executes the next
//! instruction of the core whose counter is lower (core 0 on a tie), so every shared-state
//! access (SRAM banks, SIO FIFOs, spinlocks, timer) happens in global cycle order and a run
//! is a pure function of the initial state: deterministic, whatever the host. A sleeping core
//! (WFI/WFE) skips ahead to the next cycle at which something could wake it. Core 1 starts
//! parked in the boot ROM's launch protocol (RP2040 datasheet 2.8.2): it echoes the FIFO
//! sequence `0, 0, 1, vector table, stack pointer, entry` and then starts.
//!
//! **Speed.** [`Board::run_until`] lets the core whose turn it is run a burst of
//! instructions until it gets ahead of the other core, taking instructions from a
//! direct-mapped decode cache that also holds their timing-table costs and a pre-decoded
//! form (module `fast`); a store into an SRAM page holding cached code, or any host write,
//! invalidates the cache (an epoch), so self-modifying code stays correct. Interrupt lines
//! are recomputed only when a peripheral was accessed or a timer event is due. Once a core
//! is in a state where its next instructions cannot take an exception (running, Thumb,
//! nothing takeable pending, the current interrupt lines already pending on it), the fast
//! path runs it in a tight loop (`Core::execute_op`): common instructions with SRAM and
//! flash accesses complete there; anything else (peripherals, SIO, PPB, faults, sleep,
//! SEV, SVC, exception return, a cache miss) runs through the general path and ends the
//! loop, after which every condition is checked again — except a single load that leaves
//! every such condition as it was (a timer read: no event, the same interrupt-line epoch,
//! timer event and SysTick wrap), after which the loop goes on as the board would. The loop also stops at each core's
//! deadline: the run's limit, the next timer event and its next SysTick wrap. With both
//! cores running, one loop alternates between them in the lock-step order (whichever is
//! behind, core 0 on ties); with one core asleep and nothing able to wake it, the loop runs
//! the other core and moves the sleeper's cycle counter exactly as its sleep steps would.
//! While functions are profiled, the loop also stops after any instruction that lands on a
//! profiled entry or on the return address of the innermost open call, the only places
//! where the per-instruction profiling bookkeeping can do anything; exception handlers
//! profiled with [`Board::profile_handler`] are entered and left only by exception entry
//! and return, in the general path, so they cost the loop no such check.
//! So the order of all shared-state accesses, and every result, is the same as stepping
//! one instruction at a time.
//!
//! **Running ahead** ([`Config::own_banks`], block engine only). With both cores on the
//! fast path, lock-step turns last an instruction or two. Instead, the core that is behind
//! (A) runs a *window* of compiled code ahead, *confined* to its own SRAM banks S_A: every
//! load and store, and every instruction fetch from SRAM, is checked against S_A and the
//! code leaves before an instruction that would touch anything else (another bank,
//! SIO, a peripheral, the PPB; flash and ROM are read-only and always allowed), and every
//! store journals the word it overwrites. The window ends where A leaves, at the first
//! deadline of either core (the run's limit, the next timer event, either core's SysTick),
//! or when the journal is full. Then the other core (B) catches up to A's cycle (one past
//! it when B is core 0, which goes first on a tie) confined to the *other* banks. If B
//! gets there, the window is kept; if B stops before (it needs one of A's banks, SIO, a
//! peripheral, an exception, a sleep, a fetch from A's banks), A is rolled back — its
//! stores undone from the journal, newest first, its bank claims, stall count and core
//! state restored — and the cores go on in lock-step from there, B's instructions
//! standing. *Why this is the lock-step result:* in the window A touches only S_A, B
//! touches none of S_A, and neither touches anything else the other can see (no SIO, no
//! peripheral, no interrupt line, no event: those leave; the timer has no event and no
//! SysTick wraps before the window's end; nothing is fetched from a bank the other core
//! writes). So no word either core reads is written by the other in the window, and an
//! access's arbitration depends only on the other core's last claim of the *same* bank,
//! which the other core does not change in the window: it is the value it had at the
//! window's start, whichever order the two cores' instructions run in. The instructions of
//! the two cores in the window therefore commute, and running all of A's before all of
//! B's gives the registers, memory, cycles and stalls of the interleaved order. A rollback
//! is exact for the same reason: B's instructions commute with A's, and A re-runs from
//! the same state. Tests: `tests/block_engine.rs` (random two-core programs on own banks
//! with shared, other-bank and SIO traffic, SysTick, WFI/WFE/SEV; the own-bank speed
//! loop), `firmware/tests/image.rs` (an image of every shipped instrument, both cores). [`Config::engine`] selects what runs that fast path for one
//! core: the interpreter above ([`Engine::Interp`]) or the block engine ([`Engine::Block`],
//! the default; module [`crate::block`]: code regions compiled to native code with
//! cranelift, pre-decoded basic blocks where they do not fit; the same results).
//! [`Board::step`] is the same machine one instruction at a time, recording
//! [`Core::last`] for traces.
//!
//! **Sensors and DAC.** Firmware sees the key sensors and the motor drivers the way a DMA from
//! SPI converters would leave them: word arrays in SRAM at [`SENSOR_BASE`] and [`DAC_BASE`],
//! one 32-bit word per key (ADC sample, or DAC code, in the low 16 bits). The host writes
//! sensors and reads forces with [`Board::set_sensor`] / [`Board::dac`], which cost the
//! cores nothing; firmware loads and stores them as ordinary SRAM (2 cycles, bank 3:2
//! striping and contention apply). Link firmware so nothing else lives there.

use crate::block::{self, Blocks};
use crate::bus::{sram_location, Bus, System, ALL_BANKS, SRAM_END};
use crate::core::{Core, Event, Fault, RunState};
use crate::decode::{decode, Instr};
use crate::elf::{self, ElfError, Image};
use crate::fast::Op;
use crate::nvic::{IRQ0, SVCALL};
use crate::timing::cycles;
use std::fmt;

/// Sensor block: `MAX_KEYS` words from 0x2003f000 (last 4 KB of striped SRAM), word k = key
/// k's latest ADC sample.
pub const SENSOR_BASE: u32 = 0x2003_f000;
/// DAC block: `MAX_KEYS` words from 0x2003f400, word k = the force (DAC code) for key k's
/// motor.
pub const DAC_BASE: u32 = 0x2003_f400;
/// Keys the sensor and DAC blocks have room for.
pub const MAX_KEYS: usize = 128;

/// Board configuration.
#[derive(Clone, Debug)]
pub struct Config {
    /// System clock in Hz (RP2040: 133 MHz); drives the microsecond timer.
    pub clock_hz: u64,
    /// Stop [`Board::run_until`] at every SVC with [`StopReason::Svc`] (for host calls such as a
    /// test harness's `write`/`exit`) instead of taking the SVCall exception.
    pub svc_halts: bool,
    /// Stop [`Board::run_until`] with [`StopReason::Fault`] after a core takes a HardFault, instead
    /// of running the firmware's HardFault handler.
    pub stop_on_fault: bool,
    /// Which engine runs the fast path of [`Board::run_until`] / [`Board::run_for`]
    /// (default [`Engine::Block`], the faster: see BENCHMARKS.md, "the block compiler").
    /// Both give the same cycles, registers and memory; [`Board::step`] is always the
    /// general path.
    pub engine: Engine,
    /// The SRAM banks each core may run ahead in (bit per bank: 0-3 SRAM0-3, 4 SRAM4,
    /// 5 SRAM5). With both cores running on [`Engine::Block`], the core that is behind may
    /// run compiled code ahead of the other while it touches only its own banks, the other
    /// then catching up while it touches none of them (see "Running ahead" in this
    /// module). Default `[0, 0]`: the two cores in lock-step on the interpreter — on the
    /// firmware images, whose own banks are [`FIRMWARE_OWN_BANKS`], running ahead cost more
    /// than it saved (BENCHMARKS.md, issue 18: the README demo took 53.6 CPU-s with it and
    /// 45.2 without, the same strikes). Results never depend on it, only speed.
    pub own_banks: [u8; 2],
}

/// The banks each core of a firmware image owns (`tactus-firmware`, `image/mod.rs`: core 0
/// SRAM0 and SRAM4, core 1 SRAM1 and SRAM5), for [`Config::own_banks`].
pub const FIRMWARE_OWN_BANKS: [u8; 2] = [0b01_0001, 0b10_0010];

/// The engine behind [`Board::run_until`]'s fast path.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Engine {
    /// The interpreter: one instruction at a time from the decode cache (module `fast`).
    Interp,
    /// The block engine (module [`crate::block`]): code regions compiled to native code
    /// with cranelift (module `jit`) once warm, pre-decoded basic blocks otherwise, the
    /// same cycles and results as [`Engine::Interp`]. It runs one core at a time; with both
    /// cores running and [`Config::own_banks`] set, the core behind runs ahead in its own
    /// banks ("Running ahead" in [`crate::board`]) and the interpreter's lock-step turns run where
    /// that is not possible, as while functions are profiled with [`Board::profile_addr`].
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

/// Why [`Board::run_until`] returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// Both cores reached the cycle limit.
    CycleLimit,
    /// A core executed SVC with [`Config::svc_halts`] set (its PC is past the SVC).
    Svc {
        /// The core.
        core: usize,
        /// The SVC immediate.
        imm: u8,
    },
    /// A core faulted (with [`Config::stop_on_fault`]); it has entered its HardFault handler.
    Fault {
        /// The core.
        core: usize,
        /// The fault.
        fault: Fault,
    },
    /// A core locked up (fault while handling HardFault, or failed stacking).
    Lockup {
        /// The core.
        core: usize,
        /// The fault.
        fault: Fault,
    },
    /// No core can run (all parked or locked up).
    Idle,
    /// The emulator refused what a core did: a clock or voltage write that would run clk_sys
    /// faster than the core voltage allows (`crate::clocks`). The store faulted.
    Refused {
        /// The core.
        core: usize,
        /// Why.
        why: crate::clocks::Refusal,
    },
}

/// Where [`Board::call`] puts its return stub: the last word of SRAM (the stack given to a
/// call must be below it).
pub const CALL_STUB: u32 = SRAM_END - 4;

/// What a function called with [`Board::call`] returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CallResult {
    /// r0 at return (the AAPCS result word).
    pub r0: u32,
    /// r1 at return (the high word of a 64-bit result).
    pub r1: u32,
    /// Cycles from the first instruction to the return, the return included.
    pub cycles: u64,
}

/// Why [`Board::call`] did not return normally.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CallError {
    /// The board stopped before the function returned.
    Stopped {
        /// Why it stopped.
        reason: StopReason,
        /// The core's PC then.
        pc: u32,
    },
    /// A host access failed.
    Emu(EmuError),
}

impl fmt::Display for CallError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CallError::Stopped { reason, pc } => {
                write!(
                    f,
                    "the called function did not return: {reason:?} at pc {pc:#010x}"
                )
            }
            CallError::Emu(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for CallError {}

/// A host-side error.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EmuError {
    /// The ELF file could not be loaded.
    Elf(ElfError),
    /// A host access to an address outside ROM, flash and SRAM.
    Unmapped(u32),
    /// No symbol of that name.
    NoSymbol(String),
    /// The boot ROM's check of boot2 failed (`crate::xip::check_boot2`).
    Boot2Checksum {
        /// CRC-32 of the first 252 bytes of flash.
        computed: u32,
        /// The word stored after them.
        stored: u32,
    },
}

impl fmt::Display for EmuError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EmuError::Elf(e) => e.fmt(f),
            EmuError::Unmapped(a) => write!(f, "no memory at {a:#010x}"),
            EmuError::NoSymbol(s) => write!(f, "no symbol named `{s}`"),
            EmuError::Boot2Checksum { computed, stored } => write!(
                f,
                "the boot ROM rejects boot2 (the first 256 bytes of flash): their CRC-32 is \
                 {computed:#010x} but the last word says {stored:#010x}; on the chip the ROM \
                 retries 128 times and then starts USB boot (BOOTSEL mode) instead of the image"
            ),
        }
    }
}

impl std::error::Error for EmuError {}

impl From<ElfError> for EmuError {
    fn from(e: ElfError) -> Self {
        EmuError::Elf(e)
    }
}

/// One measured call of a profiled function.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Call {
    /// Core that made the call.
    pub core: usize,
    /// Cycle at which the function's first instruction started.
    pub start: u64,
    /// Cycles from the function's first instruction to the first instruction after its
    /// return (the return instruction and any exception taken meanwhile included; the call
    /// instruction excluded).
    pub cycles: u64,
}

#[derive(Clone, Debug)]
struct Profile {
    entry: u32,
    /// Measures only activations entered by exception entry ([`Board::profile_handler`]):
    /// the fast path need not watch the entry, which only the general path reaches then.
    handler_only: bool,
    /// Open calls per core: (return address or exception number, SP at entry, start cycle).
    open: [Vec<(Return, u32, u64)>; 2],
    calls: Vec<Call>,
    /// Times the entry was reached (calls open or completed, both cores).
    entries: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Return {
    To(u32),
    FromException(u32),
}

/// Where core 1's boot ROM is in its wait loop (pico-bootrom `bootrom/bootrom_rt0.S`,
/// `wait_for_vector`; RP2040 datasheet 2.8.2): the next word it waits for, the VTOR and
/// stack pointer received so far, and a word it could not yet send because core 0's RX
/// FIFO was full (the ROM waits in `WFE` for room, `send_and_then_again`).
#[derive(Clone, Copy, Debug, Default)]
struct Launch {
    /// 0: the command 1; 1: the vector table; 2: the stack pointer; 3: the entry point;
    /// 4: launching once the entry point's echo is sent.
    step: usize,
    vtor: u32,
    sp: u32,
    entry: u32,
    unsent: Option<u32>,
}

/// Decode cache entry: the instruction, its pre-decoded fast-path form and its size,
/// tagged by its address and the code epoch.
#[derive(Clone, Copy)]
struct Cached {
    /// [`cache_key`] of the address and the [`System::code_epoch`] when decoded.
    key: u64,
    op: Op,
    instr: Instr,
    size: u32,
    /// Cycles from the timing table: (not taken, taken).
    cost: (u8, u8),
}

/// Decode cache tag: the instruction's address and the code epoch in one word (addresses
/// are even, so the empty tag `u64::MAX` never matches).
#[inline(always)]
fn cache_key(pc: u32, epoch: u32) -> u64 {
    (epoch as u64) << 32 | pc as u64
}

const CACHE_SLOTS: usize = 1 << 14;

/// The emulated RP2040.
pub struct Board {
    /// Configuration.
    pub config: Config,
    /// The two cores.
    pub cores: [Core; 2],
    /// Memories and peripherals.
    pub system: System,
    /// The loaded image's symbols etc. (empty until [`Board::load_elf`]).
    pub image: Image,
    profiles: Vec<Profile>,
    launch: Option<Launch>,
    cache: Box<[Cached; CACHE_SLOTS]>,
    blocks: Blocks,
    /// Run-ahead windows kept, rolled back and partly kept ([`Board::run_ahead_windows`]).
    windows: [u64; 3],
    /// Each core's active exceptions at its last [`Board::profile_step`] that ran its loop
    /// (`u64::MAX`, which no core has, before any).
    profiled_active: [u64; 2],
    /// No profile watches an address (none, or handler profiles only): the fast path's
    /// watch sets are empty ([`Board::watch_set`]).
    watch_free: bool,
    /// Interrupt lines as of `lines_epoch` (a [`System::irq_epoch`] value).
    lines: u32,
    lines_epoch: u64,
}

impl Board {
    /// A board with zeroed memory and both cores parked (core 1 in the launch protocol).
    pub fn new(config: Config) -> Self {
        let system = System::new(config.clock_hz);
        let mut cores = [Core::new(0), Core::new(1)];
        for c in &mut cores {
            // SysTick's reference: the 1 µs pulse of the watchdog's tick generator.
            c.nvic.clock_hz = config.clock_hz;
        }
        let mut board = Board {
            config,
            cores,
            system,
            image: Image::default(),
            profiles: Vec::new(),
            launch: None,
            lines: 0,
            profiled_active: [u64::MAX; 2],
            watch_free: true,
            lines_epoch: u64::MAX,
            blocks: Blocks::new(),
            windows: [0; 3],
            cache: vec![
                Cached {
                    key: u64::MAX,
                    op: Op::Other,
                    instr: Instr::Undefined { hw1: 0, hw2: 0 },
                    size: 2,
                    cost: (0, 0)
                };
                CACHE_SLOTS
            ]
            .into_boxed_slice()
            .try_into()
            .unwrap_or_else(|_| unreachable!()),
        };
        // Core 1 reaches `wait_for_vector` a few cycles after reset, long before core 0
        // can send anything: its first handshake is part of the power-on state.
        board.launch = Some(Launch::default());
        board.launch_handshake();
        board
    }

    /// Parses and loads an ELF executable, then starts core 0: from its vector table if the
    /// image has one (`.vectors`/`.vector_table`/`.isr_vector` section), else at the entry
    /// point with SP at the top of SRAM.
    pub fn load_elf(&mut self, bytes: &[u8]) -> Result<(), EmuError> {
        let image = elf::parse(bytes)?;
        for seg in &image.segments {
            self.write_bytes(seg.addr, &seg.data).map_err(|_| {
                EmuError::Elf(ElfError::Unmapped {
                    addr: seg.addr,
                    size: seg.data.len() as u32,
                })
            })?;
        }
        match image.vector_table {
            _ if image.boot2 => self.boot_from_flash()?,
            Some(vt) => self.boot_from_vectors(0, vt)?,
            None => self.enter_ram_image(image.entry),
        }
        self.image = image;
        Ok(())
    }

    /// Powers the board on from flash, as the boot ROM's flash path does on core 0
    /// (pico-bootrom `bootrom/bootrom_main.c`, `_flash_boot`): the SSI set to plain serial
    /// reads, the flash chip out of continuous-read mode, its first 256 bytes read into the
    /// top of SRAM5 ([`crate::xip::BOOT2_LOAD`]) and checked against their CRC-32
    /// ([`crate::xip::check_boot2`]), and core 0 entered there in Thumb state with LR = 0
    /// ("entered from the boot ROM": boot2 then enters the image through the vector table at
    /// 0x10000100) and SP at the ROM's stack top. Core 1 stays in the boot ROM's launch
    /// protocol. The flash holds what the host wrote (a UF2's blocks, an ELF's segments).
    ///
    /// SRAM powers up holding garbage: the rest of SRAM is filled with a fixed pseudo-random
    /// pattern, so firmware that relies on zeroed SRAM fails here as on the chip. The boot
    /// ROM's own instructions are not run: core 0 enters boot2 at the board's current cycle.
    ///
    /// Errors: [`EmuError::Boot2Checksum`] (the chip's ROM would retry and start USB boot).
    pub fn boot_from_flash(&mut self) -> Result<(), EmuError> {
        let mut x = 0x2545_f491u32;
        for w in self.system.sram.chunks_mut(4) {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            for (b, v) in w.iter_mut().zip(x.to_le_bytes()) {
                *b = v;
            }
        }
        self.system.invalidate_code();
        self.system.xip.power_on();
        let boot2 = self.system.xip.boot_rom_read_boot2(&self.system.flash);
        self.write_bytes(crate::xip::BOOT2_LOAD, &boot2)?;
        self.system.refresh_xip();
        if let Err((computed, stored)) = crate::xip::check_boot2(&boot2) {
            return Err(EmuError::Boot2Checksum { computed, stored });
        }
        let core = &mut self.cores[0];
        core.reset_to(crate::xip::BOOT2_LOAD | 1, crate::xip::BOOT_ROM_STACK_TOP);
        core.r[14] = 0;
        core.nvic.vtor = 0;
        Ok(())
    }

    /// `stop` in words, with what the emulator knows beyond it: why a refused write was
    /// refused, why a bus fault in the flash window found no flash (the XIP path's state,
    /// `crate::xip`), and where the cores were.
    pub fn describe_stop(&self, stop: &StopReason) -> String {
        let pcs = format!(
            "core pcs {:#010x}, {:#010x}",
            self.cores[0].r[15], self.cores[1].r[15]
        );
        match stop {
            StopReason::Refused { core, why } => format!("core {core}: refused: {why} ({pcs})"),
            StopReason::Fault { core, fault } | StopReason::Lockup { core, fault } => {
                let what = if matches!(stop, StopReason::Fault { .. }) {
                    "HardFault"
                } else {
                    "locked up"
                };
                let mut s = format!("core {core} {what}: {fault}");
                if let crate::core::FaultKind::Bus { addr } = fault.kind {
                    let flash = addr.wrapping_sub(crate::bus::FLASH_BASE) < crate::bus::FLASH_SIZE;
                    if let (true, Some(why)) = (flash, self.system.xip_error()) {
                        s.push_str(&format!(" (the XIP window does not read the flash: {why})"));
                    }
                }
                format!("{s} ({pcs})")
            }
            other => format!("{other:?} ({pcs})"),
        }
    }

    /// Starts core 0 at `entry` (Thumb bit set) with SP at the top of SRAM and VTOR 0 (the
    /// boot ROM's table), as the boot ROM enters a RAM image after a UF2 download: it
    /// reboots through the watchdog with `entry` = the lowest address the UF2 wrote and
    /// SP = 0x20042000 (pico-bootrom `bootrom/virtual_disk.c`,
    /// `safe_reboot(lowest_addr, SRAM_END, …)`; `bootrom/bootrom_rt0.S`, `check_wdog`).
    /// Core 1 stays in the boot ROM's launch protocol.
    pub fn enter_ram_image(&mut self, entry: u32) {
        self.cores[0].reset_to(entry, SRAM_END);
        self.cores[0].nvic.vtor = 0;
    }

    /// Starts `core` from the vector table at `vtor` (SP = word 0, PC = word 1), as the boot
    /// ROM does; the core stops taking part in the launch protocol.
    pub fn boot_from_vectors(&mut self, core: usize, vtor: u32) -> Result<(), EmuError> {
        let sp = self.read_u32(vtor)?;
        let pc = self.read_u32(vtor.wrapping_add(4))?;
        self.start_core(core, pc, sp, vtor);
        Ok(())
    }

    /// Starts `core` at `pc` with stack pointer `sp` and VTOR `vtor`, at the current cycle,
    /// as a debugger would. Core 1 taken from the boot ROM's wait loop this way is started
    /// as if it had never entered it: what the ROM sent core 0 (its handshake 0) is
    /// withdrawn from core 0's RX FIFO. (A launch over the FIFOs keeps the echoes.)
    pub fn start_core(&mut self, core: usize, pc: u32, sp: u32, vtor: u32) {
        if core == 1 && self.launch.is_some() {
            while self.system.sio.fifo_status(0) & 1 != 0 {
                self.system.sio.fifo_pop(0);
            }
        }
        self.start_core_at(core, pc, sp, vtor);
    }

    fn start_core_at(&mut self, core: usize, pc: u32, sp: u32, vtor: u32) {
        let now = self.cores[1 - core].cycle.max(self.cores[core].cycle);
        let c = &mut self.cores[core];
        c.cycle = now;
        c.reset_to(pc, sp);
        c.nvic.vtor = vtor;
        if core == 1 {
            self.launch = None;
        }
    }

    /// Address of symbol `name` in the loaded image.
    pub fn symbol(&self, name: &str) -> Result<u32, EmuError> {
        self.image
            .symbol(name)
            .map(|s| s.addr)
            .ok_or_else(|| EmuError::NoSymbol(name.to_string()))
    }

    // ---- host memory access (no cycles, no contention) ----

    /// Reads bytes without side effects or cycles (ROM, flash, SRAM only).
    pub fn read_bytes(&mut self, addr: u32, out: &mut [u8]) -> Result<(), EmuError> {
        // Words of one SRAM view (the records and windows a harness reads every sample):
        // no address decode per word.
        if let Some((off, stride)) = u32::try_from(out.len())
            .ok()
            .and_then(|n| crate::bus::sram_word_run(addr, n))
        {
            let sram = &self.system.sram;
            for (i, w) in out.chunks_exact_mut(4).enumerate() {
                let o = off as usize + stride as usize * i;
                w.copy_from_slice(&sram[o..o + 4]);
            }
            return Ok(());
        }
        // Whole aligned words map to four consecutive bytes of one memory (the regions and
        // the SRAM banks' words are aligned): one address decode per word.
        if addr & 3 == 0 && out.len().is_multiple_of(4) {
            for (i, w) in out.chunks_exact_mut(4).enumerate() {
                let a = addr.wrapping_add(4 * i as u32);
                let (mem, off) = self.system.backing(a).ok_or(EmuError::Unmapped(a))?;
                w.copy_from_slice(&mem[off..off + 4]);
            }
            return Ok(());
        }
        for (i, b) in out.iter_mut().enumerate() {
            let a = addr.wrapping_add(i as u32);
            let (mem, off) = self.system.backing(a).ok_or(EmuError::Unmapped(a))?;
            *b = mem[off];
        }
        Ok(())
    }

    /// Writes bytes without cycles (ROM, flash, SRAM only), as a loader or DMA would.
    pub fn write_bytes(&mut self, addr: u32, data: &[u8]) -> Result<(), EmuError> {
        self.write_data(addr, data)?;
        self.system.invalidate_code();
        Ok(())
    }

    /// Writes data bytes without cycles and without invalidating decoded code: for buffers
    /// the host refills often (sensor words, arguments). The caller guarantees that no
    /// instruction lives in the range (else the core may run stale code).
    pub fn write_data(&mut self, addr: u32, data: &[u8]) -> Result<(), EmuError> {
        if let Some((off, stride)) = u32::try_from(data.len())
            .ok()
            .and_then(|n| crate::bus::sram_word_run(addr, n))
        {
            let sram = &mut self.system.sram;
            for (i, w) in data.chunks_exact(4).enumerate() {
                let o = off as usize + stride as usize * i;
                sram[o..o + 4].copy_from_slice(w);
            }
            return Ok(());
        }
        // Whole aligned words: one address decode per word, as in `read_bytes`.
        if addr & 3 == 0 && data.len().is_multiple_of(4) {
            for (i, w) in data.chunks_exact(4).enumerate() {
                let a = addr.wrapping_add(4 * i as u32);
                let (mem, off) = self.system.backing(a).ok_or(EmuError::Unmapped(a))?;
                mem[off..off + 4].copy_from_slice(w);
            }
            return Ok(());
        }
        for (i, b) in data.iter().enumerate() {
            let a = addr.wrapping_add(i as u32);
            let (mem, off) = self.system.backing(a).ok_or(EmuError::Unmapped(a))?;
            mem[off] = *b;
        }
        Ok(())
    }

    /// Reads `out.len()` little-endian words from `addr`, `addr + 4`, … (host access, no
    /// cycles): [`Board::read_bytes`] without the byte buffer — a harness reading records
    /// and windows every sample takes the words straight from SRAM when they lie in one
    /// view (striped, SRAM4/5, one bank of the non-striped alias). Errors: as
    /// [`Board::read_bytes`].
    pub fn read_words(&mut self, addr: u32, out: &mut [u32]) -> Result<(), EmuError> {
        let run = u32::try_from(out.len())
            .ok()
            .and_then(|n| n.checked_mul(4))
            .and_then(|len| crate::bus::sram_word_run(addr, len));
        if let Some((off, stride)) = run {
            // One bounds check for the run, then a word per `stride` bytes.
            let (off, stride) = (off as usize, stride as usize);
            let end = off + stride * out.len().saturating_sub(1) + 4;
            if let Some(region) = self.system.sram.get(off..end) {
                for (w, c) in out.iter_mut().zip(region.chunks(stride)) {
                    *w = u32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                }
                return Ok(());
            }
        }
        for (i, w) in out.iter_mut().enumerate() {
            *w = self.read_u32(addr.wrapping_add(4 * i as u32))?;
        }
        Ok(())
    }

    /// Writes `words` little-endian at `addr`, `addr + 4`, … without cycles and, like
    /// [`Board::write_data`], without invalidating decoded code (for the sensor words a
    /// harness refills every sample; no instruction may live there). Errors: as
    /// [`Board::write_data`].
    pub fn write_words(&mut self, addr: u32, words: &[u32]) -> Result<(), EmuError> {
        let run = u32::try_from(words.len())
            .ok()
            .and_then(|n| n.checked_mul(4))
            .and_then(|len| crate::bus::sram_word_run(addr, len));
        if let Some((off, stride)) = run {
            let sram = &mut self.system.sram;
            for (i, w) in words.iter().enumerate() {
                let o = off as usize + stride as usize * i;
                sram[o..o + 4].copy_from_slice(&w.to_le_bytes());
            }
            return Ok(());
        }
        for (i, w) in words.iter().enumerate() {
            self.write_data(addr.wrapping_add(4 * i as u32), &w.to_le_bytes())?;
        }
        Ok(())
    }

    /// Reads a little-endian word (host access).
    pub fn read_u32(&mut self, addr: u32) -> Result<u32, EmuError> {
        let mut b = [0; 4];
        self.read_bytes(addr, &mut b)?;
        Ok(u32::from_le_bytes(b))
    }

    /// Writes a little-endian word (host access).
    pub fn write_u32(&mut self, addr: u32, value: u32) -> Result<(), EmuError> {
        self.write_bytes(addr, &value.to_le_bytes())
    }

    /// Sets key `key`'s sensor word (what the sensor DMA would deliver). Panics-free: keys
    /// beyond [`MAX_KEYS`] are an error.
    pub fn set_sensor(&mut self, key: usize, value: u32) -> Result<(), EmuError> {
        if key >= MAX_KEYS {
            return Err(EmuError::Unmapped(SENSOR_BASE + 4 * key as u32));
        }
        self.write_u32(SENSOR_BASE + 4 * key as u32, value)
    }

    /// Key `key`'s DAC word (the force the firmware last wrote).
    pub fn dac(&mut self, key: usize) -> Result<u32, EmuError> {
        if key >= MAX_KEYS {
            return Err(EmuError::Unmapped(DAC_BASE + 4 * key as u32));
        }
        self.read_u32(DAC_BASE + 4 * key as u32)
    }

    // ---- calling a function from the host ----

    /// Calls the Thumb function at `addr` on `core` as AAPCS code would (arguments in r0–r3,
    /// at most 4), with the stack at `sp`, and runs until it returns or `limit` cycles pass.
    ///
    /// The return address is a stub at [`CALL_STUB`] (an `SVC #0xCA`, written by this call)
    /// that stops the board; the other core keeps running meanwhile. Returns r0 and r1 and the
    /// cycles from the function's first instruction to its return (the return instruction
    /// included, the stub and the caller's `BL` not: add 3 for a `BL`, Cortex-M0+ TRM 3.3).
    ///
    /// Errors: [`CallError::Stopped`] when the function faults, hits the cycle limit or the
    /// board stops for another reason; [`CallError::Emu`] when the stub cannot be written.
    pub fn call(
        &mut self,
        core: usize,
        addr: u32,
        args: &[u32],
        sp: u32,
        limit: u64,
    ) -> Result<CallResult, CallError> {
        const STUB_SVC: u8 = 0xca;
        // Rewriting an unchanged stub would empty the decode cache on every call.
        let stub = [STUB_SVC, 0xdf, 0, 0xbe];
        let mut now = [0u8; 4];
        self.read_bytes(CALL_STUB, &mut now)
            .map_err(CallError::Emu)?;
        if now != stub {
            self.write_bytes(CALL_STUB, &stub).map_err(CallError::Emu)?;
        }
        let halts = std::mem::replace(&mut self.config.svc_halts, true);
        let c = &mut self.cores[core];
        c.reset_to(addr | 1, sp);
        for (i, a) in args.iter().take(4).enumerate() {
            c.r[i] = *a;
        }
        c.r[14] = CALL_STUB | 1;
        let start = c.cycle;
        let stop = self.run_until(start.saturating_add(limit));
        self.config.svc_halts = halts;
        let c = &self.cores[core];
        match stop {
            StopReason::Svc { core: k, imm } if k == core && imm == STUB_SVC => {
                let svc = cycles(&Instr::Svc { imm }, false, false) as u64;
                Ok(CallResult {
                    r0: c.r[0],
                    r1: c.r[1],
                    cycles: c.cycle - start - svc,
                })
            }
            other => Err(CallError::Stopped {
                reason: other,
                pc: c.r[15],
            }),
        }
    }

    // ---- profiling ----

    /// A new profile of the code at `addr` (Thumb bit ignored); its handle.
    fn add_profile(&mut self, addr: u32, handler_only: bool) -> usize {
        self.profiled_active = [u64::MAX; 2];
        self.watch_free &= handler_only;
        self.profiles.push(Profile {
            entry: addr & !1,
            handler_only,
            open: [Vec::new(), Vec::new()],
            calls: Vec::new(),
            entries: 0,
        });
        self.profiles.len() - 1
    }

    /// Starts measuring every call of the function at `addr` (Thumb bit ignored) on both
    /// cores; see [`Board::calls`]. Returns a handle.
    pub fn profile_addr(&mut self, addr: u32) -> usize {
        self.add_profile(addr, false)
    }

    /// Starts measuring the exception handler at `addr` (Thumb bit ignored) on both cores:
    /// like [`Board::profile_addr`], but only activations entered by exception entry are
    /// measured (from the handler's first instruction to the first instruction after the
    /// exception return that deactivates it, as `profile_addr` measures them); a branch or
    /// call to `addr` is not. Both ends of such an activation are exception entry and
    /// return, which the general path executes, so unlike `profile_addr` this costs the
    /// fast path nothing: use it for interrupt handlers. Returns a handle for
    /// [`Board::calls`].
    pub fn profile_handler(&mut self, addr: u32) -> usize {
        self.add_profile(addr, true)
    }

    /// Starts measuring the function named `name`.
    pub fn profile(&mut self, name: &str) -> Result<usize, EmuError> {
        let addr = self.symbol(name)?;
        Ok(self.profile_addr(addr))
    }

    /// The completed calls of profiled function `handle`.
    pub fn calls(&self, handle: usize) -> &[Call] {
        self.profiles.get(handle).map_or(&[], |p| &p.calls)
    }

    /// How many times the entry of profiled address `handle` has been reached (0 for an
    /// unknown handle). Unlike [`Board::calls`], which completes a call when control returns
    /// to the link register it was entered with, this counts a block that is not a function
    /// (a code generator's `BL` long branches change LR inside one) at the moment it runs.
    pub fn entries(&self, handle: usize) -> u64 {
        self.profiles.get(handle).map_or(0, |p| p.entries)
    }

    /// Forgets the completed calls of profiled function `handle` (read them with
    /// [`Board::calls`] first); measuring continues. Long runs call this now and then so the
    /// record does not grow without bound. An unknown handle is ignored.
    pub fn clear_calls(&mut self, handle: usize) {
        if let Some(p) = self.profiles.get_mut(handle) {
            p.calls.clear();
        }
    }

    fn profile_step(&mut self, k: usize) {
        let core = &self.cores[k];
        let (pc, sp, now) = (core.r[15], core.r[13], core.cycle);
        // Handler profiles only, the core's active exceptions as at this core's last call
        // and no profiled entry at the PC: no activation can open or close (an open one
        // closes when its exception's active bit clears; one opens at an entry), so the
        // loop below would do nothing.
        if self.profiled_active[k] == core.nvic.active
            && self
                .profiles
                .iter()
                .all(|p| p.handler_only && p.entry != pc)
        {
            return;
        }
        self.profiled_active[k] = core.nvic.active;
        for p in &mut self.profiles {
            while let Some(&(ret, entry_sp, start)) = p.open[k].last() {
                let done = match ret {
                    Return::To(addr) => pc == addr && sp >= entry_sp,
                    Return::FromException(exc) => core.nvic.active & (1 << exc) == 0,
                };
                if !done {
                    break;
                }
                p.open[k].pop();
                p.calls.push(Call {
                    core: k,
                    start,
                    cycles: now - start,
                });
            }
            if pc == p.entry && core.thumb {
                p.entries += 1;
                let lr = core.r[14];
                let ret = if lr >> 28 == 0xf && core.ipsr != 0 {
                    Return::FromException(core.ipsr)
                } else if p.handler_only {
                    continue;
                } else {
                    Return::To(lr & !1)
                };
                p.open[k].push((ret, sp, now));
            }
        }
    }

    // ---- running ----

    /// Basic blocks the block engine ([`Engine::Block`]) has decoded so far (0 with
    /// [`Engine::Interp`]): a block is decoded again after a store into a page holding
    /// decoded code or a host write drops them all.
    pub fn blocks_decoded(&self) -> u64 {
        self.blocks.decoded
    }

    /// Code regions the block engine has compiled to native code so far ([`crate::jit`]).
    pub fn regions_compiled(&self) -> u64 {
        let b = &self.blocks;
        let confined: u64 = b
            .confined
            .iter()
            .chain(&b.confined_solo)
            .map(|j| j.count)
            .sum();
        b.jit.count + b.solo.count + confined
    }

    /// Run-ahead windows so far ("Running ahead" in the module documentation): (kept,
    /// rolled back because the other core could not catch up confined). A window whose
    /// first part was kept ([`Board::run_ahead_partly_kept`]) counts in neither.
    pub fn run_ahead_windows(&self) -> (u64, u64) {
        (self.windows[0], self.windows[1])
    }

    /// Run-ahead windows of which only the part before the other core's stop was kept
    /// (the core that ran ahead rolled back and run again up to there).
    pub fn run_ahead_partly_kept(&self) -> u64 {
        self.windows[2]
    }

    /// The block engine compiles a code region to native code once its entry has been
    /// reached `times` times (default 16; 0 compiles every region at once — the tests use
    /// it to run everything natively). Results never depend on it, only speed.
    pub fn set_compile_threshold(&mut self, times: u32) {
        self.blocks.jit.threshold = times;
        self.blocks.solo.threshold = times;
        let b = &mut self.blocks;
        for j in b.confined.iter_mut().chain(b.confined_solo.iter_mut()) {
            j.threshold = times;
        }
    }

    /// Total cycles elapsed: the lower of the running cores' counters.
    pub fn cycle(&self) -> u64 {
        match self.next_core() {
            Some(k) => self.cores[k].cycle,
            None => self.cores[0].cycle.max(self.cores[1].cycle),
        }
    }

    /// Runs for `cycles` more cycles (from [`Board::cycle`]) or until a stop.
    pub fn run_for(&mut self, cycles: u64) -> StopReason {
        let limit = self.cycle().saturating_add(cycles);
        self.run_until(limit)
    }

    /// Runs until both running cores reach cycle `limit`, or a stop. Instructions are not
    /// split: each core stops at its first instruction boundary at or after `limit` (a
    /// multi-cycle instruction that starts before the limit completes).
    pub fn run_until(&mut self, limit: u64) -> StopReason {
        self.lines_epoch = u64::MAX; // the host may have touched SIO or the timer
        loop {
            let Some(k) = self.next_core() else {
                return StopReason::Idle;
            };
            let now = self.cores[k].cycle;
            if now >= limit {
                return StopReason::CycleLimit;
            }
            if self.cores[k].state != RunState::Running {
                match self.step(limit) {
                    Some(Ok(_)) => continue,
                    Some(Err(stop)) => return stop,
                    None => return StopReason::CycleLimit,
                }
            }
            // Both cores running the fast path: interleave them there, in lock-step order.
            if self.fast_ready(0) && self.fast_ready(1) {
                let deadline = |c: &Core| {
                    limit
                        .min(self.system.timer.next_event)
                        .min(c.nvic.syst_next)
                };
                let deadline = [deadline(&self.cores[0]), deadline(&self.cores[1])];
                let mut slots = NO_WATCHES;
                if let (true, Some(watch)) = (now < deadline[k], self.watch_sets(&mut slots)) {
                    let mut deadline = deadline;
                    if self.config.engine == Engine::Block
                        && watch[0][0] == NO_WATCH
                        && watch[1][0] == NO_WATCH
                        && self.config.own_banks[k] != 0
                    {
                        let retry = match self.run_ahead(k, deadline) {
                            Window::Kept => continue,
                            // The core behind needs the general path (or cold code) at
                            // once: a short lock-step stretch runs it.
                            Window::Idle => RETRY,
                            Window::RolledBack => RETRY,
                        };
                        // Lock-step for a while before the next attempt.
                        let now = self.cores[0].cycle.min(self.cores[1].cycle);
                        deadline = deadline.map(|d| d.min(now.saturating_add(retry)));
                    }
                    let (k, ran) = self.fast_run::<true>(k, deadline, watch);
                    if let Some(event) = ran {
                        if !self.profiles.is_empty() {
                            self.profile_step(k);
                        }
                        if let Some(stop) = self.handle_event(k, event) {
                            return stop;
                        }
                    }
                    continue;
                }
            }
            // Core k running the fast path while the other core sleeps and nothing can
            // wake it: the sleeper's steps only move its cycle counter, done in the loop.
            if self.fast_ready(k) && self.launch.is_none() && self.sleeps_soundly(1 - k) {
                let s = &self.cores[1 - k];
                let deadline = limit
                    .min(self.system.timer.next_event)
                    .min(self.cores[k].nvic.syst_next);
                let wake_check = limit
                    .min(self.system.timer.next_event)
                    .min(s.nvic.syst_next);
                if let (true, Some(watch)) = (now < deadline, self.watch_set(k)) {
                    let [c0, c1] = &mut self.cores;
                    let (sys, cache) = (&mut self.system, &self.cache);
                    let blocks = &mut self.blocks;
                    let on_blocks = self.config.engine == Engine::Block;
                    let run = match (k == 0, watch[0] == NO_WATCH) {
                        (true, true) if on_blocks => blocks_beside_sleeper::<false>(
                            c0, c1, sys, blocks, deadline, wake_check,
                        ),
                        (false, true) if on_blocks => {
                            blocks_beside_sleeper::<true>(c1, c0, sys, blocks, deadline, wake_check)
                        }
                        (true, true) => run_beside_sleeper::<false, false>(
                            c0, c1, sys, cache, deadline, wake_check, &watch,
                        ),
                        (true, false) => run_beside_sleeper::<false, true>(
                            c0, c1, sys, cache, deadline, wake_check, &watch,
                        ),
                        (false, true) => run_beside_sleeper::<true, false>(
                            c1, c0, sys, cache, deadline, wake_check, &watch,
                        ),
                        (false, false) => run_beside_sleeper::<true, true>(
                            c1, c0, sys, cache, deadline, wake_check, &watch,
                        ),
                    };
                    // Ok: the sleeper reached its wake check; Err: core k must leave.
                    if let Err(exit) = run {
                        if let Some(event) = self.finish_fast(k, exit) {
                            if !self.profiles.is_empty() {
                                self.profile_step(k);
                            }
                            if let Some(stop) = self.handle_event(k, event) {
                                return stop;
                            }
                        }
                    }
                    continue;
                }
            }
            // Core k keeps the turn while it stays behind the other core (core 0 on ties).
            let other = &self.cores[1 - k];
            let horizon = if active(other) {
                other.cycle + (k == 0) as u64
            } else {
                u64::MAX
            };
            let event = self.burst(k, horizon.min(limit));
            if let Some(stop) = self.handle_event(k, event) {
                return stop;
            }
        }
    }

    /// The core whose turn it is: the active core with the lower cycle, core 0 on ties.
    fn next_core(&self) -> Option<usize> {
        match (active(&self.cores[0]), active(&self.cores[1])) {
            (true, true) => Some((self.cores[1].cycle < self.cores[0].cycle) as usize),
            (true, false) => Some(0),
            (false, true) => Some(1),
            (false, false) => None,
        }
    }

    /// Runs core `k` while its cycle is below `horizon` and it is running; returns early with
    /// any event other than `None`. The fast path: interrupt lines are recomputed only when a
    /// peripheral was touched or a timer event is due, and instructions come from the
    /// decode cache with their cycle costs.
    fn burst(&mut self, k: usize, horizon: u64) -> Event {
        loop {
            let core = &mut self.cores[k];
            if core.cycle >= horizon || core.state != RunState::Running {
                return Event::None;
            }
            if self.system.irq_epoch != self.lines_epoch
                || core.cycle >= self.system.timer.next_event
            {
                let now = core.cycle;
                if self.launch.is_some() {
                    self.poll_launch();
                    if self.launch.is_none() {
                        return Event::None; // core 1 started: re-pick whose turn it is
                    }
                }
                self.lines = self.system.irq_lines(k, now);
                self.lines_epoch = self.system.irq_epoch;
            }
            // The fast path when it can run; a single general step otherwise.
            let slots;
            let watch = match self.watch_set(k) {
                _ if self.watch_free => Some(&NO_WATCHES),
                Some(w) => {
                    slots = [w; 2];
                    Some(&slots)
                }
                None => None,
            };
            if let (true, Some(watch)) = (self.fast_ready(k), watch) {
                let deadline = horizon
                    .min(self.system.timer.next_event)
                    .min(self.cores[k].nvic.syst_next);
                if self.cores[k].cycle < deadline {
                    let (_, ran) = self.fast_run::<false>(k, [deadline; 2], watch);
                    if let Some(event) = ran {
                        if !self.profiles.is_empty() {
                            self.profile_step(k);
                        }
                        if event != Event::None {
                            return event;
                        }
                    }
                    continue;
                }
            }
            let event = self.step_cached::<false>(k, self.lines);
            if !self.profiles.is_empty() {
                self.profile_step(k);
            }
            if event != Event::None {
                return event;
            }
        }
    }

    /// True when core `k`'s next instructions may take the fast path ([`Board::fast_run`]):
    /// it is running in Thumb state with no exception it could take, the interrupt lines
    /// are current and already pending on it (so the per-instruction "OR the lines into
    /// pending" of [`Board::step_cached`] would change nothing), and the XIP window reads
    /// the flash (the fast paths read flash bytes directly; without XIP only the general
    /// path's accesses fault as they must, `crate::xip`).
    /// Everything the fast path executes leaves these conditions true; everything that
    /// could change them leaves the fast path.
    #[inline]
    fn fast_ready(&self, k: usize) -> bool {
        let c = &self.cores[k];
        c.state == RunState::Running
            && c.thumb
            && c.nvic.takeable() == 0
            && ((self.lines as u64) << IRQ0) & !c.nvic.active & !c.nvic.pending == 0
            && self.lines_epoch == self.system.irq_epoch
            && self.system.xip_answers
    }

    /// The addresses at which core `k`'s fast path must stop for [`Board::profile_step`]
    /// (unused slots hold 1, which no PC equals), or `None` when there are too many. After
    /// any other instruction of the fast path `profile_step` would do nothing: no call can
    /// start (the PC is no profiled entry) and none can end (the PC is not the return
    /// address of the innermost open call, and a call ending with an exception return
    /// leaves the fast path anyway).
    #[inline(always)]
    fn watch_set(&self, k: usize) -> Option<[u32; WATCH_SLOTS]> {
        // Handler profiles ([`Board::profile_handler`]) watch nothing: they open and close
        // at exception entry and return, on the general path.
        if self.watch_free {
            return Some([NO_WATCH; WATCH_SLOTS]);
        }
        self.watched(k)
    }

    /// Both cores' watch sets ([`Board::watch_set`]): the constant empty sets when nothing
    /// is watched (no copy: the hot loop of [`Board::run_until`] passes them on by
    /// reference), else built in `slots`; `None` when there are too many.
    #[inline(always)]
    fn watch_sets<'a>(
        &self,
        slots: &'a mut [[u32; WATCH_SLOTS]; 2],
    ) -> Option<&'a [[u32; WATCH_SLOTS]; 2]> {
        if self.watch_free {
            return Some(&NO_WATCHES);
        }
        *slots = [self.watched(0)?, self.watched(1)?];
        Some(slots)
    }

    /// [`Board::watch_set`] when some profile watches an address.
    #[inline(never)]
    fn watched(&self, k: usize) -> Option<[u32; WATCH_SLOTS]> {
        let mut watch = [NO_WATCH; WATCH_SLOTS];
        let mut n = 0;
        for p in &self.profiles {
            let addrs = [
                (!p.handler_only).then_some(p.entry),
                match p.open[k].last() {
                    Some(&(Return::To(addr), _, _)) => Some(addr),
                    _ => None,
                },
            ];
            for a in addrs.into_iter().flatten() {
                *watch.get_mut(n)? = a;
                n += 1;
            }
        }
        Some(watch)
    }

    /// The fast path: runs core `k` (or, with `BOTH`, whichever core is behind, core 0 on
    /// ties: the lock-step order) while the core to run is below its `deadline` (its
    /// horizon, the next timer event and its next SysTick wrap; see [`Board::fast_ready`]
    /// for the other conditions). Instructions come from the decode cache and run through
    /// [`Core::execute_fast`]; the first one that needs the general path (a decode-cache
    /// miss, a peripheral access, anything that could fault or change exception state) is
    /// executed exactly as [`Board::step_cached`] would and ends the run, so the caller
    /// re-checks everything as before. Returns the core that ran last and its event.
    #[inline(always)]
    fn fast_run<const BOTH: bool>(
        &mut self,
        k: usize,
        deadline: [u64; 2],
        watch: &[[u32; WATCH_SLOTS]; 2],
    ) -> (usize, Option<Event>) {
        // Slots fill from the first: nothing to watch when it is empty.
        let unwatched = if BOTH {
            watch[0][0] == NO_WATCH && watch[1][0] == NO_WATCH
        } else {
            watch[k][0] == NO_WATCH
        };
        // Both cores running: lock-step turns of one or two instructions, too short for
        // a compiled region to fit in; the interpreter's loop below is the faster there
        // (BENCHMARKS.md, "the block compiler").
        // A short turn (the other core's cycle a few cycles on, as in `burst`) fits no
        // compiled region: the interpreter's loop costs less per call.
        if unwatched
            && !BOTH
            && self.config.engine == Engine::Block
            && deadline[k] >= self.cores[k].cycle.saturating_add(SHORT_TURN)
        {
            let (sys, blocks) = (&mut self.system, &mut self.blocks);
            let core = &mut self.cores[k];
            let exit = match block::run(core, sys, blocks, deadline[k], &mut block::Alone) {
                Ok(()) => Exit::Deadline,
                Err(_) => Exit::Miss,
            };
            return (k, self.finish_fast(k, exit));
        }
        let (cores, sys, cache) = (&mut self.cores, &mut self.system, &self.cache);
        let (k, exit) = match (BOTH, unwatched) {
            (true, true) => run_both::<false>(cores, sys, cache, deadline, watch),
            (true, false) => run_both::<true>(cores, sys, cache, deadline, watch),
            (false, true) => (
                k,
                run_one::<false>(&mut cores[k], sys, cache, deadline[k], &watch[k]),
            ),
            (false, false) => (
                k,
                run_one::<true>(&mut cores[k], sys, cache, deadline[k], &watch[k]),
            ),
        };
        (k, self.finish_fast(k, exit))
    }

    /// One window of running ahead (see "Running ahead" in the module documentation): core
    /// `a` (the one behind, both cores on the fast path with `deadline`s as in
    /// [`Board::run_until`]) runs compiled code confined to its own banks, the other core
    /// then catches up confined to every other bank. When the other core stops before
    /// catching up, core `a` is rolled back and runs again up to where the other stopped
    /// (the window's first part is kept); it is rolled back for good when that part is
    /// shorter than [`MIN_WINDOW`] (the other core's instructions stand either way: they
    /// commute with the window).
    fn run_ahead(&mut self, a: usize, deadline: [u64; 2]) -> Window {
        let b = 1 - a;
        let start = self.cores[a].cycle;
        // The other core must be able to reach the window's end (`+ 1` when it is core 0,
        // which runs first on a tie) before its own deadline.
        let end = deadline[a].min(deadline[b].saturating_sub((b == 0) as u64));
        if start.saturating_add(MIN_WINDOW) > end {
            return Window::Idle;
        }
        let saved = Saved {
            core: self.cores[a].clone(),
            claims: self.system.bank_claim.map(|c| c[a]),
            stalls: self.system.contention_stalls[a],
        };
        let epoch = self.system.code_epoch;
        let (sys, blocks) = (&mut self.system, &mut self.blocks);
        let mut journal = std::mem::take(&mut blocks.journal);
        let mut marks = std::mem::take(&mut blocks.marks);
        journal.clear();
        marks.clear();
        sys.allowed_banks = self.config.own_banks[a] & ALL_BANKS;
        let _ = block::run_confined(
            &mut self.cores[a],
            sys,
            blocks,
            end,
            Some(&mut journal),
            Some(&mut marks),
        );
        let reached = self.cores[a].cycle;
        let mut kept = reached > start;
        let mut partly = false;
        if kept {
            let target = reached + (b == 0) as u64;
            sys.allowed_banks = ALL_BANKS & !self.config.own_banks[a];
            let caught = block::run_confined(&mut self.cores[b], sys, blocks, target, None, None);
            kept = caught.is_ok() && self.cores[b].cycle >= target;
            if !kept {
                // Core `b` stopped at `t`, before an instruction it could not run confined.
                // Cut core `a` back to its last mark before `b`'s next instruction in the
                // lock-step order (at or before `t`, `t + 1` when `a` is core 0): what it
                // ran up to there is in the window and stands.
                let redo = self.cores[b].cycle + (a == 0) as u64;
                let mark = marks
                    .iter()
                    .rev()
                    .find(|m| m.core.cycle <= redo)
                    .filter(|m| m.core.cycle >= start.saturating_add(MIN_WINDOW));
                let cut = match mark {
                    Some(m) => Saved {
                        core: m.core.clone(),
                        claims: m.claims,
                        stalls: m.stalls,
                    },
                    None => saved,
                };
                let from = mark.map_or(0, |m| m.journal);
                partly = mark.is_some();
                undo(&mut self.cores[a], sys, a, &cut, &journal[from..], epoch);
            }
        }
        sys.allowed_banks = ALL_BANKS;
        blocks.journal = journal;
        blocks.marks = marks;
        if reached == start {
            return Window::Idle;
        }
        self.windows[if kept {
            0
        } else if partly {
            2
        } else {
            1
        }] += 1;
        if kept || partly {
            Window::Kept
        } else {
            Window::RolledBack
        }
    }

    /// Completes a fast-path run of core `k` that left with `exit`: the instruction that
    /// needs the general path runs as [`Board::step_cached`] would run it. Returns the event
    /// of the instruction the run ended with, `None` when it ended before one.
    fn finish_fast(&mut self, k: usize, exit: Exit) -> Option<Event> {
        Some(match exit {
            Exit::Deadline => return None,
            Exit::Watch => Event::None,
            Exit::Ran(event) => event,
            Exit::Miss => self.step_cached::<false>(k, self.lines),
            Exit::General => {
                let core = &mut self.cores[k];
                let pc = core.r[15];
                let slot = &self.cache[((pc >> 1) as usize) & (CACHE_SLOTS - 1)];
                let (instr, size, cost) = (slot.instr, slot.size, slot.cost);
                core.run_priced::<_, false>(&mut self.system, pc, instr, size, Some(cost))
            }
        })
    }

    /// True when core `s` is asleep and its sleep steps ([`Board::step`]) would only move
    /// its cycle counter as long as nothing changes the interrupt lines, its NVIC or its
    /// event register and no timer event or SysTick wrap is due: no wake-up event, the
    /// current lines already pending on it, and no pending exception that would wake it.
    fn sleeps_soundly(&self, s: usize) -> bool {
        let c = &self.cores[s];
        let RunState::Sleeping { wfe } = c.state else {
            return false;
        };
        let lines = self.system.current_irq_lines();
        !(wfe && c.event)
            && ((lines as u64) << IRQ0) & !c.nvic.active & !c.nvic.pending == 0
            && c.nvic
                .highest_pending()
                .is_none_or(|(_, p)| p >= c.nvic.active_priority())
    }

    /// Applies a step's event; `Some` when the run must stop.
    fn handle_event(&mut self, k: usize, event: Event) -> Option<StopReason> {
        match event {
            Event::None => None,
            Event::Sev => {
                // The event reaches the other core at the end of the SEV's cycle: a core
                // sleeping in WFE resumes no earlier than the next cycle.
                let after = self.cores[k].cycle;
                let other = &mut self.cores[1 - k];
                other.event = true;
                if matches!(other.state, RunState::Sleeping { .. }) {
                    other.cycle = other.cycle.max(after);
                }
                None
            }
            Event::Svc(imm) => {
                if self.config.svc_halts {
                    Some(StopReason::Svc { core: k, imm })
                } else {
                    self.cores[k].nvic.pending |= 1 << SVCALL;
                    None
                }
            }
            Event::Fault | Event::Lockup if self.system.sysctl.refusal.is_some() => self
                .system
                .sysctl
                .take_refusal()
                .map(|why| StopReason::Refused { core: k, why }),
            Event::Fault => {
                let fault = self.cores[k].fault?;
                self.config
                    .stop_on_fault
                    .then_some(StopReason::Fault { core: k, fault })
            }
            Event::Lockup => self.cores[k]
                .fault
                .map(|fault| StopReason::Lockup { core: k, fault }),
        }
    }

    /// Executes one instruction (or exception entry, or a sleep interval) on the core that
    /// is behind, if it is before `limit`. `None` when both running cores are at `limit`;
    /// `Some(Ok(core))` names the core that acted (its [`Core::last`] is the instruction).
    pub fn step(&mut self, limit: u64) -> Option<Result<usize, StopReason>> {
        let Some(k) = self.next_core() else {
            return Some(Err(StopReason::Idle));
        };
        let now = self.cores[k].cycle;
        if now >= limit {
            return None;
        }
        if self.launch.is_some() && k == 0 {
            self.poll_launch();
        }
        let lines = self.system.irq_lines(k, now);
        if let RunState::Sleeping { wfe } = self.cores[k].state {
            let (other_running, other_cycle) = (
                self.cores[1 - k].state == RunState::Running,
                self.cores[1 - k].cycle,
            );
            let core = &mut self.cores[k];
            if (wfe && core.event) || core.wakes_from_sleep(lines) {
                if wfe {
                    core.event = false;
                }
                core.state = RunState::Running;
            } else {
                // Skip to the next cycle at which something could wake this core.
                let mut next = self
                    .system
                    .timer
                    .next_event
                    .min(core.nvic.syst_next)
                    .min(limit);
                if other_running {
                    next = next.min(other_cycle + 1);
                }
                core.cycle = next.max(now + 1);
            }
            return Some(Ok(k));
        }
        let event = self.step_cached::<true>(k, lines);
        if !self.profiles.is_empty() {
            self.profile_step(k);
        }
        match self.handle_event(k, event) {
            None => Some(Ok(k)),
            Some(stop) => Some(Err(stop)),
        }
    }

    /// Steps core `k` through the decode cache: an instruction is decoded once per address
    /// and reused until a store hits an SRAM page holding cached code or the host writes
    /// memory (both bump [`System::code_epoch`]), so self-modifying code stays correct.
    #[inline(always)]
    fn step_cached<const TRACE: bool>(&mut self, k: usize, lines: u32) -> Event {
        let core = &mut self.cores[k];
        let pc = core.r[15];
        if lines != 0 {
            core.nvic.pending |= ((lines as u64) << IRQ0) & !core.nvic.active;
        }
        if core.nvic.takeable() != 0 || core.nvic.syst_next <= core.cycle || !core.thumb {
            return core.step(&mut self.system, lines);
        }
        let slot = &mut self.cache[((pc >> 1) as usize) & (CACHE_SLOTS - 1)];
        if slot.key != cache_key(pc, self.system.code_epoch) {
            let Ok((hw1, hw2, size)) = self.system.fetch_instr(pc) else {
                return core.step(&mut self.system, lines);
            };
            for a in [pc, pc.wrapping_add(size - 2)] {
                if let Some((off, _)) = sram_location(a) {
                    self.system.code_pages[off >> 8] = true;
                }
            }
            let instr = decode(hw1, hw2);
            let cost = (
                cycles(&instr, false, false) as u8,
                cycles(&instr, true, false) as u8,
            );
            *slot = Cached {
                key: cache_key(pc, self.system.code_epoch),
                op: Op::new(&instr, pc),
                instr,
                size,
                cost,
            };
        }
        let (instr, size, cost) = (slot.instr, slot.size, slot.cost);
        core.run_priced::<_, TRACE>(&mut self.system, pc, instr, size, Some(cost))
    }

    /// Core 1's boot ROM at `core_0_handshake_loop`: drain its RX FIFO, send 0 to core 0
    /// and wait for the command 1.
    fn launch_handshake(&mut self) {
        // The drain reads while VLD is set: it never underflows.
        while self.system.sio.fifo_status(1) & 1 != 0 {
            self.system.sio.fifo_pop(1);
        }
        if let Some(l) = &mut self.launch {
            *l = Launch {
                unsent: Some(0),
                ..Launch::default()
            };
        }
        self.launch_send();
    }

    /// Sends core 1's pending word to core 0 if its RX FIFO has room, then `SEV` (as the
    /// ROM's `send_and_then` does). False while the word waits for room.
    fn launch_send(&mut self) -> bool {
        let Some(l) = &mut self.launch else {
            return true;
        };
        let Some(word) = l.unsent else {
            return true;
        };
        if self.system.sio.fifo_status(1) & 2 == 0 {
            return false;
        }
        l.unsent = None;
        self.system.sio.fifo_push(1, word);
        self.cores[0].event = true;
        true
    }

    /// Core 1's boot ROM reacting to what core 0 sent, word by word (pico-bootrom
    /// `bootrom_rt0.S`: `wait_for_vector`, `send_and_then`, `receive_and_check_zero`;
    /// datasheet 2.8.2): a 0 sends it back to the handshake (drain, send 0); in the first
    /// step anything but 1 does too; otherwise it takes the word (VTOR, then SP, then the
    /// entry point), echoes it, and after echoing the entry point starts core 1 there
    /// with that VTOR and SP. The ROM's own instructions are not timed: each reaction
    /// happens when core 0 next runs (about a dozen cycles per word on the chip).
    fn poll_launch(&mut self) {
        loop {
            if !self.launch_send() {
                return;
            }
            let Some(l) = self.launch else { return };
            if l.step == 4 {
                self.start_core_at(1, l.entry, l.sp, l.vtor);
                return;
            }
            if self.system.sio.fifo_status(1) & 1 == 0 {
                return;
            }
            let Some(word) = self.system.sio.fifo_pop(1) else {
                return;
            };
            if word == 0 || (l.step == 0 && word != 1) {
                self.launch_handshake();
                continue;
            }
            let mut next = Launch {
                step: l.step + 1,
                unsent: Some(word),
                ..l
            };
            match l.step {
                1 => next.vtor = word,
                2 => next.sp = word,
                3 => next.entry = word,
                _ => {}
            }
            self.launch = Some(next);
        }
    }
}

/// Why a fast-path run ([`run_one`], [`run_both`]) returned.
enum Exit {
    /// The core to run reached its deadline.
    Deadline,
    /// The core's next instruction is not in the decode cache.
    Miss,
    /// The core's next instruction (in the cache) needs the general path.
    General,
    /// The core executed an instruction that left it at a watched address (profiling).
    Watch,
    /// The core's next instruction needed the general path and has run there, with this
    /// event ([`general_load`]).
    Ran(Event),
}

/// What a run-ahead attempt ([`Board::run_ahead`]) did.
enum Window {
    /// The window was kept, or its first part (the core behind moved on).
    Kept,
    /// The core behind ran nothing (its next instruction needs the general path, its code
    /// is not compiled yet, or the deadlines leave no room).
    Idle,
    /// The window was rolled back.
    RolledBack,
}

/// Turns shorter than this many cycles run on the interpreter's loop even with the block
/// engine ([`Board::fast_run`]); the results are the same either way.
const SHORT_TURN: u64 = 32;

/// Fewest cycles a run-ahead window may span ([`Board::run_ahead`]).
const MIN_WINDOW: u64 = 64;

/// Lock-step cycles after a run-ahead window that could not be kept, before the next.
const RETRY: u64 = 4096;

/// An unused slot of a watch set ([`Board::watch_set`]): odd, so no PC equals it.
const NO_WATCH: u32 = 1;

/// Most addresses the fast path watches for profiling ([`Board::watch_set`]).
const WATCH_SLOTS: usize = 8;

/// Both cores' watch sets when nothing is watched.
static NO_WATCHES: [[u32; WATCH_SLOTS]; 2] = [[NO_WATCH; WATCH_SLOTS]; 2];

/// One step of the fast path for `core`: false (and nothing done) with the reason when
/// it must leave.
///
/// With `WATCH`, an instruction that leaves the PC at an address in `watch` is counted here
/// and ends the run with [`Exit::Watch`].
#[inline(always)]
fn fast_step<const WATCH: bool>(
    core: &mut Core,
    sys: &mut System,
    cache: &[Cached; CACHE_SLOTS],
    deadline: u64,
    watch: &[u32; WATCH_SLOTS],
) -> Result<(), Exit> {
    if core.cycle >= deadline {
        return Err(Exit::Deadline);
    }
    let pc = core.r[15];
    let slot = &cache[((pc >> 1) as usize) & (CACHE_SLOTS - 1)];
    if slot.key != cache_key(pc, sys.code_epoch) {
        return Err(Exit::Miss);
    }
    if !core.execute_op(sys, &slot.op, &slot.instr, pc, slot.size, slot.cost) {
        return Err(Exit::General);
    }
    if WATCH && watch.contains(&core.r[15]) {
        core.instructions += 1;
        return Err(Exit::Watch);
    }
    Ok(())
}

/// The fast path on one core until it must leave. A separate function whose arguments
/// cannot alias, so the compiler may keep the core's counters in registers.
#[inline(never)]
fn run_one<const WATCH: bool>(
    core: &mut Core,
    sys: &mut System,
    cache: &[Cached; CACHE_SLOTS],
    deadline: u64,
    watch: &[u32; WATCH_SLOTS],
) -> Exit {
    let mut retired = 0;
    loop {
        match fast_step::<WATCH>(core, sys, cache, deadline, watch) {
            Ok(()) => retired += 1,
            Err(Exit::General) if !WATCH => {
                if let Some(event) = general_load(core, sys, cache) {
                    core.instructions += retired;
                    return Exit::Ran(event);
                }
            }
            Err(exit) => {
                core.instructions += retired;
                return exit;
            }
        }
    }
}

/// On [`Exit::General`] in a loop without watched addresses: when the instruction is a
/// single load (a timer read, on the firmware images), runs it on the general path as
/// [`Board::finish_fast`] would; `None` when it left everything the caller's next
/// decision depends on as it was — no event, the interrupt-line epoch, the next timer
/// event and SysTick wrap, the pending exceptions, the core running — so the fast path
/// goes on exactly as [`Board::run_until`] would resume it; else the event, for the caller
/// to return ([`Exit::Ran`]). (A load of a PPB register may signal a SysTick count at 0,
/// pending the exception; a fault is an event; a peripheral read that could change a line
/// bumps the epoch.) Any other instruction runs the same way
/// and returns its event.
#[inline(never)]
fn general_load(core: &mut Core, sys: &mut System, cache: &[Cached; CACHE_SLOTS]) -> Option<Event> {
    let pc = core.r[15];
    let slot = &cache[((pc >> 1) as usize) & (CACHE_SLOTS - 1)];
    let load = crate::timing::class(&slot.instr) == crate::timing::Class::Load;
    let before = (
        sys.irq_epoch,
        sys.timer.next_event,
        core.nvic.syst_next,
        core.nvic.pending,
    );
    let event = core.run_priced::<_, false>(sys, pc, slot.instr, slot.size, Some(slot.cost));
    let same = (
        sys.irq_epoch,
        sys.timer.next_event,
        core.nvic.syst_next,
        core.nvic.pending,
    ) == before;
    let quiet = load && same && event == Event::None && core.state == RunState::Running;
    (!quiet).then_some(event)
}

/// The fast path on both cores in lock-step order (the core that is behind, core 0 on
/// ties) until the core whose turn it is must leave; returns that core.
#[inline(never)]
fn run_both<const WATCH: bool>(
    cores: &mut [Core; 2],
    sys: &mut System,
    cache: &[Cached; CACHE_SLOTS],
    deadline: [u64; 2],
    watch: &[[u32; WATCH_SLOTS]; 2],
) -> (usize, Exit) {
    let [c0, c1] = cores;
    let mut retired = [0; 2];
    let exit = loop {
        // Two copies of the step, chosen by a branch rather than an index: the choice is
        // then predicted instead of making every instruction wait for the previous one's
        // cycle count (and each core gets its own, better predicted, dispatch).
        if c1.cycle < c0.cycle {
            match fast_step::<WATCH>(c1, sys, cache, deadline[1], &watch[1]) {
                Ok(()) => retired[1] += 1,
                Err(Exit::General) if !WATCH => {
                    if let Some(event) = general_load(c1, sys, cache) {
                        break (1, Exit::Ran(event));
                    }
                }
                Err(exit) => break (1, exit),
            }
        } else {
            match fast_step::<WATCH>(c0, sys, cache, deadline[0], &watch[0]) {
                Ok(()) => retired[0] += 1,
                Err(Exit::General) if !WATCH => {
                    if let Some(event) = general_load(c0, sys, cache) {
                        break (0, Exit::Ran(event));
                    }
                }
                Err(exit) => break (0, exit),
            }
        }
    };
    c0.instructions += retired[0];
    c1.instructions += retired[1];
    exit
}

/// The fast path on core `r` while the other core sleeps soundly ([`Board::sleeps_soundly`]),
/// in lock-step order: on the sleeper's turns, its step — skip to the next cycle at which
/// something could wake it: a timer event, its SysTick, the limit, or the cycle after the
/// running core's — is done here while its cycle is below `wake_check` (the first of
/// those), so nothing else about it can change. `Ok` when the sleeper reached
/// `wake_check`, `Err` when the running core must leave.
#[inline(never)]
fn run_beside_sleeper<const SLEEPER_IS_0: bool, const WATCH: bool>(
    run: &mut Core,
    sleep: &mut Core,
    sys: &mut System,
    cache: &[Cached; CACHE_SLOTS],
    deadline: u64,
    wake_check: u64,
    watch: &[u32; WATCH_SLOTS],
) -> Result<(), Exit> {
    loop {
        // The sleeper's turn: it is behind, or level and core 0.
        if sleep.cycle < run.cycle || (SLEEPER_IS_0 && sleep.cycle == run.cycle) {
            let now = sleep.cycle;
            if now >= wake_check {
                return Ok(());
            }
            sleep.cycle = wake_check.min(run.cycle + 1).max(now + 1);
        } else {
            match fast_step::<WATCH>(run, sys, cache, deadline, watch) {
                Ok(()) => run.instructions += 1,
                Err(exit) => return Err(exit),
            }
        }
    }
}

/// [`run_beside_sleeper`] on the block engine (nothing watched): the same interleaving.
/// The running core keeps the turn while its cycle is below the sleeper's (`+ 1` when the
/// sleeper is core 1, which loses ties); each sleeper turn before its wake check only sets
/// its cycle to `min(wake_check, run.cycle + 1)`, which makes the turn the running core's
/// again, so those turns are replayed after each instruction of a block (`after`). The
/// block runs up to the cycle from which the sleeper's turn would find it at its wake
/// check (the later of `wake_check` and the sleeper's cycle, `+ 1` when the sleeper is
/// core 1) and the deadline; the loop then takes the turns exactly as
/// [`run_beside_sleeper`] does.
#[inline(never)]
fn blocks_beside_sleeper<const SLEEPER_IS_0: bool>(
    run: &mut Core,
    sleep: &mut Core,
    sys: &mut System,
    blocks: &mut Blocks,
    deadline: u64,
    wake_check: u64,
) -> Result<(), Exit> {
    let loses_ties = !SLEEPER_IS_0 as u64;
    loop {
        if sleep.cycle < run.cycle || (SLEEPER_IS_0 && sleep.cycle == run.cycle) {
            let now = sleep.cycle;
            if now >= wake_check {
                return Ok(());
            }
            sleep.cycle = wake_check.min(run.cycle + 1).max(now + 1);
        } else {
            if run.cycle >= deadline {
                return Err(Exit::Deadline);
            }
            // From this cycle on, the sleeper's turn would find it at (or past) its wake
            // check: the loop must take that turn.
            let limit = deadline.min(wake_check.max(sleep.cycle) + loses_ties);
            let mut turns = block::Sleeper {
                cycle: &mut sleep.cycle,
                wake: wake_check,
                loses_ties: !SLEEPER_IS_0,
            };
            if block::run(run, sys, blocks, limit, &mut turns).is_err() {
                return Err(Exit::Miss);
            }
        }
    }
}

/// A core's state at the start of a run-ahead window ([`Board::run_ahead`]).
struct Saved {
    core: Core,
    claims: [u64; crate::bus::BANKS],
    stalls: u64,
}

/// Undoes (the end of) core `a`'s run-ahead window: its stores in `journal` (newest
/// first), its bank claims, stalls and state as `saved`; decoded code is dropped when a
/// store in the window hit a code page (`epoch` moved), since the undo may have changed
/// that memory back.
fn undo(core: &mut Core, sys: &mut System, a: usize, saved: &Saved, journal: &[u64], epoch: u32) {
    for &e in journal.iter().rev() {
        let off = (e >> 32) as usize;
        sys.sram[off..off + 4].copy_from_slice(&(e as u32).to_le_bytes());
    }
    *core = saved.core.clone();
    for (bank, c) in saved.claims.iter().enumerate() {
        sys.bank_claim[bank][a] = *c;
    }
    sys.contention_stalls[a] = saved.stalls;
    if sys.code_epoch != epoch {
        sys.invalidate_code();
    }
}

fn active(c: &Core) -> bool {
    matches!(c.state, RunState::Running | RunState::Sleeping { .. })
}
