//! The `tactus` binary as a user meets it: exit codes, files written, errors on bad input.

mod common;
use common::{assert_ok, tactus, temp_dir};

#[test]
fn check_accepts_every_instrument_and_prints_ir() {
    for name in ["grand_piano", "harpsichord", "harpsichord_2x8", "hammond"] {
        let out = tactus()
            .args([
                "check",
                &format!("instruments/{name}.tactus"),
                "--emit",
                "ir",
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            stdout.contains("is well-formed") && stdout.contains("body:"),
            "{stdout}"
        );
    }
}

#[test]
fn check_fails_with_diagnostics_on_a_bad_file() {
    let dir = temp_dir("cli-bad");
    let f = dir.join("bad.tactus");
    std::fs::write(
        &f,
        "instrument a {\n  sensor key: m in [0 mm, 10 mm]\n  force f = k * key\n}\n",
    )
    .unwrap();
    let out = tactus().arg("check").arg(&f).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("E0201") && err.contains("unknown name `k`") && err.contains("bad.tactus:3"),
        "{err}"
    );
}

#[test]
fn missing_file_is_a_clear_error() {
    let out = tactus()
        .args(["check", "no/such/file.tactus"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no file `no/such/file.tactus`"));
}

#[test]
fn param_override_from_the_command_line() {
    let ok = tactus()
        .args(["check", "hammond", "--param", "k=200 N/m"])
        .output()
        .unwrap();
    assert_ok(&ok);
    let bad = tactus()
        .args(["check", "hammond", "--param", "k=2 mm"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("E0303"));
}

#[test]
fn sim_writes_trace_and_plots() {
    let dir = temp_dir("cli-sim");
    let out = tactus()
        .args([
            "sim",
            "instruments/grand_piano.tactus",
            "--stimulus",
            "ff-dip",
            "--out",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("event strike"), "{stdout}");
    let csv = std::fs::read_to_string(dir.join("grand_piano-ff-dip.csv")).unwrap();
    let header = csv.lines().next().unwrap();
    for col in [
        "time [s]",
        "key [m]",
        "contact [N]",
        "escapement [N]",
        "total [N]",
        "s",
        "esc.phase",
        "hammer_vel [m/s]",
        "strike.velocity [m/s]",
    ] {
        assert!(header.contains(col), "missing {col} in {header}");
    }
    assert!(csv.lines().count() > 30_000);
    for svg in [
        "grand_piano-ff-dip-forces.svg",
        "grand_piano-ff-dip-outputs.svg",
    ] {
        let text = std::fs::read_to_string(dir.join(svg)).unwrap();
        assert!(text.contains("<svg"), "{svg}");
    }
}

#[test]
fn sim_reads_a_csv_stimulus_and_rejects_unknown_ones() {
    let dir = temp_dir("cli-csv");
    let f = dir.join("press.csv");
    std::fs::write(&f, "time_s,key_mm\n0,0\n0.05,7\n0.3,7\n0.35,0\n0.6,0\n").unwrap();
    let out = tactus()
        .args(["sim", "harpsichord", "--stimulus"])
        .arg(&f)
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("event pluck"));
    let bad = tactus()
        .args(["sim", "harpsichord", "--stimulus", "fortissimo"])
        .arg("--out")
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("ff-dip"),
        "error should list the built-ins"
    );
}

#[test]
fn sim_engines_agree_on_the_strike() {
    let dir = temp_dir("cli-engines");
    let mut strikes = Vec::new();
    for args in [
        &["--engine", "interp"][..],
        &["--engine", "jit"],
        &["--numeric", "fixed"],
        &["--numeric", "fixed", "--engine", "jit"],
    ] {
        let out = tactus()
            .args(["sim", "grand_piano", "--stimulus", "mf-dip"])
            .args(args)
            .arg("--out")
            .arg(&dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let stdout = String::from_utf8_lossy(&out.stdout).to_string();
        let line = stdout
            .lines()
            .find(|l| l.contains("event strike"))
            .unwrap_or_else(|| panic!("{stdout}"))
            .to_string();
        strikes.push(line);
    }
    // The f64 JIT is bit-identical to the interpreter, the fixed JIT to the fixed
    // interpreter; fixed point strikes at the same sample with a hammer speed within the
    // accuracy contract's 1 % of the f64 one (docs/language.md, "the accuracy contract").
    assert_eq!(strikes[0], strikes[1], "{strikes:?}");
    assert_eq!(strikes[2], strikes[3], "{strikes:?}");
    let time_speed = |line: &str| {
        let (at, v) = line.split_once(": velocity = ").unwrap();
        let v: f64 = v.trim_end_matches(" m/s").parse().unwrap();
        (at.to_string(), v)
    };
    let ((t64, v64), (tfx, vfx)) = (time_speed(&strikes[0]), time_speed(&strikes[2]));
    assert_eq!(t64, tfx, "{strikes:?}");
    assert!((vfx - v64).abs() <= 0.01 * v64, "{strikes:?}");
    for f in [
        "grand_piano-mf-dip.csv",
        "grand_piano-mf-dip-jit.csv",
        "grand_piano-mf-dip-fixed.csv",
        "grand_piano-mf-dip-fixed-jit.csv",
    ] {
        assert!(dir.join(f).exists(), "{f}");
    }
    // The fixed JIT is bit-identical to the fixed interpreter: identical traces.
    let a = std::fs::read_to_string(dir.join("grand_piano-mf-dip-fixed.csv")).unwrap();
    let b = std::fs::read_to_string(dir.join("grand_piano-mf-dip-fixed-jit.csv")).unwrap();
    assert!(a == b, "fixed interpreter and fixed JIT traces differ");
    let a = std::fs::read_to_string(dir.join("grand_piano-mf-dip.csv")).unwrap();
    let b = std::fs::read_to_string(dir.join("grand_piano-mf-dip-jit.csv")).unwrap();
    assert!(a == b, "f64 interpreter and f64 JIT traces differ");
}

#[test]
fn build_rp2040_writes_object_header_and_listing() {
    let dir = temp_dir("cli-build-rp2040");
    let out = tactus()
        .args(["build", "harpsichord", "--target", "rp2040", "-o"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let o = std::fs::read(dir.join("harpsichord.o")).unwrap();
    // ELF32, little-endian, relocatable, EM_ARM (40).
    assert_eq!(&o[..6], b"\x7fELF\x01\x01");
    assert_eq!(u16::from_le_bytes([o[16], o[17]]), 1);
    assert_eq!(u16::from_le_bytes([o[18], o[19]]), 40);
    let h = std::fs::read_to_string(dir.join("harpsichord.h")).unwrap();
    assert!(h.contains("void tactus_harpsichord_update("), "{h}");
    let s = std::fs::read_to_string(dir.join("harpsichord.s")).unwrap();
    assert!(s.contains("tactus_harpsichord_update:") && s.contains(".thumb_func"));
    // Without -o: an error naming the missing option, exit 1.
    let out = tactus()
        .args(["build", "harpsichord", "--target", "rp2040"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("-o DIR"));
}

#[test]
fn build_firmware_from_a_tactus_file_then_boot_it_in_the_emulator() {
    // One command from a .tactus file to a flash UF2 per board, then the ELF booted from
    // power-on (boot ROM, boot2, the copy to SRAM) with every key on a stimulus.
    let dir = temp_dir("cli-build-firmware");
    let out = tactus()
        .args([
            "build",
            "instruments/hammond.tactus",
            "--keys",
            "30",
            "--target",
            "rp2040",
            "-o",
        ])
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("boards of rp2040"), "{stdout}");
    let boards: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("board-")
        })
        .collect();
    assert!(
        boards.len() >= 2,
        "30 organ keys need more than one board (22 fit on one): {boards:?}"
    );
    for b in &boards {
        for f in ["firmware.elf", "firmware.uf2", "keys.json", "README.md"] {
            assert!(b.join(f).exists(), "{} missing", b.join(f).display());
        }
        let uf2 = std::fs::read(b.join("firmware.uf2")).unwrap();
        assert_eq!(&uf2[..8], b"UF2\nWQ]\x9e");
        let readme = std::fs::read_to_string(b.join("README.md")).unwrap();
        assert!(
            readme.contains("BOOTSEL") && readme.contains("picotool load"),
            "{readme}"
        );
    }
    let first = dir.join("board-01");
    let out = tactus()
        .args(["emu", "run"])
        .arg(first.join("firmware.elf"))
        .args(["--stimulus", "mf-dip", "--seconds", "0.2"])
        .output()
        .unwrap();
    assert_ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("8820 samples of `mf-dip`"), "{stdout}");
    assert_eq!(stdout.matches("misses 0").count(), 2, "{stdout}");
    // A missing key map is an error naming it.
    std::fs::remove_file(first.join("keys.json")).unwrap();
    let out = tactus()
        .args(["emu", "run"])
        .arg(first.join("firmware.elf"))
        .args(["--stimulus", "mf-dip"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("keys.json"));
    // A keyboard for the C target is an error.
    let out = tactus()
        .args(["build", "hammond", "--keys", "4", "-o"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--target rp2040"));
}

#[test]
fn build_firmware_at_200_mhz_and_ram_only() {
    let dir = temp_dir("cli-build-200");
    // A flash image at 200 MHz: its UF2 writes flash, its ELF boots through boot2 and the
    // core voltage before the PLL.
    let out = tactus()
        .args([
            "build",
            "hammond",
            "--keys",
            "4",
            "--target",
            "rp2040",
            "--board",
            "rp2040_200mhz",
            "-o",
        ])
        .arg(dir.join("fast"))
        .output()
        .unwrap();
    assert_ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("at 200 MHz") && stdout.contains("(flash)"),
        "{stdout}"
    );
    let board = dir.join("fast/board-01");
    let uf2 = std::fs::read(board.join("firmware.uf2")).unwrap();
    assert_eq!(&uf2[12..16], &0x1000_0000u32.to_le_bytes(), "a flash block");
    let readme = std::fs::read_to_string(board.join("README.md")).unwrap();
    assert!(
        readme.contains("1.15 V") && readme.contains("writes it to flash"),
        "{readme}"
    );
    let out = tactus()
        .args(["emu", "run"])
        .arg(board.join("firmware.elf"))
        .args(["--stimulus", "mf-dip", "--seconds", "0.05"])
        .output()
        .unwrap();
    assert_ok(&out);
    assert_eq!(
        String::from_utf8_lossy(&out.stdout)
            .matches("misses 0")
            .count(),
        2
    );
    // RAM-only with --ram.
    let out = tactus()
        .args([
            "build", "hammond", "--keys", "4", "--target", "rp2040", "--ram", "-o",
        ])
        .arg(dir.join("ram"))
        .output()
        .unwrap();
    assert_ok(&out);
    let uf2 = std::fs::read(dir.join("ram/board-01/firmware.uf2")).unwrap();
    assert_eq!(&uf2[12..16], &0x2000_0000u32.to_le_bytes(), "a RAM block");
    // A board file at 200 MHz without its core voltage: an error naming the field.
    let file = dir.join("fast.toml");
    std::fs::write(
        &file,
        "name = \"fast\"\nclock_hz = 200e6\ncores = 2\nsample_rate_hz = 44100\n",
    )
    .unwrap();
    let out = tactus()
        .args([
            "build", "hammond", "--keys", "4", "--target", "rp2040", "--board",
        ])
        .arg(&file)
        .arg("-o")
        .arg(dir.join("low"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("core_voltage_v = 1.15"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Runs `tactus sim FILE --stimulus STIMULUS --out DIR --wav DIR/WAV EXTRA…`, checks it
/// succeeds and names the WAV, and reads the WAV: (sample rate, samples).
fn sim_wav(
    file: &std::path::Path,
    stimulus: &str,
    dir: &std::path::Path,
    wav: &str,
    extra: &[&str],
) -> (u32, Vec<i16>) {
    let out = tactus()
        .arg("sim")
        .arg(file)
        .args(["--stimulus", stimulus, "--out"])
        .arg(dir)
        .arg("--wav")
        .arg(dir.join(wav))
        .args(extra)
        .output()
        .unwrap();
    assert_ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains(wav));
    read_wav(&dir.join(wav))
}

/// Reads a 16-bit mono WAV: (sample rate, samples).
fn read_wav(path: &std::path::Path) -> (u32, Vec<i16>) {
    let mut r = hound::WavReader::open(path).unwrap();
    let spec = r.spec();
    assert_eq!((spec.channels, spec.bits_per_sample), (1, 16));
    let samples = r.samples::<i16>().map(|s| s.unwrap()).collect();
    (spec.sample_rate, samples)
}

#[test]
fn sim_writes_a_wav_of_the_audio_outputs() {
    let dir = temp_dir("cli-wav");
    // Two `audio*` outputs proportional to the key travel and one other output that is
    // largest where the key is at rest: the WAV must hold the sum of the first two only.
    let f = dir.join("w.tactus");
    std::fs::write(
        &f,
        "instrument w {\n  sensor key: m in [0 mm, 10 mm]\n  force f = 1 N/m * key\n  \
         output audio_a = key\n  output audio_b = key\n  output other = 10 mm - key\n}\n",
    )
    .unwrap();
    let run = |extra: &[&str], wav: &str| sim_wav(&f, "mf-dip", &dir, wav, extra);
    let (rate, audio) = run(&[], "audio.wav");
    assert_eq!(rate, 44_100);
    let mut rdr = csv::Reader::from_path(dir.join("w-mf-dip.csv")).unwrap();
    let key_col = rdr
        .headers()
        .unwrap()
        .iter()
        .position(|h| h == "key [m]")
        .unwrap();
    let key: Vec<f64> = rdr
        .records()
        .map(|r| r.unwrap()[key_col].parse().unwrap())
        .collect();
    assert_eq!(audio.len(), key.len(), "one WAV sample per trace row");
    // Normalised: the peak at 90 % of full scale, where the key is deepest; silence at rest.
    let peak = key.iter().cloned().fold(0.0, f64::max);
    assert_eq!(audio.iter().map(|s| s.abs()).max(), Some(29_490));
    for (i, (&a, &k)) in audio.iter().zip(&key).enumerate() {
        let want = (k / peak * 0.9 * 32767.0).round();
        assert!(
            (f64::from(a) - want).abs() <= 1.0,
            "sample {i}: {a} vs {want}"
        );
    }
    // --wav-output chooses another output: largest at rest.
    let (_, other) = run(&["--wav-output", "other"], "other.wav");
    assert_eq!(other[0], 29_490);
    assert!(other.iter().all(|s| (0..=29_490).contains(s)));

    // Errors: an unknown output, and an instrument without audio outputs.
    let bad = tactus()
        .arg("sim")
        .arg(&f)
        .args(["--out"])
        .arg(&dir)
        .arg("--wav")
        .arg(dir.join("x.wav"))
        .args(["--wav-output", "audio_c"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(1));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("`audio_c` is not a numeric output")
            && err.contains("audio_a, audio_b, other"),
        "{err}"
    );
    let none = tactus()
        .args(["sim", "hammond", "--out"])
        .arg(&dir)
        .arg("--wav")
        .arg(dir.join("h.wav"))
        .output()
        .unwrap();
    assert_eq!(none.status.code(), Some(1));
    let err = String::from_utf8_lossy(&none.stderr);
    assert!(
        err.contains("no output named `audio*`") && err.contains("outputs: none"),
        "{err}"
    );
    assert!(!dir.join("h.wav").exists() && !dir.join("x.wav").exists());
}

/// A pen instrument keeps its WAV: the `audio` output (here the pen's stroke position) is
/// written as before, and the force's x total can be listened to with `--wav-output
/// force.x` (a viscous drag, the pen's velocity along x, zero at rest).
#[test]
fn sim_writes_a_wav_of_a_pen_instrument() {
    let dir = temp_dir("cli-pen-wav");
    let f = dir.join("p.tactus");
    std::fs::write(
        &f,
        "instrument p {\n  sensor pen: m in { z: [0 mm, 10 mm], x: [0 mm, 160 mm] }\n  \
         force contact = { z: 300 N/m * pen.z, x: -2 N*s/m * d(pen.x) }\n  \
         output audio = pen.x - 80 mm\n}\n",
    )
    .unwrap();
    let run = |extra: &[&str], wav: &str| sim_wav(&f, "press-rub", &dir, wav, extra);
    let (_, audio) = run(&[], "audio.wav");
    let (_, drag) = run(&["--wav-output", "force.x"], "drag.wav");
    let mut rdr = csv::Reader::from_path(dir.join("p-press-rub.csv")).unwrap();
    let headers = rdr.headers().unwrap().clone();
    let at = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let (x_col, fx_col) = (at("pen.x [m]"), at("force.x [N]"));
    let rows: Vec<(f64, f64)> = rdr
        .records()
        .map(|r| {
            let r = r.unwrap();
            (r[x_col].parse().unwrap(), r[fx_col].parse().unwrap())
        })
        .collect();
    assert_eq!(audio.len(), rows.len());
    assert_eq!(drag.len(), rows.len());
    let peak = |v: &mut dyn Iterator<Item = f64>| v.fold(0.0f64, |m, x| m.max(x.abs()));
    let (px, pf) = (
        peak(&mut rows.iter().map(|r| r.0 - 0.080)),
        peak(&mut rows.iter().map(|r| r.1)),
    );
    assert!(pf > 0.1, "no drag: {pf} N");
    for (i, ((x, fx), (a, d))) in rows.iter().zip(audio.iter().zip(&drag)).enumerate() {
        let (want_a, want_d) = (
            ((x - 0.080) / px * 0.9 * 32767.0).round(),
            (fx / pf * 0.9 * 32767.0).round(),
        );
        assert!(
            (f64::from(*a) - want_a).abs() <= 1.0,
            "sample {i}: audio {a} vs {want_a}"
        );
        assert!(
            (f64::from(*d) - want_d).abs() <= 1.0,
            "sample {i}: force.x {d} vs {want_d}"
        );
    }
}

#[test]
fn regulate_prints_a_sheet_judges_it_against_a_spec_and_rejects_bad_input() {
    let dir = temp_dir("cli-regulate");
    let out = tactus()
        .args(["regulate", "harpsichord", "-o"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("harpsichord — regulation sheet")
            && stdout.contains("down-weight")
            && stdout.contains("note: let-off"),
        "{stdout}"
    );
    assert!(dir.join("harpsichord-loop.svg").exists() && dir.join("harpsichord-loop.csv").exists());
    // A spec the harpsichord meets, and one it does not (a hammer figure it cannot have).
    let spec = dir.join("spec.toml");
    std::fs::write(&spec, "name = \"light\"\nkey_dip = { min = 6, max = 8 }\n").unwrap();
    let out = tactus()
        .args(["regulate", "harpsichord", "-o"])
        .arg(&dir)
        .arg("--spec")
        .arg(&spec)
        .output()
        .unwrap();
    assert_ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("within spec `light`"));
    std::fs::write(
        &spec,
        "name = \"grand\"\nkey_dip = { min = 9.5, max = 10.5 }\nlet_off = { min = 1, max = 3 }\n",
    )
    .unwrap();
    let out = tactus()
        .args(["regulate", "harpsichord", "-o"])
        .arg(&dir)
        .arg("--spec")
        .arg(&spec)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("OUTSIDE spec `grand`: 2 of 2 figures (key_dip, let_off)")
            && stdout.contains("not measured"),
        "{stdout}"
    );
    // Two specs (`--spec` repeats): a verdict line each, exit 1 when one fails.
    let light = dir.join("light.toml");
    std::fs::write(&light, "name = \"light\"\nkey_dip = { min = 6, max = 8 }\n").unwrap();
    let out = tactus()
        .args(["regulate", "harpsichord", "-o"])
        .arg(&dir)
        .arg("--spec")
        .arg(&light)
        .arg("--spec")
        .arg(&spec)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("within spec `light`") && stdout.contains("OUTSIDE spec `grand`"),
        "{stdout}"
    );
    // Bad input: exit 2 with the file and the field named.
    std::fs::write(&spec, "name = \"x\"\ndownweight = { min = 1 }\n").unwrap();
    let out = tactus()
        .args(["regulate", "harpsichord", "--spec"])
        .arg(&spec)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("`downweight` is no figure"));
    let out = tactus().args(["regulate", "rubbed_bank"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("pen instrument"));
}

/// `regulate --layout L --key N` regulates a key of a graded keyboard as the keyboard
/// compiles it (issue 70): grand88's A0 has the 11 g hammer and its sheet is inside both
/// specs; `--param` goes on top; a key the layout lacks is refused with its keys.
#[test]
fn regulate_takes_a_key_of_a_layout() {
    let dir = temp_dir("cli-regulate-key");
    let out = tactus()
        .args(["regulate", "--layout", "grand88", "--key", "21", "-o"])
        .arg(&dir)
        .args([
            "--spec",
            "instruments/specs/concert_grand.toml",
            "--spec",
            "instruments/specs/concert_grand_dynamic.toml",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert_ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("key 21 of grand88: grand_piano (M_h=11 g)")
            && stdout.contains("within spec `grand action at speed`"),
        "{stdout}"
    );
    let out = tactus()
        .args([
            "regulate",
            "--layout",
            "grand88",
            "--key",
            "108",
            "--no-dynamic",
        ])
        .args(["--param", "M_h=4 g", "-o"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_ok(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("grand_piano (M_h=4 g)"));
    let out = tactus()
        .args(["regulate", "--layout", "grand88", "--key", "5"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr)
        .contains("no instrument to key 5 (it has keys 21–108)"));
}

/// `sim --touch` plays a pianist's finger on the key (issue 70): a struck *fff* strikes the
/// grand piano's string in f64 and in fixed point at the same sample, hammer speeds within the
/// accuracy contract's 1 %, faster than a pressed *pp*; a touch that is no touch is refused
/// with the forms it takes.
#[test]
fn sim_plays_a_touch_and_refuses_a_bad_one() {
    let dir = temp_dir("cli-touch");
    let strike = |args: &[&str]| -> (String, f64) {
        let out = tactus()
            .args(["sim", "grand_piano"])
            .args(args)
            .arg("--out")
            .arg(&dir)
            .output()
            .unwrap();
        assert_ok(&out);
        let stdout = String::from_utf8_lossy(&out.stdout).to_string();
        let line = stdout
            .lines()
            .find(|l| l.contains("event strike"))
            .unwrap_or_else(|| panic!("{args:?}: {stdout}"));
        let (at, v) = line.split_once(": velocity = ").unwrap();
        (at.to_string(), v.trim_end_matches(" m/s").parse().unwrap())
    };
    let (t64, v64) = strike(&["--touch", "struck:fff"]);
    let (tfx, vfx) = strike(&["--touch", "struck:fff", "--numeric", "fixed"]);
    assert_eq!(t64, tfx);
    assert!((vfx - v64).abs() <= 0.01 * v64, "{v64} {vfx}");
    let (_, soft) = strike(&["--touch", "pressed:pp"]);
    assert!(soft < 1.0 && v64 > 5.0, "pp {soft} m/s, fff {v64} m/s");
    assert!(dir.join("grand_piano-struck-3mps.csv").exists());
    let bad = tactus()
        .args(["sim", "grand_piano", "--touch", "hit:2m/s"])
        .output()
        .unwrap();
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("pressed or struck"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
}

/// `build`, `budget` and `play` resolve and compile a keyboard in one place
/// (`tactus_host::keyboard`): on a built-in layout named bare and on a bare instrument, they
/// plan the same boards with the same keys, and `build` and `budget` give every key the
/// same instrument and params.
#[test]
fn build_budget_and_play_see_the_same_keyboard() {
    let dir = temp_dir("same-keyboard");
    for (i, (budget_args, build_args, play_args)) in [
        (
            vec!["split_harpsichord_piano"],
            vec!["split_harpsichord_piano"],
            vec!["--layout", "split_harpsichord_piano"],
        ),
        (
            vec!["harpsichord"],
            vec!["harpsichord", "--keys", "88"],
            vec!["--instrument", "harpsichord"],
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let budget = tactus()
            .arg("budget")
            .args(&budget_args)
            .args(["--quick", "--json"])
            .output()
            .unwrap();
        assert_ok(&budget);
        let v: serde_json::Value = serde_json::from_slice(&budget.stdout).unwrap();
        let keys_of = |b: &serde_json::Value| -> Vec<u8> {
            b["keys"]
                .as_array()
                .unwrap()
                .iter()
                .map(|k| k.as_u64().unwrap() as u8)
                .collect()
        };
        let planned: Vec<String> = v["boards"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| tactus_firmware::verdict::key_ranges(&keys_of(b)))
            .collect();
        assert!(planned.len() >= 2, "{v}");
        // Every key's instrument and params, as `name=value` sorted.
        let mut budgeted = std::collections::BTreeMap::new();
        for p in v["programs"].as_array().unwrap() {
            let mut params: Vec<String> = p["params"]
                .as_object()
                .unwrap()
                .iter()
                .map(|(n, x)| format!("{n}={}", x.as_str().unwrap()))
                .collect();
            params.sort();
            for k in keys_of(p) {
                budgeted.insert(
                    k,
                    (
                        p["instrument"].as_str().unwrap().to_string(),
                        params.clone(),
                    ),
                );
            }
        }
        assert_eq!(budgeted.len(), 88);
        // Between two markers of each line that has the first.
        let between = |out: &std::process::Output, start: &str, end: &str| -> Vec<String> {
            String::from_utf8_lossy(&out.stdout)
                .lines()
                .filter_map(|l| {
                    let (_, rest) = l.split_once(start)?;
                    Some(rest.split_once(end)?.0.to_string())
                })
                .collect()
        };
        let fw = dir.join(format!("fw{i}"));
        let build = tactus()
            .arg("build")
            .args(&build_args)
            .args(["--target", "rp2040", "-o"])
            .arg(&fw)
            .output()
            .unwrap();
        assert_ok(&build);
        assert_eq!(
            between(&build, ": keys ", ", UF2"),
            planned,
            "build vs budget"
        );
        let mut built = std::collections::BTreeMap::new();
        for board in std::fs::read_dir(&fw).unwrap() {
            let map = board.unwrap().path().join("keys.json");
            let map: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&map).unwrap()).unwrap();
            for k in map["keys"].as_array().unwrap() {
                let mut params: Vec<String> = k["params"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|p| p.as_str().unwrap().to_string())
                    .collect();
                params.sort();
                built.insert(
                    k["midi"].as_u64().unwrap() as u8,
                    (k["instrument"].as_str().unwrap().to_string(), params),
                );
            }
        }
        let squeeze = |m: &std::collections::BTreeMap<u8, (String, Vec<String>)>| {
            m.iter()
                .map(|(k, (i, p))| {
                    (
                        *k,
                        i.clone(),
                        p.iter().map(|x| x.replace(' ', "")).collect(),
                    )
                })
                .collect::<Vec<(u8, String, Vec<String>)>>()
        };
        assert_eq!(
            squeeze(&built),
            squeeze(&budgeted),
            "build vs budget: keys and programs"
        );
        let play = tactus()
            .arg("play")
            .args(&play_args)
            .args(["--seconds", "0.3", "--no-wav", "-o"])
            .arg(dir.join(format!("play{i}")))
            .output()
            .unwrap();
        assert_ok(&play);
        let played: Vec<String> = between(&play, "(keys ", "): core 0");
        assert_eq!(played, planned, "play vs budget");
    }
}

/// A minimal ARM ELF32 executable with `code` (halfwords) at 0x20000000.
fn tiny_elf(code: &[u16]) -> Vec<u8> {
    let code: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
    let mut f = vec![0x7f, b'E', b'L', b'F', 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0];
    for v in [2u16, 40] {
        f.extend(v.to_le_bytes()); // ET_EXEC, EM_ARM
    }
    for v in [1u32, 0x2000_0001, 52, 0, 0x0500_0000] {
        f.extend(v.to_le_bytes()); // version, entry, phoff, shoff, flags
    }
    for v in [52u16, 32, 1, 40, 0, 0] {
        f.extend(v.to_le_bytes());
    }
    let n = code.len() as u32;
    for v in [1u32, 84, 0x2000_0000, 0x2000_0000, n, n, 5, 4] {
        f.extend(v.to_le_bytes()); // PT_LOAD
    }
    f.extend(code);
    f
}

/// `tactus emu run FILE --cycles 1000 [extra]` on `bytes` written to a file (`None`: no
/// file); its exit code and output.
fn emu_run(name: &str, bytes: Option<&[u8]>, extra: &[&str]) -> (Option<i32>, String) {
    let path = temp_dir("cli-emu").join(name);
    if let Some(b) = bytes {
        std::fs::write(&path, b).unwrap();
    }
    let out = tactus()
        .args(["emu", "run"])
        .arg(&path)
        .args(["--cycles", "1000"])
        .args(extra)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.code(), text)
}

#[test]
fn emu_run_exit_codes() {
    // movs r0, #42; b .: runs to the cycle limit, traced or not.
    let ok = tiny_elf(&[0x202a, 0xe7fe]);
    let (code, text) = emu_run("ok.elf", Some(&ok), &[]);
    assert_eq!(code, Some(0), "{text}");
    assert!(
        text.contains("r0=0000002a") && text.contains("stopped: cycle limit 1000"),
        "{text}"
    );
    let (code, text) = emu_run("trace.elf", Some(&ok), &["--trace"]);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("movs"), "{text}");
    // An unknown profiled symbol, a missing, a non-ELF and a truncated file: 1.
    let (code, text) = emu_run("prof.elf", Some(&ok), &["--profile", "main"]);
    assert_eq!(code, Some(1), "{text}");
    assert_eq!(emu_run("missing.elf", None, &[]).0, Some(1));
    assert_eq!(emu_run("text.elf", Some(b"not an elf"), &[]).0, Some(1));
    assert_eq!(emu_run("short.elf", Some(&ok[..60]), &[]).0, Some(1));
    // Firmware that faults: udf #0, and bx r0 with r0 = 0 (ARM state): 2.
    let (code, text) = emu_run("udf.elf", Some(&tiny_elf(&[0xde00])), &[]);
    assert_eq!(code, Some(2), "{text}");
    let (code, text) = emu_run("bx.elf", Some(&tiny_elf(&[0x4700])), &["--trace"]);
    assert_eq!(code, Some(2), "{text}");
}

/// The `--help` of every command that takes `--board` names every board the toolchain
/// ships (`tactus_host::catalogue::BOARDS`), so a board added to the catalogue cannot be
/// missing from what a user reads.
#[test]
fn every_board_option_names_every_shipped_board() {
    for cmd in ["build", "budget", "play"] {
        let out = tactus().args([cmd, "--help"]).output().unwrap();
        assert_ok(&out);
        let help = String::from_utf8_lossy(&out.stdout);
        for (name, _) in tactus_host::catalogue::BOARDS {
            assert!(
                help.contains(&format!("`{name}`")),
                "`tactus {cmd} --help` does not name the shipped board {name}:\n{help}"
            );
        }
    }
}
