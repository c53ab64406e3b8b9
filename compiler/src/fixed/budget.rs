//! The precision budget of a format plan ([`PlanConfig`]): how much error the planner may
//! spend on cheaper arithmetic, per force term, state and compared value. The planner
//! ([`super::plan`]) spends it by error analysis, the search ([`super::search`]) by
//! simulation; the accuracy contract ([`super::contract`]) is what it must keep.

use super::*;

/// Precision budget of the `MULS` plan: a force term's or the total's error bound may grow
/// to this many DAC LSB (a quarter: the quantisation stays below what the DAC resolves).
pub const BUDGET_FORCE_LSB: f64 = 0.25;

/// Precision budget of the `MULS` plan: the error bound of a state that is only set (a held
/// force, a recorded position) may grow to this fraction of its range (2^-24).
pub const BUDGET_STATE_REL: f64 = 1.0 / (1u64 << 24) as f64;

/// Precision budget of the `MULS` plan: the one-sample error bound of an integrated
/// (accumulating) state may grow by at most this factor over its bound with exact products.
/// Its errors add up sample after sample, and a floor shift's error is a bias, not noise: a
/// near-threshold motion (a hammer that barely reaches the string) is decided by them.
pub const BUDGET_ACCUMULATING_GROWTH: f64 = 2.0;

/// Precision budget of the `MULS` plan: a value that is compared, emitted or output may
/// carry an error bound of this fraction of its range (2^-20).
pub const BUDGET_VALUE_REL: f64 = 1.0 / (1u64 << 20) as f64;

/// The precision budget of a format plan: how much error the planner may spend on cheaper
/// arithmetic. [`Default`] is the budget every engine and backend uses (the constants above);
/// the accuracy contract ([`contract`]) is what it must keep, checked by simulation against
/// the f64 reference (`compiler/tests/contract.rs`), including that a greedier budget breaks it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanConfig {
    /// [`BUDGET_FORCE_LSB`].
    pub force_lsb: f64,
    /// [`BUDGET_STATE_REL`].
    pub state_rel: f64,
    /// [`BUDGET_ACCUMULATING_GROWTH`].
    pub accumulating_growth: f64,
    /// [`BUDGET_VALUE_REL`].
    pub value_rel: f64,
    /// [`DIV_REL_TOLERANCE`].
    pub div_rel_tolerance: f64,
    /// Whether the planner also tries cheaper product forms than the error analysis proves,
    /// checked by simulating the accuracy contract (`FixedProgram::spend_by_simulation`).
    pub simulate: bool,
    /// Whether divisions by states that only events set become products with their
    /// reciprocals ([`recip`]). Off only to measure what the reciprocals save and to pin
    /// the divisor tolerance on a program that still divides.
    pub reciprocals: bool,
    /// Whether states only events write are narrowed to the hull of what they are assigned
    /// ([`range::state_hulls`]). Off only to measure what the narrowing saves.
    pub narrow_states: bool,
    /// Whether `on` handlers whose edge memory is provably false whenever their condition
    /// holds are run as `while` handlers ([`flow::edges`]: no edge load or store). Off only
    /// to measure what it saves and to check that both programs run alike.
    pub level_edges: bool,
}

impl Default for PlanConfig {
    fn default() -> Self {
        PlanConfig {
            force_lsb: BUDGET_FORCE_LSB,
            state_rel: BUDGET_STATE_REL,
            accumulating_growth: BUDGET_ACCUMULATING_GROWTH,
            value_rel: BUDGET_VALUE_REL,
            div_rel_tolerance: DIV_REL_TOLERANCE,
            simulate: true,
            reciprocals: true,
            narrow_states: true,
            level_edges: true,
        }
    }
}

impl PlanConfig {
    /// A budget with no limit on products (every product that fits `MULS` gets it) and
    /// divisors shifted to [`DIV_MIN_DIVISOR_BITS`] whatever it costs: what a planner
    /// ignoring the contract would do. For tests that show the contract catches it.
    pub fn unlimited() -> Self {
        PlanConfig {
            force_lsb: f64::INFINITY,
            state_rel: f64::INFINITY,
            accumulating_growth: f64::INFINITY,
            value_rel: f64::INFINITY,
            div_rel_tolerance: 1.0,
            simulate: false,
            reciprocals: true,
            narrow_states: true,
            level_edges: true,
        }
    }
}
