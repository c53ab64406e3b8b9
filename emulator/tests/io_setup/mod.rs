//! The converter set-up shared by `io.rs` and `io_windows.rs`: an ADS8688 on PIO0's pins,
//! its SPI master program, and the register stores with which a core starts the master and
//! two DMA channels (commands in, results out).
#![allow(dead_code)]

use tactus_emulator::bus::Bus;
use tactus_emulator::converters::SpiPins;
use tactus_emulator::system::System;
use tactus_rp2040::busctrl::BUSCTRL_BASE;
use tactus_rp2040::dma::{ctrl, reg as dreg, DMA_BASE};
use tactus_rp2040::io_bank0::{FUNCSEL_PIO0, IO_BANK0_BASE};
use tactus_rp2040::pio::{reg, PIO0_BASE};

pub const PINS: SpiPins = SpiPins {
    cs: 11,
    sclk: 10,
    sdi: 12,
    sdo: 13,
};
pub const CLOCK_HZ: u64 = 133_000_000;
/// The results' buffer: bank 2 through its non-striped alias.
pub const RESULTS: u32 = 0x2102_0000;
/// The commands: further up bank 2.
pub const COMMANDS: u32 = 0x2102_0100;
pub const FRAMES: u32 = 8;

/// The SPI mode-1 master of `tests/converters.rs` (`.side_set 2`: SCLK, CSn), divided by 2,
/// CS high for 6 PIO cycles between frames.
pub const PROGRAM: [u16; 8] = [
    0x80a0 | 0b10 << 11 | 5 << 8,
    0xe03e,
    0x6001 | 0b01 << 11 | 1 << 8,
    0x4001,
    0x0042,
    0x6001 | 0b01 << 11 | 1 << 8,
    0x4001,
    0x8020,
];

/// Core 0's stores, two cycles apart from `*t`.
pub struct Cpu<'a> {
    pub sys: &'a mut System,
    pub t: u64,
}

impl Cpu<'_> {
    pub fn store(&mut self, addr: u32, value: u32) {
        self.sys.write(0, self.t, addr, 4, value).expect("store");
        self.t += 2;
    }
}

/// Core 0's stores from cycle `t` that set up `bus_priority`, the pins, the master (running
/// `program`, at 0, wrapping at 7) and DMA channels 0 (RX FIFO 0 → [`RESULTS`]) and 1
/// ([`COMMANDS`] → TX FIFO 0) and start both, the commands written into SRAM first: returns
/// the cycle after the last store.
pub fn program_adc(sys: &mut System, program: &[u16; 8], bus_priority: u32, t: u64) -> u64 {
    // Frame i commands MAN_Ch_(i+1): frame i samples channel i (channel 0 at power-up).
    for i in 0..FRAMES {
        let command = 0xc000 | ((i + 1) % 8) << 10;
        let (mem, off) = sys.backing(COMMANDS + 4 * i).expect("SRAM");
        mem[off..off + 4].copy_from_slice(&(command << 16).to_le_bytes());
    }
    let mut cpu = Cpu { sys, t };
    cpu.store(BUSCTRL_BASE, bus_priority);
    for pin in [PINS.cs, PINS.sclk, PINS.sdi] {
        cpu.store(IO_BANK0_BASE + 8 * pin + 4, FUNCSEL_PIO0);
    }
    for (i, w) in program.iter().enumerate() {
        cpu.store(PIO0_BASE + reg::INSTR_MEM0 + 4 * i as u32, u32::from(*w));
    }
    cpu.store(PIO0_BASE + reg::SM0_CLKDIV, 2 << 16);
    cpu.store(PIO0_BASE + reg::SM0_EXECCTRL, 7 << 12);
    cpu.store(PIO0_BASE + reg::SM0_SHIFTCTRL, 0);
    cpu.store(PIO0_BASE + reg::SM0_PINCTRL, 2 << 26 | PINS.sclk << 5);
    cpu.store(PIO0_BASE + reg::SM0_INSTR, 0xe002); // set pins, 0b10: CSn high
    cpu.store(PIO0_BASE + reg::SM0_INSTR, 0xe083); // set pindirs, 0b11
    cpu.store(PIO0_BASE + reg::SM0_PINCTRL, 1 << 26 | PINS.sdi << 5);
    cpu.store(PIO0_BASE + reg::SM0_INSTR, 0xe081); // set pindirs, 1
    cpu.store(
        PIO0_BASE + reg::SM0_PINCTRL,
        2 << 29 | PINS.sclk << 10 | 1 << 20 | PINS.sdi | PINS.sdo << 15,
    );
    cpu.store(PIO0_BASE + reg::CTRL, 1);
    // Channel 0: RX FIFO 0 → the results (DREQ 4); channel 1: the commands → TX FIFO 0
    // (DREQ 0). Each started by the write of its address through its trigger alias.
    let word = 2 << ctrl::DATA_SIZE_SHIFT | ctrl::EN;
    let ch = |n: u32, off: u32| DMA_BASE + n * dreg::CH_STRIDE + off;
    cpu.store(
        ch(0, dreg::AL1_CTRL),
        word | ctrl::INCR_WRITE | 4 << ctrl::TREQ_SEL_SHIFT,
    );
    cpu.store(ch(0, dreg::READ_ADDR), PIO0_BASE + reg::RXF0);
    cpu.store(ch(0, dreg::TRANS_COUNT), FRAMES);
    cpu.store(
        ch(1, dreg::AL1_CTRL),
        word | ctrl::INCR_READ | 1 << ctrl::CHAIN_TO_SHIFT,
    );
    cpu.store(ch(1, dreg::WRITE_ADDR), PIO0_BASE + reg::TXF0);
    cpu.store(ch(1, dreg::TRANS_COUNT), FRAMES);
    cpu.store(ch(0, dreg::AL2_WRITE_ADDR_TRIG), RESULTS);
    cpu.store(ch(1, dreg::AL3_READ_ADDR_TRIG), COMMANDS);
    cpu.t
}
