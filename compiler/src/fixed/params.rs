//! Param blocks: the words of a key's run-time params inside its state ([`ParamWord`]), made
//! on the host from the key's param values ([`FixedProgram::param_block`]) or refused with
//! a [`ParamBlockError`] naming the param whose value the plan cannot hold.

use super::*;

/// Why a param block could not be made.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamBlockError {
    /// The number of values is not the number of run-time params.
    Count {
        /// Values given.
        given: usize,
        /// Run-time params of the program.
        expected: usize,
    },
    /// A value lies outside the interval the program was planned for.
    OutOfRange {
        /// The param's name.
        param: String,
        /// The value given, SI.
        value: f64,
        /// The planned interval, SI.
        range: (f64, f64),
    },
}

impl std::fmt::Display for ParamBlockError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ParamBlockError::Count { given, expected } => write!(
                f,
                "{given} param values given for a program with {expected} run-time params"
            ),
            ParamBlockError::OutOfRange {
                param,
                value,
                range,
            } => write!(
                f,
                "param `{param}` = {value:e} lies outside [{:e}, {:e}], the interval its program was planned for",
                range.0, range.1
            ),
        }
    }
}

impl std::error::Error for ParamBlockError {}

impl FixedProgram {
    /// The word of value `v` in a key's param block when `v` reads a run-time param.
    pub fn param_word_of(&self, v: Value) -> Option<usize> {
        match self.program.values[v.index()].op {
            Op::Param(p) => self.param_slot[p.index()],
            _ => None,
        }
    }

    /// A key's param block: the raw word of each run-time param ([`Program::runtime_params`]
    /// order) from its SI value `values`, rounded half up in the word's format
    /// ([`tactus_runtime::fixed::from_f64`], as every constant is). Empty for a program
    /// without run-time params.
    ///
    /// Errors: [`ParamBlockError`] when the count differs or a value lies outside the
    /// interval the program was planned for (its formats would not hold it).
    pub fn param_block(&self, values: &[f64]) -> Result<Vec<i32>, ParamBlockError> {
        if values.len() != self.param_words.len() {
            return Err(ParamBlockError::Count {
                given: values.len(),
                expected: self.param_words.len(),
            });
        }
        values
            .iter()
            .zip(&self.param_words)
            .map(|(&v, w)| {
                let d = &self.program.params[w.param.index()];
                let range = d.runtime.unwrap_or((d.value, d.value));
                if !(range.0..=range.1).contains(&v) {
                    return Err(ParamBlockError::OutOfRange {
                        param: d.name.clone(),
                        value: v,
                        range,
                    });
                }
                Ok(fx::from_f64(v, w.frac).0)
            })
            .collect()
    }

    /// The param block of the params' own values ([`ParamDecl::value`]: the first key's, for
    /// a shared program); empty without run-time params.
    pub fn nominal_param_block(&self) -> Vec<i32> {
        self.param_words
            .iter()
            .map(|w| fx::from_f64(self.program.params[w.param.index()].value, w.frac).0)
            .collect()
    }
}
