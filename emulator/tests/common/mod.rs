//! Helpers shared by the emulator's integration tests: running the ARM binutils when they
//! are installed, and parsing `key=value` state descriptions.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

/// True when `tool` can be run; otherwise prints a SKIPPED line naming it.
pub fn have_tool(tool: &str, test: &str) -> bool {
    let ok = Command::new(tool).arg("--version").output().is_ok_and(|o| o.status.success());
    if !ok {
        eprintln!("SKIPPED: {tool} not installed ({test})");
    }
    ok
}

/// A fresh scratch directory under the target dir.
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
    assert!(out.status.success(), "as failed: {}", String::from_utf8_lossy(&out.stderr));
    let out = Command::new("arm-none-eabi-ld").args(ld_args).arg("-o").arg(&elf).arg(&o).output().expect("run ld");
    assert!(out.status.success(), "ld failed: {}", String::from_utf8_lossy(&out.stderr));
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
    assert!(out.status.success(), "as failed: {}", String::from_utf8_lossy(&out.stderr));
    let bytes = std::fs::read(&o).expect("read .o");
    let file = object::File::parse(&*bytes).expect("parse .o");
    file.section_by_name(".text").expect(".text").data().expect("text data").to_vec()
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
