//! `tactus budget` as a user meets it: verdicts and exit codes, the worst key named, what
//! fits, the JSON document, and clear errors on bad input. The runs use `--quick` (a
//! smaller measurement corpus; the static figures and the verdict are the same) to keep
//! the debug-build tests fast. No cycle count is hard-coded: the Thumb backend's code
//! changes; every expectation is derived from the command's own figures.

mod common;
use common::{assert_ok, tactus, temp_dir};
use serde_json::Value;

fn budget(args: &[&str]) -> std::process::Output {
    tactus().arg("budget").args(args).output().unwrap()
}

fn json(args: &[&str]) -> (Option<i32>, Value) {
    let mut a = args.to_vec();
    a.push("--json");
    let out = budget(&a);
    let v: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "--json is not JSON ({e}): {}\nstderr: {}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (out.status.code(), v)
}

fn n(v: &Value) -> u64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}")) as u64
}

/// 88 piano keys on a 20 MHz RP2040 (453 cycles per sample): not even one key fits a
/// board, so every planned board is over budget — exit 1, naming the most expensive key
/// (MIDI number and note) with its worst path, and what would fit.
#[test]
fn a_heavy_keyboard_is_rejected_naming_the_worst_key() {
    let out = budget(&[
        "grand_piano",
        "--keys",
        "88",
        "--board",
        "boards/rp2040_20mhz.toml",
        "--quick",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(
        stdout.contains("DOES NOT FIT — 88 of 88 boards over budget"),
        "{stdout}"
    );
    assert!(stdout.contains("most expensive key: 21 (A0)"), "{stdout}");
    assert!(stdout.contains("its worst path"), "{stdout}");
    assert!(
        stdout.contains("passes: grand_piano line ") || stdout.contains("passes: escapement line "),
        "{stdout}"
    );
    // Not "0 keys … need 0 boards": it fits no such board, and why.
    assert!(
        stdout.contains("grand_piano fits no rp2040-20mhz board: core 0's sample interrupt needs"),
        "{stdout}"
    );
    assert!(
        stdout.contains("what fits on one rp2040-20mhz board:\n  grand_piano: no key fits one rp2040-20mhz board"),
        "{stdout}"
    );
    assert!(!stdout.contains("BUG"), "{stdout}");
}

/// The JSON document is consistent with itself: every key is on exactly one core of one
/// board, the boards are contiguous key ranges in order, each core's static bound is at
/// least the empty interrupt plus its keys' updates and at most that plus their glue and
/// contention (the image shares a core's set-up among its keys), measured ≤ static, and
/// the verdict and the exit code agree with the headrooms.
#[test]
fn json_parses_and_adds_up() {
    // More harpsichord keys than one board holds (what fits, from the budget itself), so
    // the plan has boards to add up.
    let (_, one) = json(&["harpsichord", "--keys", "1", "--quick"]);
    let per_board = n(&one["what_fits"][0]["keys_per_board"]);
    assert!(per_board >= 1, "{one}");
    let count = per_board + per_board / 2 + 1;
    let (code, v) = json(&["harpsichord", "--keys", &count.to_string(), "--quick"]);
    let b = &v["board"];
    let cps = n(&b["cycles_per_sample"]);
    // The shortest interval between the cores' SysTick ticks: ⌊clock/fs⌋ cycles.
    assert_eq!(cps, n(&b["clock_hz"]) / n(&b["sample_rate_hz"]));
    let isr = n(&b["isr_cycles"]);
    assert!(isr > 15 && isr < cps, "{b}");
    let p = &v["programs"][0];
    let (st, me, glue) = (
        n(&p["static_cycles"]),
        n(&p["measured_max"]),
        n(&p["glue_cycles"]),
    );
    assert!(me <= st && me > 0, "{p}");
    assert!(glue > 0 && glue < st, "{p}");
    assert_eq!(p["sound"], Value::Bool(true));
    assert!(p["measured_mean"].as_f64().unwrap() <= me as f64);
    let boards = v["boards"].as_array().unwrap();
    assert_eq!(n(&v["board_count"]) as usize, boards.len());
    assert!(
        boards.len() >= 2,
        "{count} harpsichord keys take more than one board: {v}"
    );
    let mut keys: Vec<u64> = Vec::new();
    for bd in boards {
        let on: Vec<u64> = bd["keys"].as_array().unwrap().iter().map(n).collect();
        assert!(
            on.windows(2).all(|w| w[1] == w[0] + 1),
            "contiguous: {on:?}"
        );
        let mut on_cores: Vec<u64> = Vec::new();
        let cores = bd["cores"].as_array().unwrap();
        assert_eq!(cores.len() as u64, n(&b["cores"]));
        for c in cores {
            let k = c["keys"].as_array().unwrap();
            on_cores.extend(k.iter().map(n));
            let cycles = n(&c["cycles"]);
            let nk = k.len() as u64;
            assert!(cycles >= isr + nk * st, "{c}");
            assert!(
                cycles <= isr + nk * (st + glue) + n(&c["contention"]),
                "{c}"
            );
            assert_eq!(
                c["headroom"].as_f64().unwrap() as i64,
                cps as i64 - cycles as i64
            );
        }
        on_cores.sort();
        assert_eq!(on_cores, on);
        keys.extend(on);
    }
    assert_eq!(keys, (21..21 + count).collect::<Vec<u64>>());
    let fits = boards.iter().all(|bd| {
        bd["cores"]
            .as_array()
            .unwrap()
            .iter()
            .all(|c| c["headroom"].as_f64().unwrap() >= 0.0)
    });
    assert_eq!(v["fits"], Value::Bool(fits));
    assert_eq!(code, Some(if fits { 0 } else { 1 }));
    assert_eq!(v["worst_key"]["note"], "A0");
    // "What fits" prices a key as its densest board builds it: with the guard's glue, or
    // without when that board leaves the guard out (and then says so).
    let wf = &v["what_fits"][0];
    assert_eq!(n(&wf["guarded_cycles_per_key"]), st + glue);
    if wf["guard_off"] == Value::Bool(true) {
        assert!(n(&wf["cycles_per_key"]) < st + glue, "{wf}");
    } else {
        assert_eq!(n(&wf["cycles_per_key"]), st + glue);
    }
}

/// "What fits" is exact: that many keys take one board, one more takes two.
#[test]
fn what_fits_fits_and_one_more_does_not() {
    let (_, v) = json(&["harpsichord", "--keys", "1", "--quick"]);
    let max = n(&v["what_fits"][0]["keys_per_board"]);
    assert!(max >= 2, "{v}");
    let (code, v) = json(&["harpsichord", "--keys", &max.to_string(), "--quick"]);
    assert_eq!((code, n(&v["board_count"])), (Some(0), 1), "{v}");
    let (code, v) = json(&["harpsichord", "--keys", &(max + 1).to_string(), "--quick"]);
    assert_eq!((code, n(&v["board_count"])), (Some(0), 2), "{v}");
}

/// A layout with two instruments and a graded param: one program per param set, each
/// measured (the costliest fully, the others briefly) and sound; keys as the layout says;
/// `--write-plan` writes a layout whose boards, read back, give the same verdict.
#[test]
fn a_small_split_layout_with_grading() {
    let dir = temp_dir("budget-split");
    let f = dir.join("split.toml");
    std::fs::write(
        &f,
        "name = \"mini\"\n[[range]]\nkeys = [60, 61]\ninstrument = \"harpsichord_2x8\"\n\
         [[range]]\nkeys = [62, 64]\ninstrument = \"grand_piano\"\n\
         grade = [ { param = \"M_h\", from = \"6 g\", to = \"3.5 g\" } ]\n",
    )
    .unwrap();
    let plan = dir.join("plan/mini-boards.toml");
    let (code, v) = json(&[
        f.to_str().unwrap(),
        "--quick",
        "--write-plan",
        plan.to_str().unwrap(),
    ]);
    assert_eq!(v["layout"], "mini");
    assert_eq!(v["planned"], Value::Bool(true));
    let programs = v["programs"].as_array().unwrap();
    assert_eq!(programs.len(), 1 + 3, "{v}");
    for p in programs {
        assert_eq!(p["sound"], Value::Bool(true), "{p}");
        assert!(n(&p["measured_max"]) <= n(&p["static_cycles"]));
    }
    let pianos: Vec<&Value> = programs
        .iter()
        .filter(|p| p["instrument"] == "grand_piano")
        .collect();
    assert_eq!(pianos.len(), 3);
    assert_eq!(pianos[0]["params"]["M_h"], "6 g");
    assert_eq!(
        pianos.iter().filter(|p| p["corpus"] == "quick").count(),
        1,
        "the costliest variant gets the larger corpus"
    );
    // The piano is the most expensive instrument: the worst key is one of its keys.
    let wk = n(&v["worst_key"]["key"]);
    assert!((62..=64).contains(&wk), "{v}");
    assert_eq!(
        code,
        Some(if v["fits"] == Value::Bool(true) { 0 } else { 1 })
    );
    // The plan, read back: the same boards, listed rather than planned.
    let text = std::fs::read_to_string(&plan).unwrap();
    assert!(
        text.contains("[[board]]") && text.contains("board_kind"),
        "{text}"
    );
    let (code2, v2) = json(&[plan.to_str().unwrap(), "--quick"]);
    assert_eq!(code2, code);
    assert_eq!(v2["planned"], Value::Bool(false));
    assert_eq!(v2["boards"], v["boards"], "{text}");
}

/// A listed board over budget is reported as such (exit 1), naming the board (ten piano
/// keys: five per core, where four fit).
#[test]
fn a_listed_board_over_budget_does_not_fit() {
    let dir = temp_dir("budget-over");
    let f = dir.join("over.toml");
    std::fs::write(
        &f,
        "name = \"over\"\n[[range]]\nkeys = [60, 71]\ninstrument = \"grand_piano\"\n\
         [[board]]\nkeys = [60, 61]\n[[board]]\nkeys = [62, 71]\n",
    )
    .unwrap();
    let out = budget(&[f.to_str().unwrap(), "--quick"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(stdout.contains("listed rp2040 boards"), "{stdout}");
    assert!(
        stdout.contains("DOES NOT FIT — 1 of 2 boards over budget"),
        "{stdout}"
    );
    // Ten piano keys: five on a core, over its budget (six fit since session 14's
    // cheaper products and glue; eight since issue 38's distributed constants).
    assert!(stdout.contains("board 2 (62–71"), "{stdout}");
}

#[test]
fn bad_input_exits_2_with_a_clear_message() {
    let dir = temp_dir("budget-bad");
    let err = |args: &[&str]| {
        let out = budget(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {out:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let e = err(&["no/such/layout.toml"]);
    assert!(
        e.contains("no/such/layout.toml") && e.contains("cannot read"),
        "{e}"
    );
    let typo = dir.join("typo.toml");
    std::fs::write(
        &typo,
        "name = \"x\"\n[[range]]\nkeys = [60, 61]\ninstrumnt = \"grand_piano\"\n",
    )
    .unwrap();
    let e = err(&[typo.to_str().unwrap()]);
    assert!(e.contains("typo.toml") && e.contains("instrumnt"), "{e}");
    let board = dir.join("board.toml");
    std::fs::write(
        &board,
        "name = \"b\"\nclock_hz = 133e6\ncores = 0\nsample_rate_hz = 44100\n",
    )
    .unwrap();
    let e = err(&["hammond", "--board", board.to_str().unwrap()]);
    assert!(e.contains("board.toml") && e.contains("cores"), "{e}");
    let e = err(&["hammond", "--board", "no-such-board"]);
    assert!(e.contains("no-such-board") && e.contains("rp2040"), "{e}");
    let e = err(&["no_such_instrument"]);
    assert!(e.contains("no_such_instrument"), "{e}");
    let e = err(&["hammond", "--keys", "0"]);
    assert!(e.contains("--keys"), "{e}");
    let e = err(&["instruments/layouts/grand88.toml", "--keys", "3"]);
    assert!(e.contains("--keys"), "{e}");
    let unknown = dir.join("unknown.toml");
    std::fs::write(
        &unknown,
        "name = \"x\"\n[[range]]\nkeys = [60, 61]\ninstrument = \"violin\"\n",
    )
    .unwrap();
    let e = err(&[unknown.to_str().unwrap()]);
    assert!(e.contains("unknown.toml") && e.contains("violin"), "{e}");
    // Boards: overlapping, a key on none, an unknown board kind; a path that does not exist.
    let layout = |name: &str, tail: &str| {
        let p = dir.join(name);
        std::fs::write(
            &p,
            format!("name = \"x\"\n[[range]]\nkeys = [60, 63]\ninstrument = \"hammond\"\n{tail}"),
        )
        .unwrap();
        p
    };
    let p = layout(
        "overlap.toml",
        "[[board]]\nkeys = [60, 62]\n[[board]]\nkeys = [62, 63]\n",
    );
    let e = err(&[p.to_str().unwrap()]);
    assert!(e.contains("overlap.toml") && e.contains("overlap"), "{e}");
    let p = layout("gap.toml", "[[board]]\nkeys = [60, 61]\n");
    let e = err(&[p.to_str().unwrap()]);
    assert!(e.contains("gap.toml") && e.contains("no board"), "{e}");
    let p = dir.join("kind.toml");
    std::fs::write(
        &p,
        "name = \"x\"\nboard_kind = \"pdp11\"\n[[range]]\nkeys = [60, 63]\ninstrument = \"hammond\"\n",
    )
    .unwrap();
    let e = err(&[p.to_str().unwrap()]);
    assert!(
        e.contains("kind.toml") && e.contains("board_kind") && e.contains("pdp11"),
        "{e}"
    );
    let p = layout("x.toml", "").with_file_name("path.toml");
    std::fs::write(
        &p,
        "name = \"x\"\n[[range]]\nkeys = [60, 63]\ninstrument = \"no/such/hammond.tactus\"\n",
    )
    .unwrap();
    let e = err(&[p.to_str().unwrap()]);
    assert!(e.contains("path.toml") && e.contains("no such file"), "{e}");
    // A param value outside what the instrument requires: the diagnostics, then the key.
    let p = dir.join("param.toml");
    std::fs::write(
        &p,
        "name = \"x\"\n[[range]]\nkeys = [60, 61]\ninstrument = \"grand_piano\"\nparams = { M_h = \"-5 g\" }\n",
    )
    .unwrap();
    let e = err(&[p.to_str().unwrap()]);
    assert!(
        e.contains("param.toml") && e.contains("key 60") && e.contains("M_h=-5 g"),
        "{e}"
    );
    // A grading that leaves the declared range (`require M_h <= 20 g`) at one end: the
    // key at that end, with its graded value.
    let p = dir.join("grade.toml");
    std::fs::write(
        &p,
        "name = \"x\"\n[[range]]\nkeys = [60, 62]\ninstrument = \"grand_piano\"\ngrade = [ { param = \"M_h\", from = \"3.5 g\", to = \"25 g\" } ]\n",
    )
    .unwrap();
    let e = err(&[p.to_str().unwrap()]);
    assert!(
        e.contains("grade.toml")
            && e.contains("key 62")
            && e.contains("M_h=25 g")
            && e.contains("requirement not met"),
        "{e}"
    );
}

#[test]
fn help_explains_the_figures_and_exit_codes() {
    let out = tactus().args(["budget", "--help"]).output().unwrap();
    assert_ok(&out);
    let s = String::from_utf8_lossy(&out.stdout);
    for w in [
        "static",
        "measured",
        "boards",
        "Exit codes",
        "--keys",
        "--json",
    ] {
        assert!(s.contains(w), "{w}: {s}");
    }
}

/// A pen instrument is budgeted as one pen by default, its per-pen firmware glue measured
/// from the image (two sensor words and three DAC words cost more than a keyboard key's one
/// and one), and the verdict counts pens.
#[test]
fn a_pen_is_budgeted_as_one_pen_with_its_own_glue() {
    let out = budget(&["rubbed_bank", "--quick"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("rubbed_bank × 1 (rubbed_bank): 1 pen on planned"),
        "{stdout}"
    );
    let line = stdout
        .lines()
        .find(|l| l.starts_with("most expensive pen (slot "))
        .unwrap_or_else(|| panic!("{stdout}"));
    let io: u64 = line
        .rsplit("glue ")
        .next()
        .and_then(|x| x.trim().parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    let key = budget(&["hammond", "--keys", "1", "--quick"]);
    let key_out = String::from_utf8_lossy(&key.stdout);
    let key_io: u64 = key_out
        .lines()
        .find(|l| l.starts_with("most expensive key:"))
        .and_then(|l| l.rsplit("glue ").next())
        .and_then(|x| x.trim().parse().ok())
        .unwrap_or_else(|| panic!("{key_out}"));
    assert!(io > key_io, "pen glue {io} cycles, a key's {key_io}");
    assert!(
        stdout.contains("rubbed_bank: no pen fits one rp2040 board"),
        "{stdout}"
    );
}

/// `--write-plan` keeps the `--param` overrides: the plan alone budgets the keys the run
/// budgeted (the override replaces a grade of the same param).
#[test]
fn a_plan_keeps_the_param_overrides() {
    let dir = temp_dir("budget-plan-params");
    let plan = dir.join("plan.toml");
    let (code, v) = json(&[
        "grand88",
        "--quick",
        "--param",
        "M_h=9 g",
        "--write-plan",
        plan.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&plan).unwrap();
    assert!(
        text.contains("M_h = \"9 g\"") && !text.contains("grade"),
        "{text}"
    );
    // One hammer mass on every key: one program.
    assert_eq!(v["programs"].as_array().unwrap().len(), 1, "{v}");
    assert_eq!(v["programs"][0]["params"]["M_h"], "9 g");
    let (code2, v2) = json(&[plan.to_str().unwrap(), "--quick"]);
    assert_eq!(code2, code);
    assert_eq!(v2["programs"][0]["params"], v["programs"][0]["params"]);
    assert_eq!(v2["boards"], v["boards"], "{text}");
}
