//! The accuracy contract (`fixed::contract`) on the keyboard instruments: the default format
//! plan keeps every clause on every built-in stimulus — force within 1 DAC LSB, the same
//! events (none lost or added) within 0.5 ms, event arguments within 1 %, states in range —
//! and a planner that ignores the contract (`PlanConfig::unlimited`) breaks it on the piano.

use std::path::Path;
use tactus_compiler::fixed::contract::{self, Contract, ContractCheck};
use tactus_compiler::fixed::{render, report, FixedProgram, PlanConfig};
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;
use tactus_runtime::stimulus;

const INSTRUMENTS: [&str; 4] = ["hammond", "harpsichord", "harpsichord_2x8", "grand_piano"];

fn program(name: &str) -> Program {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../instruments/{name}.tactus"));
    tactus_compiler::compile(&std::fs::read_to_string(path).unwrap(), &Config::default())
        .unwrap()
        .program
}

/// Every built-in stimulus of `p` through both engines: (stimulus, what it showed).
fn runs(p: &Program, fp: &FixedProgram) -> Vec<(&'static str, ContractCheck)> {
    let lsb = report::analyse(fp).dac_lsb_n();
    stimulus::builtin_names()
        .iter()
        .map(|(stim, _)| {
            let s = stimulus::builtin(stim, p.sensors[0].range.1, p.sample_rate_hz).unwrap();
            (*stim, contract::check(p, fp, &s.key, lsb))
        })
        .collect()
}

#[test]
fn the_default_plan_keeps_the_contract_on_every_builtin_stimulus() {
    let c = Contract::default();
    let mut broken = Vec::new();
    for name in INSTRUMENTS {
        let p = program(name);
        let fp = FixedProgram::new(&p);
        for (stim, r) in runs(&p, &fp) {
            println!(
                "{name:<16} {stim:<9} force {:.4} LSB (of {}), events {}/{} unmatched {} shift {} samples, args {:.4} % (of {} %), states out {}",
                r.max_force_lsb,
                c.force.lsb(r.dac_lsb_n),
                r.events_f64,
                r.events_fixed,
                r.unmatched,
                r.max_event_shift,
                100.0 * r.max_arg_rel,
                100.0 * c.event_arg_rel,
                r.state_out_of_range
            );
            assert!(r.samples > 0);
            for v in r.violations(&c, p.sample_rate_hz) {
                broken.push(format!("{name}/{stim}: {v}"));
            }
        }
    }
    assert!(broken.is_empty(), "contract broken:\n{}", broken.join("\n"));
}

/// The contract is not vacuous: the piano planned with no precision budget (every product
/// that fits `MULS` takes it, divisors shifted to 16 bits) breaks at least one clause.
#[test]
fn a_planner_greedier_than_the_contract_breaks_it() {
    let c = Contract::default();
    let p = program("grand_piano");
    let greedy = FixedProgram::with_config(&p, &PlanConfig::unlimited());
    let exact = FixedProgram::new(&p);
    let (g, e) = (greedy.mul_forms(), exact.mul_forms());
    println!("greedy plan: {g}; default plan: {e}");
    assert!(
        g.muls > e.muls,
        "the greedy plan must use more MULS products"
    );
    let broken: Vec<String> = runs(&p, &greedy)
        .into_iter()
        .flat_map(|(stim, r)| {
            r.violations(&c, p.sample_rate_hz)
                .into_iter()
                .map(move |v| format!("{stim}: {v}"))
        })
        .collect();
    println!("greedy plan breaks:\n{}", broken.join("\n"));
    assert!(
        !broken.is_empty(),
        "the greedy plan kept the contract: the test shows nothing"
    );
}

/// The divisor tolerance is pinned by the contract too: shifting the piano's divisors to a
/// 2^-6 relative error (its impact pulse's decay) breaks the force clause, where the
/// default 2^-10 keeps it with a margin.
#[test]
fn a_greedier_divisor_shift_breaks_the_contract() {
    let c = Contract::default();
    let p = program("grand_piano");
    // The reciprocal of `tau` (`fixed::recip`) leaves the piano no run-time division: its
    // divisions are planned as before the reciprocals to pin the tolerance.
    let divides = PlanConfig {
        reciprocals: false,
        ..PlanConfig::default()
    };
    let greedy = FixedProgram::with_config(
        &p,
        &PlanConfig {
            div_rel_tolerance: 1.0 / 64.0,
            ..divides
        },
    );
    let exact = FixedProgram::with_config(&p, &divides);
    assert!(
        greedy
            .div_shift
            .iter()
            .zip(&exact.div_shift)
            .any(|(g, e)| g > e),
        "the greedy plan must shift some divisor further"
    );
    let worst = runs(&p, &greedy)
        .iter()
        .map(|(_, r)| r.max_force_lsb)
        .fold(0.0, f64::max);
    println!("divisors within 2^-6: worst force error {worst:.3} DAC LSB");
    assert!(
        worst > c.force.lsb(1.0),
        "{worst} LSB: the contract did not catch it"
    );
}

/// The piano lowered with each of `masses` (hammer mass `M_h`) and shared, as grand88's
/// graded keys are: one program with run-time params; and each key's param values.
fn graded_piano(masses: &[&str]) -> (Program, Vec<Vec<f64>>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments/grand_piano.tactus");
    let text = std::fs::read_to_string(path).unwrap();
    let irs: Vec<Program> = masses
        .iter()
        .map(|m| {
            let config = Config {
                overrides: vec![("M_h".into(), (*m).into())],
                ..Config::default()
            };
            tactus_compiler::compile(&text, &config).unwrap().program
        })
        .collect();
    let shared = tactus_compiler::share::share(&irs).unwrap();
    let values = shared.values();
    (shared.program, values)
}

/// The contract holds with run-time params: grand88's hammer masses (11 g in the bass to
/// 3.5 g in the treble, one shared program planned once for the whole range), each clause on
/// every built-in stimulus at the ends and the middle of the grading.
#[test]
fn the_contract_holds_over_the_graded_hammer_masses() {
    let masses = ["11 g", "7.25 g", "3.5 g"];
    let (shared, values) = graded_piano(&masses);
    assert!(
        shared.runtime_params().count() > 0,
        "the masses must be run-time params"
    );
    let fp = FixedProgram::new(&shared);
    let lsb = report::analyse(&fp).dac_lsb_n();
    let mut broken = Vec::new();
    for (m, v) in masses.iter().zip(&values) {
        let mut worst = ContractCheck::default();
        for (stim, _) in stimulus::builtin_names() {
            let s =
                stimulus::builtin(stim, shared.sensors[0].range.1, shared.sample_rate_hz).unwrap();
            let run = contract::reference(&shared, &fp, &s.key, v).unwrap();
            let r = contract::compare(&shared, &fp, &run, lsb, &shared.contract, false).unwrap();
            assert!(r.samples > 0);
            for e in r.violations(&shared.contract, shared.sample_rate_hz) {
                broken.push(format!("M_h {m}/{stim}: {e}"));
            }
            worst.max_force_lsb = worst.max_force_lsb.max(r.max_force_lsb);
            worst.max_event_shift = worst.max_event_shift.max(r.max_event_shift);
            worst.max_arg_rel = worst.max_arg_rel.max(r.max_arg_rel);
            worst.unmatched += r.unmatched;
            worst.events_f64 += r.events_f64;
        }
        println!(
            "M_h {m:<7} force {:.4} LSB, events {} unmatched {}, shift {} samples, args {:.4} %",
            worst.max_force_lsb,
            worst.events_f64,
            worst.unmatched,
            worst.max_event_shift,
            100.0 * worst.max_arg_rel
        );
    }
    assert!(broken.is_empty(), "contract broken:\n{}", broken.join("\n"));
}

/// The planner's simulated search stops where the contract does: of the piano's products
/// it left more expensive than `MULS`, making them cheaper one at a time (to the cheapest
/// form it considered) breaks the contract for at least one; the test stops at the first.
/// (The search keeps half of each tolerance in reserve, so not every such step breaks the
/// whole contract.)
#[test]
fn a_plan_greedier_than_the_simulated_search_breaks_the_contract() {
    let c = Contract::default();
    let p = program("grand_piano");
    let fp = FixedProgram::new(&p);
    let analysed = FixedProgram::with_config(
        &p,
        &PlanConfig {
            simulate: false,
            ..PlanConfig::default()
        },
    );
    let (s, a) = (fp.mul_forms(), analysed.mul_forms());
    println!("simulated search: {s}; analysis only: {a}");
    assert!(
        s.cycles < a.cycles,
        "the search must find cheaper products than the analysis"
    );
    let lsb = report::analyse(&fp).dac_lsb_n();
    let refs: Vec<(&str, contract::ReferenceRun)> = stimulus::builtin_names()
        .iter()
        .map(|(stim, _)| {
            let s = stimulus::builtin(stim, p.sensors[0].range.1, p.sample_rate_hz).unwrap();
            (*stim, contract::reference(&p, &fp, &s.key, &[]).unwrap())
        })
        .collect();
    let mut breaking = 0;
    let mut tried = 0;
    for (i, k) in fp.mul_kind.iter().enumerate() {
        // The cheapest form the planner considered that is cheaper than the one it chose.
        let cheaper = k.and_then(|k| {
            fp.mul_options[i]
                .iter()
                .copied()
                .find(|o| o.cycles() < k.cycles())
        });
        let Some(cheaper) = cheaper.filter(|g| Some(*g) != *k) else {
            continue;
        };
        let mut q = fp.clone();
        q.mul_kind[i] = Some(cheaper);
        tried += 1;
        // The first broken clause on any stimulus (each run stops at its first bad sample).
        let broken = refs.iter().find_map(|(stim, run)| {
            let r = contract::compare(&p, &q, run, lsb, &c, true).unwrap();
            r.violations(&c, p.sample_rate_hz)
                .first()
                .map(|v| format!("{stim}: {v}"))
        });
        println!(
            "product v{i}: {k:?} → {cheaper:?}: {}",
            broken.as_deref().unwrap_or("holds")
        );
        if broken.is_some() {
            breaking += 1;
            break;
        }
    }
    println!("{breaking} of the {tried} cheaper steps tried break the contract");
    assert!(
        tried > 0 && breaking > 0,
        "no cheaper step breaks the contract: the test shows nothing"
    );
}

/// `tolerance` lines state the contract: the harpsichord with a looser total, a clause on
/// its plectrum term in newtons (the component instance's term by its qualified name would
/// be `jack.f`; the instrument names it `plectrum`) and one on its pluck event gets exactly
/// those clauses, and the simulation measures each of them; an output clause likewise.
#[test]
fn tolerance_lines_state_the_contract() {
    use tactus_compiler::ir::ForceBound;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments/harpsichord.tactus");
    let text = std::fs::read_to_string(path).unwrap();
    let end = text.rfind('}').unwrap();
    let with = format!(
        "{}    tolerance force = 2\n    tolerance force plectrum = 1 mN\n    tolerance event pluck {{ time = 1 ms, key_speed = 0.02 }}\n    tolerance switch = 0.25 ms\n}}\n",
        &text[..end]
    );
    let p = tactus_compiler::compile(&with, &Config::default())
        .unwrap()
        .program;
    let c = &p.contract;
    assert_eq!(c.force, ForceBound::Lsb(2.0));
    assert_eq!(c.terms.len(), 1);
    assert_eq!(p.forces[c.terms[0].0.index()].name, "plectrum");
    assert_eq!(c.terms[0].1, ForceBound::Newtons(1e-3));
    let pluck = c.events[0].event.index();
    assert_eq!(p.events[pluck].name, "pluck");
    assert!((c.time_of(pluck) - 1e-3).abs() < 1e-15);
    assert!((c.arg_rel_of(pluck, 0) - 0.02).abs() < 1e-15);
    assert!((c.switch_time_s - 0.25e-3).abs() < 1e-15);
    // The unchanged clauses keep their defaults.
    assert_eq!(c.event_arg_rel, Contract::default().event_arg_rel);
    let fp = FixedProgram::new(&p);
    let runs = contract::check_builtin(&p, &fp);
    assert_eq!(runs.len(), stimulus::builtin_names().len());
    for (stim, r) in &runs {
        let m = r.margins(&p, c);
        assert!(m.iter().any(|x| x.0 == "force `plectrum`"), "{m:?}");
        assert!(
            r.violations(c, p.sample_rate_hz).is_empty(),
            "{stim}: {:?}",
            r.violations(c, p.sample_rate_hz)
        );
        // The term's error is measured: an exact-zero bound would catch any difference.
        assert!(r.term_lsb[0] >= 0.0 && r.term_lsb[0].is_finite());
    }
    print!(
        "{}",
        tactus_compiler::fixed::render::render_margins(&p, &runs)
    );
    // A bound far below what fixed point can do breaks: the clause is enforced.
    let strict = with.replace(
        "tolerance force plectrum = 1 mN",
        "tolerance force plectrum = 1e-12 N",
    );
    let q = tactus_compiler::compile(&strict, &Config::default())
        .unwrap()
        .program;
    let fq = FixedProgram::new(&q);
    let broken = contract::check_builtin(&q, &fq)
        .iter()
        .any(|(_, r)| !r.violations(&q.contract, q.sample_rate_hz).is_empty());
    assert!(broken, "a 1e-12 N clause on the plectrum term must break");
}

/// An output clause is measured in the output's unit and enforced; and the planner spends
/// what it allows (with 1 µm the search takes a `MULS` for `key * 0.3`, worst ≈ 0.19 µm;
/// with 1e-15 m it keeps the exact product).
#[test]
fn an_output_tolerance_is_measured_and_enforced() {
    let src = |tol: &str| {
        format!(
            "instrument t {{\n    sensor key: m in [0 mm, 10 mm]\n    param full_scale = 5 N\n    force spring = 100 N/m * key\n    output depth = key * 0.3\n    tolerance output depth = {tol}\n}}\n"
        )
    };
    for (tol, holds) in [("1 um", true), ("1e-15 m", false)] {
        let p = tactus_compiler::compile(&src(tol), &Config::default())
            .unwrap()
            .program;
        assert_eq!(p.contract.outputs.len(), 1);
        let fp = FixedProgram::new(&p);
        let runs = contract::check_builtin(&p, &fp);
        let worst = runs
            .iter()
            .map(|(_, r)| r.output_err[0])
            .fold(0.0, f64::max);
        let ok = runs
            .iter()
            .all(|(_, r)| r.violations(&p.contract, p.sample_rate_hz).is_empty());
        println!("output `depth` within {tol}: worst {worst:e} m, holds {ok}");
        assert_eq!(ok, holds, "{tol}: worst {worst:e}");
    }
}

/// The 32×16 products the planner refused are refused by the contract: on the piano, every
/// product left a high word or 64-bit whose 32×16 form the planner considered is forced to
/// that form alone and simulated as the planner's search simulates it — on its own inputs
/// (`fixed::simulated_inputs`: the built-in stimuli, the full dips, the noisy press and the
/// runs of random sensor words), with half of every tolerance. Each breaks it — that is
/// why it was refused: a planner greedier than the contract fails it — and at least one
/// breaks the whole contract.
#[test]
fn every_refused_32x16_form_breaks_the_contract() {
    use tactus_compiler::fixed::{simulated_inputs, MulKind, SIMULATION_MARGIN};
    let p = program("grand_piano");
    let fp = FixedProgram::new(&p);
    let (full, strict) = (p.contract.clone(), p.contract.scaled(SIMULATION_MARGIN));
    let lsb = report::analyse(&fp).dac_lsb_n();
    let mut inputs = simulated_inputs(&p, fp.sensor_raw_range[0]);
    assert!(
        inputs.iter().any(|(name, _)| name.starts_with("noisy")),
        "the search's noisy press is among its inputs"
    );
    // The shortest first, as the planner orders them.
    inputs.sort_by_key(|(_, input)| input.len());
    let refs: Vec<(String, contract::ReferenceRun)> = inputs
        .iter()
        .map(|(name, input)| (name.clone(), input.reference(&p, &fp, &[]).unwrap()))
        .collect();
    let (mut tried, mut broken_full) = (0, 0);
    for (i, k) in fp.mul_kind.iter().enumerate() {
        let Some(k @ (MulKind::High(_) | MulKind::Wide)) = *k else {
            continue;
        };
        for &h in fp.mul_options[i]
            .iter()
            .filter(|o| matches!(o, MulKind::Mul32x16 { .. }))
        {
            let mut q = fp.clone();
            q.mul_kind[i] = Some(h);
            tried += 1;
            let first_break = |c: &Contract| {
                refs.iter().find_map(|(stim, run)| {
                    let r = contract::compare(&p, &q, run, lsb, c, true).unwrap();
                    r.violations(c, p.sample_rate_hz)
                        .first()
                        .map(|v| format!("{stim}: {v}"))
                })
            };
            let strict_break = first_break(&strict);
            let full_break = first_break(&full);
            println!(
                "v{i}: {k:?} → {h:?}: half contract {}; whole contract {}",
                strict_break.as_deref().unwrap_or("holds"),
                full_break.as_deref().unwrap_or("holds")
            );
            assert!(
                strict_break.is_some(),
                "v{i} → {h:?} keeps the planner's contract but was refused"
            );
            broken_full += usize::from(full_break.is_some());
        }
    }
    println!("{broken_full} of {tried} refused 32×16 forms break the whole contract");
    assert!(tried > 0, "no refused 32×16 form: the test shows nothing");
    assert!(
        broken_full > 0,
        "no refused 32×16 form breaks the whole contract"
    );
}

/// A comparison is refused, naming the param, when the run's param values do not fit the
/// plan: a value outside the interval the plan was planned for, or a plan with another
/// number of run-time params (`contract::compare` used to fall back to the nominal param
/// block then, comparing the f64 run of one key with the fixed run of another).
#[test]
fn a_run_whose_params_do_not_fit_the_plan_is_refused() {
    let analysis = PlanConfig {
        simulate: false,
        ..PlanConfig::default()
    };
    let (wide, values) = graded_piano(&["11 g", "3.5 g"]);
    let (narrow, _) = graded_piano(&["8 g", "7 g"]);
    let plain = program("grand_piano");
    let (fw, fn_, fp) = (
        FixedProgram::with_config(&wide, &analysis),
        FixedProgram::with_config(&narrow, &analysis),
        FixedProgram::with_config(&plain, &analysis),
    );
    assert_eq!(fw.param_words.len(), fn_.param_words.len());
    let lsb = report::analyse(&fw).dac_lsb_n();
    let s = stimulus::builtin("ff-dip", wide.sensors[0].range.1, wide.sample_rate_hz).unwrap();
    // The 11 g key's run, recorded with the plan it fits, compares.
    let run = contract::reference(&wide, &fw, &s.key, &values[0]).unwrap();
    let r = contract::compare(&wide, &fw, &run, lsb, &wide.contract, false).unwrap();
    assert_eq!(r.samples, s.key.len());
    // Against the plan of 7–8 g hammers: 11 g lies outside its intervals.
    // The refusal names the first run-time param, which the hammer mass sets (`rep_pre`,
    // the repetition spring's preload ∝ M_h, in today's piano).
    let first = &wide.params[wide.runtime_params().next().unwrap().index()].name;
    let e = contract::compare(&wide, &fn_, &run, lsb, &wide.contract, false).unwrap_err();
    let msg = e.to_string();
    println!("{msg}");
    assert!(
        msg.contains(&format!("param `{first}`")) && msg.contains("outside"),
        "{msg}"
    );
    // Against the piano with constant params: no param block takes two values.
    let e = contract::compare(&wide, &fp, &run, lsb, &wide.contract, false).unwrap_err();
    let given = format!("{} param values", values[0].len());
    assert!(e.to_string().contains(&given), "{e}");
    // And refused when recording, before the f64 run.
    let mut off = values[0].clone();
    off[0] *= 10.0;
    let e = contract::reference(&wide, &fw, &s.key, &off).unwrap_err();
    assert!(e.to_string().contains(first.as_str()), "{e}");
}

/// The planner simulates a shared program at real keys' param values: all of them when few,
/// else the grading's ends, the key nearest each run-time param's interval middle and
/// evenly spaced keys, at most `MAX_SIMULATED_KEYS` (grand88: A0, C8 and D♯6, the middle of
/// the `h/I_h`-scaled params' intervals, among six).
#[test]
fn the_planner_simulates_the_layouts_own_keys() {
    use tactus_compiler::fixed::{simulated_keys, MAX_SIMULATED_KEYS};
    let (three, _) = graded_piano(&["11 g", "7.25 g", "3.5 g"]);
    assert_eq!(simulated_keys(&three), vec![0, 1, 2]);
    let layout = Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments/layouts/grand88.toml");
    let (_, assigned) = tactus_runtime::keyboard::read_layout(&layout).unwrap();
    let masses: Vec<String> = assigned
        .iter()
        .map(|k| {
            assert_eq!(k.params[0].0, "M_h");
            k.params[0].1.clone()
        })
        .collect();
    let masses: Vec<&str> = masses.iter().map(|m| m.as_str()).collect();
    let (p, values) = graded_piano(&masses);
    assert_eq!(p.runtime_keys, values);
    let keys = simulated_keys(&p);
    println!(
        "grand88's simulated keys: {:?}",
        keys.iter().map(|&k| assigned[k].key).collect::<Vec<_>>()
    );
    assert_eq!(keys.len(), MAX_SIMULATED_KEYS);
    assert!(keys.windows(2).all(|w| w[0] < w[1]));
    assert_eq!((keys[0], keys[keys.len() - 1]), (0, 87));
    // D♯6 (MIDI 87): its 5.31 g gives the `h/I_h`-scaled params nearest their intervals'
    // middles (each ∝ 1/M_h: `B_h·h/I_h` and the lever's `l3·h/I_h` per arm, the constant
    // factors distributed into the hammer's sum, `fixed::distribute`).
    assert!(keys.iter().any(|&k| assigned[k].key == 87), "{keys:?}");
    // Each simulated point is one key's own values, not independent interval middles: params
    // in proportion at the grading's ends must be so at every simulated key. Since issue 70
    // scaled the knuckle's contacts with the hammer (`load` = M_h / m_ref), three run-time
    // params: `load` (∝ M_h), the key leads' G = balance − M_h·g·ratio and the flange's
    // `B_h·h/I_h` (∝ 1/M_h); no two of them in proportion (before: seven, seven pairs).
    let n = p.runtime_keys[0].len();
    assert_eq!(n, 3, "{:?}", p.runtime_keys[0]);
    let last = p.runtime_keys.len() - 1;
    let ratio = |k: usize, i: usize, j: usize| p.runtime_keys[k][j] / p.runtime_keys[k][i];
    let mut pairs = 0;
    for i in 0..n {
        for j in i + 1..n {
            if (ratio(last, i, j) / ratio(0, i, j) - 1.0).abs() > 1e-9 {
                continue;
            }
            pairs += 1;
            for &k in &keys {
                let r = ratio(k, i, j) / ratio(0, i, j);
                assert!((r - 1.0).abs() < 1e-9, "key {k}, params {i} and {j}: {r}");
            }
        }
    }
    assert_eq!(pairs, 0, "{:?}", p.runtime_keys[0]);
}

/// The error analysis proves the piano's per-sample force within the contract's 1 DAC LSB
/// (given exact states, as `--report precision` states it), and its contact term within
/// 0.05 LSB: the contact's products' floors and roundings (`report::analyse`, known zero
/// bits), not one LSB of a cut damping constant times the closing speed's whole range
/// (0.11 N, 72.2 LSB, before issue 16's fix; 1.5 LSB with issue 35's repetition lever damping
/// the knuckle's speed by 0.81 N·s, 0.02 LSB with its 3/4 N·s of two significant bits).
#[test]
fn the_pianos_static_force_bound_is_within_one_lsb() {
    let p = program("grand_piano");
    let fp = FixedProgram::new(&p);
    let pr = report::analyse(&fp);
    let lsb = pr.dac_lsb_n();
    let contact = p.forces.iter().position(|f| f.name == "contact").unwrap();
    println!(
        "contact {:.4e} N ({:.4} LSB), total {:.4e} N ({:.4} LSB)",
        pr.force[contact],
        pr.force[contact] / lsb,
        pr.total,
        pr.total / lsb
    );
    assert!(
        pr.force[contact] / lsb < 0.05,
        "contact bound {} LSB",
        pr.force[contact] / lsb
    );
    assert!(pr.total / lsb < 1.0, "total bound {} LSB", pr.total / lsb);
}

/// The switch clause compares every branch decision of the planned program with the f64
/// run's: each decision of the piano's planned update (contact, lever, back-check, rest
/// felt, the let-off's mode and edges) has its partner in the lowered program, and the
/// Heaviside contact `c > 0 m` is among them.
#[test]
fn every_decision_of_the_planned_program_is_compared() {
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../instruments/grand_piano.tactus"),
    )
    .unwrap();
    let p = program("grand_piano");
    let fp = FixedProgram::new(&p);
    let (a, b) = (contract::decisions(&p), contract::decisions(&fp.program));
    let pairs = contract::matched_decisions(&a, &b);
    println!(
        "{} decisions lowered, {} planned, {} compared",
        a.len(),
        b.len(),
        pairs.len()
    );
    let unmatched: Vec<String> = (0..b.len())
        .filter(|j| !pairs.iter().any(|x| x.1 == *j))
        .map(|j| b[j].describe(&fp.program))
        .collect();
    assert!(unmatched.is_empty(), "not compared: {unmatched:?}");
    let contact = a
        .iter()
        .position(|d| {
            d.kind == contract::DecisionKind::Select
                && text[d.span.clone()].starts_with("if c > 0 m {")
        })
        .expect("the contact's Heaviside switch is a decision");
    assert!(pairs.iter().any(|x| x.0 == contact));
    assert!(a
        .iter()
        .any(|d| matches!(d.kind, contract::DecisionKind::Mode(..))));
    assert!(a
        .iter()
        .any(|d| matches!(d.kind, contract::DecisionKind::Edge(..))));
}

/// A wrong plan at a switch is caught by the switch clause: the piano's plan with its
/// hammer–key contact closing at 0.1 mm of compression instead of 0 (in the fixed program
/// only) keeps its discrete state apart from f64's for longer than 0.5 ms — a switch lost
/// or added — where the plan itself holds every clause.
#[test]
fn a_switch_moved_by_a_wrong_plan_breaks_the_switch_clause() {
    use tactus_compiler::ir::{CmpOp, Op};
    let p = program("grand_piano");
    let fp = FixedProgram::new(&p);
    let mut q = fp.clone();
    let contact = q
        .program
        .values
        .iter()
        .find_map(|v| match v.op {
            Op::Select(c, _, _) => match q.program.values[c.index()].op {
                Op::Cmp(CmpOp::Gt, _, z) if q.program.const_value(z) == Some(0.0) => Some(z),
                _ => None,
            },
            _ => None,
        })
        .expect("the contact `c > 0 m`");
    q.program.values[contact.index()].op = Op::Const(1e-4);
    let c = &p.contract;
    let mut lost = 0;
    for (stim, r) in contract::check_builtin(&p, &fp) {
        assert!(
            r.violations(c, p.sample_rate_hz).is_empty(),
            "{stim}: {:?}",
            r.violations(c, p.sample_rate_hz)
        );
    }
    for (stim, r) in contract::check_builtin(&p, &q) {
        let v = r.violations(c, p.sample_rate_hz);
        println!(
            "{stim}: {} switches, {} lost or added, worst {:.3} of its bound: {v:?}",
            r.switch_count, r.switches_unresolved, r.switch_ratio
        );
        if v.iter().any(|x| x.contains("a switch lost or added")) {
            lost += 1;
        }
    }
    assert!(
        lost > 0,
        "no stimulus saw the moved contact as a lost switch"
    );
}

/// A mass falling onto a stiff, damped floor: the contact `x < floor` is a switch whose
/// after-effect is not a time shift — a run that closes it a sample late misses a sample
/// of the floor's deceleration and keeps the speed it did not lose.
const DROP: &str = "instrument drop {
    sensor key: m in [0 mm, 10 mm]
    param full_scale = 5 N
    param mass = 10 g
    param k = 2000 N/m
    param b = 2.5 N*s/m
    param grav = 9.81 m/s^2
    state x = 0.2 mm in [-1 mm, 1 mm]
    state v = 0 m/s in [-1 m/s, 1 m/s]
    let f = if x < -0.01 mm { max(-k * x - b * v, 0 N) } else { 0 N }
    dynamics {
        v' = f / mass - grav
        x' = v
    }
    force floor = f
}
";

/// The re-timed reference excuses a switch's timing, not arithmetic: the falling mass of
/// [`DROP`] with its fixed-point contact closing exactly one sample after the f64 run's
/// (the plan's threshold moved between the f64 run's positions at those two samples) holds
/// the contract — against the f64 run re-timed to that switch, where its recorded reading
/// breaks (the window's force 25.7 DAC LSB from the recorded run against a bound of 16.9)
/// — and the same plan with a greedier product for the floor's damping (18 bits of the
/// speed dropped, ≈ 4 LSB) breaks it in both readings, as that error alone does.
#[test]
fn the_retimed_reference_excuses_a_late_switch_but_not_an_arithmetic_error() {
    use tactus_compiler::fixed::MulKind;
    use tactus_compiler::interp::Instance;
    use tactus_compiler::ir::{CmpOp, Op};
    let p = tactus_compiler::compile(DROP, &Config::default())
        .unwrap()
        .program;
    let fp = FixedProgram::new(&p);
    let lsb = report::analyse(&fp).dac_lsb_n();
    let c = &p.contract;
    let keys = vec![0.0; 4410];
    let run = contract::reference(&p, &fp, &keys, &[]).unwrap();
    // The f64 run's positions: the contact closes at `n0`.
    let mut a = Instance::new(&p);
    let xs: Vec<f64> = keys
        .iter()
        .map(|&k| {
            a.step(&[k]);
            a.states()[0]
        })
        .collect();
    let n0 = xs.iter().position(|&x| x < -1e-5).expect("the mass lands");
    println!(
        "the f64 contact closes at sample {n0}: x {:e}, {:e} m",
        xs[n0 - 1],
        xs[n0]
    );
    // The planned threshold, and the damping.
    let threshold = fp
        .program
        .values
        .iter()
        .find_map(|v| match v.op {
            Op::Cmp(CmpOp::Lt, _, t) if fp.program.const_value(t) == Some(-1e-5) => Some(t),
            _ => None,
        })
        .expect("the contact `x < -0.01 mm`");
    let late = |fp: &FixedProgram| {
        let mut q = fp.clone();
        q.program.values[threshold.index()].op = Op::Const(0.5 * (xs[n0] + xs[n0 + 1]));
        q
    };
    // The floor's damping product `b·v` computed with the speed's lowest 18 bits dropped (a
    // `MULS` form the planner would refuse): an error of up to 2^-12 m/s × 2.5 N·s/m ≈ 4 DAC
    // LSB while the mass touches the floor, nothing in the air.
    let damping = fp
        .program
        .values
        .iter()
        .position(|v| match v.op {
            Op::Arith(tactus_compiler::ir::ArithOp::Mul, x, y) => [x, y].iter().any(|w| {
                matches!(fp.program.values[w.index()].op, Op::Param(id) if fp.program.params[id.index()].name == "b")
            }),
            _ => false,
        })
        .expect("the product b·v");
    println!("b·v: {:?}", fp.mul_kind[damping]);
    let off = |fp: &FixedProgram| {
        let mut q = fp.clone();
        let Op::Arith(_, x, _) = q.program.values[damping].op else {
            unreachable!()
        };
        let b_first = matches!(q.program.values[x.index()].op, Op::Param(_));
        // The constant 2.5 (0b101 · 2^-1, its word at 29 fraction bits) loses nothing to a
        // pre-shift by 28 bits; the speed loses 18.
        q.mul_kind[damping] = Some(if b_first {
            MulKind::Muls(28, 18)
        } else {
            MulKind::Muls(18, 28)
        });
        q
    };
    let check = |q: &FixedProgram| contract::compare(&p, q, &run, lsb, c, false).unwrap();
    let exact = check(&fp);
    assert!(
        exact.violations(c, p.sample_rate_hz).is_empty(),
        "{:?}",
        exact.violations(c, p.sample_rate_hz)
    );
    let r = check(&late(&fp));
    println!(
        "contact a sample late: switches {}, re-timed reading {}, {} samples re-timed, force {:.3} LSB: {:?}",
        r.switch_count,
        r.retimed,
        r.retimed_samples,
        r.max_force_lsb,
        r.violations(c, p.sample_rate_hz)
    );
    // A sample's decision reads the state the sample before left: the f64 contact is
    // decided closed at `n0 + 1`, the moved one at `n0 + 2`.
    assert!(
        r.switch_count == 1 && r.switches[0].sample == n0 + 1 && r.switches[0].samples == 1,
        "{:?}",
        r.switches
    );
    assert!(r.violations(c, p.sample_rate_hz).is_empty());
    assert!(
        r.retimed && r.retimed_samples == 1,
        "the recorded reading (a time shift) must break here, or the test shows nothing"
    );
    // `--report precision` says which reading the run held by.
    let margins = render::render_margins(&p, &[("late contact", r.clone())]);
    print!("{margins}");
    assert!(
        margins.contains("0 run(s) against the recorded f64 run; 1 against the f64 run re-timed to the fixed run's switches (late contact)"),
        "{margins}"
    );
    for (what, q) in [
        ("b·v with 18 bits of the speed dropped", off(&fp)),
        ("both", late(&off(&fp))),
    ] {
        let r = check(&q);
        let v = r.violations(c, p.sample_rate_hz);
        println!(
            "{what}: force {:.3} LSB, re-timed {}: {v:?}",
            r.max_force_lsb, r.retimed
        );
        assert!(!v.is_empty(), "{what}: the contract did not catch it");
        assert!(
            !r.retimed && r.retimed_force_lsb.is_none_or(|f| f > 1.0),
            "{what}: neither reading may hold"
        );
    }
    // With the late switch, the re-timed reading was tried, and broke by the error itself.
    let r = check(&late(&off(&fp)));
    assert!(
        r.retimed_force_lsb.is_some_and(|f| f > 2.0),
        "{:?}",
        r.retimed_force_lsb
    );
}

/// A click when the key passes 5 mm: one branch of the update, decided by the key alone.
const CLICK: &str = "instrument click {
    sensor key: m in [0 mm, 10 mm]
    param full_scale = 5 N
    force click = if key > 5 mm { 1 N } else { 0 N }
}
";

/// The re-timed reading takes over only decisions the f64 semantics itself takes within
/// the switch tolerance: a fixed-point threshold moved so that the click comes a sample
/// early, on a dip that passes 5 mm, is a switch moved in time and holds; the same moved
/// threshold on a dip that peaks at 4.95 mm — where the f64 semantics never clicks — flips a
/// branch for two samples that no f64 run takes: a switch added, which both readings
/// refuse — the re-timed run keeps its own decision and differs by the whole click, though
/// taking the fixed run's decision over would make its force equal the fixed run's.
#[test]
fn the_retimed_reading_refuses_a_decision_the_f64_semantics_never_takes() {
    use tactus_compiler::ir::{CmpOp, Op};
    let p = tactus_compiler::compile(CLICK, &Config::default())
        .unwrap()
        .program;
    let fp = FixedProgram::new(&p);
    let lsb = report::analyse(&fp).dac_lsb_n();
    let c = &p.contract;
    // The planned threshold of `key > 5 mm`, moved down by `by` metres.
    let threshold = fp
        .program
        .values
        .iter()
        .find_map(|v| match v.op {
            Op::Cmp(CmpOp::Gt | CmpOp::Lt | CmpOp::Ge | CmpOp::Le, a, b) => [a, b]
                .into_iter()
                .find(|t| fp.program.const_value(*t) == Some(5e-3)),
            _ => None,
        })
        .expect("the comparison `key > 5 mm`");
    let moved = |by: f64| {
        let mut q = fp.clone();
        q.program.values[threshold.index()].op = Op::Const(5e-3 - by);
        q
    };
    // A triangular dip to `peak` m and back, 0.05 mm a sample.
    let dip = |peak: f64| -> Vec<f64> {
        let up: Vec<f64> = (0..=(peak / 5e-5) as usize)
            .map(|i| i as f64 * 5e-5)
            .collect();
        let mut keys = up.clone();
        keys.extend(up.iter().rev());
        keys.extend(vec![0.0; 400]);
        keys
    };
    let check = |keys: &[f64], q: &FixedProgram| {
        let run = contract::reference(&p, q, keys, &[]).unwrap();
        contract::compare(&p, q, &run, lsb, c, false).unwrap()
    };
    // The unmoved plan holds on both dips.
    for peak in [5.2e-3, 4.95e-3] {
        let r = check(&dip(peak), &fp);
        assert!(
            r.violations(c, p.sample_rate_hz).is_empty(),
            "{peak}: {r:?}"
        );
    }
    // Passing 5 mm, the moved threshold clicks a sample early: a switch moved in time, held
    // by the re-timed reading.
    let early = check(&dip(5.2e-3), &moved(6e-5));
    let v = early.violations(c, p.sample_rate_hz);
    println!(
        "moved switch: {} switches, re-timed {} ({} samples): {v:?}",
        early.switch_count, early.retimed, early.retimed_samples
    );
    assert!(v.is_empty(), "a switch moved by a sample must hold: {v:?}");
    // Peaking at 4.95 mm, the f64 semantics never clicks; the fixed run does for two
    // samples, within the switch tolerance (23 samples): refused, a switch added.
    let keys = dip(4.95e-3);
    let spurious = check(&keys, &moved(6e-5));
    let v = spurious.violations(c, p.sample_rate_hz);
    println!(
        "spurious decision: {} switches, {} lost or added, re-timed {}: {v:?}",
        spurious.switch_count, spurious.switches_unresolved, spurious.retimed
    );
    assert!(!v.is_empty() && !spurious.retimed, "{v:?}");
    // The re-timed run kept the f64 semantics' own decision — no click — so it differs
    // from the fixed run by the whole click (1 N = 6553.6 DAC LSB at a 5 N full scale);
    // taken over, the difference would have been 0.
    let click_lsb = 1.0 / lsb;
    assert!(
        spurious
            .retimed_force_lsb
            .is_some_and(|f| f > 0.99 * click_lsb),
        "the spurious decision was taken over: {:?} of {click_lsb}",
        spurious.retimed_force_lsb
    );
    assert!(
        spurious.switches.iter().all(|w| w.samples < 23),
        "the flip must be shorter than the switch tolerance, or the test shows nothing: {:?}",
        spurious.switches
    );
}
