//! `tactus emu …`: run ELF files on the emulated RP2040 (owned by the emulator work, issue 4).
//!
//! With `--stimulus`, the ELF is firmware from `tactus build … --target rp2040` and its key
//! map (`keys.json` beside it) says where each key's sensor word is: the firmware boots
//! from reset (core 0 launches core 1 over the FIFOs), every key follows the stimulus, and
//! the command prints per core the handler's worst and mean cycles and the misses
//! (`tactus_firmware::flash::run_elf`).
//!
//! The only place the emulator's results are printed: the library returns values, this
//! module formats them.

use std::process::ExitCode;
use tactus_emulator::core::{Core, RunState};
use tactus_emulator::{Board, Config, StopReason};

/// Subcommands of `tactus emu`.
#[derive(Debug, clap::Subcommand)]
pub enum EmuCommand {
    /// Run an ELF file on the emulated dual-core RP2040 and print each core's registers
    /// and cycle count.
    Run {
        /// ELF executable (ARM, Thumb) to load. An image with a `.boot2` section (flash
        /// firmware from `tactus build`, pico-sdk binaries) boots from flash through the
        /// emulated boot ROM (boot2's CRC checked); otherwise core 0 starts from its vector
        /// table (`.vectors` section) or else at its entry point with SP at the top of SRAM.
        file: std::path::PathBuf,
        /// Stop after this many cycles (133 MHz: 133 000 000 cycles = 1 s).
        #[arg(long, default_value_t = 10_000_000)]
        cycles: u64,
        /// Print every instruction with its core, start cycle and cycle cost.
        #[arg(long)]
        trace: bool,
        /// Count the cycles of every call of this function (entry to return); repeatable.
        #[arg(long, value_name = "SYMBOL")]
        profile: Vec<String>,
        /// Run firmware built by `tactus build LAYOUT --target rp2040` with every key
        /// following this stimulus: a built-in (`mf-dip`, `pp-dip`, …: `tactus sim --help`)
        /// or a CSV file (`key_mm` or `time_s,key_mm`), repeated to `--seconds`.
        #[arg(long, value_name = "NAME_OR_CSV")]
        stimulus: Option<String>,
        /// The firmware's key map (default: `keys.json` beside the ELF).
        #[arg(long, value_name = "FILE")]
        keys: Option<std::path::PathBuf>,
        /// Emulated seconds to run with `--stimulus` (at most 60).
        #[arg(long, default_value_t = 1.0)]
        seconds: f64,
        /// Serve GDB on 127.0.0.1:PORT and wait for it before running (0: any free port,
        /// printed). Both cores are threads; breakpoints, watchpoints, stepping and
        /// `monitor cycles` leave every cycle count as it is (docs/firmware.md).
        #[arg(long, value_name = "PORT")]
        gdb: Option<u16>,
    },
}

/// Listens on 127.0.0.1:`port` and waits for one GDB client.
fn wait_for_gdb(port: u16) -> Result<Box<dyn tactus_emulator::debug::Debugger>, String> {
    use tactus_emulator::debug::gdb;
    let listener = gdb::listen(port).map_err(|e| format!("--gdb {port}: cannot listen: {e}"))?;
    let addr = listener
        .local_addr()
        .map_err(|e| format!("--gdb {port}: {e}"))?;
    eprintln!("tactus emu: waiting for gdb on {addr} (in gdb: target remote {addr})");
    let (conn, peer) = listener
        .accept()
        .map_err(|e| format!("--gdb {port}: {e}"))?;
    eprintln!("tactus emu: gdb connected from {peer}");
    Ok(Box::new(gdb::GdbSession::new(
        conn,
        Box::new(|line| eprintln!("tactus emu: {line}")),
    )))
}

/// Runs an `emu` subcommand; returns the process exit code (1 for an unloadable file, 2
/// when the firmware faults or locks up).
pub fn run(cmd: EmuCommand) -> ExitCode {
    let EmuCommand::Run {
        file,
        cycles,
        trace,
        profile,
        stimulus,
        keys,
        seconds,
        gdb,
    } = cmd;
    if let Some(stimulus) = stimulus {
        return match run_firmware(&file, &stimulus, keys.as_deref(), seconds, gdb) {
            Ok(code) => code,
            Err(e) => {
                eprintln!("error: {e}");
                ExitCode::FAILURE
            }
        };
    }
    let bytes = match read_elf(&file) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let mut board = Board::new(Config::default());
    if let Err(e) = board.load_elf(&bytes) {
        eprintln!("error: cannot load {}: {e}", file.display());
        return ExitCode::FAILURE;
    }
    let mut profiles = Vec::new();
    for name in &profile {
        match board.profile(name) {
            Ok(handle) => profiles.push((name, handle)),
            Err(e) => {
                eprintln!("error: {}: {e}", file.display());
                return ExitCode::FAILURE;
            }
        }
    }
    if let Some(port) = gdb {
        match wait_for_gdb(port) {
            Ok(d) => board.attach_debugger(d),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    let stop = if trace {
        run_traced(&mut board, cycles)
    } else {
        board.run_for(cycles)
    };
    board.finish_debugging();
    for core in &board.cores {
        print_core(core);
    }
    for (name, handle) in profiles {
        let calls = board.calls(handle);
        let cycles: Vec<u64> = calls.iter().map(|c| c.cycles).collect();
        match (cycles.iter().min(), cycles.iter().max()) {
            (Some(min), Some(max)) => {
                let mean = cycles.iter().sum::<u64>() as f64 / cycles.len() as f64;
                println!(
                    "{name}: {} calls, cycles min {min} mean {mean:.1} max {max}",
                    cycles.len()
                );
            }
            _ => println!("{name}: no completed calls"),
        }
    }
    match stop {
        StopReason::CycleLimit => {
            println!("stopped: cycle limit {cycles} reached");
            ExitCode::SUCCESS
        }
        StopReason::Idle => {
            println!("stopped: no core running");
            ExitCode::SUCCESS
        }
        StopReason::Svc { core, imm } => {
            println!("stopped: core {core} executed svc #{imm}");
            ExitCode::SUCCESS
        }
        StopReason::Fault { .. } => {
            eprintln!("error: {}: {}", file.display(), board.describe_stop(&stop));
            ExitCode::from(2)
        }
        StopReason::Lockup { .. } | StopReason::Refused { .. } => {
            eprintln!("error: {}: {}", file.display(), board.describe_stop(&stop));
            ExitCode::from(2)
        }
    }
}

/// The largest ELF file read, bytes: every memory an ELF may load into (ROM, 2 MB of
/// flash, SRAM) is far smaller; a bound on what a mistaken path (`/dev/zero`) can make the
/// command hold.
const MAX_ELF_BYTES: u64 = 64 << 20;

/// Reads an ELF file of at most [`MAX_ELF_BYTES`]; errors name the file.
fn read_elf(path: &std::path::Path) -> Result<Vec<u8>, String> {
    use std::io::Read;
    let f =
        std::fs::File::open(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let mut bytes = Vec::new();
    f.take(MAX_ELF_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    if bytes.len() as u64 > MAX_ELF_BYTES {
        return Err(format!(
            "{}: longer than {MAX_ELF_BYTES} bytes, not firmware for the RP2040",
            path.display()
        ));
    }
    Ok(bytes)
}

fn run_traced(board: &mut Board, cycles: u64) -> StopReason {
    let limit = board.cycle().saturating_add(cycles);
    loop {
        let before = [board.cores[0].cycle, board.cores[1].cycle];
        let before_count = [board.cores[0].instructions, board.cores[1].instructions];
        match board.step(limit) {
            None => return StopReason::CycleLimit,
            Some(result) => {
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
                        println!(
                            "core{k} {:>10} {:08x} {:<20} {:<28} {} cycles",
                            before[k],
                            last.pc,
                            func,
                            last.instr.to_string(),
                            last.cycles
                        );
                    }
                } else if core.cycle != before[k] {
                    let what = if matches!(core.state, RunState::Sleeping { .. }) {
                        "sleep"
                    } else {
                        "exception entry"
                    };
                    println!(
                        "core{k} {:>10} {what} ({} cycles)",
                        before[k],
                        core.cycle - before[k]
                    );
                }
                if let Err(stop) = result {
                    return stop;
                }
            }
        }
    }
}

fn print_core(core: &Core) {
    let state = match core.state {
        RunState::Running => "running",
        RunState::Sleeping { wfe: false } => "sleeping (WFI)",
        RunState::Sleeping { wfe: true } => "sleeping (WFE)",
        RunState::Parked => "parked",
        RunState::Lockup => "locked up",
    };
    println!(
        "core {}: {state}, {} cycles, {} instructions",
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
        println!("  {}", regs.join("  "));
    }
    let flag = |b: bool, c: char| if b { c.to_ascii_uppercase() } else { c };
    println!(
        "  xpsr={:08x} [{}{}{}{}] primask={} ipsr={}",
        core.xpsr(),
        flag(core.n, 'n'),
        flag(core.z, 'z'),
        flag(core.c, 'c'),
        flag(core.v, 'v'),
        core.primask as u8,
        core.ipsr
    );
}

/// `tactus emu run FIRMWARE.elf --stimulus S`: see the module documentation. Exit code 0
/// without misses, 2 with.
fn run_firmware(
    file: &std::path::Path,
    stimulus: &str,
    keys: Option<&std::path::Path>,
    seconds: f64,
    gdb: Option<u16>,
) -> Result<ExitCode, String> {
    use tactus_firmware::flash::{self, KeyMap};
    let elf = read_elf(file)?;
    let map_path = keys.map_or_else(
        || file.with_file_name("keys.json"),
        std::path::Path::to_path_buf,
    );
    let text = tactus_runtime::keyboard::read_text(&map_path).map_err(|e| {
        format!(
            "{}: cannot read the key map ({e}); `tactus build LAYOUT --target rp2040` writes it beside the ELF, or name it with --keys",
            file.display()
        )
    })?;
    let map: KeyMap = serde_json::from_str(&text)
        .map_err(|e| format!("{}: not a Tactus key map: {e}", map_path.display()))?;
    if !(seconds > 0.0 && seconds <= 60.0) {
        return Err(format!("--seconds {seconds}: from just above 0 to 60"));
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
    let (words, which) = tactus_host::keyboard::key_map_sensor_words(
        &map,
        &map_path.display().to_string(),
        stimulus,
        samples,
        &mut crate::source::report_compile,
    )?;
    let sensors: Vec<&[i32]> = which.iter().map(|&i| words[i].as_slice()).collect();
    let debugger = gdb.map(wait_for_gdb).transpose()?;
    let bar = if debugger.is_some() {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new(samples as u64)
    };
    let run = flash::run_elf(
        &elf,
        &map,
        &sensors,
        samples,
        &mut |d, _| bar.set_position(d as u64),
        debugger,
    )
    .map_err(|e| format!("{}: {e}", file.display()))?;
    bar.finish_and_clear();
    println!(
        "{}: board {} ({} keys), {} samples of `{stimulus}` at {} Hz, {} cycles per sample",
        file.display(),
        map.board,
        map.keys.len(),
        run.samples,
        map.sample_rate_hz,
        run.cycles_per_sample
    );
    for (c, core) in run.cores.iter().enumerate() {
        println!(
            "core {c}: keys {:?}, {} samples, handler cycles mean {:.1} worst {} ({:.1} % of the period), misses {}",
            map.cores.get(c).map(|m| m.keys.clone()).unwrap_or_default(),
            core.samples,
            core.mean_cycles,
            core.worst_cycles,
            100.0 * core.worst_cycles as f64 / run.cycles_per_sample.max(1) as f64,
            core.misses
        );
    }
    println!(
        "final cycles: core 0 {}, core 1 {}",
        run.final_cycles[0], run.final_cycles[1]
    );
    println!(
        "DAC words at the end: {:08x?}; digest of every sample's words {:016x}",
        run.dac_final, run.dac_digest
    );
    let missed = run.cores.iter().any(|c| c.misses > 0);
    Ok(if missed {
        ExitCode::from(2)
    } else {
        ExitCode::SUCCESS
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A minimal ARM ELF32 executable with `code` (halfwords) at 0x20000000.
    fn elf(code: &[u16]) -> Vec<u8> {
        let code: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
        let mut f = vec![0x7f, b'E', b'L', b'F', 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0];
        for v in [2u16, 40] {
            f.extend(v.to_le_bytes()); // ET_EXEC, EM_ARM
        }
        for v in [1u32, 0x2000_0001, 52, 0, 0x0500_0000] {
            f.extend(v.to_le_bytes()); // version, entry, phoff, shoff, flags
        }
        for v in [52u16, 32, 1, 40, 0, 0] {
            f.extend(v.to_le_bytes());
        }
        let n = code.len() as u32;
        for v in [1u32, 84, 0x2000_0000, 0x2000_0000, n, n, 5, 4] {
            f.extend(v.to_le_bytes()); // PT_LOAD
        }
        f.extend(code);
        f
    }

    fn run_file(name: &str, bytes: Option<&[u8]>, trace: bool) -> ExitCode {
        let path =
            std::env::temp_dir().join(format!("tactus-emu-cli-{}-{name}", std::process::id()));
        if let Some(b) = bytes {
            std::fs::write(&path, b).unwrap();
        }
        run(EmuCommand::Run {
            file: path,
            cycles: 1000,
            trace,
            profile: Vec::new(),
            stimulus: None,
            keys: None,
            seconds: 1.0,
            gdb: None,
        })
    }

    #[test]
    fn runs_to_the_cycle_limit() {
        // movs r0, #42; b .
        assert_eq!(
            run_file("ok.elf", Some(&elf(&[0x202a, 0xe7fe])), false),
            ExitCode::SUCCESS
        );
        assert_eq!(
            run_file("trace.elf", Some(&elf(&[0x202a, 0xe7fe])), true),
            ExitCode::SUCCESS
        );
    }

    #[test]
    fn unknown_profile_symbol_exits_1() {
        let path =
            std::env::temp_dir().join(format!("tactus-emu-cli-{}-prof.elf", std::process::id()));
        std::fs::write(&path, elf(&[0xe7fe])).unwrap();
        let cmd = EmuCommand::Run {
            file: path,
            cycles: 10,
            trace: false,
            profile: vec!["main".into()],
            stimulus: None,
            keys: None,
            seconds: 1.0,
            gdb: None,
        };
        assert_eq!(run(cmd), ExitCode::FAILURE);
    }

    #[test]
    fn unloadable_files_exit_1() {
        assert_eq!(run_file("missing.elf", None, false), ExitCode::FAILURE);
        assert_eq!(
            run_file("text.elf", Some(b"not an elf"), false),
            ExitCode::FAILURE
        );
        let good = elf(&[0xe7fe]);
        assert_eq!(
            run_file("short.elf", Some(&good[..60]), false),
            ExitCode::FAILURE
        );
    }

    #[test]
    fn firmware_faults_exit_2() {
        // udf #0
        assert_eq!(
            run_file("udf.elf", Some(&elf(&[0xde00])), false),
            ExitCode::from(2)
        );
        // bx r0 with r0 = 0 (even): ARM state
        assert_eq!(
            run_file("bx.elf", Some(&elf(&[0x4700])), true),
            ExitCode::from(2)
        );
    }
}
