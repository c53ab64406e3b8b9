//! `tactus budget`: does a keyboard fit its boards, and how few boards does it need?
//!
//! The command resolves the input (a layout, or one instrument on `--keys` keys) with
//! `tactus_host::keyboard::compile`, printing each program's diagnostics, and hands the
//! keyboard to `tactus_host::budget::budget` (its boards planned once, or the layout's own
//! checked, by the static analysis of each board's sample interrupt; its programs measured),
//! which returns the report; this module prints it (text or `--json`) and has
//! `--write-plan` written (`tactus_host::budget::write_plan`).
//!
//! Exit codes: 0 fits; 1 does not fit (or measured > static, an analysis bug); 2 bad input.

use crate::check_cmd::parse_override;
use crate::progress::StageBar;
use crate::source;
use std::path::PathBuf;
use std::process::ExitCode;
use tactus_host::budget;
use tactus_host::keyboard::{self, KeyboardSpec};

/// Arguments of `tactus budget`.
#[derive(Debug, clap::Args)]
#[command(after_long_help = "\
Examples:
  tactus budget instruments/layouts/grand88.toml
  tactus budget instruments/layouts/grand88.toml --board rp2040_200mhz --write-plan out/grand88-boards.toml
  tactus budget grand_piano --keys 12
  tactus budget harpsichord --keys 88 --json > budget.json

A keyboard is a set of boards, each a microcontroller with a few keys (each key with its
own motor driver and converter channels); the sample deadline holds per board, on its
cores. A layout may list its boards ([[board]] keys = [21, 28], contiguous key ranges);
otherwise Tactus plans the fewest: a greedy sweep along the keyboard giving each board as
many keys as still fit, which is optimal because any sub-range of a fitting range fits.

How to read it: `static` is the proven worst case of one key's update (cycles per
key-sample, call included); `glue` the key's share of the sample interrupt (sensor copy,
call set-up, safety limiter, DAC store); `measured` the worst and mean of the update over
the stimulus corpus in the emulator (always ≤ static, else the analysis has a bug). Per
board, per core: the static bound of that core's whole sample interrupt as the firmware
image lays it out (entry, tick, every key's glue and update, window contention, return)
against the cycles of the shortest interval between two sample ticks (each core's SysTick
ticks every ⌊clock/fs⌋ cycles or one more, exactly fs times a second: 3,015 cycles at
133 MHz and 44.1 kHz, whose mean period is 3,015.87), its utilisation and headroom.
`what fits` is the most keys of each instrument one board holds. The costliest param set
of each instrument is measured over the full corpus (presses, repeated notes, trills, half
dips, noise, glitches, random words), its other param sets over a brief one; `--quick`
shrinks the full one (the static figures and the verdict do not change).

Exit codes: 0 fits, 1 does not fit (or measured > static), 2 bad input.")]
pub struct BudgetArgs {
    /// A layout (`instruments/layouts/grand88.toml`: which instrument on which keys, and
    /// optionally on which boards; or a built-in layout's name: `grand88`,
    /// `split_harpsichord_piano`), or one instrument (file or built-in name, e.g.
    /// `grand_piano`) on `--keys` keys.
    pub input: String,
    /// The board kind: a built-in name (`rp2040`, `rp2040_200mhz`, `rp2040_20mhz`; with
    /// converters `rp2040_io`, `rp2040_io_200mhz`) or a board TOML file (name, clock_hz,
    /// cores, sample_rate_hz, an optional `[converters]`). Default: the layout's
    /// `board_kind`, else rp2040.
    #[arg(long, value_name = "NAME_OR_FILE")]
    pub board: Option<String>,
    /// For a single instrument: how many keys (identical copies; default 88, a pen 1), from
    /// MIDI 21 (A0) up.
    #[arg(long, value_name = "N")]
    pub keys: Option<u32>,
    /// Override a param of every key: `--param M_h=8 g` (repeatable; after the layout's own).
    #[arg(long = "param", value_name = "NAME=VALUE", value_parser = parse_override)]
    pub params: Vec<(String, String)>,
    /// Print the result as one JSON document on stdout instead of the tables.
    #[arg(long)]
    pub json: bool,
    /// Measure over the quick corpus (about a fifth of the samples; the static figures and
    /// the verdict do not change).
    #[arg(long)]
    pub quick: bool,
    /// Write the layout with its boards as planned (`board_kind` and one `[[board]]` per
    /// board) to FILE, for `tactus play --layout` and later runs of `tactus budget`.
    #[arg(long, value_name = "FILE")]
    pub write_plan: Option<PathBuf>,
    /// The emulator's engine for the measurements: `block` (code compiled to native code
    /// with cranelift), `interp` (the interpreter) or `lock-step` (the machine with no
    /// accelerator, the reference): the same cycles; compare their speed.
    #[arg(long, value_enum, default_value = "block")]
    pub emu: crate::values::EmuEngine,
}

/// A failure: bad input (exit 2) with its message.
struct Bad(String);

/// Runs `tactus budget`.
pub fn run(args: BudgetArgs) -> ExitCode {
    match run_budget(&args) {
        Ok(code) => code,
        Err(Bad(e)) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

fn run_budget(args: &BudgetArgs) -> Result<ExitCode, Bad> {
    let kb = keyboard::compile(
        &KeyboardSpec {
            input: &args.input,
            as_layout: None,
            board: args.board.as_deref(),
            keys: args.keys,
            params: &args.params,
        },
        &mut source::report_compile,
    )
    .map_err(|e| Bad(e.to_string()))?;
    let bar = StageBar::new();
    let report = budget::budget(
        &kb,
        args.quick,
        args.emu.into(),
        &mut |stage, done, total| bar.update(stage, done, total),
    )
    .map_err(Bad)?;
    bar.finish();

    if args.json {
        let json = serde_json::to_string_pretty(&report)
            .map_err(|e| Bad(format!("cannot write the report as JSON: {e}")))?;
        println!("{json}");
    } else {
        print!("{}", report.text());
    }
    for line in report.error_lines(&kb.name) {
        eprintln!("{line}");
    }
    if let Some(out) = &args.write_plan {
        budget::write_plan(&kb, &report, out).map_err(Bad)?;
        if !args.json {
            println!(
                "plan: {} boards written to {}",
                report.board_count,
                out.display()
            );
        }
    }
    Ok(ExitCode::from(report.exit_code()))
}
