//! Differential test against a real ARM implementation: seeded random sequences of ARMv6-M
//! data-processing, load/store and branch instructions, assembled with `arm-none-eabi-as`,
//! run under `qemu-arm` (user mode) and in the emulator, comparing r0-r8, the flags and a
//! 256-byte data area after every sequence.
//!
//! Each sequence is wrapped by a prologue that loads random registers and flags and an
//! epilogue that stores the registers and flags to `out` and writes `out` and `data` to
//! stdout with the Linux `write` syscall (`svc 0`, r7 = 4); the program ends with `exit`
//! (r7 = 1). The emulator runs the same ELF with SVC halting and plays the syscalls itself,
//! so both produce the same byte stream when they agree. Invariants the generator keeps:
//! r6 always holds `data` (loads and stores address `data` through it), SP points to
//! `data + 128` at the start and end of every sequence (PUSH/POP are balanced within a unit),
//! and branches only go forward over straight-line units, so every sequence terminates.

mod common;

use std::fmt::Write as _;
use std::process::Command;
use tactus_emulator::{Board, Config, StopReason};

/// Instructions per CI run must be at least this many.
const MIN_INSTRUCTIONS: usize = 100_000;
const FILES: usize = 4;
const SEQUENCES_PER_FILE: usize = 250;
const UNITS_PER_SEQUENCE: usize = 70;
const SEED: u64 = 0x7ac7_05e1_u64;
const OUT_BYTES: usize = 40;
const DATA_BYTES: usize = 256;

/// xorshift64* — deterministic, no dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: u32) -> u32 {
        (self.next() >> 33) as u32 % n
    }
    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len() as u32) as usize]
    }
    /// A register value: often an edge case, otherwise random.
    fn value(&mut self) -> u32 {
        match self.below(4) {
            0 => *self.pick(&[
                0,
                1,
                2,
                31,
                32,
                33,
                0x7fff_ffff,
                0x8000_0000,
                0xffff_ffff,
                0xffff_fffe,
                0x8000,
                0xff,
            ]),
            1 => self.below(64),
            _ => self.next() as u32,
        }
    }
}

/// Destination-capable low registers: r6 is the data base and never written.
const DST: [&str; 7] = ["r0", "r1", "r2", "r3", "r4", "r5", "r7"];
const SRC: [&str; 8] = ["r0", "r1", "r2", "r3", "r4", "r5", "r6", "r7"];
const CONDS: [&str; 14] = [
    "eq", "ne", "cs", "cc", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le",
];

/// One straight-line instruction (no branch, no stack change); appends it and returns the
/// number of instructions emitted.
fn simple(rng: &mut Rng, out: &mut String) -> usize {
    let d = *rng.pick(&DST);
    let s = *rng.pick(&SRC);
    let s2 = *rng.pick(&SRC);
    match rng.below(30) {
        0 => writeln!(out, "movs {d}, #{}", rng.below(256)),
        1 => writeln!(out, "adds {d}, {s}, {s2}"),
        2 => writeln!(out, "subs {d}, {s}, {s2}"),
        3 => writeln!(out, "adds {d}, {s}, #{}", rng.below(8)),
        4 => writeln!(out, "subs {d}, {s}, #{}", rng.below(8)),
        5 => writeln!(out, "adds {d}, #{}", rng.below(256)),
        6 => writeln!(out, "subs {d}, #{}", rng.below(256)),
        7 => writeln!(out, "cmp {s}, #{}", rng.below(256)),
        8 => writeln!(out, "lsls {d}, {s}, #{}", rng.below(32)),
        9 => writeln!(out, "lsrs {d}, {s}, #{}", 1 + rng.below(32)),
        10 => writeln!(out, "asrs {d}, {s}, #{}", 1 + rng.below(32)),
        11..=13 => {
            let op = rng.pick(&[
                "ands", "eors", "lsls", "lsrs", "asrs", "adcs", "sbcs", "rors", "tst", "cmp",
                "cmn", "orrs", "bics", "mvns",
            ]);
            let dst = if matches!(*op, "tst" | "cmp" | "cmn") {
                s2
            } else {
                d
            };
            writeln!(out, "{op} {dst}, {s}")
        }
        14 => writeln!(out, "rsbs {d}, {s}, #0"),
        15 => writeln!(out, "muls {d}, {s}, {d}"),
        16 => writeln!(
            out,
            "{} {d}, {s}",
            rng.pick(&["sxth", "sxtb", "uxth", "uxtb", "rev", "rev16", "revsh"])
        ),
        17 => writeln!(out, "mov r8, {s}"),
        18 => writeln!(out, "add {d}, r8"),
        19 => writeln!(out, "cmp {s}, r8"),
        20 => writeln!(out, "mov {d}, {s}"),
        21 => writeln!(out, "ldr {d}, [r6, #{}]", 4 * rng.below(32)),
        22 => writeln!(out, "str {s}, [r6, #{}]", 4 * rng.below(32)),
        23 => {
            let (op, scale) = *rng.pick(&[("ldrh", 2), ("strh", 2), ("ldrb", 1), ("strb", 1)]);
            let r = if op.starts_with("ld") { d } else { s };
            writeln!(out, "{op} {r}, [r6, #{}]", scale * rng.below(32))
        }
        24 | 25 => {
            // register offset: r5 = small aligned index, then the access
            let (op, scale) = *rng.pick(&[
                ("ldr", 4),
                ("str", 4),
                ("ldrh", 2),
                ("strh", 2),
                ("ldrb", 1),
                ("strb", 1),
                ("ldrsh", 2),
                ("ldrsb", 1),
            ]);
            let r = if op.starts_with("ld") {
                *rng.pick(&["r0", "r1", "r2", "r3", "r4", "r7"])
            } else {
                s
            };
            writeln!(
                out,
                "movs r5, #{}\n{op} {r}, [r6, r5]",
                scale * rng.below(128 / scale)
            )
            .unwrap();
            return 2;
        }
        26 => writeln!(out, "ldr {d}, [sp, #{}]", 4 * rng.below(32)),
        27 => writeln!(out, "str {s}, [sp, #{}]", 4 * rng.below(32)),
        28 => match rng.below(3) {
            0 => writeln!(out, "add {d}, sp, #{}", 4 * rng.below(256)),
            1 => writeln!(out, "add {d}, pc"),
            _ => writeln!(out, "mov {d}, pc"),
        },
        _ => writeln!(out, "ldr {d}, ={:#x}", rng.value()),
    }
    .unwrap();
    1
}

fn reg_list(rng: &mut Rng, n: usize, exclude: &[&str]) -> Vec<&'static str> {
    let mut regs: Vec<&'static str> = ["r0", "r1", "r2", "r3", "r4", "r5", "r7"]
        .into_iter()
        .filter(|r| !exclude.contains(r))
        .collect();
    while regs.len() > n {
        let i = rng.below(regs.len() as u32) as usize;
        regs.remove(i);
    }
    regs
}

/// One unit: a simple instruction, a forward branch over simple instructions, a balanced
/// PUSH/POP, or an LDM/STM through r5. Returns the instructions emitted.
fn unit(rng: &mut Rng, out: &mut String, label: &mut usize) -> usize {
    match rng.below(12) {
        0 | 1 => {
            *label += 1;
            let l = format!(".Lt{label}");
            let br = match rng.below(6) {
                0 => format!("b {l}"),
                1 => format!("bl {l}"),
                _ => format!("b{} {l}", rng.pick(&CONDS)),
            };
            writeln!(out, "{br}").unwrap();
            let mut n = 1;
            for _ in 0..1 + rng.below(3) {
                n += simple(rng, out);
            }
            writeln!(out, "{l}:").unwrap();
            n
        }
        2 => {
            let k = 1 + rng.below(4) as usize;
            let a = reg_list(rng, k, &[]);
            let b = reg_list(rng, k, &[]);
            writeln!(out, "push {{{}}}", a.join(", ")).unwrap();
            let mut n = 2;
            for _ in 0..rng.below(3) {
                n += simple(rng, out);
            }
            writeln!(out, "pop {{{}}}", b.join(", ")).unwrap();
            n
        }
        3 => {
            let k = 1 + rng.below(4) as usize;
            let list = reg_list(rng, k, &["r5"]);
            let op = if rng.below(2) == 0 { "ldmia" } else { "stmia" };
            writeln!(
                out,
                "adds r5, r6, #{}\n{op} r5!, {{{}}}",
                4 * rng.below(2),
                list.join(", ")
            )
            .unwrap();
            2
        }
        _ => simple(rng, out),
    }
}

/// One program of `SEQUENCES_PER_FILE` sequences; returns (source, instructions, per-sequence
/// source for reporting).
fn program(rng: &mut Rng) -> (String, usize, Vec<String>) {
    let mut src = String::from(
        ".syntax unified\n.cpu cortex-m0\n.thumb\n.text\n.global _start\n.thumb_func\n_start:\n",
    );
    let mut count = 0;
    let mut label = 0;
    let mut sequences = Vec::new();
    for seq in 0..SEQUENCES_PER_FILE {
        let mut body = String::new();
        writeln!(body, "ldr r0, =data+128\nmov sp, r0\nldr r6, =data").unwrap();
        writeln!(body, "ldr r0, ={:#x}\nmov r8, r0", rng.value()).unwrap();
        writeln!(
            body,
            "ldr r0, ={:#x}\nmsr apsr_nzcvq, r0",
            rng.below(16) << 28
        )
        .unwrap();
        for r in DST {
            writeln!(body, "ldr {r}, ={:#x}", rng.value()).unwrap();
        }
        let mut seq_src = String::new();
        for _ in 0..UNITS_PER_SEQUENCE {
            count += unit(rng, &mut seq_src, &mut label);
        }
        body.push_str(&seq_src);
        // Epilogue: out = r0-r5, r7, r6, flags, r8; write(1, out, 40); write(1, data, 256).
        writeln!(
            body,
            "mov r9, r6\nldr r6, =out\nstmia r6!, {{r0-r5}}\nstr r7, [r6, #0]\nmov r0, r9\nstr r0, [r6, #4]\n\
             mrs r0, apsr\nlsrs r0, r0, #28\nstr r0, [r6, #8]\nmov r0, r8\nstr r0, [r6, #12]\n\
             movs r0, #1\nldr r1, =out\nmovs r2, #{OUT_BYTES}\nmovs r7, #4\nsvc #0\n\
             movs r0, #1\nldr r1, =data\nldr r2, ={DATA_BYTES}\nmovs r7, #4\nsvc #0\n\
             b .Lnext{seq}\n.ltorg\n.Lnext{seq}:"
        )
        .unwrap();
        src.push_str(&body);
        sequences.push(seq_src);
    }
    src.push_str("movs r0, #0\nmovs r7, #1\nsvc #0\n.ltorg\n");
    writeln!(
        src,
        ".data\n.balign 4\ndata: .space {DATA_BYTES}\nout: .space {OUT_BYTES}"
    )
    .unwrap();
    (src, count, sequences)
}

/// Runs the ELF in the emulator, playing the `write` and `exit` syscalls; returns stdout.
fn run_emulator(elf: &[u8]) -> Result<Vec<u8>, String> {
    let mut board = Board::new(Config {
        svc_halts: true,
        ..Config::default()
    });
    board.load_elf(elf).map_err(|e| e.to_string())?;
    let mut stdout = Vec::new();
    loop {
        match board.run_for(100_000_000) {
            StopReason::Svc { core: 0, imm: 0 } => {
                let r = board.cores[0].r;
                match r[7] {
                    4 => {
                        let mut buf = vec![0; r[2] as usize];
                        board
                            .read_bytes(r[1], &mut buf)
                            .map_err(|e| e.to_string())?;
                        stdout.extend(buf);
                    }
                    1 => return Ok(stdout),
                    n => return Err(format!("unexpected syscall {n}")),
                }
            }
            other => return Err(format!("emulator stopped: {other:?}")),
        }
    }
}

fn describe(chunk: &[u8]) -> String {
    let word = |i: usize| u32::from_le_bytes(chunk[4 * i..4 * i + 4].try_into().unwrap());
    let names = ["r0", "r1", "r2", "r3", "r4", "r5", "r7", "r6", "nzcv", "r8"];
    names
        .iter()
        .enumerate()
        .map(|(i, n)| format!("{n}={:#x}", word(i)))
        .collect::<Vec<_>>()
        .join(" ")
}

#[test]
fn random_sequences_match_qemu() {
    if !common::have_tool("arm-none-eabi-as", "random_sequences_match_qemu")
        || !common::have_tool("arm-none-eabi-ld", "random_sequences_match_qemu")
        || !common::have_tool("qemu-arm", "random_sequences_match_qemu")
    {
        return;
    }
    // Longer local runs: TACTUS_DIFF_FILES=40 TACTUS_DIFF_SEED=7 cargo test --test differential
    let env = |name: &str, default: u64| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let files = env("TACTUS_DIFF_FILES", FILES as u64) as usize;
    let dir = common::scratch_dir("diff");
    let mut rng = Rng(env("TACTUS_DIFF_SEED", SEED));
    let mut total = 0;
    let mut compared = 0;
    for file in 0..files {
        let (src, count, sequences) = program(&mut rng);
        total += count;
        let elf_path = common::assemble_and_link(
            &dir,
            &format!("seq{file}"),
            &src,
            &["-Ttext=0x10000000", "-Tdata=0x20000000", "-e", "_start"],
        );
        let qemu = Command::new("qemu-arm")
            .arg(&elf_path)
            .output()
            .expect("run qemu-arm");
        assert!(
            qemu.status.success(),
            "qemu-arm failed on {}: {}",
            elf_path.display(),
            String::from_utf8_lossy(&qemu.stderr)
        );
        let elf = std::fs::read(&elf_path).unwrap();
        let ours = run_emulator(&elf).unwrap_or_else(|e| panic!("{}: {e}", elf_path.display()));
        let per = OUT_BYTES + DATA_BYTES;
        assert_eq!(
            qemu.stdout.len(),
            SEQUENCES_PER_FILE * per,
            "qemu output size"
        );
        for (i, (a, b)) in qemu.stdout.chunks(per).zip(ours.chunks(per)).enumerate() {
            if a != b {
                let regs = if a[..OUT_BYTES] != b[..OUT_BYTES] {
                    format!("qemu:     {}\nemulator: {}", describe(a), describe(b))
                } else {
                    let at = a.iter().zip(b).position(|(x, y)| x != y).unwrap() - OUT_BYTES;
                    format!("data differs first at byte {at}")
                };
                panic!(
                    "{}: sequence {i} differs\n{regs}\nsequence:\n{}",
                    elf_path.display(),
                    sequences[i]
                );
            }
            compared += 1;
        }
        assert_eq!(ours.len(), qemu.stdout.len(), "emulator output size");
    }
    let _ = std::fs::remove_dir_all(&dir);
    eprintln!("differential: {total} random instructions in {compared} sequences, 0 mismatches");
    assert!(
        total >= MIN_INSTRUCTIONS,
        "only {total} instructions generated"
    );
}
