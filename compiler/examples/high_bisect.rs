// Scratch (not committed): which high-word product breaks the contract.
use tactus_compiler::fixed::{contract, report, FixedProgram, MulKind};
use tactus_runtime::stimulus;
fn main() {
    let text = std::fs::read_to_string("instruments/grand_piano.tactus").unwrap();
    let p = tactus_compiler::compile(&text, &Default::default()).unwrap().program;
    let fp = FixedProgram::new(&p);
    let lsb = report::analyse(&fp).dac_lsb_n();
    let highs: Vec<usize> = (0..fp.mul_kind.len()).filter(|i| matches!(fp.mul_kind[*i], Some(MulKind::High(_)))).collect();
    println!("{} high products", highs.len());
    let s = stimulus::builtin("slow-dip", p.sensors[0].range.1, p.sample_rate_hz).unwrap();
    for &h in &highs {
        let mut f2 = fp.clone();
        for &o in &highs { if o != h { f2.mul_kind[o] = Some(MulKind::Wide); } }
        let r = contract::check(&p, &f2, &s.key, lsb);
        let fr = fp.frac[h];
        let (x, y) = match p.values[h].op { tactus_compiler::ir::Op::Arith(_, x, y) => (x, y), _ => continue };
        println!("v{h} {:?} e={} {:?} x f{} y f{}: force {:.3} LSB", fp.mul_kind[h], fr - fp.frac[x.index()] - fp.frac[y.index()], p.values[h].op, fp.frac[x.index()], fp.frac[y.index()], r.max_force_lsb);
    }
}
