//! Helpers shared by the integration tests that run the `tactus` binary.

use std::path::PathBuf;
use std::process::{Command, Output};

/// The `tactus` binary under test.
pub fn tactus() -> Command {
    Command::new(env!("CARGO_BIN_EXE_tactus"))
}

/// A fresh, empty temporary folder unique to this test process and `name`.
pub fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tactus-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Asserts that a run succeeded, showing its stderr otherwise.
pub fn assert_ok(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
