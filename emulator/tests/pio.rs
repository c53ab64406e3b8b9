//! The PIO model (`tactus_emulator::pio`) against the RP2040 datasheet's chapter 3: an SPI
//! mode-0 master (pico-examples' `spi_cpha0`, the program the converter drivers will use)
//! exchanging bytes with a device model at the datasheet's rate of four state-machine cycles
//! a bit, with SCK held low while it waits for data; the clock divider's fractional rate; a
//! `jmp x--` loop's count and timing; autopush stalling on a full RX FIFO; non-blocking
//! PULL; FIFO joining and levels; the input synchroniser's two cycles.

use tactus_emulator::pio::Pio;
use tactus_rp2040::pio::reg;

/// pioasm's encodings (pico-examples `spi.pio`, `.side_set 1`):
/// `out pins, 1 side 0 [1]` and `in pins, 1 side 1 [1]`.
const SPI_CPHA0: [u16; 2] = [0x6101, 0x5101];

const SCK: u32 = 2;
const MOSI: u32 = 3;
const MISO: u32 = 4;

/// Loads `program` at 0 into `pio` and configures state machine 0 from the fields given.
fn load(pio: &mut Pio, program: &[u16]) {
    for (i, &w) in program.iter().enumerate() {
        pio.write(reg::INSTR_MEM0 + 4 * i as u32, u32::from(w));
    }
}

/// An SPI mode-0 device: samples MOSI on SCK's rising edge and presents the next bit of
/// `tx` (MSB first) on MISO after each falling edge, the first before the first rising edge.
struct Device {
    tx: u8,
    rx: u8,
    bits: u32,
    last_sck: bool,
    miso: bool,
    rising_edges: Vec<u64>,
}

impl Device {
    fn new(tx: u8) -> Self {
        Device {
            tx,
            rx: 0,
            bits: 0,
            last_sck: false,
            miso: tx & 0x80 != 0,
            rising_edges: Vec::new(),
        }
    }

    /// What the device drives this cycle.
    fn gpio_in(&self) -> u32 {
        u32::from(self.miso) << MISO
    }

    /// Sees the pins after cycle `t`.
    fn observe(&mut self, t: u64, pins: u32) {
        let sck = pins & (1 << SCK) != 0;
        let mosi = pins & (1 << MOSI) != 0;
        if sck && !self.last_sck {
            self.rx = self.rx << 1 | u8::from(mosi);
            self.bits += 1;
            self.rising_edges.push(t);
        }
        if !sck && self.last_sck && self.bits < 8 {
            self.miso = (self.tx >> (7 - self.bits)) & 1 != 0;
        }
        self.last_sck = sck;
    }
}

/// State machine 0 as an SPI master: SCK the side-set pin, MOSI the OUT pin, MISO the IN
/// pin, 8-bit frames MSB first with autopull and autopush, clock divider `div`.
fn spi_master(div: u32) -> Pio {
    let mut pio = Pio::new();
    load(&mut pio, &SPI_CPHA0);
    let sm = 0;
    let base = reg::SM0_CLKDIV + sm * reg::SM_STRIDE;
    pio.write(base, div << 16);
    // EXECCTRL: WRAP_TOP 1, WRAP_BOTTOM 0.
    pio.write(base + 4, 1 << 12);
    // SHIFTCTRL: autopush, autopull, both shifts left, thresholds 8.
    pio.write(base + 8, 1 << 16 | 1 << 17 | 8 << 20 | 8 << 25);
    // PINCTRL: one side-set pin at SCK, one OUT pin at MOSI, IN from MISO.
    pio.write(
        base + 0x14,
        1 << 29 | SCK << 10 | 1 << 20 | MOSI | MISO << 15,
    );
    pio.write(reg::CTRL, 1);
    pio
}

/// Runs `pio` with `device` for `cycles` cycles from cycle `t0`.
fn run(pio: &mut Pio, device: &mut Device, t0: u64, cycles: u64) {
    for t in t0..t0 + cycles {
        pio.tick(device.gpio_in());
        device.observe(t, pio.pin_values());
    }
}

#[test]
fn spi_cpha0_exchanges_a_byte_at_four_state_machine_cycles_a_bit() {
    for (div, sent, answer) in [(2u32, 0xa5u8, 0x3cu8), (4, 0x81, 0x7e), (2, 0xff, 0x00)] {
        let mut pio = spi_master(div);
        let mut dev = Device::new(answer);
        // No data: the OUT stalls with its side-set asserted, SCK low, for as long as it
        // waits.
        run(&mut pio, &mut dev, 0, 100);
        assert_eq!(pio.pin_values() & (1 << SCK), 0);
        assert!(dev.rising_edges.is_empty());
        assert_eq!(pio.read(reg::SM0_ADDR), 0, "stalled on the OUT");
        // A byte, left-justified (the bus replicates a byte write into all lanes).
        pio.write(reg::TXF0, u32::from(sent) << 24);
        run(&mut pio, &mut dev, 100, 200);
        assert_eq!(dev.bits, 8, "div {div}: {:?}", dev.rising_edges);
        assert_eq!(dev.rx, sent, "div {div}: the device read MOSI");
        assert_eq!(pio.read(reg::FLEVEL) >> 4 & 0xf, 1, "one word pushed");
        assert_eq!(pio.read(reg::RXF0), u32::from(answer), "div {div}: MISO");
        // SCK period: 4 state-machine cycles of `div` system cycles (datasheet 3.6.1's
        // SPI example: "4 cycles per bit").
        let periods: Vec<u64> = dev.rising_edges.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(
            periods.iter().all(|&p| p == 4 * u64::from(div)),
            "{periods:?}"
        );
        // The first rising edge: the autopull's stall cycle, the OUT and its delay cycle,
        // then the IN's side-set (3 state-machine cycles after the one that saw data).
        let first = dev.rising_edges[0] - 100;
        assert!(
            (3 * u64::from(div)..=4 * u64::from(div)).contains(&first),
            "first rising edge {first} cycles after the write"
        );
        // Back to waiting with SCK low.
        assert_eq!(pio.pin_values() & (1 << SCK), 0);
        assert_eq!(pio.read(reg::FSTAT) >> 24 & 1, 1, "TX empty");
    }
}

#[test]
fn back_to_back_bytes_keep_the_clock_running() {
    let mut pio = spi_master(2);
    let mut dev = Device::new(0);
    pio.write(reg::TXF0, 0x1200_0000);
    pio.write(reg::TXF0, 0x3400_0000);
    run(&mut pio, &mut dev, 0, 200);
    // The second word is pulled while the first's last bit shifts (3.5.4.2): no gap.
    assert_eq!(dev.rising_edges.len(), 16);
    let periods: Vec<u64> = dev.rising_edges.windows(2).map(|w| w[1] - w[0]).collect();
    assert!(periods.iter().all(|&p| p == 8), "{periods:?}");
    assert_eq!(pio.read(reg::FLEVEL) >> 4 & 0xf, 2);
}

#[test]
fn the_input_synchroniser_delays_what_a_state_machine_sees_by_two_cycles() {
    // `wait 1 gpio 4` (0x2084), then `set x, 1` (0xe021): X becomes 1 three cycles after
    // the level rises (two synchroniser flops, then the WAIT's cycle that sees it), or one
    // cycle with the synchroniser bypassed.
    for (bypass, expected) in [(false, 3u64), (true, 1)] {
        let mut pio = Pio::new();
        load(&mut pio, &[0x2084, 0xe021, 0x0002]);
        if bypass {
            pio.write(reg::INPUT_SYNC_BYPASS, 1 << 4);
        }
        pio.write(reg::CTRL, 1);
        for _ in 0..10 {
            pio.tick(0);
        }
        assert_eq!(pio.read(reg::SM0_ADDR), 0, "waiting");
        let mut t = 0;
        while pio.read(reg::SM0_ADDR) == 0 {
            pio.tick(1 << 4);
            t += 1;
            assert!(t < 10);
        }
        assert_eq!(t, expected, "bypass {bypass}");
    }
}

#[test]
fn a_fractional_divider_enables_the_machine_at_its_average_rate() {
    // `set pins, 1` / `set pins, 0` on the wrap: one pin edge per enabled cycle.
    for (int, frac, cycles) in [
        (1u32, 0u32, 1000u64),
        (2, 128, 1000),
        (3, 64, 1300),
        (0, 0, 200_000),
    ] {
        let mut pio = Pio::new();
        load(&mut pio, &[0xe001, 0xe000]);
        pio.write(reg::SM0_CLKDIV, int << 16 | frac << 8);
        pio.write(reg::SM0_EXECCTRL, 1 << 12);
        pio.write(reg::SM0_PINCTRL, 1 << 26); // one SET pin at GPIO 0
        pio.write(reg::CTRL, 1);
        let mut edges = 0u64;
        let mut last = 0;
        for _ in 0..cycles {
            pio.tick(0);
            let now = pio.pin_values() & 1;
            edges += u64::from(now != last);
            last = now;
        }
        let divisor = if int == 0 {
            65_536.0
        } else {
            int as f64 + frac as f64 / 256.0
        };
        let expected = cycles as f64 / divisor;
        assert!(
            (edges as f64 - expected).abs() <= 1.0,
            "INT {int} FRAC {frac}: {edges} enabled cycles in {cycles}, expected {expected:.2}"
        );
    }
}

#[test]
fn jmp_x_decrement_loops_x_plus_one_times() {
    // set x, 5; loop: jmp x-- loop; irq set 0; jmp 3 (halt)
    let mut pio = Pio::new();
    load(&mut pio, &[0xe025, 0x0041, 0xc000, 0x0003]);
    pio.write(reg::CTRL, 1);
    let mut t = 0;
    while pio.read(reg::IRQ) & 1 == 0 {
        pio.tick(0);
        t += 1;
        assert!(t < 100);
    }
    // SET, six JMPs (X = 5 … 0), the IRQ.
    assert_eq!(t, 1 + 6 + 1);
    // X wrapped to all ones on the last, untaken, decrement: `mov isr, x; push` shows it.
    // (An SMx_INSTR write runs on the machine's next cycle.)
    pio.write(reg::SM0_INSTR, 0xa0c1); // mov isr, x
    pio.tick(0);
    pio.write(reg::SM0_INSTR, 0x8020); // push block
    pio.tick(0);
    assert_eq!(pio.read(reg::RXF0), u32::MAX);
    // IRQ is write-one-to-clear.
    pio.write(reg::IRQ, 1);
    assert_eq!(pio.read(reg::IRQ), 0);
}

#[test]
fn autopush_stalls_on_a_full_rx_fifo_and_loses_nothing() {
    // in x, 32 forever with autopush at 32: one word a cycle until the FIFO holds 4.
    let mut pio = Pio::new();
    load(&mut pio, &[0x4020]); // in x, 32
    pio.write(reg::SM0_EXECCTRL, 0); // wrap at 0
    pio.write(reg::SM0_SHIFTCTRL, 1 << 16);
    pio.write(reg::SM0_INSTR, 0xe02a); // set x, 10 (executed at once: disabled)
    pio.write(reg::CTRL, 1);
    for _ in 0..20 {
        pio.tick(0);
    }
    assert_eq!(pio.read(reg::FLEVEL) >> 4 & 0xf, 4);
    assert_eq!(pio.read(reg::FSTAT) & 1, 1, "RX full");
    assert!(pio.rx_dreq(0));
    for _ in 0..4 {
        assert_eq!(pio.read(reg::RXF0), 10);
    }
    assert!(!pio.rx_dreq(0));
    // The stalled IN goes on as soon as there is room.
    pio.tick(0);
    assert_eq!(pio.read(reg::FLEVEL) >> 4 & 0xf, 1);
}

#[test]
fn pull_noblock_on_an_empty_fifo_copies_x() {
    let mut pio = Pio::new();
    pio.write(reg::SM0_INSTR, 0xe03f); // set x, 31
    pio.write(reg::SM0_INSTR, 0x8080); // pull noblock
    pio.write(reg::SM0_INSTR, 0xa0c7); // mov isr, osr
    pio.write(reg::SM0_INSTR, 0x8020); // push block
    assert_eq!(pio.read(reg::RXF0), 31);
}

#[test]
fn joined_fifos_hold_eight_words_and_levels_read_back() {
    let mut pio = Pio::new();
    assert!(pio.tx_dreq(0));
    for i in 0..6 {
        pio.write(reg::TXF0, i);
    }
    // Four words fit; the rest are dropped.
    assert_eq!(pio.read(reg::FLEVEL) & 0xf, 4);
    assert!(!pio.tx_dreq(0));
    assert_eq!(pio.read(reg::FSTAT) >> 16 & 1, 1, "TX full");
    // Joining discards the FIFOs (datasheet 3.5.3) and doubles TX.
    pio.write(reg::SM0_SHIFTCTRL, 1 << 30);
    assert_eq!(pio.read(reg::FLEVEL) & 0xf, 0);
    for i in 0..9 {
        pio.write(reg::TXF0, i);
    }
    assert_eq!(pio.read(reg::FLEVEL) & 0xf, 8);
    // No RX FIFO: it reads both full and empty.
    assert_eq!(pio.read(reg::FSTAT) & 0x101, 0x101);
    // Other state machines are untouched.
    assert_eq!(pio.read(reg::FLEVEL) >> 8, 0);
}

#[test]
fn random_programs_and_register_writes_never_panic() {
    // Any instruction word and any register value is legal input to the block: a firmware
    // under test may write garbage, and the model must answer as hardware would, not stop.
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    for _ in 0..200 {
        let mut pio = Pio::new();
        for i in 0..32 {
            pio.write(reg::INSTR_MEM0 + 4 * i, next() as u32);
        }
        for _ in 0..64 {
            let offset = (next() % 0x140) as u32 & !3;
            pio.write(offset, next() as u32);
        }
        pio.write(reg::CTRL, 0xf);
        for t in 0..2_000u32 {
            pio.tick(next() as u32);
            if t % 97 == 0 {
                let offset = (next() % 0x140) as u32;
                let _ = pio.read(offset);
                pio.write(offset & !3, next() as u32);
            }
        }
        let _ = (
            pio.pin_values(),
            pio.pin_dirs(),
            pio.tx_dreq(3),
            pio.rx_dreq(7),
        );
    }
}

/// What a caller running by events does (`tactus_emulator::io`): skip a quiet block, or the
/// cycles in which only FIFO-stalled machines would run, in one step; the same pins, FIFOs,
/// PCs and device as ticking every cycle, on the autopulling and autopushing SPI master
/// with bytes written and words read at random cycles (some while it runs, some after it
/// stalled) and its RX FIFO left to fill.
#[test]
fn skipping_by_events_equals_ticking_every_cycle() {
    let mut rng = tactus_runtime::rng::XorShift64::new(0x0dd_ba11);
    for div in [1u32, 2, 3] {
        let (mut a, mut b) = (spi_master(div), spi_master(div));
        let (mut da, mut db) = (Device::new(0x5a), Device::new(0x5a));
        let mut t = 0u64;
        for step in 0..60 {
            // A stretch of up to 120 cycles, then perhaps a write or a read.
            let end = t + 1 + rng.below(120) as u64;
            for c in t..end {
                a.tick(da.gpio_in());
                da.observe(c, a.pin_values());
            }
            let mut c = t;
            while c < end {
                let idle = if b.quiet() { u64::MAX } else { b.idle_cycles() };
                if idle > 0 {
                    let n = idle.min(end - c);
                    b.skip(n, db.gpio_in());
                    c += n;
                    continue;
                }
                b.tick(db.gpio_in());
                db.observe(c, b.pin_values());
                c += 1;
            }
            t = end;
            for p in [reg::FLEVEL, reg::FSTAT, reg::SM0_ADDR, reg::SM0_INSTR] {
                assert_eq!(
                    a.read(p),
                    b.read(p),
                    "div {div} step {step} register {p:#x}"
                );
            }
            assert_eq!(
                (a.pin_values(), a.pin_dirs()),
                (b.pin_values(), b.pin_dirs())
            );
            assert_eq!((da.rx, da.bits), (db.rx, db.bits));
            assert_eq!(da.rising_edges, db.rising_edges, "div {div} step {step}");
            match rng.below(4) {
                0 | 1 => {
                    let w = (rng.next_u64() as u32) << 24;
                    a.write(reg::TXF0, w);
                    b.write(reg::TXF0, w);
                    da.bits = 0;
                    db.bits = 0;
                }
                2 => assert_eq!(a.read(reg::RXF0), b.read(reg::RXF0)),
                _ => {}
            }
        }
        assert!(da.rising_edges.len() > 40, "div {div}: the master ran");
    }
}

/// A bit loop run in one step (`Pio::sm_loop`, `sm_loop_run`, the run-ahead's bulk path in
/// `tactus_emulator::io`) against its instructions ticked one cycle at a time, on loops of
/// the converter drivers' kinds and odder ones (two-bit OUTs, `SET PINS`, `NOP`, `IN NULL`,
/// `OUT NULL`, optional side-set, a one-instruction loop), both shift directions, dividers
/// 1–3, X set to 9 or taken from the OSR (`OUT X, 6`: 45 times round shifting left, 33
/// right — past the 32 bits the OSR and ISR hold, and from an OSR already shifted): for
/// every number of times round the whole block's state is the same, and so are the pin
/// levels `sm_loop_pin` gives at each step of each time round.
#[test]
fn a_bit_loop_in_one_step_equals_its_instructions() {
    const IN_PIN: u32 = 4;
    // pull block; set x, 9; the loop from 2; jmp 31 (halt at the end of memory).
    let loops: [(&[u16], u32); 3] = [
        // .side_set 1 (SCLK on pin 2): out pins, 1 side 1 [1]; in pins, 1 side 0;
        // jmp x--, 2 side 0.
        (&[0x6001 | 1 << 12 | 1 << 8, 0x4001, 0x0042], 1),
        // .side_set 1 opt: out pins, 2 side 1 [2]; set pins, 1; nop side 0 [1];
        // in null, 3; out null, 1; in pins, 1; jmp x--, 2.
        (
            &[
                0x6002 | 0b11 << 11 | 2 << 8,
                0xe001,
                0xa042 | 0b10 << 11 | 1 << 8,
                0x4063,
                0x6061,
                0x4001,
                0x0042,
            ],
            2 | 1 << 3,
        ),
        // .side_set 1: jmp x--, 2 side 1 [3].
        (&[0x0042 | 1 << 12 | 3 << 8], 1),
    ];
    let gpio = |c: u64| (((c * 0x9e37_79b9) >> 7) as u32 & 1) << IN_PIN;
    // set x, 9; out x, 6.
    for (body, side, count) in loops
        .iter()
        .flat_map(|&(b, s)| [(b, s, 0xe029), (b, s, 0x6026)])
    {
        for div in 1..=3u32 {
            for shift in [0u32, 3 << 18] {
                let mut pio = Pio::new();
                let mut program = vec![0x80a0, count];
                program.extend_from_slice(body);
                load(&mut pio, &program);
                pio.write(reg::INSTR_MEM0 + 4 * 31, 0x001f);
                let base = reg::SM0_CLKDIV;
                pio.write(base, div << 16);
                // SIDE_EN for the optional side-set; WRAP_TOP 31.
                pio.write(base + 4, u32::from(side & 8 != 0) << 30 | 31 << 12);
                pio.write(base + 8, shift);
                // OUT 3-4, SET 5, side-set 2, IN 4; side-set count as the program has it.
                let side_count = side & 7;
                pio.write(
                    base + 0x14,
                    side_count << 29 | 1 << 26 | 2 << 20 | IN_PIN << 15 | 2 << 10 | 5 << 5 | 3,
                );
                pio.write(reg::TXF0, 0xb5c3_96e1);
                pio.write(reg::CTRL, 1);
                let mut t = 0u64;
                while pio.sm_pc(0) != 2 || pio.sm_fast(0).is_none() {
                    pio.tick(gpio(t));
                    t += 1;
                    assert!(t < 100);
                }
                let lp = pio.sm_loop(0, 2).expect("a bit loop");
                let left = match (count, shift) {
                    (0xe029, _) => 10,
                    // 0xb5c3_96e1's top six bits, or its low six.
                    (_, 0) => 46,
                    _ => 34,
                };
                assert_eq!(pio.sm_loop_left(0), left);
                for k in 1..=left {
                    let what =
                        format!("loop {body:x?} x {count:#x} div {div} shift {shift:#x} k {k}");
                    let mut a = pio.clone();
                    let mut levels = vec![[0u32; 8]; k as usize];
                    for c in t..t + k * lp.period {
                        a.tick(gpio(c));
                        let (i, at) = ((c - t) / lp.period, (c - t) % lp.period);
                        for (j, l) in levels[i as usize].iter_mut().enumerate() {
                            if j < body.len() && lp.at(j) == at {
                                *l = a.pin_values();
                            }
                        }
                    }
                    let mut in_bits = [0u64; tactus_emulator::pio::LOOP_MAX];
                    for j in lp.reads() {
                        for i in 0..k {
                            let c = t + i * lp.period + lp.at(j);
                            in_bits[j] |= u64::from(gpio(c - 2) >> IN_PIN & 1) << i;
                        }
                    }
                    let mut b = pio.clone();
                    b.sm_loop_run(0, &lp, k, &in_bits);
                    b.set_sync(a.sync());
                    assert_eq!(format!("{a:?}"), format!("{b:?}"), "{what}");
                    for j in 0..body.len() {
                        for pin in 2..6 {
                            let Some(bits) = pio.sm_loop_pin(0, &lp, k, j, pin) else {
                                continue;
                            };
                            for (i, l) in levels.iter().enumerate() {
                                assert_eq!(
                                    bits >> i & 1,
                                    u64::from(l[j] >> pin & 1),
                                    "{what} step {j} pin {pin}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }
}
