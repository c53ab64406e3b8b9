//! `--fault` end to end through the CLI (issue 72): a sensor fault injected by `tactus play`
//! on a plain board and on a converter board, and by `tactus emu run` on one board's
//! firmware from `tactus build`, with the firmware's sensor check on as shipped (no flag):
//! the fault report
//! names the check, the key and the sample, and the key's motor is at zero force within
//! 1 ms; `emu run` and `play` run a fault through the one path (`ImageRun::inject`) and
//! report the same trips on both boards; a hung update with `--watchdog on` resets the
//! board, and `emu run` says so with the fault word it leaves, each reset at the run's
//! sample it came in (within docs/firmware.md's bound after the hang) and the hung handler counted
//! unfinished, never measured; a stalled DAC and a flipped bit, which no check sees, keep
//! the motor's current within the limiter's peak (the board's limiter); a `--fault` that
//! cannot be run names its field.

mod common;

use common::{assert_ok, small_layout, tactus, temp_dir, write_midi};
use std::path::{Path, PathBuf};

/// The fault's onset, s: key 60 is held at the bottom of its travel then.
const AT_S: f64 = 0.2;

/// Rows (time, force word N, motor current A) of a play trace CSV (`--trace-keys`).
fn trace(path: &Path) -> Vec<(f64, f64, f64)> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap();
    let (t, f, i) = (col("time_s"), col("force_n"), col("motor_current_a"));
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (v[t], v[f], v[i])
        })
        .collect()
}

/// `tactus build LAYOUT --target rp2040 --board BOARD -o OUT`, which must succeed.
fn build_for(layout: &Path, board: &str, out: &Path) {
    let built = tactus()
        .args(["build", layout.to_str().unwrap(), "--target", "rp2040"])
        .args(["--board", board, "-o"])
        .arg(out)
        .output()
        .unwrap();
    assert_ok(&built);
}

#[test]
fn a_shorted_sensor_under_play_trips_its_check_and_its_motor_is_at_zero_within_1_ms() {
    let dir = temp_dir("cli-faults-play");
    let layout = small_layout(&dir, 60, 63);
    let midi = dir.join("held.mid");
    write_midi(&midi, &[(60, 90, 0.05, 0.35), (62, 60, 0.1, 0.3)], &[]);
    // Held key 60 on the layout, 0.3 s, the sensor check on.
    let play = || {
        let mut c = tactus();
        c.args(["play", midi.to_str().unwrap(), "--layout"])
            .arg(&layout)
            .args(["--seconds", "0.3", "--no-wav"]);
        c
    };
    for board in ["rp2040", "rp2040_io"] {
        let out_dir = dir.join(board);
        let out = play()
            .args(["--board", board])
            .args(["--fault", "kind=short,note=60,at=0.2s"])
            .args([
                "--trace-keys",
                "60",
                "--trace-from",
                "0.19",
                "--trace-to",
                "0.21",
            ])
            .arg("-o")
            .arg(&out_dir)
            .output()
            .unwrap();
        assert_ok(&out);
        let stdout = String::from_utf8_lossy(&out.stdout);
        // Tripped within 1 ms (44 samples) of the onset: on the converter board the ADC's
        // frame of a sample is read in the sample before.
        let sample: u64 = stdout
            .lines()
            .find_map(|l| l.split_once(": sensor-range on key 60 (C4) at sample "))
            .and_then(|(_, rest)| rest.split(' ').next()?.parse().ok())
            .unwrap_or_else(|| panic!("{board}: {stdout}"));
        assert!((8820..=8820 + 44).contains(&sample), "{board}: {stdout}");
        assert!(
            stdout.contains("faults: 1 TRIP on 1 of 1 boards"),
            "{board}: {stdout}"
        );
        let csv = std::fs::read_to_string(out_dir.join("held-faults.csv")).unwrap();
        assert!(
            csv.contains(&format!(",sensor-range,1,0,60,1,{sample},")),
            "{board}: {csv}"
        );
        let rows = trace(&out_dir.join("held-key60.csv"));
        // Held down before the fault: its force is not 0 (the check has something to stop).
        let before: Vec<_> = rows.iter().filter(|r| r.0 < AT_S - 1e-9).collect();
        assert!(
            before.iter().all(|r| r.1.abs() > 0.05),
            "{board}: {before:?}"
        );
        let after: Vec<_> = rows.iter().filter(|r| r.0 >= AT_S + 1e-3).collect();
        assert!(after.len() > 300, "{board}: {} rows", after.len());
        for r in after {
            assert!(
                r.1 == 0.0 && r.2.abs() < 1e-4,
                "{board}: at {} s: {r:?}",
                r.0
            );
        }
    }
    // The same run without the fault: no trip, said.
    let out = play().arg("-o").arg(dir.join("clean")).output().unwrap();
    assert_ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("faults: 0 trips on 1 board\n"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn emu_run_injects_a_sensor_fault_into_built_firmware_and_reports_its_fault_word() {
    let dir = temp_dir("cli-faults-emu");
    let layout = small_layout(&dir, 60, 63);
    let fw = dir.join("fw");
    let out = tactus()
        .args(["build", layout.to_str().unwrap(), "--target", "rp2040"])
        .arg("-o")
        .arg(&fw)
        .output()
        .unwrap();
    assert_ok(&out);
    let elf = fw.join("board-01/firmware.elf");
    let run = |fault: &[&str]| {
        tactus()
            .args(["emu", "run", elf.to_str().unwrap(), "--stimulus", "mf-dip"])
            .args(["--seconds", "0.101"])
            .args(fault)
            .output()
            .unwrap()
    };
    // A shorted wire on key 61 from 0.1 s: the run ends 1 ms after it.
    let out = run(&["--fault", "kind=short,note=61,at=0.1s"]);
    assert_ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains(": sensor-range on key 61 (C#4) at sample 4410 (0.1000 s), 1 trip"),
        "{stdout}"
    );
    assert!(
        stdout.contains("faults: 1 TRIP on 1 of 1 boards"),
        "{stdout}"
    );
    // The DAC codes at the end, in keys.json's order (60, 61, 62, 63): key 61's is 0, the
    // others' are not (the mf dip holds them down).
    let dac = stdout
        .lines()
        .find_map(|l| l.strip_prefix("DAC codes at the end: ["))
        .and_then(|l| l.split(']').next())
        .unwrap();
    let codes: Vec<i16> = dac.split(", ").map(|w| w.parse().unwrap()).collect();
    assert_eq!(codes.len(), 4, "{dac}");
    assert_eq!(codes[1], 0, "{dac}");
    assert!(
        codes.iter().enumerate().all(|(k, &w)| k == 1 || w != 0),
        "{dac}"
    );
    // Without a fault: no trip, said.
    let out = run(&[]);
    assert_ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("faults: 0 trips on 1 board\n"));
    // What cannot be run names its field.
    for (fault, field) in [
        (
            "kind=short,note=70,at=0.05s",
            "field `note`: board 1 does not play MIDI key 70",
        ),
        ("kind=stuck,note=61,at=0.05s", "field `code`"),
        (
            "kind=short,board=2,key=0,at=0.05s",
            "field `board`: board 2: this firmware is board 1",
        ),
        (
            "kind=flip,word=100000,bit=3,note=61,at=0.05s",
            "`word`: word 100000 of a state struct of",
        ),
    ] {
        let out = run(&["--fault", fault]);
        assert!(!out.status.success(), "{fault}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(field), "{fault}: {stderr}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The lines of a fault report that name a trip (`board 1 core 0: sensor-rate on key 62 …`),
/// unindented.
fn trip_lines(stdout: &str) -> Vec<String> {
    (stdout.lines())
        .map(str::trim)
        .filter(|l| l.starts_with("board ") && l.contains(" core ") && l.contains(" trip"))
        .map(str::to_string)
        .collect()
}

#[test]
fn emu_run_and_play_report_the_same_trips_for_the_same_faults_on_both_boards() {
    let dir = temp_dir("cli-faults-same");
    let layout = small_layout(&dir, 60, 63);
    // Keys 61 and 62 at rest in both runs: a CSV stimulus of the key at the top, and a
    // performance that plays key 63 only, after the faults began.
    let rest = dir.join("rest.csv");
    std::fs::write(&rest, "key_mm\n0\n").unwrap();
    let midi = dir.join("late.mid");
    write_midi(&midi, &[(63, 80, 0.1, 0.15)], &[]);
    let faults = [
        "--fault",
        "kind=noise,amplitude=5000,note=62,at=0.05s",
        "--fault",
        "kind=adc-silent,board=1,core=1,at=0.1s",
    ];
    for board in ["rp2040", "rp2040_io"] {
        let fw = dir.join(format!("fw-{board}"));
        build_for(&layout, board, &fw);
        let out = tactus()
            .args(["emu", "run"])
            .arg(fw.join("board-01/firmware.elf"))
            .args(["--stimulus", rest.to_str().unwrap(), "--seconds", "0.12"])
            .args(faults)
            .output()
            .unwrap();
        assert_ok(&out);
        let emu = trip_lines(&String::from_utf8_lossy(&out.stdout));
        let out = tactus()
            .args(["play", midi.to_str().unwrap(), "--layout"])
            .arg(&layout)
            .args(["--board", board, "--seconds", "0.12", "--no-wav"])
            .args(faults)
            .arg("-o")
            .arg(dir.join(board))
            .output()
            .unwrap();
        assert_ok(&out);
        let play = trip_lines(&String::from_utf8_lossy(&out.stdout));
        // The noise's codes are drawn once per run in both (the same codes, the same
        // sample); the silent ADC reads full scale on both keys of core 1.
        assert_eq!(emu.len(), 2, "{board}: {emu:?}");
        assert!(
            emu[0].starts_with("board 1 core 0: sensor-rate on key 62 (D4) at sample ")
                && emu[1].starts_with("board 1 core 1: sensor-range on key 61 (C#4) at sample "),
            "{board}: {emu:?}"
        );
        assert_eq!(emu, play, "{board}: emu run against play");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_hung_update_with_the_watchdog_on_resets_the_board_under_emu_run() {
    let dir = temp_dir("cli-faults-watchdog");
    let layout = small_layout(&dir, 60, 61);
    let fw = dir.join("fw");
    let build = |watchdog: &str| {
        tactus()
            .args(["build", layout.to_str().unwrap(), "--target", "rp2040"])
            .args(["--watchdog", watchdog, "-o"])
            .arg(&fw)
            .output()
            .unwrap()
    };
    let run = || {
        tactus()
            .args(["emu", "run"])
            .arg(fw.join("board-01/firmware.elf"))
            .args(["--stimulus", "mf-dip", "--seconds", "0.06"])
            .args(["--fault", "kind=hang,note=61,at=0.05s,until=0.055s"])
            .output()
            .unwrap()
    };
    assert_ok(&build("on"));
    let out = run();
    assert_ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains(", watchdog on"), "{stdout}");
    // Fed only when both cores finished their sample: the hung core stops the feed, the
    // watchdog resets the board within its period, and the firmware boots again from flash
    // with its fault record kept.
    let reset = (stdout.lines())
        .find_map(|l| l.strip_prefix("reset: watchdog timer reset at t = "))
        .unwrap_or_else(|| panic!("{stdout}"));
    // At the run's sample of the reset: within the stated bound after the hang's (2205).
    let sample = reset_sample(reset);
    assert!(reset_window(2205).contains(&sample), "{stdout}");
    assert!(reset.contains("booted again"), "{stdout}");
    assert!(
        stdout.contains(&format!(
            "board 1 core 0: watchdog on key 61 (C#4) at sample {sample} ("
        )),
        "{stdout}"
    );
    // The hung handler is no handler time: the samples from the hang to the reset are
    // counted unfinished on key 61's core, and every core's worst handler is a handler's,
    // within the period (not a hung sample's, nor a sample's sum of several).
    for core in 0..2 {
        let (worst, unfinished) = emu_core_line(&stdout, core);
        assert!(
            worst < emu_period(&stdout),
            "core {core}: worst {worst}: {stdout}"
        );
        let hung = if core == 0 { sample - 2205 } else { 0 };
        assert_eq!(unfinished, hung, "core {core}: {stdout}");
    }
    // Without the watchdog nothing resets the board: the hung core never completes its
    // sample, an error of the run.
    assert_ok(&build("off"));
    let out = run();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("sample 2206 not completed"), "{stderr}");
    // keys.json records the options it was built with; the rebuild reads them and builds
    // once, so a key map that says otherwise is not its firmware's.
    let keys = fw.join("board-01/keys.json");
    let json = std::fs::read_to_string(&keys).unwrap();
    let map: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(map["watchdog"], serde_json::Value::Bool(false), "{json}");
    assert_eq!(map["sensor_check"], serde_json::Value::Bool(true), "{json}");
    let edit = |f: &dyn Fn(&mut serde_json::Map<String, serde_json::Value>)| {
        let mut m = map.clone();
        f(m.as_object_mut().unwrap());
        std::fs::write(&keys, serde_json::to_string_pretty(&m).unwrap()).unwrap();
        run()
    };
    let out = edit(&|m| {
        m.insert("watchdog".into(), true.into());
    });
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("not the firmware its key maps build")
            && stderr.contains("the sensor check on and the watchdog on as ")
            && stderr.contains("the ELFs differ"),
        "{stderr}"
    );
    // A key map from before the options were recorded: the file, the field, what to do.
    for field in ["sensor_check", "watchdog"] {
        let out = edit(&|m| {
            m.remove(field);
        });
        assert_eq!(out.status.code(), Some(1), "{field}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains(&format!(
                "board-01/keys.json: no `{field}` field: written by an older tactus"
            )) && stderr.contains("build the firmware again with `tactus build"),
            "{field}: {stderr}"
        );
    }
    // --watchdog takes on or off.
    let out = build("maybe");
    assert_eq!(out.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_note_at_0_s_is_struck_on_every_engine_and_trips_no_check() {
    // Its stroke needs longer than the piece gives it before 0 s: the run starts that much
    // earlier (a lead-in), the times reported stay the performance's. Before, the position
    // player pressed the key in 1 ms (10 mm: the sensor check's sensor-rate tripped, no
    // strike under the firmware).
    let dir = temp_dir("cli-faults-lead");
    let layout = small_layout(&dir, 60, 63);
    let midi = dir.join("zero.mid");
    write_midi(&midi, &[(63, 80, 0.0, 0.05)], &[]);
    for (engine, player) in [
        ("emu", "position"),
        ("emu", "force"),
        ("fixed", "position"),
        ("jit", "position"),
        ("interp", "position"),
    ] {
        let out_dir = dir.join(format!("{engine}-{player}"));
        let mut play = tactus();
        play.args(["play", midi.to_str().unwrap(), "--layout"])
            .arg(&layout)
            .args(["--engine", engine, "--player", player])
            .args(["--seconds", "0.3", "--no-wav"])
            .args(["--trace-keys", "63", "--trace-from=-1", "-o"])
            .arg(&out_dir);
        // On the firmware, a fault at 0.1 s of the performance on a resting key: its trip
        // is reported at the performance's sample 4410 (+ at most 1 ms), not the run's.
        let faulted = (engine, player) == ("emu", "position");
        if faulted {
            play.args(["--fault", "kind=short,note=60,at=0.1s"]);
        }
        let out = play.output().unwrap();
        assert_ok(&out);
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stdout.contains("→ 1 strikes (1 answer a note within 50 ms; 0 notes without a strike)"),
            "{engine} {player}: {stdout}"
        );
        assert!(
            !stderr.contains("could not be placed"),
            "{engine} {player}: {stderr}"
        );
        if engine == "emu" && !faulted {
            assert!(
                stdout.contains("faults: 0 trips on 1 board\n"),
                "{engine} {player}: {stdout}"
            );
        }
        if faulted {
            let csv = std::fs::read_to_string(out_dir.join("zero-faults.csv")).unwrap();
            let row = (csv.lines())
                .find(|l| l.contains(",sensor-range,"))
                .unwrap_or_else(|| panic!("{csv}"));
            let cols: Vec<&str> = row.split(',').collect();
            let (sample, at): (u64, f64) = (cols[7].parse().unwrap(), cols[8].parse().unwrap());
            assert!(
                cols[5] == "60" && (4410..=4410 + 44).contains(&sample),
                "{csv}"
            );
            assert!((at - sample as f64 / 44_100.0).abs() < 1e-6, "{csv}");
        }
        let csv = std::fs::read_to_string(out_dir.join("zero-strikes.csv")).unwrap();
        let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
        let t: f64 = row[1].parse().unwrap();
        assert!(row[0] == "63" && t.abs() < 0.05, "{engine} {player}: {csv}");
        // The trace from the run's first sample: the lead-in before 0 s, then a row at the
        // performance's 0 s itself (the lead-in is whole samples), one a sample.
        let (head, rows) = trace_rows(&out_dir.join("zero-key63.csv"));
        assert_eq!(head[0], "time_s");
        let first = rows[0][0];
        assert!(
            (-0.1..-1e-3).contains(&first),
            "{engine} {player}: the trace starts at {first} s"
        );
        let zero = rows.iter().position(|r| r[0].abs() < 1e-9);
        let zero = zero.unwrap_or_else(|| panic!("{engine} {player}: no row at 0 s"));
        assert!(
            (zero as f64 / 44_100.0 + first).abs() < 1e-9,
            "{engine} {player}: row {zero} at 0 s, the first at {first} s"
        );
        // The strike's row: the hammer meets the string within the trace, at the strike.
        assert!(
            rows.iter().any(|r| (r[0] - t).abs() < 1e-9),
            "{engine} {player}: no trace row at the strike's {t} s"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_bad_fault_for_play_names_its_field_before_anything_runs() {
    for (fault, field) in [
        ("kind=open,note=60", "field `at`: missing"),
        (
            "kind=opne,note=60,at=1s",
            "field `kind`: `opne` is not a fault",
        ),
        (
            "kind=open,note=128,at=1s",
            "field `note`: 128 is outside 0–127",
        ),
    ] {
        let out = tactus()
            .args(["play", "--no-wav", "--fault", fault])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{fault}");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains(field), "{fault}: {stderr}");
    }
}

#[test]
fn the_budget_corpus_trips_no_check_but_its_glitches_and_random_words_do() {
    let dir = temp_dir("cli-faults-corpus");
    let layout = small_layout(&dir, 60, 61);
    let out = tactus()
        .args(["corpus", "trips", layout.to_str().unwrap(), "--quick"])
        .args(["--watchdog", "on"])
        .output()
        .unwrap();
    assert_ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("sensor check on, watchdog on"), "{stdout}");
    for physical in ["ff-dip", "press-12ms", "trill-16Hz-80%", "noisy-press-0.5%"] {
        let line = (stdout.lines())
            .find(|l| l.trim_start().starts_with(physical))
            .unwrap_or_else(|| panic!("{physical}: {stdout}"));
        assert!(line.ends_with(" 0 trips"), "{line}");
    }
    let glitch = (stdout.lines())
        .find(|l| l.trim_start().starts_with("glitch-every-50"))
        .unwrap();
    assert!(
        glitch.contains("(a fault by design) (first: board 1 core "),
        "{glitch}"
    );
    assert!(!glitch.contains(" 0 trips"), "{glitch}");
    assert!(
        stdout.contains("budget corpus through 1 board: 0 trips and 0 resets in the physical runs"),
        "{stdout}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn keys_held_from_power_on_trip_no_check_under_emu_run_on_either_board() {
    // `--stimulus hold`: every key at half its dip from power-on. A converter board's
    // first handler reads the start alarm's ADC burst, which must sample the keys where
    // the stimulus starts (not at rest, code 0): else the check takes the next reading for
    // a jump of half the dip (a false alarm on `rp2040_io`, exit 2).
    let dir = temp_dir("cli-faults-held");
    let layout = small_layout(&dir, 60, 63);
    for board in ["rp2040", "rp2040_io"] {
        let fw = dir.join(format!("fw-{board}"));
        build_for(&layout, board, &fw);
        let out = tactus()
            .args(["emu", "run"])
            .arg(fw.join("board-01/firmware.elf"))
            .args(["--stimulus", "hold", "--seconds", "0.01"])
            .output()
            .unwrap();
        assert_ok(&out);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            stdout.contains("faults: 0 trips on 1 board"),
            "{board}: {stdout}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The limiter's peak on board `board` — the one configuration `tactus build` and `tactus
/// play` give its firmware (`LimiterConfig::for_board`) — as a DAC code and as a motor
/// current, A (`Limiter::peak_ua`).
fn limiter_peak(board: &str) -> (i32, f64) {
    use tactus_runtime::limiter::{Limiter, LimiterConfig};
    let spec = tactus_host::catalogue::board(board).unwrap();
    let limiter = Limiter::new(&LimiterConfig::for_board(&spec)).unwrap();
    (limiter.peak_code(), f64::from(limiter.peak_ua()) * 1e-6)
}

/// The run's samples a watchdog reset may come in after a hang that began in sample `hang`
/// (at its start, the injection's `at`), by docs/firmware.md's stated bound ("Faults", the
/// hung core's row): at most the watchdog's period `P` and one sample after the hang began,
/// more than `P` less `G` samples after it, `G` the feeding class's longest gap, 4 samples
/// on the 133 MHz boards these tests run (`rp2040`, `rp2040_io`). At 44.1 kHz (`P` = 44.1
/// samples): `hang + 40 ..= hang + 45`, the sample of a time being its floor.
fn reset_window(hang: u64) -> std::ops::RangeInclusive<u64> {
    /// `G` at 133 MHz (docs/firmware.md: 5 at 200 MHz).
    const FEED_GAP: u64 = 4;
    // The period in millionths of a sample (44.1 samples: 44,100,000).
    let period = u64::from(tactus_firmware::image::fault::WATCHDOG_PERIOD_US) * 44_100;
    let low = (period - FEED_GAP * 1_000_000) / 1_000_000;
    let high = (period + 1_000_000) / 1_000_000;
    hang + low..=hang + high
}

/// The fields of `emu run`'s line for core `core` (`core 1: keys […], N samples, handler
/// cycles mean … worst W (P % of the period), misses M[, U samples unfinished (…)]`): the
/// worst handler's cycles and the samples unfinished (0 when the line names none).
fn emu_core_line(stdout: &str, core: usize) -> (u64, u64) {
    let line = (stdout.lines())
        .find(|l| l.starts_with(&format!("core {core}: keys ")))
        .unwrap_or_else(|| panic!("{stdout}"));
    let worst = (line.split_once(" worst "))
        .and_then(|(_, w)| w.split(' ').next())
        .unwrap_or_else(|| panic!("{line}"))
        .parse()
        .unwrap();
    let unfinished = (line.split_once("misses "))
        .and_then(|(_, m)| m.split_once(", "))
        .map_or(0, |(_, u)| u.split(' ').next().unwrap().parse().unwrap());
    (worst, unfinished)
}

/// The cycles of a sample period `emu run` names in its first line (`…, 3015 cycles per
/// sample, …`).
fn emu_period(stdout: &str) -> u64 {
    (stdout.split_once(" cycles per sample"))
        .and_then(|(a, _)| a.rsplit(' ').next())
        .unwrap_or_else(|| panic!("{stdout}"))
        .parse()
        .unwrap()
}

/// The sample of a reset line (`… reset at t = 0.0500 s (sample 2205, cycle …): …`).
fn reset_sample(line: &str) -> u64 {
    let after = line
        .split_once("(sample ")
        .unwrap_or_else(|| panic!("{line}"))
        .1;
    after.split(',').next().unwrap().parse().unwrap()
}

/// Every row of a play trace CSV (`--trace-keys`) as numbers, by column name.
fn trace_rows(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let head = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    (head, rows)
}

#[test]
fn play_names_a_watchdog_reset_and_a_flip_stays_under_the_peak_on_both_boards() {
    // Key 61 (core 1) and key 63 (core 0) pressed from about 10 ms, held to 0.3 s.
    let rig = FlipRig::new("cli-faults-play-reset", [61, 63]);
    let fs = 44_100.0;
    let play_for = |seconds: &str, board: &str, name: &str, fault: Option<&str>| {
        rig.play_with(seconds, true, board, name, fault)
    };
    let play = |board: &str, name: &str, fault: Option<&str>| play_for("0.3", board, name, fault);
    for board in ["rp2040", "rp2040_io"] {
        let (_, clean61, clean63) = play(board, "clean", None);
        let col = |head: &[String], name: &str| head.iter().position(|h| h == name).unwrap();
        let (force, current) = (
            col(&clean61.0, "force_n"),
            col(&clean61.0, "motor_current_a"),
        );

        // A flipped sign bit in key 61's state (its fourth word) before its press: not
        // detected, its outputs change, never above the limiter's peak (the board's
        // limiter: 2 A), and key 63 on the other core plays exactly as without it.
        let (_, peak_a) = limiter_peak(board);
        let (stdout, flip61, flip63) = play(
            board,
            "flip",
            Some("kind=flip,word=3,bit=31,note=61,at=0.001s"),
        );
        assert!(
            stdout.contains("faults: 0 trips on 1 board\n"),
            "{board}: {stdout}"
        );
        let changed = (flip61.1.iter().zip(&clean61.1))
            .filter(|(a, b)| a[force] != b[force])
            .count();
        assert!(changed > 100, "{board}: the flip changed {changed} samples");
        for r in &flip61.1 {
            assert!(r[current].abs() <= peak_a + 1e-9, "{board}: {r:?}");
        }
        assert_eq!(flip63.1, clean63.1, "{board}: key 63 changed");

        // Core 1's DAC stalls at 0.06 s, key 61 mid-press: nothing detects it (the DAC8568
        // has no read-back), so its motor holds the current of the sample before, never
        // above the limiter's peak; key 63 on core 0 plays exactly as without it.
        let (stdout, stall61, stall63) = play(
            board,
            "stall",
            Some("kind=dac-stall,board=1,core=1,at=0.06s"),
        );
        assert!(
            stdout.contains("faults: 0 trips on 1 board\n"),
            "{board}: {stdout}"
        );
        let at = stall61.1.iter().position(|r| r[0] >= 0.06).unwrap();
        let held = stall61.1[at - 1][current];
        assert!(held != 0.0, "{board}: key 61 pushes at the stall");
        for (r, c) in stall61.1.iter().zip(&clean61.1) {
            assert!(r[current].abs() <= peak_a + 1e-9, "{board}: {r:?}");
            if r[0] < 0.06 {
                assert_eq!(r, c, "{board}: before the stall");
            } else {
                assert_eq!(r[current], held, "{board}: {r:?}");
            }
        }
        assert_eq!(stall63.1, clean63.1, "{board}: key 63 changed");

        // A hang of key 61's update while it moves (its descent): the watchdog resets the
        // board within 1 ms and a sample; the boot ROM enters the RAM image play runs again
        // (its re-entry restores the data), but the hang is in the code, which stays hung:
        // each boot hangs again at key 61's next update and resets again, every reset
        // named and counted, the motors at zero force through each boot.
        // (0.06 s: a boot every 1.1 ms from 0.03 s is some 27 boots, each emulated.)
        let hang = Some("kind=hang,note=61,at=0.03s");
        let (stdout, hung61, _) = play_for("0.06", board, "hang", hang);
        let lines: Vec<&str> = (stdout.lines())
            .filter_map(|l| {
                l.trim()
                    .strip_prefix("board 1: watchdog timer reset at t = ")
            })
            .collect();
        // Each reset at the run's sample it came in, within the stated bound after its
        // hang: the first after the hang's (1323), each next after the boot's first sample
        // (where key 61 hangs again), every one within the run's samples.
        let first = reset_sample(lines.first().unwrap_or_else(|| panic!("{board}: {stdout}")));
        assert!(reset_window(1323).contains(&first), "{board}: {stdout}");
        assert!(
            lines.len() >= 10,
            "{board}: {} resets: {stdout}",
            lines.len()
        );
        let run_samples = hung61.1.len() as u64;
        let mut last: Option<(u64, u64)> = None;
        for line in &lines {
            let sample = reset_sample(line);
            assert!(sample < run_samples, "{board}: {line} of {run_samples}");
            let zero: u64 = (line.split_once("booted again, "))
                .and_then(|(_, z)| z.split(' ').next())
                .unwrap_or_else(|| panic!("{board}: {line}"))
                .parse()
                .unwrap();
            if let Some((before, zero_before)) = last {
                let hangs = before + zero_before + 1;
                assert!(
                    reset_window(hangs).contains(&sample),
                    "{board}: {line} after a reset at {before}"
                );
            }
            last = Some((sample, zero));
        }
        // The watchdog's trip at the last reset; the hung core's samples unfinished, no
        // handler over the period on either core (a hung handler is not measured).
        let (last, _) = last.unwrap();
        assert!(
            stdout.contains(&format!(
                "board 1 core 1: watchdog on key 61 (C#4) at sample {last} ("
            )),
            "{board}: {stdout}"
        );
        let budget = (stdout.lines())
            .find(|l| l.trim_start().starts_with("board 1 (keys "))
            .unwrap_or_else(|| panic!("{board}: {stdout}"));
        let deadline: u64 = (stdout.split_once(" cycles per sample per core"))
            .and_then(|(a, _)| a.rsplit('(').next())
            .unwrap()
            .parse()
            .unwrap();
        let (core0, core1) = budget.split_once("; core 1: ").unwrap();
        assert!(
            !core0.contains("unfinished") && core1.contains(" samples unfinished ("),
            "{board}: {budget}"
        );
        for part in [core0, core1] {
            let max: u64 = (part.split_once("max "))
                .and_then(|(_, m)| m.split(' ').next())
                .unwrap()
                .parse()
                .unwrap();
            assert!(max < deadline, "{board}: {budget}");
        }
        assert!(
            stdout.contains(&format!(
                "faults: {n} TRIPS, {n} RESETS on 1 of 1 boards",
                n = lines.len()
            )),
            "{board}: {stdout}"
        );
        // The same hang cleared while the board boots again (`until` in the reset's
        // samples of zero force): one reset, the board at zero force through the boot,
        // then both keys play again (from rest: the re-entry restored their states while
        // the player's keys moved on), and the fault report counts the watchdog's trip.
        let until = format!("{:.7}s", (first as f64 + 1.5) / fs);
        let fault = format!("kind=hang,note=61,at=0.03s,until={until}");
        let (stdout, hang61, hang63) = play(board, "hang-clears", Some(&fault));
        let line = (stdout.lines())
            .find_map(|l| {
                l.trim()
                    .strip_prefix("board 1: watchdog timer reset at t = ")
            })
            .unwrap_or_else(|| panic!("{board}: {stdout}"));
        assert_eq!(reset_sample(line), first, "{board}: {line}");
        let zero: u64 = (line.split_once("booted again, "))
            .and_then(|(_, z)| z.split(' ').next())
            .unwrap_or_else(|| panic!("{board}: {line}"))
            .parse()
            .unwrap();
        assert!(
            stdout.contains("faults: 1 TRIP, 1 RESET on 1 of 1 boards"),
            "{board}: {stdout}"
        );
        // On key 61's core, which fell behind (core 0 kept its samples), naming key 61, at
        // the reset's sample (the record is written at the boot after it, from sample 0).
        assert!(
            stdout.contains(&format!(
                "board 1 core 1: watchdog on key 61 (C#4) at sample {first} ("
            )) && !stdout.contains("board 1 core 0: "),
            "{board}: {stdout}"
        );
        let (from, back) = ((first + 1) as f64 / fs, (first + zero) as f64 / fs);
        for rows in [&hang61.1, &hang63.1] {
            let booting: Vec<_> = rows
                .iter()
                .filter(|r| r[0] >= from && r[0] < back)
                .collect();
            assert!(
                booting.len() as u64 + 1 >= zero,
                "{board}: {} rows",
                booting.len()
            );
            for r in booting {
                assert!(r[force] == 0.0 && r[current] == 0.0, "{board}: {r:?}");
            }
            let playing = rows.iter().filter(|r| r[0] > back + 0.01);
            assert!(playing.clone().count() > 10_000, "{board}");
            assert!(
                playing.clone().any(|r| r[force] != 0.0),
                "{board}: plays again"
            );
            for r in playing {
                assert!(r[current].abs() <= peak_a + 1e-9, "{board}: {r:?}");
            }
        }
        // A brown-out clears SRAM and the RAM image with it: the boot ROM waits in USB
        // boot, play says so, the motors stay at zero, and the lost fault record (SRAM's
        // power-on pattern where it was) is not reported as trips.
        if board == "rp2040" {
            let (stdout, brown61, _) =
                play(board, "brownout", Some("kind=brownout,board=1,at=0.05s"));
            assert!(
                stdout.contains("the boot ROM waits in USB boot")
                    && stdout.contains("faults: 0 trips, 1 RESET on 1 of 1 boards"),
                "{board}: {stdout}"
            );
            assert!(!stdout.contains("unknown kind"), "{board}: {stdout}");
            let after = brown61.1.iter().filter(|r| r[0] > 0.0501);
            assert!(after.clone().count() > 10_000, "{board}");
            for r in after {
                assert!(r[force] == 0.0 && r[current] == 0.0, "{board}: {r:?}");
            }
        }
    }
    rig.done();
}

/// The DAC codes at the end of an `emu run` (keys.json's order) and its whole output.
fn emu_codes(out: &std::process::Output) -> (Vec<i32>, String) {
    assert_ok(out);
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    let codes = (stdout.lines())
        .find_map(|l| l.strip_prefix("DAC codes at the end: ["))
        .and_then(|l| l.split(']').next())
        .unwrap_or_else(|| panic!("{stdout}"))
        .split(", ")
        .map(|w| w.parse().unwrap())
        .collect();
    (codes, stdout)
}

#[test]
fn emu_run_injects_a_dac_stall_a_brownout_and_a_hang_on_both_boards() {
    let dir = temp_dir("cli-faults-kinds");
    let layout = small_layout(&dir, 60, 63);
    for board in ["rp2040", "rp2040_io"] {
        let fw = dir.join(board);
        build_for(&layout, board, &fw);
        let run = |fault: &[&str]| {
            let out = tactus()
                .args(["emu", "run"])
                .arg(fw.join("board-01/firmware.elf"))
                .args(["--stimulus", "mf-dip", "--seconds", "0.07"])
                .args(fault)
                .output()
                .unwrap();
            emu_codes(&out)
        };
        let (clean, stdout) = run(&[]);
        // The firmware's reset word of the run's power-on: CHIP_RESET.HAD_POR, REASON 0.
        assert!(
            stdout.contains(
                "boot: its firmware recorded its boot from a power-on or brown-out (reset \
                 word 0x00000100)\n"
            ),
            "{board}: {stdout}"
        );
        // Keys 60, 61 on core 1, 62, 63 on core 0.
        assert!(
            stdout.contains("core 1: keys [60, 61]"),
            "{board}: {stdout}"
        );
        assert_eq!(clean.len(), 4, "{board}: {stdout}");

        // Core 1's DAC takes no frame from 0.05 s: its keys hold the codes they had then
        // (not the clean run's at the end: the dip moved on), core 0's keys are untouched.
        // Nothing detects it (docs/firmware.md, "Faults"): 0 trips.
        // The held codes never above the limiter's peak (the board's limiter: its DAC code).
        let (stalled, stdout) = run(&["--fault", "kind=dac-stall,board=1,core=1,at=0.05s"]);
        assert_eq!(stalled[2..], clean[2..], "{board}: {stdout}");
        assert!(
            stalled[0] != clean[0] && stalled[1] != clean[1],
            "{board}: {stalled:?} vs {clean:?}"
        );
        let (peak_code, _) = limiter_peak(board);
        for code in &stalled {
            assert!(code.abs() <= peak_code, "{board}: {stalled:?}");
        }
        assert!(
            stdout.contains("faults: 0 trips on 1 board\n"),
            "{board}: {stdout}"
        );
        // The stall clears at 0.06 s: the DAC takes frames again and its outputs follow
        // the firmware's codes again, the clean run's at the end, though the run's codes
        // differed while it held (the digest of every sample's codes).
        let digest = |s: &str| {
            (s.lines())
                .find_map(|l| l.split_once("digest of every sample's codes "))
                .map(|(_, d)| d.to_string())
                .unwrap_or_else(|| panic!("{s}"))
        };
        let (_, clean_stdout) = run(&[]);
        let (recovered, stdout) = run(&[
            "--fault",
            "kind=dac-stall,board=1,core=1,at=0.05s,until=0.06s",
        ]);
        assert_eq!(recovered, clean, "{board}: {stdout}");
        assert_ne!(digest(&stdout), digest(&clean_stdout), "{board}: {stdout}");
        assert!(
            stdout.contains("faults: 0 trips on 1 board\n"),
            "{board}: {stdout}"
        );

        // A brown-out at 0.05 s: a power-on reset in that sample, the flash image boots
        // again within a few samples of zero force, the fault record starts again at 0.
        let (_, stdout) = run(&["--fault", "kind=brownout,board=1,at=0.05s"]);
        let line = (stdout.lines())
            .find_map(|l| l.strip_prefix("reset: brown-out reset at t = 0.0500 s "))
            .unwrap_or_else(|| panic!("{board}: {stdout}"));
        assert_eq!(reset_sample(line), 2205, "{board}: {line}");
        let zero: u64 = (line.split_once("booted again, ").unwrap().1)
            .split(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!((1..=20).contains(&zero), "{board}: {line}");
        assert!(
            stdout.contains("faults: 0 trips, 1 RESET on 1 of 1 boards"),
            "{board}: {stdout}"
        );
        // The boot after it wrote its reset word into SRAM the brown-out had filled with
        // the power-on pattern: a power-on or brown-out (HAD_POR, REASON 0), which the run
        // names the brown-out.
        assert!(
            stdout.contains(
                "board 1: its firmware recorded its last boot from a power-on or brown-out \
                 (reset word 0x00000100): the brown-out at sample 2205 (the board ran before \
                 it; its trips before it were lost with SRAM and the scratch registers)"
            ) && !stdout.contains("boot: "),
            "{board}: {stdout}"
        );

        // A hung update (the plain board's is in
        // a_hung_update_with_the_watchdog_on_resets_the_board_under_emu_run): the watchdog
        // resets the converter board within 1 ms and a sample, and its fault word says so.
        if board == "rp2040_io" {
            let (_, stdout) = run(&["--fault", "kind=hang,note=61,at=0.05s,until=0.055s"]);
            let line = (stdout.lines())
                .find_map(|l| l.strip_prefix("reset: watchdog timer reset at t = "))
                .unwrap_or_else(|| panic!("{board}: {stdout}"));
            // At the run's sample it came in, within the stated bound after the hang's;
            // the hung core's samples till then unfinished, no handler over the period.
            let sample = reset_sample(line);
            assert!(reset_window(2205).contains(&sample), "{line}");
            assert!(line.contains("booted again"), "{line}");
            // The reset word: REASON.TIMER beside the power-on's HAD_POR, which a watchdog
            // reset keeps (CHIP_RESET records chip-level resets only).
            assert!(
                stdout.contains(&format!(
                    "board 1: its firmware recorded its last boot from the watchdog (reset \
                     word 0x00000101): the watchdog's reset at sample {sample}"
                )),
                "{stdout}"
            );
            for core in 0..2 {
                let (worst, unfinished) = emu_core_line(&stdout, core);
                assert!(
                    worst < emu_period(&stdout),
                    "core {core}: worst {worst}: {stdout}"
                );
                let hung = if core == 1 { sample - 2205 } else { 0 };
                assert_eq!(unfinished, hung, "core {core}: {stdout}");
            }
            // Key 61's core, which fell behind: core 1's record, naming key 61.
            assert!(
                stdout.contains("board 1 core 1: watchdog on key 61 (C#4)")
                    && !stdout.contains("board 1 core 0: ")
                    && stdout.contains("faults: 1 TRIP, 1 RESET on 1 of 1 boards"),
                "{stdout}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_hang_on_a_key_standing_still_is_warned_about_and_waits_for_it_to_move() {
    // Key 61 pressed by 0.05 s and held to 0.3 s; key 60 never played.
    let dir = temp_dir("cli-faults-resting-hang");
    let layout = small_layout(&dir, 60, 63);
    let midi = dir.join("held.mid");
    write_midi(&midi, &[(61, 80, 0.05, 0.3)], &[]);
    let play = |fault: &str| {
        let out = tactus()
            .args(["play", midi.to_str().unwrap(), "--layout"])
            .arg(&layout)
            .args(["--seconds", "0.3", "--no-wav", "--fault", fault, "-o"])
            .arg(dir.join("out"))
            .output()
            .unwrap();
        assert_ok(&out);
        (
            String::from_utf8_lossy(&out.stdout).to_string(),
            String::from_utf8_lossy(&out.stderr).to_string(),
        )
    };
    // Held still from 0.07 s: the guard skips its update, the hang waits for the release
    // at 0.3 s, and the warning says so; the watchdog resets the board then.
    let (stdout, stderr) = play("kind=hang,note=61,at=0.07s");
    assert!(
        stderr.contains(
            "warning: --fault kind=hang,note=61,at=0.07s: key 61 (C#4) stands still at 0.070 s"
        ) && stderr.contains("at the latest when the key next moves, at 0.300 s"),
        "{stderr}"
    );
    let line = (stdout.lines())
        .find_map(|l| {
            l.trim()
                .strip_prefix("board 1: watchdog timer reset at t = ")
        })
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(
        (13_230..=13_230 + 45).contains(&reset_sample(line)),
        "{line}"
    );
    // A key that rests over the whole fault, as does every key of its instrument: the hang
    // never runs (no reset), and the warning says it may not.
    let (stdout, stderr) = play("kind=hang,note=60,at=0.07s,until=0.1s");
    assert!(
        stderr.contains("key 60 (C4) stands still at 0.070 s")
            && stderr.contains("the hang may never run"),
        "{stderr}"
    );
    assert!(stdout.contains("faults: 0 trips on 1 board\n"), "{stdout}");
    // A key moving when the hang begins: no warning.
    let (_, stderr) = play("kind=hang,note=61,at=0.03s");
    assert!(!stderr.contains("stands still"), "{stderr}");
    // `emu run` warns of the same fact in the same words (`fault::RestingHang`): `mf-dip`
    // holds every key at the bottom from 0.08 s to 0.38 s.
    let fw = dir.join("fw");
    assert_ok(
        &tactus()
            .args([
                "build",
                layout.to_str().unwrap(),
                "--target",
                "rp2040",
                "-o",
            ])
            .arg(&fw)
            .output()
            .unwrap(),
    );
    let emu = |seconds: &str, fault: &str| {
        let out = tactus()
            .args(["emu", "run"])
            .arg(fw.join("board-01/firmware.elf"))
            .args([
                "--stimulus",
                "mf-dip",
                "--seconds",
                seconds,
                "--fault",
                fault,
            ])
            .output()
            .unwrap();
        assert_ok(&out);
        String::from_utf8_lossy(&out.stderr).to_string()
    };
    let stderr = emu("0.12", "kind=hang,note=61,at=0.1s");
    assert!(
        stderr.contains(
            "warning: --fault kind=hang,note=61,at=0.1s: key 61 (C#4) stands still at 0.100 s"
        ) && stderr.contains("the hang may never run"),
        "{stderr}"
    );
    let stderr = emu("0.12", "kind=hang,note=61,at=0.09s,until=0.11s");
    assert!(stderr.contains("stands still at 0.090 s"), "{stderr}");
    // Moving (the dip's descent) when the hang begins: no warning.
    let stderr = emu("0.06", "kind=hang,note=61,at=0.05s");
    assert!(!stderr.contains("stands still"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// `kind=adc-no-dreq`: a converter board's ADC raises no more DREQ (its state machine
/// stops), so the DMA channel that reads its results never completes a burst. The
/// firmware's burst check (docs/firmware.md, "Faults") sees it at the next sample: the
/// stalled core's motors at zero force within two samples, an `adc-stall` trip on every
/// key of the core, the other core untouched. When the ADC runs again (`until`) the keys
/// read positions again, their change checks trip on the jump, and 100 ms of plausible
/// readings later they play again, the clean run's codes at the end. A board without
/// converters refuses the kind, naming the field, in `emu run` and in `play`.
#[test]
fn an_adc_without_dreq_is_injected_on_a_converter_board_and_refused_on_a_plain_one() {
    let dir = temp_dir("cli-faults-no-dreq");
    let layout = small_layout(&dir, 60, 63);
    for board in ["rp2040", "rp2040_io"] {
        let fw = dir.join(board);
        build_for(&layout, board, &fw);
        let run = |seconds: &str, fault: &[&str]| {
            tactus()
                .args(["emu", "run"])
                .arg(fw.join("board-01/firmware.elf"))
                .args(["--stimulus", "mf-dip", "--seconds", seconds])
                .args(fault)
                .output()
                .unwrap()
        };
        if board == "rp2040" {
            let out = run(
                "0.07",
                &["--fault", "kind=adc-no-dreq,board=1,core=1,at=0.05s"],
            );
            assert!(!out.status.success(), "{out:?}");
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(
                stderr.contains("`kind`: `adc-no-dreq`") && stderr.contains("no converters"),
                "{stderr}"
            );
            let midi = dir.join("held.mid");
            write_midi(&midi, &[(60, 90, 0.05, 0.1)], &[]);
            let out = tactus()
                .args(["play", midi.to_str().unwrap(), "--layout"])
                .arg(&layout)
                .args(["--seconds", "0.1", "--no-wav", "--board", board])
                .args(["--fault", "kind=adc-no-dreq,board=1,core=0,at=0.05s"])
                .output()
                .unwrap();
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(
                !out.status.success() && stderr.contains("`kind`: `adc-no-dreq`"),
                "{stderr}"
            );
            continue;
        }
        let (clean, _) = emu_codes(&run("0.07", &[]));
        // Keys 60, 61 on core 1, 62, 63 on core 0. The burst check sees the stall at the
        // first sample whose results it should have filled: core 1's motors at DAC code 0
        // (zero force) and its keys out of the model for as long as it lasts, one trip of
        // kind adc-stall on every key of the core; core 0 plays as without it.
        let (stalled, stdout) = emu_codes(&run(
            "0.07",
            &["--fault", "kind=adc-no-dreq,board=1,core=1,at=0.05s"],
        ));
        assert_eq!(stalled[2..], clean[2..], "{stdout}");
        assert_eq!(stalled[..2], [0, 0], "{stdout}");
        assert_ne!(clean[..2], [0, 0], "{stdout}");
        assert!(
            stdout.contains("board 1 core 1: adc-stall on every key of the core")
                && stdout.contains(", 1 trip\n")
                && !stdout.contains("board 1 core 0: "),
            "{stdout}"
        );
        // Within two samples: a stall from sample s is seen by the handler of s + 1 (a run of
        // samples 0 to s sees none), whose
        // zero codes the DMA sends at the tick of s + 2.
        let from = 2205; // 0.05 s at 44.1 kHz
        assert!(
            stdout.contains(&format!("(from sample {from} on)")),
            "{stdout}"
        );
        for (samples, seen) in [(from + 1, false), (from + 2, true)] {
            let seconds = format!("{:.9}", (samples as f64 + 0.01) / 44_100.0);
            let (codes, stdout) = emu_codes(&run(
                &seconds,
                &["--fault", "kind=adc-no-dreq,board=1,core=1,at=0.05s"],
            ));
            assert_eq!(stdout.contains("adc-stall"), seen, "{samples}: {stdout}");
            if seen {
                assert!(
                    stdout.contains(&format!("adc-stall on every key of the core (its ADC's burst did not finish) at sample {}", from + 1)),
                    "{stdout}"
                );
                assert_eq!(codes[..2], [0, 0], "{samples}: {stdout}");
            }
        }

        // When the ADC answers again (`until`), the bursts finish and the keys read
        // positions again: the keys moved during the stall (`mf-dip` presses them), so
        // their change checks trip and the keys recover as from any sensor fault, after
        // which the board plays as the clean run does.
        let (clean, _) = emu_codes(&run("0.3", &[]));
        let (back, stdout) = emu_codes(&run(
            "0.3",
            &[
                "--fault",
                "kind=adc-no-dreq,board=1,core=1,at=0.05s,until=0.06s",
            ],
        ));
        assert!(
            stdout.contains("board 1 core 1: ") && !stdout.contains("board 1 core 0: "),
            "{stdout}"
        );
        assert_eq!(back, clean, "{stdout}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A trace of one key: its CSV's header and rows ([`trace_rows`]).
type KeyTrace = (Vec<String>, Vec<Vec<f64>>);

/// The set-up the flip tests share: a temporary folder, a layout of keys 60–63 on one
/// board, and a MIDI file `two.mid` pressing the two traced keys `keys` from about 10 ms
/// before 0.05 s, held to 0.3 s (the run goes on to rest).
struct FlipRig {
    dir: PathBuf,
    layout: PathBuf,
    midi: PathBuf,
    keys: [u8; 2],
}

/// A clean run of a [`FlipRig`] on one board: the two keys' traces, the columns asked for
/// (by header name, in order) and the board's limiter peak as a motor current, A.
struct CleanRun<const N: usize> {
    a: KeyTrace,
    b: KeyTrace,
    cols: [usize; N],
    peak_a: f64,
}

impl FlipRig {
    /// The rig in a fresh temporary folder named after `name`.
    fn new(name: &str, keys: [u8; 2]) -> Self {
        let dir = temp_dir(name);
        let layout = small_layout(&dir, 60, 63);
        let midi = dir.join("two.mid");
        let [a, b] = keys;
        write_midi(&midi, &[(a, 80, 0.05, 0.3), (b, 80, 0.05, 0.3)], &[]);
        FlipRig {
            dir,
            layout,
            midi,
            keys,
        }
    }

    /// `tactus play two.mid --layout LAYOUT --board BOARD --seconds 0.3
    /// --no-quiescent-guard --trace-keys A,B [--fault FAULT]` into `dir/BOARD-NAME` (every
    /// update runs, as on grand88's boards), which must succeed: its standard output and
    /// the traces of the two keys.
    fn play(&self, board: &str, name: &str, fault: Option<&str>) -> (String, KeyTrace, KeyTrace) {
        self.play_with("0.3", false, board, name, fault)
    }

    /// [`FlipRig::play`] of `seconds` of music, with the quiescent-key guard when `guard`.
    fn play_with(
        &self,
        seconds: &str,
        guard: bool,
        board: &str,
        name: &str,
        fault: Option<&str>,
    ) -> (String, KeyTrace, KeyTrace) {
        let [a, b] = self.keys;
        let out_dir = self.dir.join(format!("{board}-{name}"));
        let mut c = tactus();
        c.args(["play", self.midi.to_str().unwrap(), "--layout"])
            .arg(&self.layout)
            .args(["--board", board, "--seconds", seconds, "--no-wav"]);
        if !guard {
            c.arg("--no-quiescent-guard");
        }
        c.args(["--trace-keys", &format!("{a},{b}"), "-o"])
            .arg(&out_dir);
        if let Some(f) = fault {
            c.args(["--fault", f]);
        }
        let out = c.output().unwrap();
        assert_ok(&out);
        let stdout = String::from_utf8_lossy(&out.stdout).to_string();
        let key = |k: u8| trace_rows(&out_dir.join(format!("two-key{k}.csv")));
        (stdout, key(a), key(b))
    }

    /// The clean run on `board` (no fault), with the columns `names` of the first key's
    /// trace.
    fn clean<const N: usize>(&self, board: &str, names: [&str; N]) -> CleanRun<N> {
        let (_, a, b) = self.play(board, "clean", None);
        let cols = names.map(|n| a.0.iter().position(|h| h == n).unwrap());
        let (_, peak_a) = limiter_peak(board);
        CleanRun { a, b, cols, peak_a }
    }

    /// Removes the temporary folder (left in place when a test fails, to be read).
    fn done(self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// What every contained flip must show (`case` names it in failures): `stdout` reports no
/// trip; the `other` key's rows (flipped run, clean run) are the clean run's; the `flipped`
/// key's rows are as many as the clean run's, each sample's motor current (column
/// `current`) within the limiter's `peak` A, and its last 0.1 s (4,410 samples) the clean
/// run's (worn off). `cols` = (force column, current column, peak A). Returns the samples
/// whose force (column `force`) differs from the clean run's.
fn assert_flip_contained(
    case: &str,
    stdout: &str,
    (flipped, clean): (&[Vec<f64>], &[Vec<f64>]),
    (other, other_clean): (&[Vec<f64>], &[Vec<f64>]),
    (force, current, peak): (usize, usize, f64),
) -> Vec<usize> {
    assert!(
        stdout.contains("faults: 0 trips on 1 board\n"),
        "{case}: {stdout}"
    );
    assert_eq!(other, other_clean, "{case}: the other key changed");
    assert_eq!(flipped.len(), clean.len(), "{case}");
    for r in flipped {
        assert!(r[current].abs() <= peak + 1e-9, "{case}: {r:?}");
    }
    let tail = clean.len() - 4_410;
    assert_eq!(flipped[tail..], clean[tail..], "{case}: not worn off");
    (flipped.iter().zip(clean))
        .enumerate()
        .filter(|(_, (a, b))| a[force] != b[force])
        .map(|(i, _)| i)
        .collect()
}

/// The flips of `a_flipped_bit_in_any_state_word_…`: (word of the grand piano key's state
/// struct, bit, time s, whether the key's forces change, what the word is). The struct
/// (`tactus_compiler::abi::StateLayout`, `tactus build grand_piano --target rp2040`'s
/// header): byte 0 the escapement's mode (`ready`, `hold`, `escaped`: 0–2), bytes 1–7 the
/// `on` handlers' edges, byte 8 the differentiator ring's position (word 2: left out here,
/// `a_flipped_high_bit_of_the_ring_position_…`), words 3–10 the states `s`, `w`, `pulse`, `tau`,
/// `fr.w`, `esc.xmax`, `esc.fhold`, `dt/tau`, words 11–44 the ring, 45–53 the published
/// forces and outputs. The times: 0.02 s with the key starting its press, 0.1 s held at
/// the bottom after its strike. A mode byte out of range trips the state check instead
/// (`a_mode_byte_out_of_range_trips_…`).
const FLIPS: [(u32, u8, f64, bool, &str); 14] = [
    (
        0,
        1,
        0.02,
        true,
        "mode ready to escaped: a valid mode, which no check sees",
    ),
    (1, 24, 0.02, true, "an edge byte"),
    (3, 30, 0.02, true, "s, the hammer's angle"),
    (3, 30, 0.1, true, "s while held"),
    (4, 31, 0.02, true, "w, the hammer's speed"),
    (5, 30, 0.02, true, "pulse"),
    (
        5,
        31,
        0.1,
        true,
        "pulse's sign while held: saturated to 0 N",
    ),
    (
        6,
        31,
        0.02,
        false,
        "tau, read only with a pulse, rewritten with it",
    ),
    (7, 30, 0.02, true, "fr.w, clamped every sample"),
    (
        8,
        30,
        0.02,
        true,
        "esc.xmax, kept at rest, read by the press",
    ),
    (9, 31, 0.02, false, "esc.fhold, rewritten before it is read"),
    (10, 31, 0.02, true, "dt/tau"),
    (27, 31, 0.02, true, "a ring word: one sample's d()"),
    (
        45,
        31,
        0.02,
        false,
        "a published word, rewritten every sample",
    ),
];

#[test]
fn a_flipped_bit_in_any_state_word_stays_under_the_peak_and_wears_off_on_both_boards() {
    // Key 61 (core 1) and key 63 (core 0) pressed from about 10 ms before 0.05 s, held to
    // 0.3 s; the run goes on to rest (0.86 s). Every update runs (no quiescent guard, as on
    // grand88's boards). Each flip of FLIPS in key 61's state: no check trips (the state
    // check sees only a mode byte out of range: docs/firmware.md), every sample's motor current within the board's
    // limiter peak, key 63 on the other core exactly as without it, key 61's forces changed
    // where the word is read (a test that could not fail otherwise), and the flip worn off:
    // key 61's last 0.1 s (4,410 samples) exactly the clean run's.
    let rig = FlipRig::new("cli-faults-flips", [61, 63]);
    for board in ["rp2040", "rp2040_io"] {
        let clean = rig.clean(board, ["force_n", "motor_current_a"]);
        let (clean61, clean63, [force, current]) = (&clean.a, &clean.b, clean.cols);
        assert!(clean61.1.len() > 30_000, "{board}: {}", clean61.1.len());
        for (word, bit, at, changes, what) in FLIPS {
            let fault = format!("kind=flip,word={word},bit={bit},note=61,at={at}s");
            let name = format!("w{word}b{bit}t{at}");
            let (stdout, flip61, flip63) = rig.play(board, &name, Some(&fault));
            let case = format!("{board}, {fault} ({what})");
            let changed = assert_flip_contained(
                &case,
                &stdout,
                (&flip61.1, &clean61.1),
                (&flip63.1, &clean63.1),
                (force, current, clean.peak_a),
            );
            assert_eq!(!changed.is_empty(), changes, "{case}: {changed:?}");
            if let (Some(first), Some(last)) = (changed.first(), changed.last()) {
                eprintln!(
                    "{case}: {} samples changed, from {first} to {last}",
                    changed.len()
                );
            }
        }
    }
    rig.done();
}

#[test]
fn a_flipped_high_bit_of_the_ring_position_writes_no_other_key_on_both_boards() {
    // Keys 60 and 61 (adjacent state structs: docs/firmware.md's flip table) pressed from
    // about 10 ms before 0.05 s, held to 0.3 s. A flip of bit 6 or 7 of key 60's ring
    // position (byte 8 of its state, word 2's low byte), starting the press and while held:
    // the position leaves 4..=68, and the update takes the wrap (the ring starts again at
    // its end) instead of storing its readings past its struct. Key 61 exactly as without
    // the flip, no trip and no fault, key 60's current within the board's limiter peak, and
    // key 60's last 0.1 s (4,410 samples) the clean run's. Without the wrap, the update
    // stores past its struct into key 61's (a HardFault when it hits key 61's position).
    let rig = FlipRig::new("cli-faults-ring-pos", [60, 61]);
    for board in ["rp2040", "rp2040_io"] {
        let clean = rig.clean(board, ["force_n", "motor_current_a"]);
        let (clean60, clean61, [force, current]) = (&clean.a, &clean.b, clean.cols);
        assert!(clean60.1.len() > 30_000, "{board}: {}", clean60.1.len());
        for bit in [6, 7] {
            for at in [0.02, 0.1] {
                let fault = format!("kind=flip,word=2,bit={bit},note=60,at={at}s");
                let (stdout, flip60, flip61) =
                    rig.play(board, &format!("b{bit}t{at}"), Some(&fault));
                let case = format!("{board}, {fault}");
                let changed = assert_flip_contained(
                    &case,
                    &stdout,
                    (&flip60.1, &clean60.1),
                    (&flip61.1, &clean61.1),
                    (force, current, clean.peak_a),
                )
                .len();
                // Starting the press the ring's readings differ, so its d() (and the
                // hammer after it) change: the flip reached the update. Held, they are
                // alike and nothing changes.
                assert_eq!(changed > 0, at < 0.05, "{case}: {changed} samples changed");
            }
        }
    }
    rig.done();
}

#[test]
fn a_mode_byte_out_of_range_trips_the_state_check_and_recovers_on_both_boards() {
    // Key 61 (core 1) and key 63 (core 0) as in `a_flipped_bit_in_any_state_word_…`. A
    // flip that leaves key 61's escapement mode byte (byte 0 of its state: variants 0–2)
    // out of range, while it starts its press (bit 2, at two samples) and while it is held
    // (bit 7): the state check trips at the key's next check, within its class's longest
    // gap (docs/firmware.md: at most 7 samples at 133 MHz), as `state-range` on key 61 with
    // that sample; its motor at DAC code 0 from that sample for 100 ms (4,410 samples),
    // then it plays again (its state from rest) and is the clean run's again by the end;
    // key 63 on the other core exactly as without it; never a current above the peak.
    // Without the state check the same flips trip nothing (the mode is kept until the
    // press's end, the escapement's let-off left out meanwhile: docs/firmware.md).
    let rig = FlipRig::new("cli-faults-state-check", [61, 63]);
    let fs = 44_100.0;
    for board in ["rp2040", "rp2040_io"] {
        let clean = rig.clean(board, ["motor_current_a", "dac_code"]);
        let (clean61, clean63, [current, code]) = (&clean.a, &clean.b, clean.cols);
        let peak_a = clean.peak_a;
        for (bit, at) in [(2u8, 882usize), (2, 883), (7, 4410)] {
            // The flip before sample `at` (a time just under it: its sample is the ceiling).
            let fault = format!(
                "kind=flip,word=0,bit={bit},note=61,at={:.9}s",
                (at as f64 - 0.5) / fs
            );
            let (stdout, flip61, flip63) = rig.play(board, &format!("b{bit}-{at}"), Some(&fault));
            let case = format!("{board}, {fault}");
            assert!(
                stdout.contains("faults: 1 TRIP on 1 of 1 boards"),
                "{case}: {stdout}"
            );
            let tripped: usize = (stdout
                .split_once("board 1 core 1: state-range on key 61 (C#4) at sample "))
            .and_then(|(_, rest)| rest.split(' ').next())
            .unwrap_or_else(|| panic!("{case}: {stdout}"))
            .parse()
            .unwrap();
            assert!((at..=at + 7).contains(&tripped), "{case}: at {tripped}");
            assert_eq!(flip63.1, clean63.1, "{case}: key 63 changed");
            assert_eq!(flip61.1[..at], clean61.1[..at], "{case}: before the flip");
            let back = tripped + 4_410;
            for r in &flip61.1[tripped..back] {
                assert!(r[current] == 0.0 && r[code] == 0.0, "{case}: {r:?}");
            }
            assert!(
                flip61.1[back..back + 50].iter().any(|r| r[code] != 0.0),
                "{case}: plays again"
            );
            for r in &flip61.1 {
                assert!(r[current].abs() <= peak_a + 1e-9, "{case}: {r:?}");
            }
            let tail = clean61.1.len() - 4_410;
            assert_eq!(
                flip61.1[tail..],
                clean61.1[tail..],
                "{case}: not the clean run's"
            );
        }
    }
    rig.done();
}

#[test]
fn a_flipped_low_bit_of_the_ring_position_resets_the_board_at_once_on_both_boards() {
    // Keys 60 (core 1) and 61 pressed from about 10 ms before 0.05 s, held to 0.3 s, as in
    // `a_flipped_high_bit_of_the_ring_position_…`. A flip of bit 0 or 1 of key 60's ring
    // position (byte 8 of its state) leaves it no multiple of 4: its next update's ring
    // store is unaligned, a HardFault, whose handler records a `hard-fault` trip and resets
    // the board at once through the watchdog's trigger (docs/firmware.md, "Faults"). The
    // bound: the reset in the sample of the key's next update, here the flip's own (every
    // update runs every sample). Then every motor at DAC code 0 from the reset's sample
    // through the boot's samples, the fault report naming the kind, the key and the
    // sample, never a current above the peak, and the board plays again (from rest: the
    // clean run's over the last 0.1 s). Without the handler the core would hang in `B .`
    // until the watchdog's count ran out (a `watchdog timer` reset 40–45 samples later).
    let rig = FlipRig::new("cli-faults-hard-fault", [60, 61]);
    let fs = 44_100.0;
    for board in ["rp2040", "rp2040_io"] {
        let clean = rig.clean(board, ["force_n", "motor_current_a", "dac_code"]);
        let (clean60, clean61, [force, current, code]) = (&clean.a, &clean.b, clean.cols);
        let peak_a = clean.peak_a;
        for bit in [0, 1] {
            // Starting the press (sample 882) and held at the bottom (sample 4,410).
            for at in [882usize, 4_410] {
                let fault = format!(
                    "kind=flip,word=2,bit={bit},note=60,at={:.9}s",
                    (at as f64 - 0.5) / fs
                );
                let (stdout, flip60, flip61) =
                    rig.play(board, &format!("b{bit}-{at}"), Some(&fault));
                let case = format!("{board}, {fault}");
                assert!(
                    stdout.contains("faults: 1 TRIP, 1 RESET on 1 of 1 boards"),
                    "{case}: {stdout}"
                );
                assert!(
                    stdout.contains(&format!(
                        "board 1 core 1: hard-fault on key 60 (C4) at sample {at} ("
                    )),
                    "{case}: {stdout}"
                );
                let line = (stdout.lines())
                    .find_map(|l| {
                        l.trim()
                            .strip_prefix("board 1: watchdog trigger reset at t = ")
                    })
                    .unwrap_or_else(|| panic!("{case}: {stdout}"));
                assert_eq!(reset_sample(line), at as u64, "{case}: {line}");
                let zero: usize = (line.split_once("booted again, "))
                    .and_then(|(_, z)| z.split(' ').next())
                    .unwrap_or_else(|| panic!("{case}: {line}"))
                    .parse()
                    .unwrap();
                assert!(zero <= 10, "{case}: {zero} samples booting");
                let back = at + zero + 1;
                for (rows, clean) in [(&flip60.1, &clean60.1), (&flip61.1, &clean61.1)] {
                    assert_eq!(rows.len(), clean.len(), "{case}");
                    assert_eq!(rows[..at], clean[..at], "{case}: before the flip");
                    for r in &rows[at..back] {
                        assert!(
                            r[force] == 0.0 && r[current] == 0.0 && r[code] == 0.0,
                            "{case}: {r:?}"
                        );
                    }
                    for r in rows.iter() {
                        assert!(r[current].abs() <= peak_a + 1e-9, "{case}: {r:?}");
                    }
                    assert!(
                        rows[back..back + 50].iter().any(|r| r[code] != 0.0),
                        "{case}: plays again"
                    );
                    let tail = clean.len() - 4_410;
                    assert_eq!(rows[tail..], clean[tail..], "{case}: not recovered");
                }
            }
        }
    }
    rig.done();
}
