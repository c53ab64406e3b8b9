//! The Thumb backend against the fixed interpreter, bit for bit, in the emulated RP2040:
//! every instrument, every built-in stimulus, and random raw sensor words (in and far out
//! of range). The update's code is loaded into SRAM and called per sample with
//! `Board::call`; compared on every sample: the force terms, total, outputs, emitted
//! events with their arguments, the states and the modes.

use std::path::Path;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::lower::Config;
use tactus_compiler::thumb::{self, ThumbObject};
use tactus_emulator::Board;
use tactus_runtime::rng::XorShift64;
use tactus_runtime::stimulus;

const CODE: u32 = 0x2000_0000;
const STATE: u32 = 0x2002_0000;
const SENSORS: u32 = 0x2002_8000;
const OUT: u32 = 0x2002_9000;
const STACK: u32 = 0x2003_e000;

fn instruments() -> Vec<(String, String)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments");
    let mut v: Vec<(String, String)> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "tactus"))
        .map(|p| {
            (
                p.file_stem().unwrap().to_string_lossy().into_owned(),
                std::fs::read_to_string(&p).unwrap(),
            )
        })
        .collect();
    v.sort();
    assert!(!v.is_empty());
    v
}

struct Emu {
    board: Board,
    init: u32,
    update: u32,
}

impl Emu {
    /// A board running an executable linked from the object (symbols from its ELF).
    fn from_elf(obj: &ThumbObject, elf: &[u8]) -> Self {
        let mut board = Board::new(Default::default());
        board.load_elf(elf).unwrap();
        let init = board.symbol(&obj.init_name()).unwrap() & !1;
        let update = board.symbol(&obj.update_name()).unwrap() & !1;
        let mut e = Emu {
            board,
            init,
            update,
        };
        e.reset();
        e
    }

    fn new(obj: &ThumbObject) -> Self {
        let mut board = Board::new(Default::default());
        board.write_bytes(CODE, &obj.code.text).unwrap();
        let init = CODE + obj.symbol(&obj.init_name()).unwrap().0 as u32;
        let update = CODE + obj.symbol(&obj.update_name()).unwrap().0 as u32;
        let mut e = Emu {
            board,
            init,
            update,
        };
        e.reset();
        e
    }

    fn reset(&mut self) {
        self.board
            .call(0, self.init, &[STATE], STACK, 100_000)
            .unwrap();
    }

    /// Runs one sample; returns out[] and the cycles of the call.
    fn step(&mut self, sensors: &[i32], out_len: usize) -> (Vec<i32>, u64) {
        for (i, w) in sensors.iter().enumerate() {
            self.board
                .write_data(SENSORS + 4 * i as u32, &w.to_le_bytes())
                .unwrap();
        }
        let r = self
            .board
            .call(0, self.update, &[STATE, SENSORS, OUT], STACK, 100_000)
            .unwrap_or_else(|e| panic!("update faulted: {e}"));
        let out = (0..out_len)
            .map(|i| self.board.read_u32(OUT + 4 * i as u32).unwrap() as i32)
            .collect();
        (out, r.cycles)
    }
}

fn random_word(rng: &mut XorShift64, prev: i32, (lo, hi): (i32, i32)) -> i32 {
    let span = (hi as i64 - lo as i64).max(1) as u64;
    match rng.below(8) {
        0 => rng.next_u64() as i32,
        1 => (lo as i64 + (rng.next_u64() % (span + 1)) as i64) as i32,
        2 => [
            i32::MIN,
            i32::MAX,
            lo,
            hi,
            lo.saturating_sub(1),
            hi.saturating_add(1),
            0,
        ][rng.below(7)],
        _ => {
            let step = ((rng.next_u64() % (span / 200 + 2)) as i64) - (span / 400) as i64;
            (prev as i64 + step).clamp(lo as i64, hi as i64) as i32
        }
    }
}

/// Runs records through the Thumb code and the interpreter; returns (mismatch texts,
/// worst cycles, total cycles, samples).
fn compare(
    fp: &FixedProgram,
    obj: &ThumbObject,
    label: &str,
    records: &[Vec<i32>],
) -> (Vec<String>, u64, u64) {
    compare_on(Emu::new(obj), fp, obj, label, records)
}

fn compare_on(
    mut emu: Emu,
    fp: &FixedProgram,
    obj: &ThumbObject,
    label: &str,
    records: &[Vec<i32>],
) -> (Vec<String>, u64, u64) {
    let p = &fp.program;
    let mut inst = FixedInstance::new(fp);
    let l = &obj.out;
    let mut bad = Vec::new();
    let (mut worst, mut total) = (0, 0);
    for (n, rec) in records.iter().enumerate() {
        let (row, cycles) = emu.step(rec, l.len);
        worst = worst.max(cycles);
        total += cycles;
        let want = inst.step_raw(rec).clone();
        let mut got_events = Vec::new();
        let mut stray = false;
        for site in &l.emits {
            let nargs = p.events[site.event.index()].args.len();
            let args = &row[site.offset + 1..site.offset + 1 + nargs];
            match row[site.offset] {
                1 => got_events.push((site.event, args.to_vec())),
                0 => stray |= args.iter().any(|&a| a != 0),
                _ => stray = true,
            }
        }
        let st = obj.state;
        let states: Vec<i32> = (0..p.states.len())
            .map(|i| {
                emu.board
                    .read_u32(STATE + (st.states + 4 * i) as u32)
                    .unwrap() as i32
            })
            .collect();
        let modes: Vec<u32> = (0..p.modes.len())
            .map(|i| {
                let mut b = [0u8];
                emu.board
                    .read_bytes(STATE + (st.modes + i) as u32, &mut b)
                    .unwrap();
                b[0] as u32
            })
            .collect();
        let ok = row[l.forces..l.forces + p.forces.len()] == want.forces[..]
            && row[l.total] == want.total
            && row[l.outputs..l.outputs + p.outputs.len()] == want.outputs[..]
            && got_events == want.events
            && !stray
            && states == inst.states()
            && modes == inst.modes();
        if !ok && bad.len() < 5 {
            bad.push(format!(
                "{label} sample {n} sensors {rec:?}:\n  thumb: {row:?} states {states:?} modes {modes:?}\n  interp: forces {:?} total {} outputs {:?} events {:?} states {:?} modes {:?}",
                want.forces, want.total, want.outputs, want.events, inst.states(), inst.modes()
            ));
        } else if !ok {
            bad.push(String::new());
        }
    }
    (bad, worst, total)
}

fn check_instrument(name: &str, text: &str) {
    check_source(name, text, true, 4)
}

fn check_source(name: &str, text: &str, stimuli: bool, random_runs: usize) {
    let p = tactus_compiler::compile(text, &Config::default())
        .unwrap()
        .program;
    let fp = FixedProgram::new(&p);
    let obj = thumb::compile(&fp).unwrap_or_else(|e| panic!("{name}: {e}"));
    let ns = p.sensors.len();
    let mut runs: Vec<(String, Vec<Vec<i32>>)> = Vec::new();
    for (stim, _) in stimulus::builtin_names().iter().filter(|_| stimuli) {
        let s = stimulus::builtin(stim, p.sensors[0].range.1, 44_100.0).unwrap();
        let records = s
            .key
            .iter()
            .map(|&k| {
                (0..ns)
                    .map(|i| FixedInstance::sensor_raw(&fp, i, if i == 0 { Some(k) } else { None }))
                    .collect()
            })
            .collect();
        runs.push((format!("{name}/{stim}"), records));
    }
    let mut rng = XorShift64::new(0x5EED ^ name.len() as u64);
    for r in 0..random_runs {
        let mut prev: Vec<i32> = fp.sensor_raw_range.iter().map(|r| r.0).collect();
        let records = (0..3000)
            .map(|_| {
                for (i, w) in prev.iter_mut().enumerate() {
                    *w = random_word(&mut rng, *w, fp.sensor_raw_range[i]);
                }
                prev.clone()
            })
            .collect();
        runs.push((format!("{name}/random{r}"), records));
    }
    let mut all_bad = Vec::new();
    let (mut worst, mut total, mut n) = (0, 0, 0);
    for (label, records) in &runs {
        let (bad, w, t) = compare(&fp, &obj, label, records);
        worst = worst.max(w);
        total += t;
        n += records.len();
        all_bad.extend(bad);
    }
    println!(
        "{name:<16} {n} samples, {} mismatches, cycles worst {worst} mean {:.1}, .text {} bytes",
        all_bad.len(),
        total as f64 / n as f64,
        obj.code.text.len()
    );
    let shown: Vec<&String> = all_bad.iter().filter(|s| !s.is_empty()).collect();
    assert!(
        all_bad.is_empty(),
        "{name}: {} mismatching samples; first:\n{}",
        all_bad.len(),
        shown
            .iter()
            .map(|s| s.as_str())
            .collect::<Vec<_>>()
            .join("\n")
    );
}

#[test]
fn thumb_matches_the_fixed_interpreter_bit_for_bit() {
    for (name, text) in instruments() {
        check_instrument(&name, &text);
    }
}

/// Small programs for the operations the shipped instruments use only in a few formats:
/// run-time division (positive and negative divisors, scaled both ways), sums of operands
/// in distant formats, comparisons across formats, min/max/abs, negation.
#[test]
fn thumb_matches_the_fixed_interpreter_on_operation_corners() {
    let cases = [
        ("div_pos", "instrument t {\n sensor a: N in [-30 N, 30 N]\n sensor b: s in [0.1 ms, 10 ms]\n output q = a / b\n output r = 1 N*s / (b + 1 ms)\n}\n"),
        ("div_neg", "instrument t {\n sensor a: m in [-2 m, 3 m]\n sensor b: m in [-5 m, -0.5 m]\n output q = a / b\n output r = (a * 1000) / b\n output u = a / (b * 1000)\n}\n"),
        ("sums", "instrument t {\n sensor a: m in [-1e-3 m, 1e-3 m]\n sensor b: m in [-100 m, 100 m]\n output s = a + b\n output df = a - b\n output e = b - a\n output f = (a + a) - (b - b * 0.5)\n force g = (a + b) * 1 N/m\n}\n"),
        ("decay", "instrument t {\n sensor a: Hz in [-150 Hz, 150 Hz]\n state pulse = 0 N in [0 N, 30 N]\n state tau = 3 ms in [0.1 ms, 10 ms]\n while a < 0 Hz { pulse = 0.27 N*s * -a }\n dynamics { pulse' = -pulse / tau }\n force f = pulse\n}\n"),
        ("compare", "instrument t {\n sensor a: m in [-1e-3 m, 1e-3 m]\n sensor b: m in [-100 m, 100 m]\n output lt = a < b\n output ge = a >= b\n output eq = a == b\n output ne = a != b\n output mn = min(a, b)\n output mx = max(a, -b)\n output ab = abs(b)\n output ng = -a\n output c = a > 0.5 mm\n output c2 = b <= -3 m\n output c3 = b == 0 m\n}\n"),
    ];
    for (name, text) in cases {
        check_source(name, text, false, 3);
    }
}

fn have(tool: &str) -> bool {
    std::process::Command::new(tool)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Tools the next test needs: present, or a clear skip (a failure under CI, which installs
/// them: binutils-arm-none-eabi).
fn tools_present(tools: &[&str]) -> bool {
    let missing: Vec<&&str> = tools.iter().filter(|t| !have(t)).collect();
    if missing.is_empty() {
        return true;
    }
    let msg = format!("{missing:?} not installed (Debian: binutils-arm-none-eabi)");
    assert!(std::env::var_os("CI").is_none(), "{msg}");
    println!("SKIPPED: {msg}");
    false
}

fn text_of(elf: &[u8]) -> Vec<u8> {
    use object::{Object, ObjectSection};
    let f = object::File::parse(elf).unwrap();
    f.section_by_name(".text").unwrap().data().unwrap().to_vec()
}

/// The `.s` listing assembles with GNU as to exactly the bytes of the object, and the
/// object links with GNU ld into an executable the emulator runs with the interpreter's bits.
#[test]
fn listing_assembles_to_the_same_bytes_and_the_object_links() {
    if !tools_present(&["arm-none-eabi-as", "arm-none-eabi-ld"]) {
        return;
    }
    let dir = std::env::temp_dir().join(format!("tactus-thumb-as-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, text) in instruments() {
        let p = tactus_compiler::compile(&text, &Config::default())
            .unwrap()
            .program;
        let fp = FixedProgram::new(&p);
        let obj = thumb::compile(&fp).unwrap();
        let ours = obj.elf().unwrap();
        assert_eq!(text_of(&ours), obj.code.text, "{name}: the ELF's .text");
        let s = dir.join(format!("{name}.s"));
        std::fs::write(&s, &obj.code.listing).unwrap();
        let o = dir.join(format!("{name}-as.o"));
        let out = std::process::Command::new("arm-none-eabi-as")
            .args(["-mcpu=cortex-m0plus", "-o"])
            .arg(&o)
            .arg(&s)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{name}: as failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            out.stderr.is_empty(),
            "{name}: as warned: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let theirs = text_of(&std::fs::read(&o).unwrap());
        assert_eq!(theirs.len(), obj.code.text.len(), "{name}: .text sizes");
        if let Some(i) = (0..theirs.len()).find(|&i| theirs[i] != obj.code.text[i]) {
            panic!("{name}: as gives other bytes from offset {i:#x}");
        }
        // Link our object (not the assembler's) into an executable at the start of SRAM.
        let ours_path = dir.join(format!("{name}.o"));
        std::fs::write(&ours_path, &ours).unwrap();
        let ld = dir.join("link.ld");
        std::fs::write(&ld, "SECTIONS { . = 0x20000000; .text : { *(.text*) } }\n").unwrap();
        let exe = dir.join(format!("{name}.elf"));
        let out = std::process::Command::new("arm-none-eabi-ld")
            .arg("-T")
            .arg(&ld)
            .arg("-e")
            .arg(obj.update_name())
            .arg("-o")
            .arg(&exe)
            .arg(&ours_path)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{name}: ld failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let emu = Emu::from_elf(&obj, &std::fs::read(&exe).unwrap());
        let stim = stimulus::builtin("ff-dip", p.sensors[0].range.1, 44_100.0).unwrap();
        let records: Vec<Vec<i32>> = stim
            .key
            .iter()
            .map(|&k| {
                (0..p.sensors.len())
                    .map(|i| FixedInstance::sensor_raw(&fp, i, if i == 0 { Some(k) } else { None }))
                    .collect()
            })
            .collect();
        let (bad, worst, _) = compare_on(emu, &fp, &obj, &format!("{name}/linked"), &records);
        assert!(
            bad.is_empty(),
            "{name}: linked firmware differs: {}",
            bad[0]
        );
        println!("{name}: listing = object bytes ({} B); linked executable matches ({} samples, worst {worst} cycles)", theirs.len(), records.len());
    }
    let _ = std::fs::remove_dir_all(&dir);
}
