//! The ARMv6-M Thumb backend: a [`FixedProgram`] as machine code for the Cortex-M0+.
//!
//! Pipeline: [`select`] (fixed-point IR → [`mir`] over virtual registers, choosing each
//! sequence from the range analysis' word bounds) → [`regalloc`] (linear scan, spilling
//! to the stack) → [`emit`] (prologue/epilogue per AAPCS into the [`buffer`], which places
//! literal pools, relaxes branches, encodes with the emulator's encoder and writes a GNU
//! assembler listing; the firmware image's glue uses the same buffer) → `peephole` (each
//! function's allocated code: compares with 0 the flags already answer, loads of values a
//! register holds, register copies) → [`elf`] (a relocatable object).
//!
//! The generated functions have the interface and state layout of [`crate::abi`] exactly,
//! as the C backend's do — one header describes both:
//!
//! ```c
//! void tactus_<name>_init(struct tactus_<name>_state *s);
//! void tactus_<name>_update(struct tactus_<name>_state *s, const int32_t *sensors, int32_t *out);
//! ```
//!
//! AAPCS (ARM IHI 0042): arguments in r0–r2; r4–r11 and SP preserved; LR is saved and the
//! return is `POP {…, PC}`. The state pointer lives in r7 for the whole update. That is
//! [`compile`]'s; [`compile_with`] takes a [`Convention`] that leaves some callee-saved
//! registers free — the firmware image's own ([`Convention::SAMPLE_ISR`]), where only its
//! glue calls the update — and the object records which it leaves modified
//! ([`ThumbObject::clobbers`]). The code is position independent (PC-relative branches and
//! literal loads only, no data sections), so the object needs no relocations: it can run
//! from SRAM or flash at any word address.

pub mod buffer;
mod cse;
mod dce;
pub mod elf;
pub mod emit;
mod forward;
pub mod ins;
mod literals;
pub mod mir;
mod peephole;
pub mod regalloc;
pub mod select;

use crate::abi::{self, CConfig, Interface, OutLayout, StateLayout};
use crate::fixed::FixedProgram;
use std::fmt;

/// Why a program cannot be compiled to Thumb code.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ThumbError {
    /// A construct the Thumb backend does not implement yet (the C backend does).
    Unsupported(String),
    /// The interface (header) could not be generated; see [`abi::InterfaceError`].
    Interface(String),
    /// An instruction did not encode (a backend bug: a field out of range).
    Encoding(String),
    /// The IR breaks an invariant ([`crate::verify`]: a compiler bug), as its message.
    Ir(String),
}

impl fmt::Display for ThumbError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ThumbError::Unsupported(what) => {
                write!(f, "the Thumb backend does not support {what}")
            }
            ThumbError::Interface(e) => write!(f, "cannot describe the interface: {e}"),
            ThumbError::Encoding(e) => write!(f, "internal error: {e}"),
            ThumbError::Ir(e) => write!(f, "internal error: {e}"),
        }
    }
}

impl std::error::Error for ThumbError {}

/// A compiled instrument: code, interface and layouts.
#[derive(Clone, Debug)]
pub struct ThumbObject {
    /// Machine code, symbols and listing.
    pub code: emit::Code,
    /// The C header describing the interface (the C backend's header).
    pub header: String,
    /// Identifier stem: the functions are `tactus_<stem>_init` / `_update`.
    pub stem: String,
    /// Layout of `out[]`.
    pub out: OutLayout,
    /// Layout of the state struct.
    pub state: StateLayout,
    /// Callee-saved registers (bit *n* = r*n*) its functions may leave modified: 0 under
    /// AAPCS; under another [`Convention`] the free registers they use.
    pub clobbers: u16,
    /// The convention it was compiled for.
    pub convention: Convention,
}

/// The calling convention of the generated functions: which AAPCS callee-saved registers
/// (r4–r11) they may leave modified, so that their prologue neither saves nor restores
/// them, and which words of `out[]` the update writes (the backend's config;
/// [`compile_with`]). Arguments, the state pointer in r7, SP and the return through the
/// saved LR are AAPCS's in every convention, and so is the layout of `out[]`
/// ([`crate::abi::OutLayout`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Convention {
    /// Free callee-saved registers, bit *n* = r*n* (only r4–r11 mean anything).
    pub free: u16,
    /// The update leaves the force terms' words of `out[]` (`OutLayout::forces`…)
    /// unwritten: its caller reads only the total (what drives the motor), the outputs and
    /// the events. Under AAPCS (`false`) it writes every word the header names.
    pub skip_terms: bool,
}

impl Convention {
    /// AAPCS: r4–r11 preserved, every word of `out[]` written (the ELF object and header
    /// users link against).
    pub const AAPCS: Convention = Convention {
        free: 0,
        skip_terms: false,
    };
    /// The firmware image's sample interrupt, which alone calls the update there: r5 (the
    /// control block, which the handler loads again once before its end) and r8–r11 (the
    /// limiter's constants, which the glue then takes from its literal pool or an
    /// immediate) are free; r4, r6 and r7 (the key's record, the window bases) are
    /// preserved. The force terms' words are not written: the glue drives the DAC from the
    /// total, and the terms are the host engines' traces. The figures: BENCHMARKS.md.
    pub const SAMPLE_ISR: Convention = Convention {
        free: 1 << 5 | 0xf << 8,
        skip_terms: true,
    };
}

impl ThumbObject {
    /// Offset and size (bytes) in `.text` of the function named `name`.
    pub fn symbol(&self, name: &str) -> Option<(usize, usize)> {
        self.code
            .symbols
            .iter()
            .find(|(n, ..)| n == name)
            .map(|&(_, o, s)| (o, s))
    }

    /// Name of the update function.
    pub fn update_name(&self) -> String {
        abi::update_symbol(&self.stem)
    }

    /// Name of the init function.
    pub fn init_name(&self) -> String {
        abi::init_symbol(&self.stem)
    }

    /// The object as an ELF relocatable file (ARM, EABI 5).
    pub fn elf(&self) -> Result<Vec<u8>, ThumbError> {
        elf::write(&self.code)
    }
}

/// The largest object the backend produces: the RP2040's 256 KB of striped SRAM (the
/// firmware runs its per-sample code from SRAM; the datasheet's SRAM0–3).
pub const MAX_CODE_BYTES: usize = 256 * 1024;

fn too_big(bytes: usize) -> ThumbError {
    ThumbError::Unsupported(format!(
        "an update of {} KB or more of code, more than the {} KB of SRAM the firmware runs code from",
        bytes / 1024,
        MAX_CODE_BYTES / 1024
    ))
}

/// Compiles a fixed-point program to Thumb code.
///
/// Errors: [`ThumbError::Unsupported`] for a division by a run-time value whose range
/// contains 0, a few format corners no shipped instrument reaches (the C backend supports
/// them), and code larger than [`MAX_CODE_BYTES`]; `sqrt` and `exp` are inlined (see
/// [`select`]).
pub fn compile(fp: &FixedProgram) -> Result<ThumbObject, ThumbError> {
    compile_with(fp, Convention::AAPCS)
}

/// [`compile`] under calling convention `conv`: the same code but for the prologues and
/// epilogues (the free registers are not saved) and the spill homes (a free high register
/// is cheaper).
///
/// Errors: as [`compile`].
pub fn compile_with(fp: &FixedProgram, conv: Convention) -> Result<ThumbObject, ThumbError> {
    crate::verify::verify(&fp.program).map_err(|e| ThumbError::Ir(e.to_string()))?;
    let c = Interface::new(fp, &CConfig::default())
        .map_err(|e| ThumbError::Interface(e.to_string()))?;
    let p = &fp.program;
    let st = StateLayout::new(p);
    let (used, _) = crate::ir::live_values(p);
    let upd = select::Sel::new(fp, &st, &c.layout, used.clone())
        .skip_terms(conv.skip_terms)
        .run()?;
    // Every machine instruction takes at least 2 bytes: refuse early what cannot fit.
    let at_least = 2 * upd
        .code
        .iter()
        .filter(|m| !matches!(m, mir::M::Label(_) | mir::M::Note(_) | mir::M::Mark(_)))
        .count();
    if at_least > MAX_CODE_BYTES {
        return Err(too_big(at_least));
    }
    let ini = select::Sel::new(fp, &st, &c.layout, used).init_body();
    let functions = [
        (abi::init_symbol(&c.stem), ini),
        (abi::update_symbol(&c.stem), upd),
    ];
    let allocs: Vec<_> = functions
        .iter()
        .map(|(_, sel)| regalloc::allocate(&sel.code, sel.nregs))
        .collect();
    let exclusive: Vec<_> = functions
        .iter()
        .flat_map(|(_, sel)| sel.exclusive.iter().copied())
        .collect();
    // First with LR as a free spill home, which no branch may then be relaxed into a `BL`
    // for; where one must (a long body), again with LR left alone.
    let free = conv.free & 0x0ff0;
    let lower = |homes: emit::Homes, long: buffer::LongBranch| {
        let mut buf = buffer::CodeBuffer::new(long);
        let mut clobbers = 0;
        for ((name, sel), alloc) in functions.iter().zip(&allocs) {
            clobbers |= emit::lower(&mut buf, name, &sel.code, alloc, homes);
        }
        emit::assemble(&buf, &exclusive).map(|code| (code, clobbers))
    };
    let (code, clobbers) = match lower(emit::Homes { lr: true, free }, buffer::LongBranch::Refuse) {
        Ok(done) => done,
        Err(_) => lower(emit::Homes { lr: false, free }, buffer::LongBranch::Bl)?,
    };
    if code.text.len() > MAX_CODE_BYTES {
        return Err(too_big(code.text.len()));
    }
    Ok(ThumbObject {
        code,
        header: c.header,
        stem: c.stem,
        out: c.layout,
        state: st,
        clobbers,
        convention: conv,
    })
}
