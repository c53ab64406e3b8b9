//! The DMA model (`tactus_emulator::dma`) against the RP2040 datasheet's section 2.5: an
//! unpaced memory copy at one transfer a cycle with its interrupt; the four register
//! aliases and their triggers; null triggers with and without IRQ_QUIET; chaining; the ring
//! wrap; a bus fault; and the credit-based pacing against the PIO model — a channel feeding
//! a slow state machine's TX FIFO never loses a word and fills the FIFO back to back, and a
//! channel draining an RX FIFO that a state machine fills every cycle never reads one twice.

use std::collections::BTreeMap;
use tactus_emulator::bus::BusFault;
use tactus_emulator::dma::{Dma, DmaPort};
use tactus_emulator::pio::Pio;
use tactus_rp2040::dma::{ctrl, reg, TREQ_PERMANENT, TREQ_TIMER0};
use tactus_rp2040::pio;

const SRAM: u32 = 0x2000_0000;

/// SRAM as a map of words, PIO0 at its base, and a record of every access.
struct Port {
    mem: BTreeMap<u32, u32>,
    pio: Pio,
    reads: Vec<(u64, u32)>,
    writes: Vec<(u64, u32, u32)>,
    /// Wait states of each SRAM access.
    wait: u32,
}

impl Port {
    fn new() -> Self {
        Port {
            mem: BTreeMap::new(),
            pio: Pio::new(),
            reads: Vec::new(),
            writes: Vec::new(),
            wait: 0,
        }
    }

    fn is_pio(addr: u32) -> bool {
        (pio::PIO0_BASE..pio::PIO0_BASE + 0x1000).contains(&addr)
    }
}

impl DmaPort for Port {
    fn read(&mut self, cycle: u64, addr: u32, size: u32) -> Result<(u32, u32), BusFault> {
        self.reads.push((cycle, addr));
        if Self::is_pio(addr) {
            return Ok((self.pio.read(addr - pio::PIO0_BASE), 0));
        }
        if !(SRAM..SRAM + 0x4_2000).contains(&addr) {
            return Err(BusFault { addr });
        }
        let word = self.mem.get(&(addr & !3)).copied().unwrap_or(0);
        let shift = 8 * (addr & 3);
        let mask = if size == 4 {
            u32::MAX
        } else {
            (1 << (8 * size)) - 1
        };
        Ok(((word >> shift) & mask, self.wait))
    }

    fn write(&mut self, cycle: u64, addr: u32, size: u32, value: u32) -> Result<u32, BusFault> {
        self.writes.push((cycle, addr, value));
        if Self::is_pio(addr) {
            self.pio.write(addr - pio::PIO0_BASE, value);
            return Ok(0);
        }
        if !(SRAM..SRAM + 0x4_2000).contains(&addr) {
            return Err(BusFault { addr });
        }
        let shift = 8 * (addr & 3);
        let mask = if size == 4 {
            u32::MAX
        } else {
            ((1 << (8 * size)) - 1) << shift
        };
        let w = self.mem.entry(addr & !3).or_insert(0);
        *w = (*w & !mask) | ((value << shift) & mask);
        Ok(self.wait)
    }

    fn dreq_room(&self, n: u32) -> u32 {
        match n {
            0..=3 => self.pio.tx_room(n as usize),
            4..=7 => self.pio.rx_level(n as usize - 4),
            _ => 0,
        }
    }
}

/// CTRL with `fields`, word size, chained to itself, paced by `treq`.
fn ctrl_word(ch: u32, treq: u32, fields: u32) -> u32 {
    ctrl::EN
        | 2 << ctrl::DATA_SIZE_SHIFT
        | ch << ctrl::CHAIN_TO_SHIFT
        | treq << ctrl::TREQ_SEL_SHIFT
        | fields
}

fn ch(n: u32, offset: u32) -> u32 {
    n * reg::CH_STRIDE + offset
}

/// Ticks `dma` (and the PIO) from `from` until `until` holds or `limit` cycles pass; returns
/// the cycle after the last tick.
fn run(dma: &mut Dma, port: &mut Port, from: u64, limit: u64, until: impl Fn(&Dma) -> bool) -> u64 {
    let mut t = from;
    while t < from + limit && !until(dma) {
        dma.tick(t, port);
        port.pio.tick(0);
        t += 1;
    }
    t
}

#[test]
fn unpaced_copy_is_one_transfer_a_cycle_and_raises_its_interrupt() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    for i in 0..8 {
        port.mem.insert(SRAM + 4 * i, 0x1000 + i);
    }
    dma.write(reg::INTE0, 1 << 3);
    dma.write(ch(3, reg::READ_ADDR), SRAM);
    dma.write(ch(3, reg::WRITE_ADDR), SRAM + 0x100);
    dma.write(ch(3, reg::TRANS_COUNT), 8);
    assert!(!dma.busy(3), "not started before its trigger");
    dma.write(
        ch(3, reg::CTRL_TRIG),
        ctrl_word(3, TREQ_PERMANENT, ctrl::INCR_READ | ctrl::INCR_WRITE),
    );
    assert!(dma.busy(3));
    assert_ne!(dma.read(ch(3, reg::CTRL_TRIG)) & ctrl::BUSY, 0);
    let end = run(&mut dma, &mut port, 0, 100, |d| !d.busy(3));
    for i in 0..8 {
        assert_eq!(port.mem[&(SRAM + 0x100 + 4 * i)], 0x1000 + i);
    }
    // Reads on cycles 0..8, each write the cycle after its read.
    let read_cycles: Vec<u64> = port.reads.iter().map(|r| r.0).collect();
    let write_cycles: Vec<u64> = port.writes.iter().map(|w| w.0).collect();
    assert_eq!(read_cycles, (0..8).collect::<Vec<_>>());
    assert_eq!(write_cycles, (1..9).collect::<Vec<_>>());
    assert_eq!(end, 9, "BUSY clears with the last write");
    assert_eq!(dma.read(ch(3, reg::TRANS_COUNT)), 0);
    assert_eq!(dma.read(ch(3, reg::READ_ADDR)), SRAM + 32);
    assert_eq!(
        dma.read(reg::DBG_TCR + 3 * reg::CH_STRIDE),
        8,
        "the reload value stays"
    );
    assert_eq!(dma.read(reg::INTR), 1 << 3);
    assert!(dma.irq0() && !dma.irq1());
    dma.write(reg::INTS0, 1 << 3);
    assert!(!dma.irq0(), "write 1 to INTS0 clears the flag");
    // A second trigger repeats the same count from where the addresses are now.
    let c = dma.read(ch(3, reg::CTRL_TRIG));
    dma.write(ch(3, reg::CTRL_TRIG), c);
    run(&mut dma, &mut port, end, 100, |d| !d.busy(3));
    assert_eq!(port.writes.len(), 16);
    assert_eq!(port.writes[8].1, SRAM + 0x120);
}

#[test]
fn wait_states_hold_the_ports() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    port.wait = 2;
    dma.write(ch(0, reg::TRANS_COUNT), 3);
    dma.write(ch(0, reg::READ_ADDR), SRAM);
    dma.write(ch(0, reg::WRITE_ADDR), SRAM + 0x40);
    dma.write(
        ch(0, reg::CTRL_TRIG),
        ctrl_word(0, TREQ_PERMANENT, ctrl::INCR_READ | ctrl::INCR_WRITE),
    );
    run(&mut dma, &mut port, 0, 100, |d| !d.busy(0));
    let read_cycles: Vec<u64> = port.reads.iter().map(|r| r.0).collect();
    let write_cycles: Vec<u64> = port.writes.iter().map(|w| w.0).collect();
    assert_eq!(read_cycles, [0, 3, 6]);
    assert_eq!(write_cycles, [3, 6, 9]);
}

#[test]
fn every_alias_reaches_the_same_registers_and_its_last_word_triggers() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    port.mem.insert(SRAM, 7);
    // Alias 1: CTRL, READ_ADDR, WRITE_ADDR, TRANS_COUNT_TRIG.
    dma.write(ch(1, reg::AL1_CTRL), ctrl_word(1, TREQ_PERMANENT, 0));
    dma.write(ch(1, 0x14), SRAM);
    dma.write(ch(1, 0x18), SRAM + 0x10);
    assert_eq!(dma.read(ch(1, reg::READ_ADDR)), SRAM);
    assert_eq!(dma.read(ch(1, 0x28)), SRAM, "alias 2's READ_ADDR");
    assert_eq!(dma.read(ch(1, 0x34)), SRAM + 0x10, "alias 3's WRITE_ADDR");
    assert!(!dma.busy(1), "CTRL through alias 1 is not a trigger");
    dma.write(ch(1, reg::AL1_TRANS_COUNT_TRIG), 1);
    assert!(dma.busy(1), "TRANS_COUNT_TRIG starts it");
    assert_eq!(dma.read(ch(1, reg::TRANS_COUNT)), 1);
    run(&mut dma, &mut port, 0, 10, |d| !d.busy(1));
    assert_eq!(port.mem[&(SRAM + 0x10)], 7);
    // Alias 2's trigger is the write address, alias 3's the read address.
    dma.write(ch(1, reg::AL2_WRITE_ADDR_TRIG), SRAM + 0x20);
    assert!(dma.busy(1));
    run(&mut dma, &mut port, 10, 10, |d| !d.busy(1));
    assert_eq!(port.mem[&(SRAM + 0x20)], 7);
    dma.write(ch(1, 0x34), SRAM + 0x30);
    dma.write(ch(1, reg::AL3_READ_ADDR_TRIG), SRAM);
    run(&mut dma, &mut port, 20, 10, |d| !d.busy(1));
    assert_eq!(port.mem[&(SRAM + 0x30)], 7);
    // A trigger while busy does nothing; a trigger with EN clear does nothing.
    dma.write(ch(2, reg::TRANS_COUNT), 1);
    dma.write(
        ch(2, reg::CTRL_TRIG),
        ctrl_word(2, TREQ_PERMANENT, 0) & !ctrl::EN,
    );
    assert!(!dma.busy(2));
    assert_eq!(dma.read(reg::N_CHANNELS), 12);
}

#[test]
fn null_triggers_start_nothing_and_interrupt_only_when_quiet() {
    let mut dma = Dma::new();
    dma.write(ch(4, reg::AL1_CTRL), ctrl_word(4, TREQ_PERMANENT, 0));
    dma.write(ch(4, reg::AL1_TRANS_COUNT_TRIG), 0);
    assert!(!dma.busy(4));
    assert_eq!(dma.read(reg::INTR), 0);
    dma.write(
        ch(4, reg::AL1_CTRL),
        ctrl_word(4, TREQ_PERMANENT, ctrl::IRQ_QUIET),
    );
    dma.write(ch(4, reg::AL2_WRITE_ADDR_TRIG), 0);
    assert!(!dma.busy(4));
    assert_eq!(dma.read(reg::INTR), 1 << 4);
}

#[test]
fn a_finished_channel_triggers_its_chain_quietly_or_not() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    port.mem.insert(SRAM, 1);
    port.mem.insert(SRAM + 4, 2);
    // Channel 5 copies one word, then chains to 6, which copies another; 5 is quiet.
    dma.write(ch(6, reg::READ_ADDR), SRAM + 4);
    dma.write(ch(6, reg::WRITE_ADDR), SRAM + 0x84);
    dma.write(ch(6, reg::TRANS_COUNT), 1);
    dma.write(ch(6, reg::AL1_CTRL), ctrl_word(6, TREQ_PERMANENT, 0));
    dma.write(ch(5, reg::READ_ADDR), SRAM);
    dma.write(ch(5, reg::WRITE_ADDR), SRAM + 0x80);
    dma.write(ch(5, reg::TRANS_COUNT), 1);
    dma.write(
        ch(5, reg::CTRL_TRIG),
        ctrl_word(5, TREQ_PERMANENT, ctrl::IRQ_QUIET) & !(0xf << ctrl::CHAIN_TO_SHIFT)
            | 6 << ctrl::CHAIN_TO_SHIFT,
    );
    let end = run(&mut dma, &mut port, 0, 20, |d| !d.busy(5) && !d.busy(6));
    assert_eq!(port.mem[&(SRAM + 0x80)], 1);
    assert_eq!(port.mem[&(SRAM + 0x84)], 2);
    assert_eq!(dma.read(reg::INTR), 1 << 6, "only the loud channel's flag");
    assert_eq!(end, 4, "6 starts as 5's write lands, reads the cycle after");
}

#[test]
fn the_ring_wraps_the_selected_address() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    for i in 0..4 {
        port.mem.insert(SRAM + 4 * i, 10 + i);
    }
    // Ten words read from a 16-byte ring (RING_SIZE 4) into a straight buffer.
    dma.write(ch(0, reg::READ_ADDR), SRAM);
    dma.write(ch(0, reg::WRITE_ADDR), SRAM + 0x100);
    dma.write(ch(0, reg::TRANS_COUNT), 10);
    dma.write(
        ch(0, reg::CTRL_TRIG),
        ctrl_word(
            0,
            TREQ_PERMANENT,
            ctrl::INCR_READ | ctrl::INCR_WRITE | 4 << ctrl::RING_SIZE_SHIFT,
        ),
    );
    run(&mut dma, &mut port, 0, 50, |d| !d.busy(0));
    let got: Vec<u32> = (0..10).map(|i| port.mem[&(SRAM + 0x100 + 4 * i)]).collect();
    assert_eq!(got, [10, 11, 12, 13, 10, 11, 12, 13, 10, 11]);
    assert_eq!(dma.read(ch(0, reg::READ_ADDR)), SRAM + 8);
}

#[test]
fn a_bus_fault_halts_the_channel_with_its_flags_and_no_chain() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    dma.write(ch(7, reg::AL1_CTRL), ctrl_word(7, TREQ_PERMANENT, 0));
    dma.write(ch(0, reg::READ_ADDR), 0x1000_0000 - 4);
    dma.write(ch(0, reg::WRITE_ADDR), SRAM);
    dma.write(ch(0, reg::TRANS_COUNT), 4);
    dma.write(
        ch(0, reg::CTRL_TRIG),
        ctrl_word(0, TREQ_PERMANENT, ctrl::INCR_READ) & !(0xf << ctrl::CHAIN_TO_SHIFT)
            | 7 << ctrl::CHAIN_TO_SHIFT,
    );
    run(&mut dma, &mut port, 0, 20, |d| !d.busy(0));
    let c = dma.read(ch(0, reg::CTRL_TRIG));
    assert_ne!(c & ctrl::READ_ERROR, 0);
    assert_ne!(c & ctrl::AHB_ERROR, 0);
    assert!(!dma.busy(7), "no chain after an error");
    assert_eq!(dma.read(reg::INTR), 1);
    // Writing the flag back clears it.
    dma.write(ch(0, reg::AL1_CTRL), c);
    assert_eq!(dma.read(ch(0, reg::CTRL_TRIG)) & ctrl::AHB_ERROR, 0);
}

/// pioasm encodings: `pull block` and `out pins, 32 [15]`.
const SLOW_OUT: [u16; 2] = [0x80a0, 0x6f00];

#[test]
fn tx_pacing_fills_a_pio_fifo_back_to_back_and_never_overruns_it() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    for (i, &w) in SLOW_OUT.iter().enumerate() {
        port.pio
            .write(pio::reg::INSTR_MEM0 + 4 * i as u32, u32::from(w));
    }
    // OUT_BASE 0, OUT_COUNT 32; wrap over the two instructions.
    port.pio.write(pio::reg::SM0_PINCTRL, 32 << 20);
    port.pio.write(pio::reg::SM0_EXECCTRL, 1 << 12);
    let words: Vec<u32> = (0..12).map(|i| 0xa000_0000 | i).collect();
    for (i, &w) in words.iter().enumerate() {
        port.mem.insert(SRAM + 4 * i as u32, w);
    }
    dma.write(ch(2, reg::READ_ADDR), SRAM);
    dma.write(ch(2, reg::WRITE_ADDR), pio::PIO0_BASE + pio::reg::TXF0);
    dma.write(ch(2, reg::TRANS_COUNT), words.len() as u32);
    // DREQ 0: PIO0 TX0.
    dma.write(ch(2, reg::CTRL_TRIG), ctrl_word(2, 0, ctrl::INCR_READ));
    // Four words go into the FIFO back to back before the state machine runs.
    let t = run(&mut dma, &mut port, 0, 20, |_| false);
    let first: Vec<u64> = port.writes.iter().map(|w| w.0).collect();
    assert_eq!(
        first,
        [1, 2, 3, 4],
        "four writes, one a cycle, then the FIFO is full"
    );
    port.pio.write(pio::reg::CTRL, 1);
    let mut seen = Vec::new();
    let mut t = t;
    while t < 2000 {
        dma.tick(t, &mut port);
        port.pio.tick(0);
        let v = port.pio.pin_values();
        if v != 0 && seen.last() != Some(&v) {
            seen.push(v);
        }
        assert!(port.pio.tx_room(0) <= 4, "cycle {t}");
        t += 1;
    }
    assert_eq!(seen, words, "every word out, in order, none dropped");
    assert!(!dma.busy(2));
}

/// `in pins, 32` with autopush at 32 bits: a word of the GPIO inputs every cycle.
const FAST_IN: [u16; 1] = [0x4000];

#[test]
fn rx_pacing_drains_a_pio_fifo_without_reading_a_word_twice() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    port.pio.write(pio::reg::INSTR_MEM0, u32::from(FAST_IN[0]));
    port.pio.write(pio::reg::SM0_EXECCTRL, 0);
    // AUTOPUSH, PUSH_THRESH 32 (0), IN_SHIFTDIR left; no synchroniser.
    port.pio.write(pio::reg::SM0_SHIFTCTRL, 1 << 16);
    port.pio.write(pio::reg::INPUT_SYNC_BYPASS, u32::MAX);
    dma.write(ch(0, reg::READ_ADDR), pio::PIO0_BASE + pio::reg::RXF0);
    dma.write(ch(0, reg::WRITE_ADDR), SRAM);
    dma.write(ch(0, reg::TRANS_COUNT), 64);
    // DREQ 4: PIO0 RX0.
    dma.write(ch(0, reg::CTRL_TRIG), ctrl_word(0, 4, ctrl::INCR_WRITE));
    port.pio.write(pio::reg::CTRL, 1);
    let mut t = 0;
    while dma.busy(0) && t < 1000 {
        dma.tick(t, &mut port);
        // The inputs count cycles from 1.
        port.pio.tick(t as u32 + 1);
        t += 1;
    }
    assert!(!dma.busy(0));
    let got: Vec<u32> = (0..64).map(|i| port.mem[&(SRAM + 4 * i)]).collect();
    assert!(
        got.windows(2).all(|w| w[1] > w[0]),
        "strictly increasing: {got:?}"
    );
    assert!(got.iter().all(|&w| w != 0), "no read of an empty FIFO");
}

#[test]
fn a_pacing_timer_gives_x_transfers_every_y_cycles() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    // TIMER1 at 1/4: one transfer every fourth cycle.
    dma.write(reg::TIMER0 + 4, 1 << 16 | 4);
    dma.write(ch(0, reg::READ_ADDR), SRAM);
    dma.write(ch(0, reg::WRITE_ADDR), SRAM + 0x40);
    dma.write(ch(0, reg::TRANS_COUNT), 5);
    dma.write(ch(0, reg::CTRL_TRIG), ctrl_word(0, TREQ_TIMER0 + 1, 0));
    run(&mut dma, &mut port, 0, 100, |d| !d.busy(0));
    let read_cycles: Vec<u64> = port.reads.iter().map(|r| r.0).collect();
    assert_eq!(read_cycles, [3, 7, 11, 15, 19]);
}

#[test]
fn high_priority_channels_are_served_first_each_round() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    for (n, high) in [(0u32, false), (1, false), (2, true), (3, true)] {
        dma.write(ch(n, reg::READ_ADDR), SRAM + 0x100 * n);
        dma.write(ch(n, reg::WRITE_ADDR), SRAM + 0x1000 + 0x100 * n);
        dma.write(ch(n, reg::TRANS_COUNT), 6);
        let p = if high { ctrl::HIGH_PRIORITY } else { 0 };
        dma.write(
            ch(n, reg::AL1_CTRL),
            ctrl_word(n, TREQ_PERMANENT, p | ctrl::INCR_READ),
        );
    }
    dma.write(reg::MULTI_CHAN_TRIGGER, 0xf);
    run(&mut dma, &mut port, 0, 12, |_| false);
    let order: Vec<u32> = port.reads.iter().map(|r| (r.1 - SRAM) / 0x100).collect();
    // Each round: both high-priority channels, then one low-priority one, alternating.
    assert_eq!(order, [2, 3, 0, 2, 3, 1, 2, 3, 0, 2, 3, 1]);
}

#[test]
fn abort_ends_a_sequence_without_an_interrupt() {
    let mut dma = Dma::new();
    let mut port = Port::new();
    dma.write(ch(0, reg::TRANS_COUNT), 100);
    dma.write(ch(0, reg::READ_ADDR), SRAM);
    dma.write(ch(0, reg::WRITE_ADDR), SRAM + 0x1000);
    dma.write(
        ch(0, reg::CTRL_TRIG),
        ctrl_word(0, TREQ_PERMANENT, ctrl::INCR_READ | ctrl::INCR_WRITE),
    );
    run(&mut dma, &mut port, 0, 5, |_| false);
    dma.write(reg::CHAN_ABORT, 1);
    assert!(!dma.busy(0) && dma.idle());
    let n = port.writes.len();
    run(&mut dma, &mut port, 5, 5, |_| false);
    assert_eq!(port.writes.len(), n, "nothing after the abort");
    assert_eq!(dma.read(reg::INTR), 0);
}
