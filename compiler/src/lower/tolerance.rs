//! `tolerance` lines: the instrument's accuracy contract ([`Contract`]) as its writer states
//! it. Their bounds are compile-time constants, evaluated with the other constants
//! ([`Lowerer::evaluate_tolerance`]); the force terms, outputs and events they name exist
//! only once the body is lowered, so the names are resolved last
//! ([`Lowerer::resolve_tolerances`]). `tolerance switch = T` sets the switch clause's
//! window ([`Contract::switch_time_s`]). Errors E0313–E0317 (docs/language.md, "Tolerances").

use super::{Lowerer, ScopeId};
use crate::ast::{self, ToleranceKind};
use crate::diagnostics::Diagnostic;
use crate::ir::*;
use crate::units::Dim;

/// A `tolerance` line with its constants evaluated, waiting for its names.
pub(super) struct PendingTolerance<'a> {
    kind: &'a ToleranceKind,
    name: Option<&'a ast::Name>,
    /// The bound of a force or output clause (SI value, dimension, span).
    value: Option<(f64, Dim, ast::Span)>,
    /// The fields of an event clause.
    fields: Vec<(&'a ast::Name, f64, Dim, ast::Span)>,
    span: ast::Span,
}

impl<'a> Lowerer<'a> {
    /// Evaluates the bounds of a `tolerance` line of scope `scope` (E0313 outside the
    /// instrument).
    pub(super) fn evaluate_tolerance(&mut self, scope: ScopeId, d: &'a ast::Decl) {
        let ast::Decl::Tolerance {
            kind,
            name,
            value,
            fields,
            span,
        } = d
        else {
            return;
        };
        if scope.0 != 0 {
            self.err(
                Diagnostic::error(
                    "E0313",
                    "`tolerance` lines belong to the instrument, not to a component",
                    span.clone(),
                )
                .hint("the contract is the instrument's: move the line into `instrument … { }` and name the instance's term (`tolerance force jack.bump = 0.5`)"),
            );
            return;
        }
        let value = match value {
            Some(e) => match self.const_value(scope, e) {
                Some((v, dim)) => Some((v, dim, e.span.clone())),
                None => return,
            },
            None => None,
        };
        let mut out = Vec::new();
        for (n, e) in fields {
            let Some((v, dim)) = self.const_value(scope, e) else {
                return;
            };
            out.push((n, v, dim, e.span.clone()));
        }
        self.tolerances.push(PendingTolerance {
            kind,
            name: name.as_ref(),
            value,
            fields: out,
            span: span.clone(),
        });
    }

    /// Resolves the names of the evaluated `tolerance` lines against the lowered program and
    /// writes [`Program::contract`].
    pub(super) fn resolve_tolerances(&mut self) {
        let pending = std::mem::take(&mut self.tolerances);
        let mut contract = Contract::default();
        let mut seen: Vec<(String, ast::Span)> = Vec::new();
        for t in pending {
            let key = match (t.kind, t.name) {
                (ToleranceKind::Force, None) => "force".to_string(),
                (ToleranceKind::Force, Some(n)) => format!("force {}", n.node),
                (ToleranceKind::Output, Some(n)) => format!("output {}", n.node),
                (ToleranceKind::Word(w), Some(n)) => format!("{} {}", w.node, n.node),
                (ToleranceKind::Word(w), None) => w.node.clone(),
                (ToleranceKind::Output, None) => "output".into(),
            };
            if let Some((_, first)) = seen.iter().find(|(k, _)| *k == key) {
                self.err(
                    Diagnostic::error(
                        "E0317",
                        format!("`tolerance {key}` is stated twice"),
                        t.span.clone(),
                    )
                    .with_secondary(first.clone(), "first stated here")
                    .hint("keep one line per force term, output and event, and one `tolerance switch`"),
                );
                continue;
            }
            seen.push((key, t.span.clone()));
            match t.kind {
                ToleranceKind::Force => self.force_tolerance(&t, &mut contract),
                ToleranceKind::Output => self.output_tolerance(&t, &mut contract),
                ToleranceKind::Word(w) if w.node == "event" && t.name.is_some() => {
                    self.event_tolerance(&t, &mut contract)
                }
                ToleranceKind::Word(w) if w.node == "switch" && t.name.is_none() => {
                    self.switch_tolerance(&t, &mut contract)
                }
                ToleranceKind::Word(w) if w.node == "event" => self.err(
                    Diagnostic::error(
                        "E0314",
                        "`tolerance event` names its event and gives its fields",
                        t.span.clone(),
                    )
                    .hint("write `tolerance event NAME { time = 1 ms, ARG = 0.01 }`; the events' default time tolerance is 0.5 ms"),
                ),
                ToleranceKind::Word(w) if w.node == "switch" => self.err(
                    Diagnostic::error(
                        "E0314",
                        "`tolerance switch` is one clause for every switch of the instrument: it takes no name and no fields",
                        t.span.clone(),
                    )
                    .hint("write `tolerance switch = 0.5 ms`: how long the fixed-point and f64 runs may be in different discrete states"),
                ),
                ToleranceKind::Word(w) => self.err(
                    Diagnostic::error(
                        "E0314",
                        format!("`tolerance {}` is not a clause of the contract", w.node),
                        w.span.clone(),
                    )
                    .hint("write `tolerance force [TERM] = …`, `tolerance output NAME = …`, `tolerance event NAME { time = …, ARG = … }` or `tolerance switch = …`"),
                ),
            }
        }
        self.prog.contract = contract;
    }

    /// A bound that is not a positive finite number: E0316.
    fn positive(&mut self, v: f64, span: &ast::Span) -> bool {
        if v > 0.0 && v.is_finite() {
            return true;
        }
        self.err(
            Diagnostic::error(
                "E0316",
                format!("a tolerance must be positive, this one is {v}"),
                span.clone(),
            )
            .hint("state how far the fixed-point run may stray from the exact one, e.g. `tolerance force = 0.5`"),
        );
        false
    }

    /// A force bound: a plain number is DAC LSB, a force newtons (E0316 otherwise).
    fn force_bound(&mut self, v: f64, dim: Dim, span: &ast::Span) -> Option<ForceBound> {
        if dim != Dim::NONE && dim != Dim::FORCE {
            self.err(
                Diagnostic::error(
                    "E0316",
                    format!(
                        "a force tolerance is in newtons or DAC LSB (a plain number), not {dim}"
                    ),
                    span.clone(),
                )
                .hint("write e.g. `tolerance force = 0.5` (DAC LSB) or `tolerance force = 2 mN`"),
            );
            return None;
        }
        if !self.positive(v, span) {
            return None;
        }
        Some(if dim == Dim::NONE {
            ForceBound::Lsb(v)
        } else {
            ForceBound::Newtons(v)
        })
    }

    fn force_tolerance(&mut self, t: &PendingTolerance<'a>, c: &mut Contract) {
        let Some((v, dim, span)) = t.value.clone() else {
            return;
        };
        let Some(bound) = self.force_bound(v, dim, &span) else {
            return;
        };
        match t.name {
            None => c.force = bound,
            Some(n) => {
                let names: Vec<&str> = self.prog.forces.iter().map(|f| f.name.as_str()).collect();
                match names.iter().position(|f| *f == n.node) {
                    Some(i) => c.terms.push((ForceId(i as u32), bound)),
                    None => {
                        let d = unknown("force term", n, &names);
                        self.err(d)
                    }
                }
            }
        }
    }

    fn output_tolerance(&mut self, t: &PendingTolerance<'a>, c: &mut Contract) {
        let (Some(n), Some((v, dim, span))) = (t.name, t.value.clone()) else {
            return;
        };
        let names: Vec<&str> = self.prog.outputs.iter().map(|o| o.name.as_str()).collect();
        let Some(i) = names.iter().position(|o| *o == n.node) else {
            let d = unknown("output", n, &names);
            self.err(d);
            return;
        };
        let want = match self.prog.outputs[i].ty {
            Ty::Real(d) => d,
            _ => Dim::NONE,
        };
        if dim != want {
            self.err(
                Diagnostic::error(
                    "E0316",
                    format!("output `{}` is {want}, its tolerance {dim}", n.node),
                    span.clone(),
                )
                .hint("state the tolerance in the output's own unit"),
            );
            return;
        }
        if self.positive(v, &span) {
            c.outputs.push((OutputId(i as u32), v));
        }
    }

    /// `tolerance switch = T`: the switch clause's window, a positive time (E0316).
    fn switch_tolerance(&mut self, t: &PendingTolerance<'a>, c: &mut Contract) {
        let Some((v, dim, span)) = t.value.clone() else {
            return;
        };
        if dim != Dim::TIME {
            self.err(
                Diagnostic::error(
                    "E0316",
                    format!("the switch tolerance is a time, not {dim}"),
                    span,
                )
                .hint("write e.g. `tolerance switch = 0.5 ms`: how long the two runs may be in different discrete states"),
            );
        } else if self.positive(v, &span) {
            c.switch_time_s = v;
        }
    }

    fn event_tolerance(&mut self, t: &PendingTolerance<'a>, c: &mut Contract) {
        let Some(n) = t.name else { return };
        let names: Vec<&str> = self.prog.events.iter().map(|e| e.name.as_str()).collect();
        let Some(e) = names.iter().position(|x| *x == n.node) else {
            let d = unknown("event", n, &names);
            self.err(d);
            return;
        };
        let mut clause = EventTolerance {
            event: EventId(e as u32),
            time_s: None,
            args_rel: Vec::new(),
        };
        for (f, v, dim, span) in &t.fields {
            if f.node == "time" {
                if *dim != Dim::TIME {
                    self.err(
                        Diagnostic::error(
                            "E0316",
                            format!("an event's time tolerance is a time, not {dim}"),
                            span.clone(),
                        )
                        .hint("write e.g. `time = 0.5 ms`"),
                    );
                } else if self.positive(*v, span) {
                    clause.time_s = Some(*v);
                }
                continue;
            }
            let args: Vec<&str> = self.prog.events[e]
                .args
                .iter()
                .map(|a| a.0.as_str())
                .collect();
            let Some(i) = args.iter().position(|a| *a == f.node) else {
                let mut with_time = args.clone();
                with_time.push("time");
                let d = unknown(&format!("argument of `{}`", n.node), f, &with_time);
                self.err(d);
                continue;
            };
            if *dim != Dim::NONE {
                self.err(
                    Diagnostic::error(
                        "E0316",
                        format!("an argument's tolerance is a fraction of its value (a plain number), not {dim}"),
                        span.clone(),
                    )
                    .hint(format!("write e.g. `{} = 0.01` for 1 %", f.node)),
                );
            } else if self.positive(*v, span) {
                clause.args_rel.push((i, *v));
            }
        }
        c.events.push(clause);
    }
}

/// E0315: a `tolerance` line names something the instrument does not have.
fn unknown(what: &str, n: &ast::Name, names: &[&str]) -> Diagnostic {
    let hint = match crate::diagnostics::closest(&n.node, names.iter().copied()) {
        Some(c) => format!("did you mean `{c}`?"),
        None if names.is_empty() => format!("this instrument has no {what}"),
        None => format!("the instrument's: {}", names.join(", ")),
    };
    Diagnostic::error(
        "E0315",
        format!("no {what} named `{}`", n.node),
        n.span.clone(),
    )
    .hint(hint)
}
