//! `tactus budget` on the host side: a compiled keyboard's budget ([`budget`]: its firmware
//! programs, the keyboard's one plan of boards, then each program's static and measured
//! cost and the verdict, `tactus_firmware::verdict::keyboard_budget`) and the plan written
//! as a layout file ([`write_plan`]). The caller shows progress and prints the report.

use crate::keyboard::Keyboard;
use std::path::Path;
use tactus_firmware::verdict::{self, BudgetInput, BudgetReport};

/// The budget of `kb`: its firmware ([`Keyboard::firmware`]), its boards
/// ([`Keyboard::plan`]), each program measured over the full corpus (or the quick one with
/// `quick`) on the emulator's `engine`, and the verdict. `progress(stage, done, total)`
/// follows the planning, the measuring and what fits.
///
/// Errors, as messages naming the input or the instrument: a program that does not compile
/// to firmware or cannot be costed, planned or measured.
pub fn budget(
    kb: &Keyboard,
    quick: bool,
    engine: tactus_emulator::Engine,
    progress: &mut dyn FnMut(&str, usize, usize),
) -> Result<BudgetReport, String> {
    let programs = kb.firmware().map_err(|e| e.to_string())?;
    let plan = kb
        .plan(&programs, &mut |d, n| progress("planning boards", d, n))
        .map_err(|e| e.to_string())?;
    let input = BudgetInput {
        name: kb.name.clone(),
        input: kb.input.clone(),
        board: kb.board.clone(),
        programs: kb.program_inputs(&programs),
        keys: kb.key_programs(),
        plan,
        quick,
        engine,
        limiter: kb.limiter(),
    };
    verdict::keyboard_budget(&input, progress).map_err(|e| e.0)
}

/// Writes `kb` with `report`'s boards as a layout file ([`Keyboard::plan_text`]) to `out`,
/// creating its directory: what `tactus budget --write-plan` writes.
///
/// Errors, as messages naming `out`: a layout that cannot be written as TOML (nothing
/// written), a directory or file that cannot be made.
pub fn write_plan(kb: &Keyboard, report: &BudgetReport, out: &Path) -> Result<(), String> {
    let text = kb
        .plan_text(report)
        .map_err(|e| format!("{}: {e}; nothing written", out.display()))?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("{}: cannot create: {e}", dir.display()))?;
    }
    std::fs::write(out, text).map_err(|e| format!("{}: cannot write: {e}", out.display()))
}
