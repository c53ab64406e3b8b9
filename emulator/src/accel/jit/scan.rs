//! Region discovery: which instructions the block compiler translates, where a region
//! starts and ends, and the cycle bound from each instruction to the region's next exit
//! (see the parent module's documentation).

use crate::bus::Bus;
use crate::exec::branch_target;
use crate::system::System;
use tactus_isa::decode::{decode, Instr};
use tactus_isa::timing;

/// Most instructions in one region. Compiling grows steeply with a region's length, and a
/// region cut by the cap costs one more dispatch each time it runs; 132 is the measured best
/// of the demo's host instructions (`tactus play --no-wav`, cachegrind, one thread) on the
/// plain and the converter board: 128 gave 13.83 / 18.13 G, 130 13.75 / 18.04 G, 132
/// 13.76 / 18.02 G, 134 13.75 / 18.05 G, 136 13.75 / 18.06 G, 144 13.88 / 18.21 G (192 and
/// 256 cost more still). A key update's first region with the firmware's ring bound is
/// longer than 128, so at 128 every natively run update took one more entry.
pub(crate) const MAX_REGION: usize = 132;

/// One instruction of a region.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RegionInstr {
    pub pc: u32,
    pub size: u32,
    pub instr: Instr,
    /// (not taken, taken) cycles from the timing table.
    pub cost: (u32, u32),
}

/// Whether the block compiler translates `instr`.
pub(crate) fn translated(instr: &Instr) -> bool {
    use Instr::*;
    match *instr {
        LslImm { .. } | LsrImm { .. } | AsrImm { .. } | AddReg { .. } | SubReg { .. } => true,
        AddImm { .. } | SubImm { .. } | MovImm { .. } | CmpImm { .. } | Alu { .. } => true,
        CmpHi { .. } | Sxth { .. } | Sxtb { .. } | Uxth { .. } | Uxtb { .. } => true,
        Rev { .. } | Rev16 { .. } | Revsh { .. } | AddHi { .. } | MovHi { .. } => true,
        Bx { .. } | Blx { .. } | LdrLit { .. } | MemReg { .. } | MemImm { .. } => true,
        Adr { .. } | AddSpImm { .. } | AddSp { .. } | SubSp { .. } => true,
        Push { list } | Pop { list } => list != 0,
        Stm { list, .. } | Ldm { list, .. } => list != 0,
        Instr::Hint(tactus_isa::decode::Hint::Nop | tactus_isa::decode::Hint::Yield) => true,
        BCond { cond, .. } => cond < 14,
        B { .. } | Bl { .. } => true,
        _ => false,
    }
}

/// True when `instr` always transfers control (nothing falls through it).
pub(super) fn unconditional(instr: &Instr) -> bool {
    use Instr::*;
    match *instr {
        B { .. } | Bl { .. } | Bx { .. } | Blx { .. } => true,
        Pop { list } => list & 0x8000 != 0,
        AddHi { rdn, .. } => rdn == 15,
        MovHi { rd, .. } => rd == 15,
        _ => false,
    }
}

/// The internal target of a B / B<cond> at `pc`.
pub(super) fn branch_of(i: &RegionInstr) -> Option<u32> {
    match i.instr {
        Instr::B { offset } | Instr::BCond { offset, .. } => Some(branch_target(i.pc, offset)),
        _ => None,
    }
}

/// Data words `instr` moves (each may wait one cycle for the other core).
pub(crate) fn data_words(instr: &Instr) -> u32 {
    use Instr::*;
    match *instr {
        LdrLit { .. } | MemImm { .. } | MemReg { .. } => 1,
        Push { list } | Pop { list } => list.count_ones(),
        Stm { list, .. } | Ldm { list, .. } => list.count_ones(),
        _ => 0,
    }
}

/// Decodes the region at `entry` (see the module documentation), marking the SRAM pages
/// it comes from as code pages. Returns its instructions and halfwords (the cache key).
/// The region ends before any address of `stops` (sorted) but its entry: a memoized span's entry
/// ([`crate::accel::memo`]) is tried only where a core is dispatched, so no region runs
/// through one (a core's keys part, entered by falling through from the sample
/// interrupt's tick code, would otherwise never be replayed).
pub(crate) fn scan(sys: &mut System, entry: u32, stops: &[u32]) -> (Vec<RegionInstr>, Vec<u16>) {
    let mut instrs = Vec::new();
    let mut halfwords = Vec::new();
    let mut a = entry;
    let mut furthest = entry;
    // The instruction at `a` is a branch island the region went on to (see `island`).
    let mut hop = false;
    while instrs.len() < MAX_REGION {
        if a != entry && stops.binary_search(&a).is_ok() {
            break;
        }
        let Ok((hw1, hw2, size)) = sys.fetch_instr(a) else {
            break;
        };
        let instr = decode(hw1, hw2);
        if !translated(&instr) {
            break;
        }
        for h in [a, a.wrapping_add(size - 2)] {
            if let Some((off, _)) = tactus_rp2040::memory::sram_location(h) {
                sys.code_pages[off >> 8] = true;
            }
        }
        halfwords.push(hw1);
        if size == 4 {
            halfwords.push(hw2);
        }
        let cost = (
            timing::cycles(&instr, false, false),
            timing::cycles(&instr, true, false),
        );
        let i = RegionInstr {
            pc: a,
            size,
            instr,
            cost,
        };
        if let Some(t) = branch_of(&i) {
            if t > a && t.wrapping_sub(entry) < 4 * MAX_REGION as u32 {
                furthest = furthest.max(t);
            }
        }
        instrs.push(i);
        let next = a.wrapping_add(size);
        if next < a {
            break;
        }
        if unconditional(&instr) && (hop || furthest < next) {
            match island(sys, &i) {
                Some(t) => {
                    (a, hop) = (t, true);
                    continue;
                }
                None => break,
            }
        }
        a = next;
    }
    (instrs, halfwords)
}

/// The target of `i` when it is a `B` ahead whose target is itself a `B` (a branch island:
/// the assembler's hop to a target beyond a conditional branch's reach), where the region
/// goes on (see the module documentation): at an address past every one scanned so far, so
/// a region's addresses still rise and none is scanned twice.
fn island(sys: &mut System, i: &RegionInstr) -> Option<u32> {
    let Instr::B { offset } = i.instr else {
        return None;
    };
    let t = branch_target(i.pc, offset);
    let (hw1, hw2, _) = sys.fetch_instr(t).ok()?;
    (t > i.pc && matches!(decode(hw1, hw2), Instr::B { .. })).then_some(t)
}

/// Per instruction, an upper bound on the cycles from its start to the region's next exit
/// or back edge (see the module documentation); `targets[i]` is the index a B / B<cond>
/// jumps to when it stays in the region.
pub(super) fn bounds(instrs: &[RegionInstr], targets: &[Option<usize>]) -> Vec<u64> {
    let mut bound = vec![0u64; instrs.len() + 1];
    for i in (0..instrs.len()).rev() {
        let ins = &instrs[i];
        let own = ins.cost.0.max(ins.cost.1).max(1) as u64 + data_words(&ins.instr) as u64;
        let fall = if unconditional(&ins.instr) {
            0
        } else {
            bound[i + 1]
        };
        let jump = match targets[i] {
            Some(t) if t > i => bound[t],
            _ => 0,
        };
        bound[i] = own + fall.max(jump);
    }
    bound
}
