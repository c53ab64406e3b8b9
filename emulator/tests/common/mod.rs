//! Helpers shared by the emulator's integration tests: running the ARM binutils when they
//! are installed, and parsing `key=value` state descriptions.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// True when `tool` can be run; otherwise prints a SKIPPED line naming it, and fails when
/// `CI` is set (`.ci/run` installs binutils-arm-none-eabi and qemu-user: there a missing
/// tool is a broken set-up, not a reason to pass).
pub fn have_tool(tool: &str, test: &str) -> bool {
    let ok = Command::new(tool)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var_os("CI").is_none(),
            "{tool} is not installed and CI is set ({test}): .ci/run installs it"
        );
        eprintln!("SKIPPED: {tool} not installed ({test})");
    }
    ok
}

/// A fresh scratch directory under the system temporary directory (one per test process).
pub fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("tactus-emu-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create scratch dir");
    dir
}

/// Assembles `source` (Thumb, ARMv6-M) and links it with `ld_args`; returns the ELF path.
pub fn assemble_and_link(dir: &Path, name: &str, source: &str, ld_args: &[&str]) -> PathBuf {
    let s = dir.join(format!("{name}.s"));
    let o = dir.join(format!("{name}.o"));
    let elf = dir.join(format!("{name}.elf"));
    std::fs::write(&s, source).expect("write .s");
    let out = Command::new("arm-none-eabi-as")
        .args(["-mcpu=cortex-m0", "-mthumb", "-o"])
        .arg(&o)
        .arg(&s)
        .output()
        .expect("run arm-none-eabi-as");
    assert!(
        out.status.success(),
        "as failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = Command::new("arm-none-eabi-ld")
        .args(ld_args)
        .arg("-o")
        .arg(&elf)
        .arg(&o)
        .output()
        .expect("run ld");
    assert!(
        out.status.success(),
        "ld failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    elf
}

/// Assembles `source` into an object file and returns its `.text` bytes.
pub fn assemble_text(dir: &Path, name: &str, source: &str) -> Vec<u8> {
    use object::{Object, ObjectSection};
    let s = dir.join(format!("{name}.s"));
    let o = dir.join(format!("{name}.o"));
    std::fs::write(&s, source).expect("write .s");
    let out = Command::new("arm-none-eabi-as")
        .args(["-mcpu=cortex-m0", "-mthumb", "-o"])
        .arg(&o)
        .arg(&s)
        .output()
        .expect("run arm-none-eabi-as");
    assert!(
        out.status.success(),
        "as failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(&o).expect("read .o");
    let file = object::File::parse(&*bytes).expect("parse .o");
    file.section_by_name(".text")
        .expect(".text")
        .data()
        .expect("text data")
        .to_vec()
}

/// Parses a number written in decimal or `0x` hex.
pub fn num(s: &str) -> u32 {
    let s = s.trim();
    match s.strip_prefix("0x") {
        Some(h) => u32::from_str_radix(h, 16),
        None => s.parse(),
    }
    .unwrap_or_else(|_| panic!("bad number `{s}`"))
}

/// Minimal Thumb encoders for test programs that must run without binutils: one function
/// per encoding class, arguments named after the bit fields (checked against the assembler
/// in `rp2040.rs` when it is installed).
pub mod enc {
    fn lo(r: u16) -> u16 {
        assert!(r < 8, "low register expected");
        r
    }
    /// `MOVS Rd, #imm8`
    pub fn movs(rd: u16, imm8: u16) -> u16 {
        assert!(imm8 < 256);
        0x2000 | lo(rd) << 8 | imm8
    }
    /// `LDR Rt, [Rn, #imm]` (imm multiple of 4, < 128)
    pub fn ldr(rt: u16, rn: u16, imm: u16) -> u16 {
        assert!(imm.is_multiple_of(4) && imm < 128);
        0x6800 | (imm / 4) << 6 | lo(rn) << 3 | lo(rt)
    }
    /// `STR Rt, [Rn, #imm]`
    pub fn str(rt: u16, rn: u16, imm: u16) -> u16 {
        assert!(imm.is_multiple_of(4) && imm < 128);
        0x6000 | (imm / 4) << 6 | lo(rn) << 3 | lo(rt)
    }
    /// `LSLS Rd, Rm, #imm5`
    pub fn lsls(rd: u16, rm: u16, imm5: u16) -> u16 {
        assert!(imm5 < 32);
        imm5 << 6 | lo(rm) << 3 | lo(rd)
    }
    /// `ADDS Rdn, #imm8`
    pub fn adds_imm8(rdn: u16, imm8: u16) -> u16 {
        assert!(imm8 < 256);
        0x3000 | lo(rdn) << 8 | imm8
    }
    /// `SUBS Rdn, #imm8`
    pub fn subs_imm8(rdn: u16, imm8: u16) -> u16 {
        assert!(imm8 < 256);
        0x3800 | lo(rdn) << 8 | imm8
    }
    /// `B<cond> .+offset` (offset from the instruction, even)
    pub fn bcond(cond: u16, offset: i32) -> u16 {
        let imm = (offset - 4) / 2;
        assert!((-128..128).contains(&imm) && cond < 14);
        0xd000 | cond << 8 | (imm as u16 & 0xff)
    }
    /// `NOP` (the ARMv6-M hint; GNU as spells `nop` as `mov r8, r8` = 46c0)
    pub fn nop() -> u16 {
        0xbf00
    }
    /// `SVC #imm8`
    pub fn svc(imm8: u16) -> u16 {
        0xdf00 | imm8
    }
    /// `CMP Rn, #imm8`
    pub fn cmp_imm(rn: u16, imm8: u16) -> u16 {
        0x2800 | lo(rn) << 8 | imm8
    }
    /// `STRH Rt, [Rn, #imm]` (imm even, < 64)
    pub fn strh(rt: u16, rn: u16, imm: u16) -> u16 {
        assert!(imm.is_multiple_of(2) && imm < 64);
        0x8000 | (imm / 2) << 6 | lo(rn) << 3 | lo(rt)
    }
    /// `B .+offset`
    pub fn b(offset: i32) -> u16 {
        let imm = (offset - 4) / 2;
        assert!((-1024..1024).contains(&imm));
        0xe000 | (imm as u16 & 0x7ff)
    }
    /// `BL .+offset` (two halfwords): I1 = NOT(J1 XOR S), I2 = NOT(J2 XOR S).
    pub fn bl(offset: i32) -> [u16; 2] {
        let imm = ((offset - 4) >> 1) as u32;
        let s = (imm >> 23) & 1;
        let i1 = (imm >> 22) & 1;
        let i2 = (imm >> 21) & 1;
        let j1 = (!i1 ^ s) & 1;
        let j2 = (!i2 ^ s) & 1;
        [
            0xf000 | (s << 10) as u16 | ((imm >> 11) & 0x3ff) as u16,
            0xd000 | (j1 << 13) as u16 | (j2 << 11) as u16 | (imm & 0x7ff) as u16,
        ]
    }
    /// `PUSH {lr}`
    pub fn push_lr() -> u16 {
        0xb500
    }
    /// `POP {pc}`
    pub fn pop_pc() -> u16 {
        0xbd00
    }
    /// Table of (encoding, assembly) for checking against the assembler.
    pub fn examples() -> Vec<(Vec<u16>, &'static str)> {
        vec![
            (vec![movs(3, 200)], "movs r3, #200"),
            (vec![ldr(1, 0, 0x70)], "ldr r1, [r0, #0x70]"),
            (vec![str(2, 7, 0x64)], "str r2, [r7, #0x64]"),
            (vec![lsls(0, 0, 28)], "lsls r0, r0, #28"),
            (vec![adds_imm8(5, 1)], "adds r5, #1"),
            (vec![subs_imm8(4, 1)], "subs r4, #1"),
            (vec![bcond(1, -4)], "bne .-4"),
            (vec![svc(0)], "svc #0"),
            (vec![cmp_imm(6, 9)], "cmp r6, #9"),
            (vec![strh(2, 1, 6)], "strh r2, [r1, #6]"),
            (vec![b(-8)], "b .-8"),
            (bl(0x1234).to_vec(), "bl .+0x1234"),
            (bl(-0x2000).to_vec(), "bl .-0x2000"),
            (vec![push_lr()], "push {lr}"),
            (vec![pop_pc()], "pop {pc}"),
        ]
    }
}

/// Loads `code` at `addr` and starts core `core` there with SP `sp`.
pub fn load_program(
    board: &mut tactus_emulator::Board,
    core: usize,
    addr: u32,
    sp: u32,
    code: &[u16],
) {
    let bytes: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
    board
        .write_bytes(addr, &bytes)
        .expect("program fits in memory");
    board.start_core(core, addr | 1, sp, 0);
}

/// The tests' deterministic PRNG (xorshift64*, Vigna 2016): `Rng(seed)` with a non-zero
/// seed.
pub struct Rng(pub u64);

impl Rng {
    /// The next 64 random bits.
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// A number below `n` (`n` ≥ 1, at most 65,536).
    pub fn below(&mut self, n: u32) -> u16 {
        ((self.next() >> 33) as u32 % n) as u16
    }
}

/// Both cores of `b` and the contention stalls, as two boards that ran the same program
/// must agree on them: cycle, instructions, registers, flags, IPSR, run state and fault.
pub fn cores_state(b: &tactus_emulator::Board) -> String {
    let mut s = String::new();
    for c in &b.cores {
        s +=
            &format!(
            "core {}: cycle {} instr {} r {:08x?} nzcv {}{}{}{} ipsr {} state {:?} fault {:?}\n",
            c.id, c.cycle, c.instructions, c.r, c.n as u8, c.z as u8, c.c as u8, c.v as u8,
            c.ipsr, c.state, c.fault
        );
    }
    s + &format!("stalls {:?}\n", b.system.contention_stalls)
}
