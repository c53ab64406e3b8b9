//! The whole firmware image (`tactus_firmware::image`) on the emulated RP2040:
//!
//! - a layout that fits runs one simulated second (44 100 samples) with no deadline miss,
//!   every key's force word equal to the fixed interpreter's total and every current and
//!   DAC word equal to `runtime/src/limiter.rs`, events equal, and every measured handler
//!   within its static WCET bound;
//! - an overloaded image (grand piano keys on a slow clock) counts misses;
//! - the firmware limiter against the reference on adversarial force words (noise,
//!   stuck at full scale, glitches): directly on every shift path, and through an image
//!   whose instrument passes its sensor through as the force;
//! - pens (several sensor words per key, one DAC word per force axis): a small pen and the
//!   rubbed resonator bank, every axis' DAC code equal to the limiter of the fixed
//!   interpreter's axis total (z: the total, x/y: the outputs `force.x`/`force.y`), no miss;
//!   their glue cost measured and static; window overflows are errors naming the program.

use std::path::Path;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_compiler::ir::{Axis, AxisTotal};
use tactus_compiler::lower::Config;
use tactus_emulator::{Board, Config as BoardConfig, Engine};
use tactus_firmware::image::glue::Scale;
use tactus_firmware::image::{
    assign_cores, compile_layout, guard_record_routine, key_specs, limiter_routine, FirmwareImage,
    ImageRun, KeySpec, Program,
};
use tactus_runtime::keyboard::{assign, parse_layout, BoardSpec};
use tactus_runtime::limiter::{Limiter, LimiterConfig};
use tactus_runtime::rng::XorShift64;
use tactus_runtime::stimulus;

#[path = "common/layouts.rs"]
mod layouts;

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn instrument(name: &str, overrides: &[(&str, &str)]) -> Program {
    let text = std::fs::read_to_string(root().join(format!("instruments/{name}.tactus"))).unwrap();
    let config = Config {
        overrides: overrides
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect(),
        ..Config::default()
    };
    Program::compile(&text, &config).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn rp2040() -> BoardSpec {
    layouts::shipped_board("rp2040")
}

/// Key `i`'s stimulus: the built-ins in turn, each repeated to `len` samples.
fn stimuli(p: &Program, i: usize, len: usize) -> Vec<i32> {
    let names = stimulus::builtin_names();
    let s0 = &p.fixed.program.sensors[0];
    let (name, _) = names[i % names.len()];
    let s = stimulus::builtin(name, s0.range.1, 44_100.0).unwrap();
    (0..len)
        .map(|n| FixedInstance::sensor_raw(&p.fixed, 0, Some(s.key[n % s.key.len()])))
        .collect()
}

/// Per-core statistics of a run.
#[derive(Default, Debug)]
struct Stats {
    worst: Vec<u64>,
    total: Vec<u64>,
    stalls: Vec<u64>,
    events: usize,
    /// Per key and DAC word: the distinct DAC codes the image wrote.
    codes: Vec<Vec<std::collections::BTreeSet<i16>>>,
}

/// Runs `sensors[key][n]` (one word per key and sample: keyboard keys) through the image
/// and through interpreter + reference limiter; see [`run_words_against_reference`].
fn run_against_reference(
    image: &FirmwareImage,
    sensors: &[Vec<i32>],
    samples: usize,
) -> (usize, Vec<String>, Stats, ImageRun) {
    let words: Vec<Vec<Vec<i32>>> = sensors
        .iter()
        .map(|s| s[..samples].iter().map(|&w| vec![w]).collect())
        .collect();
    run_words_against_reference(image, &words, samples)
}

/// The reference of one key's DAC words: per DAC word of the image's key (in the image's
/// order), the axis it should carry and, from the interpreter's `RawOut`, the force word
/// and its format — taken from the IR's `force_axes`, not from the image's `Program::drives`.
fn reference_words(
    p: &Program,
    axes: &[Option<Axis>],
    want: &tactus_compiler::fixed::interp::RawOut,
) -> Vec<(i32, i32)> {
    let fp = &p.fixed;
    axes.iter()
        .map(|axis| {
            let t = axis.map_or(AxisTotal::Total, |a| {
                fp.program
                    .force_axes
                    .iter()
                    .find(|(b, _)| *b == a)
                    .unwrap()
                    .1
            });
            match t {
                AxisTotal::Total => (want.total, fp.total_frac),
                AxisTotal::Output(id) => (want.outputs[id.index()], fp.output_frac[id.index()]),
            }
        })
        .collect()
}

/// Runs `sensors[key][n]` (each key's sensor words of sample `n`) through the image and
/// through interpreter + one reference limiter per DAC word; returns the mismatch count
/// (every DAC word of every key and the events compared; the first few described), cycle
/// statistics and the run.
fn run_words_against_reference(
    image: &FirmwareImage,
    sensors: &[Vec<Vec<i32>>],
    samples: usize,
) -> (usize, Vec<String>, Stats, ImageRun) {
    let programs = image.programs();
    let keys = image.keys();
    let mut insts: Vec<FixedInstance> = keys
        .iter()
        .map(|k| {
            FixedInstance::with_params(
                &programs[k.program].fixed,
                programs[k.program].params.clone(),
            )
        })
        .collect();
    let axes: Vec<Vec<Option<Axis>>> = keys
        .iter()
        .map(|k| {
            let p = &programs[k.program];
            if p.fixed.program.is_pen() {
                // z first, then the other axes in the program's order.
                let mut v = vec![Some(Axis::Z)];
                v.extend(
                    p.fixed
                        .program
                        .force_axes
                        .iter()
                        .filter(|(a, _)| *a != Axis::Z)
                        .map(|(a, _)| Some(*a)),
                );
                v
            } else {
                vec![None]
            }
        })
        .collect();
    let mut lims: Vec<Vec<Limiter>> = axes
        .iter()
        .map(|a| {
            a.iter()
                .map(|_| Limiter::new(image.limiter_config()).unwrap())
                .collect()
        })
        .collect();
    let mut run = image.run().unwrap();
    let cores = image.cores();
    let mut st = Stats {
        worst: vec![0; cores],
        total: vec![0; cores],
        stalls: vec![0; cores],
        events: 0,
        codes: axes
            .iter()
            .map(|a| vec![Default::default(); a.len()])
            .collect(),
    };
    let (mut bad, mut first) = (0, Vec::new());
    let mut words = Vec::with_capacity(image.sensor_words());
    for n in 0..samples {
        words.clear();
        for s in sensors {
            words.extend_from_slice(&s[n]);
        }
        let got = run.step(&words).unwrap().clone();
        for c in 0..cores {
            assert_eq!(got.handler_runs[c], 1, "sample {n} core {c}");
            st.worst[c] = st.worst[c].max(got.core_cycles[c]);
            st.total[c] += got.core_cycles[c];
            st.stalls[c] += got.stalls[c];
        }
        let mut want_events = Vec::new();
        for (k, spec) in keys.iter().enumerate() {
            let p = &programs[spec.program];
            let want = insts[k].step_raw(&sensors[k][n]).clone();
            for (e, args) in &want.events {
                want_events.push((k, *e, args.clone()));
            }
            let drives = &got.drives[k];
            let mut ok = drives.len() == axes[k].len()
                && got.force[k] == want.total
                && (got.current_ua[k], got.dac[k]) == (drives[0].current_ua, drives[0].dac);
            let mut desc = String::new();
            for (j, (word, frac)) in reference_words(p, &axes[k], &want).into_iter().enumerate() {
                let lim = lims[k][j].step(word, frac);
                let d = drives.get(j).copied().unwrap_or_default();
                st.codes[k][j].insert(d.dac);
                let same = d.axis == axes[k][j]
                    && Some(d.slot) == image.window_words(k).map(|w| w.1[j])
                    && (d.force, d.current_ua, d.dac) == (word, lim.current_ua, lim.dac);
                if !same {
                    ok = false;
                    desc += &format!(
                        " [word {j}: image {d:?}; reference axis {:?} force {word} current {} dac {}]",
                        axes[k][j], lim.current_ua, lim.dac
                    );
                }
            }
            if !ok {
                bad += 1;
                if first.len() < 5 {
                    first.push(format!(
                        "sample {n} key {k}: image force {} current {} dac {}, total {}{desc}",
                        got.force[k], got.current_ua[k], got.dac[k], want.total
                    ));
                }
            }
        }
        let got_events: Vec<_> = got
            .events
            .iter()
            .map(|e| (e.key, e.event, e.args.clone()))
            .collect();
        st.events += got_events.len();
        if got_events != want_events {
            bad += 1;
            if first.len() < 5 {
                first.push(format!(
                    "sample {n}: events {got_events:?}, reference {want_events:?}"
                ));
            }
        }
    }
    (bad, first, st, run)
}

#[test]
fn a_layout_that_fits_runs_a_second_without_misses_bit_exact_within_its_wcet() {
    // Three programs (two harpsichord parameter sets share nothing; the hammond is shared by
    // two keys), six keys on both cores by LPT.
    let programs = vec![
        instrument("harpsichord", &[]),
        instrument("harpsichord", &[("G", "0.4 N")]),
        instrument("hammond", &[]),
    ];
    let key_programs = [0, 1, 2, 2, 0, 1];
    let cores = assign_cores(&programs, &key_programs, 2).unwrap();
    let keys: Vec<KeySpec> = key_programs
        .iter()
        .zip(&cores)
        .enumerate()
        .map(|(i, (&program, &core))| KeySpec {
            slot: 60 + i,
            program,
            core,
        })
        .collect();
    let board = rp2040();
    let image = FirmwareImage::build(&programs, &keys, &board, &LimiterConfig::default()).unwrap();
    let samples = 44_100;
    let sensors: Vec<Vec<i32>> = keys
        .iter()
        .enumerate()
        .map(|(i, k)| stimuli(&programs[k.program], i, samples))
        .collect();
    let (bad, first, st, mut run) = run_against_reference(&image, &sensors, samples);
    let last = run.step(&vec![0; keys.len()]).unwrap().clone();
    for c in 0..image.cores() {
        let w = image.wcet(c).unwrap();
        println!(
            "core {c}: keys {:?}, code {} bytes, handler cycles mean {:.1} worst {} (budget {}), \
             static {} + contention {} = {}, stalls {}, misses {}",
            image.core_keys(c),
            image.code_bytes(c),
            st.total[c] as f64 / samples as f64,
            st.worst[c],
            image.cycles_per_sample(),
            w.analysed,
            w.contention,
            w.bound(),
            st.stalls[c],
            last.misses[c]
        );
        assert_eq!(last.misses[c], 0, "core {c} missed deadlines");
        assert!(
            st.worst[c] <= w.bound(),
            "core {c}: measured {} > static bound {}",
            st.worst[c],
            w.bound()
        );
        assert!(st.worst[c] > 0 && w.bound() < image.cycles_per_sample());
    }
    assert!(bad == 0, "{bad} mismatches; first:\n{}", first.join("\n"));
    println!("{} events (plucks)", st.events);
    assert!(st.events > 0, "no event to compare");
    assert_eq!(run.samples(), samples as u64 + 1);
    // The image's tick schedule is the host's: after sample n (from 0) each core's SysTick
    // next reaches 0 at tick n+1's cycle.
    let next = run.tick_cycle(run.samples());
    for c in 0..2 {
        assert_eq!(run.board().cores[c].nvic.syst_next, next, "core {c}");
    }
}

/// The sample tick is each core's SysTick: both cores' handlers are entered on the same
/// cycle, exactly one exception entry after tick n's cycle `first + ⌊n·clock/fs⌋`; the
/// periods are `⌊clock/fs⌋` (the deadline) or one more, and 63 of them at 133 MHz and
/// 44.1 kHz take exactly 63 · 133e6 / 44100 cycles (3015 + 55/63 each). At 200 MHz the
/// same with 4535 + 65/441.
#[test]
fn the_sample_tick_is_cycle_exact_and_the_same_on_both_cores() {
    use tactus_isa::timing::EXCEPTION_ENTRY;
    let programs = vec![instrument("hammond", &[])];
    let keys: Vec<KeySpec> = (0..2)
        .map(|i| KeySpec {
            slot: 60 + i,
            program: 0,
            core: i,
        })
        .collect();
    for (file, q, rem, den) in [
        ("rp2040", 3015u64, 55u64, 63u64),
        ("rp2040_200mhz", 4535, 65, 441),
    ] {
        let board = layouts::shipped_board(file);
        let image =
            FirmwareImage::build(&programs, &keys, &board, &LimiterConfig::default()).unwrap();
        assert_eq!(image.cycles_per_sample(), q);
        let t = image.tick();
        assert_eq!((t.q as u64, t.rem as u64, t.den as u64), (q, rem, den));
        let mut run = image.run().unwrap();
        let handlers: Vec<usize> = (0..2)
            .map(|c| {
                let isr = image.core_addresses(c).unwrap()[2];
                run.board().profile_handler(isr)
            })
            .collect();
        let samples = 2 * den as usize + 1;
        for _ in 0..samples {
            run.step(&[0, 0]).unwrap();
        }
        let starts: Vec<Vec<u64>> = handlers
            .iter()
            .map(|&h| run.board().calls(h).iter().map(|c| c.start).collect())
            .collect();
        assert_eq!(starts[0].len(), samples, "{file}");
        assert_eq!(
            starts[0], starts[1],
            "{file}: the cores tick on the same cycles"
        );
        for (n, &at) in starts[0].iter().enumerate() {
            assert_eq!(
                at,
                run.tick_cycle(n as u64) + EXCEPTION_ENTRY as u64,
                "{file}: tick {n}"
            );
        }
        let gaps: Vec<u64> = starts[0].windows(2).map(|w| w[1] - w[0]).collect();
        assert!(
            gaps.iter().all(|&g| g == q || g == q + 1),
            "{file}: {gaps:?}"
        );
        assert_eq!(*gaps.iter().min().unwrap(), q);
        assert_eq!(
            starts[0][den as usize] - starts[0][0],
            den * q + rem,
            "{file}"
        );
        println!(
            "{file}: periods of {q} and {} cycles, {} of the longer in {den}",
            q + 1,
            gaps[..den as usize].iter().filter(|&&g| g == q + 1).count()
        );
    }
}

#[test]
fn an_overloaded_image_counts_deadline_misses() {
    // Two grand piano keys per core at 48 MHz: 1088 cycles per sample, a piano key's update
    // alone costs more. Without the watchdog: it would reset the overloaded board (a core a
    // sample behind stops the feeds; `tests/watchdog.rs` shows that), and this counts the
    // misses of a board left running.
    let mut piano = instrument("grand_piano", &[]);
    piano.watchdog = false;
    let programs = vec![piano];
    let keys: Vec<KeySpec> = (0..4)
        .map(|i| KeySpec {
            slot: 40 + i,
            program: 0,
            core: i % 2,
        })
        .collect();
    let board = BoardSpec {
        clock_hz: 48e6,
        ..rp2040()
    };
    let image = FirmwareImage::build(&programs, &keys, &board, &LimiterConfig::default()).unwrap();
    assert!(image.wcet(0).unwrap().bound() > image.cycles_per_sample());
    let mut run = image.run().unwrap();
    let sensors = stimuli(&programs[0], 0, 300);
    let mut last = None;
    for w in &sensors {
        last = Some(run.step(&[*w; 4]).unwrap().clone());
    }
    let last = last.unwrap();
    println!("overloaded: misses {:?} after 300 samples", last.misses);
    for c in 0..2 {
        assert!(last.misses[c] > 0, "core {c}: no miss counted");
    }
}

/// The emulator's block engine against its interpreter on a firmware image (two grand
/// piano keys per core, both cores): after the start-up, every sample's outputs (forces,
/// currents, DAC words, events, handler cycles per core, contention stalls, misses) and
/// the cores' final cycle counters, instruction counts and registers are identical.
#[test]
fn the_emulators_block_engine_runs_an_image_exactly_as_its_interpreter() {
    let programs = vec![instrument("grand_piano", &[])];
    let keys: Vec<KeySpec> = (0..4)
        .map(|i| KeySpec {
            slot: 40 + i,
            program: 0,
            core: i % 2,
        })
        .collect();
    let image =
        FirmwareImage::build(&programs, &keys, &rp2040(), &LimiterConfig::default()).unwrap();
    let sensors = stimuli(&programs[0], 0, 1000);
    let mut runs = [image.run().unwrap(), image.run().unwrap()];
    runs[1].board().config.engine = Engine::Block;
    runs[1].board().config.own_banks = image.own_banks();
    runs[0].board().config.engine = Engine::Interp;
    for (n, w) in sensors.iter().enumerate() {
        let a = runs[0].step(&[*w; 4]).unwrap().clone();
        let b = runs[1].step(&[*w; 4]).unwrap().clone();
        assert_eq!(a, b, "sample {n}");
    }
    let [a, b] = &mut runs;
    assert!(b.board().blocks_decoded() > 0, "the block engine never ran");
    // The key programs run in each core's own bank and scratch bank: the cores run ahead
    // of each other there (`tactus_emulator::board`, "Running ahead").
    let (kept, undone) = b.board().run_ahead_windows();
    eprintln!("windows: {kept} kept, {undone} undone");
    eprintln!("memo: {:?}", b.board().memo_stats());
    assert!(kept > 0, "the cores never ran ahead");
    let mut sram = [vec![0u8; 0x4_2000], vec![0u8; 0x4_2000]];
    a.board().read_bytes(0x2000_0000, &mut sram[0]).unwrap();
    b.board().read_bytes(0x2000_0000, &mut sram[1]).unwrap();
    assert!(sram[0] == sram[1], "SRAM differs");
    for c in 0..2 {
        let (x, y) = (a.board().cores[c].clone(), b.board().cores[c].clone());
        assert_eq!(
            (x.cycle, x.instructions, x.r),
            (y.cycle, y.instructions, y.r),
            "core {c}"
        );
    }
}

/// Adversarial force words: noise, stuck at ±full scale, glitches between extremes,
/// small forces; `n` of them.
fn adversarial(rng: &mut XorShift64, n: usize, lo: i32, hi: i32) -> Vec<i32> {
    let mut v = Vec::with_capacity(n);
    while v.len() < n {
        let len = 1 + rng.below(6000);
        let kind = rng.below(5);
        for _ in 0..len.min(n - v.len()) {
            v.push(match kind {
                0 => rng.next_u64() as i32,                          // noise
                1 => hi,                                             // stuck at +full scale
                2 => lo,                                             // stuck at -full scale
                3 if rng.below(50) == 0 => [lo, hi][rng.below(2)],   // glitches
                _ => (rng.next_u64() as i32) >> (8 + rng.below(20)), // small forces
            });
        }
    }
    v
}

/// Checks the limiter invariants on the image's currents: never above peak, never above
/// rated for more than 100 ms in a row.
fn check_invariants(currents: &[i32], lim: &Limiter) {
    let mut run = 0i64;
    for (n, &i) in currents.iter().enumerate() {
        assert!(
            i.unsigned_abs() <= lim.peak_ua() as u32,
            "sample {n}: {i} µA"
        );
        if i.unsigned_abs() > lim.rated_ua() as u32 {
            run += 1;
        } else {
            run = 0;
        }
        assert!(
            run <= lim.over_samples(),
            "sample {n}: {run} samples above rated"
        );
    }
}

/// The Thumb limiter against `Limiter::step`, word for word and budget for budget, with its
/// scale in registers and from literals, for MIKEY's motor and for limiters whose budget
/// is short (a few samples: every path, spending to the last unit) with the largest and
/// the smallest recovery.
#[test]
fn the_firmware_limiter_equals_the_reference_on_adversarial_words() {
    let short = |recovery| LimiterConfig {
        recovery,
        over_time_s: 3.0 / 44_100.0,
        ..LimiterConfig::default()
    };
    let mut cases = Vec::new();
    // Force formats giving products shifted by < 32, 32 and > 32 bits.
    for frac in [0, 10, 21, 24, 30] {
        cases.push((LimiterConfig::default(), frac, Scale::InRegisters, 30_000));
    }
    for frac in [10, 24] {
        cases.push((LimiterConfig::default(), frac, Scale::Literal, 5_000));
        cases.push((short(255), frac, Scale::InRegisters, 5_000));
        cases.push((short(1), frac, Scale::Literal, 5_000));
        // The registers clobbered by the update (every constant a literal or immediate).
        cases.push((LimiterConfig::default(), frac, Scale::Clobbered, 5_000));
        cases.push((short(255), frac, Scale::Clobbered, 5_000));
        cases.push((short(1), frac, Scale::Clobbered, 5_000));
    }
    for (cfg, frac, scale, count) in cases {
        let base = 0x2000_1000;
        let (code, entry) = limiter_routine(&cfg, frac, scale, base).unwrap();
        let mut b = Board::new(BoardConfig::default());
        b.write_bytes(base, &code).unwrap();
        let mut reference = Limiter::new(&cfg).unwrap();
        let data = 0x2000_8000;
        b.write_u32(data, reference.budget() as u32).unwrap();
        let mut rng = XorShift64::new(0xC0FFEE + frac as u64);
        let mut words = vec![i32::MIN, i32::MAX, 0, -1, 1];
        words.extend(adversarial(&mut rng, count, i32::MIN, i32::MAX));
        let mut currents = Vec::new();
        for (n, &f) in words.iter().enumerate() {
            let r = b
                .call(0, entry, &[f as u32, data], 0x2002_0000, 10_000)
                .unwrap();
            let want = reference.step(f, frac);
            assert_eq!(
                (r.r0 as i32, b.read_u32(data).unwrap() as i64),
                (want.dac as i32, reference.budget()),
                "frac {frac} sample {n} force {f:#x}"
            );
            currents.push(want.current_ua);
        }
        check_invariants(&currents, &reference);
    }
}

#[test]
fn adversarial_forces_through_the_image_stay_within_the_motor_limits() {
    // The force is the sensor: ±100 N in Q7.24, the limiter's gain makes most of that range
    // far above the 2 A peak.
    let text = "instrument pass {\n sensor f: N in [-100 N, 100 N]\n force out = f\n}\n";
    let programs = vec![Program::compile(text, &Config::default()).unwrap()];
    let keys: Vec<KeySpec> = (0..2)
        .map(|i| KeySpec {
            slot: i,
            program: 0,
            core: i,
        })
        .collect();
    let image =
        FirmwareImage::build(&programs, &keys, &rp2040(), &LimiterConfig::default()).unwrap();
    let (lo, hi) = programs[0].fixed.sensor_raw_range[0];
    let samples = 20_000;
    let mut rng = XorShift64::new(99);
    let sensors: Vec<Vec<i32>> = (0..2)
        .map(|_| adversarial(&mut rng, samples, lo, hi))
        .collect();
    let (bad, first, _, _) = run_against_reference(&image, &sensors, samples);
    assert!(bad == 0, "{bad} mismatches; first:\n{}", first.join("\n"));
    // And the invariants on the image's own currents, replayed from a fresh run.
    let mut run = image.run().unwrap();
    let lim = Limiter::new(image.limiter_config()).unwrap();
    let mut currents = vec![Vec::new(), Vec::new()];
    for (&a, &b) in sensors[0].iter().zip(&sensors[1]) {
        let s = run.step(&[a, b]).unwrap();
        for (c, &i) in currents.iter_mut().zip(&s.current_ua) {
            c.push(i);
        }
    }
    for c in &currents {
        check_invariants(c, &lim);
        assert!(c.iter().any(|&i| i.unsigned_abs() > lim.rated_ua() as u32));
    }
}

#[test]
fn bad_keys_and_boards_are_errors() {
    let programs = vec![instrument("hammond", &[])];
    let k = |slot, program, core| KeySpec {
        slot,
        program,
        core,
    };
    let lim = LimiterConfig::default();
    let b = rp2040();
    let err = |keys: &[KeySpec], board: &BoardSpec| {
        FirmwareImage::build(&programs, keys, board, &lim)
            .unwrap_err()
            .to_string()
    };
    assert!(err(&[k(200, 0, 0)], &b).contains("slot 200"));
    assert!(err(&[k(1, 0, 0), k(1, 0, 1)], &b).contains("also key 0"));
    assert!(err(&[k(1, 3, 0)], &b).contains("program 3"));
    assert!(err(&[k(1, 0, 2)], &b).contains("core 2"));
    let three = BoardSpec {
        cores: 3,
        ..b.clone()
    };
    assert!(err(&[k(1, 0, 0)], &three).contains("3 cores"));
    let odd = BoardSpec {
        sample_rate_hz: 44_100.5,
        ..b.clone()
    };
    assert!(err(&[k(1, 0, 0)], &odd).contains("whole number"));
    let mut run = FirmwareImage::build(&programs, &[k(1, 0, 0)], &b, &lim)
        .unwrap()
        .run()
        .unwrap();
    // A limiter product the Thumb code cannot shift (force words with 60 fraction bits).
    let e = limiter_routine(&lim, 60, Scale::InRegisters, 0x2000_0000)
        .unwrap_err()
        .to_string();
    assert!(e.contains("fraction bits"), "{e}");
    // Thirty copies of the piano's code (thirty distinct programs: clones of one `Program`
    // share one copy) do not fit one core's bank (twenty did, at 2.6 KB of code each).
    let piano = instrument("grand_piano", &[]);
    let many: Vec<Program> = (0..30)
        .map(|_| Program::new((*piano.fixed).clone(), (*piano.thumb).clone()))
        .collect();
    let keys: Vec<KeySpec> = (0..30).map(|i| k(i, i, 0)).collect();
    let e = FirmwareImage::build(&many, &keys, &b, &lim)
        .unwrap_err()
        .to_string();
    assert!(e.contains("core 0: code and data need"), "{e}");
    assert!(run
        .step(&[])
        .unwrap_err()
        .to_string()
        .contains("0 sensor words"));
}

#[test]
fn handler_overhead_per_core_and_per_key_measured_and_static() {
    // Two hammond keys on core 0, none on core 1 (its handler is the bare per-core cost).
    // Without the quiescent guard: every sample calls both updates, and the glue measured
    // is the issue-15 glue alone (the guard's cost: `quiescent_guard_*`).
    let mut programs = vec![instrument("hammond", &[])];
    programs[0].quiescent_guard = false;
    // The issue-15 glue without the sensor check either (its cost: `budget.rs`).
    programs[0].sensor_check = false;
    let keys: Vec<KeySpec> = (0..2)
        .map(|i| KeySpec {
            slot: 10 + i,
            program: 0,
            core: 0,
        })
        .collect();
    let image =
        FirmwareImage::build(&programs, &keys, &rp2040(), &LimiterConfig::default()).unwrap();
    let mut run = image.run().unwrap();
    assert_eq!(
        image.update_addr(0),
        image.update_addr(1),
        "one copy per program"
    );
    let sensors = stimuli(&programs[0], 0, 2000);
    let (mut empty_worst, mut glue_worst, mut handler_worst) = (0, 0, 0);
    let profile = run.board().profile_addr(image.update_addr(0).unwrap());
    for &w in &sensors {
        let s = run.step(&[w, w]).unwrap().clone();
        assert_eq!(s.misses, [0, 0]);
        // Both keys share one copy of the program, so the profile sees both calls.
        let updates: u64 = run
            .board()
            .calls(profile)
            .iter()
            .map(|c| 3 + c.cycles)
            .sum();
        assert_eq!(run.board().calls(profile).len(), 2);
        run.board().clear_calls(profile);
        empty_worst = u64::max(empty_worst, s.core_cycles[1]);
        handler_worst = u64::max(handler_worst, s.core_cycles[0]);
        // Per key: sensor copy, call set-up, limiter, DAC store.
        let glue = (s.core_cycles[0] - s.core_cycles[1] - updates) / 2;
        glue_worst = u64::max(glue_worst, glue);
    }
    let (w0, w1) = (image.wcet(0).unwrap(), image.wcet(1).unwrap());
    let static_glue = (w0.analysed - w0.updates - w1.analysed) / 2;
    println!(
        "per core: measured {empty_worst} cycles, static {}; per key (limiter included): \
         measured worst {glue_worst}, static {static_glue}; core 0 handler worst {handler_worst}, \
         static {} (updates {})",
        w1.analysed,
        w0.bound(),
        w0.updates
    );
    assert!(empty_worst > 0 && empty_worst <= w1.analysed);
    assert!(glue_worst > 0 && glue_worst <= static_glue);
    assert!(handler_worst <= w0.bound());
    // The issue's target for the whole per-key glue (sensor copy, call, limiter, DAC store).
    assert!(static_glue <= 40, "static glue per key {static_glue} > 40");
}

/// The instrument text for a layout's instrument name (the shipped ones by name).
fn shipped(name: &str) -> Result<String, String> {
    std::fs::read_to_string(root().join(format!("instruments/{name}.tactus")))
        .map_err(|e| e.to_string())
}

/// A layout with graded piano hammers (a program per key) and shared harpsichord keys, on
/// the 200 MHz board: no miss, bit-exact, events equal. (The static bound does not prove
/// the fit: the piano update's static WCET is far above its measured worst.)
#[test]
fn grand_piano_keys_from_a_layout_run_one_per_core_at_200_mhz_without_misses() {
    // Two harpsichord keys (one program) and two piano keys with graded hammers (a program
    // each).
    let text = r#"
        name = "test"
        [[range]]
        keys = [58, 59]
        instrument = "harpsichord"
        [[range]]
        keys = [60, 61]
        instrument = "grand_piano"
        grade = [ { param = "M_h", from = "6 g", to = "3.5 g" } ]
    "#;
    let layout = parse_layout(text, "test").unwrap();
    let assigned = assign(&layout, "test", Path::new(".")).unwrap();
    let (programs, index) = compile_layout(&assigned, &shipped, 44_100.0).unwrap();
    assert_eq!(programs.len(), 3);
    assert_eq!(index, [0, 0, 1, 2]);
    for p in &programs {
        println!(
            "{}: static update WCET {}",
            p.thumb.stem,
            p.update_wcet().unwrap()
        );
    }
    let cores = assign_cores(&programs, &index, 2).unwrap();
    let keys = key_specs(&assigned, &index, &cores);
    let board = layouts::shipped_board("rp2040_200mhz");
    let image = FirmwareImage::build(&programs, &keys, &board, &LimiterConfig::default()).unwrap();
    let samples = 11_025; // 0.25 s
    let sensors: Vec<Vec<i32>> = keys
        .iter()
        .enumerate()
        .map(|(i, k)| stimuli(&programs[k.program], i + 1, samples))
        .collect();
    let (bad, first, st, mut run) = run_against_reference(&image, &sensors, samples);
    assert!(bad == 0, "{bad} mismatches; first:\n{}", first.join("\n"));
    let misses = run.step(&[0; 4]).unwrap().misses.clone();
    println!("{} events (strikes, plucks)", st.events);
    assert!(st.events > 0);
    for (c, &missed) in misses.iter().enumerate() {
        let w = image.wcet(c).unwrap();
        println!(
            "200 MHz core {c}: keys {:?}, worst {} mean {:.0}, static bound {} of {}",
            image.core_keys(c),
            st.worst[c],
            st.total[c] as f64 / samples as f64,
            w.bound(),
            image.cycles_per_sample()
        );
        assert_eq!(missed, 0);
        assert!(st.worst[c] <= w.bound() && st.worst[c] < image.cycles_per_sample());
    }
}

/// A pen with three sensors and a force on every axis, in three different formats: a plane
/// on z, viscous drag on x, a stiff spring on y (up to ±40 N: far above the limiter's peak,
/// so its budget and clamps are exercised on that axis).
const TINY_PEN: &str = "instrument tiny_pen {
    sensor pen: m in { z: [0 mm, 10 mm], x: [0 mm, 100 mm], y: [-20 mm, 20 mm] }
    force contact = { z: 300 N/m * pen.z, x: -2 N*s/m * d(pen.x), y: -2000 N/m * pen.y }
}
";

/// Sample `n` of a pen gesture at `fs` Hz, per sensor of `p` (raw words): presses on the
/// first sensor (z: 0.4 s down, 0.1 s lifted, depth varying from press to press) and, per
/// further sensor, a stroke sweeping its range at its own rate, with `seed`'s noise and an
/// occasional out-of-range glitch.
fn pen_gesture(
    p: &Program,
    fs: f64,
    len: usize,
    rng: &mut XorShift64,
    glitches: bool,
) -> Vec<Vec<i32>> {
    let fp = &p.fixed;
    let sensors = &fp.program.sensors;
    (0..len)
        .map(|n| {
            let t = n as f64 / fs;
            sensors
                .iter()
                .enumerate()
                .map(|(i, s)| {
                    let (lo, hi) = s.range;
                    let span = hi - lo;
                    let noise = (rng.below(1001) as f64 - 500.0) * 1e-6 * span;
                    let x = if i == 0 {
                        let press = (t / 0.5) as u64;
                        let phase = t - press as f64 * 0.5;
                        let depth = 0.2 + 0.8 * ((press * 7919 % 10) as f64 / 10.0);
                        if phase < 0.4 {
                            lo + span * depth * (std::f64::consts::PI * phase / 0.4).sin()
                        } else {
                            lo
                        }
                    } else {
                        let f = 1.3 * i as f64 + 0.7;
                        lo + span * (0.5 + 0.45 * (2.0 * std::f64::consts::PI * f * t).sin())
                    };
                    let x = if rng.below(500) == 0 && glitches {
                        [lo - span, hi + span][rng.below(2)]
                    } else {
                        x + noise
                    };
                    FixedInstance::sensor_raw(fp, i, Some(x))
                })
                .collect()
        })
        .collect()
}

/// Runs the pens and checks: bit-exact DAC words, no miss, measured within the static bound.
/// Returns the statistics.
fn check_pen_run(
    image: &FirmwareImage,
    sensors: &[Vec<Vec<i32>>],
    samples: usize,
    what: &str,
) -> Stats {
    let (bad, first, st, mut run) = run_words_against_reference(image, sensors, samples);
    let words: usize = image.keys().len();
    let last = run.step(&vec![0; image.sensor_words()]).unwrap().clone();
    let drives: usize = last.drives.iter().map(Vec::len).sum();
    println!(
        "{what}: {samples} samples, {words} keys, {drives} DAC words each sample ({} \
         compared); key-samples with a mismatch: {bad}",
        samples * drives
    );
    assert!(
        bad == 0,
        "{what}: {bad} mismatches; first:\n{}",
        first.join("\n")
    );
    for c in 0..image.cores() {
        let w = image.wcet(c).unwrap();
        println!(
            "{what} core {c}: keys {:?}, code {} bytes, handler worst {} mean {:.0}, static {} \
             + contention {} = {} of {} cycles per sample; misses {}",
            image.core_keys(c),
            image.code_bytes(c),
            st.worst[c],
            st.total[c] as f64 / samples as f64,
            w.analysed,
            w.contention,
            w.bound(),
            image.cycles_per_sample(),
            last.misses[c]
        );
        assert_eq!(last.misses[c], 0, "{what}: core {c} missed deadlines");
        assert!(st.worst[c] <= w.bound(), "{what}: core {c} over its bound");
        assert!(w.bound() < image.cycles_per_sample());
    }
    st
}

/// The first pen of a run drove more than 10 distinct DAC codes on z and on x, and one on y
/// (an instrument whose force has no y term).
fn assert_z_and_x_move_y_still(st: &Stats, what: &str) {
    let distinct: Vec<usize> = st.codes[0].iter().map(|s| s.len()).collect();
    println!("{what}: distinct DAC codes (z, x, y) {distinct:?}");
    assert!(
        distinct[0] > 10 && distinct[1] > 10 && distinct[2] == 1,
        "{what}: {distinct:?}"
    );
}

#[test]
fn a_pen_drives_one_dac_word_per_axis_each_the_limited_axis_total() {
    // The sensor check off: the gesture glitches out of range by design (the update's
    // saturation held bit-exact), which the check would trip on (the check on a pen:
    // `a_checked_pen_plays_bit_exact_without_a_trip`).
    let mut pen = Program::compile(TINY_PEN, &Config::default()).unwrap();
    pen.sensor_check = false;
    assert_eq!(pen.sensor_words(), 3);
    let axes: Vec<_> = pen.drives().unwrap().iter().map(|d| d.axis).collect();
    assert_eq!(axes, [Some(Axis::Z), Some(Axis::X), Some(Axis::Y)]);
    let fracs: Vec<_> = pen.drives().unwrap().iter().map(|d| d.frac).collect();
    println!("tiny pen: force formats (z, x, y) {fracs:?}");
    // A pen and a keyboard key on core 0, a second pen on core 1: the windows hold the
    // pens' words back to back with the key's.
    let programs = vec![pen, instrument("hammond", &[])];
    let keys = [
        KeySpec {
            slot: 10,
            program: 0,
            core: 0,
        },
        KeySpec {
            slot: 13,
            program: 1,
            core: 0,
        },
        KeySpec {
            slot: 14,
            program: 0,
            core: 1,
        },
    ];
    let image =
        FirmwareImage::build(&programs, &keys, &rp2040(), &LimiterConfig::default()).unwrap();
    assert_eq!(image.sensor_words(), 7);
    let samples = 8000;
    let mut rng = XorShift64::new(7);
    let sensors: Vec<Vec<Vec<i32>>> = keys
        .iter()
        .enumerate()
        .map(|(i, k)| {
            let p = &programs[k.program];
            if k.program == 0 {
                pen_gesture(p, 44_100.0, samples, &mut rng, true)
            } else {
                stimuli(p, i, samples)
                    .into_iter()
                    .map(|w| vec![w])
                    .collect()
            }
        })
        .collect();
    let st = check_pen_run(&image, &sensors, samples, "tiny pens + hammond");
    // Every axis of both pens moved: the words compared are not trivially equal.
    for k in [0, 2] {
        for (j, s) in st.codes[k].iter().enumerate() {
            assert!(s.len() > 10, "pen {k} DAC word {j}: codes {s:?}");
        }
    }
    let mut run = image.run().unwrap();
    let flat: Vec<i32> = sensors.iter().flat_map(|s| s[100].clone()).collect();
    // The DAC window words the run reports are the board's.
    let slots: Vec<_> = run.step(&flat).unwrap().drives[2]
        .iter()
        .map(|d| (d.slot, d.dac))
        .collect();
    for (slot, dac) in slots {
        let word = tactus_firmware::windows::DAC_BASE + 4 * slot as u32;
        assert_eq!(run.board().read_u32(word).unwrap() as i32 as i16, dac);
    }
}

#[test]
fn the_rubbed_bank_runs_as_a_pen_at_8_khz_bit_exact_without_misses() {
    // Its 11 masses need about 13 000 cycles per sample: 8 kHz on the 133 MHz board gives
    // 16 625 (its `require`s hold from about 3.2 kHz).
    let fs = 8000.0;
    let text = std::fs::read_to_string(root().join("instruments/rubbed_bank.tactus")).unwrap();
    let config = Config {
        sample_rate_hz: fs,
        ..Config::default()
    };
    let mut bank = Program::compile(&text, &config).unwrap();
    // The gesture glitches out of range by design: the sensor check off (as for the pens).
    bank.sensor_check = false;
    assert_eq!(bank.sensor_words(), 2);
    let axes: Vec<_> = bank.drives().unwrap().iter().map(|d| d.axis).collect();
    assert_eq!(axes, [Some(Axis::Z), Some(Axis::X), Some(Axis::Y)]);
    println!(
        "rubbed_bank: update static WCET {}",
        bank.update_wcet().unwrap()
    );
    let programs = vec![bank];
    let keys = [KeySpec {
        slot: 0,
        program: 0,
        core: 0,
    }];
    let board = BoardSpec {
        sample_rate_hz: fs,
        ..rp2040()
    };
    let image = FirmwareImage::build(&programs, &keys, &board, &LimiterConfig::default()).unwrap();
    let samples = 8000; // one second
    let mut rng = XorShift64::new(11);
    let sensors = vec![pen_gesture(&programs[0], fs, samples, &mut rng, true)];
    let st = check_pen_run(&image, &sensors, samples, "rubbed_bank at 8 kHz");
    // The plane (z) and the friction (x) move; nothing pushes along y.
    assert_z_and_x_move_y_still(&st, "rubbed_bank");
    // Its glue (2 sensor copies, 3 limiter calls and DAC stores), as `FirmwareImage::key_glue`
    // prices it: the handler of core 0 less the update and less core 1's bare handler, in
    // the image without the watchdog (whose feed is core 0's alone, `glue::Feed`).
    let mut quiet = programs.clone();
    quiet[0].watchdog = false;
    let image = FirmwareImage::build(&quiet, &keys, &board, &LimiterConfig::default()).unwrap();
    let (w0, w1) = (image.wcet(0).unwrap(), image.wcet(1).unwrap());
    let g = FirmwareImage::key_glue(&programs[0], &board, &LimiterConfig::default()).unwrap();
    println!(
        "rubbed_bank: glue static {} cycles, {} window words",
        g.cycles, g.window_words
    );
    assert_eq!(g.cycles, w0.analysed - w0.updates - w1.analysed);
    assert_eq!(g.window_words, 5);
}

#[test]
fn pen_glue_per_key_measured_and_static() {
    // One tiny pen on core 0, nothing on core 1 (its handler is the bare per-core cost): the
    // pen's glue is its three sensor copies, three limiter calls and three DAC stores.
    // Without the watchdog, whose feed is core 0's alone (`glue::Feed`): the difference of
    // the cores is then the key's glue.
    let mut pen = Program::compile(TINY_PEN, &Config::default()).unwrap();
    pen.watchdog = false;
    // The glue without the sensor check (the gesture's glitches would trip it).
    pen.sensor_check = false;
    let programs = vec![pen];
    let keys = [KeySpec {
        slot: 5,
        program: 0,
        core: 0,
    }];
    let image =
        FirmwareImage::build(&programs, &keys, &rp2040(), &LimiterConfig::default()).unwrap();
    let mut run = image.run().unwrap();
    let profile = run.board().profile_addr(image.update_addr(0).unwrap());
    let mut rng = XorShift64::new(3);
    let sensors = pen_gesture(&programs[0], 44_100.0, 3000, &mut rng, true);
    let mut glue_worst = 0;
    for w in &sensors {
        let s = run.step(w).unwrap().clone();
        assert_eq!(s.misses, [0, 0]);
        let update: u64 = run
            .board()
            .calls(profile)
            .iter()
            .map(|c| 3 + c.cycles)
            .sum();
        run.board().clear_calls(profile);
        glue_worst = glue_worst.max(s.core_cycles[0] - s.core_cycles[1] - update);
    }
    let (w0, w1) = (image.wcet(0).unwrap(), image.wcet(1).unwrap());
    let static_glue = w0.analysed - w0.updates - w1.analysed;
    // The keyboard key's glue, the same way.
    let mut hammond = vec![instrument("hammond", &[])];
    hammond[0].watchdog = false;
    hammond[0].sensor_check = false;
    let kb = FirmwareImage::build(&hammond, &keys, &rp2040(), &LimiterConfig::default()).unwrap();
    let (k0, k1) = (kb.wcet(0).unwrap(), kb.wcet(1).unwrap());
    let key_glue = k0.analysed - k0.updates - k1.analysed;
    println!(
        "pen (3 sensors, 3 axes) glue: measured worst {glue_worst}, static {static_glue}, \
         contention {} words; keyboard key glue static {key_glue}",
        w0.contention
    );
    assert!(glue_worst > 0 && glue_worst <= static_glue);
    // Its 3 sensor loads and 3 DAC stores are in core 0's own banks (the split windows):
    // no access can wait for the other core.
    assert_eq!(w0.contention, 0);
    assert!(image.window_words(0).is_some_and(|(s, d)| s.len() == 3
        && d.len() == 3
        && s.iter().chain(d).all(|w| w % 4 == 0 || w % 4 == 2)));
    // FirmwareImage::key_glue (what `tactus budget` uses) prices the most one key adds: a
    // key alone, or a second beside it, which costs one ADDS more (the step to its record)
    // but not the control block's reload before the handler's end (its update takes r5,
    // `Convention::SAMPLE_ISR`: 2 cycles once per core, which the first key carries).
    let lim = LimiterConfig::default();
    let g = FirmwareImage::key_glue(&programs[0], &rp2040(), &lim).unwrap();
    assert_eq!((g.cycles, g.window_words), (static_glue, 6));
    let g = FirmwareImage::key_glue(&hammond[0], &rp2040(), &lim).unwrap();
    assert_eq!((g.cycles, g.window_words), (key_glue, 2));
    // Each further axis costs at least another limiter; each further sensor a copy.
    assert!(
        static_glue > key_glue + 2 * 20,
        "{static_glue} vs {key_glue}"
    );
}

#[test]
fn pens_that_overflow_or_overlap_the_windows_are_errors_naming_the_program() {
    let pen = Program::compile(TINY_PEN, &Config::default()).unwrap();
    let programs = vec![pen, instrument("hammond", &[])];
    let lim = LimiterConfig::default();
    let k = |slot, program, core| KeySpec {
        slot,
        program,
        core,
    };
    let err = |keys: &[KeySpec]| {
        FirmwareImage::build(&programs, keys, &rp2040(), &lim)
            .unwrap_err()
            .to_string()
    };
    // Slots 126, 127 and 128: one past the windows.
    let e = err(&[k(126, 0, 0)]);
    assert!(e.contains("tiny_pen") && e.contains("126..129"), "{e}");
    // The last word is fine: a keyboard key there, the pen just before it.
    assert!(
        FirmwareImage::build(&programs, &[k(124, 0, 0), k(127, 1, 1)], &rp2040(), &lim).is_ok()
    );
    // The key at 12 takes the pen's y words.
    let e = err(&[k(10, 0, 0), k(12, 1, 1)]);
    assert!(e.contains("slot 12 is also key 0"), "{e}");
    // The wrong number of sensor words.
    let image = FirmwareImage::build(&programs, &[k(0, 0, 0)], &rp2040(), &lim).unwrap();
    let e = image.run().unwrap().step(&[0]).unwrap_err().to_string();
    assert!(e.contains("1 sensor words") && e.contains("reads 3"), "{e}");
}

/// A program whose code is larger than a core's 63 KB of bank: 150 inlined `exp`s (about
/// 80 KB of Thumb code).
const TOO_LARGE: &str = "
instrument too_large {
    sensor x: m in [0 mm, 10 mm]
    for i in 0..150 {
        state s[i] = 0 in [-1, 1]
        while true { s[i] = exp(-x / 10 mm - i / 1000) - 0.5 }
    }
    force f = x * 1 N/m
}
";

#[test]
fn a_program_too_large_for_a_bank_is_a_no_room_error() {
    let big = Program::compile(TOO_LARGE, &Config::default()).unwrap();
    let text = big.thumb.code.text.len();
    println!("too_large: {text} bytes of Thumb code");
    assert!(text > 0xfc00, "{text} bytes: not larger than a bank");
    let keys = [KeySpec {
        slot: 0,
        program: 0,
        core: 0,
    }];
    let e = FirmwareImage::build(&[big], &keys, &rp2040(), &LimiterConfig::default())
        .expect_err("a program larger than the bank was placed");
    assert!(e.to_string().contains("core 0: code and data need"), "{e}");
}

/// The plucked string fits one core at the board's 44.1 kHz (its static WCET with the pen's
/// glue is under the deadline): a second of pen gestures with plucks runs bit-exact on every
/// DAC word, without a missed deadline, within the static bound.
#[test]
fn the_plucked_string_runs_as_a_pen_at_44_1_khz_bit_exact_without_misses() {
    // The gesture glitches out of range by design: the sensor check off (as for the pens).
    let mut pen = instrument("plucked_string", &[]);
    pen.sensor_check = false;
    assert_eq!(pen.sensor_words(), 3);
    assert_eq!(pen.drives().unwrap().len(), 3);
    let (programs, image) = one_pen(pen);
    let samples = 44_100;
    let mut rng = XorShift64::new(13);
    let sensors = vec![pen_gesture(&programs[0], 44_100.0, samples, &mut rng, true)];
    // The gesture plucks: the reference emits `pluck` events.
    let mut reference = FixedInstance::new(&programs[0].fixed);
    let plucks: usize = sensors[0]
        .iter()
        .map(|w| reference.step_raw(w).events.len())
        .sum();
    println!("plucked_string: {plucks} plucks in the second");
    assert!(plucks >= 2, "{plucks} plucks");
    let st = check_pen_run(&image, &sensors, samples, "plucked_string at 44.1 kHz");
    // The plane (z) and the string (x: its lateral stiffness and the windings) push; y not.
    assert_z_and_x_move_y_still(&st, "plucked_string");
}

/// `pen` alone on core 0 of the stock board: its programs and image.
fn one_pen(pen: Program) -> (Vec<Program>, FirmwareImage) {
    let keys = [KeySpec {
        slot: 0,
        program: 0,
        core: 0,
    }];
    let programs = vec![pen];
    let image =
        FirmwareImage::build(&programs, &keys, &rp2040(), &LimiterConfig::default()).unwrap();
    (programs, image)
}

/// A pen as shipped (the sensor check on) playing a gesture without glitches: bit-exact
/// with the fixed interpreter from the first sample, so no trip (a trip's force is 0), and
/// it plucks; the same gesture with its glitches trips the check.
#[test]
fn a_checked_pen_plays_bit_exact_without_a_trip() {
    let pen = instrument("plucked_string", &[]);
    assert!(pen.sensor_check, "the check is on by default");
    let (programs, image) = one_pen(pen);
    let samples = 22_050;
    let sensors = vec![pen_gesture(
        &programs[0],
        44_100.0,
        samples,
        &mut XorShift64::new(13),
        false,
    )];
    let mut reference = FixedInstance::new(&programs[0].fixed);
    let plucks: usize = sensors[0]
        .iter()
        .map(|w| reference.step_raw(w).events.len())
        .sum();
    assert!(plucks >= 1, "{plucks} plucks");
    let st = check_pen_run(&image, &sensors, samples, "checked plucked_string");
    assert_z_and_x_move_y_still(&st, "checked plucked_string");
    // With its glitches the same pen trips: its forces leave the reference's.
    let glitchy = vec![pen_gesture(
        &programs[0],
        44_100.0,
        samples,
        &mut XorShift64::new(13),
        true,
    )];
    let (bad, ..) = run_words_against_reference(&image, &glitchy, samples);
    assert!(bad > 0, "the glitches tripped nothing");
}

/// The quiescent-key guard (`glue::GuardCode`, docs/language.md "Quiescent keys"): on every
/// shipped keyboard instrument, a key at rest, pressed, released and at rest again, next to
/// a key that never moves, gives the same out words, forces, currents, DAC codes and events
/// sample for sample with the guard as without it (so, by the image's other tests, the
/// fixed interpreter's bits); at rest the guarded handler skips the updates (its cycles
/// fall to a small fraction of the unguarded ones), and no handler ever exceeds the static
/// bound, which counts the full update plus the guard.
#[test]
fn quiescent_guard_skips_idle_keys_bit_exact_with_every_update_run() {
    for name in ["grand_piano", "harpsichord", "harpsichord_2x8", "hammond"] {
        let mut plain = instrument(name, &[]);
        plain.quiescent_guard = false;
        let guarded = instrument(name, &[]);
        let keys: Vec<KeySpec> = (0..2)
            .map(|i| KeySpec {
                slot: 40 + i,
                program: 0,
                core: i,
            })
            .collect();
        let build = |p: Program| {
            FirmwareImage::build(&[p], &keys, &rp2040(), &LimiterConfig::default()).unwrap()
        };
        let (img_g, img_p) = (build(guarded), build(plain));
        let p = &img_g.programs()[0];
        let rest = FixedInstance::sensor_raw(&p.fixed, 0, Some(0.0));
        let press = stimuli(p, 1, 6000);
        let words: Vec<i32> = std::iter::repeat_n(rest, 1500)
            .chain(press)
            .chain(std::iter::repeat_n(rest, 20_000))
            .collect();
        let (mut rg, mut rp) = (img_g.run().unwrap(), img_p.run().unwrap());
        let (mut tail_g, mut tail_p) = (0u64, 0u64);
        let tail_from = words.len() - 4000;
        for (n, &w) in words.iter().enumerate() {
            let g = rg.step(&[w, rest]).unwrap().clone();
            let u = rp.step(&[w, rest]).unwrap().clone();
            assert_eq!(
                (&g.force, &g.current_ua, &g.dac, &g.events),
                (&u.force, &u.current_ua, &u.dac, &u.events),
                "{name}: sample {n}"
            );
            for k in 0..2 {
                assert_eq!(
                    rg.out(k),
                    rp.out(k),
                    "{name}: key {k}'s out words, sample {n}"
                );
            }
            assert_eq!(
                (g.misses.clone(), u.misses.clone()),
                (vec![0, 0], vec![0, 0])
            );
            for c in 0..2 {
                assert!(g.core_cycles[c] <= img_g.wcet(c).unwrap().bound(), "{name}");
                assert!(u.core_cycles[c] <= img_p.wcet(c).unwrap().bound(), "{name}");
            }
            if n >= tail_from {
                tail_g += g.core_cycles[0] + g.core_cycles[1];
                tail_p += u.core_cycles[0] + u.core_cycles[1];
            }
        }
        let (bg, bp) = (img_g.wcet(0).unwrap(), img_p.wcet(0).unwrap());
        println!(
            "{name}: static handler with the guard {} cycles, without {} (the guard: +{}); \
             at rest {:.0} cycles per sample and core with it, {:.0} without",
            bg.bound(),
            bp.bound(),
            bg.bound() - bp.bound(),
            tail_g as f64 / 8000.0,
            tail_p as f64 / 8000.0
        );
        assert!(
            bg.bound() > bp.bound(),
            "{name}: the bound counts the guard"
        );
        assert!(
            tail_g * 2 < tail_p,
            "{name}: at rest the guard skips the updates ({tail_g} vs {tail_p} cycles)"
        );
    }
}

/// The emulator's block engine against its interpreter on an image of every shipped
/// instrument (one key or pen per core, both cores running, 8 kHz so that every program's
/// update fits a sample, or the rate its `require`s need): every sample's outputs, the cores' final state and all of SRAM
/// are identical, with the cores running ahead of each other on their own banks
/// (`tactus_emulator::board`, "Running ahead"). An instrument without an image (its code
/// does not fit: `bowed_string`) is reported and left out.
#[test]
fn the_block_engine_runs_every_instruments_image_exactly_as_the_interpreter() {
    let mut checked = 0;
    let mut kept_total = 0;
    for entry in std::fs::read_dir(root().join("instruments")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "tactus") {
            continue;
        }
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(&path).unwrap();
        // 8 kHz, or 44.1 kHz for a program whose `require`s need it (`plucked_string`).
        let compiled = [8000.0, 44_100.0].map(|fs| {
            let config = Config {
                sample_rate_hz: fs,
                ..Config::default()
            };
            Program::compile(&text, &config).map(|p| (fs, p))
        });
        let [first, second] = compiled;
        let (fs, program) = match first.or(second) {
            Ok(x) => x,
            Err(e) => {
                // `bowed_string`: its code is larger than the SRAM firmware runs from.
                eprintln!("{name}: left out, no image ({e})");
                continue;
            }
        };
        let board = BoardSpec {
            sample_rate_hz: fs,
            ..rp2040()
        };
        let keys: Vec<KeySpec> = (0..2)
            .map(|core| KeySpec {
                slot: 8 * core,
                program: 0,
                core,
            })
            .collect();
        let programs = vec![program];
        let image = match FirmwareImage::build(&programs, &keys, &board, &LimiterConfig::default())
        {
            Ok(image) => image,
            Err(e @ tactus_firmware::image::ImageError::NoRoom { .. }) => {
                eprintln!("{name}: left out ({e})");
                continue;
            }
            Err(e) => panic!("{name}: {e}"),
        };
        let words = stimuli(&programs[0], 0, 300);
        let mut runs = [image.run().unwrap(), image.run().unwrap()];
        runs[0].board().config.engine = Engine::Interp;
        runs[1].board().config.engine = Engine::Block;
        for (n, w) in words.iter().enumerate() {
            let sensors = vec![*w; image.sensor_words()];
            let a = runs[0].step(&sensors).unwrap().clone();
            let b = runs[1].step(&sensors).unwrap().clone();
            assert_eq!(a, b, "{name}: sample {n}");
        }
        let [a, b] = &mut runs;
        for c in 0..2 {
            let (x, y) = (a.board().cores[c].clone(), b.board().cores[c].clone());
            assert_eq!(
                (x.cycle, x.instructions, x.r),
                (y.cycle, y.instructions, y.r),
                "{name}: core {c}"
            );
        }
        let mut sram = [vec![0u8; 0x4_2000], vec![0u8; 0x4_2000]];
        a.board().read_bytes(0x2000_0000, &mut sram[0]).unwrap();
        b.board().read_bytes(0x2000_0000, &mut sram[1]).unwrap();
        assert!(sram[0] == sram[1], "{name}: SRAM differs");
        let (kept, undone) = b.board().run_ahead_windows();
        eprintln!("{name}: exact; windows {kept} kept, {undone} undone");
        kept_total += kept;
        checked += 1;
    }
    assert!(checked >= 6, "only {checked} instruments checked");
    assert!(kept_total > 0, "the cores never ran ahead");
}

/// The static glue of one keyboard key alone on its core (`FirmwareImage::key_glue`: sensor
/// copy, call set-up, the guard, the limiter and the DAC store), with and without the
/// quiescent-key guard, for each shipped keyboard instrument; the guard's share grows with
/// the state words it compares. Prints the figures of docs/benchmarks-log.md "Session 13 (glue16)".
#[test]
fn key_glue_with_and_without_the_guard_per_instrument() {
    let lim = LimiterConfig::default();
    for name in ["grand_piano", "harpsichord", "harpsichord_2x8", "hammond"] {
        let guarded = instrument(name, &[]);
        let mut plain = guarded.clone();
        plain.quiescent_guard = false;
        let g = FirmwareImage::key_glue(&guarded, &rp2040(), &lim).unwrap();
        let p = FirmwareImage::key_glue(&plain, &rp2040(), &lim).unwrap();
        let words = guarded.guard_words().unwrap();
        let update = guarded.static_cost().unwrap().cycles;
        println!(
            "{name}: glue {} cycles with the guard ({words} state words compared), {} without; \
             update {update} (the call included, clobbers {:#06x}): {} per key without the guard",
            g.cycles,
            p.cycles,
            guarded.thumb.clobbers,
            update + p.cycles
        );
        assert_eq!(plain.guard_words(), None);
        assert!(g.cycles > p.cycles, "{name}: the bound counts the guard");
        assert_eq!(g.window_words, p.window_words);
    }
}

/// The guard's bookkeeping after an update on random word sets (runs and gaps, single words
/// and pairs), states and shadows differing in none, one or several words, at every chunk:
/// afterwards the shadow equals the compared state words, the counter is one more when
/// nothing differed and 0 otherwise, and nothing else in memory changed.
#[test]
fn the_guards_shadow_always_ends_equal_to_the_state() {
    let base = 0x2000_1000;
    let (record, shadow_end) = (0x2000_8000u32, 0x2000_9000u32);
    let mut rng = XorShift64::new(0x6a09_e667);
    let mut b = Board::new(BoardConfig::default());
    let mut differing_cases = 0;
    for case in 0..1500 {
        // Up to 40 word offsets in 0..400 bytes, clustered into runs.
        let n = rng.below(14);
        let mut words: Vec<u32> = Vec::new();
        let mut at = 4 * rng.below(4) as u32;
        for _ in 0..n {
            words.push(at);
            at += if rng.below(3) == 0 {
                4 * (1 + rng.below(40) as u32)
            } else {
                4
            };
        }
        let (code, entry) = guard_record_routine(&words, base).unwrap();
        b.write_bytes(base, &code).unwrap();
        let state = shadow_end;
        let shadow = state - 4 * words.len() as u32;
        let span = at as usize + 64;
        // The memory around: random words from below the shadow to past the state.
        let below = 16usize;
        let mut mem: Vec<u32> = (0..(below + words.len() + span / 4))
            .map(|_| rng.next_u64() as u32)
            .collect();
        let mem_base = shadow - 4 * below as u32;
        let idx = |addr: u32| ((addr - mem_base) / 4) as usize;
        for (j, &o) in words.iter().enumerate() {
            mem[idx(shadow) + j] = mem[idx(state + o)];
        }
        let mut differ = 0;
        if !words.is_empty() && rng.below(3) > 0 {
            for _ in 0..1 + rng.below(3) {
                let j = rng.below(words.len());
                mem[idx(shadow) + j] ^= 1 << rng.below(32);
                differ += 1;
            }
        }
        for (k, w) in mem.iter().enumerate() {
            b.write_u32(mem_base + 4 * k as u32, *w).unwrap();
        }
        let calm = rng.below(1000) as u32;
        b.write_u32(record, state).unwrap();
        b.write_u32(record + 4, calm).unwrap();
        b.call(0, entry, &[record], 0x2002_0000, 10_000).unwrap();
        let mut want = mem.clone();
        for (j, &o) in words.iter().enumerate() {
            want[idx(shadow) + j] = mem[idx(state + o)];
        }
        let same = (0..words.len()).all(|j| mem[idx(shadow) + j] == want[idx(shadow) + j]);
        differing_cases += !same as usize;
        let got: Vec<u32> = (0..mem.len())
            .map(|k| b.read_u32(mem_base + 4 * k as u32).unwrap())
            .collect();
        assert!(
            got == want,
            "case {case}: words {words:?}, {differ} changed"
        );
        let expect = if same || words.is_empty() {
            calm + 1
        } else {
            0
        };
        assert_eq!(
            (b.read_u32(record).unwrap(), b.read_u32(record + 4).unwrap()),
            (state, expect),
            "case {case}: words {words:?}"
        );
    }
    assert!(differing_cases > 500, "{differing_cases}");
}
