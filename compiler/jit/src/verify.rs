//! The IR verifier lives in the compiler crate (`tactus_compiler::verify`), where every engine
//! and backend calls it; the JIT reports its failures as [`JitError`]s.

use crate::JitError;
use tactus_compiler::ir::Program;
use tactus_compiler::verify::VerifyError;

/// Checks `program` ([`tactus_compiler::verify::verify`]): every index in range, every
/// declared range ordered and NaN-free, every value defined once and before each use in scope.
pub fn verify(program: &Program) -> Result<(), JitError> {
    tactus_compiler::verify::verify(program).map_err(JitError::from)
}

impl From<VerifyError> for JitError {
    fn from(e: VerifyError) -> Self {
        match e {
            VerifyError::UndefinedValue { value } => JitError::UndefinedValue { value },
            VerifyError::Redefined { value } => JitError::Redefined { value },
            VerifyError::BadIndex { kind, index, len } => JitError::BadIndex { kind, index, len },
            VerifyError::BadRange { kind, name, lo, hi } => {
                JitError::BadRange { kind, name, lo, hi }
            }
        }
    }
}
