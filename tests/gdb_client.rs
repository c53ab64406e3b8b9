//! End-to-end test of the GDB stub with a real `gdb-multiarch` in batch mode against a
//! shipped board image (`tactus build harpsichord --keys 4 --target rp2040`): break at
//! core 1's sample interrupt, read a key's state words, step, read the cycle counters with
//! `monitor cycles`, continue, watch the sample counter, detach; the run's final cycle counts and
//! DAC words equal those of the run without the debugger. Fails when `CI` is set and
//! `gdb-multiarch` is missing (`.ci/run` installs it); prints why and passes elsewhere.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

const TACTUS: &str = env!("CARGO_BIN_EXE_tactus");

fn have_gdb() -> bool {
    Command::new("gdb-multiarch")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

fn tactus(args: &[&str]) -> String {
    let out = Command::new(TACTUS)
        .args(args)
        .output()
        .expect("running tactus");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "tactus {args:?} failed:\n{text}");
    text
}

/// The lines of `tactus emu run` that must not change under a debugger.
fn outcome(text: &str) -> Vec<String> {
    let lines: Vec<String> = text
        .lines()
        .filter(|l| l.starts_with("final cycles") || l.starts_with("DAC codes at the end"))
        .map(str::to_string)
        .collect();
    assert_eq!(lines.len(), 2, "no final cycles or DAC lines in:\n{text}");
    lines
}

/// The `"0x…"` value of `field` in the key map's first key of core `core`.
fn key_field(map: &str, core: usize, field: &str) -> String {
    let v: serde_json::Value = serde_json::from_str(map).unwrap();
    let key = v["keys"]
        .as_array()
        .unwrap()
        .iter()
        .find(|k| k["core"] == core)
        .expect("a key on the core");
    match &key[field] {
        serde_json::Value::Array(a) => a[0].as_str().unwrap().to_string(),
        x => x.as_str().unwrap().to_string(),
    }
}

#[test]
fn gdb_breaks_steps_reads_and_detaches_without_changing_the_run() {
    if !have_gdb() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set and gdb-multiarch is missing: `.ci/run` installs it (apt-get install gdb-multiarch)"
        );
        eprintln!("skipped: gdb-multiarch is not installed");
        return;
    }
    let dir = std::env::temp_dir().join(format!("tactus-gdb-e2e-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = dir.to_str().unwrap();
    tactus(&[
        "build",
        "harpsichord",
        "--keys",
        "4",
        "--target",
        "rp2040",
        "-o",
        d,
    ]);
    let board = dir.join("board-01");
    let elf = board.join("firmware.elf");
    let elf_s = elf.to_str().unwrap();
    let map = std::fs::read_to_string(board.join("keys.json")).unwrap();
    let run = [
        "emu",
        "run",
        elf_s,
        "--stimulus",
        "mf-dip",
        "--seconds",
        "0.005",
    ];

    let plain = outcome(&tactus(&run));

    let mut server = Command::new(TACTUS)
        .args(run)
        .args(["--gdb", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting tactus emu run --gdb 0");
    let mut stderr = BufReader::new(server.stderr.take().unwrap());
    let mut line = String::new();
    let port = loop {
        line.clear();
        assert!(
            stderr.read_line(&mut line).unwrap() > 0,
            "tactus ended before listening"
        );
        if let Some(at) = line.find("127.0.0.1:") {
            let rest = &line[at + "127.0.0.1:".len()..];
            let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
            break digits.parse::<u16>().unwrap();
        }
    };
    let state = key_field(&map, 1, "state");
    // Core 1's sample counter (its control block's word 2, `glue::ctrl::SAMPLES`): written
    // by every sample interrupt (a resting key's DAC word is not: the quiescent-key guard
    // skips it).
    let v: serde_json::Value = serde_json::from_str(&map).unwrap();
    let control = u32::from_str_radix(
        v["cores"][1]["control"]
            .as_str()
            .unwrap()
            .trim_start_matches("0x"),
        16,
    )
    .unwrap();
    let samples_word = format!("{:#x}", control + 8);
    let target = format!("target remote 127.0.0.1:{port}");
    let x_state = format!("x/4xw {state}");
    let watch = format!("watch *(unsigned int *){samples_word}");
    let script = [
        "set pagination off",
        "set confirm off",
        &target,
        "info threads",
        "break *core1_sample_isr",
        "continue",
        "p/x $pc",
        &x_state,
        "monitor cycles",
        "stepi",
        "p/x $pc",
        "monitor cycles",
        "continue",
        "monitor cycles",
        "delete",
        &watch,
        "continue",
        "delete",
        "detach",
    ];
    let mut gdb = Command::new("gdb-multiarch");
    gdb.args(["-nx", "-batch"]);
    for c in script {
        gdb.args(["-ex", c]);
    }
    let out = gdb.arg(elf_s).output().expect("running gdb-multiarch");
    let g = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let status = server.wait().unwrap();
    let mut rest = String::new();
    let _ = std::io::Read::read_to_string(&mut stderr, &mut rest);
    let mut stdout = String::new();
    let _ = std::io::Read::read_to_string(&mut server.stdout.take().unwrap(), &mut stdout);
    assert!(
        status.success(),
        "tactus under gdb failed:\n{stdout}{rest}\ngdb said:\n{g}"
    );

    // Both cores are threads; the breakpoint is hit on core 1 (thread 2).
    assert!(g.contains("Thread 1") && g.contains("Thread 2"), "{g}");
    assert!(
        g.contains("Thread 2") && g.contains("hit Breakpoint 1"),
        "{g}"
    );
    let isr = u32::from_str_radix(
        g.lines()
            .find_map(|l| l.strip_prefix("$1 = 0x"))
            .unwrap_or_else(|| panic!("no $1 in\n{g}")),
        16,
    )
    .unwrap();
    let stepped = u32::from_str_radix(
        g.lines()
            .find_map(|l| l.strip_prefix("$2 = 0x"))
            .unwrap_or_else(|| panic!("no $2 in\n{g}")),
        16,
    )
    .unwrap();
    assert!(
        stepped == isr + 2 || stepped == isr + 4,
        "stepi from {isr:#x} went to {stepped:#x}"
    );
    // The key's state words were read.
    let state_addr = u32::from_str_radix(state.trim_start_matches("0x"), 16).unwrap();
    assert!(
        g.lines()
            .any(|l| l.starts_with(&format!("{state_addr:#x}"))),
        "no x/4xw of {state} in\n{g}"
    );
    // `monitor cycles` three times: core 1's counter grows, and after a whole sample
    // interrupt its cycles are known.
    let core1: Vec<u64> = g
        .lines()
        .filter_map(|l| l.strip_prefix("core 1: cycle "))
        .map(|r| r.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(core1.len(), 3, "{g}");
    assert!(core1[0] < core1[1] && core1[1] < core1[2], "{core1:?}");
    assert!(g.contains("last sample interrupt"), "{g}");
    // The watchpoint on the sample counter fired: one more sample.
    assert_eq!(g.matches("Hardware watchpoint 2").count(), 2, "{g}");
    assert!(g.contains("New value"), "{g}");
    assert!(g.contains("detached"), "{g}");

    // The emulated time and the outputs are those of the run without gdb.
    assert_eq!(outcome(&stdout), plain, "gdb said:\n{g}");
    let _ = std::fs::remove_dir_all(&dir);
}
