//! The abstract syntax tree, exactly as written, with byte spans.
//!
//! The AST keeps source order and spelling and resolves nothing: names are strings and
//! units are already folded into literals by the lexer. [`crate::lower`] turns it into the
//! IR, checking names and dimensions on the way. Spans are byte ranges into the source file,
//! offset by the file's base in a [`crate::sources::SourceMap`] when it was imported (the
//! main file's base is 0, so its spans are its own byte offsets).

use crate::lexer::Literal;

/// A byte range in the source file (offset by its file's base in a
/// [`crate::sources::SourceMap`]: 0 for the main file).
pub type Span = std::ops::Range<usize>;

/// A value with the span it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Spanned<T> {
    /// The node.
    pub node: T,
    /// Where it was written.
    pub span: Span,
}

/// A name as written.
pub type Name = Spanned<String>;

/// A whole `.tactus` file: imports, components and instruments in source order.
#[derive(Clone, Debug, PartialEq)]
pub struct File {
    /// Top-level definitions.
    pub items: Vec<TopItem>,
}

/// A top-level definition.
#[derive(Clone, Debug, PartialEq)]
pub enum TopItem {
    /// `instrument NAME { … }`
    Instrument(Body),
    /// `component NAME { … }`
    Component(Body),
    /// `import "FILE"` or `import "FILE" { NAME, … }`: resolved and removed by
    /// [`crate::imports::link`], so expansion and lowering never see one.
    Import(Import),
}

/// `import "FILE"` (every component `FILE` defines) or `import "FILE" { NAME, … }` (only
/// those): components from another file, found next to the importing file, then in
/// Tactus's library ([`crate::library`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Import {
    /// The file name as written, without the quotes; its span includes them.
    pub path: Spanned<String>,
    /// The components listed in braces, or `None` for all of them.
    pub names: Option<Vec<Name>>,
    /// The whole import.
    pub span: Span,
}

/// The body shared by instruments and components.
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    /// The instrument's or component's name.
    pub name: Name,
    /// Declarations in source order.
    pub decls: Vec<Decl>,
    /// The span of the whole definition.
    pub span: Span,
}

/// A type annotation: a unit whose dimension is meant, or `bool`.
#[derive(Clone, Debug, PartialEq)]
pub enum TypeAnn {
    /// `bool`.
    Bool,
    /// A unit expression such as `m`, `N*s/m` or `1`; each factor is (name, exponent).
    Unit(Vec<(Name, i32)>),
}

/// A closed interval `[lo, hi]` declared for a sensor or state.
#[derive(Clone, Debug, PartialEq)]
pub struct Range {
    /// Lower bound.
    pub lo: Expr,
    /// Upper bound.
    pub hi: Expr,
    /// Span of the brackets.
    pub span: Span,
}

/// A half-open range of indices `LO..HI` (a loop's or a sum's), both whole numbers known at
/// compile time.
#[derive(Clone, Debug, PartialEq)]
pub struct IndexRange {
    /// First index.
    pub lo: Expr,
    /// One past the last index.
    pub hi: Expr,
    /// Span of `LO..HI`.
    pub span: Span,
}

/// A declaration inside an instrument or component. Fields are named as in the syntax shown.
///
/// `index` fields hold the `[EXPR]` of an array element (`state u[i] = …`); they are only
/// ever `Some` before [`crate::expand`] has run, which turns them into plain names (`u[3]`).
/// The same holds for [`Decl::For`], [`Decl::Solve`], [`ExprKind::Element`] and
/// [`ExprKind::Sum`]: lowering sees none of them.
#[allow(missing_docs)]
#[derive(Clone, Debug, PartialEq)]
pub enum Decl {
    /// `sensor NAME [: TYPE] in [lo, hi]`
    Sensor {
        name: Name,
        ty: Option<Spanned<TypeAnn>>,
        range: Option<Range>,
    },
    /// `sensor NAME [: TYPE] in { x: [lo, hi], z: [lo, hi], … }`: a vector sensor (a pen's
    /// position), one range per component; components are `x`, `y`, `z`, each at most once.
    /// [`crate::expand`] turns it into scalar sensors `NAME.x`, … in the written order.
    VectorSensor {
        name: Name,
        ty: Option<Spanned<TypeAnn>>,
        components: Vec<(Name, Range)>,
        /// Span of the braces.
        span: Span,
    },
    /// `input NAME : TYPE` (components only)
    Input {
        name: Name,
        ty: Option<Spanned<TypeAnn>>,
    },
    /// `param NAME [: TYPE] = EXPR`
    Param {
        name: Name,
        ty: Option<Spanned<TypeAnn>>,
        value: Expr,
    },
    /// `state NAME [: TYPE] = EXPR in [lo, hi]`
    State {
        name: Name,
        index: Option<Expr>,
        ty: Option<Spanned<TypeAnn>>,
        init: Expr,
        range: Option<Range>,
    },
    /// `mode NAME { a, b, … } [= a]`
    Mode {
        name: Name,
        variants: Vec<Name>,
        init: Option<Name>,
    },
    /// `let NAME = EXPR`
    Let {
        name: Name,
        index: Option<Expr>,
        value: Expr,
    },
    /// `force NAME = EXPR`; `axis` is set by [`crate::expand`] on the scalar terms a
    /// [`Decl::VectorForce`] becomes (the parser always leaves it `None`).
    Force {
        name: Name,
        index: Option<Expr>,
        value: Expr,
        axis: Option<Axis>,
    },
    /// `force NAME = { x: EXPR, z: EXPR, … }`: a vector force term of a pen instrument, in
    /// newtons per component; components are `x`, `y`, `z`, each at most once, and a
    /// missing one is 0 N. [`crate::expand`] turns it into scalar terms `NAME.x`, ….
    VectorForce {
        name: Name,
        index: Option<Expr>,
        components: Vec<(Name, Expr)>,
        /// Span of the braces.
        span: Span,
    },
    /// `output NAME = EXPR`
    Output {
        name: Name,
        index: Option<Expr>,
        value: Expr,
    },
    /// `dynamics { x' = EXPR … }`
    Dynamics { eqs: Vec<Equation>, span: Span },
    /// `on COND { … }` (rising edge) or `while COND { … }` (level).
    Handler {
        trigger: Trigger,
        cond: Expr,
        body: Vec<Stmt>,
        span: Span,
    },
    /// `use NAME = COMPONENT(arg = EXPR, …)`
    Use {
        name: Name,
        index: Option<Expr>,
        component: Name,
        args: Vec<(Name, Expr)>,
        span: Span,
    },
    /// `for VAR in LO..HI { DECLS }`: the declarations once per index, `VAR` standing for
    /// the index (a dimensionless whole number).
    For {
        var: Name,
        range: IndexRange,
        decls: Vec<Decl>,
        span: Span,
    },
    /// `solve NAME in [LO, HI] { start = EXPR  residual = EXPR  iterations = N
    /// [min_slope = EXPR] }`: Newton–Raphson on the residual, a fixed number of iterations.
    Solve {
        name: Name,
        index: Option<Expr>,
        range: Option<Range>,
        fields: Vec<(Name, Expr)>,
        span: Span,
    },
    /// `require COND`: a compile-time condition on params (a stability bound, say).
    Require { cond: Expr, span: Span },
    /// The range of a solve's unknown, left by `crate::expand` beside the iterates it
    /// clamps into it, so that lowering folds and checks it as every other range (E0306 for
    /// `[1 m, -1 m]`, E0308): not written in source.
    SolveRange { name: Name, range: Range },
    /// A clause of the instrument's accuracy contract (docs/language.md, "Tolerances"):
    /// `tolerance force [TERM] = EXPR` (newtons, or a plain number of DAC LSB),
    /// `tolerance output NAME = EXPR` (the output's unit),
    /// `tolerance event NAME { time = EXPR, ARG = EXPR, … }` (seconds; a fraction per argument),
    /// `tolerance switch = EXPR` (seconds: the switch clause's window).
    Tolerance {
        /// What the clause bounds: `force`, `output` or the word before the event's name.
        kind: ToleranceKind,
        /// The force term, output or event named (none: the total force).
        name: Option<Name>,
        /// The bound of a force, output or switch clause.
        value: Option<Expr>,
        /// The fields of an event clause.
        fields: Vec<(Name, Expr)>,
        span: Span,
    },
}

/// The subject of a `tolerance` line.
#[derive(Clone, Debug, PartialEq)]
pub enum ToleranceKind {
    /// `tolerance force …`
    Force,
    /// `tolerance output …`
    Output,
    /// `tolerance WORD NAME { … }` or `tolerance WORD = …`: `event` (with a name and fields)
    /// and `switch` (with a value) are the words allowed (anything else is E0314).
    Word(Name),
}

/// When a handler's body runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trigger {
    /// `on`: the sample where the condition becomes true.
    Edge,
    /// `while`: every sample where the condition holds.
    Level,
}

/// `x' = EXPR` in a dynamics block.
#[derive(Clone, Debug, PartialEq)]
pub struct Equation {
    /// The state being integrated.
    pub state: Name,
    /// The element index of an array state (`u[i]' = …`), before [`crate::expand`].
    pub index: Option<Expr>,
    /// Its time derivative.
    pub rhs: Expr,
}

/// A statement in a handler body. Fields are named as in the syntax shown.
#[allow(missing_docs)]
#[derive(Clone, Debug, PartialEq)]
pub enum Stmt {
    /// `NAME = EXPR` — a state or a mode.
    Assign {
        target: Name,
        index: Option<Expr>,
        value: Expr,
    },
    /// `emit EVENT(arg = EXPR, …)`
    Emit {
        event: Name,
        args: Vec<(Name, Expr)>,
        span: Span,
    },
}

/// An expression with its span.
pub type Expr = Spanned<ExprKind>;

/// Binary operators, loosest binding first in the grammar.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(missing_docs)]
pub enum BinOp {
    Or,
    And,
    Eq,
    Ne,
    Lt,
    Le,
    Gt,
    Ge,
    Add,
    Sub,
    Mul,
    Div,
}

/// Expression forms.
#[derive(Clone, Debug, PartialEq)]
pub enum ExprKind {
    /// A number with unit.
    Number(Literal),
    /// `true` / `false`.
    Bool(bool),
    /// A name, possibly qualified by an instance: `key`, `esc.f`.
    Path(Vec<Name>),
    /// `-x`
    Neg(Box<Expr>),
    /// `not x`
    Not(Box<Expr>),
    /// `a OP b`
    Binary(BinOp, Box<Expr>, Box<Expr>),
    /// `x ^ N` with an integer literal `N`.
    Pow(Box<Expr>, Spanned<f64>),
    /// `f(args)`
    Call(Name, Vec<Expr>),
    /// `if c { a } else { b }`
    If(Box<Expr>, Box<Expr>, Box<Expr>),
    /// A path with element indices: `u[i + 1]`, `r[i].f` (each segment, its index if any).
    Element(Vec<(Name, Option<Expr>)>),
    /// `sum(VAR in LO..HI, EXPR)`: `EXPR` added up over the indices.
    Sum {
        /// The index variable.
        var: Name,
        /// Its range.
        range: Box<IndexRange>,
        /// The term, read once per index.
        body: Box<Expr>,
    },
}

/// An axis of a pen instrument's 3-DoF contact point (the pen of Onofrei, Fontana & Serafin
/// 2023). `Z` is the depth into the surface (positive into the plane; a force on `z` is
/// positive pushing the pen out of it, like a keyboard's force pushing the key up), `X` the
/// stroke axis (rubbing, bowing, plucking), `Y` across it. Forces on `X` and `Y` are in
/// newtons along the positive axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Axis {
    /// The stroke axis.
    X,
    /// Across the stroke.
    Y,
    /// Depth into the surface (the normal axis).
    Z,
}

impl Axis {
    /// The three axes in the order `x, y, z`.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// The component name as written in the source: `"x"`, `"y"` or `"z"`.
    pub fn name(self) -> &'static str {
        match self {
            Axis::X => "x",
            Axis::Y => "y",
            Axis::Z => "z",
        }
    }

    /// The axis a component name denotes, or `None` for anything but `x`, `y`, `z`.
    pub fn from_name(name: &str) -> Option<Axis> {
        match name {
            "x" => Some(Axis::X),
            "y" => Some(Axis::Y),
            "z" => Some(Axis::Z),
            _ => None,
        }
    }
}

impl std::fmt::Display for Axis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
