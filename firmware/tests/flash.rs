//! Firmware a user can flash (issue 20): every board of the shipped layouts built as
//! `tactus build LAYOUT --target rp2040` builds it, booted from its ELF in the emulator —
//! entry stub, clock set-up, core 1 launched over the SIO FIFOs by the boot ROM's protocol
//! — and run for one emulated second of the budget corpus against the fixed interpreter
//! and the reference limiter; each UF2 checked by a reader written here from the format's
//! specification (microsoft/uf2 `README.md`) and by the format's own `uf2conv.py`
//! (vendored in `tests/tools/uf2/`); each ELF read by `arm-none-eabi-readelf` and
//! `arm-none-eabi-objdump`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_firmware::corpus::{self, Size};
use tactus_firmware::flash::{self, BoardFirmware, KeyboardInput};
use tactus_firmware::image::{compile_layout, Program};
use tactus_runtime::keyboard::{read_board, read_layout, Board};
use tactus_runtime::limiter::{Limiter, LimiterConfig};

fn root() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."))
}

fn shipped(name: &str) -> Result<String, String> {
    let p = if name.ends_with(".tactus") {
        root().join(name)
    } else {
        root().join(format!("instruments/{name}.tactus"))
    };
    std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))
}

/// A tool the CI installs (`.ci/run`): a missing one fails under `CI`, else says loudly
/// that the check is skipped.
fn tool(name: &str) -> bool {
    let ok = Command::new(name).arg("--version").output().is_ok();
    if !ok {
        assert!(
            std::env::var_os("CI").is_none(),
            "{name} is not installed (CI installs it)"
        );
        eprintln!("SKIPPED: {name} is not installed; its check did not run");
    }
    ok
}

/// Every board of `layout` as `tactus build` makes it (boards planned when the layout lists
/// none), with the board kind it uses.
fn firmware(layout: &str) -> (Vec<BoardFirmware>, Board) {
    let path = root().join(layout);
    let (l, keys) = read_layout(&path).unwrap();
    let kind = l.board_kind.clone().unwrap_or_else(|| "rp2040".into());
    let board = read_board(&root().join(format!("boards/{}.toml", kind.trim_end_matches(".toml"))))
        .unwrap();
    let (programs, index) = compile_layout(&keys, &shipped, board.sample_rate_hz).unwrap();
    let mut names = vec![(String::new(), Vec::new()); programs.len()];
    for (k, &p) in keys.iter().zip(&index) {
        names[p] = (k.instrument.clone(), k.params.clone());
    }
    let mut pairs: Vec<(u8, usize)> = keys.iter().map(|k| k.key).zip(index).collect();
    pairs.sort_unstable();
    let boards = tactus_runtime::keyboard::board_keys(&l, layout, &keys).unwrap();
    let limiter = LimiterConfig {
        sample_rate_hz: board.sample_rate_hz,
        ..LimiterConfig::default()
    };
    let input = KeyboardInput {
        name: &l.name,
        programs: &programs,
        program_names: &names,
        keys: &pairs,
        board: &board,
        boards: boards.as_deref(),
        limiter: &limiter,
        command: "test",
    };
    let fw = flash::keyboard_firmware(&input, &mut |_, _, _| {}).unwrap();
    (fw, board)
}

/// One emulated second of the budget corpus (quick) for each key, its runs concatenated
/// and repeated, each key starting at its own offset.
fn corpus_words(p: &Program, key: usize, samples: usize) -> Vec<i32> {
    let runs = corpus::corpus(&p.fixed, Size::Quick);
    let all: Vec<i32> = runs
        .iter()
        .flat_map(|r| r.records.iter().map(|w| w.first().copied().unwrap_or(0)))
        .collect();
    let off = key * 7919;
    (0..samples).map(|n| all[(off + n) % all.len()]).collect()
}

/// Boots `fw` from its ELF and runs one second: returns (samples with a DAC or force
/// mismatch, first mismatches, per-core misses, per-core worst handler cycles).
fn boot_and_run(fw: &BoardFirmware, board: &Board) -> (usize, Vec<String>, Vec<u32>, Vec<u64>) {
    let image = &fw.image;
    let mut run = tactus_firmware::image::ImageRun::from_elf(image, &fw.elf).unwrap();
    // Booted as on the chip: the clock the board file names, core 1 started by the boot
    // ROM with the vector table the key map names.
    let b = run.board();
    assert_eq!(
        b.system.sysctl.clk_sys_hz(),
        Some(board.clock_hz as u64),
        "board {}: clk_sys as programmed",
        fw.index
    );
    assert_eq!(b.system.sysctl.tick_cycles(), Some(12), "1 µs timer tick");
    if image.cores() == 2 {
        let vt = &fw.key_map.cores[1].vector_table;
        assert_eq!(format!("{:#010x}", b.cores[1].nvic.vtor), *vt);
        assert_eq!(
            b.system.sio.fifo_status(0) & 0xd,
            0,
            "FIFO drained, no error"
        );
    }
    let programs = image.programs();
    let keys = image.keys();
    // The key map's param block holds each key's words, as booted (graded keys share code).
    for (entry, k) in fw.key_map.keys.iter().zip(&keys) {
        let params = &programs[k.program].params;
        assert_eq!(entry.param_block.is_some(), !params.is_empty(), "{entry:?}");
        if let Some(at) = &entry.param_block {
            let at = u32::from_str_radix(at.trim_start_matches("0x"), 16).unwrap();
            for (j, &w) in params.iter().enumerate() {
                let got = run.board().read_u32(at + 4 * j as u32).unwrap();
                assert_eq!(
                    got as i32, w,
                    "board {} key {}: param word {j}",
                    fw.index, entry.midi
                );
            }
        }
    }
    let samples = board.sample_rate_hz as usize;
    let words: Vec<Vec<i32>> = keys
        .iter()
        .enumerate()
        .map(|(i, k)| corpus_words(&programs[k.program], fw.keys[0] as usize + i, samples))
        .collect();
    let mut insts: Vec<FixedInstance> = keys
        .iter()
        .map(|k| {
            let p = &programs[k.program];
            FixedInstance::with_params(&p.fixed, p.params.clone())
        })
        .collect();
    let mut lims: Vec<Limiter> = keys
        .iter()
        .map(|_| Limiter::new(image.limiter_config()).unwrap())
        .collect();
    let (mut bad, mut first) = (0, Vec::new());
    let mut worst = vec![0u64; image.cores()];
    let mut sensors = vec![0i32; keys.len()];
    let mut misses = Vec::new();
    for n in 0..samples {
        for (s, w) in sensors.iter_mut().zip(&words) {
            *s = w[n];
        }
        let got = run.step(&sensors).unwrap();
        for (c, w) in worst.iter_mut().enumerate() {
            *w = (*w).max(got.core_cycles[c]);
        }
        for (k, spec) in keys.iter().enumerate() {
            let want = insts[k].step_raw(&[sensors[k]]).total;
            let lim = lims[k].step(want, programs[spec.program].fixed.total_frac);
            if (got.force[k], got.dac[k]) != (want, lim.dac) {
                bad += 1;
                if first.len() < 3 {
                    first.push(format!(
                        "board {} key {k} sample {n}: image force {} dac {}, reference {want} {}",
                        fw.index, got.force[k], got.dac[k], lim.dac
                    ));
                }
            }
        }
        misses.clone_from(&got.misses);
    }
    (bad, first, misses, worst)
}

/// UF2 blocks read from the specification: (flags, target, payload size, block number,
/// block count, family, payload).
type Block = (u32, u32, u32, u32, u32, u32, Vec<u8>);

fn read_uf2(bytes: &[u8]) -> Vec<Block> {
    assert_eq!(bytes.len() % 512, 0, "whole 512-byte blocks");
    bytes
        .chunks(512)
        .map(|b| {
            let w = |i: usize| u32::from_le_bytes(b[4 * i..4 * i + 4].try_into().unwrap());
            assert_eq!((w(0), w(1)), (0x0A32_4655, 0x9E5D_5157), "start magics");
            assert_eq!(w(127), 0x0AB1_6F30, "end magic");
            let size = w(4) as usize;
            assert!(size <= 476);
            (
                w(2),
                w(3),
                w(4),
                w(5),
                w(6),
                w(7),
                b[32..32 + size].to_vec(),
            )
        })
        .collect()
}

/// The striped SRAM address of `addr` (RP2040 datasheet 2.6.1, written here again: striped
/// word *w* is word *w*/4 of bank *w* mod 4; the non-striped alias of bank *b* is at
/// 0x21000000 + *b*·0x10000).
fn striped(addr: u32) -> u32 {
    match addr {
        0x2000_0000..=0x2004_1fff => addr,
        0x2100_0000..=0x2103_ffff => {
            let (bank, off) = ((addr - 0x2100_0000) >> 16, addr & 0xffff);
            0x2000_0000 + (off / 4) * 16 + bank * 4 + off % 4
        }
        _ => panic!("{addr:#x} is not SRAM"),
    }
}

/// The ELF's loadable bytes, read with `object` (program headers, physical addresses), at
/// their striped addresses.
fn elf_bytes(elf: &[u8]) -> BTreeMap<u32, u8> {
    use object::read::elf::{ElfFile32, ProgramHeader};
    let f = ElfFile32::<object::Endianness>::parse(elf).unwrap();
    let e = f.endian();
    let mut m = BTreeMap::new();
    for ph in f.elf_program_headers() {
        if ph.p_type(e) != object::elf::PT_LOAD {
            continue;
        }
        let data = ph.data(e, elf).unwrap();
        assert_eq!(
            data.len() as u32,
            ph.p_memsz(e),
            "no zero-fill beyond the file"
        );
        for (i, &b) in data.iter().enumerate() {
            let at = striped(ph.p_paddr(e) + i as u32);
            assert!(m.insert(at, b).is_none(), "two segments at {at:#x}");
        }
    }
    m
}

/// The UF2 checks of the issue, on one board.
fn check_uf2(fw: &BoardFirmware) {
    let blocks = read_uf2(&fw.uf2);
    let n = blocks.len() as u32;
    assert!(n > 0);
    let start = blocks[0].1;
    assert_eq!(
        start, 0x2000_0000,
        "starts at the entry stub, the lowest address"
    );
    let mut payload = Vec::new();
    for (i, (flags, target, size, no, count, family, data)) in blocks.into_iter().enumerate() {
        assert_eq!(flags, 0x2000, "family ID present, nothing else");
        assert_eq!(family, 0xe48b_ff56, "RP2040 family");
        assert_eq!(size, 256, "256-byte payloads");
        assert_eq!((no, count), (i as u32, n), "contiguous block numbers");
        assert_eq!(
            target,
            start + 256 * i as u32,
            "contiguous target addresses"
        );
        assert!(
            (0x2000_0000..0x2004_2000).contains(&target),
            "a RAM target the boot ROM accepts"
        );
        payload.extend(data);
    }
    // The payload is the ELF's loadable bytes (at their striped addresses), zeros between.
    let elf = elf_bytes(&fw.elf);
    for (i, &b) in payload.iter().enumerate() {
        let at = start + i as u32;
        assert_eq!(b, elf.get(&at).copied().unwrap_or(0), "byte at {at:#x}");
    }
    let last = *elf.keys().last().unwrap();
    assert!(
        last < start + payload.len() as u32,
        "every ELF byte in the UF2"
    );
}

fn run_tool(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{cmd:?} failed:\n{text}");
    text
}

/// `uf2conv.py --info` and a conversion back to binary, by the format's own tool.
fn check_with_uf2conv(fw: &BoardFirmware, dir: &Path) {
    let script = root().join("tests/tools/uf2/uf2conv.py");
    let uf2 = dir.join(format!("{}.uf2", fw.dir_name()));
    let bin = dir.join(format!("{}.bin", fw.dir_name()));
    std::fs::write(&uf2, &fw.uf2).unwrap();
    let info = run_tool(Command::new("python3").arg(&script).arg("--info").arg(&uf2));
    assert!(
        info.contains("Family ID is RP2040, hex value is 0xe48bff56"),
        "{info}"
    );
    assert!(info.contains("Target Address is 0x20000000"), "{info}");
    assert!(
        info.contains("All block flag values consistent, 0x2000"),
        "{info}"
    );
    run_tool(
        Command::new("python3")
            .arg(&script)
            .arg("--convert")
            .arg("--output")
            .arg(&bin)
            .arg(&uf2),
    );
    let flat = std::fs::read(&bin).unwrap();
    let elf = elf_bytes(&fw.elf);
    for (&at, &b) in &elf {
        assert_eq!(
            flat[(at - 0x2000_0000) as usize],
            b,
            "uf2conv byte at {at:#x}"
        );
    }
}

fn check_with_binutils(fw: &BoardFirmware, dir: &Path) {
    let elf = dir.join(format!("{}.elf", fw.dir_name()));
    std::fs::write(&elf, &fw.elf).unwrap();
    let re = run_tool(
        Command::new("arm-none-eabi-readelf")
            .arg("-a")
            .arg("-W")
            .arg(&elf),
    );
    assert!(
        !re.to_lowercase().contains("warning"),
        "readelf complains:\n{re}"
    );
    assert!(re.contains("EXEC (Executable file)"), "{re}");
    assert!(
        re.contains("Entry point address:               0x20000001"),
        "{re}"
    );
    let od = run_tool(Command::new("arm-none-eabi-objdump").arg("-d").arg(&elf));
    assert!(
        !od.to_lowercase().contains("warning"),
        "objdump complains:\n{od}"
    );
    assert!(
        od.contains("<core0_sample_isr>:"),
        "objdump finds the handler"
    );
}

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tactus-flash-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn check_layout(layout: &str) {
    let t = std::time::Instant::now();
    let (boards, board) = firmware(layout);
    let built = t.elapsed();
    let dir = out_dir(layout.rsplit('/').next().unwrap().trim_end_matches(".toml"));
    let (uf2conv, binutils) = (tool("python3"), tool("arm-none-eabi-readelf"));
    for fw in &boards {
        check_uf2(fw);
        if uf2conv {
            check_with_uf2conv(fw, &dir);
        }
        if binutils {
            check_with_binutils(fw, &dir);
        }
    }
    // One emulated second per board, boards on the host's cores.
    let results: Vec<_> = std::thread::scope(|s| {
        let chunks: Vec<_> = boards.chunks(boards.len().div_ceil(2).max(1)).collect();
        let handles: Vec<_> = chunks
            .into_iter()
            .map(|c| {
                let board = &board;
                s.spawn(move || {
                    c.iter()
                        .map(|fw| boot_and_run(fw, board))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    for (fw, (bad, first, misses, worst)) in boards.iter().zip(&results) {
        println!(
            "{layout} board {} keys {:?}: {} UF2 blocks, worst handler cycles {worst:?} of {}, misses {misses:?}",
            fw.index,
            fw.keys,
            fw.uf2.len() / 512,
            fw.image.cycles_per_sample()
        );
        assert_eq!(*bad, 0, "mismatches: {first:?}");
        assert!(
            misses.iter().all(|&m| m == 0),
            "board {}: misses {misses:?}",
            fw.index
        );
    }
    println!(
        "{layout}: {} boards built in {built:.1?}, checked and run in {:.1?}",
        boards.len(),
        t.elapsed()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_grand88_board_boots_from_its_elf_and_runs_a_second_bit_exact_without_misses() {
    check_layout("instruments/layouts/grand88.toml");
}

#[test]
fn every_split_keyboard_board_boots_from_its_elf_and_runs_a_second_bit_exact_without_misses() {
    check_layout("instruments/layouts/split_harpsichord_piano.toml");
}

#[test]
fn a_bad_ram_image_is_an_error_not_a_uf2() {
    use tactus_firmware::uf2::{rp2040_ram, Uf2Error};
    assert_eq!(
        rp2040_ram(&[(0x1000_0000, vec![1, 2, 3, 4])]),
        Err(Uf2Error::NotRam { addr: 0x1000_0000 })
    );
    // Bank 1's word 0 through the alias is striped word 1.
    assert_eq!(
        rp2040_ram(&[(0x2000_0004, vec![1]), (0x2101_0000, vec![2])]),
        Err(Uf2Error::Overlap { addr: 0x2000_0004 })
    );
    let ok = rp2040_ram(&[(0x2101_0000, vec![7; 8])]).unwrap();
    let blocks = read_uf2(&ok);
    assert_eq!(blocks.len(), 1);
    assert_eq!(blocks[0].1, 0x2000_0000);
    assert_eq!(&blocks[0].6[4..8], &[7; 4]);
    assert_eq!(&blocks[0].6[20..24], &[7; 4]);
    assert_eq!(blocks[0].6[0], 0);
}
