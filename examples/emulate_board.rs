//! Build one board's firmware image and run it on the emulated RP2040, every key following
//! a key stimulus: the firmware `tactus build` writes, stepped a sample at a time.
//!
//! ```text
//! cargo run --release --example emulate_board                      # grand88's first board, mf-dip, 0.1 s
//! cargo run --release --example emulate_board -- hammond 2 ff-dip  # KEYBOARD [BOARD [STIMULUS [SECONDS]]]
//! ```
//!
//! The keyboard is a layout (`grand88`, a `.toml` file) or one instrument on 88 keys; the
//! board is its number in the keyboard's plan (from 1). The library calls, in order:
//! `tactus_host::keyboard::compile` (the one resolution and compilation of a keyboard),
//! `Keyboard::firmware` (fixed point and Thumb code per program), `Keyboard::plan` (the
//! boards `tactus budget` reports), `tactus_firmware::flash::keyboard_firmware` on the one
//! board (its image, ELF and flash UF2), then `FirmwareImage::run` and `ImageRun::step` once
//! per sample with every key's sensor word. Prints each core's static bound against the
//! worst handler it ran and its deadline misses. Exit code 1 on bad input, 2 on a miss.

use std::process::ExitCode;
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_firmware::flash::{self, KeyboardInput, Load};
use tactus_host::keyboard::{self, KeyboardSpec};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, default: &str| args.get(i).cloned().unwrap_or(default.to_string());
    let result = (|| {
        let board: usize = arg(1, "1").parse().map_err(|e| format!("BOARD: {e}"))?;
        let seconds: f64 = arg(3, "0.1").parse().map_err(|e| format!("SECONDS: {e}"))?;
        run(&arg(0, "grand88"), board, &arg(2, "mf-dip"), seconds)
    })();
    match result {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(2),
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// Runs board `which` (from 1) of `input`; whether no core missed a deadline.
fn run(input: &str, which: usize, stimulus: &str, seconds: f64) -> Result<bool, String> {
    if !(seconds > 0.0 && seconds <= 10.0) {
        return Err(format!("SECONDS {seconds}: from just above 0 to 10"));
    }
    let spec = KeyboardSpec {
        input,
        as_layout: None,
        board: None,
        keys: None,
        params: &[],
    };
    let kb = keyboard::compile(&spec, &mut |src, diagnostics| {
        eprint!(
            "{}",
            tactus_compiler::diagnostics::emit_to_string(&src.name, &src.text, diagnostics)
        )
    })
    .map_err(|e| e.to_string())?;
    let programs = kb.firmware().map_err(|e| e.to_string())?;
    let plan = kb
        .plan(&programs, &mut |_, _| {})
        .map_err(|e| e.to_string())?;
    let lists = plan.key_lists();
    let Some(list) = which.checked_sub(1).and_then(|i| lists.get(i)) else {
        return Err(format!(
            "BOARD {which}: {input} has boards 1 to {}",
            lists.len()
        ));
    };
    let names: Vec<(String, Vec<(String, String)>)> = (kb.sets.iter())
        .map(|s| (s.instrument.clone(), s.params.clone()))
        .collect();
    let built = flash::keyboard_firmware(
        &KeyboardInput {
            name: &kb.name,
            programs: &programs,
            program_names: &names,
            keys: &kb.key_programs(),
            board: &kb.board,
            boards: std::slice::from_ref(list),
            images: &[],
            limiter: &kb.limiter(),
            load: Load::Flash,
            command: "cargo run --example emulate_board",
        },
        &mut |_, _, _| {},
    )?;
    let image = &built[0].image;
    println!(
        "{}: board {which} of {} (keys {}), flash UF2 {} bytes",
        kb.name,
        lists.len(),
        tactus_firmware::verdict::key_ranges(list),
        built[0].uf2.len()
    );

    // Every key's sensor word of each sample: the stimulus at its own sensor's travel.
    let fs = kb.board.sample_rate_hz;
    let samples = (seconds * fs).round() as usize;
    let keys = image.keys();
    let mut words = Vec::with_capacity(keys.len());
    for k in &keys {
        let fp = &image.programs()[k.program].fixed;
        let dip_m = fp.program.sensors.first().map_or(0.01, |s| s.range.1);
        let stim =
            tactus_runtime::stimulus::builtin(stimulus, dip_m, fs).map_err(|e| e.to_string())?;
        words.push(
            (0..samples)
                .map(|n| FixedInstance::sensor_raw(fp, 0, stim.key.get(n).copied()))
                .collect::<Vec<i32>>(),
        );
    }
    let mut run = image.run().map_err(|e| e.to_string())?;
    let mut worst = vec![0u64; image.cores()];
    let mut misses = vec![0u32; image.cores()];
    for n in 0..samples {
        let now: Vec<i32> = words.iter().map(|w| w[n]).collect();
        let out = run.step(&now).map_err(|e| format!("sample {n}: {e}"))?;
        for c in 0..image.cores() {
            worst[c] = worst[c].max(out.core_cycles[c]);
            misses[c] = out.misses[c];
        }
    }
    for c in 0..image.cores() {
        let bound = image.wcet(c).map_or(0, |w| w.bound());
        println!(
            "core {c}: worst handler {} cycles of {} (static bound {bound}), {} misses",
            worst[c],
            image.cycles_per_sample(),
            misses[c]
        );
    }
    println!("{samples} samples of `{stimulus}` on every key");
    Ok(misses.iter().all(|&m| m == 0))
}

/// `cargo test` builds this example and runs it briefly, so that it cannot go stale.
#[cfg(test)]
mod tests {
    #[test]
    fn runs_a_board_of_an_organ_without_a_miss() {
        assert!(super::run("hammond", 1, "ff-dip", 0.02).unwrap());
        let e = super::run("hammond", 9, "ff-dip", 0.02).unwrap_err();
        assert!(e.contains("boards 1 to"), "{e}");
    }
}
