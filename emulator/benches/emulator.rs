//! Emulated cycles per host second of the two engines in the same run (criterion reports
//! "elements" = emulated cycles): the speed loop (ALU, multiply, SRAM loads/stores and a
//! taken branch), the same loop with each core's code and data in its own SRAM bank, and
//! firmware-like key updates in the SysTick interrupt (see `common/mod.rs`), each on one
//! core and on both (per core: elements are each core's cycles).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use tactus_emulator::Engine;

mod common;

fn bench(c: &mut Criterion) {
    const CYCLES: u64 = 1_000_000;
    let mut group = c.benchmark_group("emulated_cycles");
    group.throughput(Throughput::Elements(CYCLES));
    for engine in [Engine::Interp, Engine::Block] {
        for cores in [1, 2] {
            let mut b = common::speed_loop(engine, cores);
            group.bench_function(format!("loop_{cores}_core_{engine:?}"), |bench| {
                bench.iter(|| b.run_for(CYCLES))
            });
        }
        for cores in [1, 2] {
            // Each core's code and data in its own bank: two cores run ahead of each other.
            let mut b = common::speed_loop_own_banks(engine, cores);
            group.bench_function(format!("own_banks_loop_{cores}_core_{engine:?}"), |bench| {
                bench.iter(|| b.run_for(CYCLES))
            });
        }
        for cores in [1, 2] {
            // 44 keys per core (88 on two cores: a whole keyboard) at 44.1 kHz / 133 MHz.
            let mut b = common::key_updates(engine, cores, 44, 3016);
            group.bench_function(format!("keys_{cores}_core_{engine:?}"), |bench| {
                bench.iter(|| b.run_for(CYCLES))
            });
        }
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10).measurement_time(std::time::Duration::from_secs(3)).warm_up_time(std::time::Duration::from_secs(1));
    targets = bench
}
criterion_main!(benches);
