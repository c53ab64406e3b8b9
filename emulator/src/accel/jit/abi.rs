//! The calling convention between a compiled region and the board: the context the
//! native code reads its pointers from and writes its counts to, the exit reasons, and
//! the call itself.

use crate::accel::io_window::{IoAccess, IoKind};
use crate::bus::load_le;
use crate::core::Core;
use crate::io::Io;
use crate::system::System;

/// What the native code shares with the board for one call (`#[repr(C)]`: the generated
/// code reads its fields at fixed offsets).
#[repr(C)]
pub(crate) struct Ctx {
    /// [`System::sram`]'s bytes.
    pub sram: *mut u8,
    /// [`System::flash`]'s bytes.
    pub flash: *const u8,
    /// [`System::code_pages`] (one `bool` per 256-byte page).
    pub code_pages: *const u8,
    /// `bank_claim[0][core]` (banks are 16 bytes apart).
    pub claims_self: *mut u64,
    /// `bank_claim[0][other core]`.
    pub claims_other: *const u64,
    /// `contention_stalls[core]`.
    pub stalls: *mut u64,
    /// Out: end cycle of the last instruction that cost two cycles or more (0: none).
    pub q: u64,
    /// Out: instructions retired (zero on the call; the native code adds to it in place).
    pub retired: u64,
    /// Confined code only: the undo journal, one entry per store, `(word offset << 32) |
    /// the word's old value`, in store order; null for none.
    pub journal: *mut u64,
    /// Confined code only: entries used (in and out).
    pub journal_len: u64,
    /// Confined code only: entries available; a store that finds the journal full leaves
    /// before it ([`Exit::General`]).
    pub journal_cap: u64,
    /// Confined code in a window on a board with converters only (`accel/io_window/`):
    /// bit *b* set when a single load or store to SRAM bank *b* (not in the code's bank mask,
    /// [`super::Flavour::Confined`]: the DMA's) is done inline and logged ([`io_sram`]); 0
    /// elsewhere.
    pub io_banks: u64,
    /// The window's log of the core's accesses to the I/O ([`io_sram`], [`io_reg`]); null
    /// when `io_banks` is 0.
    pub io_log: *mut Vec<IoAccess>,
    /// The board's I/O, as the window's start left it ([`io_reg`]); null when `io_log` is.
    pub io: *const Io,
}

/// Why native code returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub(crate) enum Exit {
    /// At a branch out of the region or the region's end; PC is where to go on.
    Out = 0,
    /// Before an instruction the native code does not complete (PC is its address).
    General = 1,
    /// After a store into a code page (PC is the next instruction): drop decoded code.
    Invalidate = 2,
    /// A loop's back edge did not fit before the deadline (PC is the loop's head).
    Deadline = 3,
}

impl Exit {
    fn from_raw(r: u32) -> Exit {
        match r {
            0 => Exit::Out,
            1 => Exit::General,
            2 => Exit::Invalidate,
            _ => Exit::Deadline,
        }
    }
}

/// SYST_RVR (DDI0419 B3.3.4): the one private peripheral register native code stores to
/// ([`ppb_store`]).
pub(crate) const SYST_RVR: u32 = 0xe000_e014;

/// A word load from the core's private peripheral bus (NVIC, SysTick, SCB) at data-phase
/// cycle `at`, for native code: what the executor's load does there (`Nvic::read`, no
/// wait state). Returns `1 << 32 | value`, or 0 — nothing done — for an address the NVIC
/// does not implement (a bus fault) or a cycle at or after SysTick's next wrap (the
/// caller's deadline keeps native code before it; the general path handles the wrap).
///
/// # Safety
/// `core` points to the [`Core`] the native code runs, not otherwise borrowed during the
/// call.
pub(crate) unsafe extern "C" fn ppb_load(core: *mut Core, at: u64, addr: u32) -> u64 {
    // SAFETY: the caller's.
    let core = unsafe { &mut *core };
    if at >= core.nvic.syst_next {
        return 0;
    }
    let ipsr = core.ipsr;
    core.nvic
        .read(at, addr, ipsr)
        .map_or(0, |v| 1 << 32 | v as u64)
}

/// A word store of `value` to [`SYST_RVR`] at data-phase cycle `at`, for native code:
/// what the executor's store does there (`Nvic::write`: the reload value of the next
/// wrap; it changes neither the next wrap's cycle nor any exception's state). Returns 1,
/// or 0 — nothing done — at or after SysTick's next wrap (as [`ppb_load`]). Other private
/// peripheral registers can pend, enable or restart things, so native code leaves
/// before storing to them.
///
/// # Safety
/// As [`ppb_load`].
pub(crate) unsafe extern "C" fn ppb_store(core: *mut Core, at: u64, value: u32) -> u32 {
    // SAFETY: the caller's.
    let core = unsafe { &mut *core };
    if at >= core.nvic.syst_next {
        return 0;
    }
    core.nvic.write(at, SYST_RVR, value) as u32
}

/// A single load or store by native code to SRAM offset `off` in one of [`Ctx::io_banks`]
/// (a bank the DMA may reach, in a window: `accel/io_window/`), called before the
/// access, which the native code then does as in any allowed bank (arbitration, journal):
/// logs it as the window's bus (`accel/window.rs`, `Confined`) logs the general path's —
/// the instruction's start cycle `start`, the data phase `start + 1` (a single LDR or
/// STR's, DDI0484 3.3), the offset, the size, the value loaded (the bytes in SRAM now) or
/// the register stored (`value`, whole, as the executor passes it), and a store's old
/// word. `packed`: `off << 32 | store << 8 | size`.
///
/// # Safety
/// `ctx` is the context of the running call, its `io_log` a live vector not otherwise
/// borrowed during the call, its `sram` the SRAM's bytes with `off` plus the size inside.
pub(crate) unsafe extern "C" fn io_sram(ctx: *mut Ctx, start: u64, packed: u64, value: u32) {
    // SAFETY: the caller's.
    let ctx = unsafe { &mut *ctx };
    let off = (packed >> 32) as u32;
    let size = packed as u32 & 0xff;
    let store = packed >> 8 & 1 != 0;
    // SAFETY: `off + size` and the word holding it are inside the SRAM (the caller's).
    let at = |o: u32, n: u32| {
        let bytes = unsafe { std::slice::from_raw_parts(ctx.sram.add(o as usize), n as usize) };
        load_le(bytes, 0, n)
    };
    let a = match store {
        true => IoAccess::new(
            start,
            start + 1,
            IoKind::Store,
            off,
            size,
            value,
            at(off & !3, 4),
        ),
        false => IoAccess::new(start, start + 1, IoKind::Load, off, size, at(off, size), 0),
    };
    // SAFETY: the caller's.
    unsafe { (*ctx.io_log).push(a) };
}

/// A word store of `value` to `addr` by native code in a window on a board with converters:
/// when `addr` is a register of the I/O's DMA or PIOs that it accepts now ([`Io::accepts`],
/// the I/O as the window's start left it), logs it for the replay with the instruction's
/// start cycle `start` and its data phase `start + 1`, as the window's bus does instead of
/// the store, and returns 1 (the store done: no wait state,
/// [`crate::io::AHB_PERIPHERAL_WAIT`]); otherwise 0, nothing done (the general path).
///
/// # Safety
/// As [`io_sram`]; `io` null or the board's I/O, not mutably borrowed during the call.
pub(crate) unsafe extern "C" fn io_reg(ctx: *mut Ctx, start: u64, addr: u32, value: u32) -> u32 {
    // SAFETY: the caller's.
    let ctx = unsafe { &mut *ctx };
    // SAFETY: the caller's.
    let accepts = !ctx.io.is_null() && unsafe { &*ctx.io }.accepts(addr);
    if !accepts || ctx.io_log.is_null() {
        return 0;
    }
    let a = IoAccess::new(start, start + 1, IoKind::Reg, addr, 4, value, 0);
    // SAFETY: the caller's.
    unsafe { (*ctx.io_log).push(a) };
    1
}

/// A compiled region: `fn(core, ctx, limit) -> Exit`.
pub(crate) type NativeFn = unsafe extern "C" fn(*mut Core, *mut Ctx, u64) -> u32;

/// Runs `f` on `core`: the raw call with the context built from `sys`, for code that is not
/// confined ([`call_confined`] runs that). Returns why it stopped, the instructions retired
/// and the `q` cycle (see [`Ctx::q`]).
#[inline(always)]
pub(crate) fn call(f: NativeFn, core: &mut Core, sys: &mut System, limit: u64) -> (Exit, u64, u64) {
    let id = core.id & 1;
    let claims = sys.bank_claim.as_mut_ptr() as *mut u64;
    let mut ctx = Ctx {
        sram: sys.sram.as_mut_ptr(),
        flash: sys.flash.as_ptr(),
        code_pages: sys.code_pages.as_ptr() as *const u8,
        // SAFETY (both): `bank_claim` is `[[u64; 2]; BANKS]`; `id` and `1 - id` are 0 or 1.
        claims_self: unsafe { claims.add(id) },
        claims_other: unsafe { claims.add(1 - id) },
        stalls: &mut sys.contention_stalls[id],
        q: 0,
        retired: 0,
        journal: std::ptr::null_mut(),
        journal_len: 0,
        journal_cap: 0,
        io_banks: 0,
        io_log: std::ptr::null_mut(),
        io: std::ptr::null(),
    };
    // SAFETY: `f` was compiled by `Jit::compile` for this layout of `Core` and `Ctx`; it
    // reads and writes only the core's registers, flags, cycle, PC, the SRAM and flash
    // bytes at offsets it has bounds-checked against `SRAM_SIZE` / `FLASH_SIZE`, the code
    // page flags of those offsets, the claim table's six banks and the stall counter;
    // confined code ([`call_confined`]) also writes journal entries below `journal_cap`,
    // the vector's capacity, whose length is then set to the entries written (each
    // initialised), and calls `io_sram` and `io_reg` with the context (the I/O log's vector
    // and the I/O, untouched by anything else during the call).
    let exit = unsafe { f(core, &mut ctx, limit) };
    (Exit::from_raw(exit), ctx.retired, ctx.q)
}

impl Ctx {
    /// The context of a run of calls of confined code on core `id` of `sys`
    /// ([`call_confined`]): made once a run rather than once a call (a region call cost the
    /// `rp2040_io` demo about 30 host instructions of context, of some 9 M calls). The
    /// pointers to the SRAM, flash and code pages are taken here: they are heap buffers of
    /// `sys` that nothing resizes during the run, and a vector's `as_mut_ptr` pointer stays
    /// valid beside every other use of it. With `io` (in a window on a board with
    /// converters: the SRAM banks outside the code's mask whose single loads and stores the
    /// native code does and logs, and the I/O as the window's start left it, which nothing
    /// changes during the run), [`Ctx::io_banks`] and [`Ctx::io`]; the log is set by each
    /// call. [`Ctx::retired`] adds up over the run's calls.
    pub(crate) fn confined(sys: &mut System, io: Option<(u8, *const Io)>) -> Ctx {
        let (io_banks, io) = io.map_or((0, std::ptr::null()), |(b, io)| (u64::from(b), io));
        Ctx {
            sram: sys.sram.as_mut_ptr(),
            flash: sys.flash.as_ptr(),
            code_pages: sys.code_pages.as_ptr() as *const u8,
            claims_self: std::ptr::null_mut(),
            claims_other: std::ptr::null(),
            stalls: std::ptr::null_mut(),
            q: 0,
            retired: 0,
            journal: std::ptr::null_mut(),
            journal_len: 0,
            journal_cap: u64::MAX,
            io_banks,
            io_log: std::ptr::null_mut(),
            io,
        }
    }
}

/// [`call`] for confined code with the run's context `ctx` ([`Ctx::confined`], made from this
/// `sys`): sets what the run's other code may have moved since the last call — the claim
/// and stall pointers (fields of `sys`), the journal's pointer, length and capacity (a
/// memo's or a pre-decoded store may have pushed to it) and the I/O log's pointer — and
/// returns why the code stopped. The instructions it retired are added to
/// [`Ctx::retired`]; its `q` is not needed (the window replays no sleeper).
#[inline(always)]
pub(crate) fn call_confined(
    f: NativeFn,
    core: &mut Core,
    sys: &mut System,
    limit: u64,
    ctx: &mut Ctx,
    journal: Option<&mut Vec<u64>>,
    io_log: Option<&mut Vec<IoAccess>>,
) -> Exit {
    let id = core.id & 1;
    let claims = sys.bank_claim.as_mut_ptr() as *mut u64;
    // SAFETY (both): `bank_claim` is `[[u64; 2]; BANKS]`; `id` and `1 - id` are 0 or 1.
    ctx.claims_self = unsafe { claims.add(id) };
    ctx.claims_other = unsafe { claims.add(1 - id) };
    ctx.stalls = &mut sys.contention_stalls[id];
    if let Some(log) = io_log {
        ctx.io_log = log;
    }
    let exit = match journal {
        Some(j) => {
            ctx.journal = j.as_mut_ptr();
            ctx.journal_len = j.len() as u64;
            ctx.journal_cap = j.capacity() as u64;
            // SAFETY: as in `call`; the SRAM, flash and code-page pointers are those of
            // `sys`'s buffers (`Ctx::confined`), the rest set above.
            let exit = unsafe { f(core, ctx, limit) };
            // SAFETY: the native code wrote entries `len..journal_len`, within the capacity.
            unsafe { j.set_len(ctx.journal_len as usize) };
            exit
        }
        // SAFETY: as above; code called without a journal has no journal code.
        None => unsafe { f(core, ctx, limit) },
    };
    Exit::from_raw(exit)
}
