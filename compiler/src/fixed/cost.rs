//! The planner's cost model on the Cortex-M0+: the cycles of each product form and of a
//! run-time division, priced by the one timing table (`tactus_isa::timing`) from the
//! instruction sequences the Thumb backend emits for them. The forms themselves are chosen
//! by precision, cheapest first ([`super::products`]); these figures are what the precision
//! report and the Thumb selector quote and compare.

use super::*;

/// Cycles of a straight-line sequence of `alu` single-cycle ALU instructions, `loads`
/// literal-pool loads and `muls` `MULS`, priced by the one timing table
/// ([`tactus_isa::timing`]): the planner's and the precision report's cost model.
pub(super) const fn sequence_cycles(alu: u32, loads: u32, muls: u32) -> u32 {
    alu * Class::Alu.cost().base + loads * Class::Load.cost().base + muls * Class::Mul.cost().base
}

/// Estimated Cortex-M0+ cycles of a run-time division of `quotient_bits` quotient bits:
/// `(steps, cycles)` on the SIO divider when that is cheaper than the restoring division
/// (`compiler/src/thumb/select/divide.rs`), else `(0, cycles)` of the restoring division.
/// Priced by the timing table: the restoring division takes 12 single-cycle instructions of
/// set-up and signs, then per quotient bit `LSLS`, `ADCS`, `SUBS`, `ADCS` and a `B<cond>`
/// taken (or not taken and a `MOV`): 6 cycles. The SIO divider takes about 18 single-cycle
/// instructions of set-up and sign handling, then per step the divider's latency
/// ([`DIVIDER_LATENCY`], which also shifts the digits), three accesses on the single-cycle
/// I/O port (the dividend store, the quotient and remainder loads) and three ALU
/// instructions (the remainder's shift, the merge of the digit): 14 cycles.
pub fn division_cycles(quotient_bits: i32, divisor_bits: i32) -> (u32, u32) {
    let alu = Class::Alu.cost().base;
    let per_bit = 4 * alu + Class::BranchCond.cost().base + Class::BranchCond.cost().taken;
    let restoring = 12 * alu + per_bit * quotient_bits.max(1) as u32;
    let io = Class::Load.cost().io_port;
    let per_step = DIVIDER_LATENCY + 3 * io + 3 * alu;
    let sio_setup = 18 * alu;
    match sio_division_steps(quotient_bits, divisor_bits) {
        Some(n) if sio_setup + per_step * n < restoring => (n, sio_setup + per_step * n),
        _ => (0, restoring),
    }
}

impl MulKind {
    /// Estimated Cortex-M0+ cycles, operand splitting and the final rounding included,
    /// priced by the timing table ([`tactus_isa::timing`]: single-cycle ALU and `MULS`, a
    /// literal load 2): `Muls` 6 (two pre-shifts, a constant load, `MULS`, the rounding
    /// shift); `Mul32x16` 9 (`ASRS`/`UXTH` for the kept operand's halves, the cut operand's
    /// `ASRS` or its constant's `LDR`, 2 `MULS`, `LSLS`, `ASRS`, `ADDS`; its unit `k` is chosen
    /// so that no rounding shift follows — the piano's listing has exactly these 8
    /// instructions); `High` 14 (halves of each operand and a copy for the first `MULS`, 3
    /// `MULS`, 3 shifts, 2 adds, the rounding); `Wide` 23 (a literal load, halves and a copy,
    /// 4 `MULS`, the cross terms into a 64-bit pair with `ADDS`/`ADCS`, a 64-bit rounding
    /// shift).
    pub fn cycles(self) -> u32 {
        match self {
            MulKind::Muls(..) => sequence_cycles(3, 1, 1),
            MulKind::Mul32x16 { .. } => sequence_cycles(5, 1, 2),
            MulKind::High(_) => sequence_cycles(4 + 1 + 3 + 2 + 1, 0, 3),
            MulKind::Wide => sequence_cycles(4 + 1 + 8 + 4, 1, 4),
        }
    }
}
