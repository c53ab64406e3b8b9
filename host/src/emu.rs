//! `tactus emu run` on the host side: an ELF read with a bound ([`read_elf`]) and run on a
//! board ([`ElfJob`], with an instruction trace: [`run_traced`]), its cores, profiles and
//! stop as text ([`core_text`], [`profile_line`], [`stop_line`]), firmware from `tactus
//! build` driven by a stimulus through its key map ([`FirmwareJob`]), and a GDB client
//! waited for ([`wait_for_gdb`]). The caller shows progress and prints.

use crate::fault::{BoardFaults, FaultError, FaultSpec};
use crate::keyboard::{on_off, Reporter};
use std::path::{Path, PathBuf};
use tactus_emulator::core::{Core, RunState};
use tactus_emulator::debug::gdb;
use tactus_emulator::Debugger;
use tactus_emulator::{Board, Config, StopReason};
use tactus_firmware::flash::{self, KeyMap};
use tactus_firmware::image::{FaultKind, FirmwareImage, ImageRun, Injection, ResetRecord};

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

/// Firmware from `tactus build LAYOUT --target rp2040` with its key map, rebuilt from the
/// key maps of its keyboard and checked to be that build's byte for byte
/// ([`FirmwareJob::new`]), and every key's sensor words of a stimulus, ready to run through
/// [`ImageRun`] — the run `tactus play` gives every board, on a plain board or one with
/// converters, with any fault injected ([`FirmwareJob::run`]).
pub struct FirmwareJob {
    file: PathBuf,
    stimulus: String,
    elf: Vec<u8>,
    map: KeyMap,
    /// The image the ELF is, as its build made it (its keys, cores and addresses).
    image: FirmwareImage,
    /// Per program of the image, its first sensor's words over the stimulus (one run of
    /// it, at most the samples to run; empty without a sensor).
    words: Vec<Vec<i32>>,
    /// The faults to inject, resolved on this board.
    faults: Vec<(FaultSpec, Injection)>,
    /// Samples to run.
    pub samples: usize,
}

/// A firmware run as text ([`FirmwareJob::run`]).
#[derive(Clone, Debug)]
pub struct FirmwareText {
    /// The lines to print: the board, per core the handler's cycles and misses, the final
    /// cycles, the DAC codes and their digest, the faults injected, the resets, the fault
    /// report.
    pub lines: Vec<String>,
    /// Whether some core missed a deadline with no fault injected (with one, a hung core's
    /// misses are the fault's).
    pub missed: bool,
    /// The board's fault records at the end ([`crate::fault::report_lines`] are among
    /// `lines`).
    pub faults: BoardFaults,
    /// The resets the board met (the watchdog's, a brown-out).
    pub resets: Vec<ResetRecord>,
    /// With no fault injected, a trip of the firmware's checks or a reset: a false alarm,
    /// said.
    pub false_alarm: Option<String>,
    /// Warnings: each `--fault kind=hang` whose key the stimulus leaves standing still when
    /// the hang begins ([`crate::fault::RestingHang`], as `tactus play` warns of it).
    pub warnings: Vec<String>,
}

/// The most key maps of one keyboard read beside a board's (`board-NN` directories).
const MAX_BOARDS: usize = 128;

/// The key maps of the keyboard whose board's key map is `map`, read from `map_path`:
/// `map` and, when its directory is a `board-NN` of a build's output, the `keys.json` of
/// every other `board-NN` beside it (at most [`MAX_BOARDS`]), of the same board kind.
///
/// Errors, as messages naming the file: a sibling key map that cannot be read or parsed.
pub fn keyboard_maps(map: &KeyMap, map_path: &Path) -> Result<Vec<KeyMap>, String> {
    let mut maps = vec![map.clone()];
    let dir = map_path.parent().filter(|d| !d.as_os_str().is_empty());
    let is_board = |name: &str| {
        name.strip_prefix("board-")
            .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
    };
    let Some(dir) = dir.filter(|d| {
        d.file_name()
            .is_some_and(|n| is_board(&n.to_string_lossy()))
    }) else {
        return Ok(maps);
    };
    let Some(Ok(entries)) = dir.parent().map(std::fs::read_dir) else {
        return Ok(maps);
    };
    let mut others: Vec<PathBuf> = entries
        .filter_map(Result::ok)
        .filter(|e| is_board(&e.file_name().to_string_lossy()))
        .map(|e| e.path())
        .filter(|p| p.file_name() != dir.file_name())
        .take(MAX_BOARDS)
        .map(|p| p.join("keys.json"))
        .filter(|p| p.exists())
        .collect();
    others.sort();
    for path in others {
        let text = tactus_runtime::keyboard::read_text(&path)?;
        let other = tactus_firmware::key_map::parse(&text).map_err(|e| {
            format!(
                "{}: {e} (a key map beside {}: every board of the keyboard is rebuilt to \
                 find the firmware's shared code)",
                path.display(),
                map_path.display()
            )
        })?;
        if other.board != map.board && other.board_kind == map.board_kind {
            maps.push(other);
        }
    }
    Ok(maps)
}

/// The paths (`clock_hz`, `cores[0].keys`, `keys[3].sensor_words`, …) where two key maps
/// as JSON differ, in order, at most `most` of them.
fn map_differences(a: &serde_json::Value, b: &serde_json::Value, most: usize) -> Vec<String> {
    fn walk(
        a: &serde_json::Value,
        b: &serde_json::Value,
        at: &str,
        out: &mut Vec<String>,
        most: usize,
    ) {
        use serde_json::Value;
        if out.len() >= most {
            return;
        }
        match (a, b) {
            (Value::Object(x), Value::Object(y)) => {
                let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
                keys.dedup();
                let mut seen = Vec::new();
                for k in keys {
                    if seen.contains(&k) {
                        continue;
                    }
                    seen.push(k);
                    let path = if at.is_empty() {
                        k.clone()
                    } else {
                        format!("{at}.{k}")
                    };
                    match (x.get(k), y.get(k)) {
                        (Some(u), Some(v)) => walk(u, v, &path, out, most),
                        _ => out.push(path),
                    }
                }
            }
            (Value::Array(x), Value::Array(y)) if x.len() == y.len() => {
                for (i, (u, v)) in x.iter().zip(y).enumerate() {
                    walk(u, v, &format!("{at}[{i}]"), out, most);
                }
            }
            _ if a == b => {}
            _ => out.push(at.to_string()),
        }
    }
    let mut out = Vec::new();
    walk(a, b, "", &mut out, most);
    out
}

/// The image of board `map.board` of the keyboard `kb` (rebuilt from its key maps:
/// [`crate::keyboard::from_key_maps`]) as `tactus build` builds it, with the sensor check
/// and the watchdog as the key map records them (`KeyMap::sensor_check`, `watchdog`),
/// checked to be `elf` byte for byte and to write `map`. Returns the image.
///
/// Errors, as messages naming `file` and `map_name`: the build of the key maps is not `elf`
/// (another keyboard's or version's firmware, or a key map edited by hand), or it is but
/// its key map differs from `map` (the fields named).
fn rebuild(
    kb: &mut crate::keyboard::Keyboard,
    map: &KeyMap,
    elf: &[u8],
    file: &Path,
    map_name: &str,
) -> Result<FirmwareImage, String> {
    let defaults = kb.firmware().map_err(|e| format!("{map_name}: {e}"))?;
    let (sensor_check, watchdog) = (map.sensor_check, map.watchdog);
    let names: Vec<(String, Vec<(String, String)>)> = (kb.sets.iter())
        .map(|s| (s.instrument.clone(), s.params.clone()))
        .collect();
    let keys = kb.key_programs();
    let list: Vec<u8> = map.keys.iter().map(|k| k.midi).collect();
    let load = match map.entry.trim_start_matches("0x") {
        e if u32::from_str_radix(e, 16).ok() == Some(tactus_firmware::image::boot::ENTRY | 1) => {
            flash::Load::Ram
        }
        _ => flash::Load::Flash,
    };
    let limiter = kb.limiter();
    let wanted = serde_json::to_value(map).map_err(|e| format!("{map_name}: {e}"))?;
    let programs: Vec<_> = (defaults.iter())
        .map(|p| {
            let mut p = p.clone();
            p.sensor_check = sensor_check;
            p.watchdog = watchdog;
            p
        })
        .collect();
    let input = flash::KeyboardInput {
        name: &kb.name,
        programs: &programs,
        program_names: &names,
        keys: &keys,
        board: &kb.board,
        boards: std::slice::from_ref(&list),
        images: &[],
        limiter: &limiter,
        load,
        command: "",
    };
    let maps = kb.boards.as_ref().map_or(1, Vec::len);
    let not_it = |why: &str| {
        format!(
            "{}: not the firmware its key maps build (board {}, rebuilt from {maps} key map{} \
             of {} keys, the sensor check {} and the watchdog {} as {map_name} records them: \
             {why}): built by another version of tactus, from other key maps, with a key map \
             edited since, or a board taken out of its build (an instrument graded over the \
             keyboard shares one code planned over every board's keys: keep the build's \
             board-NN directories together); build it again with `tactus build … --target \
             rp2040`",
            file.display(),
            map.board,
            if maps == 1 { "" } else { "s" },
            kb.keys.len(),
            on_off(sensor_check),
            on_off(watchdog),
        )
    };
    let mut built = flash::keyboard_firmware(&input, &mut |_, _, _| {}).map_err(|e| not_it(&e))?;
    let Some(mut fw) = built.pop() else {
        return Err(not_it("no board built"));
    };
    if fw.elf != elf {
        return Err(not_it("the ELFs differ"));
    }
    fw.key_map.board = map.board;
    let ours = serde_json::to_value(&fw.key_map).map_err(|e| format!("{map_name}: {e}"))?;
    let differ = map_differences(&wanted, &ours, 6);
    if !differ.is_empty() {
        return Err(format!(
            "{map_name}: {} {} not what the build of {} writes: the key map does not \
             describe its firmware",
            differ
                .iter()
                .map(|d| format!("`{d}`"))
                .collect::<Vec<_>>()
                .join(", "),
            if differ.len() == 1 { "is" } else { "are" },
            file.display()
        ));
    }
    kb.sensor_check = Some(sensor_check);
    kb.watchdog = Some(watchdog);
    Ok(fw.image)
}

/// Per program of `image`, its first sensor's raw words over `stimulus` (a built-in key
/// stimulus in the sensor's own range, or a CSV file of key positions, read once) at `fs`
/// Hz, at most `samples` of them (one run of the stimulus; the run repeats it); empty for
/// a program without a sensor. The words are the program's own sensor format (the code the
/// firmware was compiled with, shared code included).
///
/// Errors, as messages: a stimulus that cannot be read or has no samples.
pub fn stimulus_words(
    image: &FirmwareImage,
    stimulus: &str,
    fs: f64,
    samples: usize,
) -> Result<Vec<Vec<i32>>, String> {
    use tactus_compiler::fixed::interp::FixedInstance;
    let csv = match Path::new(stimulus).exists() {
        true => Some(
            tactus_runtime::stimulus::from_csv(Path::new(stimulus), fs)
                .map_err(|e| format!("--stimulus {stimulus}: {e}"))?,
        ),
        false => None,
    };
    (image.programs().iter())
        .map(|p| {
            let fp = &p.fixed;
            let Some(s0) = fp.program.sensors.first() else {
                return Ok(Vec::new());
            };
            let builtin;
            let st = match &csv {
                Some(st) => st,
                None => {
                    builtin = tactus_runtime::stimulus::builtin(stimulus, s0.range.1, fs)
                        .map_err(|e| format!("--stimulus {stimulus}: {e}"))?;
                    &builtin
                }
            };
            if st.key.is_empty() {
                return Err(format!("--stimulus {stimulus}: no samples"));
            }
            Ok((st.key.iter().take(samples))
                .map(|&x| FixedInstance::sensor_raw(fp, 0, Some(x)))
                .collect())
        })
        .collect()
}

impl FirmwareJob {
    /// Reads the ELF `file` and its key map (`keys`, default `keys.json` beside it), checks
    /// the map against the ELF ([`tactus_firmware::key_map::check`]), rebuilds the
    /// keyboard it belongs to from its key maps (the board's, and those of the `board-NN`
    /// directories beside it: [`keyboard_maps`], [`crate::keyboard::from_key_maps`]; the
    /// diagnostics to `report`) and the board's image as `tactus build` builds it, checked
    /// to be the ELF byte for byte and to write the key map (the sensor check and the
    /// watchdog found as built), makes every key's sensor words of `stimulus` (a built-in
    /// key stimulus or a CSV file) for `seconds` emulated seconds, and resolves `faults`
    /// on the board ([`FaultSpec::resolve_on_board`]).
    ///
    /// Errors, as messages naming the file: an unreadable ELF or key map, a map that is not
    /// a key map or does not describe the firmware, `seconds` outside (0,
    /// [`MAX_FIRMWARE_SECONDS`]], a keyboard that cannot be rebuilt or whose build is not
    /// the ELF, a stimulus that cannot be made, a fault that names what the board does not
    /// have.
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
        let map = tactus_firmware::key_map::parse(&text)
            .map_err(|e| format!("{}: {e}", map_path.display()))?;
        if !(seconds > 0.0 && seconds <= MAX_FIRMWARE_SECONDS) {
            return Err(format!(
                "--seconds {seconds}: from just above 0 to {MAX_FIRMWARE_SECONDS}"
            ));
        }
        // The map against the firmware it describes, before anything is made for its keys.
        let parsed = tactus_emulator::elf::parse(&elf)
            .map_err(|e| format!("{}: cannot load: {e}", file.display()))?;
        tactus_firmware::key_map::check(&map, &parsed).map_err(|e| {
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
        let maps = keyboard_maps(&map, &map_path)?;
        let mut kb =
            crate::keyboard::from_key_maps(&maps, &map_name, report).map_err(|e| e.to_string())?;
        let image = rebuild(&mut kb, &map, &elf, file, &map_name)?;
        let words = stimulus_words(&image, stimulus, fs, samples)?;
        Ok(FirmwareJob {
            file: file.to_path_buf(),
            stimulus: stimulus.to_string(),
            elf,
            map,
            image,
            words,
            faults,
            samples,
        })
    }

    /// Boots the firmware from its ELF and runs it sample by sample through
    /// [`ImageRun`] (the board's converters at their pins when it has them; the rest
    /// replay on unless a debugger is attached), with the faults injected
    /// ([`ImageRun::inject`]), `progress(done, total)` in samples, under `debugger` if one
    /// is given (attached at the first sample tick); returns the run as text.
    ///
    /// Errors: what the run reports (the board stops, a core never completes a sample),
    /// naming the file.
    pub fn run(
        &self,
        debugger: Option<Box<dyn tactus_emulator::Debugger>>,
        progress: &mut dyn FnMut(usize, usize),
    ) -> Result<FirmwareText, String> {
        let (map, image, file) = (&self.map, &self.image, self.file.display());
        let fail = |e: tactus_firmware::image::ImageError| format!("{file}: {e}");
        // Each key's words: its first sensor following the stimulus (repeated), the others
        // at the bottom of their range.
        let specs = image.keys();
        let programs = image.programs();
        let rest: Vec<Vec<i32>> = (specs.iter())
            .map(|k| {
                let p = &programs[k.program];
                (0..p.sensor_words())
                    .map(|i| {
                        tactus_compiler::fixed::interp::FixedInstance::sensor_raw(&p.fixed, i, None)
                    })
                    .collect()
            })
            .collect();
        let cores = image.cores();
        let (mut worst, mut total, mut runs) =
            (vec![0u64; cores], vec![0u64; cores], vec![0u64; cores]);
        let mut misses = vec![0u32; cores];
        let mut digest: u64 = 0xcbf2_9ce4_8422_2325;
        let mut flat = Vec::with_capacity(image.sensor_words());
        let words_at = |n: usize, flat: &mut Vec<i32>| {
            flat.clear();
            for (k, r) in specs.iter().zip(&rest) {
                let w = &self.words[k.program];
                flat.extend_from_slice(r);
                if let (Some(first), false) = (
                    flat.len().checked_sub(r.len()),
                    w.is_empty() || r.is_empty(),
                ) {
                    flat[first] = w[n % w.len()];
                }
            }
        };
        // The keys where the stimulus starts from power-on (a converter board's first
        // handler reads the burst of the start alarm: `FirmwareImage::run_from`).
        words_at(0, &mut flat);
        let mut run = ImageRun::from_elf(image, &self.elf, Some(&flat)).map_err(fail)?;
        run.set_rest_replay(debugger.is_none()).map_err(fail)?;
        if let Some(d) = debugger {
            run.board().attach_debugger(d);
        }
        for (spec, f) in &self.faults {
            run.inject(*f).map_err(|e| format!("{}: {e}", spec.text))?;
        }
        let mut dac: Vec<i16> = Vec::new();
        for n in 0..self.samples {
            words_at(n, &mut flat);
            let out = run
                .step(&flat)
                .map_err(|e| format!("{file}: sample {n}: {e}"))?;
            for c in 0..cores {
                worst[c] = worst[c].max(out.core_cycles[c]);
                total[c] += out.core_cycles[c];
                runs[c] += u64::from(out.handler_runs[c]);
                misses[c] = out.misses[c];
            }
            dac.clear();
            dac.extend(out.drives.iter().flatten().map(|d| d.dac));
            for b in dac.iter().flat_map(|d| d.to_le_bytes()) {
                digest = (digest ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
            }
            if n % 4410 == 0 {
                progress(n, self.samples);
            }
        }
        progress(self.samples, self.samples);
        run.settle().map_err(fail)?;
        run.board().finish_debugging();
        let records = crate::fault::run_records(&mut run)?;
        let resets = run.resets().to_vec();
        let mut lines = vec![format!(
            "{file}: board {} ({} keys, {}), {} samples of `{}` at {} Hz, {} cycles per sample, sensor check {}, watchdog {}",
            map.board,
            map.keys.len(),
            map.board_kind,
            self.samples,
            self.stimulus,
            map.sample_rate_hz,
            image.cycles_per_sample(),
            on_off(map.sensor_check),
            on_off(map.watchdog),
        )];
        for c in 0..cores {
            lines.push(format!(
                "core {c}: keys {:?}, {} samples, handler cycles mean {:.1} worst {} ({:.1} % of the period), misses {}{}",
                map.cores.get(c).map(|m| m.keys.clone()).unwrap_or_default(),
                runs[c],
                total[c] as f64 / runs[c].max(1) as f64,
                worst[c],
                100.0 * worst[c] as f64 / image.cycles_per_sample().max(1) as f64,
                misses[c],
                crate::fault::unfinished_text(run.unfinished().get(c).copied().unwrap_or(0)),
            ));
        }
        let board = run.board();
        lines.push(format!(
            "final cycles: core 0 {}, core 1 {}",
            board.cores[0].cycle, board.cores[1].cycle
        ));
        lines.push(format!(
            "DAC codes at the end: {dac:?}; digest of every sample's codes {digest:016x}"
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
        let fs = f64::from(map.sample_rate_hz);
        lines
            .extend((resets.iter()).map(|r| format!("reset: {}", crate::fault::reset_text(r, fs))));
        let faults = BoardFaults {
            board: map.board,
            cores: records,
            slots: crate::fault::image_slots(
                image,
                &map.keys.iter().map(|k| k.midi).collect::<Vec<_>>(),
            ),
            resets: resets.clone(),
        };
        if faults.boot_line().is_none() {
            // No reset the board booted again from: the run's own power-on (the fault
            // report says the boot after a reset).
            if let Some(w) = faults.cores.first() {
                lines.push(format!(
                    "boot: its firmware recorded its boot from {} (reset word {:#010x})",
                    w.reset_cause().text(),
                    w.reset_word
                ));
            }
        }
        lines.extend(crate::fault::report_lines(
            std::slice::from_ref(&faults),
            f64::from(map.sample_rate_hz),
        ));
        let trips = faults.trips();
        let false_alarm = (self.faults.is_empty() && (trips > 0 || !resets.is_empty())).then(|| {
            format!(
                "with no fault injected the firmware's checks tripped {trips} times and the board reset {} times: a false alarm",
                resets.len()
            )
        });
        let missed = self.faults.is_empty() && misses.iter().any(|&m| m > 0);
        let warnings = (self.resting_hangs().iter())
            .map(crate::fault::RestingHang::warning)
            .collect();
        Ok(FirmwareText {
            lines,
            missed,
            faults,
            resets,
            false_alarm,
            warnings,
        })
    }

    /// The hangs injected on keys that the stimulus leaves standing still when the hang
    /// begins ([`crate::fault::RestingHang::of`]), on keys whose program runs with the
    /// quiescent-key guard; times are the run's. A key's first sensor follows the stimulus
    /// (repeated), so it next moves at the first sample whose word differs from the one
    /// before.
    pub fn resting_hangs(&self) -> Vec<crate::fault::RestingHang> {
        let (specs, programs) = (self.image.keys(), self.image.programs());
        let fs = f64::from(self.map.sample_rate_hz);
        let end = self.samples as u64;
        let mut out = Vec::new();
        for (spec, inj) in &self.faults {
            let Some(k) = inj
                .key
                .filter(|_| inj.kind == FaultKind::Hang && inj.from < end)
            else {
                continue;
            };
            let (Some(key), Some(program)) =
                (self.map.keys.get(k), specs.get(k).map(|s| s.program))
            else {
                continue;
            };
            if programs[program].guard_words().is_none() {
                continue;
            }
            let until = inj.until.unwrap_or(end).min(end);
            let w = &self.words[program];
            let at = |n: u64| w[(n % w.len() as u64) as usize];
            let next = match w.is_empty() {
                true => None,
                false => (inj.from.max(1)..until).find(|&n| at(n) != at(n - 1)),
            };
            let next_s = next.map_or(f64::INFINITY, |n| n as f64 / fs);
            out.extend(crate::fault::RestingHang::of(
                &spec.text,
                key.midi,
                inj.from as f64 / fs,
                until as f64 / fs,
                next_s,
                fs,
            ));
        }
        out
    }
}
