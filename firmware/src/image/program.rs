//! The key programs of an image: an instrument compiled to its fixed-point program and
//! its Thumb code ([`Program`]), with the static costs of its functions computed once and
//! the force words it drives ([`Drive`]). The parameter sets of one instrument share one
//! code and differ in their param block ([`compile_shared`], [`compile_layout`]), so that
//! the image places such code once per core.

use super::error::ImageError;
use super::glue;
use std::sync::{Arc, OnceLock};
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::ir::{Axis, AxisTotal};
use tactus_compiler::thumb::ThumbObject;
use tactus_runtime::keyboard::KeyAssignment;

/// Most state words (states, modes, edges) the quiescent-key guard compares; a program
/// with more runs every update.
pub const MAX_GUARDED_WORDS: u32 = 160;

/// A compiled key program: the fixed-point program (for its formats and the interpreter)
/// and its Thumb code, with the static WCETs of its functions computed once, and the
/// param block of its keys.
///
/// Programs that share code ([`compile_layout`]: one instrument, params as run-time data)
/// hold the same `Arc`s and differ only in [`Program::params`]; the image places such code
/// once per core, and its static costs are computed once for all of them.
#[derive(Clone, Debug)]
pub struct Program {
    /// The fixed-point program.
    pub fixed: Arc<FixedProgram>,
    /// Its Thumb object (position-independent `.text`).
    pub thumb: Arc<ThumbObject>,
    /// The param block of the keys running this program: one word per run-time param of
    /// `fixed` (`FixedProgram::param_block`), written into each key's state at
    /// `StateLayout::params`; empty without run-time params.
    pub params: Vec<i32>,
    /// `static_cost`, once computed (images of many boards, and the budget, share
    /// programs).
    update_cost: Arc<OnceLock<Result<crate::budget::StaticCost, ImageError>>>,
    /// `init_wcet`, once computed.
    init_cycles: Arc<OnceLock<Result<u64, ImageError>>>,
    /// Whether the image guards this program's updates with the quiescent-key guard
    /// ([`glue::GuardCode`]: a key whose sensors and state stand still skips its update and
    /// keeps its outputs). On by default; its cost is in every static bound of the image.
    pub quiescent_guard: bool,
    /// Whether the image checks its keys' first sensor word ([`glue::SensorCheck`],
    /// docs/firmware.md, "Faults"): every few samples, a class of keys a sample
    /// ([`glue::Turns`]), a tripped key's limiters gated to DAC code 0 between its checks;
    /// with it the state check of the checked key's mode bytes ([`glue::SensorCheck::modes`]).
    /// Its dispatch and one key's check a sample fit grand88 on every board kind (11, 11,
    /// 8 and 8 boards: `tactus budget grand88 --quick [--board …]`). **On by default**;
    /// a key's first reading in range is taken as it
    /// stands (`SensorCheck::seed`), so a checked board is the model from its first
    /// sample. Off (`--sensor-check off`) only to measure a key's glue alone or to run a
    /// stimulus that is not a sensor's (a jump no key's physics makes).
    pub sensor_check: bool,
    /// Whether an image holding this program runs the RP2040's watchdog, fed by core 0
    /// when both cores finished their sample ([`fault`], "The watchdog": a core that stops
    /// finishing samples resets the board within [`fault::WATCHDOG_PERIOD_US`] and a
    /// sample). **On by default**: its 18 cycles of core 0's handler (and a possible wait
    /// of core 1's for its bank, `glue::Feed::other_core_cycles`) fit grand88 on every
    /// board kind (`tactus budget grand88 --quick [--board …]`; BENCHMARKS.md). Off only
    /// for an image meant to run overloaded (a core a sample behind the other, which the
    /// budget never builds, would be reset) or to measure a key's glue alone;
    /// `tactus play --watchdog off`.
    ///
    /// [`fault`]: super::fault
    /// [`fault::WATCHDOG_PERIOD_US`]: super::fault::WATCHDOG_PERIOD_US
    pub watchdog: bool,
}

impl Program {
    /// A program of already compiled parts, with the params' own values as its param block
    /// (`FixedProgram::nominal_param_block`).
    pub fn new(fixed: FixedProgram, thumb: ThumbObject) -> Program {
        Program {
            params: fixed.nominal_param_block(),
            fixed: Arc::new(fixed),
            thumb: Arc::new(thumb),
            update_cost: Arc::default(),
            init_cycles: Arc::default(),
            quiescent_guard: true,
            sensor_check: true,
            watchdog: true,
        }
    }

    /// The same code with another param block (for another key of a shared program).
    pub fn with_params(&self, params: Vec<i32>) -> Program {
        Program {
            params,
            ..self.clone()
        }
    }

    /// Whether `self` and `other` run the same code (one copy per core serves both).
    pub fn same_code(&self, other: &Program) -> bool {
        Arc::ptr_eq(&self.thumb, &other.thumb)
    }

    /// The quiescent-key guard for a key of this program, its calm counter at
    /// `calm_offset` in the record; `None` when [`Program::quiescent_guard`] is off or the
    /// state has more than [`MAX_GUARDED_WORDS`] words (the guard's `B` over the comparison
    /// reaches 2 KB, at 10 bytes per word).
    pub(super) fn guard(&self, calm_offset: u32) -> Option<glue::GuardCode> {
        let differentiated = self.fixed.program.sensors.iter().any(|s| s.differentiated);
        let (p, st) = (&self.fixed.program, &self.thumb.state);
        // The words holding states, modes and edges (the layout pads empty arrays to one
        // element: those are never written and not compared). A state no statement of the
        // update writes keeps the word `init` gave it (a state carried by its reciprocal,
        // `tactus_compiler::fixed::recip`: the piano's `tau`), so it always equals its
        // shadow after the first update and is not compared either.
        let written = tactus_compiler::ir::written_states(&p.body, p.states.len());
        let mut words: Vec<u32> = (0..p.states.len() as u32)
            .filter(|&i| written[i as usize])
            .map(|i| st.states as u32 + 4 * i)
            .collect();
        for (at, n) in [(st.modes, p.modes.len()), (st.edges, p.edges.len())] {
            for b in at..at + n {
                let w = (b as u32) & !3;
                if words.last() != Some(&w) {
                    words.push(w);
                }
            }
        }
        let few = words.len() as u32 <= MAX_GUARDED_WORDS;
        (self.quiescent_guard && few).then_some(glue::GuardCode {
            calm_offset,
            calm_needed: if differentiated {
                (2 * tactus_runtime::differentiator::WINDOW + 1) as u8
            } else {
                // Two, so that the first update (compared with a zero shadow) never
                // decides alone.
                2
            },
            words,
        })
    }

    /// Words of the key's state struct the quiescent-key guard compares after each update
    /// ([`glue::GuardCode::words`]: the states the update writes and the words of its mode
    /// and edge bytes); `None` when the program runs without the guard.
    pub fn guard_words(&self) -> Option<usize> {
        self.guard(0).map(|g| g.words.len())
    }

    /// Compiles instrument source `text` with `config` (sample rate, `--param`
    /// overrides) to a fixed-point program and Thumb code. Errors are the rendered
    /// diagnostics' messages or the Thumb backend's error.
    pub fn compile(
        text: &str,
        config: &tactus_compiler::lower::Config,
    ) -> Result<Program, ImageError> {
        let lowered = lower(text, config)?;
        Program::of_ir(&lowered)
    }

    /// Plans formats for an IR program and compiles it to Thumb code under the image's
    /// calling convention (`Convention::SAMPLE_ISR`: only the image's glue calls the
    /// update; it keeps r4, r6 and r7 across the call and re-establishes r5 and the
    /// limiter's constants itself, [`glue::KeyCode::clobbers`]).
    fn of_ir(ir: &tactus_compiler::ir::Program) -> Result<Program, ImageError> {
        let fixed = FixedProgram::new(ir);
        let conv = tactus_compiler::thumb::Convention::SAMPLE_ISR;
        let thumb = tactus_compiler::thumb::compile_with(&fixed, conv)
            .map_err(|e| ImageError::Compile(e.to_string()))?;
        Ok(Program::new(fixed, thumb))
    }

    /// Static WCET (cycles, first instruction to return) of the program's update, as
    /// [`tactus_isa::wcet::analyse`] prices it (the code is position independent, so anywhere).
    pub fn update_wcet(&self) -> Result<u64, ImageError> {
        self.static_cost()
            .map(|c| c.cycles - crate::runner::BL_CYCLES)
    }

    /// The update's static cost as the budget reports it ([`crate::budget::static_update`]:
    /// cycles with the caller's `BL`, the worst path and its events), computed once.
    ///
    /// Errors: [`ImageError::Wcet`] when the analysis fails.
    pub fn static_cost(&self) -> Result<crate::budget::StaticCost, ImageError> {
        self.update_cost
            .get_or_init(|| {
                crate::budget::static_update(&self.thumb)
                    .map_err(|e| ImageError::Wcet(e.to_string()))
            })
            .clone()
    }

    /// Static WCET of the program's init, as [`Program::update_wcet`].
    pub fn init_wcet(&self) -> Result<u64, ImageError> {
        self.init_cycles
            .get_or_init(|| self.wcet_of(&self.thumb.init_name()))
            .clone()
    }

    /// Sensor window words a key of this program reads per sample: one per sensor of the
    /// program (a pen's vector sensor counts its components), in the program's sensor
    /// order; at least one (a program without sensors still gets its window word copied).
    pub fn sensor_words(&self) -> usize {
        self.fixed.program.sensors.len().max(1)
    }

    /// The force words a key of this program drives, in the order of its DAC window words:
    /// a keyboard program drives one, its total force (`out[total]`); a pen program
    /// ([`tactus_compiler::ir::Program::is_pen`]) drives one per axis of
    /// [`tactus_compiler::ir::Program::force_axes`], **z first** (the total, so a pen's
    /// first DAC word is the normal force, like a key's), then the other axes in the
    /// program's axis order (`x`, then `y`: the outputs `force.x`, `force.y`).
    ///
    /// Errors: [`ImageError::Compile`] naming the program when an axis names an output
    /// the program does not have (a compiler bug).
    pub fn drives(&self) -> Result<Vec<Drive>, ImageError> {
        let out = &self.thumb.out;
        let total = Drive {
            axis: None,
            out_index: out.total,
            frac: self.fixed.total_frac,
        };
        let axes = &self.fixed.program.force_axes;
        if axes.is_empty() {
            return Ok(vec![total]);
        }
        let mut v = Vec::with_capacity(axes.len());
        if axes.iter().any(|(_, t)| *t == AxisTotal::Total) {
            let z = axes
                .iter()
                .find(|(_, t)| *t == AxisTotal::Total)
                .map(|a| a.0);
            v.push(Drive { axis: z, ..total });
        }
        for &(axis, t) in axes {
            if let AxisTotal::Output(id) = t {
                let frac = self
                    .fixed
                    .output_frac
                    .get(id.index())
                    .copied()
                    .ok_or_else(|| {
                        ImageError::Compile(format!(
                            "program `{}`: force axis {axis} is output {} of {}",
                            self.thumb.stem,
                            id.index(),
                            self.fixed.output_frac.len()
                        ))
                    })?;
                v.push(Drive {
                    axis: Some(axis),
                    out_index: out.outputs + id.index(),
                    frac,
                });
            }
        }
        Ok(v)
    }

    fn wcet_of(&self, name: &str) -> Result<u64, ImageError> {
        crate::budget::function_wcet(&self.thumb, name)
            .map(|w| w.cycles)
            .map_err(|e| ImageError::Wcet(e.to_string()))
    }
}

/// The IR of instrument source `text` under `config`; errors are the diagnostics' messages.
fn lower(
    text: &str,
    config: &tactus_compiler::lower::Config,
) -> Result<tactus_compiler::ir::Program, ImageError> {
    tactus_compiler::compile(text, config)
        .map(|l| l.program)
        .map_err(|d| {
            ImageError::Compile(
                d.iter()
                    .map(|d| d.message.clone())
                    .collect::<Vec<_>>()
                    .join("; "),
            )
        })
}

/// Compiles lowered programs, given with their instrument names (one per distinct parameter
/// set), to one [`Program`] each, in order: the sets of one instrument share one code
/// ([`tactus_compiler::share`]; run-time params, a param block per program) when the
/// instrument has several and they differ only in param values, else each set gets its own.
///
/// Errors: the index of the set and [`ImageError::Compile`] when the Thumb backend fails or
/// a set's param values do not fit its shared program's intervals (a bug), or
/// [`ImageError::Contract`] when a plan breaks its instrument's accuracy contract on a
/// built-in stimulus.
pub fn compile_shared(
    sets: &[(&str, &tactus_compiler::ir::Program)],
) -> Result<Vec<Program>, (usize, ImageError)> {
    let mut programs: Vec<Option<Program>> = vec![None; sets.len()];
    let mut instruments: Vec<&str> = sets.iter().map(|s| s.0).collect();
    instruments.sort_unstable();
    instruments.dedup();
    for name in instruments {
        let members: Vec<usize> = (0..sets.len()).filter(|&i| sets[i].0 == name).collect();
        let irs: Vec<tactus_compiler::ir::Program> =
            members.iter().map(|&i| sets[i].1.clone()).collect();
        // No program whose accuracy contract its plan breaks (at its own param values;
        // a shared code at its nominal block).
        let contract = |ir: &tactus_compiler::ir::Program, code: &Program| {
            tactus_compiler::fixed::contract::verdict(ir, &code.fixed)
                .map_err(|b| ImageError::Contract(b.to_string()))
        };
        match tactus_compiler::share::share(&irs) {
            Ok(shared) if members.len() > 1 => {
                let code = Program::of_ir(&shared.program).map_err(|e| (members[0], e))?;
                contract(&shared.program, &code).map_err(|e| (members[0], e))?;
                for (&i, values) in members.iter().zip(&shared.values()) {
                    let block = code
                        .fixed
                        .param_block(values)
                        .map_err(|e| (i, ImageError::Compile(e.to_string())))?;
                    programs[i] = Some(code.with_params(block));
                }
            }
            _ => {
                for &i in &members {
                    let code = Program::of_ir(sets[i].1).map_err(|e| (i, e))?;
                    contract(sets[i].1, &code).map_err(|e| (i, e))?;
                    programs[i] = Some(code);
                }
            }
        }
    }
    programs
        .into_iter()
        .enumerate()
        .map(|(i, p)| p.ok_or((i, ImageError::Compile("not compiled".into()))))
        .collect()
}

/// Compiles the programs a resolved keyboard layout needs (`tactus_runtime::keyboard::assign`):
/// one per distinct (instrument, parameter overrides), each key's `require`s checked with its
/// own values. The parameter sets of one instrument then share one code
/// ([`tactus_compiler::share`]: a param that differs between the keys is run-time data, a
/// word of each key's param block, planned over the interval the keys span), so a graded
/// grand piano is one piano program whatever the number of keys; the returned programs of
/// one instrument differ only in [`Program::params`] ([`Program::same_code`]). An instrument
/// whose parameter sets cannot share (a state range computed from a param) gets one code
/// per set. `source` returns an instrument's text by the name the layout gives (a built-in
/// name or a path). Returns the programs and, per key, the index of its program.
///
/// This is the firmware's own tests', benches' and examples' way to a layout's programs;
/// the toolchain resolves and compiles a keyboard in one place, `tactus_host::keyboard`
/// (with diagnostics and overrides), which hands its distinct sets to [`compile_shared`]
/// as this does.
///
/// Errors: [`ImageError::Compile`] naming the key and instrument when `source` fails or the
/// instrument does not compile (a `require` a key's param value breaks among them).
pub fn compile_layout(
    keys: &[KeyAssignment],
    source: &dyn Fn(&str) -> Result<String, String>,
    sample_rate_hz: f64,
) -> Result<(Vec<Program>, Vec<usize>), ImageError> {
    // Which keys share a program: the one rule (`group_sets`), as the toolchain's keyboard.
    let (sets, index) = tactus_runtime::keyboard::group_sets(keys, |k| {
        let text = source(&k.instrument).map_err(|e| compile_error(k, &e))?;
        let config = tactus_compiler::lower::Config {
            sample_rate_hz,
            overrides: k.params.clone(),
        };
        let ir = lower(&text, &config).map_err(|e| compile_error(k, &e.to_string()))?;
        Ok::<_, ImageError>((k, ir))
    })?;
    let lowered: Vec<(&str, &tactus_compiler::ir::Program)> = sets
        .iter()
        .map(|(k, ir)| (k.instrument.as_str(), ir))
        .collect();
    let programs =
        compile_shared(&lowered).map_err(|(i, e)| compile_error(sets[i].0, &e.to_string()))?;
    Ok((programs, index))
}

/// A key's compile failure, naming the key and its instrument.
fn compile_error(k: &KeyAssignment, e: &str) -> ImageError {
    ImageError::Compile(format!("key {} (`{}`): {e}", k.key, k.instrument))
}

/// One force word a key drives to a DAC window word ([`Program::drives`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Drive {
    /// The pen axis it is the total force of; `None` for a keyboard program's force word.
    pub axis: Option<Axis>,
    /// Index of the word in the update's `out` array (`OutLayout::total`, or
    /// `OutLayout::outputs` + the output's index for `force.x`/`force.y`).
    pub out_index: usize,
    /// Fraction bits of the word (`FixedProgram::total_frac` or the output's
    /// `FixedProgram::output_frac`): the force in newtons is `word / 2^frac`, and the
    /// limiter scales it with this format's `DacScale`.
    pub frac: i32,
}
