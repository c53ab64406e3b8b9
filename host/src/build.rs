//! `tactus build` on the host side: one instrument to C99 sources or a Thumb object
//! ([`build_instrument`]), and a compiled keyboard to flashable firmware per board
//! ([`build_firmware`]), with the files written and what to print returned.

use crate::catalogue::Source;
use crate::keyboard::{Keyboard, Reporter};
use std::path::{Path, PathBuf};
use tactus_compiler::abi::CConfig;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::ir::Program;
use tactus_compiler::{cgen, thumb};
use tactus_firmware::flash::{self, KeyboardInput, Load};

/// What `tactus build` generates for one instrument.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// Portable C99 (`<stdint.h>` only): `NAME.h` and `NAME.c`.
    C,
    /// A Thumb ELF object for the Cortex-M0+ (`NAME.o`), its header (`NAME.h`) and a GNU
    /// assembler listing (`NAME.s`).
    Rp2040,
}

/// Writes `bytes` to `path`, creating its directory; the error names the path.
fn write(path: &Path, bytes: &[u8]) -> Result<(), String> {
    if let Some(d) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(d).map_err(|e| format!("cannot create `{}`: {e}", d.display()))?;
    }
    std::fs::write(path, bytes).map_err(|e| format!("cannot write `{}`: {e}", path.display()))
}

/// Compiles `program` (lowered from `src` with `params`) to fixed point and writes it into
/// `dir` as `target` says. The fixed-point plan's warnings go to `report`. Returns the line
/// to print: the files written, their sizes and the update function to call.
///
/// Errors, as messages naming the source: a plan that breaks the instrument's own accuracy
/// contract (nothing written), a code generator's refusal, a file that cannot be written.
pub fn build_instrument(
    src: &Source,
    program: &Program,
    params: &[(String, String)],
    target: Target,
    dir: &Path,
    report: &mut Reporter,
) -> Result<String, String> {
    let name = &src.name;
    let fp = FixedProgram::new(program);
    if !fp.warnings.is_empty() {
        report(src, &fp.warnings);
    }
    // No firmware from an instrument whose own accuracy contract the plan breaks.
    tactus_compiler::fixed::contract::verdict(program, &fp)
        .map_err(|b| format!("{name}: {b}; nothing written"))?;
    let write = |path: &Path, bytes: &[u8]| write(path, bytes).map_err(|e| format!("{name}: {e}"));
    if target == Target::Rp2040 {
        let obj = thumb::compile(&fp).map_err(|e| format!("{name}: {e}"))?;
        let elf = obj.elf().map_err(|e| format!("{name}: {e}"))?;
        let o = dir.join(format!("{}.o", obj.stem));
        let h = dir.join(format!("{}.h", obj.stem));
        let s = dir.join(format!("{}.s", obj.stem));
        write(&o, &elf)?;
        write(&h, obj.header.as_bytes())?;
        write(&s, obj.code.listing.as_bytes())?;
        let (_, size) = obj.symbol(&obj.update_name()).unwrap_or((0, 0));
        return Ok(format!(
            "{name}: wrote {}, {} and {} (.text {} bytes, update {} bytes; link the object and call {} once per sample)",
            o.display(),
            h.display(),
            s.display(),
            obj.code.text.len(),
            size,
            obj.update_name()
        ));
    }
    let config = CConfig {
        source_name: Some(name.clone()),
        overrides: params.iter().map(|(n, v)| format!("{n}={v}")).collect(),
    };
    let c = cgen::emit_c_with(&fp, &config).map_err(|e| format!("{name}: {e}"))?;
    let h = dir.join(format!("{}.h", c.stem));
    let s = dir.join(format!("{}.c", c.stem));
    for (path, text) in [(&h, &c.header), (&s, &c.source)] {
        write(path, text.as_bytes())?;
    }
    Ok(format!(
        "{name}: wrote {} and {} ({} + {} lines; call {} once per sample)",
        h.display(),
        s.display(),
        c.header.lines().count(),
        c.source.lines().count(),
        tactus_compiler::abi::update_symbol(&c.stem)
    ))
}

/// Builds the firmware of every board of `kb`'s plan ([`Keyboard::plan`],
/// [`flash::keyboard_firmware`]: a flash image,
/// or with `ram` a RAM-only one) and writes `dir/board-NN/` with `firmware.elf`,
/// `firmware.uf2`, `keys.json` and `README.md` (which quotes `command`). `input` is the
/// keyboard as the user named it, for the messages.
/// `progress(stage, done, total)` follows the build. Returns the lines to print: one per
/// board (its keys, UF2 blocks, each core's static bound against the sample period), then
/// the summary and how to flash.
///
/// Errors, as messages: a program that does not compile to firmware, a board the planner
/// cannot fill, a file that cannot be written (naming it).
pub fn build_firmware(
    input: &str,
    kb: &Keyboard,
    ram: bool,
    command: &str,
    dir: &Path,
    progress: &mut dyn FnMut(&str, usize, usize),
) -> Result<Vec<String>, String> {
    let programs = kb.firmware().map_err(|e| e.to_string())?;
    let names: Vec<(String, Vec<(String, String)>)> = kb
        .sets
        .iter()
        .map(|s| (s.instrument.clone(), s.params.clone()))
        .collect();
    let key_programs = kb.key_programs();
    let limiter = kb.limiter();
    let plan = kb
        .plan(&programs, &mut |d, n| progress("planning boards", d, n))
        .map_err(|e| e.to_string())?;
    let firmware_input = KeyboardInput {
        name: &kb.name,
        programs: &programs,
        program_names: &names,
        keys: &key_programs,
        board: &kb.board,
        boards: &plan.key_lists(),
        images: &plan.images,
        limiter: &limiter,
        load: if ram { Load::Ram } else { Load::Flash },
        command,
    };
    let boards =
        flash::keyboard_firmware(&firmware_input, progress).map_err(|e| format!("{input}: {e}"))?;
    let mut lines = Vec::with_capacity(boards.len() + 1);
    for b in &boards {
        let d: PathBuf = dir.join(b.dir_name());
        let json = serde_json::to_string_pretty(&b.key_map)
            .map_err(|e| format!("cannot write the key map: {e}"))?;
        write(&d.join("firmware.elf"), &b.elf)?;
        write(&d.join("firmware.uf2"), &b.uf2)?;
        write(&d.join("keys.json"), json.as_bytes())?;
        write(&d.join("README.md"), b.readme.as_bytes())?;
        let cores: Vec<String> = (0..b.image.cores())
            .map(|c| {
                let w = b.image.wcet(c).unwrap_or_default();
                let period = b.image.cycles_per_sample();
                format!("core {c} {} / {period} cycles", w.bound())
            })
            .collect();
        lines.push(format!(
            "{}: keys {}, UF2 {} blocks; sample interrupt {}",
            d.display(),
            tactus_firmware::verdict::key_ranges(&b.keys),
            b.uf2.len() / tactus_firmware::uf2::BLOCK,
            cores.join(", ")
        ));
    }
    let (kind, then) = match ram {
        true => ("RAM-only", "it runs until power-off"),
        false => ("flash", "it boots from flash at every power-on"),
    };
    lines.push(format!(
        "{}: {} boards of {} at {} MHz in {}, each with firmware.uf2 ({kind}), firmware.elf, keys.json, README.md\n\
         flash a board: hold BOOTSEL, plug it in, copy its firmware.uf2 onto the RPI-RP2 drive; {then}",
        kb.name,
        boards.len(),
        kb.board.name,
        kb.board.clock_hz / 1e6,
        dir.display()
    ));
    Ok(lines)
}
