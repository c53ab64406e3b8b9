//! The converters' I/O on the emulated bus (`tactus_emulator::io`): a core programs PIO0,
//! IO_BANK0, BUS_PRIORITY and two DMA channels through their registers, and an ADS8688's
//! frames come back into SRAM by DMA, paced by the PIO's DREQs, inside the part's timing.
//! The machine skips quiet stretches in one step: the same frames, words and cycles as
//! ticking it every cycle. A core's access to a bank the DMA writes in the same cycle waits
//! when the DMA has the higher bus priority, and wins otherwise.

use tactus_emulator::bus::Bus;
use tactus_emulator::io::{Io, IoConfig};
use tactus_emulator::system::System;
use tactus_rp2040::busctrl::priority;
use tactus_rp2040::dma::{reg as dreg, DMA_BASE};
use tactus_rp2040::pio::{reg, PIO0_BASE};
use tactus_runtime::converters::ADS8688;

mod io_setup;
use io_setup::{Cpu, CLOCK_HZ, COMMANDS, FRAMES, PINS, PROGRAM, RESULTS};

/// A system with an ADS8688 on PIO0's pins, its channels reading `0x1000·ch + 0x0abc`,
/// `priority` in BUS_PRIORITY, and core 0 having set up the master and two DMA channels
/// (commands in, results out) and started them: returns the system and the cycle after the
/// last store.
fn set_up(bus_priority: u32, stepwise: bool) -> (System, u64) {
    set_up_with(&PROGRAM, bus_priority, stepwise)
}

/// [`set_up`] with the master's program `program` (at 0, wrapping at 7).
fn set_up_with(program: &[u16; 8], bus_priority: u32, stepwise: bool) -> (System, u64) {
    let mut sys = System::new(CLOCK_HZ);
    let mut io = Io::new(
        &IoConfig {
            adcs: vec![(&ADS8688, PINS)],
            dacs: vec![],
        },
        CLOCK_HZ as f64,
        0,
    );
    io.stepwise = stepwise;
    for ch in 0..8 {
        io.adcs[0].set_code(ch, 0x1000 * ch as u16 + 0x0abc);
    }
    sys.io = Some(Box::new(io));
    let t = io_setup::program_adc(&mut sys, program, bus_priority, 100);
    (sys, t)
}

/// The word at `addr` as the host sees it (no cycle, no claim).
fn peek(sys: &mut System, addr: u32) -> u32 {
    let (mem, off) = sys.backing(addr).expect("SRAM");
    u32::from_le_bytes(mem[off..off + 4].try_into().expect("word"))
}

/// Cycles of eight frames of 2.03 µs at 133 MHz, with room to spare.
const RUN: u64 = 8 * 300 + 200;

#[test]
fn frames_come_back_into_sram_by_dma_inside_the_parts_timing() {
    let (mut sys, t) = set_up(priority::DMA_R | priority::DMA_W, false);
    // The channels' banks leave the fast path: bank 2 only.
    sys.io_advance(t + RUN);
    let io = sys.io.as_ref().expect("io");
    let adc = &io.adcs[0];
    assert!(adc.violations().is_empty(), "{:?}", adc.violations());
    assert_eq!(adc.frames().len(), FRAMES as usize);
    for (i, f) in adc.frames().iter().enumerate() {
        assert_eq!(f.channel, i as u8);
        assert_eq!(f.sclks, 32);
    }
    assert_eq!(io.reach_banks(), 1 << 2);
    for i in 0..FRAMES {
        let w = peek(&mut sys, RESULTS + 4 * i);
        assert_eq!(w & 0xffff, 0x1000 * i + 0x0abc, "word {i}: {w:#x}");
    }
    // Both channels done.
    let io = sys.io.as_mut().expect("io");
    assert!(!io.dma.busy(0) && !io.dma.busy(1));
    // A core's read of the last word, through the bus, sees it too.
    let (v, wait) = sys.read(0, t + RUN + 1, RESULTS + 28, 4).expect("read");
    assert_eq!((v & 0xffff, wait), (0x7abc, 0));
}

/// Everything observable of the machine and its memory, for comparing two runs: the
/// frames, the words in SRAM, registers, and the whole state of the PIO blocks, the DMA
/// and the converters.
fn snapshot(sys: &mut System) -> (Vec<u64>, Vec<u32>, [u32; 4], String) {
    let words = (0..FRAMES)
        .map(|i| peek(sys, RESULTS + 4 * i))
        .collect::<Vec<_>>();
    let io = sys.io.as_mut().expect("io");
    let frames = io.adcs[0].frames().iter().map(|f| f.cs_fall).collect();
    let regs = [
        io.pio[0].read(reg::FLEVEL),
        io.pio[0].read(reg::SM0_ADDR),
        io.dma.read(dreg::TRANS_COUNT),
        io.dma.read(dreg::CH_STRIDE + dreg::TRANS_COUNT),
    ];
    let state = format!("{:?} {:?} {:?} {:?}", io.pio, io.dma, io.adcs, io.dacs);
    (frames, words, regs, state)
}

#[test]
fn skipping_quiet_stretches_changes_nothing() {
    let (mut fast, t) = set_up(priority::DMA_R | priority::DMA_W, false);
    let (mut slow, _) = set_up(priority::DMA_R | priority::DMA_W, true);
    // The slow one a cycle at a time, the fast one in strides that end anywhere (mid-frame,
    // in a quiet stretch); both observed at the same points.
    let mut at = t;
    let mut stride = 1;
    while at < t + RUN + 500 {
        let next = at + stride;
        while slow.io.as_ref().expect("io").cycle() < next {
            let c = slow.io.as_ref().expect("io").cycle();
            slow.io_advance(c + 1);
        }
        fast.io_advance(next);
        assert_eq!(snapshot(&mut fast), snapshot(&mut slow), "at cycle {next}");
        at = next;
        stride = stride * 7 % 127 + 1;
    }
    // A second burst after the quiet stretch: restart both channels.
    for sys in [&mut fast, &mut slow] {
        let mut cpu = Cpu { sys, t: at };
        let ch = |n: u32, off: u32| DMA_BASE + n * dreg::CH_STRIDE + off;
        cpu.store(ch(0, dreg::AL2_WRITE_ADDR_TRIG), RESULTS);
        cpu.store(ch(1, dreg::AL3_READ_ADDR_TRIG), COMMANDS);
    }
    let end = at + 4 + RUN;
    while slow.io.as_ref().expect("io").cycle() < end {
        let c = slow.io.as_ref().expect("io").cycle();
        slow.io_advance(c + 1);
    }
    fast.io_advance(end);
    let (frames, ..) = snapshot(&mut fast);
    assert_eq!(frames.len(), 2 * FRAMES as usize);
    assert_eq!(snapshot(&mut fast), snapshot(&mut slow));
}

/// Brings `sys`, a machine ticked every cycle, to `cycle` one cycle at a time.
fn tick_to(sys: &mut System, cycle: u64) {
    while sys.io.as_ref().expect("io").cycle() < cycle {
        let c = sys.io.as_ref().expect("io").cycle();
        sys.io_advance(c + 1);
    }
}

#[test]
fn state_machines_left_behind_by_the_cores_bank_accesses_change_nothing() {
    // A core's access to a bank the DMA may reach runs the machine to its cycle without
    // settling it: the ADC's state machine may stay behind at a bit loop's head, its frame
    // half clocked, until an advance reaches the loop's end (`Io::advance`). Core 0 reads
    // the results' bank every few cycles; the same reads, waits and states as ticking the
    // machine every cycle, observed where `io_advance` settles it.
    // Also with a loop that reads at its head (the level of two cycles before it).
    let mut reading = PROGRAM;
    reading[2..5].copy_from_slice(&[0x4001, PROGRAM[2], 0x0042]);
    for program in [PROGRAM, reading] {
        left_behind_changes_nothing(&program);
    }
}

fn left_behind_changes_nothing(program: &[u16; 8]) {
    let (mut fast, t) = set_up_with(program, priority::DMA_R | priority::DMA_W, false);
    let (mut slow, _) = set_up_with(program, priority::DMA_R | priority::DMA_W, true);
    let (mut at, mut stride, mut gap) = (t, 1u64, 1u64);
    let mut reads = 0;
    while at < t + RUN + 500 {
        let next = at + stride;
        let mut c = at;
        while c < next {
            tick_to(&mut slow, c);
            let a = fast.read(0, c, RESULTS + 0x800, 4).expect("read");
            let b = slow.read(0, c, RESULTS + 0x800, 4).expect("read");
            assert_eq!(a, b, "read at cycle {c}");
            reads += 1;
            gap = gap * 5 % 13 + 1;
            c += gap + u64::from(a.1);
        }
        let next = next.max(c);
        tick_to(&mut slow, next);
        fast.io_advance(next);
        assert_eq!(snapshot(&mut fast), snapshot(&mut slow), "at cycle {next}");
        at = next;
        stride = stride * 7 % 127 + 1;
    }
    assert!(reads > 200, "{reads} reads");
    let (frames, ..) = snapshot(&mut fast);
    assert_eq!(frames.len(), FRAMES as usize);
}

/// The cycle in which the DMA writes results word `i` (its new value visible from the
/// next), found by running a copy cycle by cycle.
fn dma_write_cycle(sys: &System, t: u64, i: u32) -> u64 {
    let mut probe = sys.clone();
    let mut c = t;
    loop {
        probe.io_advance(c + 1);
        if peek(&mut probe, RESULTS + 4 * i) != 0 {
            return c;
        }
        c += 1;
        assert!(c < t + RUN, "word {i} never written");
    }
}

#[test]
fn the_dma_and_a_core_meet_on_a_bank_as_bus_priority_says() {
    // DMA high: a core reading the word in the DMA's cycle waits one cycle and sees it.
    let (sys, t) = set_up(priority::DMA_R | priority::DMA_W, false);
    let w = dma_write_cycle(&sys, t, 3);
    let mut a = sys.clone();
    let (v, wait) = a.read(0, w - 1, RESULTS + 12, 4).expect("read");
    assert_eq!((v, wait), (0, 0), "a cycle early: the old word, no wait");
    let mut b = sys.clone();
    let (v, wait) = b.read(0, w, RESULTS + 12, 4).expect("read");
    assert_eq!(
        (v & 0xffff, wait),
        (0x3abc, 1),
        "in the DMA's cycle: waits, sees it"
    );
    // Another bank in the same cycle: no wait.
    let mut c = sys.clone();
    let (_, wait) = c.read(0, w, 0x2101_0000, 4).expect("read");
    assert_eq!(wait, 0);
    // Equal priorities: the core wins its cycle (the old word, no wait); the DMA's write
    // waits, and the word is there a cycle later.
    let (sys, t) = set_up(0, false);
    assert_eq!(
        dma_write_cycle(&sys, t, 3),
        w,
        "the same frames without contention"
    );
    let mut d = sys.clone();
    let (v, wait) = d.read(0, w, RESULTS + 12, 4).expect("read");
    assert_eq!((v, wait), (0, 0));
    let (v, wait) = d.read(0, w + 1, RESULTS + 12, 4).expect("read");
    assert_eq!((v & 0xffff, wait), (0x3abc, 0));
}

#[test]
fn blocks_in_reset_refuse_access_and_come_back_at_reset_values() {
    let (mut sys, t) = set_up(priority::DMA_R | priority::DMA_W, false);
    const RESETS: u32 = 0x4000_c000;
    // Hold PIO0 in reset (RESETS' SET alias): its registers fault, its state is gone.
    sys.write(0, t, RESETS + 0x2000, 4, 1 << 10).expect("reset");
    assert!(sys.read(0, t + 2, PIO0_BASE + reg::CTRL, 4).is_err());
    sys.write(0, t + 4, RESETS + 0x3000, 4, 1 << 10)
        .expect("release");
    let (ctrl, _) = sys.read(0, t + 6, PIO0_BASE + reg::CTRL, 4).expect("read");
    assert_eq!(ctrl, 0, "state machines disabled again");
    let (clkdiv, _) = sys
        .read(0, t + 8, PIO0_BASE + reg::SM0_CLKDIV, 4)
        .expect("read");
    assert_eq!(clkdiv, 1 << 16);
}
