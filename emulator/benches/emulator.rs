//! Emulated cycles per host second, one core and both cores, on a loop mixing ALU,
//! multiply, SRAM loads/stores and a taken branch (criterion reports "elements" = cycles).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use tactus_emulator::{Board, Config};

/// loop: ldr r1,[r0]; adds r1,r1,r2; str r1,[r0,#4]; muls r3,r1,r3; lsrs r4,r3,#3;
///       subs r5,#1; bne loop  — 10 cycles per iteration.
const LOOP: [u16; 7] = [0x6801, 0x1889, 0x6041, 0x434b, 0x08dc, 0x3d01, 0xd1f8];

fn board(cores: usize) -> Board {
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
    b
}

fn bench(c: &mut Criterion) {
    const CYCLES: u64 = 1_000_000;
    let mut group = c.benchmark_group("emulated_cycles");
    group.throughput(Throughput::Elements(CYCLES));
    for cores in [1, 2] {
        let mut b = board(cores);
        group.bench_function(format!("{cores}_core"), |bench| {
            bench.iter(|| b.run_for(CYCLES))
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10).measurement_time(std::time::Duration::from_secs(3)).warm_up_time(std::time::Duration::from_secs(1));
    targets = bench
}
criterion_main!(benches);
