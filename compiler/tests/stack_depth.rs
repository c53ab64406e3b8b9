//! Class 1 of issue 19 (recursion depth from input): the longest chains and deepest nests
//! the compiler accepts compile within a 512 KB stack in a debug build — a quarter of a
//! test thread's, a sixteenth of a main thread's. A `sum` over 4096 indices (a chain of
//! 4096 additions) used to need 2 MB; expressions nest at most `MAX_NESTING` deep.

use tactus_compiler::lower::Config;
use tactus_compiler::parse::MAX_NESTING;

fn instrument(force: &str) -> String {
    format!("instrument t {{\n    sensor key: m in [0 mm, 10 mm]\n    force f = {force}\n}}\n")
}

/// Compiles `src` on a thread with a 512 KB stack; the diagnostics' codes on failure.
fn compile_small_stack(src: String) -> Result<(), Vec<&'static str>> {
    std::thread::Builder::new()
        .stack_size(512 << 10)
        .spawn(move || {
            tactus_compiler::compile(&src, &Config::default())
                .map(|_| ())
                .map_err(|d| d.iter().map(|d| d.code).collect())
        })
        .unwrap()
        .join()
        .unwrap()
}

#[test]
fn long_chains_and_deep_nests_fit_a_small_stack() {
    let deep = MAX_NESTING as usize - 10;
    let cases = [
        (
            "sum over 4096",
            instrument("sum(i in 0..4096, key * 1 N/m)"),
        ),
        (
            "unary chain",
            instrument(&format!("{}key * 1 N/m", "- ".repeat(deep))),
        ),
        (
            "nested calls",
            instrument(&format!(
                "{}key{} * 1 N/m",
                "max(key, ".repeat(deep),
                ")".repeat(deep)
            )),
        ),
        (
            "nested ifs",
            instrument(&format!(
                "{}1 N{}",
                "if key > 1 mm { 1 N } else { ".repeat(deep / 2),
                " }".repeat(deep / 2)
            )),
        ),
        (
            "sum chain",
            instrument(&vec!["key * 1 N/m"; deep].join(" + ")),
        ),
        (
            "sum of deep terms",
            instrument(&format!(
                "sum(i in 0..1000, {}key * 1 N/m)",
                "- ".repeat(deep)
            )),
        ),
    ];
    for (name, src) in cases {
        assert_eq!(compile_small_stack(src), Ok(()), "{name}");
    }
}

#[test]
fn one_level_more_is_e0008_not_a_stack_overflow() {
    let over = MAX_NESTING as usize + 1;
    for src in [
        instrument(&format!("{}key * 1 N/m", "- ".repeat(over))),
        instrument(&vec!["key * 1 N/m"; 20_000].join(" + ")),
        instrument(&format!(
            "{}key{} * 1 N/m",
            "max(key, ".repeat(over),
            ")".repeat(over)
        )),
    ] {
        assert_eq!(compile_small_stack(src), Err(vec!["E0008"]));
    }
}
