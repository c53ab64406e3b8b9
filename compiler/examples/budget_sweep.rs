// Scratch (not committed): which precision budgets keep the contract on the piano.
use tactus_compiler::fixed::{contract, report, FixedProgram, PlanConfig};
use tactus_runtime::stimulus;
fn main() {
    let name = std::env::args().nth(1).unwrap_or("grand_piano".into());
    let text = std::fs::read_to_string(format!("instruments/{name}.tactus")).unwrap();
    let p = tactus_compiler::compile(&text, &Default::default()).unwrap().program;
    let d = PlanConfig::default();
    let p2 = |k: i32| 2f64.powi(-k);
    let cfgs = vec![
        ("default", d),
        ("div 2^-14", PlanConfig { div_rel_tolerance: p2(14), ..d }),
        ("div 2^-12", PlanConfig { div_rel_tolerance: p2(12), ..d }),
        ("div 2^-10", PlanConfig { div_rel_tolerance: p2(10), ..d }),
        ("div 2^-8", PlanConfig { div_rel_tolerance: p2(8), ..d }),
        ("div 2^-6", PlanConfig { div_rel_tolerance: p2(6), ..d }),
    ];
    for (label, cfg) in cfgs {
        let fp = FixedProgram::with_config(&p, &cfg);
        let lsb = report::analyse(&fp).dac_lsb_n();
        let (m, w, cyc) = fp.mul_cost();
        let mut worst = (0.0f64, 0usize, 0usize, 0.0f64);
        let mut bad = vec![];
        for (stim, _) in stimulus::builtin_names() {
            let s = stimulus::builtin(stim, p.sensors[0].range.1, p.sample_rate_hz).unwrap();
            let r = contract::check(&p, &fp, &s.key, lsb);
            worst.0 = worst.0.max(r.max_force_lsb);
            worst.1 += r.unmatched;
            worst.2 = worst.2.max(r.max_event_shift);
            worst.3 = worst.3.max(r.max_arg_rel);
            let v = r.violations(&contract::Contract::default(), p.sample_rate_hz);
            if !v.is_empty() { bad.push(format!("{stim}: {}", v.join("; "))); }
        }
        let sh: Vec<u8> = fp.div_shift.iter().copied().filter(|b| *b > 0).collect();
        println!("{label:<20} {sh:?} MULS {m} wide {w} ≈{cyc} cyc | force {:.3} LSB unmatched {} shift {} arg {:.4}% | {}", worst.0, worst.1, worst.2, 100.0*worst.3, bad.join(" | "));
    }
}
