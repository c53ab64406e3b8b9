//! Fixed workload for measuring host instructions per emulated cycle under callgrind:
//! the criterion bench's loop (SRAM load, add, SRAM store, MULS, shift, subtract, taken
//! branch; 10 cycles per iteration) on one or both cores.
//!
//! ```text
//! cargo build --release -p tactus-emulator --example speed
//! valgrind --tool=callgrind target/release/examples/speed 1 5000000
//! ```
//!
//! `cores` = 3 runs the loop on core 0 with core 1 started but asleep in WFI (no interrupt
//! will wake it); `cores` = 4 runs, on core 0, a loop calling a profiled function
//! (`Board::profile_addr`) that does the SRAM load, add and store (16 cycles per call). Prints the cycles run, each core's registers as a checksum, and the
//! wall-clock rate.

use tactus_emulator::{Board, Config};

/// loop: ldr r1,[r0]; adds r1,r1,r2; str r1,[r0,#4]; muls r3,r1,r3; lsrs r4,r3,#3;
///       subs r5,#1; bne loop
const LOOP: [u16; 7] = [0x6801, 0x1889, 0x6041, 0x434b, 0x08dc, 0x3d01, 0xd1f8];

fn main() {
    let mut args = std::env::args().skip(1);
    let mode: usize = args
        .next()
        .map_or(1, |a| a.parse().expect("cores: 1, 2 or 3"));
    let cores = if mode == 2 || mode == 3 { 2 } else { 1 };
    let cycles: u64 = args
        .next()
        .map_or(5_000_000, |a| a.parse().expect("cycles"));
    let mut b = Board::new(Config::default());
    for core in 0..cores {
        let code: Vec<u8> = LOOP.iter().flat_map(|h| h.to_le_bytes()).collect();
        let at = 0x2000_0000 + 0x1000 * core as u32;
        b.write_bytes(at, &code).unwrap();
        b.start_core(core, at | 1, 0x2004_0000 + 0x800 * core as u32, 0);
        let c = &mut b.cores[core];
        c.r[0] = 0x2001_0000 + 0x100 * core as u32;
        c.r[2] = 3;
        c.r[3] = 7;
        c.r[5] = u32::MAX;
    }
    if mode == 3 {
        // Core 1: wfi; b .-2 (sleeps for good: no interrupt is enabled).
        b.write_bytes(0x2000_1000, &[0x30, 0xbf, 0xfd, 0xe7])
            .unwrap();
        b.start_core(1, 0x2000_1001, 0x2004_0800, 0);
    }
    let mut profile = None;
    if mode == 4 {
        // loop: bl func; subs r5, #1; bne loop ... func (+0x20): push {lr};
        // ldr r1, [r0]; adds r1, r1, r2; str r1, [r0, #4]; pop {pc}
        let mut code = vec![0xf000, 0xf80e, 0x3d01, 0xd1fb];
        code.resize(16, 0xbf00);
        code.extend([0xb500, 0x6801, 0x1889, 0x6041, 0xbd00]);
        let bytes: Vec<u8> = code.iter().flat_map(|h: &u16| h.to_le_bytes()).collect();
        b.write_bytes(0x2000_0000, &bytes).unwrap();
        profile = Some(b.profile_addr(0x2000_0020));
    }
    let t = std::time::Instant::now();
    let stop = b.run_for(cycles);
    let secs = t.elapsed().as_secs_f64();
    println!("{stop:?} after {} cycles", b.cycle());
    for c in &b.cores[..cores] {
        println!(
            "core {}: cycle {} instructions {} r = {:08x?} stalls {}",
            c.id, c.cycle, c.instructions, c.r, b.system.contention_stalls[c.id]
        );
    }
    if let Some(h) = profile {
        let calls = b.calls(h);
        let total: u64 = calls.iter().map(|c| c.cycles).sum();
        println!("{} profiled calls, {} cycles", calls.len(), total);
    }
    println!("{:.1} M cycles/s per core", cycles as f64 / secs / 1e6);
}
