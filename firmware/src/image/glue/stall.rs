//! The burst check's stall path (docs/firmware.md, "Faults"; the check:
//! [`super::super::io::IoPlan::burst_mark`]): what a converter core's handler runs instead of
//! its keys when the ADC burst of the last sample did not finish. Kept beside the handler's
//! glue, whose registers and control block it shares (`super`'s module documentation).

use super::checks::{motors_to_zero, Feed, ZeroWord};
use super::tail::handler_tail;
use super::{ctrl, tick_step, Tick};
use tactus_compiler::thumb::buffer::{CodeBuffer, Label};
use tactus_compiler::thumb::ins::{self as asm, cond};
use tactus_isa::decode::AluOp;

/// The burst check's stall path of core `core`, its control block at `ctrl_addr` and its
/// `dac_channels` DAC words: core `core`'s ADC burst of the last sample did not finish, so
/// this sample has no positions. Emitted before the handler (within a `B<cond>`'s reach of
/// the check, which branches to the label returned), with its literal pool: the tick's
/// step, the stall's record and the motors at zero ([`stall_record`]), and the handler's
/// end as every sample's ([`handler_tail`]: the sample count, and with `feed` the
/// watchdog's feed on core 0, for the core is not hung). The keys do not run: their states
/// stay as they were.
///
/// Its cycles (about 40) are far fewer than the keys' code it takes the place of, so the
/// handler's bound does not rise but for the check itself.
pub(super) fn adc_stall_path(
    a: &mut CodeBuffer,
    core: usize,
    dac_channels: u32,
    tick: &Tick,
    ctrl_addr: u32,
    feed: Option<&Feed>,
) -> Label {
    a.align4();
    let l = a.label();
    a.bind(l);
    tick_step(a, tick);
    stall_record(a, core, dac_channels);
    handler_tail(a, ctrl_addr, false, feed, None);
    a.pool();
    l
}

/// The stall path's record and outputs ([`adc_stall_path`]). Entered with r5 = the core's
/// control block.
///
/// - **The record**: an [`super::super::fault::FaultKind::AdcStall`] trip on key
///   [`super::super::fault::NO_KEY`] (every key of the core), counted once a stall — a
///   stalled sample whose last sample was one too (the fault time one less than the sample
///   count, the word's kind and key this one's) keeps the count — and its time the stall's
///   latest sample; copied to the core's watchdog scratch pair, as every trip is.
/// - **The motors**: each of the core's `dac_channels` DAC words code 0 (zero force),
///   which the next sample's DMA sends (one `STRH` each: the frames' headers stay).
///
/// Clobbers r0-r3.
fn stall_record(a: &mut CodeBuffer, core: usize, dac_channels: u32) {
    use super::super::fault::{self, FaultKind, NO_KEY};
    use tactus_rp2040::watchdog::{reg as wreg, WATCHDOG_BASE};
    let (new, same) = (a.label(), a.label());
    let tag = u32::from(NO_KEY) << 8 | u32::from(FaultKind::AdcStall.code());
    // r2 = the tag, for the test of a stall going on and the record of a new one.
    a.mov_const(2, tag);
    a.i(asm::ldr(1, 5, ctrl::FAULT));
    a.i(asm::ldr(3, 5, ctrl::FAULT_AT));
    a.i(asm::ldr(0, 5, ctrl::SAMPLES));
    a.i(asm::adds_imm(3, 3, 1));
    a.i(asm::cmp(3, 0));
    a.bc(cond::NE, new);
    a.i(asm::lsls(3, 1, 16));
    a.i(asm::lsrs(3, 3, 16));
    a.i(asm::cmp(3, 2));
    a.bc(cond::EQ, same);
    a.bind(new);
    // A new stall: one more trip, this kind on every key.
    a.i(asm::lsrs(1, 1, 16));
    a.i(asm::adds_imm(1, 1, 1));
    a.i(asm::lsls(1, 1, 16));
    a.i(asm::alu(AluOp::Orr, 1, 2));
    a.i(asm::str(1, 5, ctrl::FAULT));
    a.bind(same);
    a.i(asm::str(0, 5, ctrl::FAULT_AT));
    let (w, _) = fault::scratch(core);
    a.ldr_const(2, WATCHDOG_BASE + wreg::SCRATCH0 + 4 * w);
    a.i(asm::str(1, 2, 0));
    a.i(asm::str(0, 2, 4));
    // The motors at zero force.
    motors_to_zero(a, (0..dac_channels).map(ZeroWord::Dac));
}
