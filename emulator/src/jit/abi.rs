//! The calling convention between a compiled region and the board: the context the
//! native code reads its pointers from and writes its counts to, the exit reasons, and
//! the call itself.

use crate::bus::System;
use crate::core::Core;

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
    /// Confined code only ([`crate::jit`], "Confinement"): bit *b* set when the core may
    /// access SRAM bank *b* (0-3 SRAM0-3, 4 SRAM4, 5 SRAM5).
    pub allowed: u64,
    /// Confined code only: the undo journal, one entry per store, `(word offset << 32) |
    /// the word's old value`, in store order; null for none.
    pub journal: *mut u64,
    /// Confined code only: entries used (in and out).
    pub journal_len: u64,
    /// Confined code only: entries available; a store that finds the journal full leaves
    /// before it ([`Exit::General`]).
    pub journal_cap: u64,
}

/// A confined run's bank mask and undo journal ([`call`]).
pub(crate) struct Confine<'a> {
    /// SRAM banks the core may access (bit per bank).
    pub allowed: u8,
    /// The undo journal: the native code appends to it, up to its capacity (`None`: the
    /// stores are not journaled).
    pub journal: Option<&'a mut Vec<u64>>,
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

/// A compiled region: `fn(core, ctx, limit) -> Exit`.
pub(crate) type NativeFn = unsafe extern "C" fn(*mut Core, *mut Ctx, u64) -> u32;

/// Runs `f` on `core`: the raw call with the context built from `sys`. Returns why it
/// stopped, the instructions retired and the `q` cycle (see [`Ctx::q`]).
#[inline(always)]
pub(crate) fn call(
    f: NativeFn,
    core: &mut Core,
    sys: &mut System,
    limit: u64,
    confine: Option<&mut Confine>,
) -> (Exit, u64, u64) {
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
        allowed: 0,
        journal: std::ptr::null_mut(),
        journal_len: 0,
        journal_cap: 0,
    };
    if let Some(c) = confine.as_deref() {
        ctx.allowed = c.allowed as u64;
        ctx.journal_cap = u64::MAX;
        if let Some(j) = c.journal.as_deref() {
            ctx.journal = j.as_ptr() as *mut u64;
            ctx.journal_len = j.len() as u64;
            ctx.journal_cap = j.capacity() as u64;
        }
    }
    // SAFETY: `f` was compiled by `Jit::compile` for this layout of `Core` and `Ctx`; it
    // reads and writes only the core's registers, flags, cycle, PC, the SRAM and flash
    // bytes at offsets it has bounds-checked against `SRAM_SIZE` / `FLASH_SIZE`, the code
    // page flags of those offsets, the claim table's six banks and the stall counter;
    // confined code also writes journal entries below `journal_cap`, the vector's
    // capacity, whose length is then set to the entries written (each initialised).
    let exit = unsafe { f(core, &mut ctx, limit) };
    if let Some(j) = confine.and_then(|c| c.journal.as_deref_mut()) {
        // SAFETY: the native code wrote entries `len..journal_len`, within the capacity.
        unsafe { j.set_len(ctx.journal_len as usize) };
    }
    (Exit::from_raw(exit), ctx.retired, ctx.q)
}
