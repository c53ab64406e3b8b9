//! A keyboard as a set of boards (`tactus_firmware::boards`):
//!
//! - the planner's board count equals the brute-force minimum over every contiguous split
//!   of small mixed layouts (up to 12 keys, three instruments, graded params), with the
//!   same fit predicate (each board's image);
//! - every planned board of the shipped layouts (grand88, split_harpsichord_piano) runs one
//!   emulated second of the budget corpus with no deadline miss, every DAC word bit-exact
//!   with the fixed interpreter plus the reference limiter, and every core's measured
//!   handler within its static bound (`--ignored`: in CI, `flash.rs` checks the same on
//!   every board booted from flash, the first and last a second, the others 50 ms).

use std::path::Path;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_firmware::boards::{self, board_image, check_board, PlanKey, ProgramCosts};
use tactus_firmware::corpus::{self, Size};
use tactus_firmware::image::{compile_layout, Program};
use tactus_runtime::keyboard::{read_layout, BoardSpec};
use tactus_runtime::limiter::{Limiter, LimiterConfig};
use tactus_runtime::rng::XorShift64;

#[path = "common/layouts.rs"]
mod layouts;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn shipped(name: &str) -> Result<String, String> {
    std::fs::read_to_string(root().join(format!("instruments/{name}.tactus")))
        .map_err(|e| format!("{name}: {e}"))
}

fn board(name: &str) -> BoardSpec {
    layouts::shipped_board(name)
}

fn limiter(b: &BoardSpec) -> LimiterConfig {
    LimiterConfig::for_board(b)
}

/// The fewest boards of any contiguous split of `keys` whose every board fits, by brute
/// force over all 2^(n−1) splits (the fit of each range computed once).
#[allow(clippy::needless_range_loop)] // `end` indexes the split, not one slice
fn brute_force(
    programs: &[Program],
    costs: &ProgramCosts,
    keys: &[PlanKey],
    b: &BoardSpec,
) -> usize {
    let n = keys.len();
    let lim = limiter(b);
    let mut fits = vec![vec![false; n]; n];
    for i in 0..n {
        for j in i..n {
            fits[i][j] = check_board(programs, costs, &keys[i..=j], b, &lim)
                .unwrap()
                .fits();
        }
    }
    let mut best = usize::MAX;
    for cuts in 0..1u32 << (n - 1) {
        let (mut start, mut count, mut ok) = (0, 0, true);
        for end in 0..n {
            if end == n - 1 || cuts & (1 << end) != 0 {
                ok &= fits[start][end];
                count += 1;
                start = end + 1;
            }
        }
        if ok {
            best = best.min(count);
        }
    }
    best
}

#[test]
fn the_planner_needs_no_more_boards_than_brute_force() {
    // Three instruments, the piano in three graded variants.
    let mut programs = Vec::new();
    for (name, params) in [
        ("hammond", vec![]),
        ("harpsichord_2x8", vec![]),
        ("grand_piano", vec![("M_h".to_string(), "9 g".to_string())]),
        ("grand_piano", vec![("M_h".to_string(), "5 g".to_string())]),
    ] {
        let config = tactus_compiler::lower::Config {
            overrides: params,
            ..Default::default()
        };
        programs.push(Program::compile(&shipped(name).unwrap(), &config).unwrap());
    }
    let mut rng = XorShift64::new(0xB0A4D);
    let mut compared = 0;
    for b in [board("rp2040"), board("rp2040_200mhz")] {
        let costs = ProgramCosts::new(&programs, &b, &limiter(&b)).unwrap();
        for trial in 0..4 {
            // Runs of one instrument, 8 to 12 keys in all.
            let n = 8 + rng.below(5);
            let mut keys = Vec::with_capacity(n);
            let mut program = rng.below(4);
            for k in 0..n {
                if rng.below(4) == 0 {
                    program = rng.below(4);
                }
                keys.push(PlanKey {
                    key: 40 + k as u8,
                    program,
                });
            }
            let plan = boards::plan(&programs, &costs, &keys, &b, &limiter(&b), &mut |_, _| {})
                .unwrap()
                .boards;
            let covered: Vec<u8> = plan.iter().flat_map(|p| p.keys.clone()).collect();
            assert_eq!(covered, keys.iter().map(|k| k.key).collect::<Vec<_>>());
            assert!(plan.iter().all(|p| p.fits()), "{plan:?}");
            let best = brute_force(&programs, &costs, &keys, &b);
            println!(
                "{} trial {trial}: {n} keys {:?} → {} boards (brute force {best})",
                b.name,
                keys.iter().map(|k| k.program).collect::<Vec<_>>(),
                plan.len()
            );
            assert_eq!(plan.len(), best);
            compared += 1;
        }
    }
    assert_eq!(compared, 8);
}

/// The instrument of MIDI key `key` in a resolved layout.
fn assigned_of(assigned: &[tactus_runtime::keyboard::KeyAssignment], key: u8) -> &str {
    assigned
        .iter()
        .find(|a| a.key == key)
        .map_or("?", |a| a.instrument.as_str())
}

/// Runs every planned board of `layout` for `samples` samples of the budget corpus, and
/// checks that each core of each board holds one code copy per instrument.
fn boards_run_bit_exact(layout: &str, samples: usize) {
    let (_, assigned) = read_layout(&root().join(layout)).unwrap();
    let b = board("rp2040");
    let lim = limiter(&b);
    let (programs, index) = compile_layout(&assigned, &shipped, b.sample_rate_hz).unwrap();
    let costs = ProgramCosts::new(&programs, &b, &lim).unwrap();
    let keys: Vec<PlanKey> = assigned
        .iter()
        .zip(&index)
        .map(|(a, &program)| PlanKey {
            key: a.key,
            program,
        })
        .collect();
    let plan = boards::plan(&programs, &costs, &keys, &b, &lim, &mut |_, _| {})
        .unwrap()
        .boards;
    assert!(plan.iter().all(|p| p.fits()), "{layout}: {plan:?}");
    // Each program's corpus, concatenated and cycled to `samples`; key i starts at an
    // offset of its own so that neighbours do not move in step.
    let words: Vec<Vec<i32>> = programs
        .iter()
        .map(|p| {
            corpus::corpus(&p.fixed, Size::Quick)
                .into_iter()
                .flat_map(|r| r.records.into_iter().map(|w| w[0]))
                .collect()
        })
        .collect();
    let mut worst_use = 0.0f64;
    for (bi, bv) in plan.iter().enumerate() {
        let bkeys: Vec<PlanKey> = keys
            .iter()
            .filter(|k| bv.keys.contains(&k.key))
            .copied()
            .collect();
        let (_, image) = board_image(&programs, &costs, &bkeys, &b, &lim).unwrap();
        let image = image.unwrap();
        // One code copy per instrument per core: graded params are run-time data.
        for c in 0..image.cores() {
            let mut instruments: Vec<&str> = image
                .core_keys(c)
                .iter()
                .map(|&i| assigned_of(&assigned, bkeys[i].key))
                .collect();
            instruments.sort_unstable();
            instruments.dedup();
            assert_eq!(
                image.code_copies(c),
                instruments.len(),
                "{layout} board {bi} core {c}: {instruments:?}"
            );
        }
        let mut run = image.run().unwrap();
        let mut insts: Vec<FixedInstance> = bkeys
            .iter()
            .map(|k| {
                FixedInstance::with_params(
                    &programs[k.program].fixed,
                    programs[k.program].params.clone(),
                )
            })
            .collect();
        let mut refs: Vec<Limiter> = bkeys.iter().map(|_| Limiter::new(&lim).unwrap()).collect();
        let mut worst = vec![0u64; image.cores()];
        let mut sensor = vec![0i32; bkeys.len()];
        for n in 0..samples {
            for (i, k) in bkeys.iter().enumerate() {
                let w = &words[k.program];
                sensor[i] = w[(n + 997 * k.key as usize) % w.len()];
            }
            let out = run.step(&sensor).unwrap();
            for (i, k) in bkeys.iter().enumerate() {
                let fp = &programs[k.program].fixed;
                let total = insts[i].step_raw(&[sensor[i]]).total;
                let dac = refs[i].step(total, fp.total_frac).dac;
                assert_eq!(
                    (out.force[i], out.dac[i]),
                    (total, dac),
                    "{layout} board {bi} key {} sample {n}",
                    k.key
                );
            }
            for (c, w) in worst.iter_mut().enumerate() {
                *w = (*w).max(out.core_cycles[c]);
            }
        }
        let last = run.step(&sensor).unwrap();
        for (c, &w) in worst.iter().enumerate() {
            let bound = image.wcet(c).unwrap().bound();
            assert_eq!(last.misses[c], 0, "{layout} board {bi} core {c}");
            assert!(
                w <= bound,
                "{layout} board {bi} core {c}: measured {w} > static {bound}"
            );
            worst_use = worst_use.max(w as f64 / image.cycles_per_sample() as f64);
        }
    }
    println!(
        "{layout}: {} boards, {samples} samples each, 0 misses, bit-exact; worst measured core {:.1}% of a sample",
        plan.len(),
        100.0 * worst_use
    );
}

/// Every board's RAM image for a second (about a CPU-minute each layout): CI runs every
/// board from flash instead (`flash.rs`: every board a short run, the first and last a
/// second; all of them a second with `--ignored`).
#[test]
#[ignore]
fn every_planned_board_of_grand88_runs_a_second_bit_exact_without_misses() {
    boards_run_bit_exact("instruments/layouts/grand88.toml", 44_100);
}

/// As the grand88 test above (`--ignored`).
#[test]
#[ignore]
fn every_planned_board_of_the_split_layout_runs_a_second_bit_exact_without_misses() {
    boards_run_bit_exact("instruments/layouts/split_harpsichord_piano.toml", 44_100);
}

/// The quiescent-key guard never costs a board: where a board's guarded image misses the
/// deadline, [`board_image`] builds it without the guard. A 133 MHz board holds as many
/// harpsichord keys with the guard on by default as without it, although with the guard
/// forced on every key (its shadow compare in every key's worst case) that board would not
/// fit.
#[test]
fn the_quiescent_guard_never_costs_a_board() {
    let b = board("rp2040");
    let lim = limiter(&b);
    let guarded =
        vec![Program::compile(&shipped("harpsichord").unwrap(), &Default::default()).unwrap()];
    assert!(guarded[0].quiescent_guard, "the guard is on by default");
    let costs = ProgramCosts::new(&guarded, &b, &lim).unwrap();
    assert!(costs.key_cycles[0] > costs.plain_key_cycles[0]);
    let cps = b.cycles_per_sample();
    // The most keys one board holds, by the planner's own verdict.
    let most_keys = |programs: &[Program], costs: &ProgramCosts| {
        (1..=32usize)
            .take_while(|&n| {
                let keys: Vec<PlanKey> = (0..n)
                    .map(|k| PlanKey {
                        key: 40 + k as u8,
                        program: 0,
                    })
                    .collect();
                check_board(programs, costs, &keys, &b, &lim)
                    .unwrap()
                    .fits()
            })
            .last()
            .unwrap()
    };
    let most = most_keys(&guarded, &costs);
    let keys: Vec<PlanKey> = (0..most)
        .map(|k| PlanKey {
            key: 40 + k as u8,
            program: 0,
        })
        .collect();
    let (_, image) = board_image(&guarded, &costs, &keys, &b, &lim).unwrap();
    let image = image.unwrap();
    let worst = (0..image.cores())
        .map(|c| image.wcet(c).unwrap().bound())
        .max()
        .unwrap();
    assert!(worst <= cps, "{worst} > {cps}");
    // The guard costs per key: with it forced on (no fallback), the same board must not fit
    // for this test to show anything.
    let guard_only = (0..image.cores())
        .map(|c| {
            let n = keys.len().div_ceil(2) as u64;
            image.wcet(c).unwrap().bound() + n * (costs.key_cycles[0] - costs.plain_key_cycles[0])
        })
        .max()
        .unwrap();
    assert!(
        guard_only > cps,
        "the fallback is not exercised: {guard_only} <= {cps}"
    );
    println!(
        "{most} harpsichord keys: {worst} cycles per core as built, about {guard_only} with the guard on every key (deadline {cps})"
    );
    let plain = vec![{
        let mut p = guarded[0].clone();
        p.quiescent_guard = false;
        p
    }];
    let plain_costs = ProgramCosts::new(&plain, &b, &lim).unwrap();
    let plain_most = most_keys(&plain, &plain_costs);
    assert_eq!(most, plain_most, "the guard cost a key per board");
}

/// The guard as a planned choice, on a synthetic board whose deadline is exactly what six
/// unguarded harpsichord keys (three per core) need: there the guard costs a board, so a
/// six-key keyboard is planned on one board without it (`guard_off`); a keyboard of twice
/// the guarded board's keys needs two boards either way, so every board keeps the guard.
#[test]
fn the_planner_drops_the_guard_only_where_it_saves_a_board() {
    // The sensor check off: the deadline is measured on the stock board, whose tick has a
    // fraction of a cycle a sample (so its keys take turns for the check, `glue::Turns`),
    // and used on a board of a whole number of cycles a sample (no accumulator: every key
    // checked every sample), which would price the same keys differently.
    let mut program =
        Program::compile(&shipped("harpsichord").unwrap(), &Default::default()).unwrap();
    program.sensor_check = false;
    let plain = {
        let mut p = program.clone();
        p.quiescent_guard = false;
        p
    };
    let keys = |n: usize| -> Vec<PlanKey> {
        (0..n)
            .map(|k| PlanKey {
                key: 40 + k as u8,
                program: 0,
            })
            .collect()
    };
    // The deadline: the fullest core of six unguarded keys on the stock board.
    let stock = board("rp2040");
    let plain_costs =
        ProgramCosts::new(std::slice::from_ref(&plain), &stock, &limiter(&stock)).unwrap();
    let six = check_board(
        std::slice::from_ref(&plain),
        &plain_costs,
        &keys(6),
        &stock,
        &limiter(&stock),
    )
    .unwrap();
    let need = six.cores.iter().map(|c| c.cycles).max().unwrap();
    let b = BoardSpec {
        name: "six unguarded harpsichord keys".into(),
        clock_hz: need as f64 * stock.sample_rate_hz,
        ..stock.clone()
    };
    assert_eq!(b.cycles_per_sample(), need);
    let lim = limiter(&b);
    let programs = vec![program];
    let costs = ProgramCosts::new(&programs, &b, &lim).unwrap();
    let plan = |n: usize| {
        boards::plan(&programs, &costs, &keys(n), &b, &lim, &mut |_, _| {})
            .unwrap()
            .boards
    };
    // With the guard on every board (the board's image, no fallback), how many keys fit.
    let guarded_fit = |n: usize| {
        let local = boards::board_image(&programs, &costs, &keys(n), &b, &lim)
            .unwrap()
            .1
            .unwrap();
        local.programs()[0].quiescent_guard
            && (0..local.cores()).all(|c| local.wcet(c).unwrap().bound() <= need)
    };
    let most_guarded = (1..=6).take_while(|&n| guarded_fit(n)).last().unwrap();
    assert!(
        most_guarded < 6,
        "the guard fits six keys: the choice does not matter here"
    );
    assert!(
        2 * most_guarded > 6,
        "{most_guarded}: case two needs more than six keys"
    );

    let one = plan(6);
    assert_eq!(one.len(), 1, "six keys fit one board without the guard");
    assert!(one[0].fits() && one[0].guard_off);

    let two = plan(2 * most_guarded);
    assert_eq!(two.len(), 2);
    assert!(
        two.iter().all(|v| v.fits() && !v.guard_off),
        "two boards either way: the guard stays on both"
    );
    println!(
        "deadline {need}: 6 keys on one board without the guard (at most {most_guarded} with it); {} keys: boards of {:?} keys, all guarded",
        2 * most_guarded,
        two.iter().map(|v| v.keys.len()).collect::<Vec<_>>()
    );
}
