//! What an editor asks about a place in a source file: which declaration a name denotes,
//! where a declaration is used, what is declared around a place (outline, completion), and
//! what the compiler knows of a term (unit, range, fixed-point format, error bound).
//!
//! Nothing here parses or checks again. Names come from the resolver itself
//! ([`crate::lower::lower_indexed`] records every name it resolves, with the span of the
//! declaration it found) and from the AST's spans; units from the IR's types; ranges,
//! formats and error bounds from the format plan ([`crate::fixed::FixedProgram`]) and its
//! precision report ([`crate::fixed::report::analyse`]), the ones `tactus check --report
//! precision` prints. Spans are byte ranges into the source, as everywhere in the compiler.

use crate::ast::{self, Decl, Span};
use crate::fixed::q_name;
use crate::fixed::report::Precision;
use crate::fixed::FixedProgram;
use crate::ir::{self, Program, Ty};
use crate::sources::{FileId, SourceMap};

/// The names the resolver resolved: each place a name is written, and the span of the name
/// of the declaration it denotes. Sorted and without duplicates (a component instanced
/// three times resolves its names three times, at the same spans).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NameIndex {
    refs: Vec<(Span, Span)>,
}

impl NameIndex {
    /// Adds resolved names: (where written, the declaration's name span).
    pub fn add(&mut self, refs: Vec<(Span, Span)>) {
        self.refs.extend(refs);
        self.refs
            .sort_by_key(|(at, def)| (at.start, at.end, def.start, def.end));
        self.refs.dedup();
    }

    /// Whether nothing was resolved (the file did not get as far as name resolution).
    pub fn is_empty(&self) -> bool {
        self.refs.is_empty()
    }

    /// Every resolved name: (where written, the declaration's name span).
    pub fn refs(&self) -> &[(Span, Span)] {
        &self.refs
    }

    /// The declaration the name at byte `offset` denotes: the span of its name. A place on
    /// a declaration's own name gives that name; `decls` are the declarations of the file
    /// ([`symbols`], flattened), so that a declaration never used is found too.
    pub fn definition_at(&self, offset: usize, decls: &[Symbol]) -> Option<Span> {
        let hit = |s: &Span| s.start <= offset && offset <= s.end;
        self.refs
            .iter()
            .filter(|(at, _)| hit(at))
            .min_by_key(|(at, _)| at.end - at.start)
            .map(|(_, def)| def.clone())
            .or_else(|| {
                decls
                    .iter()
                    .filter(|d| hit(&d.name_span))
                    .min_by_key(|d| d.name_span.end - d.name_span.start)
                    .map(|d| d.name_span.clone())
            })
    }

    /// Where the declaration named at `def` is used, in source order (not the declaration
    /// itself).
    pub fn references(&self, def: &Span) -> Vec<Span> {
        let mut v: Vec<Span> = self
            .refs
            .iter()
            .filter(|(at, d)| d == def && at != def)
            .map(|(at, _)| at.clone())
            .collect();
        v.sort_by_key(|s| (s.start, s.end));
        v.dedup();
        v
    }
}

/// What a declaration declares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SymbolKind {
    /// `instrument NAME { … }`
    Instrument,
    /// `component NAME { … }`
    Component,
    /// `sensor NAME in …`
    Sensor,
    /// `input NAME: TYPE` (components)
    Input,
    /// `param NAME = …`
    Param,
    /// `state NAME = … in […]`
    State,
    /// `mode NAME { … }`
    Mode,
    /// One variant of a mode.
    Variant,
    /// `let NAME = …`
    Let,
    /// `force NAME = …`
    Force,
    /// `output NAME = …`
    Output,
    /// `use NAME = COMPONENT(…)`: a component instance.
    Instance,
    /// `solve NAME in […] { … }`
    Solve,
    /// The index of `for VAR in LO..HI { … }`.
    Index,
}

impl SymbolKind {
    /// The word the language uses for it.
    pub fn word(self) -> &'static str {
        match self {
            SymbolKind::Instrument => "instrument",
            SymbolKind::Component => "component",
            SymbolKind::Sensor => "sensor",
            SymbolKind::Input => "input",
            SymbolKind::Param => "param",
            SymbolKind::State => "state",
            SymbolKind::Mode => "mode",
            SymbolKind::Variant => "variant",
            SymbolKind::Let => "let",
            SymbolKind::Force => "force",
            SymbolKind::Output => "output",
            SymbolKind::Instance => "use",
            SymbolKind::Solve => "solve",
            SymbolKind::Index => "for",
        }
    }

    /// Whether a component's declaration of this kind is visible from outside it
    /// (`esc.f`): the resolver's rule (outputs, forces, states, modes, params, instances).
    pub fn visible_outside(self) -> bool {
        matches!(
            self,
            SymbolKind::Param
                | SymbolKind::State
                | SymbolKind::Mode
                | SymbolKind::Force
                | SymbolKind::Output
                | SymbolKind::Instance
        )
    }
}

/// One declaration of a file, for an outline and for completion.
#[derive(Clone, Debug, PartialEq)]
pub struct Symbol {
    /// The name as written.
    pub name: String,
    /// What it declares.
    pub kind: SymbolKind,
    /// The whole declaration.
    pub span: Span,
    /// Its name.
    pub name_span: Span,
    /// A one-line summary: the component an instance uses, a mode's variants, ….
    pub detail: String,
    /// Declarations inside it (a body's, a mode's variants, a loop's).
    pub children: Vec<Symbol>,
}

impl Symbol {
    /// This symbol and all below it, depth first.
    pub fn flatten(&self) -> Vec<&Symbol> {
        let mut out = vec![self];
        for c in &self.children {
            out.extend(c.flatten());
        }
        out
    }
}

fn join(a: &Span, b: &Span) -> Span {
    a.start.min(b.start)..a.end.max(b.end)
}

fn sym(name: &ast::Name, kind: SymbolKind, end: Option<&Span>, detail: String) -> Symbol {
    Symbol {
        name: name.node.clone(),
        kind,
        span: end.map_or(name.span.clone(), |e| join(&name.span, e)),
        name_span: name.span.clone(),
        detail,
        children: Vec::new(),
    }
}

fn decl_symbols(decls: &[Decl], src: &Source, out: &mut Vec<Symbol>) {
    let text = |s: &Span| src.get(s).unwrap_or("").trim().to_string();
    for d in decls {
        match d {
            Decl::Sensor { name, range, .. } => {
                let r = range.as_ref().map(|r| &r.span);
                let detail = r.map_or(String::new(), |r| format!("in {}", text(r)));
                out.push(sym(name, SymbolKind::Sensor, r, detail));
            }
            Decl::VectorSensor { name, span, .. } => {
                out.push(sym(name, SymbolKind::Sensor, Some(span), text(span)));
            }
            Decl::Input { name, ty } => {
                let t = ty.as_ref().map(|t| &t.span);
                let detail = t.map_or(String::new(), |t| format!(": {}", text(t)));
                out.push(sym(name, SymbolKind::Input, t, detail));
            }
            Decl::Param { name, value, .. } => {
                out.push(sym(
                    name,
                    SymbolKind::Param,
                    Some(&value.span),
                    format!("= {}", text(&value.span)),
                ));
            }
            Decl::State {
                name, init, range, ..
            } => {
                let end = range.as_ref().map_or(&init.span, |r| &r.span);
                let detail = match range {
                    Some(r) => format!("= {} in {}", text(&init.span), text(&r.span)),
                    None => format!("= {}", text(&init.span)),
                };
                out.push(sym(name, SymbolKind::State, Some(end), detail));
            }
            Decl::Mode { name, variants, .. } => {
                let end = variants.last().map(|v| &v.span);
                let names: Vec<&str> = variants.iter().map(|v| v.node.as_str()).collect();
                let mut s = sym(
                    name,
                    SymbolKind::Mode,
                    end,
                    format!("{{ {} }}", names.join(", ")),
                );
                s.children = variants
                    .iter()
                    .map(|v| {
                        sym(
                            v,
                            SymbolKind::Variant,
                            None,
                            format!("of mode `{}`", name.node),
                        )
                    })
                    .collect();
                out.push(s);
            }
            Decl::Let { name, value, .. } => out.push(sym(
                name,
                SymbolKind::Let,
                Some(&value.span),
                format!("= {}", text(&value.span)),
            )),
            Decl::Force { name, value, .. } => out.push(sym(
                name,
                SymbolKind::Force,
                Some(&value.span),
                format!("= {}", text(&value.span)),
            )),
            Decl::VectorForce { name, span, .. } => {
                out.push(sym(name, SymbolKind::Force, Some(span), text(span)))
            }
            Decl::Output { name, value, .. } => out.push(sym(
                name,
                SymbolKind::Output,
                Some(&value.span),
                format!("= {}", text(&value.span)),
            )),
            Decl::Use {
                name,
                component,
                span,
                ..
            } => out.push(sym(
                name,
                SymbolKind::Instance,
                Some(span),
                format!("component `{}`", component.node),
            )),
            Decl::Solve { name, span, .. } => out.push(sym(
                name,
                SymbolKind::Solve,
                Some(span),
                "Newton–Raphson".into(),
            )),
            Decl::For {
                var,
                range,
                decls,
                span,
            } => {
                let mut s = sym(
                    var,
                    SymbolKind::Index,
                    Some(span),
                    format!("in {}", text(&range.span)),
                );
                decl_symbols(decls, src, &mut s.children);
                out.push(s);
            }
            Decl::Dynamics { .. }
            | Decl::Handler { .. }
            | Decl::Require { .. }
            | Decl::Tolerance { .. }
            | Decl::SolveRange { .. } => {}
        }
    }
}

/// Where [`symbols`] reads the text of a span: one file's text, or every file of a
/// program (an imported file's spans are offset by its base).
enum Source<'s> {
    Text(&'s str),
    Files(&'s SourceMap),
}

impl Source<'_> {
    fn get(&self, span: &Span) -> Option<&str> {
        match self {
            Source::Text(t) => t.get(span.clone()),
            Source::Files(m) => m.text(span),
        }
    }
}

/// The declarations of a parsed file as an outline: per instrument and component, its
/// sensors, params, states, modes (with their variants), lets, forces, outputs and
/// instances, in source order.
pub fn symbols(file: &ast::File, src: &str) -> Vec<Symbol> {
    symbols_from(file, &Source::Text(src))
}

fn symbols_from(file: &ast::File, src: &Source) -> Vec<Symbol> {
    file.items
        .iter()
        .filter_map(|item| {
            let (body, kind) = match item {
                ast::TopItem::Instrument(b) => (b, SymbolKind::Instrument),
                ast::TopItem::Component(b) => (b, SymbolKind::Component),
                ast::TopItem::Import(_) => return None,
            };
            let mut s = sym(&body.name, kind, Some(&body.span), String::new());
            decl_symbols(&body.decls, src, &mut s.children);
            Some(s)
        })
        .collect()
}

/// The names a place can use: the declarations of the instrument or component the byte
/// `offset` is in (all of its body's, at any depth of `for`), or none outside every body.
pub fn names_in_scope(outline: &[Symbol], offset: usize) -> Vec<&Symbol> {
    outline
        .iter()
        .find(|b| b.span.start <= offset && offset <= b.span.end)
        .map(|b| {
            b.children
                .iter()
                .flat_map(|c| c.flatten())
                .filter(|s| s.kind != SymbolKind::Variant)
                .collect()
        })
        .unwrap_or_default()
}

/// The members of instance `instance` seen from the body at `offset` (`esc.` completes
/// to what component `esc` uses makes visible outside it, [`SymbolKind::visible_outside`]).
pub fn members<'o>(outline: &'o [Symbol], offset: usize, instance: &str) -> Vec<&'o Symbol> {
    let Some(inst) = names_in_scope(outline, offset)
        .into_iter()
        .find(|s| s.kind == SymbolKind::Instance && s.name == instance)
    else {
        return Vec::new();
    };
    let component = inst
        .detail
        .strip_prefix("component `")
        .and_then(|d| d.strip_suffix('`'))
        .unwrap_or("");
    outline
        .iter()
        .find(|b| b.kind == SymbolKind::Component && b.name == component)
        .map(|b| {
            b.children
                .iter()
                .filter(|s| s.kind.visible_outside())
                .collect()
        })
        .unwrap_or_default()
}

/// What the compiler knows of one place, for an editor's hover.
#[derive(Clone, Debug, PartialEq)]
pub struct Facts {
    /// The source range described (a name, or the smallest term around the place).
    pub span: Span,
    /// What it is: "state `s`", "param `k` = 180 N/m", "term `k * key`".
    pub heading: String,
    /// (what, value) rows: `unit`, `declared range`, `range`, `format`, `error bound`, ….
    pub rows: Vec<(String, String)>,
    /// The comment block above the declaration, without its `//` (a component's
    /// documentation: its physics, units, sources), or empty.
    pub doc: String,
}

/// The format plan and its precision report, when the profile compiles.
#[derive(Clone, Copy)]
pub struct Plan<'a> {
    /// The plan.
    pub fixed: &'a FixedProgram,
    /// Its error bounds.
    pub precision: &'a Precision,
}

fn fmt_si(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if (1e-3..1e5).contains(&x.abs()) {
        let s = format!("{x:.6}");
        let s = s.trim_end_matches('0').trim_end_matches('.');
        s.to_string()
    } else {
        format!("{x:.4e}")
    }
}

fn unit_of(p: &Program, t: Ty) -> String {
    match t {
        Ty::Real(d) => d.to_string(),
        Ty::Bool => "a truth value".into(),
        Ty::Mode(m) => format!(
            "a variant of mode `{}`",
            p.modes.get(m.index()).map_or("?", |m| m.name.as_str())
        ),
    }
}

fn interval(lo: f64, hi: f64, t: Ty) -> String {
    let unit = match t {
        Ty::Real(d) => format!(" {}", d.unit_string()),
        _ => String::new(),
    };
    format!("[{}, {}]{unit}", fmt_si(lo), fmt_si(hi))
}

fn value_rows(p: &Program, v: ir::Value, plan: Option<Plan>, rows: &mut Vec<(String, String)>) {
    let ty = p.values[v.index()].ty;
    rows.push(("unit".into(), unit_of(p, ty)));
    let Some(plan) = plan else { return };
    // The plan's program is the lowered one after its rewrites (common terms, reciprocals):
    // the same value by its span and operation where it survived.
    let fp = plan.fixed;
    let span = &p.values[v.index()].span;
    let found = fp
        .program
        .values
        .iter()
        .enumerate()
        .rev()
        .find(|(_, d)| d.span == *span && d.ty == ty)
        .map(|(i, _)| i);
    let Some(i) = found else {
        rows.push((
            "format".into(),
            "folded into another term by the plan".into(),
        ));
        return;
    };
    let iv = fp.ranges.values[i];
    if matches!(ty, Ty::Real(_)) {
        rows.push(("range".into(), interval(iv.lo, iv.hi, ty)));
        rows.push(("format".into(), q_name(fp.frac[i])));
        let e = plan.precision.value[i];
        rows.push(("error bound".into(), error_text(e, ty, plan.precision)));
    }
}

fn error_text(e: f64, ty: Ty, pr: &Precision) -> String {
    let unit = match ty {
        Ty::Real(d) => format!(" {}", d.unit_string()),
        _ => String::new(),
    };
    if ty == Ty::Real(crate::units::Dim::FORCE) {
        format!("{:.3e}{unit} ({:.4} DAC LSB)", e, e / pr.dac_lsb_n())
    } else {
        format!("{e:.3e}{unit}")
    }
}

/// The facts of the place at byte `offset` of the main file of `sources`: of the
/// declaration a name there denotes (found through `index` and `outline`, which holds the
/// declarations of every file a name may resolve into: [`Analysis::outlines`]), else of
/// the smallest term of the lowered `program` around it. `plan` adds inferred ranges,
/// Q-formats and error bounds. `None` where nothing is known (white space, a keyword, a
/// file that did not lower).
pub fn facts_at(
    sources: &SourceMap,
    outline: &[Symbol],
    index: &NameIndex,
    program: Option<&Program>,
    plan: Option<Plan>,
    offset: usize,
) -> Option<Facts> {
    let src = sources;
    let decls: Vec<&Symbol> = outline.iter().flat_map(|s| s.flatten()).collect();
    let flat: Vec<Symbol> = decls.iter().map(|s| (*s).clone()).collect();
    let def = index.definition_at(offset, &flat);
    let at = index
        .refs()
        .iter()
        .filter(|(at, _)| at.start <= offset && offset <= at.end)
        .min_by_key(|(at, _)| at.end - at.start)
        .map(|(at, _)| at.clone())
        .or_else(|| def.clone());
    if let (Some(def), Some(at)) = (def, at) {
        if let Some(d) = decls.iter().find(|d| d.name_span == def) {
            return Some(decl_facts(src, d, program, plan, at));
        }
    }
    let p = program?;
    let (v, data) = p
        .values
        .iter()
        .enumerate()
        .filter(|(_, d)| d.span.start <= offset && offset < d.span.end.max(d.span.start + 1))
        .min_by_key(|(i, d)| (d.span.end - d.span.start, usize::MAX - i))?;
    let mut rows = Vec::new();
    value_rows(p, ir::Value(v as u32), plan, &mut rows);
    Some(Facts {
        span: data.span.clone(),
        heading: format!("term `{}`", src.text(&data.span).unwrap_or("").trim()),
        rows,
        doc: String::new(),
    })
}

/// The comment block right above the declaration at `span` (each line's `//` and one space
/// taken off), joined into lines.
fn doc_above(src: &SourceMap, span: &Span) -> String {
    let (id, local) = src.locate(span);
    let text = &src.get(id).text;
    let mut lines: Vec<&str> = text[..local.start.min(text.len())]
        .lines()
        .rev()
        .skip(1) // the declaration's own line, up to its start
        .take_while(|l| l.trim_start().starts_with("//"))
        .collect();
    lines.reverse();
    lines
        .iter()
        .map(|l| {
            let t = l.trim_start().trim_start_matches("//");
            t.strip_prefix(' ').unwrap_or(t)
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn decl_facts(
    src: &SourceMap,
    d: &Symbol,
    program: Option<&Program>,
    plan: Option<Plan>,
    at: Span,
) -> Facts {
    let mut rows: Vec<(String, String)> = Vec::new();
    let heading = format!("{} `{}` {}", d.kind.word(), d.name, d.detail)
        .trim_end()
        .to_string();
    let def = &d.name_span;
    if let Some(p) = program {
        match d.kind {
            SymbolKind::State => {
                for (i, s) in p.states.iter().enumerate().filter(|(_, s)| s.span == *def) {
                    let ty = Ty::Real(s.dim);
                    if d.name != s.name {
                        rows.push(("instance".into(), format!("`{}`", s.name)));
                    }
                    rows.push(("unit".into(), unit_of(p, ty)));
                    rows.push(("declared range".into(), interval(s.range.0, s.range.1, ty)));
                    rows.push((
                        "initial value".into(),
                        format!("{} {}", fmt_si(s.init), s.dim.unit_string()),
                    ));
                    if let Some(pl) = plan {
                        let fp = pl.fixed;
                        if let Some(Some((lo, hi))) = fp.narrowed.get(i) {
                            rows.push((
                                "narrowed to".into(),
                                format!(
                                    "{} (what it is assigned; declared {})",
                                    interval(
                                        fp.program.states[i].range.0,
                                        fp.program.states[i].range.1,
                                        ty
                                    ),
                                    interval(*lo, *hi, ty)
                                ),
                            ));
                        }
                        rows.push(("format".into(), q_name(fp.state_frac[i])));
                        let acc = pl.precision.accumulating[i];
                        rows.push((
                            "error bound".into(),
                            format!(
                                "{}{}",
                                error_text(pl.precision.state[i], ty, pl.precision),
                                if acc {
                                    " per sample (accumulates: integrated state)"
                                } else {
                                    ""
                                }
                            ),
                        ));
                    }
                }
            }
            SymbolKind::Sensor => {
                for (i, s) in p.sensors.iter().enumerate().filter(|(_, s)| s.span == *def) {
                    let ty = Ty::Real(s.dim);
                    rows.push(("unit".into(), unit_of(p, ty)));
                    rows.push(("declared range".into(), interval(s.range.0, s.range.1, ty)));
                    if let Some(pl) = plan {
                        rows.push(("format".into(), q_name(pl.fixed.sensor_frac[i])));
                    }
                }
            }
            SymbolKind::Param => {
                for (i, s) in p.params.iter().enumerate().filter(|(_, s)| s.span == *def) {
                    let ty = Ty::Real(s.dim);
                    if d.name != s.name {
                        rows.push(("instance".into(), format!("`{}`", s.name)));
                    }
                    rows.push(("unit".into(), unit_of(p, ty)));
                    rows.push((
                        "value".into(),
                        format!("{} {}", fmt_si(s.value), s.dim.unit_string()),
                    ));
                    if let Some(pl) = plan {
                        let fp = pl.fixed;
                        let read = fp
                            .program
                            .values
                            .iter()
                            .position(|v| v.op == ir::Op::Param(ir::ParamId(i as u32)));
                        if let Some(r) = read {
                            rows.push(("format".into(), q_name(fp.frac[r])));
                            rows.push((
                                "error bound".into(),
                                error_text(pl.precision.value[r], ty, pl.precision),
                            ));
                        }
                    }
                }
            }
            SymbolKind::Mode => {
                for m in p.modes.iter().filter(|m| m.span == *def) {
                    rows.push(("variants".into(), m.variants.join(", ")));
                    if let Some(init) = m.variants.get(m.init as usize) {
                        rows.push(("initially".into(), init.clone()));
                    }
                }
            }
            SymbolKind::Force | SymbolKind::Output => {
                let named: Vec<(usize, &ir::NamedDecl)> = if d.kind == SymbolKind::Force {
                    p.forces
                        .iter()
                        .enumerate()
                        .filter(|(_, f)| f.span == *def)
                        .collect()
                } else {
                    p.outputs
                        .iter()
                        .enumerate()
                        .filter(|(_, f)| f.span == *def)
                        .collect()
                };
                for (i, f) in named {
                    if d.name != f.name {
                        rows.push(("instance".into(), format!("`{}`", f.name)));
                    }
                    let published = published_value(&p.body, d.kind, i);
                    match published {
                        Some(v) => value_rows(p, v, plan, &mut rows),
                        None => rows.push(("unit".into(), unit_of(p, f.ty))),
                    }
                    if let (Some(pl), SymbolKind::Force) = (plan, d.kind) {
                        if let (Some(fr), Some(e)) =
                            (pl.fixed.force_frac.get(i), pl.precision.force.get(i))
                        {
                            rows.retain(|(k, _)| k != "format" && k != "error bound");
                            rows.push(("format".into(), q_name(*fr)));
                            rows.push((
                                "error bound".into(),
                                error_text(*e, Ty::Real(crate::units::Dim::FORCE), pl.precision),
                            ));
                        }
                    }
                }
            }
            SymbolKind::Let => {
                // A let has no IR entity of its own: what it is bound to is its value.
                if let Some(v) = value_at(p, &value_span(src, d)) {
                    value_rows(p, v, plan, &mut rows);
                }
            }
            _ => {}
        }
    }
    let mut doc = String::new();
    if d.kind == SymbolKind::Component {
        let (file, _) = src.locate(def);
        if file != FileId::MAIN {
            rows.push(("from".into(), src.get(file).name.clone()));
        }
        let list = |kind: SymbolKind| {
            d.children
                .iter()
                .filter(|c| c.kind == kind)
                .map(|c| match kind {
                    SymbolKind::Param => format!("`{}` {}", c.name, c.detail),
                    SymbolKind::Input => format!("`{}`{}", c.name, c.detail),
                    _ => format!("`{}`", c.name),
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        for (what, kind) in [
            ("inputs", SymbolKind::Input),
            ("outputs", SymbolKind::Output),
            ("params", SymbolKind::Param),
        ] {
            let l = list(kind);
            if !l.is_empty() {
                rows.push((what.into(), l));
            }
        }
        doc = doc_above(src, &d.span);
    }
    Facts {
        span: at,
        heading,
        rows,
        doc,
    }
}

/// The span of the expression after `=` in a declaration's text.
fn value_span(src: &SourceMap, d: &Symbol) -> Span {
    let text = src.text(&(d.name_span.end..d.span.end)).unwrap_or("");
    match text.find('=') {
        Some(i) => {
            let start = d.name_span.end + i + 1;
            let rest = src.text(&(start..d.span.end)).unwrap_or("");
            let skip = rest.len() - rest.trim_start().len();
            start + skip..d.span.end
        }
        None => d.span.clone(),
    }
}

/// The last value lowered from exactly `span` (the outermost operation of that term).
fn value_at(p: &Program, span: &Span) -> Option<ir::Value> {
    p.values
        .iter()
        .rposition(|v| v.span == *span)
        .map(|i| ir::Value(i as u32))
}

fn published_value(stmts: &[ir::Stmt], kind: SymbolKind, i: usize) -> Option<ir::Value> {
    stmts.iter().find_map(|s| match (s, kind) {
        (ir::Stmt::Force(f, v), SymbolKind::Force) if f.index() == i => Some(*v),
        (ir::Stmt::Output(o, v), SymbolKind::Output) if o.index() == i => Some(*v),
        (ir::Stmt::If(_, b), _) => published_value(b, kind, i),
        _ => None,
    })
}

/// The front end's answer for one version of a file: what `tactus check` reports, and what
/// the queries above need.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// Errors and warnings, as `tactus check` reports them (the same codes, messages,
    /// labels and hints).
    pub diagnostics: Vec<crate::diagnostics::Diagnostic>,
    /// The lowered program, when the file has no error.
    pub lowered: Option<crate::lower::Lowered>,
    /// The declarations ([`symbols`]); empty when the file does not parse.
    pub outline: Vec<Symbol>,
    /// The names resolved ([`NameIndex`]); empty when the file does not parse or expand.
    pub names: NameIndex,
    /// The components the file imports, as outlines whose spans lie in their own files (a
    /// name of the file may resolve into one: hover, definition, an instance's members).
    pub imported: Vec<Symbol>,
    /// The program's files: the file analysed first, then those it imports (to turn a span
    /// into a file and a place in it).
    pub sources: SourceMap,
}

impl Analysis {
    /// Every declaration a name of the file may denote: its outline, then the imported
    /// components'.
    pub fn outlines(&self) -> Vec<Symbol> {
        self.outline.iter().chain(&self.imported).cloned().collect()
    }
}

/// Parses and lowers `src` as [`crate::compile`] does, keeping the outline and the name
/// index besides the diagnostics.
pub fn analyse(src: &str, config: &crate::lower::Config) -> Analysis {
    let linked = crate::imports::link(
        "source",
        crate::sources::Origin::Text,
        src,
        &mut crate::imports::NoFiles,
    );
    analyse_linked(&linked, config)
}

/// [`analyse`] of a program [`crate::imports::link`] read: the outline is the main file's,
/// the names and diagnostics the program's (a name may resolve into an imported file).
pub fn analyse_linked(linked: &crate::imports::Linked, config: &crate::lower::Config) -> Analysis {
    let main = linked.sources.main();
    let outline = match linked.parsed.first() {
        Some(Some(file)) => symbols(file, &main.text),
        _ => Vec::new(),
    };
    let imported = symbols_from(
        &ast::File {
            items: linked
                .imported_components()
                .into_iter()
                .map(|b| ast::TopItem::Component(b.clone()))
                .collect(),
        },
        &Source::Files(&linked.sources),
    );
    let sources = linked.sources.clone();
    let Some(file) = &linked.file else {
        return Analysis {
            diagnostics: linked.diagnostics.clone(),
            lowered: None,
            outline,
            names: NameIndex::default(),
            imported,
            sources,
        };
    };
    let mut refs = Vec::new();
    let (diagnostics, lowered) = match crate::lower::lower_indexed(file, config, Some(&mut refs)) {
        Ok(mut l) => {
            l.warnings = linked.sited(std::mem::take(&mut l.warnings));
            (l.warnings.clone(), Some(l))
        }
        Err(d) => (linked.sited(d), None),
    };
    let mut names = NameIndex::default();
    names.add(refs);
    Analysis {
        diagnostics,
        lowered,
        outline,
        names,
        imported,
        sources,
    }
}
