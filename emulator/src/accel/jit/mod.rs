//! The block compiler: Thumb code regions translated to native code with cranelift.
//!
//! **What a region is.** A region starts at the address the core is about to execute and
//! runs linearly through memory over the instructions this module translates (data
//! processing, multiplies, loads and stores, LDM/STM/PUSH/POP, ADR/SP arithmetic, B, B<cc>,
//! BL, BX, BLX, MOV/ADD to PC), up to [`MAX_REGION`](scan::MAX_REGION) instructions; it stops before the first
//! instruction it does not translate (SVC, WFI, MSR, CPS, barriers, …) and after an
//! unconditional branch that no earlier branch jumps beyond — except a `B` ahead to a `B`
//! (a branch island, the assembler's hop for a conditional branch's short reach), where it
//! goes on at the island (and so through a chain of them) and ends after the last, so that
//! a hop costs no exit and entry (the demo's host instructions 18.25 → 18.13 G on
//! `rp2040_io`, whose state checks added hops, 13.92 → 13.83 G plain); its addresses still
//! rise. Branches whose target is an
//! instruction of the region become native jumps (a forward `if`, a counted loop), so the
//! guest registers stay in host registers across loop iterations; every other target
//! leaves the native code with the core's PC set.
//!
//! **Meaning.** Each instruction's effect is written once more here, as cranelift IR — the
//! flags of `adds`, the conditions of `condition`, the shifts of `alu`, the memory paths of
//! `mem_fast`/`push_fast`/`pop_fast` in `exec.rs`. They are not a second authority:
//! `tests/block_jit.rs` runs every translated form, on random operands and flags, as a
//! one-instruction region against `Core::execute_op` (the interpreter's executor), and
//! `tests/block_engine.rs` runs random programs, the key-update workload and (in
//! `firmware`) the firmware images on both engines with every observable compared. The
//! region's decoding is `decode::decode` and its prices are `timing::cycles`, called when
//! the region is compiled: the timing table stays the one source of cycles.
//!
//! **Cycles.** Each instruction's cost is the timing table's `(not taken, taken)` pair,
//! summed at compile time along straight-line code; the run-time additions are only the
//! data-dependent ones: which way a conditional branch went, and the wait state of an SRAM
//! access that finds its bank claimed by the other core in the same cycle (the arbiter of
//! [`crate::bus`], done inline on the same `bank_claim` table). Flash never waits. In
//! confined code (windows), a word load from the core's private peripheral bus and a word
//! store to SYST_RVR call the NVIC as the executor does ([`abi::ppb_load`],
//! [`abi::ppb_store`]: the sample interrupt's SysTick and ICSR accesses; no other PPB
//! store, since those can pend, enable or restart something); in a window on a board with
//! converters, a single access to the core's bank the DMA reaches and a word store to the
//! DMA's or PIOs' registers are logged for the I/O's replay ([`abi::io_sram`],
//! [`abi::io_reg`]; `accel/io_window/`), as the window's bus logs them. Any other address
//! (peripherals, SIO, other PPB stores, the boot ROM, an unaligned or unmapped access)
//! leaves the native code *before* the instruction, with every register, flag and counter
//! as at its start, and the board's general path executes it. The caller runs a region
//! only when the core's cycle plus the region's bound — the longest path from its entry to
//! an exit or a loop's back edge, each instruction priced by the table's larger cost plus
//! one wait per data word — is at most the run's deadline, so every instruction the native
//! code starts starts before the deadline, as the interpreter's would; each back edge
//! checks the same against the bound from the loop's head, and leaves at the head when it
//! does not fit.
//!
//! **Self-modifying code.** A region marks the SRAM pages its instructions come from as
//! code pages ([`System::code_pages`]); a native store into such a page completes, and the
//! code leaves right after that instruction so the caller drops every decoded block and
//! region ([`System::invalidate_code`]), as the interpreter's store does. Compiled code is
//! kept by the region's address *and its instruction halfwords*, so after an invalidation
//! (or a host write) an unchanged region is found again without recompiling; changed code
//! is a new key.
//!
//! **Exits.** The function returns why it stopped ([`Exit`]) and writes back the guest
//! registers and flags it changed (the flags only on paths that may have changed one: the
//! demo 17.88 → 17.80 G on `rp2040_io`, 13.64 → 13.55 G plain), the cycle counter, the contention stalls (only code that
//! arbitrates, [`Flavour::Shared`] and [`Flavour::Confined`], can add to them, so only it
//! loads and stores them: the plain demo 14.86 → 14.74 G, on `rp2040_io` 19.48 → 19.36 G), the number of
//! instructions retired and the end cycle of its last instruction that took two cycles or
//! more (what the board needs to replay a sleeping core's turns, [`crate::accel::block`]). The
//! instructions are counted in the context itself ([`abi::Ctx`]'s `retired`), added where
//! control flow leaves the code or joins a label, so no host register carries the count
//! around a loop.
//!
//! **Registers and layout.** A region keeps the flags and the cycle count in cranelift
//! variables; the guest registers stay in the core (`Core::r`): a read is a load, a write a
//! store, and a value is reused where its load or store dominates (the same block, or an
//! instruction's start since the last label), so that no exit carries them (an exit's
//! arguments were most of the register allocator's work: the demo 15.76 → 15.12 G host
//! instructions plain, 20.22 → 19.61 G with converters, and the native code no slower). Each
//! leaving path stores its PC, and there is one exit block per reason. Of the context, only
//! what nearly every access uses (the SRAM and the bank claims) is held from the entry, and
//! the rest (flash, code pages, the journal and its capacity, the stall counter) is loaded
//! where it is used, so that fewer values compete for the host's registers (x86-64 has 5
//! callee-saved ones to keep a value across a helper call in). A register the region never
//! writes ([`crate::accel::memo`]'s `usage`) is loaded by a pure load, which cranelift merges
//! and places where first needed. Exits,
//! helper calls and the general path's blocks are marked cold, so cranelift lays them
//! after the hot path (the demo's simulated I1 misses −8 % plain, −5 % with converters).
//!
//! **Confinement.** For two cores running ahead of each other ([`crate::board`], "Running
//! ahead") each region is also compiled *confined*, for one bank mask (a cache per mask;
//! the code is called only with that mask, a constant of the code): every SRAM access checks its
//! bank against the mask and leaves before the instruction when the bank is not allowed
//! (with exactly one of SRAM0-3 allowed, an access through the alias to that bank passes
//! one comparison that is the view, alignment and bank check at once), and, in the variant
//! called with a journal (the core running ahead), every store appends `(word offset, old
//! word)` to the context's undo journal; the entry and each back edge check that the
//! journal has room for every store word of the region, so no store checks it. The
//! variant without (the other core catching up) has no journal code. The runner also
//! refuses a region fetched from a bank outside the mask ([`cache::Region::banks`]).
//!
//! **Modules.** [`scan`] finds a region (which instructions are translated, where it ends,
//! the cycle bound of each instruction); [`translate`] builds a region's function (the
//! entry and exit code, the cycle and instruction counts, control flow), with the
//! instruction groups in [`alu`] (data processing: flags, conditions, shifts) and
//! [`memory`] (loads, stores, the inline SRAM arbiter, multiple transfers); [`abi`] is the
//! calling convention between native code and the board (the context, the exit reasons);
//! [`cache`] keeps the compiled regions (a board's lookup, the compile threshold,
//! invalidation by code epoch; the process's store of machine code, shared by every board).
//!
//! **Flavours.** Each region is compiled in several variants ([`Flavour`]): arbitrating
//! against the other core's bank claims or *solo* (the other core's claims are all older
//! than the core's cycle, so no access can wait and each only records its claim), each
//! plain or confined (per bank mask, with or without journal code, timed or not: timed
//! code checks the deadline before every instruction, for a region whose bound does not fit
//! before the run's limit, [`Flavour::Confined`]). The runner picks
//! solo code once the core's cycle has passed the other core's last claim (of the banks
//! it may touch, when confined), which it cannot change while this core runs.

mod abi;
mod alu;
mod cache;
mod memory;
mod scan;
mod translate;

pub(crate) use abi::{call, call_confined, Ctx, Exit};
pub(crate) use cache::Jit;
pub(crate) use scan::data_words;
pub(crate) use translate::Flavour;
