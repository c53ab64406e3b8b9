//! `tactus check` on the host side: what an instrument is made of, in a line ([`summary`]),
//! and its fixed-point precision report ([`precision`]: the format plan's ranges, Q-formats
//! and error bounds, the accuracy contract's margins on the built-in runs, and whether the
//! contract holds, as `tactus build` requires). The caller compiles the source (reporting
//! its diagnostics) and prints.

use crate::catalogue::Source;
use tactus_compiler::diagnostics::Diagnostic;
use tactus_compiler::fixed::{contract, render, report, FixedProgram};
use tactus_compiler::ir::Program;

/// `src`'s instrument in a line: its name and how many sensors, params, states, modes,
/// force terms, outputs, event kinds and IR values it has.
pub fn summary(src: &Source, p: &Program) -> String {
    format!(
        "{}: instrument `{}` is well-formed: {} sensor(s), {} params, {} states, {} modes, {} force terms, {} outputs, {} event kinds, {} IR values",
        src.name,
        p.name,
        p.sensors.len(),
        p.params.len(),
        p.states.len(),
        p.modes.len(),
        p.forces.len(),
        p.outputs.len(),
        p.events.len(),
        p.values.len()
    )
}

/// The precision report of a program ([`precision`]).
#[derive(Clone, Debug)]
pub struct Precision {
    /// The fixed-point plan's warnings, for the caller to show with the source.
    pub warnings: Vec<Diagnostic>,
    /// The report: every state's and force term's range, Q-format and error bound (N and
    /// DAC LSB) and the multiply cost, then the accuracy contract's margins on the built-in
    /// runs (when there are any). Lines end in `\n`.
    pub text: String,
    /// How the plan breaks the instrument's accuracy contract (`None`: it holds): a failure
    /// of `tactus check`, as `tactus build` refuses the instrument.
    pub broken: Option<String>,
}

/// Plans `p`'s fixed point ([`FixedProgram::new`]), analyses its error bounds
/// ([`report::analyse`]) and checks its accuracy contract on the built-in runs
/// ([`contract::check_builtin`]).
pub fn precision(p: &Program) -> Precision {
    let fp = FixedProgram::new(p);
    let pr = report::analyse(&fp);
    let mut text = render::render(&fp, &pr);
    let runs = contract::check_builtin(p, &fp);
    if !runs.is_empty() {
        text.push_str(&render::render_margins(p, &runs));
    }
    Precision {
        warnings: fp.warnings.clone(),
        text,
        broken: contract::holds_on(p, &runs).err().map(|b| b.to_string()),
    }
}
