//! Runs the grand piano's `mf-dip` stimulus through the fixed JIT's `run_block` many times:
//! the workload for counting instructions per key-sample with callgrind.
//!
//! ```text
//! CARGO_TARGET_DIR=/work/target-jit cargo build --release -p tactus-jit --example fixed_block
//! valgrind --tool=callgrind /work/target-jit/release/examples/fixed_block [engine] [repeats]
//! ```
//!
//! `engine`: `block` (default), `step`, `jit-f64`, `interp-fixed`, `interp-f64`, or `none`
//! (setup only, to subtract). Prints the number of key-samples run.

use tactus_compiler::fixed::interp::FixedInstance;
use tactus_compiler::fixed::FixedProgram;
use tactus_compiler::interp::Instance;
use tactus_compiler::lower::Config;
use tactus_jit::{FixedJitInstance, FixedJitProgram, JitInstance, JitProgram};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let engine = args.get(1).map_or("block", String::as_str);
    let repeats: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(10);
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../instruments/grand_piano.tactus"
    );
    let src = std::fs::read_to_string(path).expect("grand_piano.tactus");
    let program = tactus_compiler::compile(&src, &Config::default())
        .expect("compiles")
        .program;
    let dip = program.sensors[0].range.1;
    let stim = tactus_runtime::stimulus::builtin("mf-dip", dip, 44_100.0).expect("stimulus");
    let fp = FixedProgram::new(&program);
    let fjit = FixedJitProgram::compile(&fp).expect("fixed jit");
    let jit = JitProgram::compile(&program).expect("jit");
    let raw: Vec<i32> = stim
        .key
        .iter()
        .map(|&k| FixedInstance::sensor_raw(&fp, 0, Some(k)))
        .collect();
    let mut totals = vec![0i32; raw.len()];
    let mut sum = 0i64;
    for _ in 0..repeats {
        match engine {
            "block" => {
                let mut inst = FixedJitInstance::new(&fjit);
                inst.run_block(&raw, &mut totals);
                sum += totals.iter().map(|&t| i64::from(t)).sum::<i64>();
            }
            "step" => {
                let mut inst = FixedJitInstance::new(&fjit);
                for &k in &raw {
                    sum += i64::from(inst.step_raw(&[k]).total);
                }
            }
            "jit-f64" => {
                let mut inst = JitInstance::new(&jit);
                for &k in &stim.key {
                    sum += inst.step(&[k]).total as i64;
                }
            }
            "interp-fixed" => {
                let mut inst = FixedInstance::new(&fp);
                for &k in &raw {
                    sum += i64::from(inst.step_raw(&[k]).total);
                }
            }
            "interp-f64" => {
                let mut inst = Instance::new(&program);
                for &k in &stim.key {
                    sum += inst.step(&[k]).total as i64;
                }
            }
            _ => {}
        }
    }
    println!("{} key-samples (checksum {sum})", raw.len() * repeats);
}
