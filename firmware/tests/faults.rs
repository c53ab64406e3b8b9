//! Faults injected into a running board (`ImageRun::inject`, `image/run/inject.rs`): a
//! faulted run is the same on the lock-step machine and on the block engine with its
//! memos, windows and the rest replay, and each fault changes what it says it changes.

use tactus_compiler::fixed::interp::FixedInstance;
use tactus_emulator::Engine;
use tactus_firmware::flash::Load;
use tactus_firmware::image::{FaultKind, FirmwareImage, ImageRun, Injection};

#[path = "common/layouts.rs"]
mod layouts;
use layouts::firmware;

fn faults() -> Vec<Injection> {
    let f = |kind, key, core, from, until| Injection {
        kind,
        key,
        core,
        from,
        until,
    };
    vec![
        f(FaultKind::Stuck(20_000), Some(0), None, 100, Some(400)),
        f(FaultKind::Noise(300), Some(1), None, 150, Some(300)),
        f(FaultKind::Jump(6_000), Some(2), None, 500, Some(700)),
        f(
            FaultKind::Flip { word: 0, bit: 20 },
            Some(1),
            None,
            800,
            None,
        ),
        f(FaultKind::Open, Some(0), None, 900, Some(1000)),
        f(FaultKind::Short, Some(3), None, 950, Some(1050)),
        f(FaultKind::AdcSilent, None, Some(1), 1100, Some(1200)),
        f(FaultKind::DacStall, None, Some(0), 1250, Some(1350)),
    ]
}

/// `image` run `samples` samples at rest on `engine` (the rest replay on when `rest`), with
/// the faults or without: every sample's outputs.
fn run(
    image: &FirmwareImage,
    engine: Engine,
    rest: bool,
    faulted: bool,
    samples: usize,
) -> Vec<tactus_firmware::image::SampleOut> {
    let mut r: ImageRun = image.run().unwrap();
    r.board().config.engine = engine;
    r.set_rest_replay(rest).unwrap();
    if faulted {
        for f in faults() {
            r.inject(f).unwrap();
        }
    }
    let programs = image.programs();
    let words: Vec<i32> = (image.keys().iter())
        .map(|k| FixedInstance::sensor_raw(&programs[k.program].fixed, 0, Some(0.0)))
        .collect();
    (0..samples)
        .map(|_| r.step(&words).unwrap().clone())
        .collect()
}

fn check(kind: Option<&str>) {
    let (boards, _) = firmware("instruments/layouts/grand88.toml", kind, Load::Ram);
    let image = &boards[0].image;
    assert!(image.keys().len() >= 4);
    let n = 1_500;
    let reference = run(image, Engine::LockStep, false, true, n);
    let fast = run(image, Engine::Block, true, true, n);
    for (i, (a, b)) in reference.iter().zip(&fast).enumerate() {
        assert_eq!(a, b, "{kind:?}: sample {i}");
    }
    // The faults did something: the faulted run is not the clean one while they last, and
    // the stalled DAC held core 0's codes.
    let clean = run(image, Engine::Block, true, false, n);
    let differs = |r: std::ops::Range<usize>| r.clone().any(|i| reference[i] != clean[i]);
    assert!(
        differs(100..450),
        "{kind:?}: the stuck sensor changed nothing"
    );
    assert!(
        differs(900..1060),
        "{kind:?}: open and short changed nothing"
    );
    let keys0: Vec<usize> = (0..image.keys().len())
        .filter(|&k| image.keys()[k].core == 0)
        .collect();
    for i in 1250..1350 {
        for &k in &keys0 {
            assert_eq!(
                reference[i].drives[k][0].dac, reference[1249].drives[k][0].dac,
                "{kind:?}: sample {i} key {k}: the stalled DAC moved"
            );
        }
    }
}

#[test]
fn a_faulted_plain_board_runs_the_same_on_every_engine() {
    check(None);
}

#[test]
fn a_faulted_converter_board_runs_the_same_on_every_engine() {
    check(Some("rp2040_io"));
}

#[test]
fn a_fault_outside_the_board_is_refused_with_its_field() {
    let (boards, _) = firmware("instruments/layouts/grand88.toml", None, Load::Ram);
    let mut r = boards[0].image.run().unwrap();
    let keys = boards[0].image.keys().len();
    let bad = |kind, key, core| Injection {
        kind,
        key,
        core,
        from: 0,
        until: None,
    };
    let e = r
        .inject(bad(FaultKind::Open, Some(keys), None))
        .unwrap_err();
    assert!(e.contains("`key`"), "{e}");
    let e = r
        .inject(bad(FaultKind::AdcSilent, None, Some(2)))
        .unwrap_err();
    assert!(e.contains("`core`"), "{e}");
    let e = r
        .inject(bad(
            FaultKind::Flip {
                word: 1 << 20,
                bit: 3,
            },
            Some(0),
            None,
        ))
        .unwrap_err();
    assert!(e.contains("`word`"), "{e}");
}
