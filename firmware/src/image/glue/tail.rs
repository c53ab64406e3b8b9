//! The sample interrupt's end, which every path through the handler shares: the usual
//! end behind the keys' code, the feeding class's own end on core 0 (with the watchdog's
//! feed, [`super::Feed`]), and the ADC stall path's ([`super::stall`]). Kept beside the
//! handler's glue, whose registers and control block they share (`super`'s module
//! documentation).

use super::checks::{feed_watchdog, mark_behind, Feed};
use super::{ctrl, mov_hi, syst, EXC_RETURN_NOT};
use tactus_compiler::thumb::buffer::{CodeBuffer, Label};
use tactus_compiler::thumb::ins::{self as asm, cond};
use tactus_isa::decode::{AluOp, Instr};

/// The sample interrupt's tail (its control block at `ctrl_addr`): `r5` reloaded
/// when `reload_r5` (an update or a guard clobbers it), the miss check, the sample count,
/// with `feed` the watchdog's feed ([`feed_watchdog`], and its [`mark_behind`] path), and
/// the exception return. `keys_end` is bound at the ICSR load ([`super::CoreLabels::keys_end`]).
pub(super) fn handler_tail(
    a: &mut CodeBuffer,
    ctrl_addr: u32,
    reload_r5: bool,
    feed: Option<&Feed>,
    keys_end: Option<Label>,
) {
    if reload_r5 {
        a.ldr_const(5, ctrl_addr);
    }
    // A miss: the next tick's wrap has already pended SysTick again (ICSR.PENDSTSET: the
    // entry cleared it), so the handler ends at or after the next tick.
    a.ldr_const(0, syst::ICSR);
    if let Some(l) = keys_end {
        a.bind(l);
    }
    a.i(asm::ldr(2, 0, 0));
    a.i(asm::lsls(2, 2, 31 - syst::PENDSTSET_BIT)); // N = PENDSTSET
    let on_time = a.label();
    a.bc(cond::PL, on_time);
    a.i(asm::ldr(1, 5, ctrl::MISSES));
    a.i(asm::adds_imm(1, 1, 1));
    a.i(asm::str(1, 5, ctrl::MISSES));
    a.bind(on_time);
    a.i(asm::ldr(1, 5, ctrl::SAMPLES));
    a.i(asm::adds_imm(1, 1, 1));
    a.i(asm::str(1, 5, ctrl::SAMPLES));
    let behind = a.label();
    if let Some(f) = feed {
        feed_watchdog(a, f, behind);
    }
    let ret = |a: &mut CodeBuffer| {
        a.i(asm::movs(0, EXC_RETURN_NOT));
        a.i(asm::alu(AluOp::Mvn, 0, 0));
        a.i(mov_hi(14, 0));
        a.i(Instr::Bx { rm: 14 });
    };
    ret(a);
    if feed.is_some_and(|f| f.other_samples.is_some()) {
        // Core 1 behind: no feed, the mark instead, and its own return (no branch back:
        // as long as the feed).
        a.bind(behind);
        mark_behind(a);
        ret(a);
    }
}
