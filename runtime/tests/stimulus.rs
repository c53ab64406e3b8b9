//! Properties of the built-in key stimuli and of the CSV stimulus reader.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use tactus_runtime::stimulus::{
    builtin, builtin_names, dip, from_csv, DipConfig, Stimulus, StimulusError, DEFAULT_DIP_M,
};
use tactus_runtime::DEFAULT_SAMPLE_RATE_HZ as FS;

const DIP: f64 = DEFAULT_DIP_M;

fn stim(name: &str) -> Stimulus {
    builtin(name, DIP, FS).unwrap_or_else(|e| panic!("builtin {name}: {e}"))
}

/// A file path in the temp dir that no other test (or test run) uses.
fn temp_path(tag: &str) -> PathBuf {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let n = COUNTER.fetch_add(1, Ordering::SeqCst);
    std::env::temp_dir().join(format!(
        "tactus-stimulus-{}-{n}-{tag}.csv",
        std::process::id()
    ))
}

/// Writes `text` to a fresh temp file, runs `from_csv` on it, removes the file.
fn read_csv_text(tag: &str, text: &str) -> (PathBuf, Result<Stimulus, StimulusError>) {
    let path = temp_path(tag);
    std::fs::write(&path, text).unwrap();
    let result = from_csv(&path, FS);
    std::fs::remove_file(&path).unwrap();
    (path, result)
}

/// Seconds from the last sample at rest before the press to the first sample at the bottom.
fn descent_s(s: &Stimulus) -> f64 {
    let first_bottom = s
        .key
        .iter()
        .position(|&x| x >= DIP)
        .expect("reaches bottom");
    let last_rest = s.key[..first_bottom]
        .iter()
        .rposition(|&x| x <= 0.0)
        .expect("starts at rest");
    (first_bottom - last_rest) as f64 / FS
}

fn max_velocity(s: &Stimulus) -> f64 {
    s.velocity_m_per_s().into_iter().fold(0.0, f64::max)
}

#[test]
fn every_builtin_is_listed_and_buildable() {
    let names = builtin_names();
    assert_eq!(names.len(), 9);
    for (name, description) in names {
        let s = stim(name);
        assert_eq!(s.name, *name);
        assert_eq!(s.description, *description);
        assert_eq!(s.sample_rate_hz, FS);
        assert!(!description.is_empty());
        assert!(s.len() > 100, "{name} has {} samples", s.len());
    }
}

#[test]
fn builtins_start_and_end_at_rest_and_stay_within_the_dip() {
    for (name, _) in builtin_names() {
        let s = stim(name);
        for (i, &x) in s.key.iter().enumerate() {
            assert!(
                (0.0..=DIP).contains(&x),
                "{name}: sample {i} = {x} m outside [0, {DIP}]"
            );
        }
        if *name == "hold" {
            continue; // checked in `hold_is_still_at_half_dip`
        }
        assert_eq!(s.key[0], 0.0, "{name} starts at rest");
        assert_eq!(*s.key.last().unwrap(), 0.0, "{name} ends at rest");
        // ...and is at rest for the first 20 ms, and moves at some point.
        assert!(s.key[..(0.019 * FS) as usize].iter().all(|&x| x == 0.0));
        assert!(s.key.iter().any(|&x| x > 0.4 * DIP), "{name} moves");
        let duration = s.duration_s();
        let limit = if *name == "slow-dip" { 4.5 } else { 1.2 };
        assert!(duration <= limit, "{name} lasts {duration} s");
    }
}

#[test]
fn full_dips_reach_the_bottom_and_descent_times_are_ordered() {
    let levels = ["pp-dip", "p-dip", "mf-dip", "f-dip", "ff-dip"];
    let nominal = [0.160, 0.100, 0.060, 0.040, 0.025];
    let mut previous: Option<(f64, f64)> = None;
    for (name, want) in levels.iter().zip(nominal) {
        let s = stim(name);
        let max = s.key.iter().fold(0.0, |a: f64, &b| a.max(b));
        assert_eq!(max, DIP, "{name} reaches the full dip");
        let t = descent_s(&s);
        assert!(
            (t - want).abs() <= 2.0 / FS,
            "{name}: descent {t} s, nominal {want} s"
        );
        let v = max_velocity(&s);
        // Cycloidal law: peak velocity 2·dip/descent.
        let v_law = 2.0 * DIP / want;
        assert!(
            (v - v_law).abs() < 0.01 * v_law,
            "{name}: peak velocity {v} m/s, law {v_law} m/s"
        );
        if let Some((t_prev, v_prev)) = previous {
            assert!(t < t_prev, "{name} descends faster than the softer level");
            assert!(v > v_prev, "{name} peaks faster than the softer level");
        }
        previous = Some((t, v));
    }
}

#[test]
fn dip_is_smooth() {
    // C1: no velocity jump between samples larger than what the peak acceleration allows.
    // Cycloid peak acceleration 2π·dip/T²; one sample changes velocity by at most a/fs.
    for name in ["ff-dip", "pp-dip", "repeated", "slow-dip"] {
        let s = stim(name);
        let v = s.velocity_m_per_s();
        let a_max = 2.0 * std::f64::consts::PI * DIP / (0.025 * 0.025);
        for i in 1..v.len() {
            let dv = (v[i] - v[i - 1]).abs();
            assert!(dv <= 1.05 * a_max / FS, "{name}: velocity jump {dv} at {i}");
        }
    }
}

#[test]
fn dip_sweeps_speed_and_validates_arguments() {
    let slow = dip(0.2, 0.1, 0.1, 0.008, 10_000.0).unwrap();
    let fast = dip(0.01, 0.1, 0.1, 0.008, 10_000.0).unwrap();
    assert!(max_velocity(&fast) > 10.0 * max_velocity(&slow));
    assert_eq!(slow.key.iter().fold(0.0, |a: f64, &b| a.max(b)), 0.008);

    for bad in [
        dip(0.0, 0.1, 0.1, 0.01, FS),
        dip(0.05, -0.1, 0.1, 0.01, FS),
        dip(0.05, 0.1, f64::NAN, 0.01, FS),
        dip(0.05, 0.1, 0.1, -0.01, FS),
        dip(0.05, 0.1, 0.1, 0.01, 0.0),
        dip(0.05, 0.1, 0.1, 0.01, f64::INFINITY),
    ] {
        let e = bad.unwrap_err();
        assert!(matches!(e, StimulusError::InvalidParameter { .. }), "{e}");
        assert!(e.to_string().contains("must be finite"), "{e}");
    }
    let e = dip(1e6, 0.1, 0.1, 0.01, FS).unwrap_err();
    assert!(matches!(e, StimulusError::TooLong { .. }), "{e}");

    let config = DipConfig {
        rest_before_s: 0.1,
        ..DipConfig::default()
    };
    let s = config.stimulus("late", FS).unwrap();
    assert!(s.key[(0.099 * FS) as usize] == 0.0 && s.key[(0.13 * FS) as usize] > 0.0);
}

#[test]
fn half_dip_stops_abruptly_at_half_the_dip() {
    let s = stim("half-dip");
    let max = s.key.iter().fold(0.0, |a: f64, &b| a.max(b));
    assert!((max - 0.5 * DIP).abs() < 1e-12, "max {max}");
    let v = s.velocity_m_per_s();
    let stop = s.key.iter().position(|&x| x >= 0.5 * DIP).unwrap();
    let start = s.key.iter().position(|&x| x > 0.0).unwrap();
    // Reaches 50 % about 20 ms after leaving rest.
    let press_s = (stop - start) as f64 / FS;
    assert!((press_s - 0.020).abs() < 0.001, "press {press_s} s");
    // Fast just before the stop, still within 1 ms of it.
    let v_peak = v[..stop].iter().fold(0.0, |a: f64, &b| a.max(b));
    assert!(v_peak > 0.2, "peak {v_peak} m/s");
    let ms = (0.001 * FS) as usize;
    let fast_until = v[..stop].iter().rposition(|&x| x > 0.8 * v_peak).unwrap();
    assert!(
        stop - fast_until <= ms + 1,
        "slows down over {} samples",
        stop - fast_until
    );
    // Still (on the stop) for the next 300 ms.
    for (i, &vi) in v[stop + 1..stop + (0.3 * FS) as usize].iter().enumerate() {
        assert!(
            vi.abs() < 1e-9,
            "velocity {vi} m/s {i} samples after the stop"
        );
    }
    // Released slowly: the release is at least 5 times slower than the press.
    let v_min = v.iter().fold(0.0, |a: f64, &b| a.min(b));
    assert!(v_min < 0.0 && -v_min < v_peak / 5.0, "release peak {v_min}");
}

#[test]
fn repeated_has_four_presses_with_partial_releases() {
    let s = stim("repeated");
    let lo = 0.3 * DIP;
    // Count arrivals at the bottom, and check the key never returns to rest in between.
    let bottoms: Vec<usize> = (1..s.len())
        .filter(|&i| s.key[i] >= DIP && s.key[i - 1] < DIP)
        .collect();
    assert_eq!(bottoms.len(), 4, "{bottoms:?}");
    let between = &s.key[bottoms[0]..bottoms[3]];
    let min_between = between.iter().fold(DIP, |a: f64, &b| a.min(b));
    assert!(
        (min_between - lo).abs() < 1e-12,
        "min between {min_between}"
    );
    // ~8 notes per second.
    for w in bottoms.windows(2) {
        let period = (w[1] - w[0]) as f64 / FS;
        assert!((period - 0.125).abs() < 0.002, "period {period} s");
    }
}

#[test]
fn slow_dip_is_quasi_static() {
    let s = stim("slow-dip");
    let v = max_velocity(&s);
    assert!(v < 0.006, "peak velocity {v} m/s");
    assert!(s.duration_s() > 4.0);
    assert_eq!(s.key.iter().fold(0.0, |a: f64, &b| a.max(b)), DIP);
}

#[test]
fn hold_is_still_at_half_dip() {
    let s = stim("hold");
    assert!((s.duration_s() - 0.2).abs() < 2.0 / FS);
    assert!(s.key.iter().all(|&x| x == 0.5 * DIP));
}

#[test]
fn builtin_rejects_unknown_names_and_bad_arguments() {
    let e = builtin("mezzo-dip", DIP, FS).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("mezzo-dip"), "{msg}");
    for (name, _) in builtin_names() {
        assert!(msg.contains(name), "{msg} lacks {name}");
    }
    assert!(builtin("ff-dip", 0.0, FS).is_err());
    assert!(builtin("ff-dip", DIP, -1.0).is_err());
    assert!(builtin("slow-dip", DIP, 1e12).is_err());
    // A different dip scales the stimulus.
    let s = builtin("mf-dip", 0.007, FS).unwrap();
    assert_eq!(s.key.iter().fold(0.0, |a: f64, &b| a.max(b)), 0.007);
}

#[test]
fn csv_round_trip_key_mm() {
    let original = stim("repeated");
    let path = temp_path("roundtrip");
    let mut bytes = Vec::new();
    original.write_csv(&mut bytes).unwrap();
    std::fs::write(&path, &bytes).unwrap();
    let read = from_csv(&path, FS);
    std::fs::remove_file(&path).unwrap();
    let read = read.unwrap();
    assert_eq!(read.len(), original.len());
    assert_eq!(read.sample_rate_hz, FS);
    assert!(path.to_string_lossy().contains(&read.name));
    for (i, (a, b)) in original.key.iter().zip(&read.key).enumerate() {
        assert!((a - b).abs() <= 1e-15, "sample {i}: {a} vs {b}");
    }
}

#[test]
fn csv_time_and_key_are_interpolated_onto_the_sample_grid() {
    let text = "# comment line\n time_s , key_mm \n0.0,0\n0.001,10\n0.003, 2\n";
    let (_, s) = read_csv_text("timed", text);
    let s = s.unwrap();
    let fs = FS;
    // 0 .. 3 ms inclusive.
    assert_eq!(s.len(), (0.003 * fs).floor() as usize + 1);
    let at = |t: f64| -> f64 {
        if t <= 0.001 {
            t / 0.001 * 0.010
        } else {
            0.010 + (t - 0.001) / 0.002 * (0.002 - 0.010)
        }
    };
    for (i, &x) in s.key.iter().enumerate() {
        let t = i as f64 / fs;
        assert!((x - at(t)).abs() < 1e-12, "sample {i}: {x} vs {}", at(t));
    }
}

#[test]
fn csv_grid_starts_at_the_first_time() {
    let (_, s) = read_csv_text("offset", "time_s,key_mm\n1.0,5\n1.001,5\n");
    let s = s.unwrap();
    assert_eq!(s.len(), (0.001 * FS).floor() as usize + 1);
    assert!(s.key.iter().all(|&x| (x - 0.005).abs() < 1e-15));
}

fn csv_error(tag: &str, text: &str) -> (String, StimulusError) {
    let (path, result) = read_csv_text(tag, text);
    let e = result.expect_err("bad CSV must be an error");
    let msg = e.to_string();
    let file = path.file_name().unwrap().to_string_lossy().into_owned();
    assert!(msg.contains(&file), "`{msg}` does not name {file}");
    (msg, e)
}

#[test]
fn bad_csv_files_give_errors_naming_file_line_and_column() {
    let (msg, e) = csv_error("empty", "");
    assert!(matches!(e, StimulusError::Empty { .. }), "{msg}");

    let (msg, e) = csv_error("header-only", "key_mm\n");
    assert!(matches!(e, StimulusError::Empty { .. }), "{msg}");
    assert!(msg.contains("no samples"), "{msg}");

    let (msg, e) = csv_error("unknown-header", "position\n1\n");
    assert!(matches!(e, StimulusError::Header { .. }), "{msg}");
    assert!(msg.contains("`position`"), "{msg}");
    assert!(msg.contains("key_mm"), "{msg}");

    let (msg, e) = csv_error("not-a-number", "key_mm\n1\n2\nabc\n");
    assert!(matches!(e, StimulusError::Cell { line: 4, .. }), "{msg}");
    assert!(msg.contains(":4:") && msg.contains("`key_mm`") && msg.contains("`abc`"));

    let (msg, _) = csv_error("nan", "# comment\ntime_s,key_mm\n0,1\nNaN,2\n");
    assert!(msg.contains(":4:") && msg.contains("`time_s`"), "{msg}");

    let (msg, e) = csv_error("empty-cell", "time_s,key_mm\n0,1\n0.1,\n");
    assert!(matches!(e, StimulusError::Cell { line: 3, .. }), "{msg}");
    assert!(msg.contains("`key_mm`"), "{msg}");

    let (msg, e) = csv_error("decreasing", "time_s,key_mm\n0,1\n0.2,2\n0.1,3\n");
    assert!(
        matches!(e, StimulusError::NotIncreasing { line: 4, .. }),
        "{msg}"
    );

    let (msg, e) = csv_error("ragged", "time_s,key_mm\n0,1\n0.1\n");
    assert!(matches!(e, StimulusError::Csv { .. }), "{msg}");
    assert!(msg.contains(":3:"), "{msg}");

    let (msg, e) = csv_error("huge-span", "time_s,key_mm\n0,1\n1e12,2\n");
    assert!(matches!(e, StimulusError::TooLong { .. }), "{msg}");
}

#[test]
fn missing_csv_file_is_an_io_error_naming_it() {
    let path = temp_path("does-not-exist");
    let e = from_csv(&path, FS).unwrap_err();
    assert!(matches!(e, StimulusError::Io { .. }));
    assert!(e.to_string().contains(&*path.to_string_lossy()), "{e}");
}

#[test]
fn csv_from_a_spreadsheet_with_bom_and_crlf_is_read() {
    let (_, s) = read_csv_text("bom-crlf", "\u{feff}key_mm\r\n0\r\n2.5\r\n10\r\n");
    let s = s.unwrap();
    assert_eq!(s.key, vec![0.0, 0.0025, 0.010]);
}
