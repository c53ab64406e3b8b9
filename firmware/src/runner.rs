//! [`UpdateRunner`]: a compiled per-key update running on the emulated RP2040, called from
//! the host one key-sample at a time.
//!
//! The runner owns a [`Board`] with the code loaded, allocates the state struct, the sensor
//! words and the out words in SRAM after the code, runs `init`, and then per sample writes
//! the raw sensor words, calls `update` on core 0 with [`Board::call`] and reads back the out
//! words, the states and the modes. The stack is just below the page of [`CALL_STUB`] (the
//! top of SRAM).
//! Each buffer is followed by guard words that the runner checks after every call, so code
//! that writes past the interface is caught.
//!
//! **Cycles.** [`Sample::cycles`] is the number of core cycles per key-sample *including the
//! call and the return*: from the update's first instruction to its return instruction
//! inclusive, as the emulator's timing model charges them, plus 3 for the caller's `BL`
//! (Cortex-M0+ TRM 3.3). Code and data are in SRAM (no wait states) and core 1 stays parked,
//! so there is no bus contention.

use crate::layout::Interface;
use crate::windows::SENSOR_BASE;
use std::fmt;
use tactus_emulator::StopReason;
use tactus_emulator::{Board, CallError, CallResult, Config, EmuError, CALL_STUB};
use tactus_isa::decode::Instr;
use tactus_isa::timing::cycles;
use tactus_rp2040::memory::sram_location;

/// The return stub [`Board::call`] writes at [`CALL_STUB`]: `SVC #0xCA; BKPT`.
const STUB: [u8; 4] = [0xca, 0xdf, 0x00, 0xbe];

/// Cycles a `BL` costs the caller (Cortex-M0+ TRM 3.3), added to every measured call: the
/// timing table's row ([`tactus_isa::timing::Class::Bl`]).
pub const BL_CYCLES: u64 = tactus_isa::timing::Class::Bl.cost().base as u64;

/// Lowest address of SRAM (the runner's data must be at or above it).
pub const SRAM_BASE: u32 = 0x2000_0000;

/// Highest address (exclusive) the runner's buffers may reach: the sensor and DAC windows
/// of the board start here.
pub const DATA_LIMIT: u32 = SENSOR_BASE;

/// Initial stack pointer of every call: just below the 256-byte page holding the call stub
/// at [`CALL_STUB`]. Not in the stub's page: the emulator tracks executed code per page and
/// empties its decode cache on a store into such a page, which every `PUSH` would then do.
pub const STACK_TOP: u32 = CALL_STUB & !0xff;

/// Bytes reserved for the stack below [`STACK_TOP`]; code and buffers must stay below it.
pub const STACK_BYTES: u32 = 4096;

/// Default cycle limit of one call (far above any per-key update; a runaway loop stops here).
pub const DEFAULT_CALL_LIMIT: u64 = 1_000_000;

/// Guard words written after each buffer and checked after each call.
const GUARD_WORDS: usize = 4;
const GUARD: u32 = 0xA5C3_5A3C;

/// Why a runner could not be built or a call did not complete.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RunError {
    /// The ELF file could not be loaded (parse error or a segment outside memory).
    Load(EmuError),
    /// A function symbol the interface needs is not in the ELF symbol table.
    MissingSymbol(String),
    /// A raw code entry offset lies outside the code bytes.
    BadEntry {
        /// Which entry (`"init"` or `"update"`).
        name: &'static str,
        /// Its offset from the load address, bytes.
        offset: u32,
        /// The code's length, bytes.
        len: usize,
    },
    /// Code plus buffers do not fit in SRAM below the sensor window and the stack.
    NoRoom {
        /// First free address after the code, bytes.
        start: u32,
        /// Bytes needed for the buffers.
        need: u32,
    },
    /// The sensor slice passed to [`UpdateRunner::step`] has the wrong length.
    SensorCount {
        /// Sensors of the interface.
        expected: usize,
        /// Words passed.
        got: usize,
    },
    /// The called function faulted, locked up, or did not return within the cycle limit.
    Call {
        /// The function's symbol name.
        function: String,
        /// Why the board stopped.
        reason: StopReason,
        /// The address of the faulting instruction for a fault or a lockup, else the core's
        /// PC when it stopped.
        pc: u32,
    },
    /// The called function wrote beyond one of its buffers (a guard word changed).
    Overrun {
        /// The function's symbol name.
        function: String,
        /// Which buffer (`"state"`, `"sensors"` or `"out"`).
        buffer: &'static str,
    },
    /// A host memory access failed (a bug in the runner's placement).
    Emu(EmuError),
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::Load(e) => write!(f, "cannot load the code: {e}"),
            RunError::MissingSymbol(s) => write!(f, "the code has no symbol `{s}`"),
            RunError::BadEntry { name, offset, len } => write!(
                f,
                "entry `{name}` at offset {offset:#x} lies outside the {len} code bytes"
            ),
            RunError::NoRoom { start, need } => write!(
                f,
                "no room for {need} bytes of buffers after the code (which ends at {start:#010x})"
            ),
            RunError::SensorCount { expected, got } => {
                write!(f, "{got} sensor words given, the update reads {expected}")
            }
            RunError::Call {
                function,
                reason,
                pc,
            } => write!(
                f,
                "`{function}` did not return: {reason:?} at pc {pc:#010x}"
            ),
            RunError::Overrun { function, buffer } => {
                write!(f, "`{function}` wrote past the end of its {buffer} buffer")
            }
            RunError::Emu(e) => write!(f, "emulator access failed: {e}"),
        }
    }
}

impl std::error::Error for RunError {}

impl From<EmuError> for RunError {
    fn from(e: EmuError) -> Self {
        RunError::Emu(e)
    }
}

/// What one call of the update produced.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Sample {
    /// The `out` words (`Interface::out_len` of them), as the update wrote them.
    pub out: Vec<i32>,
    /// The state words read back from the struct after the call (`states[0..ns]`).
    pub states: Vec<i32>,
    /// The modes read back from the struct after the call (`modes[0..nm]`).
    pub modes: Vec<u8>,
    /// Cycles per key-sample including call and return: the update's first instruction to
    /// its return inclusive, plus [`BL_CYCLES`] for the caller's `BL`.
    pub cycles: u64,
}

/// A compiled update loaded into an emulated RP2040, ready to be called sample by sample.
pub struct UpdateRunner {
    board: Board,
    iface: Interface,
    init: u32,
    update: u32,
    state_addr: u32,
    sensors_addr: u32,
    out_addr: u32,
    /// Cycle limit of one call.
    limit: u64,
    sample: Sample,
    scratch: Vec<u8>,
}

impl UpdateRunner {
    /// Loads an ELF executable (linked to run from SRAM), finds `tactus_<stem>_init` and
    /// `tactus_<stem>_update` in its symbol table, places the buffers after the highest
    /// loaded byte and runs `init`.
    ///
    /// Errors: [`RunError::Load`], [`RunError::MissingSymbol`], [`RunError::NoRoom`], and
    /// the errors of [`UpdateRunner::init`].
    pub fn from_elf(bytes: &[u8], iface: Interface) -> Result<Self, RunError> {
        let mut board = Board::new(Config::default());
        board.load_elf(bytes).map_err(RunError::Load)?;
        let sym = |name: String| {
            board
                .image
                .symbol(&name)
                .map(|s| s.addr)
                .ok_or(RunError::MissingSymbol(name))
        };
        let init = sym(iface.init_symbol())?;
        let update = sym(iface.update_symbol())?;
        let end = board
            .image
            .segments
            .iter()
            .map(|s| s.addr.saturating_add(s.data.len() as u32))
            .max()
            .unwrap_or(SRAM_BASE)
            .max(SRAM_BASE);
        Self::place(board, iface, init, update, end)
    }

    /// Loads raw position-independent Thumb code at `load_addr` (in SRAM) with the init and
    /// update functions at byte offsets `init_offset` and `update_offset` (Thumb bit
    /// ignored), places the buffers after the code and runs `init`.
    ///
    /// Errors: [`RunError::BadEntry`] for an offset outside the code, [`RunError::Emu`] when
    /// the code does not fit in memory at `load_addr`, [`RunError::NoRoom`], and the errors
    /// of [`UpdateRunner::init`].
    pub fn from_code(
        code: &[u8],
        load_addr: u32,
        init_offset: u32,
        update_offset: u32,
        iface: Interface,
    ) -> Result<Self, RunError> {
        for (name, offset) in [("init", init_offset), ("update", update_offset)] {
            if (offset & !1) as usize >= code.len() {
                return Err(RunError::BadEntry {
                    name,
                    offset,
                    len: code.len(),
                });
            }
        }
        let end = load_addr
            .checked_add(code.len() as u32)
            .ok_or(RunError::Emu(EmuError::Unmapped(load_addr)))?;
        if load_addr < SRAM_BASE || end > DATA_LIMIT {
            return Err(RunError::Emu(EmuError::Unmapped(load_addr)));
        }
        let mut board = Board::new(Config::default());
        board.write_bytes(load_addr, code)?;
        let init = load_addr + (init_offset & !1);
        let update = load_addr + (update_offset & !1);
        Self::place(board, iface, init, update, end)
    }

    fn place(
        board: Board,
        iface: Interface,
        init: u32,
        update: u32,
        code_end: u32,
    ) -> Result<Self, RunError> {
        let up = |x: u32| x.div_ceil(16) * 16;
        let guard = 4 * GUARD_WORDS as u32;
        // A page of its own (the emulator tracks code per 256-byte page): host writes of
        // sensor words then never invalidate the decode cache.
        let state_addr = code_end.div_ceil(256) * 256;
        let sensors_addr = up(state_addr + iface.state.size as u32 + guard);
        let out_addr = up(sensors_addr + 4 * iface.sensors.max(1) as u32 + guard);
        let end = out_addr + 4 * iface.out_len as u32 + guard;
        if end > DATA_LIMIT.min(STACK_TOP - STACK_BYTES) {
            return Err(RunError::NoRoom {
                start: code_end,
                need: end - state_addr,
            });
        }
        let mut r = UpdateRunner {
            sample: Sample {
                out: vec![0; iface.out_len],
                states: vec![0; iface.states],
                modes: vec![0; iface.modes],
                cycles: 0,
            },
            board,
            iface,
            init,
            update,
            state_addr,
            sensors_addr,
            out_addr,
            limit: DEFAULT_CALL_LIMIT,
            scratch: Vec::new(),
        };
        r.init()?;
        Ok(r)
    }

    /// Sets the cycle limit of one call (default [`DEFAULT_CALL_LIMIT`]).
    pub fn set_call_limit(&mut self, cycles: u64) {
        self.limit = cycles;
    }

    /// The interface the runner calls.
    pub fn interface(&self) -> &Interface {
        &self.iface
    }

    /// Sets the key's param block ([`Interface::params`]) and re-runs `init` with it.
    ///
    /// Errors: those of [`UpdateRunner::init`].
    pub fn set_params(&mut self, params: Vec<i32>) -> Result<u64, RunError> {
        self.iface.params = params;
        self.init()
    }

    /// Address of the update function (Thumb bit clear).
    pub fn update_addr(&self) -> u32 {
        self.update
    }

    /// Address of the init function (Thumb bit clear).
    pub fn init_addr(&self) -> u32 {
        self.init
    }

    /// Address of the state struct in SRAM.
    pub fn state_addr(&self) -> u32 {
        self.state_addr
    }

    /// The board (to inspect memory or symbols).
    pub fn board(&mut self) -> &mut Board {
        &mut self.board
    }

    /// Fills the state struct with a junk pattern and its guards, then calls `init`, so a
    /// member `init` forgets shows up as a mismatch. Returns the cycles of the call
    /// (including [`BL_CYCLES`]).
    ///
    /// Errors: [`RunError::Call`] when init faults or does not return, [`RunError::Overrun`]
    /// when it writes past the struct.
    pub fn init(&mut self) -> Result<u64, RunError> {
        let mut junk: Vec<u8> = (0..self.iface.state.size).map(|i| 0x5B ^ i as u8).collect();
        // The key's param block, which init leaves alone.
        for (k, w) in self.iface.params.iter().enumerate() {
            let at = self.iface.state.params + 4 * k;
            if let Some(b) = junk.get_mut(at..at + 4) {
                b.copy_from_slice(&w.to_le_bytes());
            }
        }
        self.board.write_bytes(self.state_addr, &junk)?;
        let s = self.iface.state.size as u32;
        self.write_guard(self.state_addr + s)?;
        self.write_guard(self.sensors_addr + 4 * self.iface.sensors as u32)?;
        self.write_guard(self.out_addr + 4 * self.iface.out_len as u32)?;
        let cycles = self.call(self.init, &[self.state_addr])?;
        self.check_guards(self.iface.init_symbol())?;
        Ok(cycles)
    }

    /// Runs one sample: writes `sensors` (raw words, one per sensor), calls the update and
    /// reads back the out words, the states and the modes.
    ///
    /// Errors: [`RunError::SensorCount`], [`RunError::Call`] when the update faults or does
    /// not return within the cycle limit, [`RunError::Overrun`] when it writes past a buffer.
    pub fn step(&mut self, sensors: &[i32]) -> Result<&Sample, RunError> {
        if sensors.len() != self.iface.sensors {
            return Err(RunError::SensorCount {
                expected: self.iface.sensors,
                got: sensors.len(),
            });
        }
        self.scratch.clear();
        self.scratch
            .extend(sensors.iter().flat_map(|w| w.to_le_bytes()));
        poke(&mut self.board, self.sensors_addr, &self.scratch)?;
        let cycles = self.call(
            self.update,
            &[self.state_addr, self.sensors_addr, self.out_addr],
        )?;
        self.check_guards(self.iface.update_symbol())?;
        let n = self.iface.out_len;
        self.read_words(self.out_addr, n)?;
        for (o, b) in self.sample.out.iter_mut().zip(self.scratch.chunks_exact(4)) {
            *o = i32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        let ns = self.iface.states;
        self.read_words(self.state_addr + self.iface.state.states as u32, ns)?;
        for (o, b) in self
            .sample
            .states
            .iter_mut()
            .zip(self.scratch.chunks_exact(4))
        {
            *o = i32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
        let modes = self.state_addr + self.iface.state.modes as u32;
        self.board.read_bytes(modes, &mut self.sample.modes)?;
        self.sample.cycles = cycles;
        Ok(&self.sample)
    }

    /// The state words and modes as they are now (after `init` or the last sample).
    ///
    /// Errors: [`RunError::Emu`] only if the runner's own placement were wrong.
    pub fn read_state(&mut self) -> Result<(Vec<i32>, Vec<u8>), RunError> {
        let ns = self.iface.states;
        self.read_words(self.state_addr + self.iface.state.states as u32, ns)?;
        let states = self
            .scratch
            .chunks_exact(4)
            .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let mut modes = vec![0; self.iface.modes];
        self.board
            .read_bytes(self.state_addr + self.iface.state.modes as u32, &mut modes)?;
        Ok((states, modes))
    }

    fn read_words(&mut self, addr: u32, n: usize) -> Result<(), RunError> {
        self.scratch.clear();
        self.scratch.resize(4 * n, 0);
        self.board.read_bytes(addr, &mut self.scratch)?;
        Ok(())
    }

    fn call(&mut self, addr: u32, args: &[u32]) -> Result<u64, RunError> {
        let result = if self.stub_ready() {
            self.call_again(addr, args)
        } else {
            self.board.call(0, addr, args, STACK_TOP, self.limit)
        };
        match result {
            Ok(r) => Ok(r.cycles + BL_CYCLES),
            Err(CallError::Stopped { reason, pc }) => Err(RunError::Call {
                function: if addr == self.init {
                    self.iface.init_symbol()
                } else {
                    self.iface.update_symbol()
                },
                reason,
                pc: match reason {
                    // The faulting instruction, not the HardFault handler's address.
                    StopReason::Fault { fault, .. } | StopReason::Lockup { fault, .. } => fault.pc,
                    _ => pc,
                },
            }),
            Err(CallError::Emu(e)) => Err(RunError::Emu(e)),
        }
    }

    /// True when the return stub [`Board::call`] wrote is still in place.
    fn stub_ready(&mut self) -> bool {
        let mut b = [0; 4];
        self.board.read_bytes(CALL_STUB, &mut b).is_ok() && b == STUB
    }

    /// [`Board::call`] without rewriting its return stub (already in place): `Board::call`
    /// writes the stub with [`Board::write_bytes`], which empties the emulator's decode
    /// cache, so every call would decode the whole function again (about 2/3 of the host
    /// time per sample). Same registers, same stop condition, same cycle count; the test
    /// `repeated_calls_agree_with_board_call` checks that.
    fn call_again(&mut self, addr: u32, args: &[u32]) -> Result<CallResult, CallError> {
        let halts = std::mem::replace(&mut self.board.config.svc_halts, true);
        let c = &mut self.board.cores[0];
        c.reset_to(addr | 1, STACK_TOP);
        for (i, a) in args.iter().take(4).enumerate() {
            c.r[i] = *a;
        }
        c.r[14] = CALL_STUB | 1;
        let start = c.cycle;
        let stop = self.board.run_until(start.saturating_add(self.limit));
        self.board.config.svc_halts = halts;
        let c = &self.board.cores[0];
        match stop {
            StopReason::Svc { core: 0, imm } if imm == STUB[0] => Ok(CallResult {
                r0: c.r[0],
                r1: c.r[1],
                cycles: c.cycle - start - cycles(&Instr::Svc { imm }, false, false) as u64,
            }),
            reason => Err(CallError::Stopped {
                reason,
                pc: c.r[15],
            }),
        }
    }

    /// Calls `addr` always through [`Board::call`] (which rewrites its stub), for tests of
    /// the fast path; returns the cycles including [`BL_CYCLES`].
    #[doc(hidden)]
    pub fn call_via_board(&mut self, addr: u32, args: &[u32]) -> Result<u64, CallError> {
        self.board
            .call(0, addr, args, STACK_TOP, self.limit)
            .map(|r| r.cycles + BL_CYCLES)
    }

    /// The sensor and out buffer addresses (for tests that call the update directly).
    #[doc(hidden)]
    pub fn buffers(&self) -> (u32, u32) {
        (self.sensors_addr, self.out_addr)
    }

    fn write_guard(&mut self, addr: u32) -> Result<(), RunError> {
        for i in 0..GUARD_WORDS as u32 {
            self.board.write_u32(addr + 4 * i, GUARD)?;
        }
        Ok(())
    }

    fn check_guards(&mut self, function: String) -> Result<(), RunError> {
        let s = self.iface.state.size as u32;
        let buffers = [
            ("state", self.state_addr + s),
            ("sensors", self.sensors_addr + 4 * self.iface.sensors as u32),
            ("out", self.out_addr + 4 * self.iface.out_len as u32),
        ];
        for (buffer, addr) in buffers {
            for i in 0..GUARD_WORDS as u32 {
                if self.board.read_u32(addr + 4 * i)? != GUARD {
                    return Err(RunError::Overrun { function, buffer });
                }
            }
        }
        Ok(())
    }
}

/// Writes data bytes into SRAM as a DMA would. Unlike [`Board::write_bytes`], it leaves the
/// emulator's decode cache alone unless the bytes land in a page that holds cached code
/// (the runner's buffers never do), which keeps per-sample host writes cheap.
fn poke(board: &mut Board, addr: u32, data: &[u8]) -> Result<(), EmuError> {
    let end = addr.wrapping_add(data.len() as u32);
    let code = (addr..end).step_by(256).chain(end.checked_sub(1)).any(|a| {
        sram_location(a).is_none_or(|(off, _)| {
            board
                .system
                .code_pages
                .get(off / 256)
                .copied()
                .unwrap_or(true)
        })
    });
    let linear = matches!(
        (sram_location(addr), end.checked_sub(1).and_then(sram_location)),
        (Some((a, _)), Some((b, _))) if b + 1 - a == data.len() && a == (addr - SRAM_BASE) as usize
    );
    if code || !linear || data.is_empty() {
        return board.write_bytes(addr, data);
    }
    let off = (addr - SRAM_BASE) as usize;
    board.system.sram[off..off + data.len()].copy_from_slice(data);
    Ok(())
}
