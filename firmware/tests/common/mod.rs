//! Helpers shared by the firmware tests.

#[path = "../../../compiler/tests/support/shipped.rs"]
mod shipped;

/// The shipped instruments, `(file stem, source)`, sorted by name: every
/// `instruments/*.tactus`, and the experimental ones (`instruments/experimental/*.tactus`,
/// named `experimental/STEM`): every engine must agree on those too.
pub fn instruments() -> Vec<(String, String)> {
    shipped::instrument_sources(true)
}

/// Programs with more IR values than this are left out of the tests that build them with
/// the Cortex-M0+ C compilers: `bowed_string` (19,000 values) is 1.3 MB of C, over a minute
/// for each compiler at -O2. Their C is checked against the fixed interpreter on the host
/// (`compiler/tests/cgen.rs`, at -O1).
#[allow(dead_code)]
pub const LARGE_PROGRAM_VALUES: usize = 5_000;

/// [`instruments`] without the programs over [`LARGE_PROGRAM_VALUES`] values (each one left
/// out is printed).
#[allow(dead_code)] // each test binary uses a subset
pub fn small_instruments() -> Vec<(String, String)> {
    instruments()
        .into_iter()
        .filter(|(name, text)| {
            let n = tactus_compiler::compile(text, &tactus_compiler::lower::Config::default())
                .map_or(0, |l| l.program.values.len());
            if n > LARGE_PROGRAM_VALUES {
                println!("{name}: left out ({n} IR values)");
            }
            n <= LARGE_PROGRAM_VALUES
        })
        .collect()
}
