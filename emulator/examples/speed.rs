//! Fixed workloads for measuring host instructions per emulated cycle under callgrind:
//! the criterion bench's loop (SRAM load, add, SRAM store, MULS, shift, subtract, taken
//! branch; 10 cycles per iteration) on one or both cores, and its firmware-like key updates
//! (the workloads are `benches/common/mod.rs`, shared with the bench).
//!
//! ```text
//! cargo build --release -p tactus-emulator --example speed
//! valgrind --tool=callgrind target/release/examples/speed 1 5000000 block
//! ```
//!
//! Arguments: `mode cycles engine`. `mode` 1 or 2 runs the loop on 1 or 2 cores; 3 runs
//! the loop on core 0 with core 1 started but asleep in WFI (no interrupt will wake it);
//! 4 runs, on core 0, a loop calling a profiled function (`Board::profile_addr`) that does
//! the SRAM load, add and store (16 cycles per call); 5 and 6 run the key updates (44 keys
//! per core, SysTick every 3,016 cycles) on 1 and 2 cores; 7 and 8 run the loop with each
//! core's code and data in its own SRAM bank on 1 and 2 cores (the cores run ahead of each
//! other, `Config::own_banks`). `engine` is `block` (default)
//! or `interp`. Prints the cycles run, each core's registers as a checksum, and the
//! wall-clock rate.

use tactus_emulator::Engine;

#[path = "../benches/common/mod.rs"]
mod common;

fn main() {
    let mut args = std::env::args().skip(1);
    let mode: usize = args.next().map_or(1, |a| a.parse().expect("mode: 1 to 6"));
    let cores = if mode == 2 || mode == 3 || mode == 6 || mode == 8 {
        2
    } else {
        1
    };
    let cycles: u64 = args
        .next()
        .map_or(5_000_000, |a| a.parse().expect("cycles"));
    let engine = match args.next().as_deref() {
        None | Some("block") => Engine::Block,
        Some("interp") => Engine::Interp,
        Some(other) => panic!("engine: block or interp, not {other}"),
    };
    let mut b = if mode >= 7 {
        common::speed_loop_own_banks(engine, cores)
    } else if mode >= 5 {
        common::key_updates(engine, cores, 44, 3016)
    } else {
        common::speed_loop(engine, if mode == 2 { 2 } else { 1 })
    };
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
    println!(
        "{stop:?} after {} cycles ({engine:?}, {} blocks decoded)",
        b.cycle(),
        b.blocks_decoded()
    );
    println!(
        "run-ahead windows (kept, rolled back): {:?}; code epoch {}",
        b.run_ahead_windows(),
        b.system.code_epoch
    );
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
    if mode == 5 || mode == 6 {
        let dac: Vec<u32> = (0..4)
            .map(|k| b.read_u32(0x2003_f400 + 4 * k).unwrap())
            .collect();
        println!("dac[0..4] = {dac:?}");
    }
    println!("{:.1} M cycles/s per core", cycles as f64 / secs / 1e6);
}
