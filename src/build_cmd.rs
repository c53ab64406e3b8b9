//! `tactus build`: compile an instrument to firmware sources.
//!
//! `--target c` (the default) writes `DIR/<name>.h` and `DIR/<name>.c`: portable C99 with
//! the fixed-point bits of the fixed interpreter (see `tactus_compiler::cgen`).
//!
//! `--target rp2040` writes `DIR/<name>.o` (an ARM ELF relocatable object for the
//! Cortex-M0+, from `tactus_compiler::thumb`), `DIR/<name>.h` (the same interface header as
//! the C target: state struct, prototypes, Q-formats and units) and `DIR/<name>.s` (a GNU
//! assembler listing that `arm-none-eabi-as -mcpu=cortex-m0plus` assembles to the same
//! bytes).

use crate::check_cmd::{compile_reporting, parse_override};
use crate::source;
use std::path::PathBuf;
use std::process::ExitCode;
use tactus_compiler::cgen::{self, CConfig};
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::thumb;

/// Arguments of `tactus build`.
#[derive(Debug, clap::Args)]
pub struct BuildArgs {
    /// Instrument file (`instruments/grand_piano.tactus`) or built-in name (`grand_piano`).
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
    let src = source::load(&args.file).map_err(Some)?;
    let lowered = compile_reporting(&src, &args.params).ok_or(None)?;
    let fp = FixedProgram::new(&lowered.program);
    if !fp.warnings.is_empty() {
        crate::source::report(&src, &fp.warnings);
    }
    let config = CConfig {
        source_name: Some(src.name.clone()),
        overrides: args
            .params
            .iter()
            .map(|(n, v)| format!("{n}={v}"))
            .collect(),
    };
    std::fs::create_dir_all(dir).map_err(|e| {
        Some(format!(
            "{}: cannot create `{}`: {e}",
            src.name,
            dir.display()
        ))
    })?;
    let write = |path: &std::path::Path, bytes: &[u8]| {
        std::fs::write(path, bytes).map_err(|e| {
            Some(format!(
                "{}: cannot write `{}`: {e}",
                src.name,
                path.display()
            ))
        })
    };
    if args.target == Target::Rp2040 {
        let obj = thumb::compile(&fp).map_err(|e| Some(format!("{}: {e}", src.name)))?;
        let elf = obj.elf().map_err(|e| Some(format!("{}: {e}", src.name)))?;
        let o = dir.join(format!("{}.o", obj.stem));
        let h = dir.join(format!("{}.h", obj.stem));
        let s = dir.join(format!("{}.s", obj.stem));
        write(&o, &elf)?;
        write(&h, obj.header.as_bytes())?;
        write(&s, obj.code.listing.as_bytes())?;
        let (_, size) = obj.symbol(&obj.update_name()).unwrap_or((0, 0));
        println!(
            "{}: wrote {}, {} and {} (.text {} bytes, update {} bytes; link the object and call {} once per sample)",
            src.name,
            o.display(),
            h.display(),
            s.display(),
            obj.code.text.len(),
            size,
            obj.update_name()
        );
        return Ok(());
    }
    let c = cgen::emit_c_with(&fp, &config).map_err(|e| Some(format!("{}: {e}", src.name)))?;
    let h = dir.join(format!("{}.h", c.stem));
    let s = dir.join(format!("{}.c", c.stem));
    for (path, text) in [(&h, &c.header), (&s, &c.source)] {
        write(path, text.as_bytes())?;
    }
    println!(
        "{}: wrote {} and {} ({} + {} lines; call tactus_{}_update once per sample)",
        src.name,
        h.display(),
        s.display(),
        c.header.lines().count(),
        c.source.lines().count(),
        c.stem
    );
    Ok(())
}
