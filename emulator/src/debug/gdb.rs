//! A GDB remote serial protocol stub for the emulated RP2040, on the `gdbstub` crate.
//!
//! The two cores are GDB's threads 1 and 2 (core 0 and core 1). GDB reads and writes their
//! registers ([`super::arch`]) and the board's memory (ROM, flash and SRAM through the host
//! API: a read costs the cores nothing; peripherals are not readable this way, so a read
//! never pops a FIFO), sets breakpoints (software and hardware alike: nothing is written
//! into the program) and read, write and access watchpoints, steps one core by one
//! instruction, continues, and interrupts (Ctrl-C). `monitor cycles` prints each core's
//! cycle counter and the cycles of its last sample interrupt (a handler named
//! `coreN_sample_isr` in the image's symbols, as `tactus build` writes them).
//!
//! **Cycle counts.** Stepping one core runs the board in its lock-step order until that
//! core has retired an instruction: the other core runs meanwhile exactly as far as it
//! would have, so single steps, breakpoints and watchpoints never change when anything
//! happens (the argument is in [`super`]).
//!
//! **Bad packets.** `gdbstub` checks every packet (checksums, lengths, hex) and answers or
//! drops what it cannot parse; an error of the session (the client went away, a protocol
//! error) is logged and the session detaches: the run goes on without a debugger. The
//! stub listens on 127.0.0.1 only ([`listen`]).

use super::arch::{ArmV6m, V6mRegs};
use super::WatchStop;
use crate::board::{Board, Debugger};
use crate::core::RunState;
use crate::machine::StopReason;
use crate::watch::{Access, Watches, Watchpoint};
use gdbstub::common::{Signal, Tid};
use gdbstub::conn::ConnectionExt;
use gdbstub::stub::state_machine::GdbStubStateMachine;
use gdbstub::stub::{GdbStub, MultiThreadStopReason};
use gdbstub::target::ext::base::multithread::{
    MultiThreadBase, MultiThreadResume, MultiThreadResumeOps, MultiThreadSchedulerLocking,
    MultiThreadSchedulerLockingOps, MultiThreadSingleStep, MultiThreadSingleStepOps,
};
use gdbstub::target::ext::base::BaseOps;
use gdbstub::target::ext::breakpoints::{
    Breakpoints, BreakpointsOps, HwBreakpoint, HwBreakpointOps, HwWatchpoint, HwWatchpointOps,
    SwBreakpoint, SwBreakpointOps, WatchKind,
};
use gdbstub::target::ext::monitor_cmd::{ConsoleOutput, MonitorCmd, MonitorCmdOps};
use gdbstub::target::ext::thread_extra_info::{ThreadExtraInfo, ThreadExtraInfoOps};
use gdbstub::target::{Target, TargetError, TargetResult};
use std::net::{TcpListener, TcpStream};

/// The most breakpoints and watchpoints a client may set (each is checked after every
/// instruction).
pub const MAX_WATCHES: usize = 256;

/// Cycles the board runs between two looks at the connection when nothing is watched
/// (about 1 ms of emulated time at 133 MHz).
pub const CHUNK_CYCLES: u64 = 1 << 17;

/// Thread id of core `k` (GDB's threads count from 1).
pub fn tid(core: usize) -> Tid {
    Tid::new(core + 1).unwrap_or(Tid::MIN)
}

fn core_of(tid: Tid) -> Result<usize, &'static str> {
    match tid.get() {
        1 => Ok(0),
        2 => Ok(1),
        _ => Err("no such core"),
    }
}

/// Binds the stub's listening socket: 127.0.0.1 only (port 0: any free port; read it back
/// from [`TcpListener::local_addr`]).
pub fn listen(port: u16) -> std::io::Result<TcpListener> {
    TcpListener::bind(("127.0.0.1", port))
}

/// One client's session: attach it with [`Board::attach_debugger`].
pub struct GdbSession {
    conn: Option<TcpStream>,
    sm: Option<GdbStubStateMachine<'static, Board, TcpStream>>,
    detached: bool,
    /// A stop of the board itself (a fault, a lockup) reported to the client, returned to
    /// the host once the client resumes.
    pending: Option<StopReason>,
    log: Box<dyn FnMut(&str) + Send>,
}

impl GdbSession {
    /// A session over an accepted connection; `log` gets one line per event worth telling
    /// (a protocol error, the client leaving).
    pub fn new(conn: TcpStream, log: Box<dyn FnMut(&str) + Send>) -> Self {
        let _ = conn.set_nodelay(true);
        GdbSession {
            conn: Some(conn),
            sm: None,
            detached: false,
            pending: None,
            log,
        }
    }

    fn detach(&mut self, board: &mut Board, why: &str) {
        (self.log)(why);
        board.debug_state.watches = Watches::default();
        board.debug_state.step = None;
        self.sm = None;
        self.detached = true;
    }

    /// Runs until a stop the client must hear of, the limit, or incoming data.
    fn run_board(board: &mut Board, limit: u64, conn: &mut TcpStream) -> WatchStop {
        let mut poll = || conn.peek().map(|b| b.is_some()).unwrap_or(true);
        let t = &board.debug_state;
        let watching = !t.watches.breakpoints.is_empty()
            || !t.watches.watchpoints.is_empty()
            || t.step.is_some();
        let stop = if watching {
            let watches = t.watches.clone();
            let step = t.step;
            board.run_watched(limit, &watches, step, &mut poll)
        } else {
            loop {
                let now = board.cycle();
                if now >= limit {
                    break WatchStop::Board(StopReason::CycleLimit);
                }
                let stop = board.run_until(limit.min(now.saturating_add(CHUNK_CYCLES)));
                if stop != StopReason::CycleLimit {
                    break WatchStop::Board(stop);
                }
                if board.cycle() < limit && poll() {
                    break WatchStop::Polled;
                }
            }
        };
        note_isr_calls(board);
        stop
    }
}

/// Moves the completed sample interrupts of the debugger's own profiles into
/// [`crate::watch::DebugState::last_isr`] (and clears them, so they never pile up).
fn note_isr_calls(board: &mut Board) {
    for c in 0..2 {
        if let Some(h) = board.debug_state.isr[c] {
            if let Some(&last) = board.calls(h).last() {
                board.debug_state.last_isr[c] = Some(last);
            }
            board.clear_calls(h);
        }
    }
}

fn stop_reason(stop: WatchStop) -> MultiThreadStopReason<u32> {
    match stop {
        WatchStop::Breakpoint { core } => MultiThreadStopReason::SwBreak(tid(core)),
        WatchStop::Stepped { core } => MultiThreadStopReason::SignalWithThread {
            tid: tid(core),
            signal: Signal::SIGTRAP,
        },
        WatchStop::Watch { core, addr, access } => MultiThreadStopReason::Watch {
            tid: tid(core),
            kind: match access {
                Access::Read => WatchKind::Read,
                Access::Write => WatchKind::Write,
                Access::Any => WatchKind::ReadWrite,
            },
            addr,
        },
        WatchStop::Board(StopReason::Fault { core, .. } | StopReason::Lockup { core, .. }) => {
            MultiThreadStopReason::SignalWithThread {
                tid: tid(core),
                signal: Signal::SIGSEGV,
            }
        }
        WatchStop::Board(StopReason::Svc { core, .. }) => MultiThreadStopReason::SignalWithThread {
            tid: tid(core),
            signal: Signal::SIGTRAP,
        },
        WatchStop::Board(_) | WatchStop::Polled => MultiThreadStopReason::SignalWithThread {
            tid: tid(0),
            signal: Signal::SIGINT,
        },
    }
}

impl Debugger for GdbSession {
    fn run_until(&mut self, board: &mut Board, limit: u64) -> StopReason {
        if self.sm.is_none() && !self.detached {
            if board.debug_state.isr == [None, None] {
                for c in 0..2 {
                    if let Ok(a) = board.symbol(&format!("core{c}_sample_isr")) {
                        board.debug_state.isr[c] = Some(board.profile_handler(a & !1));
                    }
                }
            }
            let Some(conn) = self.conn.take() else {
                self.detached = true;
                return board.run_until(limit);
            };
            match GdbStub::new(conn).run_state_machine(board) {
                Ok(sm) => self.sm = Some(sm),
                Err(e) => self.detach(board, &format!("gdb: cannot start the session: {e}")),
            }
        }
        loop {
            let Some(sm) = self.sm.take() else {
                self.detached = true;
                return board.run_until(limit);
            };
            let next = match sm {
                GdbStubStateMachine::Idle(mut s) => {
                    let byte = match s.borrow_conn().read() {
                        Ok(b) => b,
                        Err(_) => {
                            self.detach(board, "gdb: the client went away; the run goes on");
                            continue;
                        }
                    };
                    s.incoming_data(board, byte)
                }
                GdbStubStateMachine::Running(mut s) => {
                    if let Some(stop) = self.pending.take() {
                        // The client resumed after a stop of the board itself: the host
                        // hears of it now.
                        self.sm = Some(s.into());
                        return stop;
                    }
                    let stop = GdbSession::run_board(board, limit, s.borrow_conn());
                    match stop {
                        WatchStop::Board(StopReason::CycleLimit) => {
                            self.sm = Some(s.into());
                            return StopReason::CycleLimit;
                        }
                        WatchStop::Polled => match s.borrow_conn().read() {
                            Ok(byte) => s.incoming_data(board, byte),
                            Err(_) => {
                                self.detach(board, "gdb: the client went away; the run goes on");
                                continue;
                            }
                        },
                        other => {
                            if let WatchStop::Board(b) = other {
                                self.pending = Some(b);
                            }
                            board.debug_state.step = None;
                            s.report_stop(board, stop_reason(other))
                        }
                    }
                }
                GdbStubStateMachine::CtrlCInterrupt(s) => {
                    board.debug_state.step = None;
                    s.interrupt_handled(
                        board,
                        Some(MultiThreadStopReason::SignalWithThread {
                            tid: tid(0),
                            signal: Signal::SIGINT,
                        }),
                    )
                }
                GdbStubStateMachine::Disconnected(s) => {
                    let why = format!(
                        "gdb: {:?}; the run goes on without a debugger",
                        s.get_reason()
                    );
                    self.detach(board, &why);
                    continue;
                }
            };
            match next {
                Ok(sm) => self.sm = Some(sm),
                Err(e) => self.detach(board, &format!("gdb: session error ({e}); the run goes on")),
            }
        }
    }

    fn detached(&self) -> bool {
        self.detached
    }

    fn finish(&mut self, board: &mut Board) {
        if let Some(GdbStubStateMachine::Running(s)) = self.sm.take() {
            note_isr_calls(board);
            let _ = s.report_stop(board, MultiThreadStopReason::Exited(0));
        }
        self.sm = None;
        self.detached = true;
    }
}

impl Target for Board {
    type Arch = ArmV6m;
    type Error = &'static str;

    fn base_ops(&mut self) -> BaseOps<'_, Self::Arch, Self::Error> {
        BaseOps::MultiThread(self)
    }

    fn support_breakpoints(&mut self) -> Option<BreakpointsOps<'_, Self>> {
        Some(self)
    }

    fn support_monitor_cmd(&mut self) -> Option<MonitorCmdOps<'_, Self>> {
        Some(self)
    }
}

impl MultiThreadBase for Board {
    fn read_registers(&mut self, regs: &mut V6mRegs, tid: Tid) -> TargetResult<(), Self> {
        *regs = V6mRegs::of(&self.cores[core_of(tid).map_err(TargetError::Fatal)?]);
        Ok(())
    }

    fn write_registers(&mut self, regs: &V6mRegs, tid: Tid) -> TargetResult<(), Self> {
        let k = core_of(tid).map_err(TargetError::Fatal)?;
        regs.write_to(&mut self.cores[k]);
        Ok(())
    }

    fn read_addrs(&mut self, start: u32, data: &mut [u8], _tid: Tid) -> TargetResult<usize, Self> {
        if self.read_bytes(start, data).is_ok() {
            return Ok(data.len());
        }
        // Part of the range is unmapped: as much as can be read from the start.
        for (i, b) in data.iter_mut().enumerate() {
            let mut one = [0u8];
            if self
                .read_bytes(start.wrapping_add(i as u32), &mut one)
                .is_err()
            {
                return if i == 0 {
                    Err(TargetError::NonFatal)
                } else {
                    Ok(i)
                };
            }
            *b = one[0];
        }
        Ok(data.len())
    }

    fn write_addrs(&mut self, start: u32, data: &[u8], _tid: Tid) -> TargetResult<(), Self> {
        self.write_bytes(start, data)
            .map_err(|_| TargetError::NonFatal)
    }

    fn list_active_threads(&mut self, register: &mut dyn FnMut(Tid)) -> Result<(), Self::Error> {
        register(tid(0));
        register(tid(1));
        Ok(())
    }

    fn support_resume(&mut self) -> Option<MultiThreadResumeOps<'_, Self>> {
        Some(self)
    }

    fn support_thread_extra_info(&mut self) -> Option<ThreadExtraInfoOps<'_, Self>> {
        Some(self)
    }
}

impl MultiThreadResume for Board {
    fn resume(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }

    fn clear_resume_actions(&mut self) -> Result<(), Self::Error> {
        self.debug_state.step = None;
        Ok(())
    }

    fn set_resume_action_continue(
        &mut self,
        _tid: Tid,
        _signal: Option<Signal>,
    ) -> Result<(), Self::Error> {
        // Both cores always run: freezing one would change every cycle count after it.
        Ok(())
    }

    fn support_single_step(&mut self) -> Option<MultiThreadSingleStepOps<'_, Self>> {
        Some(self)
    }

    fn support_scheduler_locking(&mut self) -> Option<MultiThreadSchedulerLockingOps<'_, Self>> {
        Some(self)
    }
}

/// GDB asks for the other threads to stay stopped while it steps one (`vCont;s:2` alone,
/// its default): the other core is never frozen here — frozen, it would fall behind and
/// every cycle count after would change — it runs in lock-step exactly as far as the
/// stepped core's instruction takes the board.
impl MultiThreadSchedulerLocking for Board {
    fn set_resume_action_scheduler_lock(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

impl MultiThreadSingleStep for Board {
    fn set_resume_action_step(
        &mut self,
        tid: Tid,
        _signal: Option<Signal>,
    ) -> Result<(), Self::Error> {
        self.debug_state.step = Some(core_of(tid)?);
        Ok(())
    }
}

impl Board {
    fn add_breakpoint(&mut self, addr: u32) -> bool {
        let w = &mut self.debug_state.watches;
        let a = addr & !1;
        if !w.breakpoints.contains(&a) {
            if w.breakpoints.len() + w.watchpoints.len() >= MAX_WATCHES {
                return false;
            }
            w.breakpoints.push(a);
        }
        true
    }

    fn remove_breakpoint(&mut self, addr: u32) -> bool {
        let w = &mut self.debug_state.watches;
        let n = w.breakpoints.len();
        w.breakpoints.retain(|&b| b != addr & !1);
        w.breakpoints.len() != n
    }
}

impl Breakpoints for Board {
    fn support_sw_breakpoint(&mut self) -> Option<SwBreakpointOps<'_, Self>> {
        Some(self)
    }

    fn support_hw_breakpoint(&mut self) -> Option<HwBreakpointOps<'_, Self>> {
        Some(self)
    }

    fn support_hw_watchpoint(&mut self) -> Option<HwWatchpointOps<'_, Self>> {
        Some(self)
    }
}

impl SwBreakpoint for Board {
    fn add_sw_breakpoint(&mut self, addr: u32, _kind: usize) -> TargetResult<bool, Self> {
        Ok(self.add_breakpoint(addr))
    }

    fn remove_sw_breakpoint(&mut self, addr: u32, _kind: usize) -> TargetResult<bool, Self> {
        Ok(self.remove_breakpoint(addr))
    }
}

impl HwBreakpoint for Board {
    fn add_hw_breakpoint(&mut self, addr: u32, _kind: usize) -> TargetResult<bool, Self> {
        Ok(self.add_breakpoint(addr))
    }

    fn remove_hw_breakpoint(&mut self, addr: u32, _kind: usize) -> TargetResult<bool, Self> {
        Ok(self.remove_breakpoint(addr))
    }
}

fn access(kind: WatchKind) -> Access {
    match kind {
        WatchKind::Read => Access::Read,
        WatchKind::Write => Access::Write,
        WatchKind::ReadWrite => Access::Any,
    }
}

impl HwWatchpoint for Board {
    fn add_hw_watchpoint(
        &mut self,
        addr: u32,
        len: u32,
        kind: WatchKind,
    ) -> TargetResult<bool, Self> {
        let w = &mut self.debug_state.watches;
        if w.breakpoints.len() + w.watchpoints.len() >= MAX_WATCHES {
            return Ok(false);
        }
        w.watchpoints.push(Watchpoint {
            addr,
            len: len.max(1),
            access: access(kind),
        });
        Ok(true)
    }

    fn remove_hw_watchpoint(
        &mut self,
        addr: u32,
        len: u32,
        kind: WatchKind,
    ) -> TargetResult<bool, Self> {
        let w = &mut self.debug_state.watches;
        let want = Watchpoint {
            addr,
            len: len.max(1),
            access: access(kind),
        };
        match w.watchpoints.iter().position(|x| *x == want) {
            Some(i) => {
                w.watchpoints.remove(i);
                Ok(true)
            }
            None => Ok(false),
        }
    }
}

impl ThreadExtraInfo for Board {
    fn thread_extra_info(&self, tid: Tid, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let k = core_of(tid)?;
        let c = &self.cores[k];
        let state = match c.state {
            RunState::Running => "running",
            RunState::Sleeping { .. } => "sleeping",
            RunState::Parked => "parked",
            RunState::Lockup => "locked up",
        };
        let text = format!("core {k}, {state}, cycle {}", c.cycle);
        let n = text.len().min(buf.len());
        buf[..n].copy_from_slice(&text.as_bytes()[..n]);
        Ok(n)
    }
}

/// The text of `monitor cycles`: per core its cycle counter, instructions retired and the
/// cycles of its last sample interrupt (exception entry included, as the budget counts
/// them).
pub fn cycles_report(board: &Board) -> String {
    let mut s = String::new();
    for (k, c) in board.cores.iter().enumerate() {
        s.push_str(&format!(
            "core {k}: cycle {}, {} instructions",
            c.cycle, c.instructions
        ));
        let t = &board.debug_state;
        match (t.isr[k], t.last_isr[k]) {
            (None, _) => s.push_str("; no sample interrupt in the image's symbols\n"),
            (Some(_), None) => s.push_str("; no sample interrupt completed yet\n"),
            (Some(_), Some(call)) => s.push_str(&format!(
                "; last sample interrupt {} cycles (entered at cycle {})\n",
                call.cycles + tactus_isa::timing::EXCEPTION_ENTRY as u64,
                call.start
            )),
        }
    }
    s
}

impl MonitorCmd for Board {
    fn handle_monitor_cmd(
        &mut self,
        cmd: &[u8],
        mut out: ConsoleOutput<'_>,
    ) -> Result<(), Self::Error> {
        let cmd = String::from_utf8_lossy(cmd);
        match cmd.trim() {
            "cycles" | "cycle" => {
                note_isr_calls(self);
                gdbstub::outputln!(out, "{}", cycles_report(self).trim_end());
            }
            "" | "help" => gdbstub::outputln!(
                out,
                "monitor cycles: each core's cycle counter and its last sample interrupt's cycles"
            ),
            other => gdbstub::outputln!(
                out,
                "unknown monitor command `{other}` (try `monitor help`)"
            ),
        }
        Ok(())
    }
}
