//! The C99 backend: a [`FixedProgram`] as one portable header and one source file.
//!
//! The generated code is the fixed interpreter ([`crate::fixed::interp`]) unrolled: one
//! `int32_t` local per live IR value, one C statement per IR statement, in the body's order,
//! with every format baked in as a constant (shift amounts, thresholds, saturation bounds).
//! The primitives come from [`prim`], which reduces each `i128` definition of
//! `tactus_runtime::fixed` to `int64_t`/`uint64_t` arithmetic on the compile-time formats,
//! so the C code gives the interpreter's bits on every sample; `compiler/tests/cgen.rs`
//! checks that on every instrument and stimulus.
//!
//! Everything the update remembers between samples lives in one caller-owned struct (no
//! globals, no allocation), so one instance per key is one struct per key. The `out` array
//! of the update is flat `int32_t` words whose layout ([`OutLayout`]) is also given as
//! macros in the header: force terms, total, outputs, then one slot per `emit` site (a
//! fired flag and the arguments).

pub mod prim;

use crate::fixed::{FixedProgram, MulKind};
use crate::ir::*;
use std::collections::HashSet;
use std::fmt::{self, Write as _};
use tactus_runtime::differentiator::WINDOW;

/// Generated C: the header (`<name>.h`) and the source (`<name>.c`), and the layout of the
/// update's `out` array.
#[derive(Clone, Debug)]
pub struct CSource {
    /// The header: state struct, prototypes, Q-format and layout macros.
    pub header: String,
    /// The implementation; includes the header as `"<name>.h"`.
    pub source: String,
    /// The C identifier stem: functions are `tactus_<stem>_init`/`_update`, the header is
    /// `<stem>.h`.
    pub stem: String,
    /// Where the update writes what.
    pub layout: OutLayout,
}

/// Layout of the `out` array of `tactus_<name>_update`, in `int32_t` words.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutLayout {
    /// Number of words.
    pub len: usize,
    /// Index of force term `i` is `forces + i` (format `force_frac[i]`).
    pub forces: usize,
    /// Index of the total force (format `total_frac`).
    pub total: usize,
    /// Index of output `i` is `outputs + i` (format `output_frac[i]`).
    pub outputs: usize,
    /// One entry per `emit` statement, in program order (which is the order in which the
    /// sites of one sample fire): the word at `offset` is 1 when the site fired this sample,
    /// else 0; the event's arguments follow it (formats `event_frac[event]`; 0 when not fired).
    pub emits: Vec<EmitSite>,
}

/// One `emit` statement's slot in the `out` array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EmitSite {
    /// Which event it emits.
    pub event: EventId,
    /// Index of its fired flag; the arguments are at `offset + 1 ..`.
    pub offset: usize,
}

/// Byte offsets of the fields of `struct tactus_<name>_state` as a C compiler for a 32-bit
/// target with natural alignment lays it out (`int32_t` 4-aligned, `uint8_t` unaligned;
/// every array at least one element). The Thumb backend uses the same layout, so one header
/// describes both.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StateLayout {
    /// `int32_t states[]`.
    pub states: usize,
    /// `int32_t params[]` (after `edges`): the key's param block, one word per run-time param
    /// ([`crate::ir::ParamDecl::runtime`]); absent (no bytes) without run-time params. The
    /// firmware writes it before `init`, which leaves it alone.
    pub params: usize,
    /// `uint8_t modes[]`.
    pub modes: usize,
    /// `uint8_t edges[]`.
    pub edges: usize,
    /// `int32_t hist[][2·(2N+1)]`: per differentiated sensor a ring of the last `2N + 1`
    /// readings, kept twice (word `k` and word `k + 2N + 1` hold the same reading), so the
    /// readings up to `2N` samples before the newest follow it without a wrap.
    pub hist: usize,
    /// `uint8_t hist_pos[]`: 0 before the first sample (the ring not primed yet), then
    /// `4·(k + 1)` with `k` the slot of the newest reading's first copy, which counts down
    /// (from `2N` in the first sample to 0, and round again): `r7 + hist_pos` is the newest
    /// reading's address less `hist - 4`.
    pub hist_pos: usize,
    /// `int32_t published[]`.
    pub published: usize,
    /// `sizeof` the struct, bytes (a multiple of 4).
    pub size: usize,
}

impl StateLayout {
    /// The layout for a program.
    pub fn new(p: &Program) -> Self {
        let align4 = |x: usize| (x + 3) & !3;
        let n = |k: usize| k.max(1);
        let nh = p.sensors.iter().filter(|s| s.differentiated).count();
        // The byte arrays first: `LDRB`/`STRB` immediates reach only 31 bytes from r7 (the
        // words' reach 124), and the update reads and writes every mode, edge and history
        // position byte each sample.
        // The history bytes start a word of their own: the firmware's quiescent-key guard
        // compares the words holding states, modes and edges, and a ring advances every
        // sample.
        let modes = 0;
        let edges = modes + n(p.modes.len());
        let hist_pos = align4(edges + n(p.edges.len()));
        let states = align4(hist_pos + n(nh));
        let params = states + 4 * n(p.states.len());
        let hist = params + 4 * p.runtime_params().count();
        let published = hist + 8 * (2 * WINDOW + 1) * n(nh);
        let size = published + 4 * (p.forces.len() + 1 + p.outputs.len());
        StateLayout {
            states,
            params,
            modes,
            edges,
            hist,
            hist_pos,
            published,
            size,
        }
    }
}

impl StateLayout {
    /// The words of a ring (indices into `hist[h]`) that the first sample's priming sets to
    /// its reading: those the first `2N + 1` samples read before writing them. The first
    /// sample's position is `2N` (as after slot 0: it counts down), so the readings it
    /// and the next `2N` samples take from before the first one lie in the second copy,
    /// words `2N + 1 … 4N`, each read from one word only.
    pub fn primed_slots() -> std::ops::Range<usize> {
        2 * WINDOW + 1..4 * WINDOW + 1
    }
}

/// What the generated code is annotated with.
#[derive(Clone, Debug, Default)]
pub struct CConfig {
    /// The source the program was compiled from (a file name), for the comment header.
    pub source_name: Option<String>,
    /// `--param` overrides applied, as `name=value` texts, for the comment header.
    pub overrides: Vec<String>,
}

/// Why a program cannot be turned into C.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CgenError {
    /// A mode has more variants than its `uint8_t` slot holds (256).
    TooManyVariants {
        /// The mode's name.
        mode: String,
        /// Its number of variants.
        count: usize,
    },
    /// Two declarations map to the same C macro name (names differ only in characters that
    /// C identifiers cannot hold, such as `a.b` and `a_b`).
    NameClash(String),
    /// An IR construct this backend does not handle (a compiler bug if the front end
    /// produced it).
    Unsupported(String),
}

impl fmt::Display for CgenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CgenError::TooManyVariants { mode, count } => {
                write!(f, "mode `{mode}` has {count} variants; the C backend stores a mode in a uint8_t (at most 256)")
            }
            CgenError::NameClash(n) => write!(
                f,
                "two declarations map to the same C name `{n}`; rename one"
            ),
            CgenError::Unsupported(what) => write!(f, "the C backend does not support {what}"),
        }
    }
}

impl std::error::Error for CgenError {}

/// Generates C99 for a fixed-point program, with default annotations.
pub fn emit_c(fp: &FixedProgram) -> Result<CSource, CgenError> {
    emit_c_with(fp, &CConfig::default())
}

/// Generates C99 for a fixed-point program.
///
/// Errors: see [`CgenError`]; none occurs for the shipped instruments.
pub fn emit_c_with(fp: &FixedProgram, config: &CConfig) -> Result<CSource, CgenError> {
    // A broken IR invariant is a compiler bug; say which instead of emitting wrong C.
    crate::verify::verify(&fp.program)
        .map_err(|e| CgenError::Unsupported(format!("a broken IR invariant: {e}")))?;
    Gen::new(fp, config)?.run()
}

/// Which values the body needs (read by a statement, or transitively by the operands of
/// one), and the event of every `emit` statement in program order.
pub fn live_values(p: &Program) -> (Vec<bool>, Vec<EventId>) {
    let mut used = vec![false; p.values.len()];
    let mut work = Vec::new();
    let mut sites = Vec::new();
    walk_stmts(&p.body, &mut |s| {
        work.extend_from_slice(s.reads());
        if let Stmt::Emit(e, _) = s {
            sites.push(*e);
        }
    });
    while let Some(v) = work.pop() {
        if std::mem::replace(&mut used[v.index()], true) {
            continue;
        }
        work.extend(operands(&p.values[v.index()].op));
    }
    (used, sites)
}

/// An identifier in upper snake case (`esc.f` → `ESC_F`).
fn upper(name: &str) -> String {
    let mut s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_uppercase()
            } else {
                '_'
            }
        })
        .collect();
    if s.starts_with(|c: char| c.is_ascii_digit()) || s.is_empty() {
        s.insert(0, '_');
    }
    s
}

/// A product `x·y` (C expressions with their fraction bits) into `fr` fraction bits in the
/// form the plan chose for it (`kind`: pre-shifted `MULS`, 32×16 with its cut operand, high
/// word, else exact): the one dispatch for a product and a product by a reciprocal, as the
/// fixed interpreter has it.
fn product(kind: Option<MulKind>, x: (String, i32), y: (String, i32), fr: i32) -> String {
    match kind {
        Some(MulKind::High(k)) => prim::mul_high(&x.0, x.1, &y.0, y.1, k, fr),
        Some(MulKind::Mul32x16 { cut, b, k }) => {
            let ((a, fa), (c, fc)) = cut.kept_cut(x, y);
            prim::mul_32x16(&a, fa, &c, fc, b, k, fr)
        }
        Some(MulKind::Muls(sa, sb)) => prim::mul(&x.0, x.1, &y.0, y.1, fr, Some((sa, sb))),
        _ => prim::mul(&x.0, x.1, &y.0, y.1, fr, None),
    }
}

/// An `int32_t` literal (C has no negative literals; `-2147483648` is not an `int`).
fn lit(x: i32) -> String {
    if x == i32::MIN {
        "INT32_MIN".into()
    } else {
        x.to_string()
    }
}

pub(crate) fn operands(op: &Op) -> Vec<Value> {
    match op {
        Op::Neg(x) | Op::Not(x) => vec![*x],
        Op::Arith(_, x, y) | Op::Cmp(_, x, y) | Op::And(x, y) | Op::Or(x, y) => vec![*x, *y],
        Op::Select(c, x, y) => vec![*c, *x, *y],
        Op::Call(_, x, y) => std::iter::once(*x).chain(*y).collect(),
        _ => vec![],
    }
}

fn unit(ty: Ty) -> String {
    match ty {
        Ty::Real(d) if d.is_none() => "dimensionless".into(),
        Ty::Real(d) => d.unit_string(),
        Ty::Bool => "bool (0/1)".into(),
        Ty::Mode(_) => "mode variant index".into(),
    }
}

/// Q-format text of a fraction-bit count.
fn q(frac: i32) -> String {
    format!("Q{}.{}", 31 - frac, frac)
}

struct Gen<'a> {
    fp: &'a FixedProgram,
    p: &'a Program,
    config: &'a CConfig,
    stem: String,
    mac: String,
    used: Vec<bool>,
    /// History slot of each differentiated sensor.
    hist_slot: Vec<Option<usize>>,
    /// Which (sensor, order) derivatives are used.
    deriv_used: HashSet<(usize, u8)>,
    layout: OutLayout,
    /// Flag offset of each emit site, in program order.
    emit_sites: Vec<usize>,
    body: String,
    next_site: usize,
}

impl<'a> Gen<'a> {
    fn new(fp: &'a FixedProgram, config: &'a CConfig) -> Result<Self, CgenError> {
        let p = &fp.program;
        for m in &p.modes {
            if m.variants.len() > 256 {
                return Err(CgenError::TooManyVariants {
                    mode: m.name.clone(),
                    count: m.variants.len(),
                });
            }
        }
        let stem = upper(&p.name).to_ascii_lowercase();
        let mac = format!("TACTUS_{}", upper(&p.name));
        let (used, sites) = live_values(p);
        let mut deriv_used = HashSet::new();
        for (v, vd) in p.values.iter().enumerate() {
            if !used[v] {
                continue;
            }
            if let Op::Deriv(s, order) = &vd.op {
                if *order != 1 && *order != 2 {
                    return Err(CgenError::Unsupported(format!(
                        "a derivative of order {order}"
                    )));
                }
                if !p.sensors[s.index()].differentiated {
                    return Err(CgenError::Unsupported(format!(
                        "d() of sensor `{}`, which is not marked differentiated",
                        p.sensors[s.index()].name
                    )));
                }
                deriv_used.insert((s.index(), *order));
            }
        }
        let mut hist_slot = vec![None; p.sensors.len()];
        let mut n = 0;
        for (i, s) in p.sensors.iter().enumerate() {
            if s.differentiated {
                hist_slot[i] = Some(n);
                n += 1;
            }
        }
        let nf = p.forces.len();
        let no = p.outputs.len();
        let mut offset = nf + 1 + no;
        let mut emits = Vec::new();
        let mut emit_sites = Vec::new();
        for e in sites {
            emits.push(EmitSite { event: e, offset });
            emit_sites.push(offset);
            offset += 1 + p.events[e.index()].args.len();
        }
        let layout = OutLayout {
            len: offset,
            forces: 0,
            total: nf,
            outputs: nf + 1,
            emits,
        };
        Ok(Gen {
            fp,
            p,
            config,
            stem,
            mac,
            used,
            hist_slot,
            deriv_used,
            layout,
            emit_sites,
            body: String::new(),
            next_site: 0,
        })
    }

    fn run(mut self) -> Result<CSource, CgenError> {
        let header = self.header()?;
        let source = self.source()?;
        Ok(CSource {
            header,
            source,
            stem: self.stem,
            layout: self.layout,
        })
    }

    fn n_hist(&self) -> usize {
        self.hist_slot.iter().flatten().count()
    }

    fn banner(&self, what: &str) -> String {
        let p = self.p;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "/* {what} for the Tactus instrument `{}`, generated by `tactus build --target c`.",
            p.name
        );
        if let Some(src) = &self.config.source_name {
            let _ = writeln!(s, " * Source: {src}");
        }
        if !self.config.overrides.is_empty() {
            let _ = writeln!(
                s,
                " * Param overrides: {}",
                self.config.overrides.join(", ")
            );
        }
        let _ = write!(
            s,
            " * Sample rate: {} Hz (the dynamics are discretised for it).
 *
 * Arithmetic: 32-bit fixed point, bit-exact with the Tactus fixed interpreter
 * (tactus_runtime::fixed). A word `raw` with F fraction bits (Q(31-F).F) stands for
 * raw * 2^-F in SI units. Every operation computes the exact result from its operands'
 * exact values, rounds it once to its result format, half up (floor(v * 2^F + 1/2)),
 * and saturates to [INT32_MIN, INT32_MAX]. Exceptions: a multiplication planned for MULS
 * floors its operands by the planned shifts first; division by a run-time value truncates
 * toward zero (x/0 saturates to the sign of x); a comparison with a constant compares
 * exact values; sqrt and exp are the integer algorithms of tactus_runtime::fixed. State
 * writes also saturate to the state's declared range. Portable C99: <stdint.h> only, no
 * 128-bit integers, no reliance on implementation-defined shifts.
 */
",
            p.sample_rate_hz
        );
        s
    }

    fn header(&self) -> Result<String, CgenError> {
        let (p, fp, m, st) = (self.p, self.fp, &self.mac, &self.stem);
        let mut names = HashSet::new();
        let mut h = self.banner("Interface");
        let guard = format!("{m}_H");
        let _ = write!(
            h,
            "#ifndef {guard}\n#define {guard}\n\n#include <stdint.h>\n\n"
        );
        let mut def = |h: &mut String,
                       name: String,
                       value: String,
                       comment: String|
         -> Result<(), CgenError> {
            if !names.insert(name.clone()) {
                return Err(CgenError::NameClash(name));
            }
            let _ = writeln!(
                h,
                "#define {name} {value}{}",
                if comment.is_empty() {
                    String::new()
                } else {
                    format!(" /* {comment} */")
                }
            );
            Ok(())
        };
        def(
            &mut h,
            format!("{m}_SAMPLE_RATE_HZ"),
            format!("{}", p.sample_rate_hz),
            "update rate the dynamics assume".into(),
        )?;
        let _ = writeln!(h, "\n/* Sensors: `sensors[i]` of the update, raw words in these formats (clamped to the raw range). */");
        def(
            &mut h,
            format!("{m}_NUM_SENSORS"),
            p.sensors.len().to_string(),
            String::new(),
        )?;
        for (i, s) in p.sensors.iter().enumerate() {
            let n = format!("{m}_SENSOR_{}", upper(&s.name));
            let u = unit(Ty::Real(s.dim));
            def(
                &mut h,
                n.clone(),
                i.to_string(),
                format!("index of `{}` in sensors[]", s.name),
            )?;
            def(
                &mut h,
                format!("{n}_FRAC"),
                fp.sensor_frac[i].to_string(),
                format!("{u}, {}", q(fp.sensor_frac[i])),
            )?;
            let (lo, hi) = fp.sensor_raw_range[i];
            def(
                &mut h,
                format!("{n}_RAW_MIN"),
                lit(lo),
                format!("{} {u}", s.range.0),
            )?;
            def(
                &mut h,
                format!("{n}_RAW_MAX"),
                lit(hi),
                format!("{} {u}", s.range.1),
            )?;
        }
        let _ = writeln!(h, "\n/* The out[] array of the update: force terms, total, outputs, then one slot per emit site. */");
        def(
            &mut h,
            format!("{m}_OUT_LEN"),
            self.layout.len.to_string(),
            "words in out[]".into(),
        )?;
        def(
            &mut h,
            format!("{m}_NUM_FORCES"),
            p.forces.len().to_string(),
            String::new(),
        )?;
        for (i, f) in p.forces.iter().enumerate() {
            let n = format!("{m}_FORCE_{}", upper(&f.name));
            def(
                &mut h,
                n.clone(),
                (self.layout.forces + i).to_string(),
                format!("out[] index of force term `{}`", f.name),
            )?;
            def(
                &mut h,
                format!("{n}_FRAC"),
                fp.force_frac[i].to_string(),
                format!("{}, {}", unit(f.ty), q(fp.force_frac[i])),
            )?;
        }
        def(
            &mut h,
            format!("{m}_TOTAL"),
            self.layout.total.to_string(),
            "out[] index of the total commanded force".into(),
        )?;
        def(
            &mut h,
            format!("{m}_TOTAL_FRAC"),
            fp.total_frac.to_string(),
            format!("N, {}", q(fp.total_frac)),
        )?;
        def(
            &mut h,
            format!("{m}_NUM_OUTPUTS"),
            p.outputs.len().to_string(),
            String::new(),
        )?;
        for (i, o) in p.outputs.iter().enumerate() {
            let n = format!("{m}_OUTPUT_{}", upper(&o.name));
            def(
                &mut h,
                n.clone(),
                (self.layout.outputs + i).to_string(),
                format!("out[] index of output `{}`", o.name),
            )?;
            def(
                &mut h,
                format!("{n}_FRAC"),
                fp.output_frac[i].to_string(),
                format!("{}, {}", unit(o.ty), q(fp.output_frac[i])),
            )?;
        }
        for (i, e) in p.events.iter().enumerate() {
            for (j, (a, d)) in e.args.iter().enumerate() {
                let f = fp.event_frac[i][j];
                def(
                    &mut h,
                    format!("{m}_EVENT_{}_{}_FRAC", upper(&e.name), upper(a)),
                    f.to_string(),
                    format!(
                        "argument {j} of `{}`: {}, {}",
                        e.name,
                        unit(Ty::Real(*d)),
                        q(f)
                    ),
                )?;
            }
        }
        let mut count = vec![0usize; p.events.len()];
        for site in &self.layout.emits {
            let e = &p.events[site.event.index()];
            let k = count[site.event.index()];
            count[site.event.index()] += 1;
            def(
                &mut h,
                format!("{m}_EMIT_{}_{k}", upper(&e.name)),
                site.offset.to_string(),
                format!("out[] index of the fired flag of emit site {k} of `{}`; its {} argument(s) follow", e.name, e.args.len()),
            )?;
        }
        let _ = writeln!(h, "\n/* States (raw words in state->states[]) and modes (variant indices in state->modes[]). */");
        for (i, s) in p.states.iter().enumerate() {
            let n = format!("{m}_STATE_{}", upper(&s.name));
            def(
                &mut h,
                n.clone(),
                i.to_string(),
                format!("index of state `{}`", s.name),
            )?;
            def(
                &mut h,
                format!("{n}_FRAC"),
                fp.state_frac[i].to_string(),
                format!("{}, {}", unit(Ty::Real(s.dim)), q(fp.state_frac[i])),
            )?;
        }
        for (i, md) in p.modes.iter().enumerate() {
            let n = format!("{m}_MODE_{}", upper(&md.name));
            def(
                &mut h,
                n.clone(),
                i.to_string(),
                format!("index of mode `{}`", md.name),
            )?;
            for (j, v) in md.variants.iter().enumerate() {
                def(
                    &mut h,
                    format!("{n}_{}", upper(v)),
                    j.to_string(),
                    String::new(),
                )?;
            }
        }
        if !fp.param_words.is_empty() {
            let _ = writeln!(h, "\n/* Run-time params: the words of `params[]` in the state (one program, a param block per key). */");
        }
        for (i, w) in fp.param_words.iter().enumerate() {
            let d = &p.params[w.param.index()];
            let (lo, hi) = d.runtime.unwrap_or((d.value, d.value));
            def(
                &mut h,
                format!("{m}_PARAM_{i}_FRAC"),
                w.frac.to_string(),
                format!(
                    "`{}` in [{lo:e}, {hi:e}] {}, {}",
                    d.name,
                    unit(Ty::Real(d.dim)),
                    q(w.frac)
                ),
            )?;
        }
        let cnt = |n: usize| n.max(1);
        let fp_params = p.runtime_params().count();
        let (ns, nm, ne, nh, np) = (
            p.states.len(),
            p.modes.len(),
            p.edges.len(),
            self.n_hist(),
            p.forces.len() + 1 + p.outputs.len(),
        );
        let _ = write!(
            h,
            "
/* Everything one instance remembers between samples (one per key). Arrays have at least
 * one element (C99 has no empty arrays); the extra element is unused.
 *   states[i]       raw word of state i, in {m}_STATE_<NAME>_FRAC, within its declared range
 *   modes[i]        current variant index of mode i ({m}_MODE_<NAME>_<VARIANT>)
 *   edges[i]        condition of the i-th `on` handler at the previous sample (0/1)
 *   hist_pos[i]     0 before the first sample, then 4 x (1 + the slot of the newest reading
 *                   in the i-th ring below), the slot counting down from 2N to 0
 *   params[i]       (only with run-time params) the key's param block: set it before
 *                   init (which leaves it alone); word i in {m}_PARAM_<i>_FRAC
 *   hist[i][{hlen2}]     raw readings of the i-th differentiated sensor for d()/d2(): a ring of
 *                   2N+1 = {hlen} words (N = {WINDOW}) kept twice (slots k and k + {hlen} hold one
 *                   reading), newest at slot hist_pos[i]/4 - 1, the one j samples earlier at
 *                   slot hist_pos[i]/4 - 1 + j (j <= 2N, no wrap); the first sample (at slot
 *                   2N) sets the slots 2N+1 .. 4N, which hold the readings before it, to its
 *                   reading
 *   published[]     force terms, total and outputs as last computed (copied to out[])
 */
struct tactus_{st}_state {{
    uint8_t modes[{}];
    uint8_t edges[{}];{}
    uint8_t hist_pos[{}];
    int32_t states[{}];{}
    int32_t hist[{}][{}];
    int32_t published[{}];
}};

/* Puts an instance at the initial state (states, modes, edges false, empty history). */
void tactus_{st}_init(struct tactus_{st}_state *s);

/* Runs one sample.
 *   sensors: {m}_NUM_SENSORS raw words, sensor i in {m}_SENSOR_<NAME>_FRAC fraction bits;
 *            each is clamped to [{m}_SENSOR_<NAME>_RAW_MIN, _RAW_MAX] first.
 *   out:     {m}_OUT_LEN words: out[{m}_FORCE_<NAME>] each force term (N, _FRAC),
 *            out[{m}_TOTAL] the total commanded force (N, {m}_TOTAL_FRAC),
 *            out[{m}_OUTPUT_<NAME>] each output (_FRAC), then for each emit site
 *            out[{m}_EMIT_<EVENT>_<k>] = 1 if it fired this sample (else 0), followed by
 *            the event's arguments ({m}_EVENT_<EVENT>_<ARG>_FRAC; 0 if not fired).
 *            Sites are numbered in program order, which is the order they fire in.
 */
void tactus_{st}_update(struct tactus_{st}_state *s, const int32_t *sensors, int32_t *out);

#endif /* {guard} */
",
            cnt(nm),
            cnt(ne),
            match (4 - (cnt(nm) + cnt(ne)) % 4) % 4 {
                0 => String::new(),
                k => format!("\n    uint8_t pad_[{k}];  /* hist_pos starts a word */"),
            },
            cnt(nh),
            cnt(ns),
            match fp_params {
                0 => String::new(),
                k => format!("\n    int32_t params[{k}];"),
            },
            cnt(nh),
            2 * (2 * WINDOW + 1),
            np,
            hlen = 2 * WINDOW + 1,
            hlen2 = 2 * (2 * WINDOW + 1),
        );
        Ok(h)
    }

    fn line(&mut self, depth: usize, text: &str) {
        for _ in 0..depth {
            self.body.push_str("    ");
        }
        self.body.push_str(text);
        self.body.push('\n');
    }

    fn source(&mut self) -> Result<String, CgenError> {
        let (p, fp) = (self.p, self.fp);
        let st = self.stem.clone();
        let hlen = 2 * WINDOW + 1;
        let mut c = self.banner("Implementation");
        let _ = write!(c, "#include \"{st}.h\"\n\n");
        c.push_str(prim::RUNTIME);
        // init
        let _ = write!(
            c,
            "\nvoid tactus_{st}_init(struct tactus_{st}_state *s) {{\n"
        );
        let _ = writeln!(c, "    int i, j;");
        let _ = writeln!(c, "    int32_t *w = &s->hist[0][0];");
        let _ = writeln!(c, "    for (i = 0; i < (int)(sizeof s->states / sizeof s->states[0]); i++) s->states[i] = 0;");
        let _ = writeln!(
            c,
            "    for (i = 0; i < (int)sizeof s->modes; i++) s->modes[i] = 0;"
        );
        let _ = writeln!(
            c,
            "    for (i = 0; i < (int)sizeof s->edges; i++) s->edges[i] = 0;"
        );
        let _ = writeln!(c, "    for (i = 0; i < (int)sizeof s->hist_pos; i++) {{");
        let _ = writeln!(c, "        s->hist_pos[i] = 0;");
        let _ = writeln!(
            c,
            "        for (j = 0; j < {}; j++) w[i * {} + j] = 0;\n    }}",
            2 * hlen,
            2 * hlen
        );
        let _ = writeln!(c, "    for (i = 0; i < (int)(sizeof s->published / sizeof s->published[0]); i++) s->published[i] = 0;");
        for (i, (sd, init)) in p.states.iter().zip(&fp.state_init).enumerate() {
            let _ = writeln!(
                c,
                "    s->states[{i}] = {}; /* {} = {} */",
                lit(*init),
                sd.name,
                sd.init
            );
        }
        for (i, md) in p.modes.iter().enumerate() {
            let _ = writeln!(
                c,
                "    s->modes[{i}] = {}; /* {} = {} */",
                md.init,
                md.name,
                md.variants.get(md.init as usize).map_or("?", |v| v)
            );
        }
        c.push_str("}\n");
        // update
        let _ = write!(c, "\nvoid tactus_{st}_update(struct tactus_{st}_state *s, const int32_t *sensors, int32_t *out) {{\n");
        self.body.clear();
        self.line(1, "int i;");
        // 1. sensors: clamp, then push the differentiator histories.
        for (i, sd) in p.sensors.iter().enumerate() {
            let (lo, hi) = fp.sensor_raw_range[i];
            self.line(
                1,
                &format!("int32_t s{i} = sensors[{i}]; /* {} */", sd.name),
            );
            // (A bound at the end of the word range needs no test, and C compilers warn.)
            if lo != i32::MIN {
                self.line(1, &format!("if (s{i} < {}) s{i} = {};", lit(lo), lit(lo)));
            }
            if hi != i32::MAX {
                self.line(1, &format!("if (s{i} > {}) s{i} = {};", lit(hi), lit(hi)));
            }
            if let Some(h) = self.hist_slot[i] {
                // The ring kept twice, its position counting down (the layout's
                // `hist_pos`, 0 before the first sample): the readings N and 2N samples
                // back need no wrap.
                self.line(1, &format!("int q{h} = s->hist_pos[{h}] - 4;"));
                self.line(1, &format!("if (q{h} <= 0) {{"));
                self.line(2, &format!("if (q{h} < 0)"));
                self.line(
                    3,
                    &format!(
                        "for (i = {}; i < {}; i++) s->hist[{h}][i] = s{i};",
                        StateLayout::primed_slots().start,
                        StateLayout::primed_slots().end
                    ),
                );
                self.line(2, &format!("q{h} = {};", 4 * hlen));
                self.line(1, "}");
                self.line(1, &format!("s->hist_pos[{h}] = (uint8_t)q{h};"));
                self.line(1, &format!("int32_t *h{h} = &s->hist[{h}][q{h} / 4 - 1];"));
                self.line(1, &format!("h{h}[0] = s{i};"));
                self.line(1, &format!("h{h}[{hlen}] = s{i};"));
                let (ago0, agon, ago2n) = (
                    format!("(int64_t)h{h}[0]"),
                    format!("(int64_t)h{h}[{WINDOW}]"),
                    format!("(int64_t)h{h}[{}]", 2 * WINDOW),
                );
                if self.deriv_used.contains(&(i, 1)) {
                    self.line(1, &format!("int64_t d{i}_1 = {ago0} - {agon};"));
                }
                if self.deriv_used.contains(&(i, 2)) {
                    self.line(
                        1,
                        &format!("int64_t d{i}_2 = {ago0} - 2 * {agon} + {ago2n};"),
                    );
                }
            }
        }
        self.line(1, "(void)sensors;");
        self.line(1, "(void)i;");
        for site in self.layout.emits.clone() {
            let n = 1 + p.events[site.event.index()].args.len();
            self.line(
                1,
                &format!("for (i = 0; i < {n}; i++) out[{} + i] = 0;", site.offset),
            );
        }
        // 2-4. the body.
        self.stmts(&p.body, 1)?;
        let np = p.forces.len() + 1 + p.outputs.len();
        self.line(
            1,
            &format!("for (i = 0; i < {np}; i++) out[i] = s->published[i];"),
        );
        c.push_str(&self.body);
        c.push_str("}\n");
        Ok(c)
    }

    fn stmts(&mut self, stmts: &[Stmt], depth: usize) -> Result<(), CgenError> {
        let (p, fp) = (self.p, self.fp);
        for s in stmts {
            match s {
                Stmt::Def(v) => {
                    if self.used[v.index()] {
                        let e = self.expr(*v)?;
                        self.line(depth, &format!("int32_t v{} = {e};", v.0));
                    }
                }
                Stmt::SetState(sid, v) => {
                    let i = sid.index();
                    let (lo, hi) = fp.state_raw_range[i];
                    let conv =
                        prim::convert(&format!("v{}", v.0), fp.frac[v.index()], fp.state_frac[i]);
                    self.line(depth, "{");
                    self.line(
                        depth + 1,
                        &format!("int32_t t = {conv}; /* {} */", p.states[i].name),
                    );
                    if lo != i32::MIN {
                        self.line(depth + 1, &format!("if (t < {}) t = {};", lit(lo), lit(lo)));
                    }
                    if hi != i32::MAX {
                        self.line(depth + 1, &format!("if (t > {}) t = {};", lit(hi), lit(hi)));
                    }
                    self.line(depth + 1, &format!("s->states[{i}] = t;"));
                    self.line(depth, "}");
                }
                Stmt::SetMode(m, i) => {
                    let md = &p.modes[m.index()];
                    self.line(
                        depth,
                        &format!(
                            "s->modes[{}] = {i}; /* {} = {} */",
                            m.0,
                            md.name,
                            md.variants.get(*i as usize).map_or("?", |v| v)
                        ),
                    );
                }
                Stmt::SetEdge(e, v) => {
                    self.line(depth, &format!("s->edges[{}] = v{} != 0;", e.0, v.0))
                }
                Stmt::If(c, body) => {
                    self.line(depth, &format!("if (v{}) {{", c.0));
                    self.stmts(body, depth + 1)?;
                    self.line(depth, "}");
                }
                Stmt::Emit(e, args) => {
                    let off = self.emit_sites[self.next_site];
                    self.next_site += 1;
                    let ed = &p.events[e.index()];
                    self.line(depth, &format!("out[{off}] = 1; /* emit {} */", ed.name));
                    for (j, (a, f)) in args.iter().zip(&fp.event_frac[e.index()]).enumerate() {
                        let conv = prim::convert(&format!("v{}", a.0), fp.frac[a.index()], *f);
                        self.line(depth, &format!("out[{}] = {conv};", off + 1 + j));
                    }
                }
                Stmt::Force(f, v) => {
                    let name = &p.forces[f.index()].name;
                    self.line(
                        depth,
                        &format!(
                            "s->published[{}] = v{}; /* force {name} */",
                            self.layout.forces + f.index(),
                            v.0
                        ),
                    );
                }
                Stmt::Output(o, v) => {
                    let name = &p.outputs[o.index()].name;
                    self.line(
                        depth,
                        &format!(
                            "s->published[{}] = v{}; /* output {name} */",
                            self.layout.outputs + o.index(),
                            v.0
                        ),
                    );
                }
                Stmt::Total(v) => self.line(
                    depth,
                    &format!(
                        "s->published[{}] = v{}; /* total */",
                        self.layout.total, v.0
                    ),
                ),
            }
        }
        Ok(())
    }

    /// The C expression of a value's definition.
    fn expr(&self, v: Value) -> Result<String, CgenError> {
        let (p, fp) = (self.p, self.fp);
        let fr = fp.frac[v.index()];
        let name = |x: &Value| format!("v{}", x.0);
        let f = |x: &Value| fp.frac[x.index()];
        let real = |x: &Value| matches!(p.values[x.index()].ty, Ty::Real(_));
        Ok(match &p.values[v.index()].op {
            Op::Param(_) if fp.param_word_of(v).is_some() => {
                format!("s->params[{}]", fp.param_word_of(v).unwrap_or(0))
            }
            Op::Const(_) | Op::Param(_) => lit(fp.consts[v.index()]),
            Op::BoolConst(t) => i32::from(*t).to_string(),
            Op::Variant(_, i) => i.to_string(),
            Op::Sensor(s) => prim::convert(&format!("s{}", s.0), fp.sensor_frac[s.index()], fr),
            Op::Deriv(s, order) => {
                let (lo, hi) = fp.sensor_raw_range[s.index()];
                let span = hi as i64 - lo as i64;
                let dmax = if *order == 1 { span } else { 2 * span };
                let (k, fk) = fp.deriv_gain[*order as usize - 1];
                prim::deriv(
                    &format!("d{}_{order}", s.0),
                    dmax,
                    k,
                    fr - (fp.sensor_frac[s.index()] + fk),
                )
            }
            Op::State(s) => {
                prim::convert(&format!("s->states[{}]", s.0), fp.state_frac[s.index()], fr)
            }
            Op::Mode(m) => format!("(int32_t)s->modes[{}]", m.0),
            Op::Edge(e) => format!("(int32_t)s->edges[{}]", e.0),
            Op::Neg(x) => prim::neg(&name(x), f(x), fr),
            Op::Not(x) => format!("!{}", name(x)),
            Op::Arith(o, x, y) => match o {
                ArithOp::Add => prim::add(&name(x), f(x), &name(y), f(y), fr, false),
                ArithOp::Sub => prim::add(&name(x), f(x), &name(y), f(y), fr, true),
                ArithOp::Mul => {
                    product(fp.mul_kind[v.index()], (name(x), f(x)), (name(y), f(y)), fr)
                }
                ArithOp::Div => match fp.recip[v.index()] {
                    Some((r, fr_r)) => {
                        let prod =
                            product(fp.mul_kind[v.index()], (name(x), f(x)), (lit(r), fr_r), fr);
                        // The divisor's word is not read: keep it used for the C compiler.
                        format!("((void){}, {})", name(y), prod)
                    }
                    None => prim::div(&name(x), f(x), &name(y), f(y), fp.div_shift[v.index()], fr),
                },
            },
            Op::Cmp(o, x, y) => match (fp.exact_const(*x), fp.exact_const(*y)) {
                (_, Some(k)) if real(x) => format!(
                    "((void){}, {})",
                    name(y),
                    prim::cmp_const(*o, &name(x), f(x), k, false)
                ),
                (Some(k), _) if real(y) => format!(
                    "((void){}, {})",
                    name(x),
                    prim::cmp_const(*o, &name(y), f(y), k, true)
                ),
                _ => prim::cmp(*o, &name(x), f(x), &name(y), f(y)),
            },
            Op::And(x, y) => format!("({} && {})", name(x), name(y)),
            Op::Or(x, y) => format!("({} || {})", name(x), name(y)),
            Op::Select(c, x, y) => match p.values[v.index()].ty {
                Ty::Real(_) => format!(
                    "({} ? {} : {})",
                    name(c),
                    prim::convert(&name(x), f(x), fr),
                    prim::convert(&name(y), f(y), fr)
                ),
                _ => format!("({} ? {} : {})", name(c), name(x), name(y)),
            },
            Op::Call(func, x, y) => {
                let (a, fa) = (name(x), f(x));
                match func {
                    Builtin::Abs => format!(
                        "({a} < 0 ? {} : {})",
                        prim::neg(&a, fa, fr),
                        prim::convert(&a, fa, fr)
                    ),
                    Builtin::Sqrt => prim::sqrt(&a, fa, fr),
                    Builtin::Exp => prim::exp(&a, fa, fr),
                    Builtin::Min | Builtin::Max => {
                        let (c, fc) = match y {
                            Some(y) => (name(y), f(y)),
                            None => (a.clone(), fa),
                        };
                        let op = if *func == Builtin::Min {
                            CmpOp::Le
                        } else {
                            CmpOp::Ge
                        };
                        format!(
                            "({} ? {} : {})",
                            prim::cmp(op, &a, fa, &c, fc),
                            prim::convert(&a, fa, fr),
                            prim::convert(&c, fc, fr)
                        )
                    }
                }
            }
        })
    }
}
