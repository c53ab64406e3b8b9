//! The reset handler's record of why the board booted: the *reset word* of each core's
//! fault record ([`super::ctrl::RESET_CAUSE`]; `super::super::fault`, "The reset word").
//!
//! **Why at boot, and why raw.** Why the chip last reset is in two registers that keep it
//! until the next reset: WATCHDOG.REASON (datasheet 4.7.6: TIMER, FORCE; a chip-level reset
//! clears it) and VREG_AND_CHIP_RESET.CHIP_RESET (2.12.7: HAD_POR for a power-on or
//! brown-out, HAD_RUN, HAD_PSM_RESTART; a watchdog reset leaves it). Their bits do not
//! overlap, so one `ORRS` keeps both whole, and the host decodes them by the one rule
//! ([`super::super::fault::ResetCause::of`]). Read once per boot, in the reset handler: no
//! cycle of the sample interrupt.

use super::ctrl;
use tactus_compiler::thumb::buffer::CodeBuffer;
use tactus_compiler::thumb::ins as asm;
use tactus_isa::decode::AluOp;
use tactus_rp2040::vreg::{reg as vreg, VREG_AND_CHIP_RESET_BASE};
use tactus_rp2040::watchdog::{reg as wreg, WATCHDOG_BASE};

/// The reset word into the control block (r5): WATCHDOG.REASON | CHIP_RESET (module
/// documentation). Clobbers r0-r2.
pub(super) fn record_reset_cause(a: &mut CodeBuffer) {
    a.ldr_const(2, WATCHDOG_BASE);
    a.i(asm::ldr(0, 2, wreg::REASON as u16));
    a.ldr_const(2, VREG_AND_CHIP_RESET_BASE);
    a.i(asm::ldr(1, 2, vreg::CHIP_RESET as u16));
    a.i(asm::alu(AluOp::Orr, 0, 1));
    a.i(asm::str(0, 5, ctrl::RESET_CAUSE));
}
