//! Fuzzing the stimulus CSV readers: the key CSV (`key_mm`, `time_s,key_mm`; runtime
//! `stimulus::from_csv`) and the multi-sensor CSV (`sim::sensor_csv`), seeded with files
//! in both formats for the shipped instruments, mutated at the byte level (with extreme
//! numbers and times, a byte-order mark, repeated rows). Each reads to a stimulus or to an
//! error naming the file — never a panic, more than a bounded time or a bounded heap.
//! `TACTUS_FUZZ_CASES=100000` for a long run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;

use proptest::prop_assert;
use proptest::test_runner::TestCaseError;
use std::cell::Cell;
use std::path::Path;
use std::time::Duration;
use tactus_compiler::lower::Config;

const TOKENS: &[&[u8]] = &[
    b"1e300",
    b"-1e300",
    b"NaN",
    b"inf",
    b"6000",
    b"\xef\xbb\xbf",
    b"\n0.5,3\n",
    b",",
    b"\n",
    b"# c\n",
    b"time [s]",
    b"key_mm",
    b"1e-300",
    b"\"",
    b"9999999999",
];

fn seeds() -> Vec<Vec<u8>> {
    let mut key = b"# a dip\ntime_s,key_mm\n0.000,0\n0.050,10\n0.350,10\n0.400,0\n".to_vec();
    let per_sample: Vec<u8> = std::iter::once("key_mm".to_string())
        .chain((0..200).map(|i| format!("{:.3}", (i as f64 * 0.05).sin().abs() * 4.0)))
        .collect::<Vec<_>>()
        .join("\n")
        .into_bytes();
    let pen = b"time [s], pen.z [m], pen.x [m]\n0, 0, 0\n0.1, 0.002, 0.01\n0.3, 0.002, 0.05\n0.4, 0, 0.05\n".to_vec();
    key.extend(b"");
    vec![key, per_sample, pen]
}

#[test]
fn mutated_stimulus_files_read_or_give_errors() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let programs: Vec<_> = ["hammond", "rubbed_bank"]
        .iter()
        .map(|n| {
            let src =
                std::fs::read_to_string(root.join(format!("../instruments/{n}.tactus"))).unwrap();
            tactus_compiler::compile(&src, &Config::default())
                .unwrap()
                .program
        })
        .collect();
    let dir = std::env::temp_dir().join(format!("tactus-fuzz-csv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("stim.csv");
    let seeds = seeds();
    let (mut runner, cases) = fuzz::runner(1500);
    let (run, read) = (Cell::new(0u32), Cell::new(0u32));
    runner
        .run(
            &(0..seeds.len(), 0..programs.len(), fuzz::edits(TOKENS)),
            |(seed, prog, edits)| {
                let bytes = fuzz::apply(&seeds[seed], &edits);
                std::fs::write(&path, &bytes).unwrap();
                let program = &programs[prog];
                let (r, dt, peak) = fuzz::measured(|| {
                    let key = tactus_runtime::stimulus::from_csv(&path, 44_100.0);
                    if let Err(e) = &key {
                        assert!(e.to_string().contains("stim"), "{e}");
                    }
                    let s = tactus_compiler::sim::sensor_csv(program, &path, 44_100.0);
                    match s {
                        Ok(s) => {
                            assert!(s.len() <= tactus_runtime::stimulus::MAX_SAMPLES);
                            true
                        }
                        Err(e) => {
                            assert!(e.to_string().contains("stim"), "{e}");
                            key.is_ok()
                        }
                    }
                });
                run.set(run.get() + 1);
                read.set(read.get() + u32::from(r));
                prop_assert!(dt < Duration::from_secs(10), "{dt:?}");
                prop_assert!(peak < 1 << 31, "{peak} bytes");
                Ok::<(), TestCaseError>(())
            },
        )
        .unwrap();
    std::fs::remove_dir_all(&dir).ok();
    eprintln!(
        "fuzz_csv: {} cases, {} read by one of the readers",
        run.get(),
        read.get()
    );
    assert!(run.get() >= cases);
}
