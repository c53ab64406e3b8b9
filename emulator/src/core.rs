//! One Cortex-M0+ core: architectural state, the step function and the exception model.
//!
//! Registers are a plain `[u32; 16]` with r13 the *active* stack pointer (the other one is
//! banked in [`Core::other_sp`]) and r15 the address of the next instruction, so the
//! executor indexes registers directly and only ADD/MOV/CMP/BX with a high register need to
//! special-case PC (which reads as address + 4). Flags are four `bool`s rather than a packed
//! xPSR because almost every instruction writes some of them. Each core carries its own
//! cycle counter: the board runs both cores in lock-step by always stepping the core whose
//! counter is behind (see [`crate::board`]). Exception entry and return follow DDI0419
//! B1.5.6-B1.5.8 (8-word frame, 8-byte stack alignment with xPSR bit 9, EXC_RETURN
//! 0xfffffff1/9/d); faults escalate to HardFault, and a fault inside HardFault or NMI locks
//! the core up (DDI0419 B1.5.15).

use crate::bus::{Bus, BusFault};
use crate::nvic::{Nvic, HARDFAULT, IRQ0, NMI, SVCALL};
use std::fmt;
use tactus_isa::decode::{decode, is_32bit, Instr};
use tactus_isa::timing::{self, EXCEPTION_ENTRY};

/// Why a core faulted (every one of these becomes a HardFault on the core).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultKind {
    /// An UNDEFINED encoding (or UDF).
    Undefined {
        /// First halfword.
        hw1: u16,
        /// Second halfword (0 for 16-bit encodings).
        hw2: u16,
    },
    /// A load or store not aligned to its size (ARMv6-M traps all unaligned accesses).
    Unaligned {
        /// The address.
        addr: u32,
    },
    /// An access to an unmapped address or a non-executable region.
    Bus {
        /// The address.
        addr: u32,
    },
    /// Execution with EPSR.T = 0: a BX/BLX/POP to an even address (ARM state) or a vector
    /// without the Thumb bit.
    InvalidState {
        /// The target address.
        target: u32,
    },
    /// BKPT with no debugger attached.
    Breakpoint {
        /// The BKPT immediate.
        imm: u8,
    },
    /// An exception return with an EXC_RETURN value that is not 0xfffffff1/9/d.
    InvalidExcReturn {
        /// The value loaded into PC.
        value: u32,
    },
    /// SVC executed at a priority that does not allow SVCall to be taken.
    SvcEscalation,
}

/// A fault: what happened and the address of the instruction that caused it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fault {
    /// Address of the faulting instruction.
    pub pc: u32,
    /// What went wrong.
    pub kind: FaultKind,
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.kind {
            FaultKind::Undefined { hw1, hw2 } if is_32bit(hw1) => {
                write!(f, "undefined instruction {hw1:04x} {hw2:04x}")?
            }
            FaultKind::Undefined { hw1, .. } => write!(f, "undefined instruction {hw1:04x}")?,
            FaultKind::Unaligned { addr } => write!(f, "unaligned access to {addr:#010x}")?,
            FaultKind::Bus { addr } => write!(f, "bus fault: nothing mapped at {addr:#010x}")?,
            FaultKind::InvalidState { target } => write!(
                f,
                "branch to ARM state (even address {target:#010x}); Thumb only"
            )?,
            FaultKind::Breakpoint { imm } => write!(f, "BKPT #{imm} with no debugger")?,
            FaultKind::InvalidExcReturn { value } => {
                write!(f, "invalid EXC_RETURN value {value:#010x}")?
            }
            FaultKind::SvcEscalation => write!(f, "SVC at a priority that blocks SVCall")?,
        }
        write!(f, " at pc {:#010x}", self.pc)
    }
}

impl From<BusFault> for FaultKind {
    fn from(e: BusFault) -> Self {
        FaultKind::Bus { addr: e.addr }
    }
}

/// Run state of a core.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunState {
    /// Executing instructions.
    Running,
    /// Sleeping in WFI (`wfe == false`) or WFE until an interrupt or event.
    Sleeping {
        /// True for WFE, which also wakes on an event.
        wfe: bool,
    },
    /// Waiting for the boot ROM's launch sequence on the FIFO (core 1 after reset), or
    /// stopped by the host.
    Parked,
    /// Locked up after a fault in HardFault/NMI.
    Lockup,
}

/// What a step asks of the board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    /// Nothing beyond executing.
    None,
    /// SEV: signal an event to the other core too.
    Sev,
    /// SVC #imm was executed (the board either halts for a host call or pends SVCall).
    Svc(u8),
    /// A fault was taken as a HardFault (details in [`Core::fault`]).
    Fault,
    /// A fault occurred where it cannot be handled: the core locked up (details in
    /// [`Core::fault`]).
    Lockup,
}

/// A trace record of the last executed instruction.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Retired {
    /// Address of the instruction.
    pub pc: u32,
    /// The instruction.
    pub instr: Instr,
    /// Cycles charged for it (including wait states and exception return).
    pub cycles: u32,
}

/// A Cortex-M0+ core.
#[derive(Clone, Debug)]
pub struct Core {
    /// Core number (0 or 1), as SIO CPUID reports.
    pub id: usize,
    /// r0-r15: r13 is the active SP, r15 the address of the next instruction.
    pub r: [u32; 16],
    /// Negative flag.
    pub n: bool,
    /// Zero flag.
    pub z: bool,
    /// Carry flag.
    pub c: bool,
    /// Overflow flag.
    pub v: bool,
    /// EPSR.T: false means the next instruction faults (ARM state does not exist).
    pub thumb: bool,
    /// IPSR: number of the exception being handled, 0 in thread mode.
    pub ipsr: u32,
    /// PRIMASK.PM: when set, only NMI and HardFault are taken.
    pub primask: bool,
    /// CONTROL: bit 1 SPSEL (thread mode uses PSP), bit 0 nPRIV (stored only).
    pub control: u32,
    /// The stack pointer not currently in r13 (PSP while r13 is MSP, and vice versa).
    pub other_sp: u32,
    /// NVIC, SysTick and SCB.
    pub nvic: Nvic,
    /// This core's cycle counter: the cycle at which its next instruction starts.
    pub cycle: u64,
    /// Run state.
    pub state: RunState,
    /// Event register for WFE.
    pub event: bool,
    /// Instructions retired.
    pub instructions: u64,
    /// The last instruction executed, recorded only by traced steps
    /// ([`crate::board::Board::step`]).
    pub last: Option<Retired>,
    /// The most recent fault (HardFault or lockup).
    pub fault: Option<Fault>,
}

impl Core {
    /// A core in reset state, parked (see [`Core::reset_to`]).
    pub fn new(id: usize) -> Self {
        Core {
            id,
            r: [0; 16],
            n: false,
            z: false,
            c: false,
            v: false,
            thumb: true,
            ipsr: 0,
            primask: false,
            control: 0,
            other_sp: 0,
            nvic: Nvic::default(),
            cycle: 0,
            state: RunState::Parked,
            event: false,
            instructions: 0,
            last: None,
            fault: None,
        }
    }

    /// Starts the core at `pc` (Thumb bit optional) with main stack pointer `sp`, in thread
    /// mode with no exception active, keeping its cycle counter.
    pub fn reset_to(&mut self, pc: u32, sp: u32) {
        let (cycle, clock_hz) = (self.cycle, self.nvic.clock_hz);
        *self = Core::new(self.id);
        self.cycle = cycle;
        self.nvic.clock_hz = clock_hz;
        self.r[13] = sp & !3;
        self.r[15] = pc & !1;
        self.thumb = pc & 1 == 1;
        self.state = RunState::Running;
    }

    /// The APSR flags as bits 31:28.
    pub fn apsr(&self) -> u32 {
        (self.n as u32) << 31
            | (self.z as u32) << 30
            | (self.c as u32) << 29
            | (self.v as u32) << 28
    }

    /// xPSR: APSR | EPSR.T | IPSR.
    pub fn xpsr(&self) -> u32 {
        self.apsr() | (self.thumb as u32) << 24 | self.ipsr
    }

    pub(crate) fn set_apsr(&mut self, v: u32) {
        self.n = v & (1 << 31) != 0;
        self.z = v & (1 << 30) != 0;
        self.c = v & (1 << 29) != 0;
        self.v = v & (1 << 28) != 0;
    }

    fn uses_psp(&self) -> bool {
        self.ipsr == 0 && self.control & 2 != 0
    }

    /// Main stack pointer.
    pub fn msp(&self) -> u32 {
        if self.uses_psp() {
            self.other_sp
        } else {
            self.r[13]
        }
    }

    /// Process stack pointer.
    pub fn psp(&self) -> u32 {
        if self.uses_psp() {
            self.r[13]
        } else {
            self.other_sp
        }
    }

    pub(crate) fn set_msp(&mut self, v: u32) {
        if self.uses_psp() {
            self.other_sp = v & !3
        } else {
            self.r[13] = v & !3
        }
    }

    pub(crate) fn set_psp(&mut self, v: u32) {
        if self.uses_psp() {
            self.r[13] = v & !3
        } else {
            self.other_sp = v & !3
        }
    }

    /// Switches the register view when the SP selection changes (mode or CONTROL.SPSEL).
    pub(crate) fn switch_sp(&mut self, was_psp: bool) {
        if was_psp != self.uses_psp() {
            std::mem::swap(&mut self.r[13], &mut self.other_sp);
        }
    }

    /// Current execution priority (DDI0419 B1.5.4): PRIMASK boosts it to 0.
    pub fn execution_priority(&self) -> i32 {
        let p = self.nvic.active_priority();
        if self.primask {
            p.min(0)
        } else {
            p
        }
    }

    /// The exception that would be taken now, given IRQ lines `lines`.
    pub fn exception_to_take(&mut self, lines: u32) -> Option<u32> {
        self.nvic.tick(self.cycle);
        self.nvic.pending |= ((lines as u64) << IRQ0) & !self.nvic.active;
        if self.nvic.takeable() == 0 {
            return None;
        }
        let (exc, prio) = self.nvic.highest_pending()?;
        (prio < self.execution_priority()).then_some(exc)
    }

    /// True when a pending exception would wake the core from WFI (any pending enabled
    /// exception, even one PRIMASK holds back: DDI0419 B1.5.19).
    pub fn wakes_from_sleep(&mut self, lines: u32) -> bool {
        self.nvic.tick(self.cycle);
        self.nvic.pending |= ((lines as u64) << IRQ0) & !self.nvic.active;
        let ep = self.nvic.active_priority();
        self.nvic.highest_pending().is_some_and(|(_, p)| p < ep)
    }

    /// Executes one instruction, or takes one pending exception, and advances the cycle
    /// counter by its cost. `lines` are the interrupt request lines (bit n = IRQ n).
    pub fn step<B: Bus>(&mut self, bus: &mut B, lines: u32) -> Event {
        if self.nvic.pending != 0 || lines != 0 || self.nvic.syst_next <= self.cycle {
            if let Some(exc) = self.exception_to_take(lines) {
                let ret = self.r[15];
                return match self.enter_exception(bus, exc, ret) {
                    Ok(()) => Event::None,
                    Err(kind) => self.lockup(Fault { pc: ret, kind }),
                };
            }
        }
        let pc = self.r[15];
        if !self.thumb {
            return self.fault(
                bus,
                Fault {
                    pc,
                    kind: FaultKind::InvalidState { target: pc },
                },
            );
        }
        let (hw1, hw2, size) = match bus.fetch_instr(pc) {
            Ok(f) => f,
            Err(e) => return self.fault(bus, Fault { pc, kind: e.into() }),
        };
        let instr = decode(hw1, hw2);
        self.run_decoded(bus, pc, instr, size)
    }

    /// Executes an already decoded instruction at `pc` of `size` bytes.
    #[inline]
    pub fn run_decoded<B: Bus>(&mut self, bus: &mut B, pc: u32, instr: Instr, size: u32) -> Event {
        self.run_priced::<B, true>(bus, pc, instr, size, None)
    }

    /// Executes a decoded instruction; `cost` is its precomputed `(not taken, taken)` cycles
    /// from [`timing::cycles`] (the decode cache keeps them), recomputed when `None` or for
    /// an I/O-port access. `TRACE` records [`Core::last`].
    #[inline(always)]
    pub(crate) fn run_priced<B: Bus, const TRACE: bool>(
        &mut self,
        bus: &mut B,
        pc: u32,
        instr: Instr,
        size: u32,
        cost: Option<(u8, u8)>,
    ) -> Event {
        match self.execute(bus, instr, pc, size) {
            Ok(o) => {
                let base = match cost {
                    Some((not_taken, taken)) if !o.io_port => {
                        if o.taken {
                            taken as u32
                        } else {
                            not_taken as u32
                        }
                    }
                    _ => timing::cycles(&instr, o.taken, o.io_port),
                };
                let cycles = base + o.extra;
                self.cycle += cycles as u64;
                self.instructions += 1;
                if TRACE {
                    self.last = Some(Retired { pc, instr, cycles });
                }
                match o.event {
                    Event::Svc(imm) => {
                        // SVCall must be able to preempt now, else it escalates (DDI0419 B1.5.4).
                        if self.nvic.priority(SVCALL) >= self.execution_priority() {
                            return self.fault(
                                bus,
                                Fault {
                                    pc,
                                    kind: FaultKind::SvcEscalation,
                                },
                            );
                        }
                        Event::Svc(imm)
                    }
                    e => e,
                }
            }
            Err(kind) => {
                if TRACE {
                    self.last = Some(Retired {
                        pc,
                        instr,
                        cycles: 0,
                    });
                }
                self.fault(bus, Fault { pc, kind })
            }
        }
    }

    fn lockup(&mut self, fault: Fault) -> Event {
        self.state = RunState::Lockup;
        self.fault = Some(fault);
        Event::Lockup
    }

    /// Takes a HardFault for `fault` (the faulting instruction is the return address), or
    /// locks up if already in HardFault or NMI.
    pub fn fault<B: Bus>(&mut self, bus: &mut B, fault: Fault) -> Event {
        if self.ipsr == HARDFAULT || self.ipsr == NMI {
            return self.lockup(fault);
        }
        match self.enter_exception(bus, HARDFAULT, fault.pc) {
            Ok(()) => {
                self.fault = Some(fault);
                Event::Fault
            }
            Err(kind) => self.lockup(Fault { pc: fault.pc, kind }),
        }
    }

    /// Exception entry (DDI0419 B1.5.6): stacks r0-r3, r12, LR, the return address and xPSR
    /// on the current stack (8-byte aligned), loads the vector, and costs
    /// [`EXCEPTION_ENTRY`] cycles.
    pub fn enter_exception<B: Bus>(
        &mut self,
        bus: &mut B,
        exc: u32,
        ret: u32,
    ) -> Result<(), FaultKind> {
        let was_psp = self.uses_psp();
        let sp = self.r[13];
        let align = sp & 4;
        let frame = sp.wrapping_sub(32 + align);
        let xpsr = self.xpsr() | ((align != 0) as u32) << 9;
        let words = [
            self.r[0], self.r[1], self.r[2], self.r[3], self.r[12], self.r[14], ret, xpsr,
        ];
        bus.write_words(self.id, self.cycle, frame, &words)?;
        self.r[13] = frame;
        self.r[14] = match (self.ipsr != 0, was_psp) {
            (true, _) => 0xffff_fff1,
            (false, false) => 0xffff_fff9,
            (false, true) => 0xffff_fffd,
        };
        self.ipsr = exc;
        self.switch_sp(was_psp);
        self.nvic.pending &= !(1u64 << exc);
        self.nvic.active |= 1u64 << exc;
        let vector = self.nvic.vtor.wrapping_add(4 * exc);
        let (target, _) = bus.read(self.id, self.cycle, vector, 4)?;
        self.r[15] = target & !1;
        self.thumb = target & 1 == 1;
        self.event = true;
        self.cycle += EXCEPTION_ENTRY as u64;
        Ok(())
    }

    /// Exception return (DDI0419 B1.5.8) for EXC_RETURN `value`.
    pub(crate) fn exception_return<B: Bus>(
        &mut self,
        bus: &mut B,
        value: u32,
    ) -> Result<(), FaultKind> {
        let (to_thread, to_psp) = match value {
            0xffff_fff1 => (false, false),
            0xffff_fff9 => (true, false),
            0xffff_fffd => (true, true),
            _ => return Err(FaultKind::InvalidExcReturn { value }),
        };
        let was_psp = self.uses_psp();
        self.nvic.active &= !(1u64 << self.ipsr);
        // Leave handler mode with the right stack selected, then unstack from it.
        self.ipsr = if to_thread { 0 } else { self.ipsr };
        if to_thread {
            self.control = (self.control & !2) | if to_psp { 2 } else { 0 };
        }
        self.switch_sp(was_psp);
        let frame = self.r[13];
        let mut w = [0u32; 8];
        bus.read_words(self.id, self.cycle, frame, &mut w)?;
        [
            self.r[0], self.r[1], self.r[2], self.r[3], self.r[12], self.r[14],
        ] = [w[0], w[1], w[2], w[3], w[4], w[5]];
        self.r[15] = w[6] & !1;
        let xpsr = w[7];
        self.set_apsr(xpsr);
        self.thumb = xpsr & (1 << 24) != 0;
        self.ipsr = if to_thread { 0 } else { xpsr & 0x3f };
        self.r[13] = frame.wrapping_add(32 + if xpsr & (1 << 9) != 0 { 4 } else { 0 });
        self.event = true;
        Ok(())
    }
}
