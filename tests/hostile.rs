//! Hostile input through the CLI (issue 19): every command on malformed or adversarial
//! files runs under `ulimit -v 4000000` (4 GB of address space) and a 60 s `timeout`, and
//! ends with exit 0 and a correct result, or exit 1/2 and a message on stderr — never a
//! signal (stack overflow, abort on a failed allocation), never the timeout. Each case is
//! also the regression test of its class: a small input that used to fail, and the clean
//! outcome now (the expected message).

mod common;
use common::temp_dir;
use std::path::Path;
use std::process::Output;

/// Runs the `tactus` binary with `args` in the repository root, bounded as the issue asks.
fn bounded(args: &[&str]) -> Output {
    let mut script = String::from("ulimit -v 4000000; exec timeout 60 \"$0\"");
    for i in 0..args.len() {
        script.push_str(&format!(" \"${{{}}}\"", i + 1));
    }
    std::process::Command::new("sh")
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_tactus"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap()
}

/// Runs and checks the outcome: `code` (0, 1 or 2), and `needle` in stderr (or stdout for
/// exit 0) when given. Returns stderr.
fn expect(args: &[&str], code: i32, needle: &str) -> String {
    let out = bounded(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let got = out.status.code();
    assert!(
        got.is_some() && got != Some(124),
        "{args:?} ended by a signal or the timeout ({:?}): {stderr}",
        out.status
    );
    assert_eq!(got, Some(code), "{args:?}: {stderr}{stdout}");
    if code != 0 {
        assert!(
            !stderr.trim().is_empty(),
            "{args:?}: exit {code} without a message"
        );
    }
    assert!(
        stderr.contains(needle) || stdout.contains(needle),
        "{args:?}: `{needle}` not in\n{stderr}{stdout}"
    );
    stderr
}

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> String {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p.display().to_string()
}

const KEY: &str = "instrument t {\n    sensor key: m in [0 mm, 10 mm]\n";

#[test]
fn class_1_deep_source_is_a_diagnostic_and_nested_components_compile() {
    let dir = temp_dir("hostile-1");
    // A sum of 20,000 terms overflowed the stack in `expand`.
    let terms = vec!["key * 1 N/m"; 20_000].join(" + ");
    let f = write(
        &dir,
        "sum.tactus",
        format!("{KEY}    force f = {terms}\n}}\n"),
    );
    expect(&["check", &f], 1, "E0008");
    // A 10 MB one-line file.
    let long = vec!["- "; 5_000_000].concat();
    let f = write(
        &dir,
        "long.tactus",
        format!("{KEY}    force f = {long}key * 1 N/m\n}}\n"),
    );
    expect(&["check", &f], 1, "E0008");
    // Components nested 12 deep were a false "uses itself" (E0116) at depth 8.
    let mut src = String::from("component c0 {\n    input x: m\n    force f = x * 1 N/m\n}\n");
    for i in 1..12 {
        src.push_str(&format!(
            "component c{i} {{\n    input x: m\n    use a = c{}(x = x)\n}}\n",
            i - 1
        ));
    }
    src.push_str(
        "instrument t {\n    sensor key: m in [0 mm, 10 mm]\n    use a = c11(x = key)\n}\n",
    );
    let f = write(&dir, "nested.tactus", &src);
    expect(&["check", &f], 0, "well-formed");
    // Real recursion through another component still is E0116, with the chain.
    let f = write(
        &dir,
        "cycle.tactus",
        "component a {\n    input x: m\n    use b = b(x = x)\n}\ncomponent b {\n    input x: m\n    use c = a(x = x)\n}\ninstrument t {\n    sensor key: m in [0 mm, 10 mm]\n    use a = a(x = key)\n}\n",
    );
    expect(&["check", &f], 1, "a → b → a");
}

#[test]
fn class_2_sizes_from_input_are_checked_before_allocation() {
    let dir = temp_dir("hostile-2");
    // 4096 × 4096 nested loops.
    let f = write(
        &dir,
        "loops.tactus",
        format!("{KEY}    for i in 0..4096 {{\n        for j in 0..4096 {{\n            let a[i * 4096 + j] = key\n        }}\n    }}\n    force f = key * 1 N/m\n}}\n"),
    );
    expect(&["check", &f], 1, "E0137");
    // A component of 12,000 nodes instanced 4096 times (each level uses the one below
    // twice): within the instance count, but 50 M nodes of IR.
    let mut src = String::from(
        "component c0 {\n    input x: m\n    force f = sum(i in 0..4096, x * 1 N/m)\n}\n",
    );
    for i in 1..13 {
        src.push_str(&format!(
            "component c{i} {{\n    input x: m\n    use a = c{p}(x = x)\n    use b = c{p}(x = x)\n}}\n",
            p = i - 1
        ));
    }
    src.push_str(
        "instrument t {\n    sensor key: m in [0 mm, 10 mm]\n    use a = c12(x = key)\n}\n",
    );
    let f = write(&dir, "wide.tactus", &src);
    expect(&["check", &f], 1, "E0136");
    // Empty loops nested three deep (no declarations to charge, 68 G iterations).
    let f = write(
        &dir,
        "empty.tactus",
        format!("{KEY}    for i in 0..4096 {{ for j in 0..4096 {{ for k in 0..4096 {{ }} }} }}\n    force f = key * 1 N/m\n}}\n"),
    );
    expect(&["check", &f], 1, "E0137");
    // A three-line CSV spanning 6000 s.
    let csv = write(&dir, "long.csv", "time_s,key_mm\n0,0\n6000,5\n");
    expect(
        &[
            "sim",
            "hammond",
            "--stimulus",
            &csv,
            "--out",
            &dir.display().to_string(),
        ],
        1,
        "limit",
    );
    // An ELF segment with p_memsz = 0xFFFFFFFF.
    let mut elf = vec![0x7f, b'E', b'L', b'F', 1, 1, 1, 0];
    elf.resize(16, 0);
    for h in [2u16, 40] {
        elf.extend(h.to_le_bytes());
    }
    for w in [1u32, 0x2000_0001, 52, 0, 0x0500_0000] {
        elf.extend(w.to_le_bytes());
    }
    for h in [52u16, 32, 1, 40, 0, 0] {
        elf.extend(h.to_le_bytes());
    }
    for w in [1u32, 84, 0x2000_0000, 0x2000_0000, 4, 0xFFFF_FFFF, 5, 4] {
        elf.extend(w.to_le_bytes());
    }
    elf.extend([0xfe, 0xe7, 0, 0]);
    let f = write(&dir, "huge.elf", elf);
    expect(&["emu", "run", &f], 1, "outside the RP2040");
}

/// A format-0 MIDI file: 480 ticks per quarter, one track of (delta, bytes) events.
fn midi(format: u16, tracks: u16, division: u16, events: &[(u32, &[u8])]) -> Vec<u8> {
    let mut t = Vec::new();
    for (d, msg) in events {
        let mut d = *d;
        let mut v = vec![(d & 0x7f) as u8];
        d >>= 7;
        while d > 0 {
            v.insert(0, 0x80 | (d & 0x7f) as u8);
            d >>= 7;
        }
        t.extend(v);
        t.extend(*msg);
    }
    t.extend([0, 0xff, 0x2f, 0]);
    let mut f = b"MThd\0\0\0\x06".to_vec();
    for h in [format, tracks, division] {
        f.extend(h.to_be_bytes());
    }
    f.extend(b"MTrk");
    f.extend((t.len() as u32).to_be_bytes());
    f.extend(t);
    f
}

#[test]
fn class_3_play_seconds_bounds_the_simulated_time() {
    let dir = temp_dir("hostile-3");
    let out = dir.display().to_string();
    // A note-off 0x0FFFFFFF ticks after its note-on hung the JIT engines and aborted emu.
    let f = write(
        &dir,
        "held.mid",
        midi(
            0,
            1,
            480,
            &[(0, &[0x90, 60, 100]), (0x0FFF_FFFF, &[0x80, 60, 0])],
        ),
    );
    // (`--engine emu` runs every board of the layout: two keys keep it to one board.)
    let layout = write(
        &dir,
        "two.toml",
        "name = \"two\"\n[[range]]\nkeys = [60, 61]\ninstrument = \"grand_piano\"\n",
    );
    for engine in ["jit", "emu"] {
        let err = expect(
            &[
                "play",
                &f,
                "--layout",
                &layout,
                "--seconds",
                "2",
                "--engine",
                engine,
                "--out",
                &out,
                "--no-wav",
            ],
            0,
            "2.00 s of music",
        );
        assert!(err.contains("held longer than 120 s"), "{err}");
    }
    // Two short notes 0x0FFFFFFF ticks (≈ 77 hours) apart, without --seconds: the emulated
    // run (every sample) would take days, the WAV allocate 49 GB; now each says what to do.
    let f = write(
        &dir,
        "gap.mid",
        midi(
            0,
            1,
            480,
            &[
                (0, &[0x90, 60, 100]),
                (480, &[0x80, 60, 0]),
                (0x0FFF_FFFF, &[0x90, 61, 100]),
                (480, &[0x80, 61, 0]),
            ],
        ),
    );
    expect(
        &[
            "play", &f, "--layout", &layout, "--engine", "emu", "--out", &out, "--no-wav",
        ],
        1,
        "--seconds",
    );
    expect(
        &["play", &f, "--engine", "jit", "--out", &out],
        1,
        "WAV rendering",
    );
}

#[test]
fn class_4_non_finite_values_are_errors() {
    let dir = temp_dir("hostile-4");
    let out = dir.display().to_string();
    for (name, body, code) in [
        (
            "nan",
            "    param k = 0 N/m / 0\n    force f = k * key\n",
            "E0312",
        ),
        (
            "big",
            "    param k = 1e309 N/m\n    force f = k * key\n",
            "E0006",
        ),
        (
            "exp",
            "    force f = exp(1000) * 1 N + key * 1 N/m\n",
            "E0312",
        ),
    ] {
        let f = write(&dir, &format!("{name}.tactus"), format!("{KEY}{body}}}\n"));
        expect(&["check", &f], 1, code);
        expect(&["sim", &f, "--out", &out], 1, code);
    }
    // `--param l1=0 mm` under a division.
    let f = write(
        &dir,
        "l1.tactus",
        format!(
            "{KEY}    param l1 = 2 mm\n    param k = 1 N / l1\n    force f = k * key / 1 m\n}}\n"
        ),
    );
    expect(&["check", &f, "--param", "l1=0 mm"], 1, "E0312");
    // A run-time NaN in the f64 engines: the first sample and the value, exit 1.
    let f = write(
        &dir,
        "rt.tactus",
        format!("{KEY}    force f = 1 N * exp(key / 1 um)\n}}\n"),
    );
    for engine in ["interp", "jit"] {
        expect(
            &["sim", &f, "--engine", engine, "--out", &out],
            1,
            "is inf at sample",
        );
    }
    // The same in `play`, on an instrument that strikes.
    let f = write(
        &dir,
        "rtplay.tactus",
        format!(
            "{KEY}    force f = 1 N * exp(key / 1 um)
    on key > 5 mm {{ emit strike(v = 1 m/s) }}
}}
"
        ),
    );
    for engine in ["interp", "jit"] {
        expect(
            &[
                "play",
                "--instrument",
                &f,
                "--engine",
                engine,
                "--seconds",
                "1",
                "--out",
                &out,
                "--no-wav",
            ],
            1,
            "non-finite value at sample",
        );
    }
}

#[test]
fn class_7_missing_files_are_never_replaced_by_built_ins() {
    expect(
        &["check", "/no/such/dir/grand_piano.tactus"],
        1,
        "no file `/no/such/dir/grand_piano.tactus`",
    );
    expect(&["check", "grand_piano"], 0, "well-formed");
    let dir = temp_dir("hostile-7");
    let layout = write(
        &dir,
        "layout.toml",
        "name = \"x\"\n[[range]]\nkeys = [60, 61]\ninstrument = \"missing/grand_piano.tactus\"\n",
    );
    let out = bounded(&["budget", &layout]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        matches!(out.status.code(), Some(1 | 2)),
        "{:?} {stderr}",
        out.status
    );
    assert!(stderr.contains("missing/grand_piano.tactus"), "{stderr}");
}

#[test]
fn class_8_corrupt_midi_and_csv_are_named() {
    let dir = temp_dir("hostile-8");
    let out = dir.display().to_string();
    let note: &[(u32, &[u8])] = &[(0, &[0x90, 60, 100]), (480, &[0x80, 60, 0])];
    for (name, bytes, msg) in [
        ("zero.mid", midi(0, 0, 480, note), "claims 0 tracks"),
        ("fmt2.mid", midi(2, 1, 480, note), "format 2"),
        ("div0.mid", midi(0, 1, 0, note), "division is 0"),
    ] {
        let f = write(&dir, name, bytes);
        let err = expect(&["play", &f, "--out", &out, "--no-wav"], 1, msg);
        assert!(err.contains(name), "{err}");
    }
    // Repaired reads: a warning with what was lost.
    let many = write(&dir, "many.mid", midi(1, 65535, 480, note));
    expect(
        &["play", &many, "--engine", "jit", "--out", &out, "--no-wav"],
        0,
        "claims 65535 tracks, the file holds 1",
    );
    let full = midi(0, 1, 480, note);
    let cut = write(&dir, "cut.mid", &full[..full.len() - 5]);
    let err = expect(
        &["play", &cut, "--engine", "jit", "--out", &out, "--no-wav"],
        0,
        "is truncated",
    );
    assert!(err.contains("1 notes have no note-off"), "{err}");
    // CSV: a byte-order mark is read; 1e300 mm is reported, not clamped silently.
    let bom = write(&dir, "bom.csv", "\u{feff}time_s,key_mm\n0,0\n0.05,3\n");
    expect(
        &["sim", "hammond", "--stimulus", &bom, "--out", &out],
        0,
        "total force",
    );
    let big = write(&dir, "big.csv", "time_s,key_mm\n0,0\n0.05,1e300\n");
    expect(
        &["sim", "hammond", "--stimulus", &big, "--out", &out],
        0,
        "outside sensor `key`'s range",
    );
    let pen = write(
        &dir,
        "pen.csv",
        "\u{feff}time [s], pen.z [m]\n0, 0\n0.05, 1e300\n",
    );
    expect(
        &["sim", "rubbed_bank", "--stimulus", &pen, "--out", &out],
        0,
        "were clamped",
    );
    // A `.tactus` file with a byte-order mark.
    let f = write(
        &dir,
        "bom.tactus",
        format!("\u{feff}{KEY}    force f = key * 1 N/m\n}}\n"),
    );
    expect(&["check", &f], 0, "well-formed");
}

#[test]
fn class_5_unstable_mass_spring_is_diagnosed() {
    let dir = temp_dir("hostile-5");
    let out = dir.display().to_string();
    // 1e12 N/m on 10 g: ω·T ≈ 227 at 44.1 kHz. Used to pass `check` and `sim` silently.
    let src = "instrument t {\n    sensor key: m in [0 mm, 10 mm]\n    param k = 1e12 N/m\n    param m = 10 g\n    state x: m = 0 mm in [-10 mm, 10 mm]\n    state v: m/s = 0 m/s in [-10 m/s, 10 m/s]\n    let spring = k * (key - x)\n    dynamics {\n        x' = v\n        v' = spring / m\n    }\n    force f = k * (x - key)\n}\n";
    let f = write(&dir, "osc.tactus", src);
    let err = expect(&["check", &f], 0, "W0003");
    assert!(err.contains("ω·T = 226.757"), "{err}");
    // The states sit on their range bounds: `sim` says so.
    let err = expect(&["sim", &f, "--out", &out], 0, "was saturated");
    assert!(err.contains("W0003"), "{err}");
    // A stiffness the sample rate can integrate gives no warning.
    let ok = write(&dir, "ok.tactus", src.replace("1e12 N/m", "100 N/m"));
    let err = expect(&["check", &ok], 0, "well-formed");
    assert!(!err.contains("W0003"), "{err}");
}

// Issue 36: the surfaces added since — board files, key maps, layouts and plans, play — and
// nothing that says FITS, "0 misses" or writes firmware when that is not so.

fn board_file(dir: &Path, name: &str, clock: &str, cores: u32, fs: u32) -> String {
    write(
        dir,
        name,
        format!("name = \"{name}\"\nclock_hz = {clock}\ncores = {cores}\nsample_rate_hz = {fs}\n"),
    )
}

#[test]
fn class_9_a_board_is_one_the_firmware_runs_on_or_bad_input() {
    let dir = temp_dir("hostile-9");
    let out = dir.display().to_string();
    // 133.3 MHz: no PLL_SYS setting makes it. `budget` said FITS, `play` ran it.
    let odd = board_file(&dir, "odd.toml", "133.3e6", 2, 44_100);
    expect(
        &[
            "budget", "hammond", "--keys", "4", "--board", &odd, "--quick",
        ],
        2,
        "`clock_hz`",
    );
    let fw = format!("{out}/fw");
    let err = expect(
        &[
            "build", "hammond", "--keys", "4", "--board", &odd, "--target", "rp2040", "-o", &fw,
        ],
        1,
        "no PLL_SYS setting",
    );
    assert!(err.contains("odd.toml"), "{err}");
    assert!(
        !Path::new(&fw).exists(),
        "firmware written for a board that cannot be built"
    );
    expect(
        &[
            "play",
            "--board",
            &odd,
            "--engine",
            "jit",
            "--out",
            &out,
            "--no-wav",
            "--seconds",
            "0.5",
        ],
        1,
        "`clock_hz`",
    );
    // 64 cores: the keys "needed 0 boards" (exit 1); the chip has two.
    let many = board_file(&dir, "many.toml", "133e6", 64, 44_100);
    expect(
        &[
            "budget", "hammond", "--keys", "4", "--board", &many, "--quick",
        ],
        2,
        "`cores`",
    );
    // The board's sample rate reaches the compiler: an instrument that requires 40 kHz is
    // refused on an 8 kHz board by every command (it compiled for 44.1 kHz before).
    let slow = board_file(&dir, "slow.toml", "133e6", 2, 8_000);
    write(
        &dir,
        "fs.tactus",
        "instrument fs {\n    sensor key: m in [0 mm, 10 mm]\n    require sample_rate >= 40 kHz\n    force f = key * 100 N/m\n    on key > 5 mm { emit strike(v = 1 m/s) }\n}\n",
    );
    let layout = write(
        &dir,
        "fs.toml",
        "name = \"fs\"\n[[range]]\nkeys = [60, 61]\ninstrument = \"fs.tactus\"\n",
    );
    let err = expect(
        &["budget", &layout, "--board", &slow, "--quick"],
        2,
        "8000 Hz",
    );
    assert!(err.contains("E0310"), "{err}");
    expect(
        &[
            "build", &layout, "--board", &slow, "--target", "rp2040", "-o", &fw,
        ],
        1,
        "8000 Hz",
    );
    assert!(!Path::new(&fw).exists());
    expect(
        &[
            "play", "--layout", &layout, "--board", &slow, "--engine", "jit", "--out", &out,
            "--no-wav",
        ],
        1,
        "8000 Hz",
    );
    // At 44.1 kHz the same layout is fine.
    expect(&["budget", &layout, "--quick"], 0, "FITS");
}

#[test]
fn class_10_a_key_map_is_checked_against_its_firmware() {
    let dir = temp_dir("hostile-10");
    let fw = dir.join("fw");
    expect(
        &[
            "build",
            "hammond",
            "--keys",
            "2",
            "--target",
            "rp2040",
            "-o",
            &fw.display().to_string(),
        ],
        0,
        "1 boards",
    );
    let elf = fw.join("board-01/firmware.elf").display().to_string();
    let good = std::fs::read_to_string(fw.join("board-01/keys.json")).unwrap();
    let run = |name: &str, map: &str, code: i32, needle: &str| {
        let f = write(&dir, name, map);
        expect(
            &[
                "emu",
                "run",
                &elf,
                "--stimulus",
                "mf-dip",
                "--keys",
                &f,
                "--seconds",
                "0.2",
            ],
            code,
            needle,
        )
    };
    run("good.json", &good, 0, "misses 0");
    let field = |from: &str, to: &str| {
        assert!(good.contains(from), "{from} not in the key map");
        good.replacen(from, to, 1)
    };
    // An absurd clock or start alarm allocated 3 GB; a 1 THz clock ran for ever.
    run(
        "clock.json",
        &field(
            "\"clock_hz\": 133000000",
            "\"clock_hz\": 18446744073709551615",
        ),
        1,
        "`clock_hz`",
    );
    run(
        "thz.json",
        &field("\"clock_hz\": 133000000", "\"clock_hz\": 1000000000000"),
        1,
        "`clock_hz`",
    );
    run(
        "pll.json",
        &field("\"clock_hz\": 133000000", "\"clock_hz\": 200000000"),
        1,
        "`period_cycles`",
    );
    let alarm = good
        .lines()
        .find(|l| l.contains("\"start_alarm_us\""))
        .unwrap()
        .trim()
        .trim_end_matches(',')
        .to_string();
    run(
        "alarm.json",
        &field(&alarm, "\"start_alarm_us\": 4294967295"),
        1,
        "`start_alarm_us`",
    );
    // A late start alarm counted 449,818 samples in a run of 8,820.
    run(
        "late.json",
        &field(&alarm, "\"start_alarm_us\": 500000"),
        1,
        "`start_alarm_us`",
    );
    // Keys that do not exist, an unmapped sample interrupt: 0 handler cycles, "0 misses".
    let json: serde_json::Value = serde_json::from_str(&good).unwrap();
    let mut ghost = json.clone();
    ghost["cores"][0]["keys"] = serde_json::json!([99]);
    run("ghost.json", &ghost.to_string(), 1, "cores[0].keys");
    let mut isr = json.clone();
    isr["cores"][0]["sample_isr"] = serde_json::json!("0x30000001");
    run("isr.json", &isr.to_string(), 1, "cores[0].sample_isr");
    let mut word = json.clone();
    word["keys"][0]["sensor_words"] = serde_json::json!(["0x2003f100"]);
    run("word.json", &word.to_string(), 1, "keys[0].sensor_words");
    let mut core = json;
    core["keys"][0]["core"] = serde_json::json!(7);
    run("core.json", &core.to_string(), 1, "keys[0].core");
}

#[test]
fn class_11_layouts_and_plans_are_whole() {
    let dir = temp_dir("hostile-11");
    let out = dir.display().to_string();
    // An empty layout built 0 boards and exited 0; `play` failed to plot.
    let empty = write(&dir, "empty.toml", "name = \"empty\"\nrange = []\n");
    for args in [
        vec!["build", &empty, "--target", "rp2040", "-o", &out],
        vec!["play", "--layout", &empty, "--engine", "jit", "--out", &out],
    ] {
        expect(&args, 1, "lists no keys");
    }
    expect(&["budget", &empty], 2, "lists no keys");
    // Every note off the layout: "cannot plot" before; now what is wrong.
    let off = write(
        &dir,
        "off.mid",
        midi(0, 1, 480, &[(0, &[0x90, 5, 100]), (480, &[0x80, 5, 0])]),
    );
    expect(
        &["play", &off, "--out", &out],
        1,
        "none of its 1 notes is on a key",
    );
    // A name with a newline: the plan did not read back.
    let nl = write(
        &dir,
        "nl.toml",
        "name = \"a\\nb\"\n[[range]]\nkeys = [60, 61]\ninstrument = \"hammond\"\n",
    );
    let plan = format!("{out}/plan.toml");
    expect(
        &["budget", &nl, "--quick", "--write-plan", &plan],
        0,
        "plan: 1 boards",
    );
    expect(&["budget", &plan, "--quick"], 0, "FITS on 1 board");
    // A grade beyond f64 was reported as `M_h=NaN g`.
    let big = write(
        &dir,
        "grade.toml",
        "name = \"g\"\n[[range]]\nkeys = [60, 61]\ninstrument = \"grand_piano\"\ngrade = [ { param = \"M_h\", from = \"1e400 g\", to = \"3 g\" } ]\n",
    );
    expect(
        &["budget", &big, "--quick"],
        2,
        "`from` = \"1e400 g\" is not a finite number",
    );
    // A board file of a megabyte and more is not read whole.
    let huge = write(&dir, "huge.toml", vec![b'#'; 2 << 20]);
    expect(&["budget", "hammond", "--board", &huge], 2, "longer than");
}

#[test]
fn class_12_fits_no_board_says_so_and_why() {
    let dir = temp_dir("hostile-12");
    // A piano key's update alone is over the 453 cycles of a 20 MHz board: "0 keys … need
    // 0 boards" before.
    let err = expect(
        &[
            "budget",
            "grand_piano",
            "--keys",
            "2",
            "--board",
            "rp2040_20mhz",
            "--quick",
        ],
        1,
        "fits no rp2040-20mhz board",
    );
    assert!(!err.contains("need 0 boards"), "{err}");
    let fw = dir.join("fw").display().to_string();
    expect(
        &[
            "build",
            "grand_piano",
            "--keys",
            "2",
            "--board",
            "rp2040_20mhz",
            "--target",
            "rp2040",
            "-o",
            &fw,
        ],
        1,
        "fits no rp2040-20mhz board",
    );
    assert!(!Path::new(&fw).exists());
}

#[test]
fn class_13_the_compiler_refuses_what_it_cannot_keep() {
    let dir = temp_dir("hostile-13");
    // A reversed solve range clamped every iterate to one end.
    let f = write(
        &dir,
        "solve.tactus",
        format!("{KEY}    solve x in [1 m, -1 m] {{\n        start = 0 m\n        residual = x - key\n        iterations = 3\n    }}\n    force f = x * 100 N/m\n}}\n"),
    );
    expect(&["check", &f], 1, "E0306");
    // An accuracy contract the plan breaks: reported BROKEN with exit 0, and built.
    let f = write(
        &dir,
        "tight.tactus",
        format!("{KEY}    force f = 0.731 N * sqrt(key / 1 mm) + key * 12.37 N/m\n    on key > 5 mm {{ emit strike(v = 1 m/s) }}\n    tolerance force = 0.000001\n}}\n"),
    );
    expect(
        &["check", &f, "--report", "precision"],
        1,
        "accuracy contract does not hold",
    );
    let c = dir.join("c").display().to_string();
    expect(
        &["build", &f, "-o", &c],
        1,
        "accuracy contract does not hold",
    );
    let fw = dir.join("fw").display().to_string();
    expect(
        &["build", &f, "--keys", "2", "--target", "rp2040", "-o", &fw],
        1,
        "accuracy contract does not hold",
    );
    expect(
        &["budget", &f, "--keys", "2", "--quick"],
        2,
        "accuracy contract does not hold",
    );
    assert!(!Path::new(&c).exists() && !Path::new(&fw).exists());
}

#[test]
fn class_14_play_ends_and_says_what_it_could_not_do() {
    let dir = temp_dir("hostile-14");
    let out = dir.display().to_string();
    // An instrument that strikes every sample: the WAV of a 10 s note took minutes.
    write(
        &dir,
        "every.tactus",
        format!("{KEY}    force f = key * 100 N/m\n    while key > 1 mm {{ emit strike(v = 1 m/s) }}\n}}\n"),
    );
    let every = write(
        &dir,
        "every.toml",
        "name = \"every\"\n[[range]]\nkeys = [60, 60]\ninstrument = \"every.tactus\"\n",
    );
    let long = write(
        &dir,
        "long.mid",
        midi(0, 1, 480, &[(0, &[0x90, 60, 100]), (9600, &[0x80, 60, 0])]),
    );
    expect(
        &[
            "play", &long, "--layout", &every, "--engine", "jit", "--out", &out,
        ],
        1,
        "use --no-wav",
    );
    // 20,000 notes on one key at once: the force player's re-strikes waited for each other
    // for hours ("use --seconds" though it was given).
    let mut dense: Vec<(u32, &[u8])> = Vec::new();
    for _ in 0..20_000 {
        dense.push((0, &[0x90, 60, 100]));
        dense.push((0, &[0x80, 60, 0]));
    }
    let dense = write(&dir, "dense.mid", midi(0, 1, 480, &dense));
    for player in ["force", "position"] {
        expect(
            &[
                "play",
                &dense,
                "--instrument",
                "grand_piano",
                "--player",
                player,
                "--seconds",
                "1",
                "--engine",
                "jit",
                "--out",
                &out,
                "--no-wav",
            ],
            0,
            "19999 notes left out",
        );
    }
    // A note at 0 s was struck at 0.5 s and not at 0 s, without a word; then struck late,
    // with a warning. The run now starts early enough (a lead-in): struck within 50 ms of
    // it, with nothing to say.
    let first = write(
        &dir,
        "first.mid",
        midi(0, 1, 480, &[(0, &[0x90, 60, 100]), (192, &[0x80, 60, 0])]),
    );
    let said = expect(
        &[
            "play",
            &first,
            "--instrument",
            "grand_piano",
            "--engine",
            "jit",
            "--out",
            &out,
            "--no-wav",
        ],
        0,
        "1 strikes (1 answer a note within 50 ms; 0 notes without a strike)",
    );
    assert!(!said.contains("could not be placed"), "{said}");
    // One strike (`key,time_s,…,note_on_s,…`), of key 60, within 50 ms of the note at 0 s.
    let csv = std::fs::read_to_string(dir.join("first-strikes.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 1, "{csv}");
    let t: f64 = rows[0][1].parse().unwrap();
    assert!(
        rows[0][0] == "60" && rows[0][4] == "0" && t.abs() < 0.05,
        "{csv}"
    );
}

#[test]
fn class_15_hostile_imports_are_diagnostics_at_the_import() {
    let dir = temp_dir("hostile-15");
    let main = |import: &str| {
        format!("{import}\n{KEY}    use s = spring(x = key)\n    force f = s.f\n}}\n")
    };
    let spring = "component spring {\n    input x: m\n    output f = 100 N/m * x\n}\n";
    // A missing file: where it was looked for.
    let f = write(&dir, "missing.tactus", main("import \"nosuch.tactus\""));
    let e = expect(
        &["check", &f],
        1,
        "error[E0140]: no file `nosuch.tactus` to import",
    );
    assert!(e.contains("and in Tactus's library"), "{e}");
    // A directory.
    std::fs::create_dir_all(dir.join("lib.tactus")).unwrap();
    let f = write(&dir, "directory.tactus", main("import \"lib.tactus\""));
    expect(&["check", &f], 1, "a directory, not a file");
    // A file of 100 MB (sparse: its size is refused before a byte is read).
    let big = std::fs::File::create(dir.join("big.tactus")).unwrap();
    big.set_len(100 << 20).unwrap();
    let f = write(&dir, "big_import.tactus", main("import \"big.tactus\""));
    expect(&["check", &f], 1, "longer than the 16777216 bytes");
    // A cycle, through a second file.
    write(&dir, "a.tactus", format!("import \"b.tactus\"\n{spring}"));
    write(&dir, "b.tactus", "import \"a.tactus\"\n");
    let f = write(&dir, "cycle.tactus", main("import \"a.tactus\""));
    let e = expect(&["check", &f], 1, "error[E0142]: an import cycle");
    assert!(e.contains("a.tactus → ") && e.contains("b.tactus"), "{e}");
    // A name imported twice, from two files: both definitions shown.
    write(&dir, "spring1.tactus", spring);
    write(&dir, "spring2.tactus", spring);
    let f = write(
        &dir,
        "twice.tactus",
        main("import \"spring1.tactus\"\nimport \"spring2.tactus\""),
    );
    let e = expect(
        &["check", &f],
        1,
        "error[E0143]: two components named `spring`",
    );
    assert!(
        e.contains("spring1.tactus:1:11") && e.contains("spring2.tactus:1:11"),
        "{e}"
    );
    // A chain of 1,000 files, each importing the next: it links.
    let chain = dir.join("chain");
    std::fs::create_dir_all(&chain).unwrap();
    for i in 0..1000 {
        write(
            &chain,
            &format!("f{i}.tactus"),
            format!("import \"f{}.tactus\"\n", i + 1),
        );
    }
    write(&chain, "f1000.tactus", spring);
    let f = write(&chain, "main.tactus", main("import \"f0.tactus\""));
    let e = expect(
        &["check", &f],
        1,
        "error[E0115]: no component named `spring`",
    );
    assert!(
        e.contains("defined in") && e.contains("f1000.tactus"),
        "{e}"
    );
    let f = write(
        &chain,
        "main2.tactus",
        main("import \"f0.tactus\"\nimport \"f1000.tactus\""),
    );
    expect(&["check", &f], 0, "is well-formed");
}
