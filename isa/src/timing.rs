//! The Cortex-M0+ cycle table: the one place that says what an instruction costs.
//!
//! The executor and the static WCET analysis of the budget checker both price instructions
//! with [`cycles`], so a measured count can never disagree with a static one because of two
//! copies of the table. The table is keyed by [`Class`] (an instruction class, as in the
//! Cortex-M0+ Technical Reference Manual, DDI0484C, section 3.3 "Instruction set summary",
//! table 3-1), each variant's doc comment citing its row, and [`Class::cost`] is the table
//! itself. All figures assume zero wait states (code and data in SRAM, RP2040 datasheet 2.6);
//! the bus adds wait states on top (APB peripherals, bank contention), see the emulator's `bus` module (`tactus_emulator::bus`).
//!
//! **POP {…, PC}.** Table 3-1 lists "`POP {<loreglist>, pc}`: 3+N". We read N as the number of
//! registers in `<loreglist>`, *excluding* PC: the syntax column names PC separately from the
//! list N refers to, and the count then agrees with the pipeline (1 address cycle + one data
//! cycle per loaded word including PC = 1+N+1, + 1 for refilling the two-stage pipeline =
//! 3+N), just as a taken branch costs 1 + 1 refill = 2. So `POP {r4, pc}` costs 4 cycles and
//! `POP {pc}` costs 3. PUSH and POP without PC are 1+N with N counting every listed register,
//! LR included.

use crate::decode::{self, Instr};

/// Instruction classes of DDI0484C table 3-1, the rows of the timing table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Class {
    /// Data processing without a PC write (MOVS, ADDS, CMP, ANDS, shifts, extends, REV, ADR,
    /// ADD/SUB SP, MOV/ADD to a non-PC register): 1 cycle. DDI0484C table 3-1 "Move", "Add",
    /// "Subtract", "Compare", "Logical", "Shift", "Rotate", "Extend", "Reverse".
    Alu,
    /// MULS: 1 cycle with the single-cycle multiplier, which the RP2040 instantiates
    /// (RP2040 datasheet 2.4.1; DDI0484C table 3-1 "Multiply: 1 or 32").
    Mul,
    /// A single load (LDR, LDRH, LDRB, LDRSH, LDRSB, literal and SP-relative): 2 cycles on
    /// the AHB-Lite bus, 1 on the single-cycle I/O port (SIO, 0xd0000000). DDI0484C table 3-1
    /// "Load" and section 3.3.1 "single-cycle I/O port".
    Load,
    /// A single store (STR, STRH, STRB): 2 cycles, 1 on the I/O port. DDI0484C table 3-1 "Store".
    Store,
    /// LDM: 1+N, N = registers in the list. DDI0484C table 3-1 "Load multiple".
    LoadMultiple,
    /// STM: 1+N. DDI0484C table 3-1 "Store multiple".
    StoreMultiple,
    /// PUSH: 1+N, N counting LR when listed. DDI0484C table 3-1 "Push".
    Push,
    /// POP without PC: 1+N. DDI0484C table 3-1 "Pop".
    Pop,
    /// POP with PC ("pop and return"): 3+N, N = registers listed *besides* PC (see the module
    /// documentation). DDI0484C table 3-1 "Pop and return".
    PopPc,
    /// B (unconditional): 2 cycles. DDI0484C table 3-1 "Branch: Unconditional".
    Branch,
    /// `B<cond>`: 1 not taken, 2 taken. DDI0484C table 3-1 "Branch: Conditional".
    BranchCond,
    /// BL: 3 cycles. DDI0484C table 3-1 "Branch with link".
    Bl,
    /// BX, BLX, and MOV/ADD with PC as destination: 2 cycles. DDI0484C table 3-1
    /// "Branch, and exchange", "Branch with link and exchange", "Move: MOV PC, Rm: 2",
    /// "Add: ADD PC, PC, Rm: 2".
    BranchReg,
    /// MRS, MSR, DMB, DSB, ISB: 3 cycles (4 on a Cortex-M0; DDI0484C table 3-1
    /// "Special register", "Barriers").
    System,
    /// CPSID/CPSIE, NOP, YIELD, SEV: 1 cycle. DDI0484C table 3-1 "State change", "Hint".
    Hint,
    /// WFI, WFE: 2 cycles before the core sleeps. DDI0484C table 3-1 "Hint: WFE, WFI: 2".
    Wait,
    /// SVC, BKPT, UDF and undefined encodings: 0 cycles of their own; the cost is the
    /// exception entry ([`EXCEPTION_ENTRY`]). DDI0484C table 3-1 lists SVC and BKPT as "-".
    Trap,
}

/// Cost of one class: `base + per_register * N` cycles, plus `taken` extra when a
/// conditional branch is taken; `io_port` replaces `base` for a single load or store that
/// goes to the single-cycle I/O port.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cost {
    /// Cycles with zero registers transferred and the branch not taken (or unconditional).
    pub base: u32,
    /// Extra cycles per register transferred (LDM/STM/PUSH/POP).
    pub per_register: u32,
    /// Extra cycles when a conditional branch is taken.
    pub taken: u32,
    /// Cycles instead of `base` when the access goes to the single-cycle I/O port.
    pub io_port: u32,
}

impl Class {
    /// The timing table (DDI0484C table 3-1, zero wait states): one row per class.
    #[inline]
    pub const fn cost(self) -> Cost {
        const fn row(base: u32, per_register: u32, taken: u32, io_port: u32) -> Cost {
            Cost {
                base,
                per_register,
                taken,
                io_port,
            }
        }
        match self {
            Class::Alu => row(1, 0, 0, 1),
            Class::Mul => row(1, 0, 0, 1),
            Class::Load => row(2, 0, 0, 1),
            Class::Store => row(2, 0, 0, 1),
            Class::LoadMultiple => row(1, 1, 0, 1),
            Class::StoreMultiple => row(1, 1, 0, 1),
            Class::Push => row(1, 1, 0, 1),
            Class::Pop => row(1, 1, 0, 1),
            Class::PopPc => row(3, 1, 0, 3),
            Class::Branch => row(2, 0, 0, 2),
            Class::BranchCond => row(1, 0, 1, 1),
            Class::Bl => row(3, 0, 0, 3),
            Class::BranchReg => row(2, 0, 0, 2),
            Class::System => row(3, 0, 0, 3),
            Class::Hint => row(1, 0, 0, 1),
            Class::Wait => row(2, 0, 0, 2),
            Class::Trap => row(0, 0, 0, 0),
        }
    }

    /// Every class, in table order (for tests and for printing the table).
    pub const ALL: [Class; 17] = [
        Class::Alu,
        Class::Mul,
        Class::Load,
        Class::Store,
        Class::LoadMultiple,
        Class::StoreMultiple,
        Class::Push,
        Class::Pop,
        Class::PopPc,
        Class::Branch,
        Class::BranchCond,
        Class::Bl,
        Class::BranchReg,
        Class::System,
        Class::Hint,
        Class::Wait,
        Class::Trap,
    ];
}

/// Exception entry: 15 cycles from the cycle the exception is taken to the first instruction
/// of the handler (DDI0484C section 5.6 "Interrupt latency": 15 cycles with zero wait states).
pub const EXCEPTION_ENTRY: u32 = 15;

/// Exception return (unstacking 8 words and refilling the pipeline), charged in addition to
/// the cycles of the instruction that loads EXC_RETURN into PC (BX or POP {…, PC}). The TRM
/// gives no figure; we charge 8 word loads + 2 refill = 10, by analogy with the 15-cycle
/// entry (8 stores + vector load + refill + bookkeeping). A model choice, not a sourced number.
pub const EXCEPTION_RETURN: u32 = 10;

/// Wait states added to each load from an APB peripheral (0x40000000-0x4fffffff): a load
/// there costs 3 cycles (RP2040 datasheet 2.1.2 / Tactus DESIGN.md "APB loads 3").
pub const APB_LOAD_WAIT: u32 = 1;

/// Wait states added to each store to an APB peripheral: a store there costs 4 cycles.
pub const APB_STORE_WAIT: u32 = 2;

/// Cycles of the SIO hardware divider: the result is valid this many cycles after the cycle
/// of the store that wrote the last operand (RP2040 datasheet 2.3.1.5).
pub const DIVIDER_LATENCY: u32 = 8;

/// The class of an instruction (its row in the table).
#[inline]
pub fn class(instr: &Instr) -> Class {
    use Instr::*;
    match *instr {
        Alu {
            op: decode::AluOp::Mul,
            ..
        } => Class::Mul,
        AddHi { rdn: 15, .. } | MovHi { rd: 15, .. } | Bx { .. } | Blx { .. } => Class::BranchReg,
        LdrLit { .. } => Class::Load,
        MemReg { op, .. } | MemImm { op, .. } => {
            if op.is_store() {
                Class::Store
            } else {
                Class::Load
            }
        }
        Push { .. } => Class::Push,
        Pop { list } if list & 0x8000 != 0 => Class::PopPc,
        Pop { .. } => Class::Pop,
        Stm { .. } => Class::StoreMultiple,
        Ldm { .. } => Class::LoadMultiple,
        B { .. } => Class::Branch,
        BCond { .. } => Class::BranchCond,
        Bl { .. } => Class::Bl,
        Msr { .. } | Mrs { .. } | Barrier(_) => Class::System,
        Cps { .. } => Class::Hint,
        Hint(decode::Hint::Wfi | decode::Hint::Wfe) => Class::Wait,
        Hint(decode::Hint::Nop | decode::Hint::Yield | decode::Hint::Sev) => Class::Hint,
        Svc { .. } | Bkpt { .. } | Udf { .. } | Undefined { .. } => Class::Trap,
        _ => Class::Alu,
    }
}

/// Number of registers an instruction transfers in the sense of table 3-1's "N": the list
/// size for LDM/STM/PUSH/POP (LR counted for PUSH, PC *not* counted for POP, see the module
/// documentation), 0 otherwise.
#[inline]
pub fn registers(instr: &Instr) -> u32 {
    match *instr {
        Instr::Push { list } => list.count_ones(),
        Instr::Pop { list } => (list & 0xff).count_ones(),
        Instr::Stm { list, .. } | Instr::Ldm { list, .. } => list.count_ones(),
        _ => 0,
    }
}

/// Cycles an instruction takes with zero wait states: `taken` says whether a conditional
/// branch is taken (ignored otherwise), `io_port` whether a single load/store addresses the
/// single-cycle I/O port. Wait states from the bus (APB, bank contention) and exception
/// entry/return come on top. This is the function the static WCET analysis uses.
#[inline]
pub fn cycles(instr: &Instr, taken: bool, io_port: bool) -> u32 {
    let class = class(instr);
    let cost = class.cost();
    let base = if io_port { cost.io_port } else { cost.base };
    base + cost.per_register * registers(instr) + if taken { cost.taken } else { 0 }
}
