//! The ADS8688 model (`tactus_emulator::converters`) driven by a PIO state machine
//! (`tactus_emulator::pio`) as a board's firmware will drive it: SPI mode 1, 32-bit frames
//! with CS high between them. The frames carry the commands and the codes both ways, the
//! channel sequence follows the commands (AUTO_RST, NO_OP, MAN_Ch_n), and the part's
//! data-sheet timing (TI SBAS582: SCLK ≤ 17 MHz, a CS falling edge at most every 2 µs, the
//! 850 ns conversion) is enforced: at 133 MHz a driver must divide the PIO clock by at
//! least 2 and pad its frames to 2 µs, and the model says so when it does not.

use tactus_emulator::converters::{Ads8688, Dac8568, SpiPins};
use tactus_emulator::pio::Pio;
use tactus_rp2040::pio::reg;
use tactus_runtime::converters::{ADS8688, DAC8568};

const PINS: SpiPins = SpiPins {
    cs: 11,
    sclk: 10,
    sdi: 12,
    sdo: 13,
};

const CLOCK_HZ: f64 = 133e6;

/// An SPI mode-1 master of 32-bit frames, hand-assembled (`.side_set 2`: bit 0 SCLK,
/// bit 1 CSn; delay in bits 10:8):
///
/// ```text
/// 0: pull block   side 0b10 [pad]  ; CSn high, wait for a command word
/// 1: set x, 30    side 0b00        ; CSn falls: the ADC samples
/// 2: out pins, 1  side 0b01 [1]    ; SCLK rises: SDI launched
/// 3: in pins, 1   side 0b00        ; SCLK falls: SDO latched
/// 4: jmp x--, 2   side 0b00
/// 5: out pins, 1  side 0b01 [1]    ; the 32nd bit
/// 6: in pins, 1   side 0b00
/// 7: push block   side 0b00        ; the frame's 32 bits to the RX FIFO
/// ```
fn program(pad: u16) -> [u16; 8] {
    let side = |s: u16, delay: u16| (s << 11) | (delay << 8);
    [
        0x80a0 | side(0b10, pad),
        0xe03e,
        0x6001 | side(0b01, 1),
        0x4001,
        0x0042,
        0x6001 | side(0b01, 1),
        0x4001,
        0x8020,
    ]
}

fn master(div_int: u32, pad: u16) -> Pio {
    let mut pio = Pio::new();
    for (i, w) in program(pad).iter().enumerate() {
        pio.write(reg::INSTR_MEM0 + 4 * i as u32, u32::from(*w));
    }
    pio.write(reg::SM0_CLKDIV, div_int << 16);
    pio.write(reg::SM0_EXECCTRL, 7 << 12);
    // Both shifts left (MSB first), no autopush or autopull.
    pio.write(reg::SM0_SHIFTCTRL, 0);
    // As pico-sdk's pio_sm_set_pins/pindirs do: SET instructions run through SM0_INSTR
    // with the SET pins moved over each group. CSn high and SCLK low before they are
    // driven, then the pins driven.
    pio.write(reg::SM0_PINCTRL, 2 << 26 | PINS.sclk << 5);
    pio.write(reg::SM0_INSTR, 0xe002); // set pins, 0b10
    pio.write(reg::SM0_INSTR, 0xe083); // set pindirs, 0b11
    pio.write(reg::SM0_PINCTRL, 1 << 26 | PINS.sdi << 5);
    pio.write(reg::SM0_INSTR, 0xe081); // set pindirs, 1
    pio.write(
        reg::SM0_PINCTRL,
        2 << 29 | PINS.sclk << 10 | 1 << 20 | PINS.sdi | PINS.sdo << 15,
    );
    pio.write(reg::CTRL, 1);
    pio
}

/// Sends `commands` (one frame each) and returns the frames' 32-bit words from the RX FIFO.
fn exchange(pio: &mut Pio, adc: &mut Ads8688, commands: &[u16], cycle: &mut u64) -> Vec<u32> {
    let mut words = Vec::new();
    for &c in commands {
        pio.write(reg::TXF0, u32::from(c) << 16);
        let start = *cycle;
        while pio.read(reg::FLEVEL) >> 4 & 0xf == 0 {
            pio.tick(adc.gpio_in());
            adc.observe(*cycle, pio.pin_values(), pio.pin_dirs());
            *cycle += 1;
            assert!(*cycle - start < 10_000, "no frame came back");
        }
        words.push(pio.read(reg::RXF0));
    }
    // Let CS rise after the last frame.
    for _ in 0..4 {
        pio.tick(adc.gpio_in());
        adc.observe(*cycle, pio.pin_values(), pio.pin_dirs());
        *cycle += 1;
    }
    words
}

#[test]
fn frames_carry_commands_in_and_codes_out_in_the_commanded_channel_order() {
    let mut adc = Ads8688::new(&ADS8688, PINS, CLOCK_HZ);
    for ch in 0..8 {
        adc.set_code(ch, 0x1000 * ch as u16 + 0x0abc);
    }
    // Divided by 2 and padded to 2 µs: inside every limit.
    let mut pio = master(2, 5);
    let mut cycle = 0;
    let mut commands = vec![0xa000u16]; // AUTO_RST
    commands.extend([0u16; 9]); // NO_OP: the sequence goes on
    commands.push(0xc000 | 5 << 10); // MAN_Ch_5
    commands.extend([0u16; 2]); // NO_OP in manual mode: channel 5 again
    let words = exchange(&mut pio, &mut adc, &commands, &mut cycle);
    let frames = adc.frames();
    assert_eq!(frames.len(), commands.len());
    // Each frame latched its command, and its low 16 bits are its own sample's code.
    for ((f, &c), &w) in frames.iter().zip(&commands).zip(&words) {
        assert_eq!(f.command, c);
        assert_eq!(f.sclks, 32);
        assert_eq!(w & 0xffff, u32::from(f.code), "{f:?}");
        assert_eq!(w >> 16, 0, "nothing on SDO during the command");
    }
    // The channels: channel 0 at power-up, then AUTO_RST's sequence from 0, then MAN_Ch_5.
    let channels: Vec<u8> = frames.iter().map(|f| f.channel).collect();
    assert_eq!(channels, [0, 0, 1, 2, 3, 4, 5, 6, 7, 0, 1, 5, 5]);
    assert!(adc.violations().is_empty(), "{:?}", adc.violations());
    // The frame period: 2 µs or a little more.
    let period = frames[1].cs_fall - frames[0].cs_fall;
    let t = period as f64 / CLOCK_HZ;
    assert!(
        (2e-6..2.1e-6).contains(&t),
        "{period} cycles, {:.3} µs",
        t * 1e6
    );
}

#[test]
fn the_part_reports_frames_too_fast_for_its_data_sheet() {
    let run = |div: u32, pad: u16| {
        let mut adc = Ads8688::new(&ADS8688, PINS, CLOCK_HZ);
        let mut pio = master(div, pad);
        let mut cycle = 0;
        exchange(&mut pio, &mut adc, &[0xa000, 0, 0, 0], &mut cycle);
        adc.violations().to_vec()
    };
    // Undivided: SCLK at 133/4 = 33 MHz, over 17 MHz, and the result clocked out before
    // the 850 ns conversion ends.
    let v = run(1, 5);
    assert!(
        v.iter().any(|v| v.what.contains("SCLK at 33.25 MHz")),
        "{v:?}"
    );
    assert!(
        v.iter()
            .any(|v| v.what.contains("before the 850 ns conversion")),
        "{v:?}"
    );
    // Divided by 2 (16.6 MHz) but not padded: frames every 1.97 µs, over 500 kS/s.
    let v = run(2, 1);
    assert!(
        !v.is_empty() && v.iter().all(|v| v.what.contains("CS falling edges")),
        "{v:?}"
    );
    // Padded: nothing.
    assert!(run(2, 5).is_empty());
}

#[test]
fn a_short_frame_is_a_violation() {
    let mut adc = Ads8688::new(&ADS8688, PINS, CLOCK_HZ);
    // CS low, 3 SCLK pulses, CS high.
    let cs = 1 << PINS.cs;
    let sclk = 1 << PINS.sclk;
    let mut levels = vec![cs, 0];
    for _ in 0..3 {
        levels.extend([sclk, sclk, 0, 0]);
    }
    levels.push(cs);
    for (t, &p) in levels.iter().enumerate() {
        adc.observe(t as u64 * 10, p, cs | sclk);
    }
    assert_eq!(adc.frames().len(), 1);
    assert_eq!(adc.frames()[0].sclks, 3);
    assert!(adc.violations()[0]
        .what
        .contains("a frame of 3 SCLKs, not 32"));
}

/// A DAC frame: `control` (4 bits), `address` (4 bits), a 16-bit `code`.
fn dac_word(control: u32, address: u32, code: u16) -> u32 {
    control << 24 | address << 20 | u32::from(code) << 4
}

/// Sends `words` through the mode-1 master (32-bit frames, MSB first) to `dac`.
fn send(pio: &mut Pio, dac: &mut Dac8568, words: &[u32], cycle: &mut u64) {
    for &w in words {
        pio.write(reg::TXF0, w);
        let start = *cycle;
        while pio.read(reg::FLEVEL) >> 4 & 0xf == 0 {
            pio.tick(0);
            dac.observe(*cycle, pio.pin_values(), pio.pin_dirs());
            *cycle += 1;
            assert!(*cycle - start < 10_000, "no frame came back");
        }
        pio.read(reg::RXF0);
    }
    for _ in 0..40 {
        pio.tick(0);
        dac.observe(*cycle, pio.pin_values(), pio.pin_dirs());
        *cycle += 1;
    }
}

#[test]
fn dac_frames_write_input_registers_and_update_outputs_on_the_32nd_edge() {
    let mut dac = Dac8568::new(&DAC8568, PINS, CLOCK_HZ);
    assert_eq!(dac.outputs(), [0x8000; 8], "midscale at power-up");
    let mut pio = master(2, 5);
    let mut cycle = 0;
    send(
        &mut pio,
        &mut dac,
        &[
            dac_word(3, 2, 0x1234),  // write and update C
            dac_word(0, 5, 0xbeef),  // write F's input register only
            dac_word(3, 15, 0x0100), // write and update every channel
            dac_word(0, 7, 0x7777),  // H's input register
            dac_word(1, 7, 0),       // update H from it
        ],
        &mut cycle,
    );
    assert!(dac.violations().is_empty(), "{:?}", dac.violations());
    let mut expected = [0x0100u16; 8];
    expected[7] = 0x7777;
    assert_eq!(dac.outputs(), expected);
    let u = dac.updates();
    assert_eq!((u[0].channel, u[0].code), (2, 0x1234));
    // F's write alone changed nothing: the next update is the broadcast.
    assert_eq!(u.len(), 1 + 8 + 1);
    assert_eq!((u[9].channel, u[9].code), (7, 0x7777));
}

#[test]
fn dac_timing_is_checked_against_its_data_sheet() {
    let run = |div: u32, pad: u16| {
        let mut dac = Dac8568::new(&DAC8568, PINS, CLOCK_HZ);
        let mut pio = master(div, pad);
        let mut cycle = 0;
        send(
            &mut pio,
            &mut dac,
            &[dac_word(3, 0, 1), dac_word(3, 1, 2)],
            &mut cycle,
        );
        dac.violations().to_vec()
    };
    // Undivided, SCLK at 33 MHz is inside the DAC's 50 MHz, but SYNC is high only 8 cycles
    // (60 ns) between frames even at the longest delay: under its 80 ns.
    let v = run(1, 7);
    assert!(
        !v.is_empty() && v.iter().all(|v| v.what.contains("SYNC high 60 ns")),
        "{v:?}"
    );
    // Divided by 2 with 6 cycles of CS high (90 ns): nothing.
    assert!(run(2, 5).is_empty());
}

/// A DAC clocked by SCLK edges one at a time (`observe`) and one clocked in bulk
/// (`Dac8568::clock_bits`, the bit loops of `crate::io`) come out equal: registers, updates,
/// violations and state, for frames cut into runs of every length, one running past the
/// frame's 32nd bit (the bits after it are ignored).
#[test]
fn a_dac_clocked_in_bulk_equals_one_clocked_edge_by_edge() {
    const PERIOD: u64 = 8;
    let (cs, sclk, sdi) = (1 << PINS.cs, 1 << PINS.sclk, 1 << PINS.sdi);
    let dirs = cs | sclk | sdi;
    let mut edges = Dac8568::new(&DAC8568, PINS, CLOCK_HZ);
    let mut bulk = Dac8568::new(&DAC8568, PINS, CLOCK_HZ);
    let words = [
        dac_word(3, 2, 0x1234),
        dac_word(3, 5, 0xbeef),
        dac_word(0, 7, 0x7777),
        dac_word(1, 7, 0),
        dac_word(3, 15, 0x0f0f),
    ];
    let cuts: [&[u32]; 5] = [&[32], &[1, 7, 13, 11], &[5, 27], &[31, 1], &[20, 20]];
    let mut cycle = 100;
    for (&w, runs) in words.iter().zip(cuts) {
        for dac in [&mut edges, &mut bulk] {
            dac.observe(cycle, 0, dirs);
        }
        cycle += 20;
        let mut bit = 0u32;
        for &k in runs {
            let first = cycle + PERIOD;
            // Bit i of the run: SDI and SCLK high half a period before its fall.
            let mut sdi_bits = 0u64;
            for i in 0..k {
                let b = bit + i;
                let level = if b < 32 { w >> (31 - b) & 1 } else { 0 };
                sdi_bits |= u64::from(level) << i;
                let fall = first + u64::from(i) * PERIOD;
                let d = if level != 0 { sdi } else { 0 };
                edges.observe(fall - PERIOD / 2, sclk | d, dirs);
                edges.observe(fall, d, dirs);
            }
            assert!(bulk.clocks_ok(PERIOD));
            bulk.clock_bits(first, PERIOD, k, sdi_bits);
            bit += k;
            cycle = first + u64::from(k - 1) * PERIOD;
        }
        cycle += 20;
        for dac in [&mut edges, &mut bulk] {
            dac.observe(cycle, cs, dirs);
        }
        cycle += 20;
    }
    assert!(edges.violations().is_empty(), "{:?}", edges.violations());
    assert_eq!(edges.updates(), bulk.updates());
    assert_eq!(edges.outputs(), bulk.outputs());
    assert_eq!(edges.updates().len(), 2 + 1 + 8);
    assert_eq!(format!("{edges:?}"), format!("{bulk:?}"));
}

/// An ADC clocked by SCLK edges one at a time (`observe`) and one clocked in bulk
/// (`Ads8688::clock_bits`, the bit loops of `crate::io`) come out equal: the SDO level after
/// every rise, the frames, violations and state, for frames cut into runs of every length
/// — across the frame's half (the result's first rise checks the conversion) and past its
/// 32nd rise (a frame too long, reported by both).
#[test]
fn an_adc_clocked_in_bulk_equals_one_clocked_edge_by_edge() {
    const PERIOD: u64 = 8;
    const FALL: u64 = 4;
    let (cs, sclk, sdi) = (1 << PINS.cs, 1 << PINS.sclk, 1 << PINS.sdi);
    let dirs = cs | sclk | sdi;
    let mut edges = Ads8688::new(&ADS8688, PINS, CLOCK_HZ);
    let mut bulk = Ads8688::new(&ADS8688, PINS, CLOCK_HZ);
    for adc in [&mut edges, &mut bulk] {
        for (ch, code) in [0xbeef, 0x0001, 0x8000, 0x7ffe, 0x5a5a, 0, 0xffff, 0x1234]
            .into_iter()
            .enumerate()
        {
            adc.set_code(ch, code);
        }
    }
    // Each frame's SDI word: a MAN_Ch_n command for the next channel in its top half.
    let cuts: [&[u32]; 8] = [
        &[32],
        &[1, 15, 16],
        &[16, 1, 15],
        &[17, 15],
        &[5, 27],
        &[31, 1],
        &[20, 20],
        &[1; 32],
    ];
    let mut cycle = 100;
    for (f, runs) in cuts.into_iter().enumerate() {
        let command = (0xc000u32 | ((f as u32 + 1) % 8) << 10) << 16;
        for adc in [&mut edges, &mut bulk] {
            adc.observe(cycle, cs, dirs);
        }
        cycle += 20;
        for adc in [&mut edges, &mut bulk] {
            adc.observe(cycle, 0, dirs);
        }
        cycle += 20;
        let mut bit = 0u32;
        for &k in runs {
            let first = cycle + PERIOD;
            let mut sdi_bits = 0u64;
            let mut want = 0u64;
            for i in 0..k {
                let b = bit + i;
                let level = if b < 32 { command >> (31 - b) & 1 } else { 0 };
                sdi_bits |= u64::from(level) << i;
                let rise = first + u64::from(i) * PERIOD;
                let d = if level != 0 { sdi } else { 0 };
                edges.observe(rise, sclk | d, dirs);
                want |= u64::from(edges.gpio_in() >> PINS.sdo & 1) << i;
                edges.observe(rise + FALL, d, dirs);
            }
            assert!(bulk.clocks_ok(PERIOD));
            let got = bulk.clock_bits(first, FALL, PERIOD, k, sdi_bits);
            assert_eq!(got, want, "frame {f}, bits {bit}..{}", bit + k);
            assert_eq!(format!("{edges:?}"), format!("{bulk:?}"), "frame {f}");
            bit += k;
            cycle = first + u64::from(k - 1) * PERIOD + FALL;
        }
        cycle += 20;
        for adc in [&mut edges, &mut bulk] {
            adc.observe(cycle, cs, dirs);
        }
        cycle += 400;
    }
    assert_eq!(edges.frames(), bulk.frames());
    assert_eq!(edges.frames().len(), cuts.len());
    assert!(
        edges.frames().iter().any(|f| f.code == 0xbeef),
        "{:?}",
        edges.frames()
    );
    assert_eq!(edges.violations().len(), 1, "{:?}", edges.violations());
    assert_eq!(format!("{edges:?}"), format!("{bulk:?}"));
}
