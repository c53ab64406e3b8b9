//! Budget a keyboard: how many RP2040 boards it needs, every board proven by the static
//! worst case of its sample interrupt, each program measured on the emulator — what
//! `tactus budget` prints.
//!
//! ```text
//! cargo run --release --example budget_layout                         # grand88 on rp2040
//! cargo run --release --example budget_layout -- grand88 rp2040_200mhz
//! cargo run --release --example budget_layout -- hammond rp2040 12    # KEYBOARD [BOARD [KEYS]]
//! ```
//!
//! The keyboard is a layout (`grand88`, `split_harpsichord_piano`, a `.toml` file) or one
//! instrument on KEYS keys; the board a built-in kind or a board file. The library calls:
//! `tactus_host::keyboard::compile`, then `tactus_host::budget::budget` (the firmware, the
//! keyboard's one plan of boards, each program's static and measured cost over the quick
//! corpus, the verdict), whose report prints as text. Exit code: 0 fits, 1 does not, 2 bad
//! input.

use std::process::ExitCode;
use tactus_host::keyboard::{self, KeyboardSpec};

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let keys = match args.get(2).map(|k| k.parse::<u32>()).transpose() {
        Ok(k) => k,
        Err(e) => {
            eprintln!("error: KEYS: {e}");
            return ExitCode::from(2);
        }
    };
    let input = args.first().map_or("grand88", String::as_str);
    match run(input, args.get(1).map(String::as_str), keys) {
        Ok((text, code)) => {
            print!("{text}");
            ExitCode::from(code)
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}

/// The budget of `input` on `board` (`keys` keys of a single instrument) as text, with its
/// exit code.
fn run(input: &str, board: Option<&str>, keys: Option<u32>) -> Result<(String, u8), String> {
    let spec = KeyboardSpec {
        input,
        as_layout: None,
        board,
        keys,
        params: &[],
    };
    let kb = keyboard::compile(&spec, &mut |src, diagnostics| {
        eprint!(
            "{}",
            tactus_compiler::diagnostics::emit_to_string(&src.name, &src.text, diagnostics)
        )
    })
    .map_err(|e| e.to_string())?;
    let report =
        tactus_host::budget::budget(&kb, true, tactus_emulator::Engine::Block, &mut |_, _, _| {})?;
    Ok((report.text(), report.exit_code()))
}

/// `cargo test` builds this example and runs it briefly, so that it cannot go stale.
#[cfg(test)]
mod tests {
    #[test]
    fn budgets_twelve_organ_keys_on_one_board() {
        let (text, code) = super::run("hammond", None, Some(12)).unwrap();
        assert_eq!(code, 0, "{text}");
        assert!(text.contains("verdict: FITS on 1 board"), "{text}");
    }
}
