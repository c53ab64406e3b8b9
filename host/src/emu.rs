//! `tactus emu run` on the host side: an ELF read with a bound ([`read_elf`]) and run on a
//! board ([`ElfJob`], with an instruction trace: [`run_traced`]), its cores, profiles and
//! stop as text ([`core_text`], [`profile_line`], [`stop_line`]), firmware from `tactus
//! build` driven by a stimulus through its key map ([`FirmwareJob`]), and a GDB client
//! waited for ([`wait_for_gdb`]). The caller shows progress and prints.

use crate::fault::{BoardFaults, FaultError, FaultSpec};
use crate::keyboard::{key_map_sensor_words, Reporter};
use std::path::{Path, PathBuf};
use tactus_emulator::core::{Core, RunState};
use tactus_emulator::debug::gdb;
use tactus_emulator::Debugger;
use tactus_emulator::{Board, Config, StopReason};
use tactus_firmware::flash::{self, ElfRun, KeyMap};

/// The largest ELF file read, bytes: every memory an ELF may load into (ROM, 2 MB of
/// flash, SRAM) is far smaller; a bound on what a mistaken path (`/dev/zero`) can make the
/// command hold.
pub const MAX_ELF_BYTES: u64 = 64 << 20;

/// The longest firmware run with a stimulus, emulated seconds.
pub const MAX_FIRMWARE_SECONDS: f64 = 60.0;

/// Reads an ELF file of at most [`MAX_ELF_BYTES`].
///
/// Errors, as messages naming the file: unreadable, or longer than the bound.
pub fn read_elf(path: &Path) -> Result<Vec<u8>, String> {
    tactus_runtime::files::read_bounded(path, MAX_ELF_BYTES, "firmware for the RP2040")
        .map_err(|e| e.to_string())
}

/// Runs `board` for `cycles` cycles one step at a time, handing `line` one line per
/// instruction (core, start cycle, address, function, instruction, cycles), per sleep and
/// per exception entry. Returns why it stopped ([`StopReason::CycleLimit`] at the limit).
pub fn run_traced(board: &mut Board, cycles: u64, line: &mut dyn FnMut(String)) -> StopReason {
    let limit = board.cycle().saturating_add(cycles);
    loop {
        let before = [board.cores[0].cycle, board.cores[1].cycle];
        let before_count = [board.cores[0].instructions, board.cores[1].instructions];
        let Some(result) = board.step(limit) else {
            return StopReason::CycleLimit;
        };
        let k = match result {
            Ok(k) => k,
            Err(StopReason::Fault { core, .. }) | Err(StopReason::Svc { core, .. }) => core,
            Err(stop) => return stop,
        };
        let core = &board.cores[k];
        if core.instructions != before_count[k] {
            if let Some(last) = core.last {
                let func = board
                    .image
                    .function_at(last.pc)
                    .map(|s| s.name.as_str())
                    .unwrap_or("");
                line(format!(
                    "core{k} {:>10} {:08x} {:<20} {:<28} {} cycles",
                    before[k],
                    last.pc,
                    func,
                    last.instr.to_string(),
                    last.cycles
                ));
            }
        } else if core.cycle != before[k] {
            let what = match core.state {
                RunState::Sleeping { .. } => "sleep",
                _ => "exception entry",
            };
            line(format!(
                "core{k} {:>10} {what} ({} cycles)",
                before[k],
                core.cycle - before[k]
            ));
        }
        if let Err(stop) = result {
            return stop;
        }
    }
}

/// A core as text: its state, cycles and instructions, the 16 registers four to a line,
/// xPSR with its flags, PRIMASK and IPSR. Lines end in `\n`.
pub fn core_text(core: &Core) -> String {
    let state = match core.state {
        RunState::Running => "running",
        RunState::Sleeping { wfe: false } => "sleeping (WFI)",
        RunState::Sleeping { wfe: true } => "sleeping (WFE)",
        RunState::Parked => "parked",
        RunState::Lockup => "locked up",
    };
    let mut s = format!(
        "core {}: {state}, {} cycles, {} instructions\n",
        core.id, core.cycle, core.instructions
    );
    for row in 0..4 {
        let regs: Vec<String> = (0..4)
            .map(|i| {
                let n = row * 4 + i;
                let name = match n {
                    13 => "sp".to_string(),
                    14 => "lr".to_string(),
                    15 => "pc".to_string(),
                    _ => format!("r{n}"),
                };
                format!("{name:>3}={:08x}", core.r[n])
            })
            .collect();
        s.push_str(&format!("  {}\n", regs.join("  ")));
    }
    let flag = |b: bool, c: char| if b { c.to_ascii_uppercase() } else { c };
    s.push_str(&format!(
        "  xpsr={:08x} [{}{}{}{}] primask={} ipsr={}\n",
        core.xpsr(),
        flag(core.n, 'n'),
        flag(core.z, 'z'),
        flag(core.c, 'c'),
        flag(core.v, 'v'),
        core.primask as u8,
        core.ipsr
    ));
    s
}

/// One profiled function's calls in a line: count, and min, mean and max cycles per call.
pub fn profile_line(name: &str, calls: &[tactus_emulator::Call]) -> String {
    let cycles: Vec<u64> = calls.iter().map(|c| c.cycles).collect();
    match (cycles.iter().min(), cycles.iter().max()) {
        (Some(min), Some(max)) => {
            let mean = cycles.iter().sum::<u64>() as f64 / cycles.len() as f64;
            format!(
                "{name}: {} calls, cycles min {min} mean {mean:.1} max {max}",
                cycles.len()
            )
        }
        _ => format!("{name}: no completed calls"),
    }
}

/// Why a run of `cycles` cycles stopped, in a line, and whether it is a success (the cycle
/// limit, no core running, an `svc`) or an error (a fault, a lockup, a refused access:
/// described by the board, with the cores' PCs).
pub fn stop_line(board: &Board, stop: &StopReason, cycles: u64) -> (bool, String) {
    match stop {
        StopReason::CycleLimit => (true, format!("stopped: cycle limit {cycles} reached")),
        StopReason::Idle => (true, "stopped: no core running".to_string()),
        StopReason::Svc { core, imm } => {
            (true, format!("stopped: core {core} executed svc #{imm}"))
        }
        StopReason::Fault { .. } | StopReason::Lockup { .. } | StopReason::Refused { .. } => {
            (false, board.describe_stop(stop))
        }
    }
}

/// Listens on 127.0.0.1:`port` (0: any free port) and waits for one GDB client, handing
/// `say` the address to give GDB and then the client's; the session's log lines go to
/// `log`.
///
/// Errors, as messages naming `--gdb PORT`: the port cannot be listened on, or no client
/// could be accepted.
pub fn wait_for_gdb(
    port: u16,
    say: &mut dyn FnMut(String),
    log: Box<dyn FnMut(&str) + Send>,
) -> Result<Box<dyn Debugger>, String> {
    let listener = gdb::listen(port).map_err(|e| format!("--gdb {port}: cannot listen: {e}"))?;
    let addr = listener
        .local_addr()
        .map_err(|e| format!("--gdb {port}: {e}"))?;
    say(format!(
        "waiting for gdb on {addr} (in gdb: target remote {addr})"
    ));
    let (conn, peer) = listener
        .accept()
        .map_err(|e| format!("--gdb {port}: {e}"))?;
    say(format!("gdb connected from {peer}"));
    Ok(Box::new(gdb::GdbSession::new(conn, log)))
}

/// An ELF on an emulated board, loaded and its profiled functions found, ready to run
/// ([`ElfJob::new`], then [`ElfJob::run`]): `tactus emu run FILE` without a stimulus.
pub struct ElfJob {
    file: PathBuf,
    board: Board,
    profiles: Vec<(String, usize)>,
}

/// An ELF's run as text ([`ElfJob::run`]).
#[derive(Clone, Debug)]
pub struct ElfText {
    /// The lines to print: every core ([`core_text`]), then every profiled function
    /// ([`profile_line`]).
    pub lines: Vec<String>,
    /// Why the run stopped ([`stop_line`]).
    pub stop: String,
    /// Whether that is a success (the cycle limit, no core running, an `svc`) rather than a
    /// fault, a lockup or a refused access.
    pub ok: bool,
}

impl ElfJob {
    /// Reads the ELF `file` ([`read_elf`]), loads it on a board with the default
    /// configuration (an image with a `.boot2` section boots from flash through the boot
    /// ROM) and finds each function of `profile` to count its calls.
    ///
    /// Errors, as messages naming the file: unreadable, not loadable, a profiled symbol
    /// that is not a function of it.
    pub fn new(file: &Path, profile: &[String]) -> Result<ElfJob, String> {
        let bytes = read_elf(file)?;
        let mut board = Board::new(Config::default());
        board
            .load_elf(&bytes)
            .map_err(|e| format!("cannot load {}: {e}", file.display()))?;
        let mut profiles = Vec::new();
        for name in profile {
            let handle = board
                .profile(name)
                .map_err(|e| format!("{}: {e}", file.display()))?;
            profiles.push((name.clone(), handle));
        }
        Ok(ElfJob {
            file: file.to_path_buf(),
            board,
            profiles,
        })
    }

    /// Runs the board for `cycles` cycles under `debugger` if one is given, handing `trace`
    /// one line per instruction when it is given ([`run_traced`]); returns every core, every
    /// profiled function and why it stopped, as text.
    pub fn run(
        mut self,
        cycles: u64,
        debugger: Option<Box<dyn Debugger>>,
        trace: Option<&mut dyn FnMut(String)>,
    ) -> ElfText {
        let board = &mut self.board;
        if let Some(d) = debugger {
            board.attach_debugger(d);
        }
        let stop = match trace {
            Some(line) => run_traced(board, cycles, line),
            None => board.run_for(cycles),
        };
        board.finish_debugging();
        let mut lines: Vec<String> = (board.cores.iter())
            .flat_map(|c| core_text(c).lines().map(str::to_string).collect::<Vec<_>>())
            .collect();
        for (name, handle) in &self.profiles {
            lines.push(profile_line(name, board.calls(*handle)));
        }
        let (ok, line) = stop_line(board, &stop, cycles);
        ElfText {
            lines,
            stop: match ok {
                true => line,
                false => format!("{}: {line}", self.file.display()),
            },
            ok,
        }
    }
}

/// Firmware from `tactus build LAYOUT --target rp2040` with its key map and every key's
/// sensor words, checked and ready to run ([`FirmwareJob::new`], then
/// [`FirmwareJob::run`]).
pub struct FirmwareJob {
    file: PathBuf,
    stimulus: String,
    elf: Vec<u8>,
    map: KeyMap,
    words: Vec<Vec<i32>>,
    which: Vec<usize>,
    /// Per distinct words, its first sensor's raw range.
    ranges: Vec<Option<(i32, i32)>>,
    /// The faults to inject, resolved on this board.
    faults: Vec<(FaultSpec, tactus_firmware::image::Injection)>,
    /// Samples to run.
    pub samples: usize,
}

/// A firmware run as text ([`FirmwareJob::run`]).
#[derive(Clone, Debug)]
pub struct FirmwareText {
    /// The lines to print: the board, per core the handler's cycles and misses, the final
    /// cycles, the DAC words and their digest.
    pub lines: Vec<String>,
    /// Whether some core missed a deadline.
    pub missed: bool,
    /// The board's fault records at the end ([`crate::fault::report_lines`] are among
    /// `lines`).
    pub faults: BoardFaults,
    /// With no fault injected, a trip of the firmware's checks: a false alarm, said.
    pub false_alarm: Option<String>,
    /// The run itself.
    pub run: ElfRun,
}

impl FirmwareJob {
    /// Reads the ELF `file` and its key map (`keys`, default `keys.json` beside it), checks
    /// the map against the firmware ([`tactus_firmware::key_map::check`]) and makes every
    /// key's sensor words of `stimulus` (a built-in key stimulus or a CSV file) for
    /// `seconds` emulated seconds, compiling each instrument of the map once (its
    /// diagnostics to `report`), with `faults` injected into its sensors
    /// ([`crate::fault::faulted_sensor_words`]).
    ///
    /// Errors, as messages naming the file: an unreadable ELF or key map, a map that is not
    /// a key map or does not describe the firmware, `seconds` outside (0,
    /// [`MAX_FIRMWARE_SECONDS`]], a stimulus or instrument that cannot be made, a fault
    /// that names what the board does not have ([`FaultSpec::resolve_on_board`]).
    pub fn new(
        file: &Path,
        stimulus: &str,
        keys: Option<&Path>,
        seconds: f64,
        faults: &[FaultSpec],
        report: &mut Reporter,
    ) -> Result<FirmwareJob, String> {
        let elf = read_elf(file)?;
        let map_path = keys.map_or_else(|| file.with_file_name("keys.json"), Path::to_path_buf);
        let text = tactus_runtime::keyboard::read_text(&map_path).map_err(|e| {
            format!(
                "{}: cannot read the key map ({e}); `tactus build LAYOUT --target rp2040` writes it beside the ELF, or name it with --keys",
                file.display()
            )
        })?;
        let map: KeyMap = serde_json::from_str(&text)
            .map_err(|e| format!("{}: not a Tactus key map: {e}", map_path.display()))?;
        if let Some(c) = &map.converters {
            return Err(format!(
                "{}: board {} drives converters ({} and {}, `converters` in {}): `tactus emu \
                 run` feeds the sensor window and does not wire the emulated parts yet; \
                 `tactus play --board {}` plays such boards through them",
                file.display(),
                map.board,
                c.adc,
                c.dac,
                map_path.display(),
                map.board_kind
            ));
        }
        if !(seconds > 0.0 && seconds <= MAX_FIRMWARE_SECONDS) {
            return Err(format!(
                "--seconds {seconds}: from just above 0 to {MAX_FIRMWARE_SECONDS}"
            ));
        }
        // The map against the firmware it describes, before anything is made for its keys.
        let image = tactus_emulator::elf::parse(&elf)
            .map_err(|e| format!("{}: cannot load: {e}", file.display()))?;
        tactus_firmware::key_map::check(&map, &image).map_err(|e| {
            format!(
                "{}: {e} (the key map of {})",
                map_path.display(),
                file.display()
            )
        })?;
        let fs = f64::from(map.sample_rate_hz);
        let samples = (seconds * fs).round().max(1.0) as usize;
        let map_name = map_path.display().to_string();
        let midi: Vec<u8> = map.keys.iter().map(|k| k.midi).collect();
        let faults = (faults.iter())
            .map(|f| Ok((f.clone(), f.resolve_on_board(map.board, &midi, fs)?)))
            .collect::<Result<Vec<_>, FaultError>>()
            .map_err(|e| e.to_string())?;
        let (words, which, ranges) =
            key_map_sensor_words(&map, &map_name, stimulus, samples, report)?;
        Ok(FirmwareJob {
            file: file.to_path_buf(),
            stimulus: stimulus.to_string(),
            elf,
            map,
            words,
            which,
            ranges,
            faults,
            samples,
        })
    }

    /// Boots the firmware and runs it ([`flash::run_elf`]), `progress(done, total)` in
    /// samples, under `debugger` if one is given; returns the run as text.
    ///
    /// Errors: what [`flash::run_elf`] reports, naming the file.
    pub fn run(
        &self,
        debugger: Option<Box<dyn tactus_emulator::Debugger>>,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<FirmwareText, String> {
        let (map, file) = (&self.map, self.file.display());
        let mut sensors: Vec<&[i32]> = self.which.iter().map(|&i| &self.words[i][..]).collect();
        let ranges: Vec<Option<(i32, i32)>> = self.which.iter().map(|&i| self.ranges[i]).collect();
        let core_of: Vec<usize> = map.keys.iter().map(|k| k.core).collect();
        let faulted = crate::fault::faulted_sensor_words(
            &sensors,
            &ranges,
            &core_of,
            &self.faults,
            self.samples,
        )
        .map_err(|e| e.to_string())?;
        for (s, f) in sensors.iter_mut().zip(&faulted) {
            if let Some(f) = f {
                *s = f;
            }
        }
        let run = flash::run_elf(&self.elf, map, &sensors, self.samples, progress, debugger)
            .map_err(|e| format!("{file}: {e}"))?;
        let mut lines = vec![format!(
            "{file}: board {} ({} keys), {} samples of `{}` at {} Hz, {} cycles per sample",
            map.board,
            map.keys.len(),
            run.samples,
            self.stimulus,
            map.sample_rate_hz,
            run.cycles_per_sample
        )];
        for (c, core) in run.cores.iter().enumerate() {
            lines.push(format!(
                "core {c}: keys {:?}, {} samples, handler cycles mean {:.1} worst {} ({:.1} % of the period), misses {}",
                map.cores.get(c).map(|m| m.keys.clone()).unwrap_or_default(),
                core.samples,
                core.mean_cycles,
                core.worst_cycles,
                100.0 * core.worst_cycles as f64 / run.cycles_per_sample.max(1) as f64,
                core.misses
            ));
        }
        lines.push(format!(
            "final cycles: core 0 {}, core 1 {}",
            run.final_cycles[0], run.final_cycles[1]
        ));
        lines.push(format!(
            "DAC words at the end: {:08x?}; digest of every sample's words {:016x}",
            run.dac_final, run.dac_digest
        ));
        for f in &self.faults {
            lines.push(format!(
                "injected: {} ({})",
                f.0.text,
                match f.1.until {
                    Some(u) => format!("samples {} to {}", f.1.from, u),
                    None => format!("from sample {} on", f.1.from),
                }
            ));
        }
        let faults = BoardFaults {
            board: map.board,
            cores: crate::fault::decode(&run.fault_records),
            // A board's keys take window slots from 0 in key order, each as many as the
            // larger of its sensor and DAC words (`tactus_firmware::boards`).
            slots: (map.keys.iter())
                .scan(0, |slot, k| {
                    let at = *slot;
                    *slot += k.sensor_words.len().max(k.dac_words.len()).max(1);
                    Some((at, k.midi))
                })
                .collect(),
        };
        lines.extend(crate::fault::report_lines(
            std::slice::from_ref(&faults),
            f64::from(map.sample_rate_hz),
        ));
        let trips = faults.trips();
        let false_alarm = (trips > 0 && self.faults.is_empty()).then(|| {
            format!("the firmware's fault checks tripped {trips} times with no fault injected: a false alarm")
        });
        let missed = run.cores.iter().any(|c| c.misses > 0);
        Ok(FirmwareText {
            lines,
            missed,
            faults,
            false_alarm,
            run,
        })
    }
}
