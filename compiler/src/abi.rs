//! The interface every backend of a fixed-point program implements, and every caller of it
//! relies on: the symbol names `tactus_<stem>_init` / `tactus_<stem>_update`, the state
//! struct's byte layout ([`StateLayout`]), the `out` array's layout ([`OutLayout`]) and the C
//! header that describes all of it ([`Interface`]). The C backend ([`crate::cgen`]) and the
//! Thumb backend ([`crate::thumb`]) both import it, and so do the firmware's callers, so one
//! header describes the code of either.
//!
//! ```c
//! void tactus_<stem>_init(struct tactus_<stem>_state *s);
//! void tactus_<stem>_update(struct tactus_<stem>_state *s, const int32_t *sensors, int32_t *out);
//! ```
//!
//! Everything the update remembers between samples lives in one caller-owned struct (no
//! globals, no allocation), so one instance per key is one struct per key. The byte arrays
//! (modes, edges, then the history positions from a word of their own) come first, within
//! `LDRB`'s 31-byte reach of the state pointer, then the words. A key's param block lives in
//! the struct (`params[]` after the states; written before `init`, which leaves it alone),
//! so every engine reads a run-time param as one load from the state pointer.

use crate::fixed::{q_name as q, FixedProgram};
use crate::ir::*;
use std::collections::HashSet;
use std::fmt::{self, Write as _};
use tactus_runtime::differentiator::WINDOW;

/// `tactus_<stem>_init`: puts an instance at its initial state.
pub fn init_symbol(stem: &str) -> String {
    format!("tactus_{stem}_init")
}

/// `tactus_<stem>_update`: runs one sample.
pub fn update_symbol(stem: &str) -> String {
    format!("tactus_{stem}_update")
}

/// `tactus_<stem>_state`: the C struct of one instance.
pub fn state_struct(stem: &str) -> String {
    format!("tactus_{stem}_state")
}

/// The C identifier stem of a program: its name in lower snake case (`esc.f` → `esc_f`).
pub fn stem(p: &Program) -> String {
    upper(&p.name).to_ascii_lowercase()
}

/// The interface of one fixed-point program: its identifier stem, its macro prefix, the
/// layout of its `out` array and its C header.
#[derive(Clone, Debug)]
pub struct Interface {
    /// The C identifier stem ([`stem`]): the functions are [`init_symbol`] and
    /// [`update_symbol`] of it, the header is `<stem>.h`.
    pub stem: String,
    /// The prefix of the header's macros (`TACTUS_<NAME>`).
    pub mac: String,
    /// Where the update writes what.
    pub layout: OutLayout,
    /// The header: state struct, prototypes, Q-format and layout macros.
    pub header: String,
}

impl Interface {
    /// The interface of `fp`, the header annotated with `config`.
    ///
    /// Errors: a mode with more than 256 variants, a derivative the differentiators do not
    /// provide, two declarations with one C name ([`InterfaceError`]).
    pub fn new(fp: &FixedProgram, config: &CConfig) -> Result<Self, InterfaceError> {
        let p = &fp.program;
        for m in &p.modes {
            if m.variants.len() > 256 {
                return Err(InterfaceError::TooManyVariants {
                    mode: m.name.clone(),
                    count: m.variants.len(),
                });
            }
        }
        let (used, sites) = live_values(p);
        for (v, vd) in p.values.iter().enumerate() {
            if !used[v] {
                continue;
            }
            if let Op::Deriv(s, order) = &vd.op {
                if *order != 1 && *order != 2 {
                    return Err(InterfaceError::Unsupported(format!(
                        "a derivative of order {order}"
                    )));
                }
                if !p.sensors[s.index()].differentiated {
                    return Err(InterfaceError::Unsupported(format!(
                        "d() of sensor `{}`, which is not marked differentiated",
                        p.sensors[s.index()].name
                    )));
                }
            }
        }
        let mut it = Interface {
            stem: stem(p),
            mac: format!("TACTUS_{}", upper(&p.name)),
            layout: OutLayout::new(p, &sites),
            header: String::new(),
        };
        it.header = it.header(fp, config)?;
        Ok(it)
    }

    fn header(&self, fp: &FixedProgram, config: &CConfig) -> Result<String, InterfaceError> {
        let (p, m, st) = (&fp.program, &self.mac, &self.stem);
        let mut names = HashSet::new();
        let mut h = banner(p, config, "Interface");
        let guard = format!("{m}_H");
        let _ = write!(
            h,
            "#ifndef {guard}\n#define {guard}\n\n#include <stdint.h>\n\n"
        );
        let mut def = |h: &mut String,
                       name: String,
                       value: String,
                       comment: String|
         -> Result<(), InterfaceError> {
            if !names.insert(name.clone()) {
                return Err(InterfaceError::NameClash(name));
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
            p.sensors.iter().filter(|s| s.differentiated).count(),
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
struct {state} {{
    uint8_t modes[{}];
    uint8_t edges[{}];{}
    uint8_t hist_pos[{}];
    int32_t states[{}];{}
    int32_t hist[{}][{}];
    int32_t published[{}];
}};

/* Puts an instance at the initial state (states, modes, edges false, empty history). */
void {init}(struct {state} *s);

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
void {update}(struct {state} *s, const int32_t *sensors, int32_t *out);

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
            init = init_symbol(st),
            update = update_symbol(st),
            state = state_struct(st),
            hlen2 = 2 * (2 * WINDOW + 1),
        );
        Ok(h)
    }
}

/// The comment that opens a generated file: `what` ("Interface", "Implementation") for
/// program `p`, its source and overrides from `config`, the sample rate and the arithmetic.
pub fn banner(p: &Program, config: &CConfig, what: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "/* {what} for the Tactus instrument `{}`, generated by `tactus build --target c`.",
        p.name
    );
    if let Some(src) = &config.source_name {
        let _ = writeln!(s, " * Source: {src}");
    }
    if !config.overrides.is_empty() {
        let _ = writeln!(s, " * Param overrides: {}", config.overrides.join(", "));
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

impl OutLayout {
    /// The layout for program `p` whose `emit` statements, in program order, emit `sites`
    /// ([`live_values`]): force terms, total, outputs, then per site its fired flag and
    /// arguments.
    pub fn new(p: &Program, sites: &[EventId]) -> Self {
        let nf = p.forces.len();
        let no = p.outputs.len();
        let mut offset = nf + 1 + no;
        let mut emits = Vec::new();
        for &e in sites {
            emits.push(EmitSite { event: e, offset });
            offset += 1 + p.events[e.index()].args.len();
        }
        OutLayout {
            len: offset,
            forces: 0,
            total: nf,
            outputs: nf + 1,
            emits,
        }
    }
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

/// Why a program has no interface (and so no C and no Thumb code).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum InterfaceError {
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

impl fmt::Display for InterfaceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            InterfaceError::TooManyVariants { mode, count } => {
                write!(f, "mode `{mode}` has {count} variants; the C backend stores a mode in a uint8_t (at most 256)")
            }
            InterfaceError::NameClash(n) => write!(
                f,
                "two declarations map to the same C name `{n}`; rename one"
            ),
            InterfaceError::Unsupported(what) => write!(f, "the C backend does not support {what}"),
        }
    }
}

impl std::error::Error for InterfaceError {}

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

/// An `int32_t` literal (C has no negative literals; `-2147483648` is not an `int`).
pub(crate) fn lit(x: i32) -> String {
    if x == i32::MIN {
        "INT32_MIN".into()
    } else {
        x.to_string()
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
