//! Where a fixed-point run departs from its f64 reference: one run of the budget corpus
//! (`tactus_firmware::corpus`, [`Size::Quick`]) at one key of a layout, through the f64
//! interpreter and the fixed interpreter of the layout's shared program (shared as
//! `firmware/tests/contract_corpus.rs` shares it), printed sample by sample — key travel,
//! total force, each force term's difference in DAC LSB, the modes, and each state in f64
//! and in fixed point — every `--every` samples and wherever the total differs by more than
//! `--above` DAC LSB, and every event of either run with its arguments (SI). `--csv FILE`
//! writes every sample (n, key m, f64 and fixed total N, then per state its f64 and fixed
//! value, SI). `--exact v193,v195` plans those products
//! (the value numbers of `tactus check --report precision`) in their most precise form
//! (64-bit, else high word) to see which product's format moves the run.
//!
//! `cargo run -p tactus-firmware --example contract_trace -- --layout
//! instruments/layouts/grand88.toml --key 108 --run half-dip-90% [--every 100] [--above 0.9]
//! [--csv trace.csv] [--exact v193,v195]`
//!
//! It found a friction piano's 1.09 DAC LSB at grand88's C8 on a half dip to 90 %: the jack
//! felt's floored products biasing the hammer's velocity (the header of
//! `instruments/grand_piano.tactus`).
//! Only straight differences per sample: the contract's switch clause and re-timed reading
//! are `contract::compare`'s.

use std::io::Write;
use std::path::{Path, PathBuf};
use tactus_compiler::fixed::interp::FixedInstance;
use tactus_compiler::fixed::{report, FixedProgram, MulKind};
use tactus_compiler::interp::Instance;
use tactus_compiler::ir::Program;
use tactus_compiler::lower::Config;
use tactus_firmware::corpus::{self, Size};
use tactus_runtime::fixed as fx;
use tactus_runtime::keyboard::read_layout;

struct Args {
    layout: PathBuf,
    key: u8,
    run: String,
    every: usize,
    above: f64,
    csv: Option<PathBuf>,
    exact: Vec<usize>,
}

fn usage() -> ! {
    eprintln!(
        "usage: contract_trace --layout FILE --key MIDI --run LABEL [--every N] [--above LSB] [--csv FILE] [--exact v1,v2]"
    );
    std::process::exit(2)
}

fn args() -> Args {
    let mut a = Args {
        layout: PathBuf::new(),
        key: 0,
        run: String::new(),
        every: 100,
        above: f64::INFINITY,
        csv: None,
        exact: Vec::new(),
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let value = it.next().unwrap_or_else(|| usage());
        match flag.as_str() {
            "--layout" => a.layout = value.into(),
            "--key" => a.key = value.parse().unwrap_or_else(|_| usage()),
            "--run" => a.run = value,
            "--every" => a.every = value.parse::<usize>().unwrap_or_else(|_| usage()).max(1),
            "--above" => a.above = value.parse().unwrap_or_else(|_| usage()),
            "--csv" => a.csv = Some(value.into()),
            "--exact" => {
                a.exact = value
                    .split(',')
                    .map(|v| {
                        v.trim_start_matches('v')
                            .parse()
                            .unwrap_or_else(|_| usage())
                    })
                    .collect()
            }
            _ => usage(),
        }
    }
    if a.layout.as_os_str().is_empty() || a.run.is_empty() {
        usage()
    }
    a
}

/// `instruments/NAME.tactus` beside the layout's directory, else under the current one.
fn instrument(layout: &Path, name: &str) -> String {
    let file = format!("{name}.tactus");
    let beside = layout
        .parent()
        .and_then(Path::parent)
        .map(|d| d.join(&file));
    let path = beside
        .filter(|p| p.exists())
        .unwrap_or_else(|| Path::new("instruments").join(&file));
    std::fs::read_to_string(&path).unwrap_or_else(|e| {
        eprintln!("{}: {e}", path.display());
        std::process::exit(1)
    })
}

fn main() {
    let a = args();
    let (_, assigned) = read_layout(&a.layout).unwrap_or_else(|e| {
        eprintln!("{}: {e}", a.layout.display());
        std::process::exit(1)
    });
    let Some(k) = assigned.iter().position(|x| x.key == a.key) else {
        eprintln!("{}: no key {}", a.layout.display(), a.key);
        std::process::exit(1)
    };
    let name = &assigned[k].instrument;
    let src = instrument(&a.layout, name);
    // The keys of the same instrument, shared into one program as the layout shares them.
    let group: Vec<usize> = (0..assigned.len())
        .filter(|&j| assigned[j].instrument == *name)
        .collect();
    let irs: Vec<Program> = group
        .iter()
        .map(|&j| {
            let config = Config {
                overrides: assigned[j].params.clone(),
                ..Config::default()
            };
            tactus_compiler::compile(&src, &config)
                .unwrap_or_else(|d| {
                    eprintln!("{name}: {d:?}");
                    std::process::exit(1)
                })
                .program
        })
        .collect();
    let shared = tactus_compiler::share::share(&irs).unwrap_or_else(|e| {
        eprintln!("{name}: {e:?}");
        std::process::exit(1)
    });
    let values = shared.values();
    let kk = group
        .iter()
        .position(|&j| j == k)
        .expect("the key is in its group");
    let p = &shared.program;
    let mut fp = FixedProgram::new(p);
    for &i in &a.exact {
        let Some(opts) = fp.mul_options.get(i).filter(|o| !o.is_empty()) else {
            eprintln!("v{i} is no planned product");
            std::process::exit(1)
        };
        let best = opts
            .iter()
            .copied()
            .find(|k| matches!(k, MulKind::Wide))
            .or_else(|| opts.iter().copied().find(|k| matches!(k, MulKind::High(_))));
        println!("v{i}: {:?} → {best:?}", fp.mul_kind[i]);
        if best.is_some() {
            fp.mul_kind[i] = best;
        }
    }
    let lsb = report::analyse(&fp).dac_lsb_n();
    let runs = corpus::corpus(&fp, Size::Quick);
    let Some(run) = runs.iter().find(|r| r.label == a.run) else {
        let labels: Vec<&str> = runs.iter().map(|r| r.label.as_str()).collect();
        eprintln!("no corpus run {:?}; the quick corpus: {labels:?}", a.run);
        std::process::exit(1)
    };
    let mut q = p.clone();
    let ids: Vec<_> = q.runtime_params().collect();
    for (id, &v) in ids.iter().zip(&values[kk]) {
        q.params[id.index()].value = v;
    }
    let block = fp.param_block(&values[kk]).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1)
    });
    let mut f64_run = Instance::new(&q);
    let mut fixed_run = FixedInstance::with_params(&fp, block);
    let (lo, hi) = fp.sensor_raw_range[0];
    let sf = fp.sensor_frac[0];
    let states: Vec<&str> = p.states.iter().map(|s| s.name.as_str()).collect();
    println!(
        "key {} {:?}, run {}: 1 DAC LSB = {lsb:.4e} N; terms {:?}; states {states:?}",
        a.key,
        assigned[k].params,
        a.run,
        p.forces.iter().map(|f| &f.name).collect::<Vec<_>>()
    );
    let mut csv = a.csv.as_ref().map(|path| {
        std::fs::File::create(path).unwrap_or_else(|e| {
            eprintln!("{}: {e}", path.display());
            std::process::exit(1)
        })
    });
    let mut worst = (0.0f64, 0usize);
    for (n, &w) in run.records.iter().map(|r| &r[0]).enumerate() {
        let x = fx::to_f64(w.clamp(lo, hi), sf);
        let oa = f64_run.step(&[x]).clone();
        let ob = fixed_run.step_raw(&[w]).clone();
        let ft = fx::to_f64(ob.total, fp.total_frac);
        let d = (oa.total - ft) / lsb;
        if d.abs() > worst.0 {
            worst = (d.abs(), n);
        }
        // The fixed program may carry hidden states after the source's (reciprocals).
        let sa = f64_run.states();
        let sb: Vec<f64> = (0..states.len())
            .map(|i| fx::to_f64(fixed_run.states()[i], fp.state_frac[i]))
            .collect();
        if let Some(f) = csv.as_mut() {
            let mut line = format!("{n},{x:e},{:e},{ft:e}", oa.total);
            for (u, v) in sa.iter().zip(&sb) {
                line.push_str(&format!(",{u:e},{v:e}"));
            }
            if writeln!(f, "{line}").is_err() {
                eprintln!("cannot write the CSV");
                std::process::exit(1)
            }
        }
        // Events, both runs' (arguments SI).
        for (e, args) in &oa.events {
            println!("{n:6} f64 event {} {args:?}", p.events[e.index()].name);
        }
        for (e, args) in &ob.events {
            let si: Vec<f64> = args
                .iter()
                .zip(&fp.event_frac[e.index()])
                .map(|(&x, &f)| fx::to_f64(x, f))
                .collect();
            println!("{n:6} fixed event {} {si:?}", p.events[e.index()].name);
        }
        if n % a.every == 0 || d.abs() > a.above {
            let terms: Vec<String> = oa
                .forces
                .iter()
                .enumerate()
                .map(|(i, f)| {
                    format!(
                        "{:+.3}",
                        (f - fx::to_f64(ob.forces[i], fp.force_frac[i])) / lsb
                    )
                })
                .collect();
            println!(
                "{n:6} key {:.4} mm  total {:+.4} N  f64 − fixed {d:+.3} LSB  terms [{}]  modes {:?}/{:?}",
                x * 1e3,
                oa.total,
                terms.join(" "),
                f64_run.modes(),
                fixed_run.modes()
            );
            let pairs: Vec<String> = states
                .iter()
                .zip(sa.iter().zip(&sb))
                .map(|(s, (u, v))| format!("{s} {u:.9e} Δ{:+.2e}", v - u))
                .collect();
            println!("         {}", pairs.join("  "));
        }
    }
    println!(
        "largest |f64 − fixed| total: {:.4} DAC LSB at sample {}",
        worst.0, worst.1
    );
}
