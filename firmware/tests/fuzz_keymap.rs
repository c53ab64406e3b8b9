//! Fuzzing `tactus emu run FIRMWARE.elf --keys keys.json` (issue 36): the key map of a
//! two-key firmware (and now and then its ELF), mutated at the byte level and field by
//! field with extreme values, either runs — and then each core completed no more samples
//! than were run, and all of them without a miss — or gives an error naming the field;
//! never a panic, more than a bounded time or a bounded heap (an absurd clock or start
//! alarm allocated 3 GB; a 1 THz clock ran for ever). `TACTUS_FUZZ_CASES=100000` for a long
//! run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;
#[path = "common/layouts.rs"]
mod layouts;

use proptest::prelude::*;
use proptest::test_runner::TestCaseError;
use std::cell::Cell;
use std::path::Path;
use std::time::Duration;
use tactus_firmware::flash::{self, KeyMap, KeyboardInput};
use tactus_firmware::image::compile_layout;
use tactus_runtime::keyboard::{BoardSpec, KeyAssignment};
use tactus_runtime::limiter::LimiterConfig;

/// Samples each accepted case runs (the key map's checks come before any of them).
const SAMPLES: usize = 60;

fn shipped(name: &str) -> Result<String, String> {
    let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../instruments"))
        .join(format!("{name}.tactus"));
    std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))
}

/// Two hammond keys on one rp2040 board: its ELF and key map (as `keys.json` text).
fn firmware() -> (Vec<u8>, String) {
    let board = BoardSpec {
        name: "rp2040".into(),
        clock_hz: 133e6,
        cores: 2,
        sample_rate_hz: 44_100.0,
        core_voltage_v: None,
        converters: None,
    };
    let keys: Vec<KeyAssignment> = [60, 61]
        .map(|key| KeyAssignment {
            key,
            instrument: "hammond".into(),
            params: vec![],
        })
        .to_vec();
    let (programs, index) = compile_layout(&keys, &shipped, board.sample_rate_hz).unwrap();
    let names = vec![("hammond".to_string(), vec![]); programs.len()];
    let pairs: Vec<(u8, usize)> = keys.iter().map(|k| k.key).zip(index).collect();
    let limiter = LimiterConfig::for_board(&board);
    let lists = layouts::plan(&programs, &pairs, &board, &limiter).unwrap();
    let fw = flash::keyboard_firmware(
        &KeyboardInput {
            name: "fuzz",
            programs: &programs,
            program_names: &names,
            keys: &pairs,
            board: &board,
            boards: &lists,
            images: &[],
            limiter: &limiter,
            command: "fuzz",
            load: flash::Load::Ram,
        },
        &mut |_, _, _| {},
    )
    .unwrap();
    let b = &fw[0];
    (
        b.elf.clone(),
        serde_json::to_string_pretty(&b.key_map).unwrap(),
    )
}

const TOKENS: &[&[u8]] = &[
    b"18446744073709551615",
    b"4294967295",
    b"1000000000000",
    b"200000000",
    b"0",
    b"-1",
    b"1e400",
    b"\"0x30000001\"",
    b"\"0x2003f100\"",
    b"\"0xffffffff\"",
    b"\"zz\"",
    b"[]",
    b"null",
    b"{\"core\": 1, \"vector_table\": \"0x0\", \"reset\": \"0x0\", \"sample_isr\": \"0x0\", \"control\": \"0x0\", \"stack_top\": \"0x0\", \"keys\": [99]}",
    b"127",
    b"255",
];

/// Extreme values a field of the map is set to.
fn extreme() -> Vec<serde_json::Value> {
    use serde_json::json;
    vec![
        json!(0),
        json!(1),
        json!(2),
        json!(127),
        json!(128),
        json!(4_294_967_295u64),
        json!(18_446_744_073_709_551_615u64),
        json!(1_000_000_000_000u64),
        json!(200_000_000),
        json!(44_100),
        json!(-1),
        json!("0x20000001"),
        json!("0x2003f000"),
        json!("0x2003f400"),
        json!("0x21000100"),
        json!("0x30000001"),
        json!("0xffffffff"),
        json!("zz"),
        json!(""),
        json!([]),
        json!([0, 0]),
        json!(null),
    ]
}

/// The map's leaves (numbers and strings), in document order, as JSON pointers.
fn leaves(v: &serde_json::Value, at: String, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                leaves(x, format!("{at}/{k}"), out);
            }
        }
        serde_json::Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                leaves(x, format!("{at}/{i}"), out);
            }
        }
        _ => out.push(at),
    }
}

#[test]
fn mutated_key_maps_run_or_name_their_field() {
    let (elf, map) = firmware();
    let doc: serde_json::Value = serde_json::from_str(&map).unwrap();
    let mut paths = Vec::new();
    leaves(&doc, String::new(), &mut paths);
    let values = extreme();
    let (mut runner, cases) = fuzz::runner(60);
    let (run, parsed, ran) = (Cell::new(0u32), Cell::new(0u32), Cell::new(0u32));
    runner
        .run(
            &(
                // Field edits (they keep the JSON a key map), and now and then byte edits.
                prop::collection::vec((any::<usize>(), any::<usize>()), 0..4),
                prop::option::weighted(0.2, fuzz::edits(TOKENS)),
                prop::option::weighted(0.1, fuzz::edits(&[b"\xff\xff\xff\xff"])),
            ),
            |(fields, edits, elf_edits)| {
                let mut d = doc.clone();
                for (p, v) in &fields {
                    if let Some(x) = d.pointer_mut(&paths[p % paths.len()]) {
                        *x = values[v % values.len()].clone();
                    }
                }
                let text = d.to_string();
                let text = match &edits {
                    Some(e) => fuzz::apply(text.as_bytes(), e),
                    None => text.into_bytes(),
                };
                let elf = match &elf_edits {
                    Some(e) => fuzz::apply(&elf, e),
                    None => elf.clone(),
                };
                let (outcome, dt, peak) = fuzz::measured(|| {
                    let Ok(m) = serde_json::from_slice::<KeyMap>(&text) else {
                        return 0;
                    };
                    let sensors: Vec<Vec<i32>> = m.keys.iter().map(|_| vec![0, 1 << 14]).collect();
                    let refs: Vec<&[i32]> = sensors.iter().map(Vec::as_slice).collect();
                    match flash::run_elf(&elf, &m, &refs, SAMPLES, &mut |_, _| {}, None) {
                        Ok(r) => {
                            for c in &r.cores {
                                assert!(c.samples as usize <= SAMPLES, "{r:?}");
                                assert!(c.misses > 0 || c.samples as usize + 1 >= SAMPLES, "{r:?}");
                            }
                            2
                        }
                        Err(e) => {
                            assert!(!e.is_empty());
                            1
                        }
                    }
                });
                run.set(run.get() + 1);
                parsed.set(parsed.get() + u32::from(outcome >= 1));
                ran.set(ran.get() + u32::from(outcome == 2));
                prop_assert!(dt < Duration::from_secs(20), "{dt:?}");
                prop_assert!(peak < 1 << 30, "{peak} bytes");
                Ok::<(), TestCaseError>(())
            },
        )
        .unwrap();
    eprintln!(
        "fuzz_keymap: {} cases, {} key maps parsed, {} ran",
        run.get(),
        parsed.get(),
        ran.get()
    );
    assert!(run.get() >= cases);
    assert!(parsed.get() > 0);
}
