//! Each C primitive of `tactus_compiler::cgen::prim` against its definition in
//! `tactus_runtime::fixed`, on random formats across the whole planner range (including
//! the shapes no shipped instrument has: shifts beyond 64 bits, sqrt, exp, run-time
//! division) and random operands including the extreme words.

use std::process::{Command, Stdio};
use tactus_compiler::cgen::prim;
use tactus_compiler::fixed::FRAC_RANGE;
use tactus_compiler::ir::CmpOp;
use tactus_runtime::fixed as fx;
use tactus_runtime::rng::XorShift64;

/// One generated C function `int32_t f(int32_t x, int32_t y)` and its reference.
struct Case {
    c: String,
    want: Box<dyn Fn(i32, i32) -> i32>,
    what: String,
}

fn frac(rng: &mut XorShift64, near: Option<i32>) -> i32 {
    let (lo, hi) = FRAC_RANGE;
    match (near, rng.below(3)) {
        (Some(f), 0 | 1) => (f + rng.below(9) as i32 - 4).clamp(lo, hi),
        _ => lo + rng.below((hi - lo + 1) as usize) as i32,
    }
}

fn word(rng: &mut XorShift64) -> i32 {
    match rng.below(6) {
        0 => [
            0,
            1,
            -1,
            i32::MIN,
            i32::MAX,
            i32::MIN + 1,
            i32::MAX - 1,
            2,
            -2,
        ][rng.below(9)],
        1 => {
            (rng.next_u64() >> (33 + rng.below(31))) as i32 * if rng.below(2) == 0 { 1 } else { -1 }
        }
        _ => rng.next_u64() as i32,
    }
}

const OPS: [CmpOp; 6] = [
    CmpOp::Eq,
    CmpOp::Ne,
    CmpOp::Lt,
    CmpOp::Le,
    CmpOp::Gt,
    CmpOp::Ge,
];

fn ord_holds(op: CmpOp, o: std::cmp::Ordering) -> bool {
    use std::cmp::Ordering::*;
    match op {
        CmpOp::Eq => o == Equal,
        CmpOp::Ne => o != Equal,
        CmpOp::Lt => o == Less,
        CmpOp::Le => o != Greater,
        CmpOp::Gt => o == Greater,
        CmpOp::Ge => o != Less,
    }
}

/// Where `fx::mul` shifts a product left by more than 64 bits its `i128` wraps (see the
/// report: only formats the planner never produces get there, a product's format being about
/// `fx + fy − 30`); the meaning of the rule, which C implements, is saturation by the sign.
fn product(p: i64, e: i32) -> Option<i32> {
    (e > 64).then(|| match p.signum() {
        0 => 0,
        1 => i32::MAX,
        _ => i32::MIN,
    })
}

/// [`fx::exp`], except where its final `rescale` shifts the Q60 sum left by more than 65
/// bits and the `i128` wraps (reachable only when the analysis clamped an unbounded `exp`):
/// there the value is above 2^31 and the rule saturates.
fn exp_ref(x: i32, fe: i32, fr: i32) -> i32 {
    const LN2_Q60: i128 = 799_144_290_325_165_667;
    let k = (2 * fx::rescale(x as i128, fe, 60) + LN2_Q60).div_euclid(2 * LN2_Q60);
    if (-200..=200).contains(&k) && fr - 60 + k as i32 > 65 {
        i32::MAX
    } else {
        fx::exp(x, fe, fr).0
    }
}

fn cases(rng: &mut XorShift64, per_kind: usize) -> Vec<Case> {
    let mut v: Vec<Case> = Vec::new();
    for _ in 0..per_kind {
        let fx_ = frac(rng, None);
        let fy = frac(rng, Some(fx_));
        let near = if rng.below(2) == 0 { fx_ } else { fy };
        let fr = frac(rng, Some(near));
        let body = |e: String| format!("return {e};");
        v.push(Case {
            c: body(prim::convert("x", fx_, fr)),
            want: Box::new(move |x, _| fx::convert(x, fx_, fr).0),
            what: format!("convert {fx_}->{fr}"),
        });
        v.push(Case {
            c: body(prim::neg("x", fx_, fr)),
            want: Box::new(move |x, _| fx::neg(x, fx_, fr).0),
            what: format!("neg {fx_}->{fr}"),
        });
        for sub in [false, true] {
            v.push(Case {
                c: body(prim::add("x", fx_, "y", fy, fr, sub)),
                want: Box::new(move |x, y| {
                    if sub {
                        fx::sub(x, fx_, y, fy, fr).0
                    } else {
                        fx::add(x, fx_, y, fy, fr).0
                    }
                }),
                what: format!("{} {fx_} {fy} -> {fr}", if sub { "sub" } else { "add" }),
            });
        }
        let frm = frac(rng, Some(fx_ + fy));
        v.push(Case {
            c: body(prim::mul("x", fx_, "y", fy, frm, None)),
            want: Box::new(move |x, y| {
                product(x as i64 * y as i64, frm - fx_ - fy)
                    .unwrap_or_else(|| fx::mul(x, fx_, y, fy, frm).0)
            }),
            what: format!("mul {fx_} {fy} -> {frm}"),
        });
        let (a, b) = (rng.below(34) as u8, rng.below(34) as u8);
        v.push(Case {
            c: body(prim::mul("x", fx_, "y", fy, frm, Some((a, b)))),
            want: Box::new(move |x, y| {
                let p = (x >> a.min(31)) as i64 * (y >> b.min(31)) as i64;
                product(p, frm - (fx_ - a as i32) - (fy - b as i32))
                    .unwrap_or_else(|| fx::mul_shifted(x, fx_, a, y, fy, b, frm).0)
            }),
            what: format!("mul_shifted {fx_}>>{a} {fy}>>{b} -> {frm}"),
        });
        // The 32×16 product on any words (also a cut word wider than 16 bits, which a
        // planned program never has) and the high word.
        let (bc, kc) = (rng.below(20) as u8, rng.below(17) as u8);
        v.push(Case {
            c: body(prim::mul_32x16("x", fx_, "y", fy, bc, kc, frm)),
            want: Box::new(move |x, y| fx::mul_32x16(x, fx_, y, fy, bc, kc, frm).0),
            what: format!("mul_32x16 {fx_} {fy}>>{bc} k {kc} -> {frm}"),
        });
        let kh = 16 + rng.below(17) as u8;
        v.push(Case {
            c: body(prim::mul_high("x", fx_, "y", fy, kh, frm)),
            want: Box::new(move |x, y| fx::mul_high(x, fx_, y, fy, kh, frm).0),
            what: format!("mul_high {fx_} {fy} k {kh} -> {frm}"),
        });
        let frd = frac(rng, Some(fx_ - fy));
        v.push(Case {
            c: body(prim::div("x", fx_, "y", fy, 0, frd)),
            want: Box::new(move |x, y| fx::div(x, fx_, y, fy, frd).0),
            what: format!("div {fx_} {fy} -> {frd}"),
        });
        let bd = rng.below(34) as u8;
        v.push(Case {
            c: body(prim::div("x", fx_, "y", fy, bd, frd)),
            want: Box::new(move |x, y| fx::div_shifted(x, fx_, y, fy, bd, frd).0),
            what: format!("div_shifted {fx_} {fy}>>{bd} -> {frd}"),
        });
        let frs = frac(rng, Some(fx_ / 2));
        v.push(Case {
            c: body(prim::sqrt("x", fx_, frs)),
            want: Box::new(move |x, _| fx::sqrt(x, fx_, frs).0),
            what: format!("sqrt {fx_} -> {frs}"),
        });
        // exp: inputs in the interesting range are small; the driver gets both kinds.
        let fe = frac(rng, Some(26));
        v.push(Case {
            c: body(prim::exp("x", fe, fr)),
            want: Box::new(move |x, _| exp_ref(x, fe, fr)),
            what: format!("exp {fe} -> {fr}"),
        });
        let op = OPS[rng.below(6)];
        v.push(Case {
            c: body(prim::cmp(op, "x", fx_, "y", fy)),
            want: Box::new(move |x, y| i32::from(ord_holds(op, fx::cmp(x, fx_, y, fy)))),
            what: format!("cmp {op:?} {fx_} {fy}"),
        });
        let c = match rng.below(4) {
            0 => fx::to_f64(word(rng), fy),
            1 => (rng.unit() - 0.5) * 2f64.powi(rng.below(200) as i32 - 100),
            2 => [
                0.0,
                -0.0,
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
                1e300,
                -1e-300,
            ][rng.below(7)],
            _ => fx::to_f64(word(rng), fx_) + 2f64.powi(-fx_ - 1),
        };
        let left = rng.below(2) == 0;
        v.push(Case {
            c: body(prim::cmp_const(op, "x", fx_, c, left)),
            want: Box::new(move |x, _| {
                let o = fx::cmp_const(x, fx_, c);
                i32::from(ord_holds(op, if left { o.reverse() } else { o }))
            }),
            what: format!("cmp_const {op:?} {fx_} {c:e} const_left={left}"),
        });
        // d·k·2^e with |d| <= 5·2^31, both the int64 product and the split product.
        let k = word(rng);
        let e = rng.below(140) as i32 - 100;
        v.push(Case {
            c: format!(
                "int64_t d = 4 * (int64_t)x + y; return {};",
                prim::deriv("d", 5 << 31, k, e)
            ),
            want: Box::new(move |x, y| {
                fx::sat32(fx::rescale((4 * x as i128 + y as i128) * k as i128, 0, e)).0
            }),
            what: format!("deriv k={k} e={e}"),
        });
    }
    v
}

#[test]
fn c_primitives_match_the_definition() {
    if Command::new("cc")
        .arg("--version")
        .stdout(Stdio::null())
        .status()
        .is_err()
    {
        // Every CI image has `cc` (Rust links with it): there, a missing one fails.
        assert!(std::env::var_os("CI").is_none(), "no cc, and CI is set");
        println!("SKIPPED: no cc");
        return;
    }
    let mut rng = XorShift64::new(0x5EED_C0DE);
    let cases = cases(&mut rng, 160);
    let dir = std::env::temp_dir().join(format!("tactus-cgen-prims-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut src = String::from("#include <stdint.h>\n#include <stdio.h>\n");
    src.push_str(prim::RUNTIME);
    for (i, c) in cases.iter().enumerate() {
        src.push_str(&format!(
            "static int32_t f{i}(int32_t x, int32_t y) {{ (void)x; (void)y; {} }}\n",
            c.c
        ));
    }
    src.push_str("typedef int32_t (*fn)(int32_t, int32_t);\nstatic const fn fns[] = {");
    for i in 0..cases.len() {
        src.push_str(&format!("f{i},"));
    }
    src.push_str(
        "};\nint main(void) {\n    int32_t r[3];\n    while (fread(r, 4, 3, stdin) == 3) {\n        int32_t z = fns[r[0]](r[1], r[2]);\n        fwrite(&z, 4, 1, stdout);\n    }\n    return 0;\n}\n",
    );
    std::fs::write(dir.join("prims.c"), &src).unwrap();
    let exe = dir.join("prims");
    let o = Command::new("cc")
        .args(["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-o"])
        .arg(&exe)
        .arg(dir.join("prims.c"))
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "cc failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let mut input = Vec::new();
    let mut expect = Vec::new();
    for (i, c) in cases.iter().enumerate() {
        for n in 0..96 {
            let (mut x, y) = (word(&mut rng), word(&mut rng));
            if c.what.starts_with("exp") && n % 2 == 0 {
                x >>= rng.below(32); // small arguments: the non-trivial range of exp
            }
            for w in [i as i32, x, y] {
                input.extend_from_slice(&w.to_ne_bytes());
            }
            expect.push((i, x, y, (c.want)(x, y)));
        }
    }
    std::fs::write(dir.join("input.bin"), &input).unwrap();
    let o = Command::new(&exe)
        .stdin(std::fs::File::open(dir.join("input.bin")).unwrap())
        .output()
        .unwrap();
    assert!(o.status.success());
    let got: Vec<i32> = o
        .stdout
        .chunks_exact(4)
        .map(|b| i32::from_ne_bytes(b.try_into().unwrap()))
        .collect();
    assert_eq!(got.len(), expect.len());
    let bad: Vec<String> = expect
        .iter()
        .zip(&got)
        .filter(|((_, _, _, w), g)| w != *g)
        .map(|((i, x, y, w), g)| {
            format!(
                "{}: x={x} y={y}: C {g}, definition {w}\n    {}",
                cases[*i].what, cases[*i].c
            )
        })
        .collect();
    println!(
        "{} cases, {} evaluations, {} mismatches",
        cases.len(),
        expect.len(),
        bad.len()
    );
    let mut kinds = std::collections::BTreeMap::new();
    for b in &bad {
        *kinds
            .entry(b.split(' ').next().unwrap_or("").to_string())
            .or_insert(0) += 1;
    }
    println!("mismatches by kind: {kinds:?}");
    assert!(
        bad.is_empty(),
        "{} mismatches; first:\n{}",
        bad.len(),
        bad[..bad.len().min(12)].join("\n")
    );
    let _ = std::fs::remove_dir_all(&dir);
}
