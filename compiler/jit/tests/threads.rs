//! A compiled program (f64 or fixed-point) is shared by instances on several threads (one
//! key per thread).

use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::lower::Config;
use tactus_jit::{FixedJitInstance, FixedJitProgram, JitInstance, JitProgram};

fn piano() -> tactus_compiler::ir::Program {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../instruments/grand_piano.tactus"
    );
    let src = std::fs::read_to_string(path).expect("grand_piano.tactus");
    tactus_compiler::compile(&src, &Config::default())
        .expect("compiles")
        .program
}

#[test]
fn programs_are_shared_across_threads() {
    fn send_sync<T: Send + Sync>() {}
    send_sync::<JitProgram>();
    let jit = JitProgram::compile(&piano()).expect("compiles");
    let totals: Vec<f64> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..2)
            .map(|_| {
                s.spawn(|| {
                    let mut key = JitInstance::new(&jit);
                    (0..1000).map(|n| key.step(&[n as f64 * 1e-5]).total).sum()
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("no panic"))
            .collect()
    });
    assert_eq!(totals[0].to_bits(), totals[1].to_bits());
}

#[test]
fn fixed_programs_are_shared_across_threads() {
    fn send_sync<T: Send + Sync>() {}
    send_sync::<FixedJitProgram>();
    let fp = FixedProgram::new(&piano());
    let jit = FixedJitProgram::compile(&fp).expect("compiles");
    let rows: Vec<i32> = (0..1000).map(|n| n * 100_000).collect();
    let totals: Vec<Vec<i32>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..2)
            .map(|_| {
                s.spawn(|| {
                    let mut key = FixedJitInstance::new(&jit);
                    let mut totals = vec![0; rows.len()];
                    key.run_block(&rows, &mut totals);
                    totals
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("no panic"))
            .collect()
    });
    assert_eq!(totals[0], totals[1]);
}
