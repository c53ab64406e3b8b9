//! `tactus emu …`: run ELF files on the emulated RP2040 (owned by the emulator work, issue 4).
//!
//! With `--stimulus`, the ELF is firmware from `tactus build … --target rp2040` and its key
//! map (`keys.json` beside it) says which keys it runs: the board's image is rebuilt from
//! the key maps of its keyboard and checked to be the ELF byte for byte, then the ELF boots
//! from reset and runs sample by sample as `tactus play` runs every board (converters
//! included), every key following the stimulus, with `--fault`s injected; the command
//! prints per core the handler's worst and mean cycles and the misses, the resets and the
//! fault words (`tactus_host::emu::FirmwareJob`).
//!
//! The only place the emulator's results are printed: the library returns values, this
//! module formats them.

use std::path::Path;
use std::process::ExitCode;
use tactus_host::emu;

/// Subcommands of `tactus emu`.
#[derive(Debug, clap::Subcommand)]
pub enum EmuCommand {
    /// Run an ELF file on the emulated dual-core RP2040 and print each core's registers
    /// and cycle count.
    #[command(after_long_help = RUN_EXAMPLES)]
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
        /// With `--stimulus`: inject a fault (repeatable), in `tactus play --fault`'s syntax:
        /// `kind=open|short|stuck|jump|noise` on a key (`note=MIDI`, or `board=N,key=K`: N
        /// this firmware's board, its keys.json's `board`; K from 0 in its key order),
        /// `kind=hang` (that key's update alone never returns) or `kind=flip` (`word=`, `bit=`) on a key,
        /// `kind=adc-silent|dac-stall` on `board=N,core=C`, `kind=brownout` on `board=N`;
        /// `at=TIME` and optionally `until=TIME` (`1.5s`, `200ms`), and the kind's value
        /// (`code=`, `delta=`, `amplitude=`). On plain and converter boards alike. After the
        /// run the board's resets and fault words are printed (kind, key, time, trips):
        /// docs/faults.md.
        #[arg(long = "fault", value_name = "FAULT", value_parser = crate::play_cmd::parse_fault, requires = "stimulus")]
        fault: Vec<tactus_host::fault::FaultSpec>,
        /// Serve GDB on 127.0.0.1:PORT and wait for it before running (0: any free port,
        /// printed; with `--stimulus` the firmware is attached at its first sample tick).
        /// Both cores are threads; breakpoints, watchpoints, stepping and `monitor cycles`
        /// leave every cycle count as it is (docs/firmware.md).
        #[arg(long, value_name = "PORT")]
        gdb: Option<u16>,
    },
}

/// `tactus emu run --help`'s examples.
const RUN_EXAMPLES: &str = "Examples:
  tactus build grand88 --target rp2040 -o fw
  tactus emu run fw/board-05/firmware.elf --stimulus mf-dip --seconds 0.5
      every key of board 5 dipping mezzoforte: each core's cycles and misses, the fault words
  tactus emu run fw/board-05/firmware.elf --stimulus mf-dip --seconds 0.5 \\
      --fault kind=short,note=60,at=0.2s,until=0.3s
      key 60's sensor wire shorted (the ADC's full scale) from 0.2 s to 0.3 s: the report names
      the check that tripped (sensor-range), the key, the sample and the trips
  tactus emu run fw/board-05/firmware.elf --stimulus pp-dip --fault kind=noise,amplitude=2000,board=5,key=3,at=0.1s
  tactus emu run fw/board-05/firmware.elf --stimulus mf-dip --fault kind=hang,note=60,at=0.1s
      key 60's update never returns (the other keys' calls of the same code do): with the
      watchdog on, the board resets within 1 ms (printed, with the samples at zero force
      until it runs again) and the fault word of key 60's core says `watchdog`
  tactus build grand88 --target rp2040 --board rp2040_io -o fw-io
  tactus emu run fw-io/board-05/firmware.elf --stimulus mf-dip --fault kind=adc-silent,board=5,core=1,at=0.1s

The firmware is rebuilt from the key maps of its keyboard (its keys.json and those of the
board-NN directories beside it) and must be that build byte for byte: firmware from another
version of tactus is refused (build it again).

A bad --fault names its field: `--fault kind=open,note=200,at=1s` → field `note`: 200 is
outside 0–127 (exit 2, nothing run). Exit status: 0; 1 for a file, key map or fault the
firmware cannot take; 2 for a bad argument, or when the firmware faults, or with no
--fault misses a deadline, trips its checks or resets (a false alarm).";

/// Waits on 127.0.0.1:`port` for one GDB client ([`emu::wait_for_gdb`]), saying where on
/// stderr.
fn wait_for_gdb(port: u16) -> Result<Box<dyn tactus_emulator::Debugger>, String> {
    emu::wait_for_gdb(
        port,
        &mut |line| eprintln!("tactus emu: {line}"),
        Box::new(|line| eprintln!("tactus emu: {line}")),
    )
}

/// Runs an `emu` subcommand; returns the process exit code (1 for an unloadable file, 2
/// when the firmware faults or locks up, or with `--stimulus` and no `--fault` misses a
/// deadline, trips a fault check or resets).
pub fn run(cmd: EmuCommand) -> ExitCode {
    let EmuCommand::Run {
        file,
        cycles,
        trace,
        profile,
        stimulus,
        keys,
        seconds,
        fault,
        gdb,
    } = cmd;
    let result = match stimulus {
        Some(stimulus) => run_firmware(&file, &stimulus, keys.as_deref(), seconds, &fault, gdb),
        None => run_elf(&file, cycles, trace, &profile, gdb),
    };
    result.unwrap_or_else(|e| {
        eprintln!("error: {e}");
        ExitCode::FAILURE
    })
}

/// `tactus emu run FILE`: the ELF on a board for `cycles` cycles ([`emu::ElfJob`]), then
/// every core, every profiled function and why it stopped.
fn run_elf(
    file: &Path,
    cycles: u64,
    trace: bool,
    profile: &[String],
    gdb: Option<u16>,
) -> Result<ExitCode, String> {
    let job = emu::ElfJob::new(file, profile)?;
    let debugger = gdb.map(wait_for_gdb).transpose()?;
    let mut print = |l: String| println!("{l}");
    let run = job.run(cycles, debugger, trace.then_some(&mut print as _));
    for line in &run.lines {
        println!("{line}");
    }
    match run.ok {
        true => {
            println!("{}", run.stop);
            Ok(ExitCode::SUCCESS)
        }
        false => {
            eprintln!("error: {}", run.stop);
            Ok(ExitCode::from(2))
        }
    }
}

/// `tactus emu run FIRMWARE.elf --stimulus S [--fault F]`: see the module documentation.
/// Exit code 0; 2 with no fault injected and misses, trips or resets.
fn run_firmware(
    file: &Path,
    stimulus: &str,
    keys: Option<&Path>,
    seconds: f64,
    faults: &[tactus_host::fault::FaultSpec],
    gdb: Option<u16>,
) -> Result<ExitCode, String> {
    let job = emu::FirmwareJob::new(
        file,
        stimulus,
        keys,
        seconds,
        faults,
        &mut crate::source::report_compile,
    )?;
    let debugger = gdb.map(wait_for_gdb).transpose()?;
    let bar = match debugger {
        Some(_) => indicatif::ProgressBar::hidden(),
        None => indicatif::ProgressBar::new(job.samples as u64),
    };
    let run = job.run(debugger, &mut |d, _| bar.set_position(d as u64))?;
    bar.finish_and_clear();
    for line in &run.lines {
        println!("{line}");
    }
    run.warnings.iter().for_each(|w| eprintln!("warning: {w}"));
    if let Some(e) = &run.false_alarm {
        eprintln!("error: {e}");
    }
    Ok(match run.missed || run.false_alarm.is_some() {
        true => ExitCode::from(2),
        false => ExitCode::SUCCESS,
    })
}
