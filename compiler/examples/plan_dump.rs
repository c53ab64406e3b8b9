// Scratch (not committed): dump the piano's products and their plans.
use tactus_compiler::fixed::{FixedProgram, MulKind};
use tactus_compiler::ir::*;
fn main() {
    let name = std::env::args().nth(1).unwrap_or("grand_piano".into());
    let text = std::fs::read_to_string(format!("instruments/{name}.tactus")).unwrap();
    let p = tactus_compiler::compile(&text, &Default::default()).unwrap().program;
    let fp = FixedProgram::new(&p);
    let pr = tactus_compiler::fixed::report::analyse(&fp);
    for (i, vd) in p.values.iter().enumerate() {
        let k = fp.mul_kind[i];
        let isdiv = matches!(vd.op, Op::Arith(ArithOp::Div, ..));
        if k.is_none() && !isdiv { continue; }
        let (x, y) = match vd.op { Op::Arith(_, x, y) => (x, y), _ => continue };
        let desc = |v: Value| format!("{:?} f{} [{:.3e},{:.3e}]", p.values[v.index()].op, fp.frac[v.index()], fp.ranges.values[v.index()].lo, fp.ranges.values[v.index()].hi);
        println!("v{i} {:?} {:?} divsh {} | f{} [{:.3e},{:.3e}] err {:.3e}\n    x: {}\n    y: {}", k, vd.op, fp.div_shift[i], fp.frac[i], fp.ranges.values[i].lo, fp.ranges.values[i].hi, pr.value[i], desc(x), desc(y));
        let _ = MulKind::Wide;
    }
    println!("{}", tactus_compiler::fixed::report::render(&fp, &pr));
}
