//! Firmware a user can flash (issues 20 and 39): every board of the shipped layouts built
//! as `tactus build LAYOUT --target rp2040 [--board rp2040_200mhz]` builds it, at 133 and
//! 200 MHz, booted from its flash UF2 in the emulator — the boot ROM's CRC check of boot2,
//! boot2 setting the flash up for XIP, the image copying itself to SRAM, then the entry
//! stub, the core voltage and clock set-up, core 1 launched over the SIO FIFOs by the boot
//! ROM's protocol — and run on the budget corpus's physical runs (`layouts::physical_words`:
//! the sensor check is on, as shipped) against the fixed interpreter and the reference
//! limiter, from the first sample: every force word, DAC word and event (so every strike) bit-exact, no
//! deadline missed. Each UF2 checked by a reader written here from the format's
//! specification (microsoft/uf2 `README.md`) and by the format's own `uf2conv.py` (vendored
//! in `tests/tools/uf2/`), its flash bytes equal to the ELF's loadable bytes at their
//! physical addresses; each ELF read by `arm-none-eabi-readelf` and `arm-none-eabi-objdump`.
//!
//! Each core's worst measured handler stays within its static bound, and holds one copy of
//! each instrument's code. In CI every board boots and runs [`SHORT`] samples, and the
//! first and last board of each layout a whole emulated second; `cargo test -p
//! tactus-firmware --test flash -- --ignored` runs every board for a second and compares it
//! with its RAM image, sample by sample and cycle by cycle.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_firmware::flash::{BoardFirmware, Load};
use tactus_firmware::image::ImageRun;
use tactus_runtime::keyboard::BoardSpec;
use tactus_runtime::limiter::Limiter;

#[path = "common/layouts.rs"]
mod layouts;
use layouts::{firmware, on_host_threads, physical_words, root};

/// Samples every board runs in CI (the first and last board of each layout run a second).
const SHORT: usize = 2_205;

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

/// What one board's run measured.
#[derive(Debug, Default)]
struct Outcome {
    /// Samples with a force, DAC or event mismatch against the interpreter and limiter.
    bad: usize,
    first: Vec<String>,
    misses: Vec<u32>,
    worst: Vec<u64>,
    /// Events (every one compared with the interpreter's).
    events: usize,
    /// Cycles from power-on to the first sample tick.
    boot_cycles: u64,
    /// Per sample: every DAC word, event count and each core's handler cycles (for the
    /// comparison with the RAM image, `--ignored` only).
    trace: Vec<(Vec<i16>, usize, Vec<u64>)>,
}

/// Runs `samples` samples of the corpus's physical runs on `run` (booted from `fw`) against
/// the fixed interpreter and the reference limiter.
fn run_corpus(fw: &BoardFirmware, mut run: ImageRun, samples: usize, trace: bool) -> Outcome {
    let image = &fw.image;
    let programs = image.programs();
    let keys = image.keys();
    let words: Vec<Vec<i32>> = keys
        .iter()
        .enumerate()
        .map(|(i, k)| physical_words(&programs[k.program], fw.keys[0] as usize + i, samples))
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
    let mut out = Outcome {
        worst: vec![0u64; image.cores()],
        boot_cycles: run.tick_cycle(0),
        ..Outcome::default()
    };
    let mut sensors = vec![0i32; keys.len()];
    for n in 0..samples {
        for (s, w) in sensors.iter_mut().zip(&words) {
            *s = w[n];
        }
        let got = run.step(&sensors).unwrap();
        for (c, w) in out.worst.iter_mut().enumerate() {
            *w = (*w).max(got.core_cycles[c]);
        }
        let mut bad = false;
        for (k, spec) in keys.iter().enumerate() {
            let want = insts[k].step_raw(&[sensors[k]]);
            let lim = lims[k].step(want.total, programs[spec.program].fixed.total_frac);
            let events: Vec<_> = got
                .events
                .iter()
                .filter(|e| e.key == k)
                .map(|e| (e.event, e.args.clone()))
                .collect();
            if (got.force[k], got.dac[k], &events) != (want.total, lim.dac, &want.events) {
                bad = true;
                if out.first.len() < 3 {
                    out.first.push(format!(
                        "board {} key {k} sample {n}: image force {} dac {} events {events:?}, \
                         reference {} {} {:?}",
                        fw.index, got.force[k], got.dac[k], want.total, lim.dac, want.events
                    ));
                }
            }
        }
        out.bad += bad as usize;
        out.events += got.events.len();
        out.misses.clone_from(&got.misses);
        if trace {
            out.trace
                .push((got.dac.clone(), got.events.len(), got.core_cycles.clone()));
        }
    }
    out
}

/// The flash bytes a UF2 writes, read from the specification: blocks at 256-byte aligned
/// flash addresses, contiguous from 0x10000000, every byte written once.
fn uf2_flash(bytes: &[u8]) -> Vec<u8> {
    let blocks = read_uf2(bytes);
    let n = blocks.len() as u32;
    let mut flash = Vec::new();
    for (i, (flags, target, size, no, count, family, data)) in blocks.into_iter().enumerate() {
        assert_eq!(flags, 0x2000, "family ID present, nothing else");
        assert_eq!(family, 0xe48b_ff56, "RP2040 family");
        assert_eq!(size, 256, "256-byte payloads");
        assert_eq!((no, count), (i as u32, n), "contiguous block numbers");
        assert_eq!(
            target,
            0x1000_0000 + 256 * i as u32,
            "contiguous flash blocks"
        );
        flash.extend(data);
    }
    flash
}

/// Boots `fw` from its flash UF2 (as the reader above decodes it) and runs `samples`
/// samples; also checks what the boot left: the clock and core voltage the board file
/// names, core 1 launched with the key map's vector table, the code in SRAM the image's,
/// each key's param block.
fn boot_and_run(fw: &BoardFirmware, board: &BoardSpec, samples: usize, trace: bool) -> Outcome {
    let image = &fw.image;
    let flash = uf2_flash(&fw.uf2);
    let mut run =
        ImageRun::from_flash(image, &flash).unwrap_or_else(|e| panic!("board {}: {e}", fw.index));
    let b = run.board();
    assert_eq!(
        b.system.sysctl.clk_sys_hz(),
        Some(board.clock_hz as u64),
        "board {}: clk_sys as programmed",
        fw.index
    );
    assert_eq!(
        Some(b.system.sysctl.core_mv()),
        board.core_mv().or(Some(1100)),
        "board {}: the core voltage",
        fw.index
    );
    assert_eq!(b.system.watchdog.tick_cycles(), Some(12), "1 µs timer tick");
    if image.cores() == 2 {
        let vt = &fw.key_map.cores[1].vector_table;
        assert_eq!(format!("{:#010x}", b.cores[1].nvic.vtor), *vt);
        assert_eq!(
            b.system.sio.fifo_status(0) & 0xd,
            0,
            "FIFO drained, no error"
        );
    }
    // The code in SRAM is the image's (its data has started changing).
    for (i, (addr, data)) in image.segments().iter().enumerate() {
        if i == 0 || i % 2 == 1 {
            let mut got = vec![0; data.len()];
            b.read_bytes(*addr, &mut got).unwrap();
            assert!(got == *data, "board {}: segment {i} in SRAM", fw.index);
        }
    }
    let programs = image.programs();
    // The key map's param block holds each key's words, as booted (graded keys share code).
    for (entry, k) in fw.key_map.keys.iter().zip(image.keys()) {
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
    run_corpus(fw, run, samples, trace)
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
/// 0x21000000 + *b*·0x10000); flash addresses as they are.
fn striped(addr: u32) -> u32 {
    match addr {
        0x1000_0000..=0x101f_ffff | 0x2000_0000..=0x2004_1fff => addr,
        0x2100_0000..=0x2103_ffff => {
            let (bank, off) = ((addr - 0x2100_0000) >> 16, addr & 0xffff);
            0x2000_0000 + (off / 4) * 16 + bank * 4 + off % 4
        }
        _ => panic!("{addr:#x} is neither flash nor SRAM"),
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

/// The UF2 checks of the issues, on one board: a flash UF2 whose bytes are the flash
/// image's and the ELF's loadable bytes (zeros between them), with a boot2 the boot ROM
/// accepts.
fn check_uf2(fw: &BoardFirmware) {
    let flash = uf2_flash(&fw.uf2);
    assert!(!flash.is_empty());
    let image = fw.flash.as_ref().unwrap();
    assert_eq!(&flash[..image.bytes.len()], &image.bytes[..]);
    assert!(flash[image.bytes.len()..].iter().all(|&b| b == 0));
    let b2: [u8; 256] = flash[..256].try_into().unwrap();
    assert!(tactus_rp2040::bootrom::check_boot2(&b2).is_ok());
    let elf = elf_bytes(&fw.elf);
    for (i, &b) in flash.iter().enumerate() {
        let at = 0x1000_0000 + i as u32;
        assert_eq!(b, elf.get(&at).copied().unwrap_or(0), "byte at {at:#x}");
    }
    let last = *elf.keys().last().unwrap();
    assert!(
        last < 0x1000_0000 + flash.len() as u32,
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
fn check_with_uf2conv(fw: &BoardFirmware, dir: &Path, start: u32) {
    let script = root().join("tests/tools/uf2/uf2conv.py");
    let uf2 = dir.join(format!("{}.uf2", fw.dir_name()));
    let bin = dir.join(format!("{}.bin", fw.dir_name()));
    std::fs::write(&uf2, &fw.uf2).unwrap();
    let info = run_tool(Command::new("python3").arg(&script).arg("--info").arg(&uf2));
    assert!(
        info.contains("Family ID is RP2040, hex value is 0xe48bff56"),
        "{info}"
    );
    assert!(
        info.contains(&format!("Target Address is {start:#010x}")),
        "{info}"
    );
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
        assert_eq!(flat[(at - start) as usize], b, "uf2conv byte at {at:#x}");
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
    let entry = u32::from_str_radix(fw.key_map.entry.trim_start_matches("0x"), 16).unwrap();
    assert!(
        re.contains(&format!("Entry point address:               {entry:#x}")),
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
    if fw.load() == Load::Flash {
        assert!(
            od.contains("<_stage2_boot>:") && od.contains("<_flash_reset>:"),
            "{od}"
        );
    }
}

fn out_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tactus-flash-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Builds every board of `layout` on the board file `kind`, checks every UF2 and ELF,
/// boots every board from its flash UF2 and runs `short` samples, and `full` boards a whole
/// second (with `compare`, each against its RAM image too, sample by sample and cycle by
/// cycle). Returns the number of boards.
fn check_layout(
    layout: &str,
    kind: &str,
    full: &(dyn Fn(usize, usize) -> bool + Sync),
    compare: bool,
) -> usize {
    let t = std::time::Instant::now();
    let (boards, board) = firmware(layout, Some(kind), Load::Flash);
    let built = t.elapsed();
    let name = layout.rsplit('/').next().unwrap().trim_end_matches(".toml");
    let dir = out_dir(&format!("{name}-{kind}"));
    let (uf2conv, binutils) = (tool("python3"), tool("arm-none-eabi-readelf"));
    for fw in &boards {
        // One code copy per instrument per core: graded params are run-time data.
        for c in 0..fw.image.cores() {
            let mut instruments: Vec<&str> = fw
                .key_map
                .keys
                .iter()
                .filter(|k| k.core == c)
                .map(|k| k.instrument.as_str())
                .collect();
            instruments.sort_unstable();
            instruments.dedup();
            assert_eq!(
                fw.image.code_copies(c),
                instruments.len(),
                "board {} core {c}: {instruments:?}",
                fw.index
            );
        }
        check_uf2(fw);
        if uf2conv {
            check_with_uf2conv(fw, &dir, 0x1000_0000);
        }
        if binutils {
            check_with_binutils(fw, &dir);
        }
    }
    let second = board.sample_rate_hz as usize;
    let n = boards.len();
    // Boards on the host's cores.
    let results: Vec<(Outcome, Option<Outcome>)> = on_host_threads(&boards, |fw| {
        let whole = full(fw.index - 1, n);
        let samples = if whole { second } else { SHORT };
        let flash = boot_and_run(fw, &board, samples, compare && whole);
        let ram =
            (compare && whole).then(|| run_corpus(fw, fw.image.run().unwrap(), samples, true));
        (flash, ram)
    });
    for (fw, (o, ram)) in boards.iter().zip(&results) {
        println!(
            "{layout} at {kind}: board {} keys {}-{}: {} UF2 blocks, boot {:.2} ms to the first tick, \
             worst handler cycles {:?} of {}, {} events, misses {:?}",
            fw.index,
            fw.keys[0],
            fw.keys[fw.keys.len() - 1],
            fw.uf2.len() / 512,
            o.boot_cycles as f64 / board.clock_hz * 1e3,
            o.worst,
            fw.image.cycles_per_sample(),
            o.events,
            o.misses
        );
        assert_eq!(o.bad, 0, "mismatches: {:?}", o.first);
        assert!(
            o.misses.iter().all(|&m| m == 0),
            "board {}: misses {:?}",
            fw.index,
            o.misses
        );
        for (c, &w) in o.worst.iter().enumerate() {
            let bound = fw.image.wcet(c).unwrap().bound();
            assert!(
                w <= bound,
                "board {} core {c}: measured {w} > static {bound}",
                fw.index
            );
        }
        if let Some(r) = ram {
            assert_eq!(r.bad, 0, "RAM image mismatches: {:?}", r.first);
            let same = o.trace.iter().zip(&r.trace).filter(|(a, b)| a == b).count();
            assert_eq!(
                (same, o.trace.len()),
                (r.trace.len(), r.trace.len()),
                "board {}: samples equal to the RAM image's (DAC words, events, handler cycles)",
                fw.index
            );
        }
    }
    println!(
        "{layout} at {kind}: {n} boards built in {built:.1?}, checked and run in {:.1?}",
        t.elapsed()
    );
    let _ = std::fs::remove_dir_all(&dir);
    n
}

/// In CI: every board a short run, the first and last a second.
fn ends(i: usize, n: usize) -> bool {
    i == 0 || i + 1 == n
}

#[test]
fn every_grand88_board_boots_from_flash_at_133_mhz() {
    assert_eq!(
        check_layout("instruments/layouts/grand88.toml", "rp2040", &ends, false),
        11,
        "grand88's board count at 133 MHz (issue 38: four piano keys per core)"
    );
}

#[test]
fn every_grand88_board_boots_from_flash_at_200_mhz() {
    assert_eq!(
        check_layout(
            "instruments/layouts/grand88.toml",
            "rp2040_200mhz",
            &ends,
            false
        ),
        8
    );
}

#[test]
fn every_split_keyboard_board_boots_from_flash_at_133_mhz() {
    check_layout(
        "instruments/layouts/split_harpsichord_piano.toml",
        "rp2040",
        &ends,
        false,
    );
}

#[test]
fn every_split_keyboard_board_boots_from_flash_at_200_mhz() {
    check_layout(
        "instruments/layouts/split_harpsichord_piano.toml",
        "rp2040_200mhz",
        &ends,
        false,
    );
}

/// The whole check (minutes): every board of both layouts at 133 and 200 MHz boots from its
/// flash UF2 and plays one emulated second of the corpus bit-exact, without a miss, and
/// sample for sample (DAC words, events, handler cycles) as its RAM image.
#[test]
#[ignore]
fn every_board_boots_from_flash_and_plays_a_second_as_its_ram_image() {
    let all = |_, _| true;
    for layout in [
        "instruments/layouts/grand88.toml",
        "instruments/layouts/split_harpsichord_piano.toml",
    ] {
        for kind in ["rp2040", "rp2040_200mhz"] {
            check_layout(layout, kind, &all, true);
        }
    }
}

/// `--ram` firmware: a RAM-only UF2 from 0x20000000 and an ELF that boots at its entry
/// stub, running as before (on a small layout of two harpsichord and two piano keys).
#[test]
fn ram_only_firmware_stays_available() {
    let dir = out_dir("ram");
    let layout = dir.join("small.toml");
    std::fs::write(
        &layout,
        "name = \"small\"\n\
         [[range]]\nkeys = [60, 61]\ninstrument = \"harpsichord_2x8\"\n\
         [[range]]\nkeys = [62, 63]\ninstrument = \"grand_piano\"\n",
    )
    .unwrap();
    let (boards, board) = firmware(layout.to_str().unwrap(), None, Load::Ram);
    let fw = &boards[0];
    assert!(fw.flash.is_none() && fw.load() == Load::Ram);
    let blocks = read_uf2(&fw.uf2);
    assert_eq!(blocks[0].1, 0x2000_0000);
    let elf = elf_bytes(&fw.elf);
    let mut payload: Vec<u8> = Vec::new();
    for (i, (flags, target, ..)) in blocks.iter().enumerate() {
        assert_eq!((*flags, *target), (0x2000, 0x2000_0000 + 256 * i as u32));
    }
    for b in &blocks {
        payload.extend(&b.6);
    }
    for (&at, &b) in &elf {
        assert_eq!(
            payload[(at - 0x2000_0000) as usize],
            b,
            "RAM UF2 byte at {at:#x}"
        );
    }
    if tool("python3") {
        check_with_uf2conv(fw, &dir, 0x2000_0000);
    }
    let _ = std::fs::remove_dir_all(&dir);
    let run = ImageRun::from_elf(&fw.image, &fw.elf, None).unwrap();
    let o = run_corpus(fw, run, SHORT, false);
    assert_eq!(o.bad, 0, "{:?}", o.first);
    assert!(o.misses.iter().all(|&m| m == 0));
    let _ = board;
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
