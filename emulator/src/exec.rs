//! Instruction semantics: one `match` arm per [`Instr`] variant.
//!
//! Each arm computes results and flags exactly as the ARMv6-M pseudocode (DDI0419 A6.7)
//! does, touches memory only through the [`Bus`] (which reports wait states), and returns what
//! the caller needs to price it with [`tactus_isa::timing::cycles`] — the one timing table — plus wait
//! states, plus [`tactus_isa::timing::EXCEPTION_RETURN`] when it returns from an exception. A fault is
//! returned as an error *before* any register is written, so the HardFault handler sees the
//! state the faulting instruction started from (multi-word loads read everything first).
//! The flag rules (AddWithCarry's C and V, the condition codes, the shifts' carry out) are
//! not written here: they are [`crate::semantics`]' generic functions, run on plain values,
//! and the block compiler runs the same functions to build its IR.

use crate::bus::Bus;
use crate::core::{Core, Event, FaultKind, RunState};
use crate::nvic::PPB_BASE;
use crate::semantics::{self, Flagged, Host, Nzcv, ShiftImm, ShiftReg};
use crate::system::System;
use tactus_isa::decode::{self, AluOp, Instr, MemOp};
use tactus_isa::timing::EXCEPTION_RETURN;
use tactus_rp2040::memory::{FLASH_BASE, FLASH_SIZE, SRAM_ALIAS_BASE, SRAM_BASE, SRAM_SIZE};
use tactus_rp2040::sio::SIO_BASE;

/// Target of a PC-relative branch (B, B<cond>, BL) at `pc`: PC reads as `pc + 4`.
#[inline(always)]
pub(crate) fn branch_target(pc: u32, offset: i32) -> u32 {
    pc.wrapping_add(4).wrapping_add(offset as u32)
}

/// Address of a literal (LDR literal, ADR) at `pc`: `Align(PC, 4) + imm`.
#[inline(always)]
pub(crate) fn literal_address(pc: u32, imm: u16) -> u32 {
    (pc.wrapping_add(4) & !3).wrapping_add(imm as u32)
}

/// What an executed instruction did, for pricing it: whether a conditional branch was taken,
/// whether its single load/store used the I/O port, extra cycles (bus wait states and
/// exception return), and the event for the board.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Outcome {
    pub taken: bool,
    pub io_port: bool,
    pub extra: u32,
    pub event: Event,
}

type Exec = Result<Outcome, FaultKind>;

/// Offset of `addr` in [`System::sram`] when it is in the striped view, SRAM4/5 or the
/// non-striped aliases of SRAM0-3 (a single access, at most a word and aligned, so it stays
/// inside one word of one bank; [`tactus_rp2040::memory::sram_location`] gives the same offset, and
/// the offset's bits 3:2 are the bank for the arbiter).
#[inline(always)]
fn sram_offset(addr: u32) -> Option<u32> {
    let off = addr.wrapping_sub(SRAM_BASE);
    if off < SRAM_SIZE {
        return Some(off);
    }
    let alias = addr.wrapping_sub(SRAM_ALIAS_BASE);
    (alias < 0x4_0000).then(|| {
        let (bank, word) = (alias >> 16, (alias & 0xffff) >> 2);
        ((word * 4 + bank) << 2) | (alias & 3)
    })
}

/// Offset of `addr` in flash.
#[inline(always)]
fn flash_offset(addr: u32) -> Option<u32> {
    let off = addr.wrapping_sub(FLASH_BASE);
    (off < FLASH_SIZE).then_some(off)
}

/// SRAM offset of `count` words from `base` when they are word-aligned and all in the
/// striped view or SRAM4/5.
#[inline(always)]
fn sram_range(base: u32, count: u32) -> Option<u32> {
    let off = base.wrapping_sub(SRAM_BASE);
    (base & 3 == 0 && off < SRAM_SIZE && SRAM_SIZE - off >= 4 * count).then_some(off)
}

impl Core {
    #[inline]
    pub(crate) fn nz(&mut self, r: u32) {
        self.n = (r as i32) < 0;
        self.z = r == 0;
    }

    /// Reads a register as an operand: PC reads as the instruction address + 4.
    #[inline]
    fn reg(&self, r: u8, pc: u32) -> u32 {
        if r == 15 {
            pc.wrapping_add(4)
        } else {
            self.r[(r & 15) as usize]
        }
    }

    #[inline]
    fn set_reg(&mut self, r: u8, v: u32) {
        self.r[(r & 15) as usize] = if r == 13 { v & !3 } else { v };
    }

    /// Load from `addr` at data-phase cycle `at`: (value, wait states). The private
    /// peripheral bus is reached here, never through the shared bus.
    #[inline(always)]
    fn load<B: Bus>(
        &mut self,
        bus: &mut B,
        addr: u32,
        size: u32,
        at: u64,
    ) -> Result<(u32, u32), FaultKind> {
        if addr & (size - 1) != 0 {
            return Err(FaultKind::Unaligned { addr });
        }
        if addr >= PPB_BASE {
            if size != 4 {
                return Err(FaultKind::Bus { addr });
            }
            let ipsr = self.ipsr;
            return self
                .nvic
                .read(at, addr, ipsr)
                .map(|v| (v, 0))
                .ok_or(FaultKind::Bus { addr });
        }
        Ok(bus.read(self.id, at, addr, size)?)
    }

    #[inline(always)]
    fn store<B: Bus>(
        &mut self,
        bus: &mut B,
        addr: u32,
        size: u32,
        value: u32,
        at: u64,
    ) -> Result<u32, FaultKind> {
        if addr & (size - 1) != 0 {
            return Err(FaultKind::Unaligned { addr });
        }
        if addr >= PPB_BASE {
            if size != 4 || !self.nvic.write(at, addr, value) {
                return Err(FaultKind::Bus { addr });
            }
            return Ok(0);
        }
        Ok(bus.write(self.id, at, addr, size, value)?)
    }

    /// BXWritePC / LoadWritePC (DDI0419 A2.3.1): interworking branch, or exception return
    /// for an EXC_RETURN value in handler mode. Returns extra cycles.
    fn bx_write_pc<B: Bus>(&mut self, bus: &mut B, target: u32) -> Result<u32, FaultKind> {
        if self.ipsr != 0 && target >> 28 == 0xf {
            self.exception_return(bus, target)?;
            return Ok(EXCEPTION_RETURN);
        }
        self.thumb = target & 1 == 1;
        self.r[15] = target & !1;
        Ok(0)
    }

    /// `AddWithCarry` with the flag update of every flag-setting add, subtract and compare
    /// (ADDS, SUBS, CMP, CMN, ADCS, SBCS, RSBS): sets N, Z, C and V and returns the result.
    #[inline(always)]
    pub(crate) fn adds(&mut self, x: u32, y: u32, carry: bool) -> u32 {
        let f = semantics::add_with_carry(&mut Host, x, y, carry);
        self.set_flags(f)
    }

    /// ADDS and CMN: [`semantics::add`]; sets N, Z, C and V and returns the result.
    #[inline(always)]
    pub(crate) fn add_flags(&mut self, x: u32, y: u32) -> u32 {
        let f = semantics::add(&mut Host, x, y);
        self.set_flags(f)
    }

    /// SUBS, CMP and RSBS: [`semantics::sub`]; sets N, Z, C and V and returns the result.
    #[inline(always)]
    pub(crate) fn sub_flags(&mut self, x: u32, y: u32) -> u32 {
        let f = semantics::sub(&mut Host, x, y);
        self.set_flags(f)
    }

    /// N and Z from the result, C, and V from the sign of the overflow word.
    #[inline(always)]
    fn set_flags(&mut self, f: Flagged<u32, bool>) -> u32 {
        (self.c, self.v) = (f.c, (f.v as i32) < 0);
        self.nz(f.result);
        f.result
    }

    /// Whether condition `cond` (0-14) holds on the current flags ([`semantics::condition`]).
    #[inline(always)]
    pub(crate) fn condition(&self, cond: u8) -> bool {
        let f = Nzcv {
            n: self.n,
            z: self.z,
            c: self.c,
            v: self.v,
        };
        semantics::condition(&mut Host, &f, cond)
    }

    /// `LSLS Rd, Rm, #imm` (imm 0-31; 0 is `MOVS Rd, Rm`, carry unchanged).
    #[inline(always)]
    pub(crate) fn lsl_imm(&mut self, rd: u8, rm: u8, imm: u8) {
        self.shift_imm(ShiftImm::Lsl, rd, rm, imm);
    }

    /// `LSRS Rd, Rm, #imm` (imm 1-32).
    #[inline(always)]
    pub(crate) fn lsr_imm(&mut self, rd: u8, rm: u8, imm: u8) {
        self.shift_imm(ShiftImm::Lsr, rd, rm, imm);
    }

    /// `ASRS Rd, Rm, #imm` (imm 1-32).
    #[inline(always)]
    pub(crate) fn asr_imm(&mut self, rd: u8, rm: u8, imm: u8) {
        self.shift_imm(ShiftImm::Asr, rd, rm, imm);
    }

    /// A shift by an immediate: [`semantics::shift_imm`], N, Z and (unless LSL #0) C.
    #[inline(always)]
    fn shift_imm(&mut self, kind: ShiftImm, rd: u8, rm: u8, imm: u8) {
        let x = self.r[(rm & 15) as usize];
        let (r, c) = semantics::shift_imm(&mut Host, kind, x, imm);
        if let Some(c) = c {
            self.c = c;
        }
        self.r[(rd & 15) as usize] = r;
        self.nz(r);
    }

    /// `ADDS Rd, Rn, Rm`.
    #[inline(always)]
    pub(crate) fn add_reg(&mut self, rd: u8, rn: u8, rm: u8) {
        let (x, y) = (self.r[(rn & 15) as usize], self.r[(rm & 15) as usize]);
        self.r[(rd & 15) as usize] = self.add_flags(x, y);
    }

    /// `SUBS Rd, Rn, Rm`.
    #[inline(always)]
    pub(crate) fn sub_reg(&mut self, rd: u8, rn: u8, rm: u8) {
        let (x, y) = (self.r[(rn & 15) as usize], self.r[(rm & 15) as usize]);
        self.r[(rd & 15) as usize] = self.sub_flags(x, y);
    }

    /// `ADDS Rd, Rn, #imm` (both encodings).
    #[inline(always)]
    pub(crate) fn add_imm(&mut self, rd: u8, rn: u8, imm: u8) {
        let x = self.r[(rn & 15) as usize];
        self.r[(rd & 15) as usize] = self.add_flags(x, imm as u32);
    }

    /// `SUBS Rd, Rn, #imm` (both encodings).
    #[inline(always)]
    pub(crate) fn sub_imm(&mut self, rd: u8, rn: u8, imm: u8) {
        let x = self.r[(rn & 15) as usize];
        self.r[(rd & 15) as usize] = self.sub_flags(x, imm as u32);
    }

    /// `MOVS Rd, #imm`.
    #[inline(always)]
    pub(crate) fn mov_imm(&mut self, rd: u8, imm: u8) {
        self.r[(rd & 15) as usize] = imm as u32;
        self.nz(imm as u32);
    }

    /// `CMP Rn, #imm`.
    #[inline(always)]
    pub(crate) fn cmp_imm(&mut self, rn: u8, imm: u8) {
        let x = self.r[(rn & 15) as usize];
        self.sub_flags(x, imm as u32);
    }

    /// The register-only data-processing instructions (shifts by immediate, ADDS/SUBS/MOVS/CMP
    /// of low registers, the ALU group, CMP of high registers, extends and byte reverses):
    /// results and flags, no memory, no PC write. **The one definition** of these
    /// instructions, with the methods it dispatches to (`lsl_imm` … `cmp_imm`, `alu`,
    /// `adds`): [`Core::execute`] and [`Core::execute_fast`] call it, and the pre-decoded
    /// executor (`Core::execute_op`, which the block engine also runs) calls the same
    /// per-instruction methods directly. Cycle cost: the caller's (1, from the timing
    /// table).
    #[inline(always)]
    pub(crate) fn data_processing(&mut self, instr: Instr, pc: u32) {
        use Instr::*;
        match instr {
            LslImm { rd, rm, imm } => self.lsl_imm(rd, rm, imm),
            LsrImm { rd, rm, imm } => self.lsr_imm(rd, rm, imm),
            AsrImm { rd, rm, imm } => self.asr_imm(rd, rm, imm),
            AddReg { rd, rn, rm } => self.add_reg(rd, rn, rm),
            SubReg { rd, rn, rm } => self.sub_reg(rd, rn, rm),
            AddImm { rd, rn, imm } => self.add_imm(rd, rn, imm),
            SubImm { rd, rn, imm } => self.sub_imm(rd, rn, imm),
            MovImm { rd, imm } => self.mov_imm(rd, imm),
            CmpImm { rn, imm } => self.cmp_imm(rn, imm),
            Alu { op, rdn, rm } => self.alu(op, (rdn & 15) as usize, self.r[(rm & 15) as usize]),
            CmpHi { rn, rm } => {
                let (x, y) = (self.reg(rn, pc), self.reg(rm, pc));
                self.sub_flags(x, y);
            }
            Sxth { rd, rm } => {
                self.r[(rd & 15) as usize] = self.r[(rm & 15) as usize] as i16 as i32 as u32
            }
            Sxtb { rd, rm } => {
                self.r[(rd & 15) as usize] = self.r[(rm & 15) as usize] as i8 as i32 as u32
            }
            Uxth { rd, rm } => {
                self.r[(rd & 15) as usize] = self.r[(rm & 15) as usize] as u16 as u32
            }
            Uxtb { rd, rm } => self.r[(rd & 15) as usize] = self.r[(rm & 15) as usize] as u8 as u32,
            Rev { rd, rm } => self.r[(rd & 15) as usize] = self.r[(rm & 15) as usize].swap_bytes(),
            Rev16 { rd, rm } => {
                let x = self.r[(rm & 15) as usize];
                self.r[(rd & 15) as usize] = ((x & 0x00ff_00ff) << 8) | ((x >> 8) & 0x00ff_00ff);
            }
            Revsh { rd, rm } => {
                self.r[(rd & 15) as usize] =
                    (self.r[(rm & 15) as usize] as u16).swap_bytes() as i16 as i32 as u32
            }
            _ => unreachable!("not a data-processing instruction: {instr}"),
        }
    }

    /// `ADD Rdn, Rm` and `MOV Rd, Rm` with a high register (no flags): the value written,
    /// and whether it went to PC (ALUWritePC: a branch without interworking, bit 0
    /// cleared). The one definition for every executor.
    #[inline(always)]
    pub(crate) fn hi_reg_op(&mut self, instr: Instr, pc: u32) -> bool {
        let (rd, r) = match instr {
            Instr::AddHi { rdn, rm } => (rdn, self.reg(rdn, pc).wrapping_add(self.reg(rm, pc))),
            Instr::MovHi { rd, rm } => (rd, self.reg(rm, pc)),
            _ => unreachable!("not ADD/MOV with a high register: {instr}"),
        };
        if rd == 15 {
            self.r[15] = r & !1;
            true
        } else {
            self.set_reg(rd, r);
            false
        }
    }

    /// Executes `instr` located at `pc` (of `size` bytes). Returns its cycles and event.
    #[inline(always)]
    pub(crate) fn execute<B: Bus>(
        &mut self,
        bus: &mut B,
        instr: Instr,
        pc: u32,
        size: u32,
    ) -> Exec {
        use Instr::*;
        let next = pc.wrapping_add(size);
        let now = self.cycle;
        let mut event = Event::None;
        let mut taken = false;
        let mut io_port = false;
        let mut wait = 0u32;
        self.r[15] = next;
        match instr {
            LslImm { .. }
            | LsrImm { .. }
            | AsrImm { .. }
            | AddReg { .. }
            | SubReg { .. }
            | AddImm { .. }
            | SubImm { .. }
            | MovImm { .. }
            | CmpImm { .. }
            | Alu { .. }
            | CmpHi { .. }
            | Sxth { .. }
            | Sxtb { .. }
            | Uxth { .. }
            | Uxtb { .. }
            | Rev { .. }
            | Rev16 { .. }
            | Revsh { .. } => self.data_processing(instr, pc),
            AddHi { .. } | MovHi { .. } => {
                self.hi_reg_op(instr, pc);
            }
            Bx { rm } => {
                let target = self.reg(rm, pc);
                wait += self.bx_write_pc(bus, target)?;
            }
            Blx { rm } => {
                let target = self.r[(rm & 15) as usize];
                self.r[14] = next | 1;
                self.thumb = target & 1 == 1;
                self.r[15] = target & !1;
            }
            LdrLit { rt, imm } => {
                let addr = literal_address(pc, imm);
                io_port = addr >> 28 == SIO_BASE >> 28;
                let (v, w) = self.load(bus, addr, 4, now + !io_port as u64)?;
                wait += w;
                self.r[(rt & 15) as usize] = v;
            }
            MemReg { op, rt, rn, rm } => {
                let addr = self.r[(rn & 15) as usize].wrapping_add(self.r[(rm & 15) as usize]);
                io_port = addr >> 28 == SIO_BASE >> 28;
                wait += self.mem(bus, op, rt, addr, now + !io_port as u64)?;
            }
            MemImm { op, rt, rn, imm } => {
                let addr = self.r[(rn & 15) as usize].wrapping_add(imm as u32);
                io_port = addr >> 28 == SIO_BASE >> 28;
                wait += self.mem(bus, op, rt, addr, now + !io_port as u64)?;
            }
            Adr { rd, imm } => self.r[(rd & 15) as usize] = literal_address(pc, imm),
            AddSpImm { rd, imm } => {
                self.r[(rd & 15) as usize] = self.r[13].wrapping_add(imm as u32)
            }
            AddSp { imm } => self.r[13] = self.r[13].wrapping_add(imm as u32),
            SubSp { imm } => self.r[13] = self.r[13].wrapping_sub(imm as u32),
            Push { list } => {
                let count = list.count_ones();
                let base = self.r[13].wrapping_sub(4 * count);
                if base & 3 != 0 {
                    return Err(FaultKind::Unaligned { addr: base });
                }
                let mut addr = base;
                for (i, reg) in (0..15).filter(|r| list & (1 << r) != 0).enumerate() {
                    wait +=
                        self.store(bus, addr, 4, self.r[reg], now + 1 + i as u64 + wait as u64)?;
                    addr = addr.wrapping_add(4);
                }
                self.r[13] = base;
            }
            Pop { list } => {
                let base = self.r[13];
                let (values, w) = self.load_multiple(bus, base, list, now)?;
                wait += w;
                self.r[13] = base.wrapping_add(4 * list.count_ones());
                for (reg, value) in values.iter().enumerate().take(8) {
                    if list & (1 << reg) != 0 {
                        self.r[reg] = *value;
                    }
                }
                if list & 0x8000 != 0 {
                    wait += self.bx_write_pc(bus, values[15])?;
                }
            }
            Stm { rn, list } => {
                let base = self.r[(rn & 15) as usize];
                if base & 3 != 0 {
                    return Err(FaultKind::Unaligned { addr: base });
                }
                let mut addr = base;
                for (i, reg) in (0..8).filter(|r| list & (1 << r) != 0).enumerate() {
                    wait +=
                        self.store(bus, addr, 4, self.r[reg], now + 1 + i as u64 + wait as u64)?;
                    addr = addr.wrapping_add(4);
                }
                self.r[(rn & 15) as usize] = addr;
            }
            Ldm { rn, list } => {
                let base = self.r[(rn & 15) as usize];
                let (values, w) = self.load_multiple(bus, base, list as u16, now)?;
                wait += w;
                if list & (1 << rn) == 0 {
                    self.r[(rn & 15) as usize] = base.wrapping_add(4 * list.count_ones());
                }
                for (reg, value) in values.iter().enumerate().take(8) {
                    if list & (1 << reg) != 0 {
                        self.r[reg] = *value;
                    }
                }
            }
            Cps { disable } => self.primask = disable,
            Bkpt { imm } => return Err(FaultKind::Breakpoint { imm }),
            Hint(h) => match h {
                decode::Hint::Nop | decode::Hint::Yield => {}
                decode::Hint::Sev => {
                    self.event = true;
                    event = Event::Sev;
                }
                decode::Hint::Wfe => {
                    if self.event {
                        self.event = false;
                    } else {
                        self.state = RunState::Sleeping { wfe: true };
                    }
                }
                decode::Hint::Wfi => self.state = RunState::Sleeping { wfe: false },
            },
            BCond { cond, offset } => {
                if self.condition(cond) {
                    taken = true;
                    self.r[15] = branch_target(pc, offset);
                }
            }
            B { offset } => self.r[15] = branch_target(pc, offset),
            Svc { imm } => event = Event::Svc(imm),
            Udf { imm } => {
                return Err(FaultKind::Undefined {
                    hw1: 0xde00 | imm as u16,
                    hw2: 0,
                })
            }
            Undefined { hw1, hw2 } => return Err(FaultKind::Undefined { hw1, hw2 }),
            Bl { offset } => {
                self.r[14] = next | 1;
                self.r[15] = branch_target(pc, offset);
            }
            Msr { sysm, rn } => self.msr(sysm, self.r[(rn & 15) as usize]),
            Mrs { rd, sysm } => self.r[(rd & 15) as usize] = self.mrs(sysm),
            Barrier(_) => {}
        }
        Ok(Outcome {
            taken,
            io_port,
            extra: wait,
            event,
        })
    }

    /// The board's fast path: executes `instr` at `pc` (of `size` bytes, costing `cost` =
    /// (not taken, taken) cycles from the timing table) when it is a common case with the
    /// same result as [`Core::execute`] priced by `run_priced` — registers and flags, SRAM
    /// and flash accesses that cannot fault, branches that stay in Thumb state and return
    /// from no exception — and returns true. Otherwise (peripherals, SIO, PPB, anything
    /// that could fault, sleep, signal or change exception state) it touches nothing and
    /// returns false, and the caller takes the general path.
    #[inline(always)]
    pub(crate) fn execute_fast(
        &mut self,
        sys: &mut System,
        instr: Instr,
        pc: u32,
        size: u32,
        cost: (u8, u8),
    ) -> bool {
        use Instr::*;
        let next = pc.wrapping_add(size);
        let now = self.cycle;
        let mut cycles = cost.0 as u64;
        match instr {
            LslImm { .. }
            | LsrImm { .. }
            | AsrImm { .. }
            | AddReg { .. }
            | SubReg { .. }
            | AddImm { .. }
            | SubImm { .. }
            | MovImm { .. }
            | CmpImm { .. }
            | Alu { .. }
            | CmpHi { .. }
            | Sxth { .. }
            | Sxtb { .. }
            | Uxth { .. }
            | Uxtb { .. }
            | Rev { .. }
            | Rev16 { .. }
            | Revsh { .. } => self.data_processing(instr, pc),
            AddHi { .. } | MovHi { .. } => {
                if self.hi_reg_op(instr, pc) {
                    return self.retire(cycles);
                }
            }
            Bx { rm } => {
                let target = self.reg(rm, pc);
                if target & 1 == 0 || (self.ipsr != 0 && target >> 28 == 0xf) {
                    return false;
                }
                self.r[15] = target & !1;
                return self.retire(cycles);
            }
            Blx { rm } => {
                let target = self.r[(rm & 15) as usize];
                if target & 1 == 0 {
                    return false;
                }
                self.r[14] = next | 1;
                self.r[15] = target & !1;
                return self.retire(cycles);
            }
            LdrLit { rt, imm } => {
                let addr = literal_address(pc, imm);
                match self.mem_fast(sys, MemOp::Ldr, rt, addr, now + 1) {
                    Some(w) => cycles += w as u64,
                    None => return false,
                }
            }
            MemReg { op, rt, rn, rm } => {
                let addr = self.r[(rn & 15) as usize].wrapping_add(self.r[(rm & 15) as usize]);
                match self.mem_fast(sys, op, rt, addr, now + 1) {
                    Some(w) => cycles += w as u64,
                    None => return false,
                }
            }
            MemImm { op, rt, rn, imm } => {
                let addr = self.r[(rn & 15) as usize].wrapping_add(imm as u32);
                match self.mem_fast(sys, op, rt, addr, now + 1) {
                    Some(w) => cycles += w as u64,
                    None => return false,
                }
            }
            Adr { rd, imm } => self.r[(rd & 15) as usize] = literal_address(pc, imm),
            AddSpImm { rd, imm } => {
                self.r[(rd & 15) as usize] = self.r[13].wrapping_add(imm as u32)
            }
            AddSp { imm } => self.r[13] = self.r[13].wrapping_add(imm as u32),
            SubSp { imm } => self.r[13] = self.r[13].wrapping_sub(imm as u32),
            Push { list } => return self.push_fast(sys, list, next, cycles),
            Pop { list } => return self.pop_fast(sys, list, next, cycles),
            Stm { rn, list } => {
                let base = self.r[(rn & 15) as usize];
                let count = list.count_ones();
                let Some(mut off) = sram_range(base, count).filter(|&o| sys.allows_words(o, count))
                else {
                    return false;
                };
                let mut bits = list;
                let mut at = now + 1;
                while bits != 0 {
                    let reg = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let w = sys.sram_write(self.id, at, off, 4, self.r[reg & 7]) as u64;
                    cycles += w;
                    at += 1 + w;
                    off += 4;
                }
                self.r[(rn & 15) as usize] = base.wrapping_add(4 * count);
            }
            Ldm { rn, list } => {
                let base = self.r[(rn & 15) as usize];
                let count = list.count_ones();
                let Some(mut off) = sram_range(base, count).filter(|&o| sys.allows_words(o, count))
                else {
                    return false;
                };
                let mut bits = list;
                let mut at = now + 1;
                let mut values = [0u32; 8];
                while bits != 0 {
                    let reg = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let (v, w) = sys.sram_read(self.id, at, off, 4);
                    values[reg & 7] = v;
                    cycles += w as u64;
                    at += 1 + w as u64;
                    off += 4;
                }
                if list & (1 << rn) == 0 {
                    self.r[(rn & 15) as usize] = base.wrapping_add(4 * count);
                }
                for (reg, value) in values.iter().enumerate() {
                    if list & (1 << reg) != 0 {
                        self.r[reg] = *value;
                    }
                }
            }
            Hint(decode::Hint::Nop | decode::Hint::Yield) => {}
            BCond { cond, offset } => {
                if self.condition(cond) {
                    cycles = cost.1 as u64;
                    self.r[15] = branch_target(pc, offset);
                    return self.retire(cycles);
                }
            }
            B { offset } => {
                self.r[15] = branch_target(pc, offset);
                return self.retire(cycles);
            }
            Bl { offset } => {
                self.r[14] = next | 1;
                self.r[15] = branch_target(pc, offset);
                return self.retire(cycles);
            }
            _ => return false,
        }
        self.r[15] = next;
        self.retire(cycles)
    }

    /// PUSH on the fast path (the stack in SRAM, word-aligned): the whole instruction, with
    /// `cycles` from the timing table and `next` the following instruction's address, or
    /// false with nothing done.
    #[inline(always)]
    pub(crate) fn push_fast(
        &mut self,
        sys: &mut System,
        list: u16,
        next: u32,
        cycles: u64,
    ) -> bool {
        let mut cycles = cycles;
        let count = list.count_ones();
        let base = self.r[13].wrapping_sub(4 * count);
        let Some(mut off) = sram_range(base, count).filter(|&o| sys.allows_words(o, count)) else {
            return false;
        };
        let mut bits = list;
        let mut at = self.cycle + 1;
        while bits != 0 {
            let reg = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let w = sys.sram_write(self.id, at, off, 4, self.r[reg & 15]) as u64;
            cycles += w;
            at += 1 + w;
            off += 4;
        }
        self.r[13] = base;
        self.r[15] = next;
        self.retire(cycles)
    }

    /// POP on the fast path (the stack in SRAM, word-aligned; a PC load that stays in Thumb
    /// state and is no exception return), as [`Core::push_fast`].
    #[inline(always)]
    pub(crate) fn pop_fast(&mut self, sys: &mut System, list: u16, next: u32, cycles: u64) -> bool {
        let mut cycles = cycles;
        let base = self.r[13];
        let count = list.count_ones();
        let Some(mut off) = sram_range(base, count).filter(|&o| sys.allows_words(o, count)) else {
            return false;
        };
        if list & 0x8000 != 0 {
            let target = sys.sram_peek(off + 4 * (count - 1));
            if target & 1 == 0 || (self.ipsr != 0 && target >> 28 == 0xf) {
                return false;
            }
        }
        let mut bits = list;
        let mut at = self.cycle + 1;
        let mut values = [0u32; 16];
        while bits != 0 {
            let reg = bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let (v, w) = sys.sram_read(self.id, at, off, 4);
            values[reg & 15] = v;
            cycles += w as u64;
            at += 1 + w as u64;
            off += 4;
        }
        self.r[13] = base.wrapping_add(4 * count);
        for (reg, value) in values.iter().enumerate().take(8) {
            if list & (1 << reg) != 0 {
                self.r[reg] = *value;
            }
        }
        self.r[15] = if list & 0x8000 != 0 {
            values[15] & !1
        } else {
            next
        };
        self.retire(cycles)
    }

    /// Charges a fast-path instruction `cycles` cycles (the caller counts it).
    #[inline(always)]
    pub(crate) fn retire(&mut self, cycles: u64) -> bool {
        // `instructions` is counted by the fast-path loop (in a register) and added when
        // it leaves.
        self.cycle += cycles;
        true
    }

    /// A single load or store on the fast path (SRAM, or a flash load; aligned); `None`
    /// (nothing done) for anything else. Returns the wait states.
    #[inline(always)]
    pub(crate) fn mem_fast(
        &mut self,
        sys: &mut System,
        op: MemOp,
        rt: u8,
        addr: u32,
        at: u64,
    ) -> Option<u32> {
        let size = op.size();
        if addr & (size - 1) != 0 {
            return None;
        }
        if op.is_store() {
            let off = sram_offset(addr).filter(|&o| sys.allows(o))?;
            return Some(sys.sram_write(self.id, at, off, size, self.r[(rt & 15) as usize]));
        }
        let (v, wait) = if let Some(off) = sram_offset(addr) {
            if !sys.allows(off) {
                return None;
            }
            sys.sram_read(self.id, at, off, size)
        } else {
            (sys.flash_read(flash_offset(addr)?, size), 0)
        };
        self.r[(rt & 15) as usize] = match op {
            MemOp::Ldrsb => v as u8 as i8 as i32 as u32,
            MemOp::Ldrsh => v as u16 as i16 as i32 as u32,
            _ => v,
        };
        Some(wait)
    }

    #[inline(always)]
    pub(crate) fn alu(&mut self, op: AluOp, d: usize, m: u32) {
        let x = self.r[d];
        let r = match op {
            AluOp::And => x & m,
            AluOp::Eor => x ^ m,
            AluOp::Orr => x | m,
            AluOp::Bic => x & !m,
            AluOp::Mvn => !m,
            AluOp::Tst => {
                self.nz(x & m);
                return;
            }
            AluOp::Lsl | AluOp::Lsr | AluOp::Asr | AluOp::Ror => {
                let kind = ShiftReg::of(op).expect("a shift or rotate");
                let (r, c) = semantics::shift_reg(&mut Host, kind, x, m, self.c);
                self.c = c;
                r
            }
            AluOp::Adc => self.adds(x, m, self.c),
            AluOp::Sbc => self.adds(x, !m, self.c),
            AluOp::Rsb => self.sub_flags(0, m),
            AluOp::Cmp => {
                self.sub_flags(x, m);
                return;
            }
            AluOp::Cmn => {
                self.add_flags(x, m);
                return;
            }
            AluOp::Mul => m.wrapping_mul(x),
        };
        self.r[d] = r;
        self.nz(r);
    }

    /// One load or store `op` of `rt` at `addr`; returns wait states.
    #[inline(always)]
    fn mem<B: Bus>(
        &mut self,
        bus: &mut B,
        op: MemOp,
        rt: u8,
        addr: u32,
        at: u64,
    ) -> Result<u32, FaultKind> {
        let size = op.size();
        if op.is_store() {
            return self.store(bus, addr, size, self.r[(rt & 15) as usize], at);
        }
        let (v, wait) = self.load(bus, addr, size, at)?;
        self.r[(rt & 15) as usize] = match op {
            MemOp::Ldrsb => v as u8 as i8 as i32 as u32,
            MemOp::Ldrsh => v as u16 as i16 as i32 as u32,
            _ => v,
        };
        Ok(wait)
    }

    /// Loads the registers of `list` (bits 0-7, 15 = PC) from consecutive words at `base`
    /// without writing any register: (values by register number, wait states).
    fn load_multiple<B: Bus>(
        &mut self,
        bus: &mut B,
        base: u32,
        list: u16,
        now: u64,
    ) -> Result<([u32; 16], u32), FaultKind> {
        if base & 3 != 0 {
            return Err(FaultKind::Unaligned { addr: base });
        }
        let mut values = [0u32; 16];
        let mut wait = 0;
        let mut addr = base;
        for (i, reg) in (0..16).filter(|r| list & (1 << r) != 0).enumerate() {
            let (v, w) = self.load(bus, addr, 4, now + 1 + i as u64 + wait as u64)?;
            wait += w;
            values[reg] = v;
            addr = addr.wrapping_add(4);
        }
        Ok((values, wait))
    }

    /// MRS (DDI0419 B5.2.2): special register `sysm`.
    fn mrs(&self, sysm: u8) -> u32 {
        match sysm {
            0..=7 => {
                let mut v = 0;
                if sysm & 1 != 0 {
                    v |= self.ipsr;
                }
                if sysm & 4 == 0 {
                    v |= self.apsr();
                }
                v // EPSR reads as zero
            }
            8 => self.msp(),
            9 => self.psp(),
            16 => self.primask as u32,
            20 => self.control & 3,
            _ => 0,
        }
    }

    /// MSR (DDI0419 B5.2.3).
    fn msr(&mut self, sysm: u8, value: u32) {
        match sysm {
            0..=3 => self.set_apsr(value),
            4..=7 => {}
            8 => self.set_msp(value),
            9 => self.set_psp(value),
            16 => self.primask = value & 1 != 0,
            20 => {
                if self.ipsr == 0 {
                    let was_psp = self.ipsr == 0 && self.control & 2 != 0;
                    self.control = value & 3;
                    self.switch_sp(was_psp);
                } else {
                    self.control = (self.control & 2) | (value & 1);
                }
            }
            _ => {}
        }
    }
}
