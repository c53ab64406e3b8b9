//! Windows on a board with converters (`tactus_emulator::board`, `io_window.rs`): the block
//! engine runs the two cores ahead of the I/O over whole windows and the I/O replays their
//! accesses to its DMA's banks and their stores to its registers; the interpreter's
//! lock-step run is the reference. Both cores' SysTick handlers use the DMA as the firmware's
//! drivers do: core 0 reads an ADC's results (DMA from a PIO state machine into its bank 2)
//! and restarts the burst through two trigger aliases; core 1 reads last sample's copy, restarts
//! a memory-to-memory channel on its bank 3 and then writes the words the DMA has just read
//! (so the DMA must see them as they were before the window); a fourth channel, paced by a
//! DMA timer, copies a word of bank 2 every 128 cycles (so some of core 0's accesses meet
//! it: those windows are undone). The first part of each
//! handler (its loads of the DMA's words and a store beside them) is memoized: a hit logs
//! those accesses for the replay as the run it stands for would. In the busy variant core 0's
//! main loop reads and writes bank 2 while the DMA writes it: windows are undone. After
//! every slice both boards agree on everything: cores, stalls, all of SRAM, the whole I/O.

use tactus_emulator::io::IoConfig;
use tactus_emulator::{Board, Config, Engine, IoWindows};
use tactus_rp2040::busctrl::priority;
use tactus_rp2040::dma::{ctrl, reg as dreg, DMA_BASE, TREQ_PERMANENT, TREQ_TIMER0};

/// The banks each core of a two-core firmware image owns (`tactus_firmware`'s
/// `FirmwareImage::own_banks`: core 0 SRAM0, SRAM2 and SRAM4, core 1 SRAM1, SRAM3 and SRAM5).
const OWN_BANKS: [u8; 2] = [0b01_0101, 0b10_1010];

use tactus_runtime::converters::ADS8688;

mod common;
mod io_setup;
use common::Rng;
use io_setup::{COMMANDS, PINS, PROGRAM, RESULTS};

/// Core `core`'s bank through the non-striped alias.
fn bank(core: usize) -> u32 {
    0x2100_0000 + 0x1_0000 * core as u32
}

/// Core 0's own word in bank 2 (besides the DMA's buffers).
const SCRATCH2: u32 = 0x2102_0200;
/// Core 1's copy channel: from `SRC` to `DST`, both in bank 3.
const SRC: u32 = 0x2103_0000;
const DST: u32 = 0x2103_0100;
const COPY: u32 = 2;
/// The channel paced by a DMA timer on bank 2.
const PACED: u32 = 3;

fn ch(n: u32, off: u32) -> u32 {
    DMA_BASE + n * dreg::CH_STRIDE + off
}

/// Thumb code with `ldr rd, =value` literals pooled after it.
#[derive(Default)]
struct Asm {
    code: Vec<u16>,
    lits: Vec<(usize, u32)>,
}

impl Asm {
    fn op(&mut self, ops: &[u16]) -> &mut Self {
        self.code.extend_from_slice(ops);
        self
    }

    fn lit(&mut self, rd: u16, value: u32) -> &mut Self {
        self.lits.push((self.code.len(), value));
        self.code.push(0x4800 | rd << 8);
        self
    }

    /// The bytes at `at` (word-aligned).
    fn bytes(&mut self, at: u32) -> Vec<u8> {
        if self.code.len() % 2 == 1 {
            self.code.push(0xbf00);
        }
        let pool = at + 2 * self.code.len() as u32;
        for (i, &(k, _)) in self.lits.iter().enumerate() {
            let pc = at + 2 * k as u32;
            let lit = pool + 4 * i as u32;
            self.code[k] |= ((lit - ((pc + 4) & !3)) / 4) as u16;
        }
        let mut out: Vec<u8> = self.code.iter().flat_map(|h| h.to_le_bytes()).collect();
        for &(_, v) in &self.lits {
            out.extend(v.to_le_bytes());
        }
        out
    }
}

/// The memoized spans of each core's handler (from its start, bytes): its loads of the
/// DMA's words and its store of their sum beside them.
const SPANS: [u32; 2] = [28, 10];

/// Core 0's handler: sums six results words (into bank 2, then its data), restarts the ADC burst
/// (two trigger-alias stores; with `mark`, after storing a mark into the last results word,
/// which the burst then overwrites, as the firmware's burst check does), counts in bank 2 (a
/// halfword and a word store).
fn handler0(data: u32, mark: bool) -> Asm {
    let mut a = Asm::default();
    a.lit(0, RESULTS)
        .op(&[0x6801, 0x6842, 0x1889, 0x6882, 0x1889, 0x68c2, 0x1889]) // ldr r1,[r0]; ldr r2,[r0,#4]; adds; #8; #12
        .op(&[0x6902, 0x1889, 0x69c2, 0x1889]) // ldr r2,[r0,#16]; adds; ldr r2,[r0,#28]; adds
        .op(&[0x6401, 0x6441]) // str r1,[r0,#0x40]; str r1,[r0,#0x44] (the span's end, SPANS)
        .lit(3, data)
        .op(&[0x681a, 0x1852, 0x601a]) // ldr r2,[r3]; adds r2,r2,r1; str r2,[r3]
        .lit(0, ch(0, dreg::AL2_WRITE_ADDR_TRIG))
        .lit(1, RESULTS);
    if mark {
        a.op(&[0x61c9]); // str r1,[r1,#28]
    }
    a.op(&[0x6001]) // str r1,[r0]
        .lit(0, ch(1, dreg::AL3_READ_ADDR_TRIG))
        .lit(1, COMMANDS)
        .op(&[0x6001])
        .lit(0, SCRATCH2)
        .op(&[0x6801, 0x3101, 0x8041, 0x6001]) // ldr r1,[r0]; adds r1,#1; strh r1,[r0,#2]; str r1,[r0]
        .op(&[0x685a, 0x3201, 0x605a, 0x4770]); // ldr r2,[r3,#4]; adds #1; str; bx lr
    a
}

/// Core 1's handler: sums last sample's copy (into bank 3, then its data), restarts the copy, waits
/// ~80 cycles (the DMA has read the source by then), then writes new source words (in
/// `few` values: bit 1 of their count, so that one sample's words do not tell the last's).
fn handler1(data: u32, few: bool, chain: Option<u32>) -> Asm {
    let mut a = Asm::default();
    a.lit(0, DST)
        .op(&[0x6801, 0x69c2, 0x1889, 0x6401]) // ldr r1,[r0]; ldr r2,[r0,#28]; adds r1,r1,r2; str r1,[r0,#0x40]
        .lit(3, data)
        .op(&[0x681a, 0x1852, 0x601a])
        .lit(0, ch(COPY, dreg::WRITE_ADDR))
        .lit(1, DST)
        .op(&[0x6001]);
    if let Some(to) = chain {
        // The chained channel's addresses back to DST → `to`.
        a.lit(0, ch(CHAINED, dreg::READ_ADDR))
            .op(&[0x6001])
            .lit(0, ch(CHAINED, dreg::WRITE_ADDR))
            .lit(1, to)
            .op(&[0x6001]);
    }
    a.lit(0, ch(COPY, dreg::AL3_READ_ADDR_TRIG))
        .lit(1, SRC)
        .op(&[0x6001])
        .op(&[0x2214, 0x3a01, 0xd1fd]) // movs r2,#20; subs r2,#1; bne .-2
        .lit(0, SRC)
        .op(&[0x685a, 0x3201, 0x605a]); // ldr r2,[r3,#4]; adds #1; str
    if few {
        a.op(&[0x0852, 0x2101, 0x400a]); // lsrs r2,r2,#1; movs r1,#1; ands r2,r1
    }
    a.op(&[0x6002, 0x61c2, 0x3203, 0x60c2, 0x4770]); // str r2,[r0]; str r2,[r0,#28]; adds #3; str r2,[r0,#12]; bx lr
    a
}

/// What the boards of a comparison run: core 0's main loop on bank 2 under the DMA
/// (`busy`); or the period memo's case (`periodic`): both SysTicks at `period` cycles, no
/// paced channel, core 1's source words in a few values, core 0's main loop counting in
/// a register (3 cycles a time round: with a period not a multiple of 3 the tick lands on
/// each of its instructions in turn, so its handler's entry and accesses move by a cycle).
/// The default: neither, nothing else.
#[derive(Clone, Copy, Default)]
struct Shape {
    busy: bool,
    periodic: bool,
    period: u64,
    /// The host rewrites the ADC's command words now and then (each slice one of two
    /// channel orders): data the ADC decodes, which the period memo must key.
    commands: bool,
    /// Core 1's copy channel chains to a second ([`CHAINED`]) that copies the words the
    /// first has just written to this address (DMA reads of the DMA's writes in one
    /// window): past them, or back to the source (whose words core 1 stores later, after
    /// the DMA wrote them).
    chain: Option<u32>,
    /// Core 0's main loop (periodic) loads its word of bank 2 every 64 cycles: now and
    /// then in a cycle in which the DMA claims the bank (the window is undone). And the
    /// parts keep no records (as in `tactus play` without an I/O trace: the period memo's
    /// hits leave their ends behind, and its plans serve).
    poll: bool,
    /// Core 0's handler marks the last results word before it restarts the burst, which
    /// overwrites the mark later in the window ([`handler0`]).
    mark: bool,
}

/// The channel [`Shape::chain`] chains the copy to.
const CHAINED: u32 = 4;

impl Shape {
    /// The period memo's case at `period` cycles, nothing else.
    fn periodic(period: u64) -> Shape {
        Shape {
            periodic: true,
            period,
            ..Shape::default()
        }
    }
}

/// A board on `engine` with the ADC, its DMA channels and the copy channel set up and
/// the DMA winning the banks, both cores in their handlers' idle loops (core 0 in `busy`'s
/// bank-2 loop instead).
fn board(
    engine: Engine,
    Shape {
        busy,
        periodic,
        period,
        chain,
        poll,
        mark,
        ..
    }: Shape,
) -> Board {
    let mut b = Board::new(Config {
        engine,
        own_banks: OWN_BANKS,
        ..Config::default()
    });
    b.set_compile_threshold(0);
    b.attach_io(&IoConfig {
        adcs: vec![(&ADS8688, PINS)],
        dacs: vec![],
    });
    let io = b.io_mut().expect("io");
    for c in 0..8 {
        io.adcs[0].set_code(c, 0x1000 * c as u16 + 0x0abc);
    }
    let t = io_setup::program_adc(
        &mut b.system,
        &PROGRAM,
        priority::DMA_R | priority::DMA_W,
        10,
    );
    let copy_to = |to: u32| {
        2 << ctrl::DATA_SIZE_SHIFT
            | ctrl::EN
            | ctrl::INCR_READ
            | ctrl::INCR_WRITE
            | to << ctrl::CHAIN_TO_SHIFT
            | TREQ_PERMANENT << ctrl::TREQ_SEL_SHIFT
    };
    let copy = copy_to(if chain.is_some() { CHAINED } else { COPY });
    let mut cpu = io_setup::Cpu {
        sys: &mut b.system,
        t,
    };
    cpu.store(ch(COPY, dreg::READ_ADDR), SRC);
    cpu.store(ch(COPY, dreg::WRITE_ADDR), DST);
    cpu.store(ch(COPY, dreg::TRANS_COUNT), 8);
    cpu.store(ch(COPY, dreg::AL1_CTRL), copy);
    if let Some(to) = chain {
        cpu.store(ch(CHAINED, dreg::READ_ADDR), DST);
        cpu.store(ch(CHAINED, dreg::WRITE_ADDR), to);
        cpu.store(ch(CHAINED, dreg::TRANS_COUNT), 8);
        cpu.store(ch(CHAINED, dreg::AL1_CTRL), copy_to(CHAINED));
    }
    // Channel 3 copies a word of bank 2 to the next one every 128 cycles (its pacing timer):
    // now and then in a cycle in which core 0 reads or writes the bank, memoized or not.
    let paced = 2 << ctrl::DATA_SIZE_SHIFT
        | ctrl::EN
        | PACED << ctrl::CHAIN_TO_SHIFT
        | TREQ_TIMER0 << ctrl::TREQ_SEL_SHIFT;
    if !periodic {
        cpu.store(DMA_BASE + dreg::TIMER0, 1 << 16 | 128);
        cpu.store(ch(PACED, dreg::READ_ADDR), SCRATCH2 + 0x100);
        cpu.store(ch(PACED, dreg::WRITE_ADDR), SCRATCH2 + 0x104);
        cpu.store(ch(PACED, dreg::TRANS_COUNT), 1 << 20);
        cpu.store(ch(PACED, dreg::CTRL_TRIG), paced);
    }
    let mut spans = Vec::new();
    for (core, span) in SPANS.into_iter().enumerate() {
        let base = bank(core);
        let handler = base + 0x100 + 0x400 * core as u32;
        let main = handler + 0x200;
        let data = base + 0x8000;
        let code = if core == 0 {
            handler0(data, mark).bytes(handler)
        } else {
            handler1(data, periodic, chain).bytes(handler)
        };
        b.write_bytes(handler, &code).unwrap();
        let idle: &[u16] = if busy && core == 0 {
            &[0x69f1, 0x6039, 0x3101, 0xe7fb] // ldr r1,[r6,#28]; str r1,[r7]; adds r1,#1; b .-6
        } else if poll && core == 0 {
            &[0x683a, 0x2314, 0x3b01, 0xd1fd, 0xe7fa] // ldr r2,[r7]; movs r3,#20; subs r3,#1; bne .-2; b .-8
        } else if periodic && core == 0 {
            &[0x3101, 0xe7fd] // adds r1,#1; b .-2
        } else {
            &[0xbf30, 0xe7fd] // wfi; b .-2
        };
        let idle: Vec<u8> = idle.iter().flat_map(|h| h.to_le_bytes()).collect();
        b.write_bytes(main, &idle).unwrap();
        b.write_u32(base + 4 * 15, handler | 1).unwrap();
        spans.push((handler, handler + span));
        b.start_core(core, main | 1, 0x2004_1000 + 0x1000 * core as u32, base);
        let c = &mut b.cores[core];
        c.r[6] = RESULTS;
        c.r[7] = SCRATCH2 + 16;
        c.nvic.syst_rvr = match periodic {
            true => period as u32 - 1,
            false => 3500 + 37 * core as u32,
        };
        c.nvic.syst_csr = 7;
        c.nvic.syst_next = 900 + core as u64 * if periodic { 1500 } else { 1 };
    }
    b.memoize(&[], &spans);
    b
}

/// Everything the two runs must agree on.
fn state(b: &mut Board) -> String {
    let mut s = common::cores_state(b);
    let hash = b
        .system
        .sram
        .iter()
        .fold(0xcbf2_9ce4_8422_2325u64, |h, &x| {
            (h ^ x as u64).wrapping_mul(0x100_0000_01b3)
        });
    s += &format!("sram {hash:016x}\n");
    s += &format!("{:?}", b.io().expect("io"));
    s
}

/// Runs both engines in random slices for `cycles`; returns the block board. In the
/// periodic shape the slices end at SysTick periods (the windows are periods) and the ADC
/// reads one of three code sets each slice. A second block board whose period memo takes
/// no plans (`io_window.rs`, "Plans") runs beside them: the same after every slice.
fn compare(shape: Shape, cycles: u64) -> Board {
    let mut block = board(Engine::Block, shape);
    let mut unplanned = board(Engine::Block, shape);
    unplanned.set_io_plans(false);
    let mut interp = board(Engine::Interp, shape);
    if shape.poll {
        for b in [&mut block, &mut unplanned, &mut interp] {
            b.io_mut().expect("io").keep_records(false);
        }
    }
    let mut rng = Rng(0x10_40d + shape.busy as u64 + 2 * shape.periodic as u64);
    let mut slice = 0u16;
    while block.cycle() < cycles {
        let limit = match shape.periodic {
            true => (block.cycle() / shape.period + 1 + rng.below(3) as u64) * shape.period + 900,
            false => block.cycle() + 1 + rng.below(9000) as u64,
        };
        // What the ADC reads changes every few slices, as the host's key positions do
        // (and rests in between: the spans' memos hit).
        slice += 1;
        let set = match shape.periodic {
            true => rng.below(3),
            false => slice / 6,
        };
        let order = match shape.commands {
            true => rng.below(2) as u32,
            false => 0,
        };
        for b in [&mut block, &mut unplanned, &mut interp] {
            let io = b.io_mut().expect("io");
            for c in 0..8 {
                io.adcs[0].set_code(c, set.wrapping_mul(97) ^ (c as u16) << 12);
            }
            if shape.commands {
                // Frame i selects channel i + 1 or i + 2 for the next (MAN_Ch_n).
                for i in 0..io_setup::FRAMES {
                    let command = 0xc000 | ((i + 1 + order) % 8) << 10;
                    b.write_u32(COMMANDS + 4 * i, command << 16).expect("SRAM");
                }
            }
        }
        let r = block.run_until(limit);
        assert_eq!(r, interp.run_until(limit));
        assert_eq!(r, unplanned.run_until(limit));
        let s = state(&mut block);
        assert_eq!(s, state(&mut interp), "at {limit}");
        assert_eq!(s, state(&mut unplanned), "at {limit}");
    }
    let (p, u) = (block.io_windows(), unplanned.io_windows());
    assert_eq!(u.memo_planned, 0);
    assert_eq!((p.kept, p.waited, p.stale), (u.kept, u.waited, u.stale));
    for core in 0..2 {
        let count = block.read_u32(bank(core) + 0x8004).unwrap();
        assert!(count > 50, "core {core}: {count} handler runs");
    }
    assert_eq!(interp.io_windows().kept, 0);
    block
}

#[test]
fn windows_with_the_dma_equal_the_lock_step() {
    let block = compare(Shape::default(), 600_000);
    let io = block.io_windows();
    let memo = block.memo_stats();
    eprintln!("{:?} {io:?} {memo:?}", block.run_ahead_windows());
    assert!(io.kept > 40, "{io:?}");
    // Memos of the span that reads and writes the DMA's bank apply, logged for the replay.
    assert!(memo.hits > 10, "{memo:?}");
}

#[test]
fn windows_whose_core_meets_the_dma_are_undone() {
    let block = compare(
        Shape {
            busy: true,
            ..Shape::default()
        },
        300_000,
    );
    let io = block.io_windows();
    eprintln!("{:?} {io:?}", block.run_ahead_windows());
    assert!(io.waited + io.stale > 10, "{io:?}");
}

#[test]
fn the_period_memo_of_the_io_equals_the_lock_step() {
    // Windows that are SysTick periods, the ADC's codes and the words core 1 leaves for
    // its copy channel each one of a few: the I/O's replays repeat with other data, which
    // the period memo gives by its routes (a recording stands for every replay from the
    // same control state), so a handful of recordings serve every window kept. At 3000
    // cycles core 1's windows are kept and hit; at 3001 core 0's handler starts at three
    // different latencies (they do). Every slice ends compared with the lock-step run.
    for period in [3000, 3001] {
        let block = compare(Shape::periodic(period), 1_200_000);
        let io = block.io_windows();
        eprintln!("{period}: {:?} {io:?}", block.run_ahead_windows());
        assert!(io.memo_hits > 120, "{period}: {io:?}");
        // Some by a plan: core 1's handler stores the words its copy channel read at the
        // tick (the DMA's reads take the words as they were before the stores).
        assert!(io.memo_planned > 20, "{period}: {io:?}");
        // Recorded here, or by another board (the process's store).
        let taken = io.memo_recorded + io.memo_shared;
        assert!((1..20).contains(&taken), "{period}: {io:?}");
    }
}

#[test]
fn planned_hits_equal_the_lock_step() {
    // A hit of the period memo takes a plan where one serves (`io_window.rs`, "Plans"):
    // the DMA's reads from the SRAM the cores' run left, from the words their stores
    // overwrote, or from the DMA's own writes of the window; loads checked against those
    // writes. Here core 1's copy chains to a second channel that copies the words the
    // first has just written (DMA reads of the DMA's writes) past them, or back to the
    // source, which the handler then stores in part (words both the DMA and a core write:
    // no plan serves); against a board without plans and the lock-step run (`compare`).
    for (period, to, planned) in [
        (3000, DST + 0x20, true),
        (3001, DST + 0x20, true),
        (3000, SRC, false),
    ] {
        let block = compare(
            Shape {
                chain: Some(to),
                ..Shape::periodic(period)
            },
            1_200_000,
        );
        let io = block.io_windows();
        eprintln!("{period} {to:x}: {io:?}");
        assert!(io.memo_hits > 120, "{period}: {io:?}");
        assert_eq!(io.memo_planned > 20, planned, "{period} {to:x}: {io:?}");
    }
}

#[test]
fn a_core_store_the_dma_overwrites_is_planned() {
    // Core 0's handler stores a mark into the last results word, then restarts the burst,
    // whose last transfer overwrites it later in the window (the firmware's burst check,
    // `tactus_firmware::image::io::IoPlan::burst_mark`): a word both a core and the DMA
    // write, the core first, which a plan serves (the DMA's writes over the SRAM the cores'
    // run left); equal to a board without plans and the lock-step run (`compare`). The
    // other order, a core's store after the DMA's write, is planned_hits_equal_the_lock_step's
    // last case (no plan serves).
    for period in [3000, 3001] {
        let block = compare(
            Shape {
                mark: true,
                ..Shape::periodic(period)
            },
            1_200_000,
        );
        let io = block.io_windows();
        eprintln!("{period}: {io:?}");
        assert!(io.memo_hits > 120, "{period}: {io:?}");
        assert!(io.memo_planned > 20, "{period}: {io:?}");
    }
}

#[test]
fn a_hit_meets_the_dmas_claims_with_or_without_a_plan() {
    // Core 0's main loop loads a word of the DMA's bank every 64 cycles: a window in which
    // one of those loads falls in a cycle the DMA claims the bank is undone (the core
    // would have waited), whether the period memo gives it by a plan or not. With a
    // period of 3,001 cycles the loads move by 7 cycles a window against the DMA's, and
    // through every phase of 64 within 64 windows (the windows' shapes then change, and
    // plans with their stretches of cycles, `Fit`, are made and left more often).
    for period in [3000, 3001] {
        let block = compare(
            Shape {
                poll: true,
                ..Shape::periodic(period)
            },
            1_200_000,
        );
        let io = block.io_windows();
        eprintln!("{period}: {io:?}");
        assert!(io.waited > 10, "{period}: {io:?}");
        assert!(io.memo_planned > 20, "{period}: {io:?}");
    }
}

#[test]
fn data_set_between_hits_is_the_lock_steps() {
    // Periodic windows whose ADC codes change through `Board::set_adc_code` (data only: the
    // period memo still knows where the I/O is) and stay for a few slices, against a board
    // whose hits make every end and the lock-step run, compared every fourth slice:
    // - period 3001, core 0 looping (its handler's entry moves by a cycle): a hit links
    //   the entry to the last one only where the window is known to start at its end;
    // - period 3000, both cores asleep between ticks and no records kept: each hit leaves
    //   its end behind ("The lazy end"), and the codes set go among its data words.
    for (period, asleep) in [(3001, false), (3000, true)] {
        let shape = Shape::periodic(period);
        let mut lazy = board(Engine::Block, shape);
        let mut made = board(Engine::Block, shape);
        made.set_io_lazy(false);
        let mut interp = board(Engine::Interp, shape);
        for b in [&mut lazy, &mut made, &mut interp] {
            if asleep {
                // wfi; b .-2 where core 0 looped.
                b.write_bytes(bank(0) + 0x300, &[0x30, 0xbf, 0xfd, 0xe7])
                    .unwrap();
                b.io_mut().expect("io").keep_records(false);
            }
        }
        let mut rng = Rng(0x1a2e + period);
        let mut set = 0u16;
        for slice in 0..120 {
            let limit = (lazy.cycle() / period + 1 + rng.below(4) as u64) * period + 900;
            if slice % 3 == 0 {
                set = rng.below(3);
            }
            for b in [&mut lazy, &mut made, &mut interp] {
                for c in 0..8 {
                    b.set_adc_code(0, c, set.wrapping_mul(97) ^ (c as u16) << 12);
                }
            }
            let r = lazy.run_until(limit);
            assert_eq!(r, made.run_until(limit), "{period}");
            assert_eq!(r, interp.run_until(limit), "{period}");
            if slice % 4 == 3 {
                let s = state(&mut lazy);
                assert_eq!(s, state(&mut made), "{period}: at {limit}");
                assert_eq!(s, state(&mut interp), "{period}: at {limit}");
            }
        }
        let (l, m) = (lazy.io_windows(), made.io_windows());
        eprintln!("{period}: {l:?} {m:?}");
        assert!(l.memo_hits > 80, "{period}: {l:?}");
        // The same windows kept, each given or recorded (the boards share recordings).
        let given = |w: &IoWindows| w.memo_hits + w.memo_recorded;
        assert_eq!((l.kept, l.stale, given(&l)), (m.kept, m.stale, given(&m)));
    }
}

#[test]
fn a_recording_without_records_gives_none_to_a_board_that_keeps_them() {
    // The period memo's recordings are the process's: one made where the parts keep no
    // frames (`tactus play` but the board of an I/O trace) has none to give. A board that
    // keeps them after one that did not: its frames, with the rest, the lock-step run's.
    let shape = Shape::periodic(3000);
    let mut none = board(Engine::Block, shape);
    none.io_mut().expect("io").keep_records(false);
    let mut keeps = board(Engine::Block, shape);
    let mut interp = board(Engine::Interp, shape);
    for limit in (1..60).map(|k| k * 3 * shape.period + 900) {
        none.run_until(limit);
    }
    assert!(
        none.io_windows().memo_recorded > 0,
        "{:?}",
        none.io_windows()
    );
    for limit in (1..60).map(|k| k * 3 * shape.period + 900) {
        assert_eq!(keeps.run_until(limit), interp.run_until(limit));
    }
    assert_eq!(state(&mut keeps), state(&mut interp));
    assert!(
        keeps.io_windows().memo_hits > 20,
        "{:?}",
        keeps.io_windows()
    );
}

#[test]
fn the_period_memo_keys_the_data_that_decides() {
    // The ADC decodes the command words the DMA reads from SRAM (the channel of the next
    // frame): a recording keys their bits (its constraints), so a window with the other
    // channel order is recorded anew, never given by a recording of the other, and every
    // slice ends as in the lock-step run.
    let block = compare(
        Shape {
            commands: true,
            ..Shape::periodic(3000)
        },
        1_200_000,
    );
    let io = block.io_windows();
    eprintln!("{io:?}");
    assert!(io.memo_hits > 80, "{io:?}");
    // Both orders recorded (here or by another board of the process), each a few times.
    assert!(io.memo_recorded + io.memo_shared >= 2, "{io:?}");
}

#[test]
fn native_code_logs_the_dmas_banks_as_the_general_path_does() {
    // In a window, a core's single loads and stores to the DMA's bank and its word stores
    // to the DMA's registers are done and logged by native code (`jit::abi`'s `io_sram`,
    // `io_reg`); the general path logs the same accesses through the window's bus. Both
    // boards run the same slices; every window's logs, in order, must be the same.
    let shapes = [
        (false, false, 0, 300_000),
        (true, false, 0, 200_000),
        (false, true, 3001, 600_000),
    ];
    for (busy, periodic, period, cycles) in shapes {
        let shape = Shape {
            busy,
            periodic,
            period,
            ..Shape::default()
        };
        let [mut native, mut general] = [true, false].map(|on| {
            let mut b = board(Engine::Block, shape);
            b.check_io_logs(on);
            b
        });
        let mut rng = Rng(0x4e_a71e + busy as u64 + 2 * periodic as u64);
        while native.cycle() < cycles {
            let limit = match periodic {
                true => (native.cycle() / period + 1 + rng.below(3) as u64) * period + 900,
                false => native.cycle() + 1 + rng.below(9000) as u64,
            };
            let set = rng.below(3);
            for b in [&mut native, &mut general] {
                let io = b.io_mut().expect("io");
                for c in 0..8 {
                    io.adcs[0].set_code(c, set.wrapping_mul(97) ^ (c as u16) << 12);
                }
            }
            assert_eq!(native.run_until(limit), general.run_until(limit));
            assert_eq!(state(&mut native), state(&mut general), "at {limit}");
        }
        let (n, g) = (native.io_log_digest(), general.io_log_digest());
        assert_eq!(n, g, "busy {busy}, periodic {periodic}");
        assert_ne!(n, Some(0));
        // The same windows kept and undone (the period memo's counts aside: the two boards
        // share the process's store, so one may take what the other recorded).
        let undone = |w: IoWindows| (w.kept, w.waited, w.stale, w.reach);
        assert_eq!(undone(native.io_windows()), undone(general.io_windows()));
        let w = native.io_windows();
        assert!(w.kept + w.waited + w.stale > 20, "{w:?}");
    }
}
