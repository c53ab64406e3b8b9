//! `tactus emu …`: run ELF files on the emulated RP2040 (owned by the emulator work, issue 4).
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
        /// ELF executable (ARM, Thumb) to load. Core 0 starts from its vector table
        /// (`.vectors` section) or else at its entry point with SP at the top of SRAM.
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
    },
}

/// Runs an `emu` subcommand; returns the process exit code (1 for an unloadable file, 2
/// when the firmware faults or locks up).
pub fn run(cmd: EmuCommand) -> ExitCode {
    let EmuCommand::Run {
        file,
        cycles,
        trace,
        profile,
    } = cmd;
    let bytes = match std::fs::read(&file) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("error: cannot read {}: {e}", file.display());
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
    let stop = if trace {
        run_traced(&mut board, cycles)
    } else {
        board.run_for(cycles)
    };
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
        StopReason::Fault { core, fault } => {
            eprintln!("error: {}: core {core} HardFault: {fault}", file.display());
            ExitCode::from(2)
        }
        StopReason::Lockup { core, fault } => {
            eprintln!("error: {}: core {core} locked up: {fault}", file.display());
            ExitCode::from(2)
        }
    }
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
