//! `tactus corpus trips`: the budget corpus (`tactus_firmware::corpus`, the key motions
//! `tactus budget` measures) through the firmware of every board of a keyboard, and the
//! trips of its fault checks per run ([`budget_corpus_trips`], [`corpus_trips_text`]).
//!
//! **Why runs from a fresh boot, every key at once.** The budget measures one key's update
//! over each run from the initial state; here the whole board runs it (every key of the
//! board its own program's run of the label), so the check sees what the hardware would:
//! the glue, both cores, the words the handler copies. A fresh boot per run keeps each run
//! from its initial state, as the budget's are, and keeps a run ending mid-travel from
//! looking like a jump to the next. The runs split in two: the physical ones (key motions,
//! sensor noise) must trip nothing, a trip being a false alarm; the ones faulty by design
//! (glitches to corner words, adversarial random words: [`by_design`]) show the checks at
//! work.

use crate::fault::{report_lines, run_records, BoardFaults};
use std::collections::BTreeMap;

/// One run of the budget corpus (`tactus_firmware::corpus`) through one board of a
/// keyboard: every key of the board following the run (each key its own program's run of
/// that label), from a fresh boot; the board's fault records after it.
#[derive(Clone, Debug)]
pub struct CorpusTrips {
    /// The run's label (`press-40ms`, `glitch-every-50`, `random0`, …).
    pub label: String,
    /// Whether the run is a fault by design (glitches to corner words, adversarial random
    /// words: [`by_design`]), whose trips are the checks doing their work, not false
    /// alarms.
    pub by_design: bool,
    /// Samples run.
    pub samples: usize,
    /// The board's fault records after the run.
    pub faults: BoardFaults,
}

pub use tactus_firmware::corpus::by_design;

/// The budget corpus (`tactus_firmware::corpus::Size::Quick` when `quick`, else `Full`)
/// through every board of `kb`'s plan (the firmware of
/// [`crate::keyboard::Keyboard::firmware`], with its `sensor_check`): per board and per
/// run, the fault records after the run ([`CorpusTrips`]); `progress(done, total)` in
/// board-runs. A keyboard whose keys' programs give runs of different labels runs the
/// labels of its first key's program (each key its own run of the label, or rest).
///
/// Errors, as messages: the firmware does not compile, the plan or a board's image cannot
/// be made, a board's run stops.
pub fn budget_corpus_trips(
    kb: &crate::keyboard::Keyboard,
    quick: bool,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<CorpusTrips>, String> {
    let size = match quick {
        true => tactus_firmware::corpus::Size::Quick,
        false => tactus_firmware::corpus::Size::Full,
    };
    use tactus_firmware::boards::{self, PlanKey, ProgramCosts};
    let programs = kb.firmware().map_err(|e| e.to_string())?;
    let plan = kb
        .plan(&programs, &mut |_, _| {})
        .map_err(|e| e.to_string())?;
    let lim = kb.limiter();
    let costs = ProgramCosts::new(&programs, &kb.board, &lim).map_err(|e| e.to_string())?;
    let key_programs = kb.key_programs();
    let corpus_of = |program: usize| {
        (programs.get(program)).map_or_else(Vec::new, |p| {
            tactus_firmware::corpus::corpus(&p.fixed, size)
        })
    };
    let lists = plan.key_lists();
    // The first key's program's runs give the labels, and serve its board (made once).
    let mut first = (key_programs.first()).map(|k| (k.1, corpus_of(k.1)));
    let labels: Vec<String> = (first.as_ref())
        .map(|(_, runs)| runs.iter().map(|r| r.label.clone()).collect())
        .unwrap_or_default();
    let total = lists.len() * labels.len();
    let mut out = Vec::with_capacity(total);
    for (b, list) in lists.iter().enumerate() {
        let bkeys: Vec<PlanKey> = (key_programs.iter())
            .filter(|k| list.contains(&k.0))
            .map(|&(key, program)| PlanKey { key, program })
            .collect();
        let (_, image) = boards::board_image(&programs, &costs, &bkeys, &kb.board, &lim)
            .map_err(|e| format!("board {}: {e}", b + 1))?;
        let image = image.map_err(|e| format!("board {}: {e}", b + 1))?;
        let midi: Vec<u8> = bkeys.iter().map(|k| k.key).collect();
        // The runs of this board's programs alone, made here and dropped with the board: a
        // graded keyboard has a program per key (grand88: 88), and every program's full
        // corpus held at once took 6.3 GB.
        let mut runs: BTreeMap<usize, Vec<tactus_firmware::measure::Run>> = BTreeMap::new();
        for k in &bkeys {
            runs.entry(k.program).or_insert_with(|| {
                match first.take_if(|(program, _)| *program == k.program) {
                    Some((_, made)) => made,
                    None => corpus_of(k.program),
                }
            });
        }
        let slots = crate::fault::image_slots(&image, &midi);
        let rest: Vec<Vec<i32>> = (bkeys.iter())
            .map(|k| {
                let p = &programs[k.program];
                let lo = |i: usize| p.fixed.sensor_raw_range.get(i).map_or(0, |r| r.0);
                (0..p.sensor_words()).map(lo).collect()
            })
            .collect();
        for label in &labels {
            progress(out.len(), total);
            // Each key's run of this label (a key whose program has none stays at rest).
            let key_runs: Vec<Option<&tactus_firmware::measure::Run>> = (bkeys.iter())
                .map(|k| runs.get(&k.program)?.iter().find(|r| &r.label == label))
                .collect();
            let samples = key_runs.iter().flatten().map(|r| r.records.len()).max();
            let words_at = |n: usize, words: &mut Vec<i32>| {
                words.clear();
                for (r, rest) in key_runs.iter().zip(&rest) {
                    let rec = r.and_then(|r| r.records.get(n)).unwrap_or(rest);
                    words.extend((0..rest.len()).map(|i| rec.get(i).copied().unwrap_or(rest[i])));
                }
            };
            // From power-on the keys where their runs start (a key held at power-on: a
            // converter board's first handler reads the start alarm's burst,
            // `FirmwareImage::run_from`).
            let mut words = Vec::new();
            words_at(0, &mut words);
            let mut run = (image.run_from(&words)).map_err(|e| format!("board {}: {e}", b + 1))?;
            for n in 0..samples.unwrap_or(0) {
                words_at(n, &mut words);
                run.step(&words)
                    .map_err(|e| format!("board {}, run {label}, sample {n}: {e}", b + 1))?;
            }
            run.settle().map_err(|e| format!("board {}: {e}", b + 1))?;
            let cores = run_records(&mut run)?;
            out.push(CorpusTrips {
                label: label.clone(),
                by_design: by_design(label),
                samples: samples.unwrap_or(0),
                faults: BoardFaults {
                    board: b + 1,
                    cores,
                    slots: slots.clone(),
                    resets: run.resets().to_vec(),
                },
            });
        }
    }
    progress(total, total);
    Ok(out)
}

/// The budget corpus's trips as text: a line per run label (its trips over every board,
/// and the first trip's board, core, kind and key), then the totals of the physical runs
/// (0 expected: a trip is a false alarm) and of the runs faulty by design, each with its
/// resets (the watchdog's, a brown-out: [`BoardFaults::resets`]). Returns the lines and
/// the physical runs' trips and resets summed (a reset in a physical run is a false alarm
/// as a trip is).
pub fn corpus_trips_text(runs: &[CorpusTrips], fs: f64) -> (Vec<String>, u64) {
    let mut labels: Vec<&str> = Vec::new();
    for r in runs {
        if !labels.contains(&r.label.as_str()) {
            labels.push(&r.label);
        }
    }
    let boards = runs.iter().map(|r| r.faults.board).max().unwrap_or(0);
    let mut lines = Vec::new();
    let (mut physical, mut designed) = (0u64, 0u64);
    let (mut physical_resets, mut designed_resets) = (0u64, 0u64);
    for label in labels {
        let of: Vec<&CorpusTrips> = runs.iter().filter(|r| r.label == label).collect();
        let trips: u64 = of.iter().map(|r| r.faults.trips()).sum();
        let resets: u64 = of.iter().map(|r| r.faults.resets.len() as u64).sum();
        let design = of.first().is_some_and(|r| r.by_design);
        let (t, r) = match design {
            true => (&mut designed, &mut designed_resets),
            false => (&mut physical, &mut physical_resets),
        };
        *t += trips;
        *r += resets;
        let first = (of.iter())
            .find(|r| r.faults.trips() > 0)
            .and_then(|r| {
                report_lines(std::slice::from_ref(&r.faults), fs)
                    .into_iter()
                    .next()
            })
            .map_or(String::new(), |l| format!(" (first: {l})"));
        lines.push(format!(
            "  {label:<24} {:>7} samples  {trips:>6} trips{}{}{first}",
            of.first().map_or(0, |r| r.samples),
            match resets {
                0 => String::new(),
                n => format!(" {n} reset{}", if n == 1 { "" } else { "s" }),
            },
            if design { " (a fault by design)" } else { "" },
        ));
    }
    lines.push(format!(
        "budget corpus through {boards} board{}: {physical} trips and {physical_resets} resets in the physical runs (0 expected), {designed} trips and {designed_resets} resets in the runs faulty by design (glitches, random words)",
        if boards == 1 { "" } else { "s" }
    ));
    (lines, physical + physical_resets)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(label: &str, resets: usize) -> CorpusTrips {
        let reset = tactus_firmware::image::ResetRecord {
            sample: 10,
            cycle: 1000,
            why: "watchdog timer",
            reboot: Ok(3),
        };
        CorpusTrips {
            label: label.into(),
            by_design: by_design(label),
            samples: 100,
            faults: BoardFaults {
                board: 1,
                cores: Vec::new(),
                slots: Vec::new(),
                resets: vec![reset; resets],
            },
        }
    }

    #[test]
    fn resets_count_as_false_alarms_in_physical_runs() {
        let (lines, physical) = corpus_trips_text(&[run("ff-dip", 0), run("random0", 2)], 44100.0);
        assert_eq!(physical, 0, "{lines:?}");
        assert!(
            lines[1].contains(" 2 resets (a fault by design)"),
            "{lines:?}"
        );
        assert!(
            lines[2].contains("0 trips and 0 resets in the physical runs"),
            "{lines:?}"
        );
        assert!(
            lines[2].contains("0 trips and 2 resets in the runs faulty"),
            "{lines:?}"
        );
        let (lines, physical) = corpus_trips_text(&[run("ff-dip", 1)], 44100.0);
        assert_eq!(physical, 1, "{lines:?}");
        assert!(lines[0].ends_with(" 0 trips 1 reset"), "{lines:?}");
    }
}
