//! The regulation sheet of a key instrument as `tactus regulate` measures it: the sheet on
//! the chosen arithmetic and engine ([`measure`], over
//! [`crate::regulate::measure`]), its text with a spec's verdicts
//! ([`sheet_text`], [`spec_line`]) and the force–travel loop's table and plot ([`loop_csv`],
//! [`write_loop`]). The caller prints.

use crate::play::engine::{FixedJitEngine, JitEngine};
use crate::plot;
use crate::regulate::{self, spec, Config, Figure, Sheet};
use crate::sim::{Engine, Numeric};
use std::path::{Path, PathBuf};
use tactus_compiler::diagnostics::Diagnostic;
use tactus_compiler::ir::Program;

/// Measures the regulation sheet of `program` on `numeric` and `engine` (the JIT and the
/// interpreter of one arithmetic give the same bits). Returns the sheet and, with
/// [`Numeric::Fixed`], the fixed-point plan's warnings (for the caller to show).
///
/// Errors, as messages: what [`regulate::measure`] rejects (not a key instrument, a
/// non-finite force), or a JIT that does not compile.
pub fn measure(
    program: &Program,
    numeric: Numeric,
    engine: Engine,
    config: &Config,
) -> Result<(Sheet, Vec<Diagnostic>), String> {
    Ok(match (numeric, engine) {
        (Numeric::F64, Engine::Interp) => (
            regulate::measure(
                program,
                tactus_compiler::interp::Instance::new(program),
                config,
            )?,
            Vec::new(),
        ),
        (Numeric::F64, Engine::Jit) => {
            let jit = tactus_jit::JitProgram::compile(program).map_err(|e| format!("JIT: {e}"))?;
            let e = JitEngine(tactus_jit::JitInstance::new(&jit));
            (regulate::measure(program, e, config)?, Vec::new())
        }
        (Numeric::Fixed, engine) => {
            let fp = tactus_compiler::fixed::FixedProgram::new(program);
            let sheet = match engine {
                Engine::Jit => {
                    let jit = tactus_jit::fixed::FixedJitProgram::compile(&fp)
                        .map_err(|e| format!("JIT: {e}"))?;
                    let e = FixedJitEngine(tactus_jit::fixed::FixedJitInstance::new(&jit), &fp);
                    regulate::measure(program, e, config)?
                }
                Engine::Interp => {
                    let e = tactus_compiler::fixed::interp::FixedInstance::new(&fp);
                    regulate::measure(program, e, config)?
                }
            };
            (sheet, fp.warnings.clone())
        }
    })
}

/// The sheet as a technician's table: a header, one line per figure (value, unit, the
/// spec's range and verdict when `verdicts` is given, how it was measured), the spec's
/// figures not measured, then the sheet's notes. Lines end in `\n`.
pub fn sheet_text(sheet: &Sheet, verdicts: Option<&[spec::Verdict]>) -> String {
    let range_of = |f: Figure| verdicts.and_then(|v| v.iter().find(|v| v.range.figure == f));
    let mut s = format!(
        "  {:<26} {:>9} {:<8} {:<14} how it was measured\n",
        "figure",
        "value",
        "unit",
        if verdicts.is_some() { "spec" } else { "" }
    );
    for m in &sheet.figures {
        let (range, verdict) = match range_of(m.figure) {
            Some(v) => (v.range.text(), if v.holds() { "ok  " } else { "OUT " }),
            None => (String::new(), "    "),
        };
        s.push_str(&format!(
            "  {:<26} {:>9} {:<8} {:<14} {verdict}{}\n",
            m.figure.title(),
            format!("{:.2}", m.value),
            m.figure.unit(),
            range,
            m.how
        ));
    }
    for v in verdicts.unwrap_or_default() {
        if v.value.is_none() {
            s.push_str(&format!(
                "  {:<26} {:>9} {:<8} {:<14} OUT not measured\n",
                v.range.figure.title(),
                "—",
                v.range.figure.unit(),
                v.range.text()
            ));
        }
    }
    for n in &sheet.notes {
        s.push_str(&format!("  note: {n}\n"));
    }
    s
}

/// The spec's verdict in one line, and whether every figure holds: `within spec …` or
/// `OUTSIDE spec …: K of N figures (keys)`.
pub fn spec_line(spec: &spec::Spec, verdicts: &[spec::Verdict]) -> (bool, String) {
    let failed: Vec<&str> = verdicts
        .iter()
        .filter(|v| !v.holds())
        .map(|v| v.range.figure.key())
        .collect();
    match failed.is_empty() {
        true => (
            true,
            format!(
                "within spec `{}`: all {} figures in range",
                spec.name,
                verdicts.len()
            ),
        ),
        false => (
            false,
            format!(
                "OUTSIDE spec `{}`: {} of {} figures ({})",
                spec.name,
                failed.len(),
                verdicts.len(),
                failed.join(", ")
            ),
        ),
    }
}

/// The force–travel loop's binned means as CSV: `travel [mm],down [gf],up [gf]`, one row
/// per bin (its middle), an empty cell where the dip did not pass in that direction.
pub fn loop_csv(sheet: &Sheet) -> String {
    let lp = &sheet.force_loop;
    let mut text = String::from("travel [mm],down [gf],up [gf]\n");
    let cell = |v: &Option<f64>| {
        v.map(|f| format!("{:.3}", regulate::n_to_gf(f)))
            .unwrap_or_default()
    };
    for (i, (d, u)) in lp.down_bins.iter().zip(&lp.up_bins).enumerate() {
        text.push_str(&format!(
            "{:.3},{},{}\n",
            (i as f64 + 0.5) * lp.bin_m * 1e3,
            cell(d),
            cell(u)
        ));
    }
    text
}

/// Writes the loop as `OUT/NAME-loop.svg` (force in gf against travel in mm, down and up
/// in two colours) and `OUT/NAME-loop.csv` ([`loop_csv`]), creating `out`; returns their
/// paths.
///
/// Errors, as messages naming the path: a directory or file that cannot be written.
pub fn write_loop(sheet: &Sheet, out: &Path) -> Result<(PathBuf, PathBuf), String> {
    std::fs::create_dir_all(out).map_err(|e| format!("cannot create `{}`: {e}", out.display()))?;
    let lp = &sheet.force_loop;
    let line = |label: &str, pts: &[(f64, f64)]| plot::Line {
        label: label.to_string(),
        x: pts.iter().map(|p| p.0 * 1e3).collect(),
        y: pts.iter().map(|p| regulate::n_to_gf(p.1)).collect(),
    };
    let svg = out.join(format!("{}-loop.svg", sheet.instrument));
    plot::plot_lines(
        &[line("going down", &lp.down), line("going up", &lp.up)],
        &format!(
            "{}: force at the key on a quasi-static dip ({} mm/s)",
            sheet.instrument,
            regulate::QUASI_STATIC_SPEED * 1e3
        ),
        "key travel [mm]",
        "force at the key [gf]",
        &svg,
    )
    .map_err(|e| e.to_string())?;
    let csv = out.join(format!("{}-loop.csv", sheet.instrument));
    std::fs::write(&csv, loop_csv(sheet))
        .map_err(|e| format!("{}: cannot write: {e}", csv.display()))?;
    Ok((svg, csv))
}
