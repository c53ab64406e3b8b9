//! `tactus build`: compile an instrument to firmware sources.
//!
//! `--target c` (the default) writes `DIR/<name>.h` and `DIR/<name>.c`: portable C99 with
//! the fixed-point bits of the fixed interpreter (see `tactus_compiler::cgen`).
//!
//! `--target rp2040` on one instrument writes `DIR/<name>.o` (an ARM ELF relocatable object
//! for the Cortex-M0+, from `tactus_compiler::thumb`), `DIR/<name>.h` (the same interface
//! header as the C target: state struct, prototypes, Q-formats and units) and
//! `DIR/<name>.s` (a GNU assembler listing that `arm-none-eabi-as -mcpu=cortex-m0plus`
//! assembles to the same bytes).
//!
//! `--target rp2040` on a keyboard — a layout (`.toml`), or an instrument with `--keys N` —
//! writes flashable firmware per board (the layout's boards, or planned as `tactus budget`
//! plans them): `DIR/board-NN/firmware.elf`, `firmware.uf2`, `keys.json` and `README.md`
//! (`tactus_firmware::flash`): a flash image that boots at power-on, or with `--ram` a
//! RAM-only image for development.

use crate::check_cmd::{compile_reporting, parse_override};
use crate::progress::StageBar;
use crate::source;
use std::path::PathBuf;
use std::process::ExitCode;
use tactus_host::build;
use tactus_host::keyboard::{self, KeyboardSpec};

/// Arguments of `tactus build`.
#[derive(Debug, clap::Args)]
#[command(after_long_help = "\
Examples:
  tactus build grand_piano -o out/c                                    # C99 sources
  tactus build grand_piano --target rp2040 -o out/obj                  # Thumb object, header, listing
  tactus build instruments/layouts/grand88.toml --target rp2040 -o out/grand88   # firmware per board
  tactus build instruments/hammond.tactus --keys 61 --target rp2040 -o out/organ

  tactus build instruments/layouts/grand88.toml --target rp2040 --board rp2040_200mhz -o out/g200

Firmware per board: for a layout (or an instrument on --keys N keys), each board — the
layout's [[board]]s, or the fewest that fit, planned as `tactus budget` plans them — gets a
directory board-NN/ with firmware.uf2 (for the RP2040 boot ROM: hold BOOTSEL, plug in, copy
it onto the RPI-RP2 drive; it is written to flash and boots at every power-on: boot2, then
the image copies itself to SRAM and runs from there), firmware.elf (the same image, for a
debugger or `tactus emu run`, which boots it through the emulated boot ROM), keys.json (each
key's MIDI number, instrument, core, sensor and DAC word addresses) and README.md. With
--ram, the UF2 and ELF are RAM-only instead (loaded straight into SRAM, gone at power-off).
A board file above 133 MHz needs its core voltage (`core_voltage_v = 1.15` for 200 MHz):
the firmware raises it before the PLL. The sensor and DAC words are memory locations a
converter driver (or DMA, or PIO) must fill and drain; the firmware contains no ADC/DAC
driver.")]
pub struct BuildArgs {
    /// Instrument file (`instruments/grand_piano.tactus`), built-in name (`grand_piano`),
    /// or keyboard layout (`instruments/layouts/grand88.toml`, rp2040 target only).
    pub file: String,
    /// What to generate: `c` (portable C99 sources) or `rp2040` (Thumb ELF object, header
    /// and assembler listing for the Cortex-M0+).
    #[arg(long, value_enum, default_value = "c")]
    pub target: Target,
    /// Output directory, created if missing; receives `<name>.h` and `<name>.c` (or `.o`,
    /// `.h` and `.s` for rp2040).
    #[arg(short = 'o', long = "out-dir", value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
    /// Override a param: `--param k=200 N/m` (repeatable; the unit must match the param's).
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_override)]
    pub params: Vec<(String, String)>,
    /// Firmware for N keys of the instrument (from A0 up), per board, instead of its object
    /// file (rp2040 target).
    #[arg(long, value_name = "N")]
    pub keys: Option<u32>,
    /// Board file or built-in board (`rp2040`, `rp2040_200mhz`, `rp2040_20mhz`; with
    /// converters `rp2040_io`, `rp2040_io_200mhz`) for
    /// firmware; default: the layout's, else `rp2040`.
    #[arg(long, value_name = "NAME_OR_FILE")]
    pub board: Option<String>,
    /// Firmware that lives in SRAM only (a RAM UF2 and ELF, for development: gone at
    /// power-off) instead of a flash image that boots at power-on.
    #[arg(long)]
    pub ram: bool,
    /// Firmware: the per-key sensor check (range and largest step per sample, and on a
    /// converter board the ADC's burst check; a trip setting the motors to zero force and
    /// the core's fault word: docs/faults.md)
    /// `on` or `off` on every key, the boards planned and priced with it [default: on,
    /// the firmware's own].
    #[arg(long, value_name = "on|off", value_parser = crate::play_cmd::parse_on_off)]
    pub sensor_check: Option<bool>,
    /// Firmware: the RP2040's watchdog (datasheet 4.7) `on` or `off` on every board, fed
    /// by core 0 only when both cores finished their sample, so that a hung core resets the
    /// board with its motors at zero force (docs/faults.md); the boards planned and priced
    /// with its feed [default: the firmware's own].
    #[arg(long, value_name = "on|off", value_parser = crate::play_cmd::parse_on_off)]
    pub watchdog: Option<bool>,
}

/// Code generation targets.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Target {
    /// Portable C99 (`<stdint.h>` only), bit-exact with `tactus sim --numeric fixed`.
    C,
    /// ARMv6-M Thumb machine code for the RP2040's Cortex-M0+ cores, bit-exact too.
    Rp2040,
}

/// Runs `tactus build`.
pub fn run(args: BuildArgs) -> ExitCode {
    match build(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(Some(e)) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
        // Diagnostics already printed.
        Err(None) => ExitCode::FAILURE,
    }
}

fn build(args: &BuildArgs) -> Result<(), Option<String>> {
    let Some(dir) = &args.out_dir else {
        return Err(Some(format!(
            "{}: `tactus build` needs an output directory: -o DIR",
            args.file
        )));
    };
    let is_keyboard = keyboard::is_layout(&args.file) || args.keys.is_some();
    if is_keyboard {
        if args.target != Target::Rp2040 {
            return Err(Some(format!(
                "{}: a keyboard (a layout, or --keys) builds firmware per board: use --target rp2040",
                args.file
            )));
        }
        return build_firmware(args, dir);
    }
    if args.board.is_some() || args.ram || args.sensor_check.is_some() || args.watchdog.is_some() {
        return Err(Some(format!(
            "{}: --board, --ram, --sensor-check and --watchdog are for firmware (a layout, or an instrument with --keys N)",
            args.file
        )));
    }
    let src = source::load(&args.file).map_err(Some)?;
    let lowered = compile_reporting(&src, &args.params, tactus_runtime::DEFAULT_SAMPLE_RATE_HZ)
        .ok_or(None)?;
    let target = match args.target {
        Target::C => build::Target::C,
        Target::Rp2040 => build::Target::Rp2040,
    };
    let line = build::build_instrument(
        &src,
        &lowered.program,
        &args.params,
        target,
        dir,
        &mut source::report,
    )?;
    println!("{line}");
    Ok(())
}

/// Firmware per board of a keyboard (see the module documentation).
fn build_firmware(args: &BuildArgs, dir: &std::path::Path) -> Result<(), Option<String>> {
    let mut kb = keyboard::compile(
        &KeyboardSpec {
            input: &args.file,
            as_layout: None,
            board: args.board.as_deref(),
            keys: args.keys,
            params: &args.params,
        },
        &mut source::report_compile,
    )
    .map_err(|e| Some(e.to_string()))?;
    kb.sensor_check = args.sensor_check;
    kb.watchdog = args.watchdog;
    let command: Vec<String> = std::env::args().skip(1).collect();
    let command = format!("tactus {}", command.join(" "));
    let bar = StageBar::new();
    let lines = build::build_firmware(
        &args.file,
        &kb,
        args.ram,
        &command,
        dir,
        &mut |stage, done, total| bar.update(stage, done, total),
    )?;
    bar.finish();
    for line in lines {
        println!("{line}");
    }
    Ok(())
}
