//! Prints the optimised Cranelift IR of the fixed JIT for one `.tactus` file (the JIT prints
//! it to stderr when `TACTUS_JIT_DUMP` is set), plus the fixed-point formats of its values.
//!
//! `TACTUS_JIT_DUMP=1 cargo run --release -p tactus-jit --example clif -- file.tactus`
fn main() {
    let path = std::env::args().nth(1).expect("usage: clif FILE.tactus");
    let src = std::fs::read_to_string(&path).expect("readable file");
    let program = tactus_compiler::compile(&src, &tactus_compiler::lower::Config::default())
        .expect("compiles")
        .program;
    let fp = tactus_compiler::fixed::FixedProgram::new(&program);
    for (i, v) in program.values.iter().enumerate() {
        println!("v{i}: {:?}  frac {}", v.op, fp.frac[i]);
    }
    match tactus_jit::FixedJitProgram::compile(&fp) {
        Ok(_) => println!("compiled"),
        Err(e) => println!("error: {e}"),
    }
}
