//! The fault tests' boards (`fault.rs`, `watchdog.rs`): three keys of a spring, keys 0 and
//! 1 on core 0 and key 2 on core 1, window slots 60–62; five whose core 0 keys take turns;
//! and each core's fault record.
#![allow(dead_code)] // each test binary uses a subset

use tactus_compiler::lower::Config;
use tactus_firmware::image::fault::FaultWord;
use tactus_firmware::image::glue::ctrl;
use tactus_firmware::image::{FirmwareImage, ImageRun, KeySpec, Program};
use tactus_runtime::limiter::LimiterConfig;

/// A position-sensed key whose force is its spring: the force follows the position every
/// sample, so a DAC word of 0 at mid-travel is a check's doing (or a reset's).
pub const SPRING: &str =
    "instrument spring {\n sensor key: m in [0 mm, 10 mm]\n force out = 300 N/m * key + 0.2 N\n}\n";

/// The spring compiled, as `Program::compile` gives it.
pub fn spring() -> Program {
    Program::compile(SPRING, &Config::default()).unwrap()
}

/// The three keys of `p` on the shipped board `board`.
pub fn three_keys(p: &Program, board: &str) -> FirmwareImage {
    let keys: Vec<KeySpec> = [(60, 0), (61, 0), (62, 1)]
        .iter()
        .map(|&(slot, core)| KeySpec {
            slot,
            program: 0,
            core,
        })
        .collect();
    let board = super::layouts::shipped_board(board);
    FirmwareImage::build(
        std::slice::from_ref(p),
        &keys,
        &board,
        &LimiterConfig::default(),
    )
    .unwrap()
}

/// Four keys of the spring on core 0 and one on core 1 (window slots 60–64), the
/// quiescent-key guard off, the sensor check and the watchdog on: core 0's keys take turns
/// (`tactus_firmware::image::glue::Turns`, four classes, as grand88's cores), core 1's is
/// checked every sample, and core 0 feeds the watchdog in one class of its samples
/// (`glue::Feed::class`). The program and its image on the shipped board `board`.
pub fn turns_image(board: &str) -> (Program, FirmwareImage) {
    let mut p = spring();
    p.quiescent_guard = false;
    p.sensor_check = true;
    p.watchdog = true;
    let keys: Vec<KeySpec> = (0..5)
        .map(|i| KeySpec {
            slot: 60 + i,
            program: 0,
            core: usize::from(i == 4),
        })
        .collect();
    let image = FirmwareImage::build(
        std::slice::from_ref(&p),
        &keys,
        &super::layouts::shipped_board(board),
        &LimiterConfig::default(),
    )
    .unwrap();
    (p, image)
}

/// Core `core`'s fault record, read from its control block.
pub fn fault(run: &mut ImageRun, image: &FirmwareImage, core: usize) -> FaultWord {
    let ctrl_addr = image.core_addresses(core).unwrap()[3];
    let b = run.board();
    let w = b.read_u32(ctrl_addr + u32::from(ctrl::FAULT)).unwrap();
    let at = b.read_u32(ctrl_addr + u32::from(ctrl::FAULT_AT)).unwrap();
    FaultWord::decode(w, at)
}
