//! Issue 73: a corpus run split into shards (`tactus play CORPUS --shard K/N`, or a
//! scheduler's index) and merged (`tactus corpus merge`) gives the tables one machine's run
//! writes; a merge of shards that are not one whole run is refused, naming what is wrong; a
//! task killed mid-item and resumed gives the same tables.
//!
//! The corpus is generated here (short MIDI files), played on the host's f64 JIT
//! (`--engine jit`: what is checked is the bookkeeping around the pieces, the same for every
//! engine; `tests/slurm.rs` runs the firmware on the emulated boards through a real Slurm).

mod common;
use common::{assert_ok, small_layout, tactus, temp_dir, without_timings, write_midi};
use std::path::{Path, PathBuf};
use std::process::Output;

/// Six short pieces on grand88's keys: a few notes each, at other keys, velocities and
/// times (`b.mid` the longest, 30 s of a repeated figure, with `long`).
fn corpus(dir: &Path, long: bool) -> PathBuf {
    let c = dir.join("corpus");
    std::fs::create_dir_all(&c).unwrap();
    for (i, name) in ["a", "b", "c", "d", "e", "f"].iter().enumerate() {
        let base = 40 + 7 * i as u8;
        let bars = if long && *name == "b" { 60 } else { 2 };
        let notes: Vec<(u8, u8, f64, f64)> = (0..bars * 3)
            .map(|j| {
                let t = 0.3 + 0.5 * j as f64 / 3.0 * (1.0 + 0.1 * i as f64);
                (
                    base + (j % 5) as u8,
                    40 + ((j * 13 + i) % 80) as u8,
                    t,
                    t + 0.12,
                )
            })
            .collect();
        write_midi(&c.join(format!("{name}.mid")), &notes, &[]);
    }
    c
}

fn play(corpus: &Path, out: &Path, extra: &[&str]) -> Output {
    tactus()
        .args(["play", "--engine", "jit", "--no-wav"])
        .arg(corpus)
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

fn merge(inputs: &[&Path], out: &Path) -> Output {
    tactus()
        .args(["corpus", "merge"])
        .args(inputs)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The tables of `a` and `b` (directories) are the same but for timings.
fn same_tables(a: &Path, b: &Path) {
    for t in ["corpus.csv", "corpus.json"] {
        assert_eq!(
            without_timings(&a.join(t)),
            without_timings(&b.join(t)),
            "{t}: {} against {}",
            a.display(),
            b.display()
        );
    }
}

/// The merge of N shards (N = 1, 2, 3), given in any order, writes the single run's tables
/// (every figure but the timings byte for byte: strikes, silent notes, music seconds) and
/// its verdict; every shard's strikes file is the single run's. Two keyboards (grand88 and
/// a small layout of its piano) make twelve items, each in its own folder.
#[test]
fn the_merge_of_n_shards_is_the_single_machine_run() {
    let dir = temp_dir("corpus-shards");
    let c = corpus(&dir, false);
    let small = small_layout(&dir, 40, 80);
    let keyboards = ["--layout", "grand88", "--layout", small.to_str().unwrap()];
    let single = dir.join("single");
    let out = play(&c, &single, &keyboards);
    assert_ok(&out);
    let rows = std::fs::read_to_string(single.join("corpus.csv")).unwrap();
    assert_eq!(rows.lines().count(), 13, "{rows}");
    assert!(single.join("small-default/b-strikes.csv").exists());
    for n in 1..=3u32 {
        let shards: Vec<PathBuf> = (1..=n)
            .map(|k| {
                let o = dir.join(format!("shards-{n}/task-{k}"));
                let out = play(
                    &c,
                    &o,
                    &[&keyboards[..], &["--shard", &format!("{k}/{n}")]].concat(),
                );
                assert_ok(&out);
                o
            })
            .collect();
        // Every item in exactly one shard.
        let items: usize = shards
            .iter()
            .map(|o| {
                let f = o.join(if n == 1 {
                    "results.jsonl".to_string()
                } else {
                    format!(
                        "results-{}-of-{n}.jsonl",
                        o.file_name()
                            .unwrap()
                            .to_str()
                            .unwrap()
                            .trim_start_matches("task-")
                    )
                });
                std::fs::read_to_string(f).unwrap().lines().count() - 1
            })
            .sum();
        assert_eq!(items, 12, "{n} shards");
        // Given in reverse, and rotated.
        for order in [
            shards.iter().rev().collect::<Vec<_>>(),
            shards.iter().cycle().skip(1).take(shards.len()).collect(),
        ] {
            let merged = dir.join(format!("merged-{n}"));
            let paths: Vec<&Path> = order.iter().map(|p| p.as_path()).collect();
            let out = merge(&paths, &merged);
            assert_ok(&out);
            same_tables(&single, &merged);
        }
        // The strikes of every piece, whichever task played it, are the single run's.
        for kb in ["grand88-default", "small-default"] {
            for p in ["a", "b", "c", "d", "e", "f"] {
                let name = format!("{kb}/{p}-strikes.csv");
                let by_shard: Vec<String> = shards
                    .iter()
                    .filter_map(|o| std::fs::read_to_string(o.join(&name)).ok())
                    .collect();
                assert_eq!(by_shard.len(), 1, "{name}: played by one shard of {n}");
                assert_eq!(
                    by_shard[0],
                    std::fs::read_to_string(single.join(&name)).unwrap()
                );
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A merge refuses, exit 2, naming the culprit: a missing shard, a shard given twice,
/// shards of different runs, an item missing from its shard's file; and says "the firmware
/// failed validation" with exit 1 when a row left a note without a strike.
#[test]
fn a_merge_names_what_is_missing_duplicated_or_different() {
    let dir = temp_dir("corpus-refusals");
    let c = corpus(&dir, false);
    let shard = |k: u32, extra: &[&str]| {
        let o = dir.join(format!("task-{k}{}", extra.join("")));
        assert_ok(&play(
            &c,
            &o,
            &[&["--shard", &format!("{k}/3")], extra].concat(),
        ));
        o
    };
    let (s1, s2, s3) = (shard(1, &[]), shard(2, &[]), shard(3, &[]));
    let out = dir.join("merged");
    let refused = |inputs: &[&Path], says: &str| {
        let o = merge(inputs, &out);
        assert_eq!(o.status.code(), Some(2), "{says}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{says}: {}", stderr(&o));
    };
    refused(&[&s1, &s3], "1 of 3 shards missing: 2/3");
    let copy = dir.join("copy");
    std::fs::create_dir_all(&copy).unwrap();
    std::fs::copy(
        s2.join("results-2-of-3.jsonl"),
        copy.join("results-2-of-3.jsonl"),
    )
    .unwrap();
    refused(&[&s1, &s2, &copy, &s3], "shard 2/3 is given twice");
    // Another --seconds: another run.
    let other = shard(2, &["--seconds", "1"]);
    refused(
        &[&s1, &other, &s3],
        "not shards of one run: manifest.options.seconds: null ≠ 1.0",
    );
    // An item dropped from its shard's file (as a task killed before it would leave it).
    let f = s3.join("results-3-of-3.jsonl");
    let text = std::fs::read_to_string(&f).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    assert!(lines.len() >= 2, "shard 3/3 holds an item: {text}");
    let mut dropped: serde_json::Value = serde_json::from_str(&lines.remove(1)).unwrap();
    let piece = dropped["key"]["piece"].as_str().unwrap().to_string();
    std::fs::write(&f, lines.join("\n") + "\n").unwrap();
    refused(
        &[&s1, &s2, &s3],
        &format!("1 of 6 items missing: {piece} (shard 3/3)"),
    );
    // Restored, but with a note left without a strike: validation failed, exit 1.
    dropped["row"]["silent"] = 1.into();
    lines.insert(1, dropped.to_string());
    std::fs::write(&f, lines.join("\n") + "\n").unwrap();
    let o = merge(&[&s1, &s2, &s3], &out);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the firmware failed validation"),
        "{}",
        stderr(&o)
    );
    std::fs::write(&f, text).unwrap();
    assert_ok(&merge(&[&s1, &s2, &s3], &out));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--shard` of a bad form is a clear error, exit 2; a Slurm array task's and a Kubernetes
/// Indexed Job pod's variables give the shard `--shard` would.
#[test]
fn shards_come_from_the_flag_or_the_schedulers_variables() {
    for (bad, says) in [
        ("3/2", "K must be at most N"),
        ("0/0", "must be at least 1"),
        ("a/b", "expected K/N"),
    ] {
        let o = tactus()
            .args(["play", "x.mid", "--shard", bad])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{bad}");
        assert!(stderr(&o).contains(says), "{bad}: {}", stderr(&o));
    }
    let dir = temp_dir("corpus-env");
    let c = corpus(&dir, false);
    let lines = |o: &Path, f: &str| std::fs::read_to_string(o.join(f)).unwrap();
    let flag = dir.join("flag");
    assert_ok(&play(&c, &flag, &["--shard", "2/3"]));
    // Slurm, an array --array=1-3: task 2 is shard 2/3.
    let slurm = dir.join("slurm");
    let o = tactus()
        .args(["play", "--engine", "jit", "--no-wav"])
        .arg(&c)
        .arg("-o")
        .arg(&slurm)
        .envs([
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_MAX", "3"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ])
        .output()
        .unwrap();
    assert_ok(&o);
    assert!(String::from_utf8_lossy(&o.stdout).contains("shard 2/3 (SLURM_ARRAY_TASK_ID=2"));
    let strip = |t: String| -> Vec<String> {
        // The items done, without their timings.
        t.lines()
            .skip(1)
            .map(|l| {
                let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
                v["row"]["wall_s"] = 0.into();
                v["row"]["rtf"] = 0.into();
                v.to_string()
            })
            .collect()
    };
    let want = strip(lines(&flag, "results-2-of-3.jsonl"));
    assert_eq!(strip(lines(&slurm, "results-2-of-3.jsonl")), want);
    // Kubernetes: JOB_COMPLETION_INDEX=1 (from 0) of --shard-count 3.
    let k8s = dir.join("k8s");
    let o = tactus()
        .args(["play", "--engine", "jit", "--no-wav", "--shard-count", "3"])
        .arg(&c)
        .arg("-o")
        .arg(&k8s)
        .env("JOB_COMPLETION_INDEX", "1")
        .output()
        .unwrap();
    assert_ok(&o);
    assert_eq!(strip(lines(&k8s, "results-2-of-3.jsonl")), want);
    // Without the count the index means nothing: exit 2.
    let o = tactus()
        .args(["play", "--engine", "jit"])
        .arg(&c)
        .env("JOB_COMPLETION_INDEX", "1")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--shard-count"), "{}", stderr(&o));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A task killed while it plays an item leaves its results file whole (the items before,
/// no half line); `--resume` plays only the items it lacks, and the tables are those of a
/// run never killed.
#[test]
fn a_task_killed_mid_item_and_resumed_gives_the_same_tables() {
    let dir = temp_dir("corpus-resume");
    let c = corpus(&dir, true);
    let whole = dir.join("whole");
    assert_ok(&play(&c, &whole, &[]));
    let out = dir.join("killed");
    let mut child = tactus()
        .args(["play", "--engine", "jit", "--no-wav"])
        .arg(&c)
        .arg("-o")
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Killed (SIGKILL: no clean-up) as soon as the first item, a.mid, is written: b.mid,
    // 30 s of music, is being played.
    let results = out.join("results.jsonl");
    let started = std::time::Instant::now();
    loop {
        let n = std::fs::read_to_string(&results).map_or(0, |t| t.lines().count());
        if n >= 2 || started.elapsed().as_secs() > 120 {
            break;
        }
        if let Ok(Some(_)) = child.try_wait() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let text = std::fs::read_to_string(&results).unwrap();
    let done = text.lines().count() - 1;
    assert!(text.ends_with('\n'), "a half line: {text}");
    assert!((1..6).contains(&done), "killed after {done} of 6 items");
    assert!(!out.join("corpus.csv").exists());
    let o = play(&c, &out, &["--resume"]);
    assert_ok(&o);
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(
        said.contains(&format!(
            "{done} done before (--resume), {} to play",
            6 - done
        )),
        "{said}"
    );
    same_tables(&whole, &out);
    // Resuming a finished run plays nothing and writes the same tables.
    assert_ok(&play(&c, &out, &["--resume"]));
    same_tables(&whole, &out);
    // Resuming with other options is refused: exit 2, the file kept.
    let o = play(&c, &out, &["--resume", "--seconds", "1"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("results of another run"),
        "{}",
        stderr(&o)
    );
    let _ = std::fs::remove_dir_all(&dir);
}
