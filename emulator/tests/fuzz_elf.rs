//! Fuzzing the ELF loader: small ARM executables (one and two `PT_LOAD` segments, in SRAM
//! and flash, with a symbol table and a `.vectors` section) mutated at the byte level —
//! extreme words dropped on sizes, offsets, counts and addresses (`p_memsz` = 0xFFFFFFFF,
//! `e_phnum` = 65535) — load into a [`Board`] or give an [`ElfError`]; a loaded one runs
//! 2,000 cycles. Never a panic, more than a bounded time or a bounded heap.
//! `TACTUS_FUZZ_CASES=100000` for a long run.

#[path = "../../tests/common/fuzz.rs"]
mod fuzz;

use proptest::prop_assert;
use proptest::test_runner::TestCaseError;
use std::cell::Cell;
use std::time::Duration;
use tactus_emulator::{Board, Config};

/// An ELF32 ARM executable: `segments` (address, bytes, extra zero-filled bytes), entry at
/// the first, a `.vectors` section and a symbol `main` on the first segment.
fn elf(segments: &[(u32, Vec<u8>, u32)]) -> Vec<u8> {
    let ph_off = 52u32;
    let data_off = ph_off + 32 * segments.len() as u32;
    let mut f = vec![0x7f, b'E', b'L', b'F', 1, 1, 1, 0];
    f.resize(16, 0);
    let mut body = Vec::new();
    let mut offsets = Vec::new();
    for (_, bytes, _) in segments {
        offsets.push(data_off + body.len() as u32);
        body.extend(bytes);
        while body.len() % 4 != 0 {
            body.push(0);
        }
    }
    // Section headers: null, .vectors, .symtab, .strtab, .shstrtab.
    let shstr = b"\0.vectors\0.symtab\0.strtab\0.shstrtab\0".to_vec();
    let strtab = b"\0main\0".to_vec();
    let mut symtab = vec![0u8; 16];
    for v in [1u32, segments[0].0 | 1, 8] {
        symtab.extend(v.to_le_bytes());
    }
    symtab.extend([0x12, 0, 1, 0]); // STB_GLOBAL|STT_FUNC, section 1
    let sym_off = data_off + body.len() as u32;
    body.extend(&symtab);
    let str_off = data_off + body.len() as u32;
    body.extend(&strtab);
    let shs_off = data_off + body.len() as u32;
    body.extend(&shstr);
    while body.len() % 4 != 0 {
        body.push(0);
    }
    let sh_off = data_off + body.len() as u32;
    let h16 = |f: &mut Vec<u8>, v: u16| f.extend(v.to_le_bytes());
    let h32 = |f: &mut Vec<u8>, v: u32| f.extend(v.to_le_bytes());
    h16(&mut f, 2); // ET_EXEC
    h16(&mut f, 40); // EM_ARM
    h32(&mut f, 1);
    h32(&mut f, segments[0].0 | 1);
    h32(&mut f, ph_off);
    h32(&mut f, sh_off);
    h32(&mut f, 0x0500_0000);
    h16(&mut f, 52);
    h16(&mut f, 32);
    h16(&mut f, segments.len() as u16);
    h16(&mut f, 40);
    h16(&mut f, 5);
    h16(&mut f, 4);
    for ((addr, bytes, extra), off) in segments.iter().zip(&offsets) {
        for v in [
            1,
            *off,
            *addr,
            *addr,
            bytes.len() as u32,
            bytes.len() as u32 + extra,
            7,
            4,
        ] {
            h32(&mut f, v);
        }
    }
    f.extend(body);
    let sh = |f: &mut Vec<u8>,
              name: u32,
              ty: u32,
              addr: u32,
              off: u32,
              size: u32,
              link: u32,
              entsize: u32| {
        for v in [name, ty, 0, addr, off, size, link, 0, 4, entsize] {
            f.extend(v.to_le_bytes());
        }
    };
    sh(&mut f, 0, 0, 0, 0, 0, 0, 0);
    sh(
        &mut f,
        1,
        1,
        segments[0].0,
        offsets[0],
        segments[0].1.len() as u32,
        0,
        0,
    );
    sh(&mut f, 10, 2, 0, sym_off, symtab.len() as u32, 3, 16);
    sh(&mut f, 18, 3, 0, str_off, strtab.len() as u32, 0, 0);
    sh(&mut f, 26, 3, 0, shs_off, shstr.len() as u32, 0, 0);
    f
}

fn seeds() -> Vec<Vec<u8>> {
    // movs r0, #1; adds r0, #2; b . (a loop)
    let code: Vec<u8> = [0x2001u16, 0x3002, 0xE7FE]
        .iter()
        .flat_map(|h| h.to_le_bytes())
        .collect();
    vec![
        elf(&[(0x2000_0000, code.clone(), 64)]),
        elf(&[
            (0x1000_0000, code.clone(), 0),
            (0x2000_1000, vec![1, 2, 3, 4], 256),
        ]),
        elf(&[(0x2100_0000, code, 16)]),
    ]
}

const TOKENS: &[&[u8]] = &[
    b"\xff\xff\xff\xff",
    b"\x01\x00\x00\x00",
    b"\x00\x00\x00\x20",
    b"\x00\x00\x00\x10",
];

#[test]
fn mutated_elf_files_load_or_give_errors() {
    let seeds = seeds();
    for s in &seeds {
        let mut b = Board::new(Config::default());
        b.load_elf(s).unwrap();
    }
    let (mut runner, cases) = fuzz::runner(3000);
    let (run, loaded) = (Cell::new(0u32), Cell::new(0u32));
    runner
        .run(&(0..seeds.len(), fuzz::edits(TOKENS)), |(seed, edits)| {
            let bytes = fuzz::apply(&seeds[seed], &edits);
            let (ok, dt, peak) = fuzz::measured(|| {
                let mut b = Board::new(Config::default());
                match b.load_elf(&bytes) {
                    Ok(()) => {
                        let _ = b.run_for(2_000);
                        true
                    }
                    Err(e) => {
                        assert!(!e.to_string().is_empty());
                        false
                    }
                }
            });
            run.set(run.get() + 1);
            loaded.set(loaded.get() + u32::from(ok));
            prop_assert!(dt < Duration::from_secs(10), "{dt:?}");
            // The board itself (2 MB flash, 264 KB SRAM, decode cache) plus the image.
            prop_assert!(peak < 256 << 20, "{peak} bytes");
            Ok::<(), TestCaseError>(())
        })
        .unwrap();
    eprintln!("fuzz_elf: {} cases, {} loaded", run.get(), loaded.get());
    assert!(run.get() >= cases);
}
