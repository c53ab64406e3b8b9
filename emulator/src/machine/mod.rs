//! The RP2040 by definition: two cores and the system ([`Machine`]), run in lock-step.
//!
//! **Lock-step.** Each core has its own cycle counter; the machine always executes the
//! next instruction of the core whose counter is lower (core 0 on a tie), so every
//! shared-state access (SRAM banks, SIO FIFOs, spinlocks, timer, the I/O) happens in global
//! cycle order and a run is a pure function of the initial state: deterministic, whatever
//! the host. A sleeping core (WFI/WFE) skips ahead to the next cycle at which something
//! could wake it. Core 1 starts parked in the boot ROM's launch protocol (RP2040 datasheet
//! 2.8.2, `launch.rs`): it echoes the FIFO sequence `0, 0, 1, vector table, stack pointer,
//! entry` and then starts. [`Machine::step_core`] is that definition, one instruction at a
//! time; the cores reach memory only through [`crate::bus::Bus`] ([`System`]'s).
//!
//! **What runs it faster** ([`crate::accel`]) drives this machine through a narrow
//! interface, and every result it gives must be the one `step_core` gives:
//! - instructions from a cache ([`Decoder`]: what memory holds at the code epoch,
//!   [`System::code_epoch`], which every store into a code page and host write bumps);
//! - a core's state at some moment and back ([`Machine::snapshot_core`],
//!   [`Machine::restore_core`]), with the SRAM words stored since put back from an undo
//!   journal ([`System::undo_stores`]);
//! - the I/O's hooks on the system ([`System::io_journal`], `io_rec`, `io_lazy`: the DMA's
//!   writes journaled, its accesses logged with their lanes while a replay is recorded, a
//!   period memo's end left behind) and its data slots (`crate::io::slots`).
//!
//! `host.rs`: what the host does to the machine without cycles (power on from flash,
//! start a core, read and write memory).

mod host;
mod launch;
mod reset;

pub use host::EmuError;

use crate::config::Config;
use crate::core::{Core, Event, Fault, RunState};
use crate::nvic::{IRQ0, SVCALL};
use crate::sio::Divider;
use crate::system::System;
use launch::Launch;
use tactus_isa::decode::{decode, Instr};
use tactus_isa::timing::cycles;
use tactus_rp2040::memory::BANKS;

/// Why a run stopped ([`crate::Board::run_until`], [`Machine::step_core`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StopReason {
    /// Both cores reached the cycle limit.
    CycleLimit,
    /// A core executed SVC with [`Config::svc_halts`] set (its PC is past the SVC).
    Svc {
        /// The core.
        core: usize,
        /// The SVC immediate.
        imm: u8,
    },
    /// A core faulted (with [`Config::stop_on_fault`]); it has entered its HardFault handler.
    Fault {
        /// The core.
        core: usize,
        /// The fault.
        fault: Fault,
    },
    /// A core locked up (fault while handling HardFault, or failed stacking).
    Lockup {
        /// The core.
        core: usize,
        /// The fault.
        fault: Fault,
    },
    /// No core can run (all parked or locked up).
    Idle,
    /// The emulator refused what a core did: a clock or voltage write that would run clk_sys
    /// faster than the core voltage allows (`crate::clocks`). The store faulted.
    Refused {
        /// The core.
        core: usize,
        /// Why.
        why: crate::clocks::Refusal,
    },
}

/// Where the machine gets a core's next instruction: its decoded form, size in bytes and
/// `(not taken, taken)` cycles from the timing table, `None` when it cannot be fetched.
/// Whatever an implementation keeps, it must give what memory holds now ([`Fetch`] is the
/// definition; the accelerator's decode cache keys its entries by the code epoch).
pub trait Decoder {
    /// The instruction at `pc` in `sys`.
    fn decoded(&mut self, sys: &mut System, pc: u32) -> Option<(Instr, u32, (u8, u8))>;
}

/// Instructions decoded from memory at each step: the definition of [`Decoder`].
pub struct Fetch;

impl Decoder for Fetch {
    fn decoded(&mut self, sys: &mut System, pc: u32) -> Option<(Instr, u32, (u8, u8))> {
        use crate::bus::Bus;
        let (hw1, hw2, size) = sys.fetch_instr(pc).ok()?;
        let instr = decode(hw1, hw2);
        let cost = (
            cycles(&instr, false, false) as u8,
            cycles(&instr, true, false) as u8,
        );
        Some((instr, size, cost))
    }
}

/// What one lock-step step did ([`Machine::step_core`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// Core `k` slept (woke up, or skipped to the next cycle something could wake it).
    Slept(usize),
    /// Core `k` executed an instruction (or took an exception) with this event, not yet
    /// applied ([`Machine::handle_event`]).
    Ran(usize, Event),
    /// The watchdog reset the chip (`reset.rs`): both cores restarted.
    Reset,
}

/// A core's part of the machine at some moment ([`Machine::snapshot_core`]): what undoing
/// its steps since then puts back, with the SRAM words it stored since (an undo journal).
#[derive(Clone, Debug)]
pub struct CoreSnapshot {
    core: Core,
    claims: [u64; BANKS],
    stalls: u64,
    divider: Divider,
    /// The code epoch ([`System::code_epoch`]): undone stores may change code back.
    epoch: u32,
}

/// The emulated RP2040: two cores and the system (module documentation).
pub struct Machine {
    /// The two cores.
    pub cores: [Core; 2],
    /// Memories and peripherals.
    pub system: System,
    /// Core 1 in the boot ROM's launch protocol, until it starts.
    pub(crate) launch: Option<Launch>,
}

impl Machine {
    /// A machine clocked at `clock_hz` with zeroed memory and both cores parked (core 1 in
    /// the launch protocol).
    pub fn new(clock_hz: u64) -> Machine {
        let system = System::new(clock_hz);
        let mut cores = [Core::new(0), Core::new(1)];
        for c in &mut cores {
            // SysTick's reference: the 1 µs pulse of the watchdog's tick generator.
            c.nvic.clock_hz = clock_hz;
        }
        let mut m = Machine {
            cores,
            system,
            launch: None,
        };
        // Core 1 reaches `wait_for_vector` a few cycles after reset, long before core 0
        // can send anything: its first handshake is part of the power-on state.
        m.launch = Some(Launch::default());
        m.launch_handshake();
        m
    }

    /// Attaches the converters' I/O of `config` (`crate::io`: both PIO blocks, the DMA,
    /// IO_BANK0's function select, BUS_PRIORITY and the parts at their pins), out of reset,
    /// its clock at the machine's cycle, on a system clocked at `clock_hz`; replaces any
    /// attached before.
    pub fn attach_io(&mut self, config: &crate::io::IoConfig, clock_hz: u64) {
        let io = crate::io::Io::new(config, clock_hz as f64, self.cycle());
        self.system.io = Some(Box::new(io));
        self.system.io_lazy = None;
        self.system.io_banks = 0;
        self.system.allowed_banks = self.system.fast_banks();
    }

    /// The attached I/O (`None` without one), run up to the machine's cycle.
    pub fn io(&mut self) -> Option<&crate::io::Io> {
        self.system.io_unlazy();
        self.system.io.as_deref()
    }

    /// Sets the code channel `channel` (0–7) of ADC `adc` reads from now on
    /// ([`crate::converters::Ads8688::set_code`]); nothing without that ADC. Only data
    /// changes: unlike a change through [`Machine::io_mut`], the I/O's period memo still
    /// knows where it is (`accel/io_window/memo.rs`), and a machine a hit left behind takes
    /// the code among its data words ("The lazy end").
    pub fn set_adc_code(&mut self, adc: usize, channel: usize, code: u16) {
        // The machine a period memo's hit left behind keeps its data words apart.
        if let (Some(l), Some(io)) = (
            self.system.io_lazy.as_deref_mut(),
            self.system.io.as_deref(),
        ) {
            if let Some(w) = io
                .adc_code_slot(adc, channel)
                .and_then(|at| l.data.get_mut(at))
            {
                *w = u32::from(code);
            }
            return;
        }
        if let Some(io) = self.system.io.as_deref_mut() {
            if let Some(a) = io.adcs.get_mut(adc) {
                a.set_code(channel, code);
                io.data_changed();
            }
        }
    }

    /// The attached I/O, to set what the ADCs read (`Ads8688::set_code`).
    pub fn io_mut(&mut self) -> Option<&mut crate::io::Io> {
        self.system.io_unlazy();
        let io = self.system.io.as_deref_mut()?;
        io.forget_idle();
        Some(io)
    }

    /// Total cycles elapsed: the lower of the running cores' counters.
    pub fn cycle(&self) -> u64 {
        match self.next_core() {
            Some(k) => self.cores[k].cycle,
            None => self.cores[0].cycle.max(self.cores[1].cycle),
        }
    }

    /// The core whose turn it is: the active core with the lower cycle, core 0 on ties.
    pub fn next_core(&self) -> Option<usize> {
        match (active(&self.cores[0]), active(&self.cores[1])) {
            (true, true) => Some((self.cores[1].cycle < self.cores[0].cycle) as usize),
            (true, false) => Some(0),
            (false, true) => Some(1),
            (false, false) => None,
        }
    }

    /// One step of the lock-step machine (module documentation): the core that is behind
    /// executes its next instruction (or exception entry, or a sleep interval), from
    /// `dec`, if it is before `limit`. `None` when both running cores are at `limit`;
    /// `Err(Idle)` when no core can run. The instruction's event is not applied yet
    /// ([`Machine::handle_event`]).
    pub fn step_core(
        &mut self,
        limit: u64,
        dec: &mut impl Decoder,
    ) -> Option<Result<Step, StopReason>> {
        let Some(k) = self.next_core() else {
            return Some(Err(StopReason::Idle));
        };
        let now = self.cores[k].cycle;
        if now >= limit {
            return None;
        }
        if now >= self.system.watchdog.fire_at {
            self.watchdog_reset();
            return Some(Ok(Step::Reset));
        }
        if self.launch.is_some() && k == 0 {
            self.poll_launch();
        }
        let lines = self.system.irq_lines(k, now);
        if let RunState::Sleeping { wfe } = self.cores[k].state {
            let (other_running, other_cycle) = (
                self.cores[1 - k].state == RunState::Running,
                self.cores[1 - k].cycle,
            );
            let core = &mut self.cores[k];
            if (wfe && core.event) || core.wakes_from_sleep(lines) {
                if wfe {
                    core.event = false;
                }
                core.state = RunState::Running;
            } else {
                // Skip to the next cycle at which something could wake this core.
                let mut next = self
                    .system
                    .timer
                    .next_event
                    .min(self.system.watchdog.fire_at)
                    .min(core.nvic.syst_next)
                    .min(limit);
                if other_running {
                    next = next.min(other_cycle + 1);
                }
                core.cycle = next.max(now + 1);
            }
            return Some(Ok(Step::Slept(k)));
        }
        let event = self.execute::<true>(k, lines, dec);
        Some(Ok(Step::Ran(k, event)))
    }

    /// Runs the lock-step machine until both running cores reach cycle `limit`, or a stop:
    /// [`Machine::step_core`] with every instruction decoded from memory ([`Fetch`]), each
    /// event applied as `config` says ([`Machine::handle_event`]), then the I/O, if any,
    /// brought up to the machine's cycle. The definition of a run, with no accelerator
    /// ([`crate::config::Engine::LockStep`]).
    pub fn run_lock_step(&mut self, limit: u64, config: &Config) -> StopReason {
        let stop = loop {
            match self.step_core(limit, &mut Fetch) {
                None => break StopReason::CycleLimit,
                Some(Err(stop)) => break stop,
                Some(Ok(Step::Slept(_) | Step::Reset)) => {}
                Some(Ok(Step::Ran(k, event))) => {
                    if let Some(stop) = self.handle_event(k, event, config) {
                        break stop;
                    }
                }
            }
        };
        if self.system.io.is_some() {
            let now = self.cycle();
            self.system.io_advance(now);
        }
        stop
    }

    /// Core `k` executes its next instruction with the interrupt lines `lines` (exception
    /// entry first when one is takeable), the instruction from `dec`; with `TRACE`, it is
    /// recorded in [`Core::last`]. Returns its event.
    #[inline(always)]
    pub fn execute<const TRACE: bool>(
        &mut self,
        k: usize,
        lines: u32,
        dec: &mut impl Decoder,
    ) -> Event {
        let core = &mut self.cores[k];
        let pc = core.r[15];
        if lines != 0 {
            core.nvic.pending |= ((lines as u64) << IRQ0) & !core.nvic.active;
        }
        if core.nvic.takeable() != 0 || core.nvic.syst_next <= core.cycle || !core.thumb {
            return core.step(&mut self.system, lines);
        }
        let Some((instr, size, cost)) = dec.decoded(&mut self.system, pc) else {
            return core.step(&mut self.system, lines);
        };
        core.run_priced::<_, TRACE>(&mut self.system, pc, instr, size, Some(cost))
    }

    /// Applies core `k`'s `event` as `config` says (SEV reaches the other core; SVC stops
    /// or pends SVCall; a fault or lockup stops, a refused write always); `Some` when the
    /// run must stop.
    pub fn handle_event(&mut self, k: usize, event: Event, config: &Config) -> Option<StopReason> {
        match event {
            Event::None => None,
            Event::Sev => {
                // The event reaches the other core at the end of the SEV's cycle: a core
                // sleeping in WFE resumes no earlier than the next cycle.
                let after = self.cores[k].cycle;
                let other = &mut self.cores[1 - k];
                other.event = true;
                if matches!(other.state, RunState::Sleeping { .. }) {
                    other.cycle = other.cycle.max(after);
                }
                None
            }
            Event::Svc(imm) => {
                if config.svc_halts {
                    Some(StopReason::Svc { core: k, imm })
                } else {
                    self.cores[k].nvic.pending |= 1 << SVCALL;
                    None
                }
            }
            Event::Fault | Event::Lockup if self.system.sysctl.refusal.is_some() => self
                .system
                .sysctl
                .take_refusal()
                .map(|why| StopReason::Refused { core: k, why }),
            Event::Fault => {
                let fault = self.cores[k].fault?;
                config
                    .stop_on_fault
                    .then_some(StopReason::Fault { core: k, fault })
            }
            Event::Lockup => self.cores[k]
                .fault
                .map(|fault| StopReason::Lockup { core: k, fault }),
        }
    }

    /// True when core `s` is asleep and its sleep steps ([`Machine::step_core`]) would only
    /// move its cycle counter as long as nothing changes the interrupt lines, its NVIC or
    /// its event register and no timer event or SysTick wrap is due: no wake-up event, the
    /// current lines already pending on it, and no pending exception that would wake it.
    pub fn sleeps_soundly(&self, s: usize) -> bool {
        let c = &self.cores[s];
        let RunState::Sleeping { wfe } = c.state else {
            return false;
        };
        let lines = self.system.current_irq_lines();
        !(wfe && c.event)
            && ((lines as u64) << IRQ0) & !c.nvic.active & !c.nvic.pending == 0
            && c.nvic
                .highest_pending()
                .is_none_or(|(_, p)| p >= c.nvic.active_priority())
    }

    /// Core `k`'s part of the machine now: the core, its bank claims and contention stalls,
    /// its SIO divider, and the code epoch.
    pub fn snapshot_core(&self, k: usize) -> CoreSnapshot {
        CoreSnapshot {
            core: self.cores[k].clone(),
            claims: self.system.bank_claim.map(|c| c[k]),
            stalls: self.system.contention_stalls[k],
            divider: self.system.sio.divider[k].clone(),
            epoch: self.system.code_epoch,
        }
    }

    /// Puts core `k` back as `snap`, the SRAM words in `undo` (an undo journal of the
    /// stores since, oldest first: [`System::undo_stores`]) put back newest first; decoded
    /// code is dropped when the code epoch moved meanwhile.
    pub fn restore_core(&mut self, k: usize, snap: CoreSnapshot, undo: &[u64]) {
        self.system.undo_stores(undo);
        self.cores[k] = snap.core;
        for (bank, c) in snap.claims.iter().enumerate() {
            self.system.bank_claim[bank][k] = *c;
        }
        self.system.contention_stalls[k] = snap.stalls;
        self.system.sio.divider[k] = snap.divider;
        if self.system.code_epoch != snap.epoch {
            self.system.invalidate_code();
        }
    }
}

/// Whether core `c` takes turns: running, or asleep.
pub(crate) fn active(c: &Core) -> bool {
    matches!(c.state, RunState::Running | RunState::Sleeping { .. })
}
