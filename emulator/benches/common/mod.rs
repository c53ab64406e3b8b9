//! The emulator's speed workloads, shared by the criterion bench (`benches/emulator.rs`)
//! and the callgrind example (`examples/speed.rs`) so both measure the same code.
//!
//! * [`speed_loop`]: the bench's loop (SRAM load, add, SRAM store, MULS, shift, subtract,
//!   taken branch; 10 cycles per iteration) on one or both cores.
//! * [`key_updates`]: firmware-like — each core sleeps in `WFI` and updates `keys` piano
//!   keys in its SysTick interrupt every `period` cycles (a sample period: 3,016 cycles is
//!   44.1 kHz at 133 MHz). Per key: load the sensor word, a first-order position filter,
//!   a velocity estimate with a Q6 gain multiply, a force clamped at zero stored to the
//!   DAC word, the filter state in SRAM (8 bytes per key); 29-31 cycles per key. Stacks in
//!   each core's own scratch bank (SRAM4 / SRAM5), sensors, DAC and state in striped SRAM.
#![allow(dead_code)]

use tactus_emulator::{Board, Config, Engine};

/// The banks each core of a two-core firmware image owns (`tactus_firmware`'s
/// `FirmwareImage::own_banks`: core 0 SRAM0, SRAM2 and SRAM4, core 1 SRAM1, SRAM3 and SRAM5).
const OWN_BANKS: [u8; 2] = [0b01_0101, 0b10_1010];
/// The firmware images' sensor and DAC windows (`tactus_firmware::windows::{SENSOR_BASE, DAC_BASE}`).
const SENSOR_BASE: u32 = 0x2003_f000;
const DAC_BASE: u32 = 0x2003_f400;

/// loop: ldr r1,[r0]; adds r1,r1,r2; str r1,[r0,#4]; muls r3,r1,r3; lsrs r4,r3,#3;
///       subs r5,#1; bne loop  — 10 cycles per iteration.
pub const LOOP: [u16; 7] = [0x6801, 0x1889, 0x6041, 0x434b, 0x08dc, 0x3d01, 0xd1f8];

fn bytes(code: &[u16]) -> Vec<u8> {
    code.iter().flat_map(|h| h.to_le_bytes()).collect()
}

/// The speed loop on `cores` cores (1 or 2), each in its own SRAM page and data area.
pub fn speed_loop(engine: Engine, cores: usize) -> Board {
    let mut b = Board::new(Config {
        engine,
        ..Config::default()
    });
    for core in 0..cores {
        let at = 0x2000_0000 + 0x1000 * core as u32;
        b.write_bytes(at, &bytes(&LOOP)).unwrap();
        b.start_core(core, at | 1, 0x2004_0000 + 0x800 * core as u32, 0);
        let c = &mut b.cores[core];
        c.r[0] = 0x2001_0000 + 0x100 * core as u32;
        c.r[2] = 3;
        c.r[3] = 7;
        c.r[5] = u32::MAX;
    }
    b
}

/// The speed loop on `cores` cores (1 or 2), each core's code and data in its own SRAM bank
/// through the non-striped alias (core k: SRAM k at `0x21000000 + k·0x10000`) and its stack
/// in its scratch bank, as the firmware images lay them out: what two cores running ahead
/// of each other need (`Config::own_banks` set to `OWN_BANKS`). 10 cycles per
/// iteration, as [`speed_loop`].
pub fn speed_loop_own_banks(engine: Engine, cores: usize) -> Board {
    let mut b = Board::new(Config {
        engine,
        own_banks: OWN_BANKS,
        ..Config::default()
    });
    for core in 0..cores {
        let bank = 0x2100_0000 + 0x1_0000 * core as u32;
        // Core 1's code at another bank offset than core 0's, as in the firmware images:
        // the engines' direct-mapped caches are indexed by the low address bits.
        let code = bank + 0x100 + 0x400 * core as u32;
        b.write_bytes(code, &bytes(&LOOP)).unwrap();
        b.start_core(core, code | 1, 0x2004_1000 + 0x1000 * core as u32, 0);
        let c = &mut b.cores[core];
        c.r[0] = bank + 0x8000;
        c.r[2] = 3;
        c.r[3] = 7;
        c.r[5] = u32::MAX;
    }
    b
}

/// Firmware-like key updates (see the module documentation) on `cores` cores, `keys`
/// keys per core (1-128 in all), SysTick every `period` cycles.
pub fn key_updates(engine: Engine, cores: usize, keys: u16, period: u32) -> Board {
    assert!(keys >= 1 && cores as u16 * keys <= 128);
    let mut b = Board::new(Config {
        engine,
        ..Config::default()
    });
    for core in 0..cores {
        let base = 0x2003_0000 + 0x1000 * core as u32;
        let handler = base + 0x100;
        let main = base + 0x80;
        let first = keys as u32 * core as u32;
        let state = 0x2002_0000 + 0x800 * core as u32;
        let mut h: Vec<u16> = vec![
            0xb5f0,        // push {r4-r7, lr}
            0x4c00,        // ldr r4, =sensors   (offsets patched below)
            0x4d00,        // ldr r5, =dac
            0x4e00,        // ldr r6, =state
            0x2700 | keys, // movs r7, #keys
        ];
        let top = h.len();
        h.extend([
            0x6820, // ldr r0, [r4]
            0x6831, // ldr r1, [r6]
            0x1a42, // subs r2, r0, r1
            0x1092, // asrs r2, r2, #2
            0x1889, // adds r1, r1, r2
            0x6031, // str r1, [r6]
            0x6873, // ldr r3, [r6, #4]
            0x1ad2, // subs r2, r2, r3
            0x202d, // movs r0, #45
            0x4342, // muls r2, r0, r2
            0x1192, // asrs r2, r2, #6
            0x189b, // adds r3, r3, r2
            0x6073, // str r3, [r6, #4]
            0x0048, // lsls r0, r1, #1
            0x18c0, // adds r0, r0, r3
            0x2800, // cmp r0, #0
            0xda00, // bge .+4
            0x2000, // movs r0, #0
            0x6028, // str r0, [r5]
            0x3404, // adds r4, #4
            0x3504, // adds r5, #4
            0x3608, // adds r6, #8
            0x3f01, // subs r7, #1
        ]);
        let back = (top as i32 - h.len() as i32) * 2 - 4;
        h.push(0xd100 | ((back >> 1) as u16 & 0xff)); // bne top
        h.push(0xbdf0); // pop {r4-r7, pc}
        if h.len() % 2 == 1 {
            h.push(0xbf00);
        }
        let pool = h.len(); // in halfwords, word-aligned
        let literals = [SENSOR_BASE + 4 * first, DAC_BASE + 4 * first, state];
        for (i, reg_load) in [1usize, 2, 3].into_iter().enumerate() {
            let pc = handler + 2 * reg_load as u32;
            let lit = handler + 2 * pool as u32 + 4 * i as u32;
            h[reg_load] |= ((lit - ((pc + 4) & !3)) / 4) as u16;
        }
        let mut code = bytes(&h);
        for l in literals {
            code.extend(l.to_le_bytes());
        }
        b.write_bytes(handler, &code).unwrap();
        b.write_bytes(main, &bytes(&[0xbf30, 0xe7fd])).unwrap(); // wfi; b .-2
        b.write_u32(base + 4 * 15, handler | 1).unwrap();
        for k in 0..keys as u32 {
            let v = 1000 + 37 * (first + k);
            b.write_data(SENSOR_BASE + 4 * (first + k), &v.to_le_bytes())
                .unwrap();
        }
        b.start_core(core, main | 1, 0x2004_1000 + 0x1000 * core as u32, base);
        let c = &mut b.cores[core];
        c.nvic.syst_rvr = period - 1;
        c.nvic.syst_csr = 7;
        c.nvic.syst_next = period as u64 + 7 * core as u64;
    }
    b
}
