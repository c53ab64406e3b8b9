//! Compile a touch profile and run it on the cranelift JIT, sample by sample, beside the
//! reference interpreter that defines its meaning.
//!
//! ```text
//! cargo run --release --example jit_profile                        # grand_piano, ff-dip
//! cargo run --release --example jit_profile -- harpsichord mf-dip  # INSTRUMENT [STIMULUS]
//! ```
//!
//! The instrument is a built-in name or a `.tactus` file (`tactus_host::catalogue::load`);
//! the stimulus a built-in key stimulus (`tactus sim --help` lists them) scaled to the key
//! sensor's travel. The library calls, in order: `tactus_compiler::compile` (parse, check,
//! lower to IR at 44.1 kHz), `tactus_jit::JitProgram::compile` (IR to native code),
//! `JitInstance::step` once per sample; each sample's forces, outputs and events are
//! compared with `tactus_compiler::interp::Instance::step` (they are equal bit for bit).
//! Prints the peak force and every event. Exit code 1 on bad input or a difference.

use std::process::ExitCode;
use tactus_compiler::interp::Instance;
use tactus_compiler::lower::Config;
use tactus_jit::{JitInstance, JitProgram};

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let instrument = args.next().unwrap_or_else(|| "grand_piano".to_string());
    let stimulus = args.next().unwrap_or_else(|| "ff-dip".to_string());
    match run(&instrument, &stimulus) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(instrument: &str, stimulus: &str) -> Result<(), String> {
    let src = tactus_host::catalogue::load(instrument)?;
    let lowered = tactus_compiler::compile(&src.text, &Config::default())
        .map_err(|d| tactus_compiler::diagnostics::emit_to_string(&src.name, &src.text, &d))?;
    let program = lowered.program;
    let [sensor] = program.sensors.as_slice() else {
        return Err(format!(
            "{}: {} sensors; this example drives one key sensor",
            src.name,
            program.sensors.len()
        ));
    };
    let dip_m = sensor.range.1;
    let stim = tactus_runtime::stimulus::builtin(stimulus, dip_m, program.sample_rate_hz)
        .map_err(|e| e.to_string())?;

    let jit = JitProgram::compile(&program).map_err(|e| format!("JIT: {e}"))?;
    let mut native = JitInstance::new(&jit);
    let mut reference = Instance::new(&program);
    let (mut peak_n, mut peak_at) = (0.0f64, 0);
    for (n, &x) in stim.key.iter().enumerate() {
        let out = native.step(&[x]);
        if out != reference.step(&[x]) {
            return Err(format!("sample {n}: the JIT differs from the interpreter"));
        }
        if out.total.abs() > peak_n.abs() {
            (peak_n, peak_at) = (out.total, n);
        }
        for (event, args) in &out.events {
            let decl = &program.events[event.index()];
            let shown: Vec<String> = (decl.args.iter().zip(args))
                .map(|((name, _), v)| format!("{name} = {v:.4}"))
                .collect();
            println!(
                "{:8.4} s  {} ({})",
                n as f64 / program.sample_rate_hz,
                decl.name,
                shown.join(", ")
            );
        }
    }
    println!(
        "{}: {} samples of `{}` ({}) on the JIT, equal to the interpreter at every sample; \
         peak force {peak_n:.3} N at {:.4} s",
        src.name,
        stim.key.len(),
        stim.name,
        stim.description,
        peak_at as f64 / program.sample_rate_hz
    );
    Ok(())
}

/// `cargo test` builds this example and runs it briefly, so that it cannot go stale.
#[cfg(test)]
mod tests {
    #[test]
    fn runs_a_piano_key_and_a_harpsichord_key() {
        super::run("grand_piano", "ff-dip").unwrap();
        super::run("harpsichord", "mf-dip").unwrap();
        let e = super::run("grand_piano", "no-such-stimulus").unwrap_err();
        assert!(e.contains("no-such-stimulus"), "{e}");
    }
}
