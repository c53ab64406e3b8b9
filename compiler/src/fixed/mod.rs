//! Fixed-point compilation: range analysis, Q-format choice, and the fixed-point program
//! that the fixed interpreter, the JIT and the firmware backends run.
//!
//! The fixed program is the IR plus a *format plan*: one binary point (fraction bits) per
//! value, per state and per sensor, the raw words of constants, and the reciprocal that
//! replaces each division by a constant. Each value's format is the finest that holds its
//! whole interval from [`range`] in a signed 32-bit word:
//! `frac = 30 − floor(log2(max |v|))`, so `|raw| < 2^31`. What an operation computes is
//! defined once, in [`tactus_runtime::fixed`]: the exact result rounded half up to the result
//! format and saturated. Because the formats hold the analysed intervals, saturation can fire
//! only where the analysis had to clamp an unbounded value, and those places are warned about.
//!
//! The modules, one job each: [`program`] (the program type), [`products`] and [`division`]
//! (the forms of products and run-time divisions and their errors), [`cost`] (their cycles,
//! from the timing table), [`plan`] (the planner) and [`budget`] (its precision budget),
//! [`search`] (the planner's search by simulating the contract) with its [`stimuli`],
//! [`params`] (param blocks); before the plan, the program transformations [`recip`],
//! [`chains`], [`common`]; the analyses [`range`], [`flow`], [`report`] (error bounds) and
//! [`contract`], and [`render`] (the precision report as text); the fixed interpreter
//! [`interp`]; [`plan_cache`] keeps searched plans. Every item is also reachable as
//! `fixed::NAME`.

pub mod budget;
pub mod chains;
pub mod common;
pub mod contract;
pub mod cost;
pub mod distribute;
pub mod division;
pub mod flow;
pub mod interp;
pub mod params;
pub mod plan;
pub mod plan_cache;
pub mod products;
pub mod program;
pub mod range;
pub mod recip;
pub mod render;
pub mod report;
pub mod search;
pub mod stimuli;
mod workers;

pub use budget::*;
pub use cost::*;
pub use division::*;
pub use params::*;
pub use plan::*;
pub use products::*;
pub use program::*;
pub use search::*;
pub use stimuli::*;

use crate::diagnostics::Diagnostic;
use crate::ir::*;
use range::{Interval, Ranges};
use tactus_isa::timing::{Class, DIVIDER_LATENCY};
use tactus_runtime::differentiator::WINDOW;
use tactus_runtime::fixed as fx;

pub use tactus_runtime::fixed::FRAC_RANGE;
