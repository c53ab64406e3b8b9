//! The board's converter I/O on the bus (issue 40): the two PIO blocks ([`crate::pio`]), the
//! DMA controller ([`crate::dma`]), the GPIO function select of IO_BANK0, the bus fabric's
//! BUS_PRIORITY, and the SPI converters at the pins ([`crate::converters`]), as one machine
//! the cores reach through their registers and, by the DMA, through SRAM.
//!
//! A board without converters has no [`Io`] ([`crate::bus::System::io`] is `None`): none
//! of this costs it anything but a test of that `None` on the general path.
//!
//! **Registers** (RP2040 datasheet 2.2): the DMA at 0x50000000, PIO0 at 0x50200000, PIO1
//! at 0x50300000 (AHB-Lite peripherals: a core's access takes no wait state, as an SRAM
//! access, [`AHB_PERIPHERAL_WAIT`]), IO_BANK0 at 0x40014000 (GPIOn_CTRL's FUNCSEL: 6 gives
//! the pad to PIO0, 7 to PIO1; other fields stored, no effect) and BUSCTRL at 0x40030000
//! (BUS_PRIORITY), each with the atomic XOR, SET and CLR aliases at +0x1000, +0x2000 and
//! +0x3000 (2.1.2). RESETS holds PIO0 (bit 10), PIO1 (11), DMA (2), IO_BANK0 (5) and
//! BUSCTRL (1): a block put into reset returns to its reset state, and an access to a block
//! held in reset is a bus fault (the emulator's way of refusing it; the chip's bus would
//! stall). Interrupts of the DMA and the PIOs do not reach the NVIC (not modelled).
//!
//! **The machine's cycle.** Each system cycle, in this order: the DMA ticks (its read and
//! write ports against SRAM and the PIO FIFOs, paced by the PIOs' DREQs: PIO0 TX0–3 are
//! DREQ 0–3, RX0–3 4–7, PIO1 8–15 likewise); both PIO blocks tick with the GPIO inputs the
//! converters drive; the converters see the pins if any driven level or direction changed.
//! A pin is driven by PIO *b* when its FUNCSEL is PIO *b*'s and the state machines set it
//! as an output; an undriven CS reads high (the board's pull-up).
//!
//! **By events.** The machine runs lazily: [`crate::bus::System`] advances it to a cycle
//! only when a core accesses one of its registers or an SRAM bank its DMA may touch, and
//! the board at the end of each run. Inside a run it goes from event to event
//! (`Io::advance_by_events`): while the DMA has nothing it could do ([`Dma::quiet`]), the
//! next cycle anything can happen is the first in which a state machine runs an
//! instruction ([`Pio::sm_idle`]: the cycles its clock divider skips and those of a pending
//! delay change nothing else), and only the state machines due then run ([`Pio::sm_tick`]);
//! each has its own clock, brought forward in one step ([`Pio::sm_skip`]) when something
//! needs it. A state machine that alone drives its converters runs ahead of the rest with
//! them (`Io::run_ahead`), and a bit loop of its program ([`crate::pio::BitLoop`]: the SPI
//! drivers' `OUT`/`IN` … `JMP X--` loops) as many times round as fit in one step, its
//! converters taking the clock edges in bulk (`Io::run_loop`). The cores' accesses to the
//! DMA's banks need only the DMA as of their cycle: there (`Io::advance` without
//! `settle`) such a state machine at a loop's head that ends later stays behind, held at its
//! clock, and runs the loop whole in a later advance (`Io::behind`); every other advance
//! settles it first. A converter sees the pins when one of its own changed. An advance
//! that stops before anything happens notes the cycle of the next event; the advances
//! that end before it (most of a window's replay: the cores' accesses come in clusters)
//! only move the clocks (`Io::skip_idle`, one in 16 checked against the full run in debug
//! builds).
//! The reference it is tested against ticks everything every cycle ([`Io::stepwise`]).
//!
//! **The DMA against the cores.** The DMA's two masters (read and write ports) arbitrate
//! for SRAM banks with the cores (a bank serves one master a cycle). With DMA_R and DMA_W
//! both high in BUS_PRIORITY and the core's bit low, the DMA wins: a core access to a bank
//! the DMA claims in that cycle waits a cycle (and again while it claims it). Otherwise the
//! core wins and the DMA waits a cycle (the round-robin among masters of equal priority is
//! not modelled: the core wins such ties). The DMA's read master wins over its write master
//! in one cycle. To see the DMA's accesses in cycle order, every core access to a bank an
//! enabled channel may reach ([`Dma::reach`], recomputed at each DMA register write) leaves
//! the fast path ([`crate::bus::System::allowed_banks`]) and advances the machine first; the
//! block engine's unconfined code, which does not check banks, does not run while an
//! [`Io`] is attached. The cores' accesses are served in the lock-step's issue order: an
//! access whose data phase is earlier than one of the other core's already served finds the
//! machine where that one left it. Where the DMA wins against both cores, the cores run in
//! windows ahead of the machine (`board/window.rs`), which then replays their accesses to
//! its banks and their stores to its registers in that order, the window undone where the
//! lock-step run would have differed (`board/io_window.rs`); a replay whose control
//! repeats a recorded one's takes its effect instead, with its own data (the period memo
//! there). For it the machine names its data words (`Io::data_slots`: the state
//! machines' registers and FIFO words, the pins' levels, the DMA's transfers in flight, the
//! parts' codes and registers), compares and takes states but for them
//! (`Io::eq_but_data`, `Io::become_but_data`) and, while a replay is recorded, keeps each
//! data bit's lane through the stepwise run (`crate::lanes`, `LaneRec`).
//!
//! Not modelled: the DMA reaching peripherals other than the PIO FIFOs (its own registers,
//! APB), the DMA's and PIOs' interrupts, GPIO overrides, pads, and the SIO's GPIO outputs.

use crate::bus::{load_le, store_le, BusFault};
use crate::converters::{AdcFrame, Ads8688, Dac8568, DacUpdate, Recorded, SpiPins};
use crate::dma::{Dma, DmaPort};
use crate::lanes::{self, Fixed, Lane, Word, CONST};
use crate::pio::{BitLoop, LoopClock, Pio, LOOP_MAX};
use tactus_rp2040::busctrl::{priority, BUSCTRL_BASE};
use tactus_rp2040::dma::DMA_BASE;
use tactus_rp2040::io_bank0::{FUNCSEL_NULL, GPIOS, IO_BANK0_BASE};
use tactus_rp2040::memory::{sram_location, BANKS};
use tactus_rp2040::pio::{PIO0_BASE, PIO1_BASE};
use tactus_rp2040::resets;
use tactus_runtime::converters::{AdcPart, DacPart};

/// Wait states of a core's access to a DMA or PIO register (AHB-Lite peripherals,
/// datasheet 2.1: not behind the APB bridge).
pub const AHB_PERIPHERAL_WAIT: u32 = 0;

/// RESETS bits of the blocks here (datasheet 2.14.3).
const IO_RESETS: u32 =
    resets::BUSCTRL | resets::DMA | resets::IO_BANK0 | resets::PIO0 | resets::PIO1;

/// The converters a board carries, with their pins: what [`crate::Board::attach_io`] wires.
#[derive(Clone, Debug, Default)]
pub struct IoConfig {
    /// ADCs (key positions), each with its pins.
    pub adcs: Vec<(&'static AdcPart, SpiPins)>,
    /// DACs (motor currents), each with its pins (`sdo` unused).
    pub dacs: Vec<(&'static DacPart, SpiPins)>,
}

/// The I/O machine. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct Io {
    /// PIO0 and PIO1.
    pub pio: [Pio; 2],
    /// The DMA controller.
    pub dma: Dma,
    /// The ADCs at their pins, in [`IoConfig::adcs`] order.
    pub adcs: Vec<Ads8688>,
    /// The DACs at their pins, in [`IoConfig::dacs`] order.
    pub dacs: Vec<Dac8568>,
    /// The first cycle not yet run.
    cycle: u64,
    gpio_ctrl: [u32; GPIOS],
    /// Per PIO block, the pins whose FUNCSEL is its.
    pio_pins: [u32; 2],
    bus_priority: u32,
    /// The blocks held in reset (RESETS bits of [`resets::ALL`]).
    held: u32,
    /// Driven levels and directions as the converters saw them last.
    pins: (u32, u32),
    /// The levels the converters drive (their SDO pins).
    gpio_in: u32,
    /// Per DMA master (read, write), the last cycle it claimed each SRAM bank.
    dma_claim: [[u64; BANKS]; 2],
    /// SRAM banks an enabled channel may reach ([`Dma::reach`]).
    reach_banks: u8,
    /// Tick every cycle, never skipping a quiet stretch: the reference the skipping is
    /// tested against (`tests/io.rs`, the firmware's `tests/converters.rs`). Results never
    /// depend on it.
    pub stepwise: bool,
    /// Per PIO block and state machine, the first cycle not yet applied to it: behind
    /// [`Io::cycle`] only inside [`Io::advance`], while the cycles between change nothing
    /// in it but its clock divider and delay ([`Pio::sm_skip`]).
    sm_clock: [[u64; 4]; 2],
    /// Inside [`Io::advance`], per ADC the GPIO inputs it drives from the cycle it started
    /// at: (first cycle, levels) at each change, oldest first; the synchronisers' flops
    /// follow from them.
    sdo_log: Vec<Vec<(u64, u32)>>,
    /// Per PIO block and state machine, what [`Io::run_ahead`] may run of it, found for the
    /// blocks' configuration epochs ([`Pio::config_epoch`]) and the I/O's register writes;
    /// shared, not copied, by a clone ([`Io::checkpoint`]).
    ahead: Option<std::sync::Arc<Ahead>>,
    /// The state machines held at the head of a bit loop behind [`Io::cycle`] (bit 4b + n),
    /// at their clocks, by an advance that did not settle ([`Io::advance`]): nothing sees
    /// them until they run on; [`Io::sdo_log`] keeps their ADCs' outputs meanwhile.
    behind: u8,
    /// Per PIO block and state machine held behind, the cycle its loop ends at: until an
    /// advance reaches it (or settles), it stays held without a look.
    held_until: [[u64; 4]; 2],
    /// The cycle before which nothing runs, as the last advance found it (`Io::skip_idle`).
    idle: Idle,
    /// The lanes of the pins' levels and of the GPIO inputs while a replay is recorded
    /// (`crate::lanes`); `None` otherwise.
    lanes: Option<Box<IoLanes>>,
    /// Which machine this is and how often it has been changed but for its data
    /// ([`Io::touches`]).
    touches: Touches,
}

/// A machine's identity (unique in the process) and a count of its changes but for its
/// data: a period memo knows from it that the machine is still as its last replay left it
/// (`board/io_window.rs`). A note, not state: machines that differ only in it are equal.
#[derive(Clone, Copy)]
struct Touches {
    id: u64,
    n: u64,
}

impl Touches {
    /// A new machine's.
    fn new() -> Touches {
        static IDS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        Touches {
            id: IDS.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            n: 0,
        }
    }
}

impl PartialEq for Touches {
    fn eq(&self, _: &Touches) -> bool {
        true
    }
}

impl std::fmt::Debug for Touches {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Touches")
    }
}

/// Where a data word of the machine lies ([`Io::locate`]): the machine's own (0 the pins'
/// levels, 1 the inputs), or a part's and its index among the part's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Slot {
    Io(usize),
    Pio(usize, usize),
    Dma(usize),
    Adc(usize, usize),
    Dac(usize, usize),
}

/// The machine's own lanes while a replay is recorded (`crate::lanes`), per GPIO.
#[derive(Clone, Debug, PartialEq, Eq)]
struct IoLanes {
    /// The levels driven, as the converters saw them last ([`Io::pins`]).
    pins: Word,
    /// The levels the converters drive ([`Io::gpio_in`]).
    gpio_in: Word,
    /// Two parts drove data onto one pin: no lane says what it reads.
    clash: bool,
}

/// What a recording's data words hold at its end ([`Io::stop_lanes`]): per data slot
/// ([`Io::data_slots`]) its value and lanes; the lanes of the codes of the frames and
/// updates the parts recorded, per part; and every lane fixed.
pub(crate) struct LanesKept {
    /// Per data slot: its value, lanes and width in bits.
    pub slots: Vec<(u32, Word, u32)>,
    pub frames: Vec<Vec<crate::converters::Lanes16>>,
    pub updates: Vec<Vec<crate::converters::Lanes16>>,
    pub fixed: Vec<Fixed>,
}

/// One SRAM access of the DMA in a recorded replay ([`LaneRec`]), at its tick (the cycle
/// the DMA's port was asked in).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum LaneOp {
    /// It read `size` bytes at SRAM offset `off`: input `input`.
    Read {
        tick: u64,
        off: u32,
        size: u8,
        input: u32,
    },
    /// It wrote the low `size` bytes of `value`, whose lanes are `lanes`, at `off`.
    Write {
        tick: u64,
        off: u32,
        size: u8,
        value: u32,
        lanes: Box<Word>,
    },
}

/// What the DMA does to SRAM and the banks while a replay is recorded with lanes
/// (`crate::lanes`, the period memo of `board/io_window.rs`).
#[derive(Clone, Default)]
pub(crate) struct LaneRec {
    /// The next input's number: the data slots' come first, then one per SRAM read.
    pub next_input: u32,
    pub ops: Vec<LaneOp>,
    /// Each bank claimed by one of the DMA's masters: (cycle, bank).
    pub claims: Vec<(u64, u8)>,
    /// Lanes fixed at the bus (data written to a register other than a TX FIFO).
    pub fixed: Vec<Fixed>,
    /// The DMA read ROM or flash (which differ from board to board): no recording.
    pub poisoned: bool,
    read_lanes: Word,
    write_lanes: Word,
}

impl LaneRec {
    /// A recording whose data slots are the first `slots` inputs.
    pub(crate) fn new(slots: u32) -> Self {
        LaneRec {
            next_input: slots,
            ..LaneRec::default()
        }
    }
}

impl std::fmt::Debug for LaneRec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LaneRec")
            .field("ops", &self.ops.len())
            .field("claims", &self.claims.len())
            .finish()
    }
}

/// What an advance found of the next cycle anything can happen in (the DMA quiet, no state
/// machine due before it, none held behind): until then an advance only moves the clocks
/// ([`Io::skip_idle`]). 0 when unknown; moved with the machine's cycles ([`Io::rebase`]),
/// kept by a clone and its rewind, forgotten by everything else that changes the machine (a
/// register access, a reset, the host's access to the parts: [`crate::Board::io_mut`]). A
/// note of the machine's to itself, not its state: machines that differ only in it are
/// equal.
#[derive(Clone, Copy, Default)]
struct Idle(u64);

/// In debug builds one idle skip in this many (per thread) is checked against the full run
/// it skips (`Io::advance_by_events`): checking every one made the tests that run converter
/// boards ten times slower.
#[cfg(debug_assertions)]
const IDLE_CHECK_EVERY: u32 = 16;

/// Whether this idle skip is one checked ([`IDLE_CHECK_EVERY`]).
#[cfg(debug_assertions)]
pub(crate) fn check_this_skip() -> bool {
    thread_local!(static SKIPS: std::cell::Cell<u32> = const { std::cell::Cell::new(0) });
    SKIPS.with(|s| {
        let n = s.get();
        s.set(n.wrapping_add(1));
        n % IDLE_CHECK_EVERY == 0
    })
}

impl PartialEq for Idle {
    fn eq(&self, _: &Idle) -> bool {
        true
    }
}

impl std::fmt::Debug for Idle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Idle")
    }
}

/// The machine at some moment, to go back to ([`Io::checkpoint`], [`Io::rewind`]).
pub(crate) struct Checkpoint {
    /// The machine then, its parts without their records.
    pub(crate) io: Box<Io>,
    /// Per ADC, then per DAC, its [`Recorded::record_counts`] then.
    counts: Vec<[usize; 2]>,
}

/// Which state machines may run ahead of the rest ([`Io::run_ahead`]), and the converters
/// each drives.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Ahead {
    /// The blocks' [`Pio::config_epoch`] it was found at.
    epochs: [u64; 2],
    /// Per block and state machine: `None`, or the ADCs and the DACs (bit k: the k-th)
    /// that see its pins and no other state machine's, and the pins it drives.
    sm: [[Option<(u32, u32, u32)>; 4]; 2],
    /// Per block and state machine, the addresses (bit a) at which one of `loops` starts.
    heads: [[u32; 4]; 2],
    /// The bit loops of the state machines that may run ahead, with their converters' edges
    /// ([`Io::run_loop`]).
    loops: Vec<LoopPlan>,
}

/// What a run ahead ([`Io::run_ahead`]) needs of the advance it is part of.
struct Run<'f> {
    /// The cycle the advance started at, and its end.
    start: u64,
    to: u64,
    /// The synchroniser flops at `start`.
    flops: &'f [[u32; 2]; 2],
    /// Whether the advance settles (every state machine brought to `to`), or may leave one
    /// behind at a bit loop's head ([`Io::behind`]).
    settle: bool,
    /// Whether the state machine reads its inputs from the ADCs' logs alone ([`Io::own_in`]).
    logs: bool,
}

/// A bit loop ([`BitLoop`]) of a state machine that may run ahead, and what it does to the
/// pins of each of its converters ([`BitLoop::clock`]): what [`Io::run_loop`] runs in one
/// step.
#[derive(Clone, Debug, PartialEq, Eq)]
struct LoopPlan {
    /// The PIO block and state machine.
    sm: (usize, usize),
    lp: BitLoop,
    /// Per ADC and per DAC it drives (their indices), the loop's clock on its pins.
    adcs: Vec<(usize, LoopClock)>,
    dacs: Vec<(usize, LoopClock)>,
}

/// What the machine reaches of the rest of the system while it runs: SRAM (with the cores'
/// bank claims and the decode cache's code pages), ROM and flash.
pub(crate) struct Memory<'a> {
    pub sram: &'a mut [u8],
    pub code_pages: &'a mut [bool],
    pub code_epoch: &'a mut u32,
    pub bank_claim: &'a [[u64; 2]; BANKS],
    pub rom: &'a [u8],
    pub flash: &'a [u8],
    pub xip_answers: bool,
    /// Where the DMA's SRAM writes journal the word they overwrite (`offset << 32 | old`),
    /// while a window's I/O is replayed (`System::io_journal`).
    pub journal: Option<&'a mut Vec<u64>>,
    /// What the DMA does while a window's replay is recorded with lanes for the period
    /// memo (`System::io_rec`, `board/io_window.rs`).
    pub rec: Option<&'a mut LaneRec>,
}

/// Cycles moved from one time base to another (a window's start to a period memo's and
/// back, [`Io::rebased`]): `from` goes to `to`, and the values no cycle can take — 0 (the
/// DMA's ports before their first transfer, a state machine held nowhere) and `u64::MAX`
/// (a bank no DMA master has claimed) — stay.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rebase {
    pub from: u64,
    pub to: u64,
}

impl Rebase {
    /// The time base the memo keeps its states at: far from 0 and `u64::MAX` either way,
    /// so that no rebased cycle meets those two.
    pub const MEMO: u64 = 1 << 62;

    /// `v` in the new time base.
    pub fn at(self, v: u64) -> u64 {
        match v {
            0 | u64::MAX => v,
            _ => v.wrapping_sub(self.from).wrapping_add(self.to),
        }
    }

    /// The move back.
    pub fn back(self) -> Rebase {
        Rebase {
            from: self.to,
            to: self.from,
        }
    }
}

/// How a period memo's hit gives its records' codes (`board/io_window.rs`): per ADC its
/// frames' routes, per DAC its updates', and the inputs they read.
#[derive(Clone, Copy)]
pub(crate) struct RecordCodes<'a> {
    pub frames: &'a [Vec<lanes::Route>],
    pub updates: &'a [Vec<lanes::Route>],
    pub inputs: &'a [u32],
}

/// A period memo entry's end state (`board/io_window.rs`): the machine at [`Rebase::MEMO`]
/// without its records, and its data slots ([`Io::data_slots`]' order) that have no place in
/// it (a word written there is dropped, and reads 0: an ADC's frame code without a frame).
#[derive(Debug)]
pub(crate) struct EndState {
    pub(crate) io: Io,
    absent: Vec<u32>,
}

impl EndState {
    /// The end state `io`.
    pub(crate) fn new(io: Io) -> EndState {
        let mut probe = io.clone();
        let n = {
            let mut n = 0;
            probe.data_slots(&mut |_, _| n += 1);
            n
        };
        let absent = (0..n)
            .filter(|&i| {
                let at = probe.locate(i);
                probe.set_slot_at(at, 1);
                probe.slot_at(at) != 1
            })
            .map(|i| i as u32)
            .collect();
        EndState { io, absent }
    }
}

/// A machine left behind by a period memo's hit (`board/io_window.rs`, "The lazy end"): the
/// machine is `end` moved by `back` but for its data words, which are `data`
/// ([`Io::data_slots`]' order). Made the live machine by [`Io::become_lazy`] before anything
/// but the period memo looks at it.
#[derive(Clone, Debug)]
pub(crate) struct LazyEnd {
    pub(crate) end: std::sync::Arc<EndState>,
    pub(crate) back: Rebase,
    pub(crate) data: Vec<u32>,
}

impl LazyEnd {
    /// The machine's cycle ([`Io::cycle`]).
    pub(crate) fn cycle(&self) -> u64 {
        self.back.at(self.end.io.cycle)
    }

    /// After a hit's data words were written: those with no place in the end state read 0,
    /// as the live machine's would.
    pub(crate) fn drop_absent(&mut self) {
        for &i in &self.end.absent {
            if let Some(v) = self.data.get_mut(i as usize) {
                *v = 0;
            }
        }
    }
}

/// The parts' records of a stretch (a period memo's, `board/io_window.rs`; a rest period's,
/// `board/rest.rs`): per ADC its frames, per DAC its updates, in [`IoConfig`] order.
#[derive(Clone, Debug, Default)]
pub(crate) struct IoRecords {
    adcs: Vec<Vec<AdcFrame>>,
    dacs: Vec<Vec<DacUpdate>>,
}

impl IoRecords {
    /// Whether it holds no frame and no update.
    pub(crate) fn is_empty(&self) -> bool {
        self.adcs.iter().all(Vec::is_empty) && self.dacs.iter().all(Vec::is_empty)
    }

    /// The routes of its codes (`crate::lanes::Route`) from their lanes (per ADC its
    /// frames', per DAC its updates', in order: [`LanesKept`]): (frames', updates').
    pub(crate) fn routes(
        &self,
        frames: &[Vec<crate::converters::Lanes16>],
        updates: &[Vec<crate::converters::Lanes16>],
    ) -> (Vec<Vec<lanes::Route>>, Vec<Vec<lanes::Route>>) {
        let route = |l: Option<&crate::converters::Lanes16>, code: u16| {
            let mut w = CONST;
            if let Some(l) = l {
                w[..16].copy_from_slice(l);
            }
            lanes::Route::of(&w, u32::from(code))
        };
        let f = (self.adcs.iter().enumerate())
            .map(|(a, fs)| {
                (fs.iter().enumerate())
                    .map(|(i, x)| route(frames.get(a).and_then(|l| l.get(i)), x.code))
                    .collect()
            })
            .collect();
        let u = (self.dacs.iter().enumerate())
            .map(|(d, us)| {
                (us.iter().enumerate())
                    .map(|(i, x)| route(updates.get(d).and_then(|l| l.get(i)), x.code))
                    .collect()
            })
            .collect();
        (f, u)
    }
}

/// Writes `size` bytes of `value` at SRAM offset `off` for the DMA: journaled while a
/// window is replayed, invalidating decoded code on the page.
#[inline]
pub(crate) fn dma_sram_write(mem: &mut Memory, off: usize, size: u32, value: u32) {
    let journal = mem.journal.as_deref_mut();
    dma_sram_store(
        mem.sram,
        mem.code_pages,
        mem.code_epoch,
        journal,
        off,
        size,
        value,
    );
}

/// [`dma_sram_write`] on the system's parts themselves (a period memo's hit,
/// `crate::bus::System::io_dma_write`): the SRAM, its pages of decoded code and their
/// epoch, and the journal.
#[inline]
pub(crate) fn dma_sram_store(
    sram: &mut [u8],
    code_pages: &mut [bool],
    code_epoch: &mut u32,
    journal: Option<&mut Vec<u64>>,
    off: usize,
    size: u32,
    value: u32,
) {
    if let Some(j) = journal {
        let word = off & !3;
        j.push((word as u64) << 32 | u64::from(load_le(sram, word, 4)));
    }
    store_le(sram, off, size, value);
    if code_pages[off >> 8] {
        *code_epoch = code_epoch.wrapping_add(1);
        code_pages.fill(false);
    }
}

/// The DMA's side of the machine for one tick: memory, the PIO FIFOs and DREQs.
struct Port<'m, 'a> {
    mem: &'m mut Memory<'a>,
    pio: &'m mut [Pio; 2],
    claim: &'m mut [[u64; BANKS]; 2],
    /// Whether each DMA master (read, write) wins a bank against core 0 and core 1.
    wins: [[bool; 2]; 2],
    /// The PIO blocks whose registers (FIFOs) the DMA read or wrote (bit b: PIO b).
    touched: u8,
}

/// Which PIO block `addr` is in (0 or 1) and the register offset (the atomic aliases of
/// DMA transfers are not decoded: an offset within the first 4 KB).
fn pio_of(addr: u32) -> Option<(usize, u32)> {
    match addr & !0xfff {
        PIO0_BASE => Some((0, addr & 0xfff)),
        PIO1_BASE => Some((1, addr & 0xfff)),
        _ => None,
    }
}

impl<'m, 'a> Port<'m, 'a> {
    /// The DMA's side of `mem` and the blocks `pio` for a tick, the masters' bank claims in
    /// `claim`, winning banks against the cores as `wins` says.
    fn new(
        mem: &'m mut Memory<'a>,
        pio: &'m mut [Pio; 2],
        claim: &'m mut [[u64; BANKS]; 2],
        wins: [[bool; 2]; 2],
    ) -> Self {
        Port {
            mem,
            pio,
            claim,
            wins,
            touched: 0,
        }
    }

    /// The wait states of master `m`'s access to `bank` in `cycle`, claiming it.
    fn claim_bank(&mut self, m: usize, bank: usize, cycle: u64) -> u32 {
        let mut wait = 0u32;
        let core_claims =
            |at: u64, k: usize| self.mem.bank_claim[bank][k] == at && !self.wins[m][k];
        while core_claims(cycle + u64::from(wait), 0)
            || core_claims(cycle + u64::from(wait), 1)
            || (m == 1 && self.claim[0][bank] == cycle + u64::from(wait))
        {
            wait += 1;
        }
        self.claim[m][bank] = cycle + u64::from(wait);
        if let Some(rec) = self.mem.rec.as_deref_mut() {
            rec.claims.push((cycle + u64::from(wait), bank as u8));
        }
        wait
    }
}

impl DmaPort for Port<'_, '_> {
    fn read(&mut self, cycle: u64, addr: u32, size: u32) -> Result<(u32, u32), BusFault> {
        if let Some((off, bank)) = sram_location(addr) {
            let wait = self.claim_bank(0, bank, cycle);
            if let Some(rec) = self.mem.rec.as_deref_mut() {
                // Each SRAM word it reads is an input of the recording.
                let input = rec.next_input;
                rec.next_input += 1;
                rec.ops.push(LaneOp::Read {
                    tick: cycle,
                    off: off as u32,
                    size: size as u8,
                    input,
                });
                rec.read_lanes = lanes::input_word(input, 8 * size);
            }
            return Ok((load_le(self.mem.sram, off, size), wait));
        }
        if let Some((b, off)) = pio_of(addr) {
            self.touched |= 1 << b;
            let v = self.pio[b].read(off & !3);
            let mask = u32::MAX >> (32 - 8 * size);
            if let Some(rec) = self.mem.rec.as_deref_mut() {
                let l = self.pio[b].lanes.as_ref().map_or(CONST, |l| l.last_read);
                rec.read_lanes = lanes::and(&lanes::shr(&l, 8 * (addr & 3)), mask);
            }
            let v = v >> (8 * (addr & 3)) & mask;
            return Ok((v, 0));
        }
        if let Some(rec) = self.mem.rec.as_deref_mut() {
            rec.poisoned = true;
            rec.read_lanes = CONST;
        }
        let flash = addr.wrapping_sub(tactus_rp2040::memory::FLASH_BASE);
        if addr < tactus_rp2040::memory::ROM_SIZE {
            return Ok((load_le(self.mem.rom, addr as usize, size), 0));
        }
        if flash < tactus_rp2040::memory::FLASH_SIZE && self.mem.xip_answers {
            return Ok((load_le(self.mem.flash, flash as usize, size), 0));
        }
        Err(BusFault { addr })
    }

    fn write(&mut self, cycle: u64, addr: u32, size: u32, value: u32) -> Result<u32, BusFault> {
        if let Some((off, bank)) = sram_location(addr) {
            let wait = self.claim_bank(1, bank, cycle);
            if let Some(rec) = self.mem.rec.as_deref_mut() {
                let mask = u32::MAX >> (32 - 8 * size);
                rec.ops.push(LaneOp::Write {
                    tick: cycle,
                    off: off as u32,
                    size: size as u8,
                    value: value & mask,
                    lanes: Box::new(lanes::and(&rec.write_lanes, mask)),
                });
            }
            dma_sram_write(self.mem, off, size, value);
            return Ok(wait);
        }
        if let Some((b, off)) = pio_of(addr) {
            // A narrow write reaches a 32-bit register replicated (datasheet 2.1.4).
            let v = match size {
                1 => (value & 0xff) * 0x0101_0101,
                2 => (value & 0xffff) * 0x0001_0001,
                _ => value,
            };
            if let Some(rec) = self.mem.rec.as_deref_mut() {
                let l = rec.write_lanes;
                let w: Word = std::array::from_fn(|i| match size {
                    1 => l[i % 8],
                    2 => l[i % 16],
                    _ => l[i],
                });
                let fifo = (tactus_rp2040::pio::reg::TXF0..tactus_rp2040::pio::reg::TXF0 + 16)
                    .contains(&(off & !3));
                match self.pio[b].lanes.as_deref_mut() {
                    Some(pl) if fifo => pl.next_write = w,
                    // Data written to any other register decides what the block does.
                    _ => lanes::fix(&mut w.clone(), v, u32::MAX, &mut rec.fixed),
                }
            }
            self.touched |= 1 << b;
            self.pio[b].write(off & !3, v);
            return Ok(0);
        }
        Err(BusFault { addr })
    }

    fn read_lanes(&mut self) -> Word {
        self.mem.rec.as_deref().map_or(CONST, |r| r.read_lanes)
    }

    fn write_lanes(&mut self, lanes: &Word) {
        if let Some(rec) = self.mem.rec.as_deref_mut() {
            rec.write_lanes = *lanes;
        }
    }

    fn dreq_room(&self, n: u32) -> u32 {
        let (b, i) = ((n / 8) as usize, (n % 8) as usize);
        match (b, i) {
            (0 | 1, 0..=3) => self.pio[b].tx_room(i),
            (0 | 1, _) => self.pio[b].rx_level(i - 4),
            _ => 0,
        }
    }
}

/// The SRAM banks the bytes `[addr, addr + len)` of the address space touch.
fn banks_of(addr: u32, len: u64) -> u8 {
    let (lo, hi) = (u64::from(addr), u64::from(addr).saturating_add(len));
    let overlaps = |a: u64, b: u64| lo < b && a < hi;
    let mut banks = 0u8;
    // The striped view: four or more bytes past a word boundary reach more banks; 16
    // bytes reach all four.
    let (s0, s1) = (0x2000_0000u64, 0x2004_0000u64);
    if overlaps(s0, s1) {
        let (a, b) = (lo.max(s0), hi.min(s1));
        if b - a >= 16 {
            banks |= 0xf;
        } else {
            let mut w = a & !3;
            while w < b {
                banks |= 1 << ((w >> 2) & 3);
                w += 4;
            }
        }
    }
    for (bank, base) in [(4, 0x2004_0000u64), (5, 0x2004_1000)] {
        if overlaps(base, base + 0x1000) {
            banks |= 1 << bank;
        }
    }
    for bank in 0..4u64 {
        let base = 0x2100_0000 + bank * 0x1_0000;
        if overlaps(base, base + 0x1_0000) {
            banks |= 1 << bank;
        }
    }
    banks
}

/// The clock edges (steps of the rise and the fall) of `c` that a part on pins `p` sees
/// with the pins `view` (levels, directions) at the loop's entry: with its select driven
/// low and its clock driven; none otherwise.
fn loop_edges(c: &LoopClock, p: SpiPins, view: (u32, u32)) -> Option<(usize, usize)> {
    let selected = view.1 >> p.cs & 1 != 0 && view.0 >> p.cs & 1 == 0;
    c.edges.filter(|_| selected && view.1 >> p.sclk & 1 != 0)
}

/// The level an ADC's output log (`Io::sdo_log`: (first cycle, levels) at each change,
/// in cycle order) gives for cycle `x`: its last entry from `x` or before, 0 before the
/// first.
fn level_at(log: &[(u64, u32)], x: u64) -> u32 {
    match log.partition_point(|&(since, _)| since <= x) {
        0 => 0,
        i => log[i - 1].1,
    }
}

/// Logs an ADC's output change to `levels` from cycle `since` (the log in cycle order,
/// as [`level_at`] needs it).
fn log_change(log: &mut Vec<(u64, u32)>, since: u64, levels: u32) {
    debug_assert!(log.last().is_none_or(|&(s, _)| s <= since));
    log.push((since, levels));
}

impl Io {
    /// The machine out of reset, on a system clocked at `clock_hz`, with `config`'s
    /// converters at their pins; its clock at `cycle`.
    pub fn new(config: &IoConfig, clock_hz: f64, cycle: u64) -> Io {
        Io {
            pio: [Pio::new(), Pio::new()],
            dma: Dma::new(),
            adcs: config
                .adcs
                .iter()
                .map(|&(part, pins)| Ads8688::new(part, pins, clock_hz))
                .collect(),
            dacs: config
                .dacs
                .iter()
                .map(|&(part, pins)| Dac8568::new(part, pins, clock_hz))
                .collect(),
            cycle,
            gpio_ctrl: [FUNCSEL_NULL; GPIOS],
            pio_pins: [0; 2],
            bus_priority: 0,
            held: 0,
            pins: (0, 0),
            gpio_in: 0,
            dma_claim: [[u64::MAX; BANKS]; 2],
            reach_banks: 0,
            stepwise: false,
            sm_clock: [[cycle; 4]; 2],
            sdo_log: Vec::new(),
            ahead: None,
            behind: 0,
            held_until: [[0; 4]; 2],
            idle: Idle(0),
            lanes: None,
            touches: Touches::new(),
        }
    }

    /// Its identity and count of changes but for its data ([`Touches`]): equal between two
    /// moments only if nothing but its data words changed in between.
    pub(crate) fn touches(&self) -> (u64, u64) {
        (self.touches.id, self.touches.n)
    }

    /// Counts a change but for its data.
    fn touch(&mut self) {
        self.touches.n += 1;
    }

    /// Starts keeping lanes (`crate::lanes`) for a recorded replay: each data word's are
    /// its own bits, its slot's number the input ([`Io::data_slots`]). Returns the number
    /// of slots (the first input a DMA read takes).
    pub(crate) fn start_lanes(&mut self) -> u32 {
        self.touch();
        self.lanes = Some(Box::new(IoLanes {
            pins: CONST,
            gpio_in: CONST,
            clash: false,
        }));
        self.pio.iter_mut().for_each(Pio::start_lanes);
        self.dma.start_lanes();
        self.adcs.iter_mut().for_each(Ads8688::start_lanes);
        self.dacs.iter_mut().for_each(Dac8568::start_lanes);
        let mut slot = 0u32;
        self.data_slots(&mut |_, l| {
            if let Some(l) = l {
                for (b, x) in l.iter_mut().enumerate() {
                    *x = Lane::input(slot, b as u32);
                }
            }
            slot += 1;
        });
        // The FIFOs' words past their lengths are 0 (`crate::pio`'s invariant): constants.
        self.pio.iter_mut().for_each(Pio::const_fifo_tails);
        slot
    }

    /// Whether it, its cycles moved by `r`, equals `other` but for its data words
    /// ([`Io::data_slots`]) and its parts' records: what a period memo's entry is keyed by
    /// (`board/io_window.rs`). Every field named, in each part too (a field added must be
    /// decided here); the same as comparing the two with their data words zeroed.
    pub(crate) fn eq_but_data(&self, other: &Io, r: Rebase) -> bool {
        let Io {
            pio,
            dma,
            adcs,
            dacs,
            cycle,
            gpio_ctrl,
            pio_pins,
            bus_priority,
            held,
            pins,
            gpio_in: _,
            dma_claim,
            reach_banks,
            stepwise,
            sm_clock,
            sdo_log,
            ahead,
            behind,
            held_until,
            idle: _, // a note, not state
            lanes: _,
            touches: _, // a note, not state
        } = self;
        let at = |a: &[[u64; 4]; 2], b: &[[u64; 4]; 2]| {
            a.iter()
                .flatten()
                .zip(b.iter().flatten())
                .all(|(&x, &y)| r.at(x) == y)
        };
        let logs = sdo_log.len() == other.sdo_log.len()
            && sdo_log.iter().zip(&other.sdo_log).all(|(a, b)| {
                a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (r.at(x.0), x.1) == *y)
            });
        r.at(*cycle) == other.cycle
            && *gpio_ctrl == other.gpio_ctrl
            && *pio_pins == other.pio_pins
            && *bus_priority == other.bus_priority
            && *held == other.held
            && pins.1 == other.pins.1
            && (dma_claim.iter().flatten())
                .zip(other.dma_claim.iter().flatten())
                .all(|(&x, &y)| r.at(x) == y)
            && *reach_banks == other.reach_banks
            && *stepwise == other.stepwise
            && at(sm_clock, &other.sm_clock)
            && logs
            && *ahead == other.ahead
            && *behind == other.behind
            && at(held_until, &other.held_until)
            && adcs.len() == other.adcs.len()
            && dacs.len() == other.dacs.len()
            && pio.iter().zip(&other.pio).all(|(a, b)| a.eq_but_data(b))
            && dma.eq_but_data(&other.dma, r)
            && adcs
                .iter()
                .zip(&other.adcs)
                .all(|(a, b)| a.eq_but_data(b, r))
            && dacs
                .iter()
                .zip(&other.dacs)
                .all(|(a, b)| a.eq_but_data(b, r))
    }

    /// [`Io::eq_but_data`] the long way, for debug builds' checks of it: both machines
    /// rebased to `r`'s base, their data words zeroed, their records and how many the
    /// parts keep left out (a board that keeps none meets entries recorded where they
    /// were kept: `board/io_window.rs`, [`Io::keep_records`]), compared whole; and every
    /// data word read by [`Io::slot`] as [`Io::data_slots`] visits it.
    #[cfg(debug_assertions)]
    pub(crate) fn check_eq_but_data(&self, other: &Io, r: Rebase) {
        let mut a = self.clone();
        let mut k = 0;
        a.data_slots(&mut |v, _| {
            assert_eq!(*v, self.slot(k), "data word {k}");
            k += 1;
        });
        let zeroed = |io: &mut Io| {
            io.data_slots(&mut |v, _| *v = 0);
            for x in &mut io.adcs {
                x.take_records();
                x.set_kept(0);
            }
            for x in &mut io.dacs {
                x.take_records();
                x.set_kept(0);
            }
        };
        a.rebase(r);
        zeroed(&mut a);
        let mut b = other.clone();
        zeroed(&mut b);
        assert_eq!(a == b, self.eq_but_data(other, r), "eq_but_data");
    }

    /// Its `i`-th data word ([`Io::data_slots`]' order; 0 past them). For checks: tests and
    /// debug builds' [`Io::check_eq_but_data`].
    #[cfg(any(test, debug_assertions))]
    pub(crate) fn slot(&self, i: usize) -> u32 {
        self.slot_at(self.locate(i))
    }

    /// The data word at `at` ([`Io::locate`]; 0 for `None`).
    #[inline]
    pub(crate) fn slot_at(&self, at: Option<Slot>) -> u32 {
        match at {
            Some(Slot::Io(0)) => self.pins.0,
            Some(Slot::Io(_)) => self.gpio_in,
            Some(Slot::Pio(b, j)) => self.pio[b].slot(j),
            Some(Slot::Dma(j)) => self.dma.slot(j),
            Some(Slot::Adc(k, j)) => self.adcs[k].slot(j),
            Some(Slot::Dac(k, j)) => self.dacs[k].slot(j),
            None => 0,
        }
    }

    #[cfg(test)]
    /// Sets its `i`-th data word ([`Io::data_slots`]' order) as that visit would.
    pub(crate) fn set_slot(&mut self, i: usize, v: u32) {
        self.set_slot_at(self.locate(i), v)
    }

    /// Sets the data word at `at` ([`Io::locate`]; nothing for `None`) as
    /// [`Io::data_slots`]' visit would.
    #[inline]
    pub(crate) fn set_slot_at(&mut self, at: Option<Slot>, v: u32) {
        match at {
            Some(Slot::Io(0)) => self.pins.0 = v,
            Some(Slot::Io(_)) => self.gpio_in = v,
            Some(Slot::Pio(b, j)) => self.pio[b].set_slot(j, v),
            Some(Slot::Dma(j)) => {
                if let Some(w) = self.dma.slot_mut(j) {
                    *w = v;
                }
            }
            Some(Slot::Adc(k, j)) => self.adcs[k].set_slot(j, v),
            Some(Slot::Dac(k, j)) => self.dacs[k].set_slot(j, v),
            None => {}
        }
    }

    /// The first ADC's first data slot ([`Io::data_slots`]' order): the machine's own two,
    /// both PIO blocks', the DMA's.
    const ADC_SLOTS: usize = 2 + 2 * Pio::SLOTS + crate::dma::TRANSFER_FIFO_DEPTH;

    /// Where its `i`-th data word lies ([`Io::data_slots`]' order).
    pub(crate) fn locate(&self, i: usize) -> Option<Slot> {
        let pio = 2;
        let dma = pio + 2 * Pio::SLOTS;
        let adcs = Self::ADC_SLOTS;
        let dacs = adcs + self.adcs.len() * Ads8688::SLOTS;
        let end = dacs + self.dacs.len() * Dac8568::SLOTS;
        Some(match i {
            _ if i < pio => Slot::Io(i),
            _ if i < dma => Slot::Pio((i - pio) / Pio::SLOTS, (i - pio) % Pio::SLOTS),
            _ if i < adcs => Slot::Dma(i - dma),
            _ if i < dacs => Slot::Adc((i - adcs) / Ads8688::SLOTS, (i - adcs) % Ads8688::SLOTS),
            _ if i < end => Slot::Dac((i - dacs) / Dac8568::SLOTS, (i - dacs) % Dac8568::SLOTS),
            _ => return None,
        })
    }

    /// A hash of some of its control state (none of its data words: [`Io::data_slots`]):
    /// machines equal but for data have equal keys (a period memo's first test).
    /// Its cycles are moved by `r` first.
    pub(crate) fn quick_key(&self, r: Rebase) -> u64 {
        let mut h = 0xcbf2_9ce4_8422_2325u64;
        let mut mix = |v: u64| h = (h ^ v).wrapping_mul(0x0000_0100_0000_01b3);
        mix(r.at(self.cycle));
        mix(u64::from(self.pins.1));
        for c in self.dma_claim.iter().flatten() {
            mix(r.at(*c));
        }
        self.pio.iter().for_each(|p| p.quick_key(&mut mix));
        self.dma.quick_key(r, &mut mix);
        h
    }

    /// Stops keeping lanes: what they held ([`LanesKept`]), or `None` when a part lost them
    /// (reset meanwhile) or two parts drove one pin with data.
    pub(crate) fn stop_lanes(&mut self) -> Option<LanesKept> {
        let mut whole = self.lanes.as_ref().is_some_and(|l| !l.clash)
            && self.pio.iter().all(|p| p.lanes.is_some())
            && self.dma.lanes.is_some()
            && self.adcs.iter().all(|a| a.lanes.is_some())
            && self.dacs.iter().all(|d| d.lanes.is_some());
        let mut slots = Vec::new();
        self.data_slots(&mut |v, l| match l {
            Some(l) => {
                let mut w = CONST;
                w[..l.len()].copy_from_slice(l);
                slots.push((*v, w, l.len() as u32));
            }
            None => whole = false,
        });
        let mut fixed = Vec::new();
        let mut frames = Vec::new();
        let mut updates = Vec::new();
        for p in &mut self.pio {
            if let Some(l) = p.lanes.take() {
                fixed.extend_from_slice(&l.fixed);
            }
        }
        self.dma.lanes = None;
        for a in &mut self.adcs {
            if let Some(l) = a.lanes.take() {
                fixed.extend_from_slice(&l.fixed);
                frames.push(l.frames);
            }
        }
        for d in &mut self.dacs {
            if let Some(l) = d.lanes.take() {
                fixed.extend_from_slice(&l.fixed);
                updates.push(l.updates);
            }
        }
        self.lanes = None;
        whole.then_some(LanesKept {
            slots,
            frames,
            updates,
            fixed,
        })
    }

    /// Its data words, each with its lanes while they are kept, in a fixed order that the
    /// rest of the machine decides (the same for equal machines but for their data): the
    /// pins' levels as the converters saw them, the levels the converters drive, then the
    /// PIO blocks' ([`Pio::data_slots`]), the DMA's, the ADCs' and the DACs'. A period memo
    /// (`board/io_window.rs`) compares machines without them, and gives a recorded
    /// replay's by their routes.
    pub(crate) fn data_slots(&mut self, f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>)) {
        let mut l = self.lanes.as_deref_mut();
        f(&mut self.pins.0, l.as_deref_mut().map(|l| &mut l.pins[..]));
        f(&mut self.gpio_in, l.map(|l| &mut l.gpio_in[..]));
        for p in &mut self.pio {
            p.data_slots(f);
        }
        self.dma.data_slots(f);
        for a in &mut self.adcs {
            a.data_slots(f);
        }
        for d in &mut self.dacs {
            d.data_slots(f);
        }
    }

    /// The machine as it is now, to go back to with [`Io::rewind`] (a window's undo,
    /// `board/io_window.rs`): a clone but for the parts' records (frames, updates,
    /// violations), which only grow meanwhile, of which it keeps the counts.
    pub(crate) fn checkpoint(&mut self) -> Checkpoint {
        let adcs: Vec<Ads8688> = self.adcs.iter_mut().map(|a| a.without_records()).collect();
        let dacs: Vec<Dac8568> = self.dacs.iter_mut().map(|d| d.without_records()).collect();
        let counts = (self.adcs.iter_mut().map(Recorded::record_counts))
            .chain(self.dacs.iter_mut().map(Recorded::record_counts))
            .collect();
        let (adcs, dacs) = (
            std::mem::replace(&mut self.adcs, adcs),
            std::mem::replace(&mut self.dacs, dacs),
        );
        let io = Box::new(self.clone());
        self.adcs = adcs;
        self.dacs = dacs;
        Checkpoint { io, counts }
    }

    /// Back to `checkpoint` ([`Io::checkpoint`]), the parts' records cut to their counts then.
    pub(crate) fn rewind(&mut self, checkpoint: Checkpoint) {
        let Checkpoint { mut io, counts } = checkpoint;
        let (adcs, dacs) = (std::mem::take(&mut io.adcs), std::mem::take(&mut io.dacs));
        let mut counts = counts.into_iter();
        for (a, then) in self.adcs.iter_mut().zip(adcs) {
            a.rewind(then, counts.next().unwrap_or_default());
        }
        for (d, then) in self.dacs.iter_mut().zip(dacs) {
            d.rewind(then, counts.next().unwrap_or_default());
        }
        io.adcs = std::mem::take(&mut self.adcs);
        io.dacs = std::mem::take(&mut self.dacs);
        *self = *io;
        // Its count went back with it: another machine now, as far as counts tell.
        self.touches = Touches::new();
    }

    /// A clone of the machine without its parts' records (as [`Io::checkpoint`]), its
    /// cycles moved by `r`: a period memo's key or end state (`board/io_window.rs`).
    pub(crate) fn rebased(&mut self, r: Rebase) -> Box<Io> {
        let mut io = self.checkpoint().io;
        io.rebase(r);
        io
    }

    /// Its cycles moved by `r`, its parts' records not (a period memo's key, end state, or
    /// the live machine compared with one: `board/io_window.rs`).
    pub(crate) fn rebase(&mut self, r: Rebase) {
        self.touch();
        self.idle = Idle(r.at(self.idle.0));
        self.cycle = r.at(self.cycle);
        for c in self.dma_claim.as_flattened_mut() {
            *c = r.at(*c);
        }
        for c in self.sm_clock.as_flattened_mut() {
            *c = r.at(*c);
        }
        for c in self.held_until.as_flattened_mut() {
            *c = r.at(*c);
        }
        for log in &mut self.sdo_log {
            for (c, _) in log {
                *c = r.at(*c);
            }
        }
        self.dma.rebase(r);
        self.adcs.iter_mut().for_each(|a| a.rebase(r));
        self.dacs.iter_mut().for_each(|d| d.rebase(r));
    }

    /// Per ADC, then per DAC, its [`Recorded::record_counts`].
    pub(crate) fn record_counts(&mut self) -> Vec<[usize; 2]> {
        (self.adcs.iter_mut().map(Recorded::record_counts))
            .chain(self.dacs.iter_mut().map(Recorded::record_counts))
            .collect()
    }

    /// The parts' records after `counts` ([`Io::record_counts`]), their cycles moved by
    /// `r`; `None` when a timing violation is among them.
    pub(crate) fn records_since(&mut self, counts: &[[usize; 2]], r: Rebase) -> Option<IoRecords> {
        let (ca, cd) = counts.split_at(self.adcs.len());
        let adcs = (self.adcs.iter_mut().zip(ca))
            .map(|(a, &c)| a.records_since(c))
            .collect::<Option<Vec<_>>>()?;
        let dacs = (self.dacs.iter_mut().zip(cd))
            .map(|(d, &c)| d.records_since(c))
            .collect::<Option<Vec<_>>>()?;
        let mut rec = IoRecords { adcs, dacs };
        for f in rec.adcs.iter_mut().flatten() {
            f.cs_fall = r.at(f.cs_fall);
        }
        for u in rec.dacs.iter_mut().flatten() {
            u.cycle = r.at(u.cycle);
        }
        Some(rec)
    }

    /// Becomes `end` (from [`Io::rebased`]) moved by `r` but for its data words
    /// ([`Io::data_slots`]), which stay as they are, its parts' records kept, and appends
    /// `records` moved by `r`, their codes given by `codes` (routes and inputs:
    /// [`IoRecords::routes`]) when some: a period memo's hit, which then sets the data
    /// words its routes give (`board/io_window.rs`).
    pub(crate) fn become_but_data(
        &mut self,
        end: &Io,
        r: Rebase,
        records: &IoRecords,
        codes: Option<RecordCodes>,
    ) {
        let Io {
            pio,
            dma,
            adcs,
            dacs,
            cycle,
            gpio_ctrl,
            pio_pins,
            bus_priority,
            held,
            pins,
            gpio_in: _,
            dma_claim,
            reach_banks,
            stepwise: _, // the live machine's
            sm_clock,
            sdo_log,
            ahead,
            behind,
            held_until,
            idle,
            lanes: _,   // none outside a recording
            touches: _, // the live machine's
        } = end;
        for (a, b) in self.pio.iter_mut().zip(pio) {
            a.assign_but_data(b);
        }
        self.dma.assign_but_data(dma);
        for (a, b) in self.adcs.iter_mut().zip(adcs) {
            a.assign_but_data(b);
        }
        for (a, b) in self.dacs.iter_mut().zip(dacs) {
            a.assign_but_data(b);
        }
        self.cycle = *cycle;
        self.gpio_ctrl = *gpio_ctrl;
        self.pio_pins = *pio_pins;
        self.bus_priority = *bus_priority;
        self.held = *held;
        self.pins.1 = pins.1;
        self.dma_claim = *dma_claim;
        self.reach_banks = *reach_banks;
        self.sm_clock = *sm_clock;
        self.sdo_log.clone_from(sdo_log);
        if !matches!((&self.ahead, ahead), (Some(a), Some(b)) if std::sync::Arc::ptr_eq(a, b)) {
            self.ahead.clone_from(ahead);
        }
        self.behind = *behind;
        self.held_until = *held_until;
        self.idle = *idle;
        self.lanes = None;
        self.rebase(r);
        self.append_records_coded(records, r, codes);
    }

    /// Its data words ([`Io::data_slots`]' order) into `into` (cleared first).
    pub(crate) fn data_words(&mut self, into: &mut Vec<u32>) {
        into.clear();
        self.data_slots(&mut |v, _| into.push(*v));
    }

    /// Becomes what `lazy` stands for (`board/io_window.rs`, "The lazy end"): its end moved
    /// back, with its data words.
    pub(crate) fn become_lazy(&mut self, lazy: &LazyEnd) {
        // Not a change of the machine, which was this since its hit: its count stays.
        let touches = self.touches;
        self.become_but_data(&lazy.end.io, lazy.back, &IoRecords::default(), None);
        self.touches = touches;
        let mut i = 0;
        self.data_slots(&mut |v, _| {
            if let Some(&w) = lazy.data.get(i) {
                *v = w;
            }
            i += 1;
        });
    }

    /// The data slot ([`Io::data_slots`]' order) of ADC `adc`'s code of channel `channel`
    /// ([`Ads8688::set_code`]: its slots 0–7); `None` without that ADC or channel.
    pub(crate) fn adc_code_slot(&self, adc: usize, channel: usize) -> Option<usize> {
        (adc < self.adcs.len() && channel < 8)
            .then(|| Self::ADC_SLOTS + adc * Ads8688::SLOTS + channel)
    }

    /// Appends `records` moved by `r`, their codes given by `codes` when some, as a run that
    /// recorded them would.
    fn append_records_coded(&mut self, records: &IoRecords, r: Rebase, codes: Option<RecordCodes>) {
        for (k, (a, frames)) in self.adcs.iter_mut().zip(&records.adcs).enumerate() {
            if a.is_full() {
                continue;
            }
            let routes = codes.map(|c| c.frames.get(k));
            a.append_records(frames.iter().enumerate().map(|(i, f)| {
                AdcFrame {
                    cs_fall: r.at(f.cs_fall),
                    code: match routes {
                        Some(rs) => (rs.and_then(|rs| rs.get(i)))
                            .map_or(f.code, |x| x.eval(codes.map_or(&[], |c| c.inputs)) as u16),
                        None => f.code,
                    },
                    ..f.clone()
                }
            }));
        }
        for (k, (d, updates)) in self.dacs.iter_mut().zip(&records.dacs).enumerate() {
            if d.is_full() {
                continue;
            }
            let routes = codes.map(|c| c.updates.get(k));
            d.append_records(updates.iter().enumerate().map(|(i, u)| {
                DacUpdate {
                    cycle: r.at(u.cycle),
                    code: match routes {
                        Some(rs) => (rs.and_then(|rs| rs.get(i)))
                            .map_or(u.code, |x| x.eval(codes.map_or(&[], |c| c.inputs)) as u16),
                        None => u.code,
                    },
                    ..*u
                }
            }));
        }
    }

    /// Appends `records` (from [`Io::records_since`]) to its parts' records, their cycles
    /// moved by `r`, as a run that recorded them would ([`crate::converters::MAX_KEPT`]).
    pub(crate) fn append_records(&mut self, records: &IoRecords, r: Rebase) {
        for (a, frames) in self.adcs.iter_mut().zip(&records.adcs) {
            a.append_records(frames.iter().map(|f| AdcFrame {
                cs_fall: r.at(f.cs_fall),
                ..f.clone()
            }));
        }
        for (d, updates) in self.dacs.iter_mut().zip(&records.dacs) {
            d.append_records(updates.iter().map(|u| DacUpdate {
                cycle: r.at(u.cycle),
                ..*u
            }));
        }
    }

    /// Whether every part keeps as many frames or updates as it can
    /// ([`Recorded::kept`]): appending more changes nothing.
    pub(crate) fn records_full(&mut self) -> bool {
        self.adcs.iter_mut().all(|a| a.is_full()) && self.dacs.iter_mut().all(|d| d.is_full())
    }

    /// Whether its parts keep their frames and updates (at most
    /// [`crate::converters::MAX_KEPT`] each, the default) or none (for a run that never
    /// reads them: `tactus play` without an I/O trace). Results never depend on it; the
    /// parts' timing violations are kept either way.
    pub fn keep_records(&mut self, on: bool) {
        let max = if on { crate::converters::MAX_KEPT } else { 0 };
        self.adcs.iter_mut().for_each(|a| a.set_kept(max));
        self.dacs.iter_mut().for_each(|d| d.set_kept(max));
    }

    /// Forgets what the last advance found of the cycles ahead ([`Idle`]): a caller that
    /// may change the machine through its public fields.
    pub(crate) fn forget_idle(&mut self) {
        self.idle = Idle(0);
        self.touch();
    }

    /// After the host changed its data words (an ADC's codes: [`crate::Board::set_adc_code`]):
    /// what the last advance found of the cycles ahead no longer holds (an ADC's output
    /// follows its codes), but its control state is as it was, so a period memo still
    /// knows where it is (no touch, unlike [`Io::forget_idle`]).
    pub(crate) fn data_changed(&mut self) {
        self.idle = Idle(0);
    }

    /// The first cycle the machine has not run yet.
    pub fn cycle(&self) -> u64 {
        self.cycle
    }

    /// Whether a state machine is held behind its cycle ([`Io::advance`] without settling).
    pub(crate) fn is_behind(&self) -> bool {
        self.behind != 0
    }

    /// SRAM banks an enabled DMA channel may reach before the next DMA register write.
    pub fn reach_banks(&self) -> u8 {
        self.reach_banks
    }

    /// Whether the DMA's masters win a bank against core `core` (module documentation).
    pub fn dma_wins(&self, core: usize) -> bool {
        let p = self.bus_priority;
        let dma_high = p & priority::DMA_R != 0 && p & priority::DMA_W != 0;
        let core_bit = if core == 0 {
            priority::PROC0
        } else {
            priority::PROC1
        };
        dma_high && p & core_bit == 0
    }

    /// Whether a DMA master claimed `bank` in `cycle`.
    pub(crate) fn dma_claims(&self, bank: usize, cycle: u64) -> bool {
        self.dma_claim[0][bank] == cycle || self.dma_claim[1][bank] == cycle
    }

    /// Whether a core's store to `addr` (one of this machine's registers, [`Io::owns`])
    /// would be taken now: its block is not held in reset.
    pub(crate) fn accepts(&self, addr: u32) -> bool {
        Self::owns(addr) && self.held & Self::reset_bit(addr & !0x3fff) == 0
    }

    /// Whether `addr` (any atomic alias) is one of this machine's registers.
    pub fn owns(addr: u32) -> bool {
        let base = addr & !0x3fff;
        matches!(
            base,
            DMA_BASE | PIO0_BASE | PIO1_BASE | IO_BANK0_BASE | BUSCTRL_BASE
        )
    }

    /// The RESETS bit of the block at `base`.
    fn reset_bit(base: u32) -> u32 {
        match base {
            DMA_BASE => resets::DMA,
            PIO0_BASE => resets::PIO0,
            PIO1_BASE => resets::PIO1,
            IO_BANK0_BASE => resets::IO_BANK0,
            _ => resets::BUSCTRL,
        }
    }

    /// The register at `addr` (any alias) without side effects where reading has some (a
    /// PIO RX FIFO reads 0 here).
    fn peek(&mut self, base: u32, off: u32) -> u32 {
        match base {
            DMA_BASE => self.dma.read(off),
            PIO0_BASE | PIO1_BASE if (0x20..0x30).contains(&off) => 0,
            PIO0_BASE => self.pio[0].read(off),
            PIO1_BASE => self.pio[1].read(off),
            IO_BANK0_BASE => self.gpio_read(off),
            _ => self.busctrl_read(off),
        }
    }

    fn gpio_read(&self, off: u32) -> u32 {
        let n = (off / 8) as usize;
        match (n < GPIOS, off % 8) {
            (true, 4) => self.gpio_ctrl[n],
            // GPIOn_STATUS: OUTTOPAD (bit 9), OETOPAD (13), INFROMPAD (17).
            (true, 0) => {
                let bit = |m: u32| (m >> n) & 1;
                bit(self.pins.0) << 9 | bit(self.pins.1) << 13 | bit(self.gpio_in) << 17
            }
            _ => 0,
        }
    }

    fn busctrl_read(&self, off: u32) -> u32 {
        match off {
            0 => self.bus_priority,
            // BUS_PRIORITY_ACK: the new priorities are in force at once here.
            4 => 1,
            _ => 0,
        }
    }

    /// A core reads the register at `addr` (the machine run up to the access's cycle);
    /// `None` for a block held in reset (a bus fault).
    pub(crate) fn read(&mut self, addr: u32) -> Option<u32> {
        self.idle = Idle(0);
        self.touch();
        let base = addr & !0x3fff;
        if self.held & Self::reset_bit(base) != 0 {
            return None;
        }
        let off = addr & 0xfff;
        Some(match base {
            DMA_BASE => self.dma.read(off),
            PIO0_BASE => self.pio[0].read(off),
            PIO1_BASE => self.pio[1].read(off),
            _ => self.peek(base, off),
        })
    }

    /// A core writes the register at `addr` (any alias); false for a block held in reset.
    pub(crate) fn write(&mut self, addr: u32, value: u32) -> bool {
        self.idle = Idle(0);
        self.touch();
        let base = addr & !0x3fff;
        if self.held & Self::reset_bit(base) != 0 {
            return false;
        }
        let off = addr & 0xfff;
        let value = match (addr >> 12) & 3 {
            0 => value,
            alias => {
                let old = self.peek(base, off);
                match alias {
                    1 => old ^ value,
                    2 => old | value,
                    _ => old & !value,
                }
            }
        };
        match base {
            DMA_BASE => {
                self.dma.write(off, value);
                self.reach_banks = self.dma.reach().fold(0, |m, (a, len)| m | banks_of(a, len));
            }
            PIO0_BASE => self.pio[0].write(off, value),
            PIO1_BASE => self.pio[1].write(off, value),
            IO_BANK0_BASE => {
                self.ahead = None;
                let n = (off / 8) as usize;
                if n < GPIOS && off % 8 == 4 {
                    self.gpio_ctrl[n] = value & 0x3303_331f;
                    self.refresh_funcsel();
                }
            }
            _ => {
                if off == 0 {
                    self.bus_priority = value & 0x1111;
                }
            }
        }
        true
    }

    fn refresh_funcsel(&mut self) {
        self.pio_pins = [0; 2];
        for (n, c) in self.gpio_ctrl.iter().enumerate() {
            match c & 0x1f {
                6 => self.pio_pins[0] |= 1 << n,
                7 => self.pio_pins[1] |= 1 << n,
                _ => {}
            }
        }
    }

    /// RESETS now holds `held` (its RESET register): a block newly put into reset returns
    /// to its reset state.
    pub(crate) fn set_resets(&mut self, held: u32) {
        self.idle = Idle(0);
        self.touch();
        let held = held & IO_RESETS;
        let entering = held & !self.held;
        self.ahead = None;
        if entering & resets::PIO0 != 0 {
            self.pio[0] = Pio::new();
        }
        if entering & resets::PIO1 != 0 {
            self.pio[1] = Pio::new();
        }
        if entering & resets::DMA != 0 {
            self.dma = Dma::new();
            self.reach_banks = 0;
        }
        if entering & resets::IO_BANK0 != 0 {
            self.gpio_ctrl = [FUNCSEL_NULL; GPIOS];
            self.refresh_funcsel();
        }
        if entering & resets::BUSCTRL != 0 {
            self.bus_priority = 0;
        }
        self.held = held;
    }

    /// The pins as the PIOs drive them through IO_BANK0: (levels, directions).
    fn driven(&self) -> (u32, u32) {
        let [m0, m1] = self.pio_pins;
        let (p0, p1) = (&self.pio[0], &self.pio[1]);
        (
            (p0.pin_values() & m0) | (p1.pin_values() & m1),
            (p0.pin_dirs() & m0) | (p1.pin_dirs() & m1),
        )
    }

    /// Shows the converters the pins after `cycle` if they changed.
    fn observe(&mut self, cycle: u64) {
        let now = self.driven();
        if self.lanes.is_some() {
            return self.observe_lanes(cycle, now);
        }
        if now == self.pins {
            return;
        }
        self.pins = now;
        let mut gpio_in = 0;
        for a in &mut self.adcs {
            a.observe(cycle, now.0, now.1);
            gpio_in |= a.gpio_in();
        }
        for d in &mut self.dacs {
            d.observe(cycle, now.0, now.1);
        }
        self.gpio_in = gpio_in;
    }

    /// [`Io::observe`] while lanes are kept, the pins driven `now`: the levels' lanes are
    /// the PIOs' on their pins (also when the levels are as before: the converters, shown
    /// no change of CS or SCLK, do nothing either way), the inputs' the ADCs' SDO lanes.
    fn observe_lanes(&mut self, cycle: u64, now: (u32, u32)) {
        let [m0, m1] = self.pio_pins;
        let out = |p: &Pio| p.lanes.as_ref().map_or(CONST, |l| l.out);
        let pins = lanes::select(m0, &out(&self.pio[0]), &lanes::and(&out(&self.pio[1]), m1));
        let Some(l) = self.lanes.as_deref_mut() else {
            return;
        };
        l.pins = pins;
        if now == self.pins {
            return;
        }
        self.pins = now;
        let mut gpio_in = 0;
        let mut in_lanes = CONST;
        for a in &mut self.adcs {
            a.observe_lanes(cycle, now.0, now.1, &pins);
            gpio_in |= a.gpio_in();
            if let Some(al) = a.lanes.as_deref() {
                let pin = a.pins().sdo as usize & 31;
                if !al.sdo_lane().is_const() {
                    l.clash |= !in_lanes[pin].is_const();
                    in_lanes[pin] = al.sdo_lane();
                }
            }
        }
        for d in &mut self.dacs {
            d.observe_lanes(cycle, now.0, now.1, &pins);
        }
        self.gpio_in = gpio_in;
        l.gpio_in = in_lanes;
    }

    /// Runs the machine through cycle `to − 1` (nothing when it is there already). With
    /// `settle`, everything is then as of that cycle; without, a state machine at the head
    /// of a bit loop that ends later may stay behind, held at its clock ([`Io::behind`]),
    /// when it alone drives its converters and nothing else reads them: what the DMA and
    /// SRAM do is the same either way, and the next advance runs it on.
    pub(crate) fn advance(&mut self, to: u64, mem: &mut Memory, settle: bool) {
        if to > self.cycle || (settle && self.behind != 0) {
            self.touch();
        }
        if self.stepwise {
            debug_assert_eq!(self.behind, 0);
            self.advance_stepwise(to, mem);
        } else {
            self.advance_by_events(to, mem, settle);
        }
    }

    /// [`Io::advance`] a cycle at a time: every cycle the DMA (unless it is quiet), both PIO
    /// blocks and the converters (when a pin changed).
    fn advance_stepwise(&mut self, to: u64, mem: &mut Memory) {
        let wins = [[self.dma_wins(0), self.dma_wins(1)]; 2];
        while self.cycle < to {
            let c = self.cycle;
            let mut port = Port::new(mem, &mut self.pio, &mut self.dma_claim, wins);
            if !self.dma.quiet(&port) {
                self.dma.tick(c, &mut port);
            }
            let gpio_in = self.gpio_in;
            for p in &mut self.pio {
                if let (Some(io), Some(pl)) = (self.lanes.as_deref(), p.lanes.as_deref_mut()) {
                    pl.gpio_in = io.gpio_in;
                }
                p.tick(gpio_in);
            }
            self.observe(c);
            self.cycle = c + 1;
        }
        self.sm_clock = [[self.cycle; 4]; 2];
    }

    /// The GPIO inputs of cycle `x` (what [`Pio::tick`] of that cycle is given) as PIO
    /// block `b` had them, for `x` from two cycles before `start`, the cycle the current
    /// [`Io::advance`] started at, whose synchroniser flops `flops` hold the two before it.
    fn inputs_at(&self, x: u64, start: u64, flops: &[[u32; 2]; 2], b: usize) -> u32 {
        if x.wrapping_add(2) == start {
            return flops[b][1];
        }
        if x.wrapping_add(1) == start {
            return flops[b][0];
        }
        self.sdo_log.iter().fold(0, |m, log| m | level_at(log, x))
    }

    /// Brings state machine `n` of PIO block `b` to cycle `at` (from its clock, over
    /// cycles in which it runs no instruction) and returns its next cycle from there.
    fn sm_resync(&mut self, b: usize, n: usize, at: u64) -> u64 {
        let skipped = at.saturating_sub(self.sm_clock[b][n]);
        self.pio[b].sm_skip(n, skipped);
        self.sm_clock[b][n] = self.sm_clock[b][n].max(at);
        self.sm_next(b, n)
    }

    /// The next cycle state machine `n` of PIO block `b` runs an instruction, from its
    /// state at its clock ([`Pio::sm_idle`]); `u64::MAX` for never.
    fn sm_next(&self, b: usize, n: usize) -> u64 {
        self.pio[b]
            .sm_idle(n)
            .map_or(u64::MAX, |k| self.sm_clock[b][n].saturating_add(k))
    }

    /// Which state machines may run ahead ([`Ahead`]): an enabled state machine whose pins
    /// (as IO_BANK0 gives them to its block) no other enabled one writes; whose
    /// converters (those seeing any of them) see only those pins; which reads no input
    /// another converter drives; and whose converters' outputs no other state machine
    /// reads.
    fn find_ahead(&self) -> Ahead {
        let epochs = [self.pio[0].config_epoch(), self.pio[1].config_epoch()];
        let pins: [[(u32, u32); 4]; 2] = std::array::from_fn(|b| {
            std::array::from_fn(|n| match self.pio[b].enabled(n) {
                true => {
                    let (w, r) = self.pio[b].sm_pins(n);
                    (w & self.pio_pins[b], r)
                }
                false => (0, 0),
            })
        });
        let sdo = |k: usize| 1u32 << self.adcs[k].pins().sdo;
        let mut sm = [[None; 4]; 2];
        for b in 0..2 {
            for n in 0..4 {
                if !self.pio[b].enabled(n) {
                    continue;
                }
                let (w, r) = pins[b][n];
                let others = (0..8)
                    .filter(|&i| i != 4 * b + n)
                    .map(|i| pins[i / 4][i % 4])
                    .fold((0, 0), |(ow, or), (w, r)| (ow | w, or | r));
                if w & others.0 != 0 {
                    continue;
                }
                let mut adcs = 0u32;
                let mut own_sdo = 0u32;
                let mut fits = true;
                for (k, a) in self.adcs.iter().enumerate() {
                    let seen = a.pins().observed();
                    if seen & w != 0 {
                        fits &= seen & !w == 0;
                        adcs |= 1 << k;
                        own_sdo |= sdo(k);
                    }
                }
                let mut dacs = 0u32;
                for (k, d) in self.dacs.iter().enumerate() {
                    let seen = d.pins().observed();
                    if seen & w != 0 {
                        fits &= seen & !w == 0;
                        dacs |= 1 << k;
                    }
                }
                let foreign_sdo = (0..self.adcs.len())
                    .filter(|k| adcs & (1 << k) == 0)
                    .fold(0, |m, k| m | sdo(k));
                if fits && r & foreign_sdo == 0 && others.1 & own_sdo == 0 {
                    sm[b][n] = Some((adcs, dacs, w));
                }
            }
        }
        let mut heads = [[0u32; 4]; 2];
        let mut loops = Vec::new();
        for (b, n) in (0..8).map(|i| (i / 4, i % 4)) {
            let Some((adcs, dacs, _)) = sm[b][n] else {
                continue;
            };
            let clocks = |mask: u32, pins: &mut dyn Iterator<Item = SpiPins>, lp: &BitLoop| {
                pins.enumerate()
                    .filter(|&(k, _)| mask & (1 << k) != 0)
                    .map(|(k, p)| Some((k, lp.clock(p.cs, p.sclk, p.sdi)?)))
                    .collect::<Option<Vec<_>>>()
            };
            for head in 0..32 {
                let Some(lp) = self.pio[b].sm_loop(n, head) else {
                    continue;
                };
                let a = clocks(adcs, &mut self.adcs.iter().map(Ads8688::pins), &lp);
                let d = clocks(dacs, &mut self.dacs.iter().map(Dac8568::pins), &lp);
                if let (Some(adcs), Some(dacs)) = (a, d) {
                    heads[b][n] |= 1 << head;
                    loops.push(LoopPlan {
                        sm: (b, n),
                        lp,
                        adcs,
                        dacs,
                    });
                }
            }
        }
        Ahead {
            epochs,
            sm,
            heads,
            loops,
        }
    }

    /// The GPIO inputs of cycle `x` that matter to a state machine of PIO block `b` which
    /// reads no input but those of the ADCs in `adcs` (bit k: the k-th; the others read
    /// 0), for `x` from two cycles before the cycle the current [`Io::advance`] started at,
    /// whose synchroniser flops are `run.flops` ([`Io::inputs_at`]); from the ADCs' logs
    /// alone for a state machine that was behind (`run.logs`: its reads are from its clock
    /// on, which the logs kept cover).
    fn own_in(&self, adcs: u32, b: usize, x: u64, run: &Run) -> u32 {
        let (start, flops) = (run.start, run.flops);
        if !run.logs && x.wrapping_add(2) <= start.wrapping_add(1) {
            return self.inputs_at(x, start, flops, b);
        }
        let mut m = 0;
        for (k, log) in self.sdo_log.iter().enumerate() {
            if adcs & (1 << k) != 0 {
                m |= level_at(log, x);
            }
        }
        m
    }

    /// When the state machine of `plan`, due at cycle `x` at its bit loop's head, may be
    /// held there behind the machine ([`Io::behind`]) by an advance to `to` that does not
    /// settle: the loop (up to 64 times round, what [`Io::run_loop`] takes in one step)
    /// ends after `to`, it can run as a whole ([`Io::loop_ready`]), none of its `IN`s reads
    /// before `x` (each at least two cycles after the head: the logs kept cover its reads),
    /// and no other ADC drives its ADCs' outputs (`adcs`: those ADCs, bit k the k-th; the
    /// synchroniser flops patched for them stand for them alone): then the loop's end.
    fn may_hold(&self, plan: &LoopPlan, (adcs, own): (u32, u32), x: u64, to: u64) -> Option<u64> {
        let ((b, n), lp) = (plan.sm, &plan.lp);
        let end = x + self.pio[b].sm_loop_left(n).min(64) * lp.period;
        if end <= to || lp.reads().any(|j| lp.at(j) < 2) {
            return None;
        }
        let sdo = |k: usize| self.adcs[k].pins().sdo;
        let shared = (0..self.adcs.len())
            .filter(|&k| adcs & (1 << k) != 0)
            .any(|k| (0..self.adcs.len()).any(|m| m != k && sdo(m) == sdo(k)));
        (!shared && self.loop_ready(plan, own).is_some()).then_some(end)
    }

    /// The pins as `plan`'s converters see them now (levels, directions), when they are
    /// where the plan needs them: its select and clock levels at the loop's entry
    /// ([`LoopClock::holds`]), each part having seen them as they are, and the SCLK rate of
    /// the parts it clocks within their maximum; `None` otherwise. `own`: the pins its
    /// state machine drives.
    fn loop_ready(&self, plan: &LoopPlan, own: u32) -> Option<(u32, u32)> {
        let ((b, _), lp) = (plan.sm, &plan.lp);
        let pio = &self.pio[b];
        let (values, dirs) = (pio.pin_values(), pio.pin_dirs());
        let view = (
            self.pins.0 & !own | values & own,
            self.pins.1 & !own | dirs & own,
        );
        // Each part: its loop clock, pins, whether it has seen the pins as they are, and
        // whether it may be clocked at the loop's period.
        let adcs = plan.adcs.iter().map(|(i, c)| {
            let a = &self.adcs[*i];
            (c, a.pins(), a.sees(view.0, view.1), a.clocks_ok(lp.period))
        });
        let dacs = plan.dacs.iter().map(|(i, c)| {
            let d = &self.dacs[*i];
            (c, d.pins(), d.sees(view.0, view.1), d.clocks_ok(lp.period))
        });
        for (c, p, sees, clocks) in adcs.chain(dacs) {
            let clocked = loop_edges(c, p, view).is_some();
            if !c.holds((p.cs, p.sclk), values) || !sees || (clocked && !clocks) {
                return None;
            }
        }
        Some(view)
    }

    /// Runs the bit loop `plan` (its state machine due at cycle `x` at its head, running
    /// ahead: [`Io::run_ahead`]) as many times round as it goes and as end by cycle `run.to`
    /// (at most 64), with its converters, in one step: the converters take its clock
    /// edges in bulk (`Ads8688::clock_bits`, `Dac8568::clock_bits`) with the data levels
    /// [`Pio::sm_loop_pin`] gives, the ADCs' outputs are logged, the `IN`s read them from
    /// the log as they would one by one, and the state machine takes its times round in
    /// one step ([`Pio::sm_loop_run`]). Exactly what [`Io::run_ahead`] does instruction by
    /// instruction. Returns the cycle it is due next; `None` (nothing done) when it goes no
    /// time round before `run.to`, or when its converters are not where the plan needs them
    /// (a select or clock at another level, a part that has not seen the pins as they are,
    /// an SCLK rate over the part's: then the instructions run one by one and the part
    /// reports it).
    fn run_loop(
        &mut self,
        plan: &LoopPlan,
        (adc_mask, own): (u32, u32),
        x: u64,
        run: &Run,
    ) -> Option<u64> {
        let ((b, n), lp) = (plan.sm, &plan.lp);
        let k = self.pio[b]
            .sm_loop_left(n)
            .min((run.to - x) / lp.period)
            .min(64);
        if k == 0 {
            return None;
        }
        let view = self.loop_ready(plan, own)?;
        let edges = |c: &LoopClock, p: SpiPins| loop_edges(c, p, view);
        // SDI at the fall of each time round.
        let sdi_bits = |pio: &Pio, fall: usize, sdi: u32| match view.1 >> sdi & 1 {
            0 => 0,
            _ => pio.sm_loop_pin(n, lp, k, fall, sdi).unwrap_or(0),
        };
        // Per pin, the ADCs driving it (any: bit 0; two or more: bit 1), and the first rise
        // and SDO levels of the one clocked.
        let mut sdo_pins = [0u8; 32];
        let mut clocked: Option<(u32, u64, u64)> = None;
        for (i, c) in &plan.adcs {
            let p = self.adcs[*i].pins();
            sdo_pins[p.sdo as usize] = (sdo_pins[p.sdo as usize] << 1) | 1;
            let Some((rise, fall)) = edges(c, p) else {
                continue;
            };
            let sdi = sdi_bits(&self.pio[b], fall, p.sdi);
            let first = x + lp.at(rise);
            let a = &mut self.adcs[*i];
            let was = u64::from(a.gpio_in() >> p.sdo);
            let sdo = a.clock_bits(first, lp.at(fall) - lp.at(rise), lp.period, k as u32, sdi);
            // The rises after which SDO differs from before them, in order.
            let mut changes = (sdo ^ (sdo << 1 | was)) & (u64::MAX >> (64 - k));
            while changes != 0 {
                let r = u64::from(changes.trailing_zeros());
                let level = ((sdo >> r) as u32 & 1) << p.sdo;
                log_change(&mut self.sdo_log[*i], first + r * lp.period + 1, level);
                changes &= changes - 1;
            }
            clocked = Some((p.sdo, first, sdo));
        }
        for (i, c) in &plan.dacs {
            let p = self.dacs[*i].pins();
            let Some((_, fall)) = edges(c, p) else {
                continue;
            };
            let sdi = sdi_bits(&self.pio[b], fall, p.sdi);
            self.dacs[*i].clock_bits(x + lp.at(fall), lp.period, k as u32, sdi);
        }
        // What each IN PINS reads: its pin two cycles before, or in the cycle where the
        // synchroniser is bypassed: the level the log gives then, which for the one ADC
        // clocked on that pin after its first rise is the SDO of its last rise before.
        let pin = lp.in_pin;
        let lag = 2 * u64::from(self.pio[b].seen(u32::MAX, 0) >> pin & 1);
        let one = clocked.filter(|&(p, ..)| p == pin && sdo_pins[pin as usize] == 1);
        let mut in_bits = [0u64; LOOP_MAX];
        for j in lp.reads() {
            // The times round from `from` on read after the one ADC's first rise: time
            // round i reads the SDO of rise `(at − first − 1) / period`, which is i + ⌊d /
            // period⌋ for d the first time round's `at − first − 1`: a shifted run of them.
            let mut from = k;
            if let Some((_, first, sdo)) = one {
                let d = (x + lp.at(j)) as i64 - lag as i64 - first as i64 - 1;
                let rise = d.div_euclid(lp.period as i64);
                from = if rise < 0 { rise.unsigned_abs() } else { 0 };
                if from < k {
                    let run = match rise >= 0 {
                        true => sdo.checked_shr(rise as u32),
                        false => sdo.checked_shl(rise.unsigned_abs() as u32),
                    };
                    let mask = (u64::MAX >> (64 - k)) & !((1u64 << from) - 1);
                    in_bits[j] |= run.unwrap_or(0) & mask;
                }
            }
            // The others from the logs.
            for i in 0..from.min(k) {
                let at = (x + i * lp.period + lp.at(j)).wrapping_sub(lag);
                let level = u64::from(self.own_in(adc_mask, b, at, run) >> pin);
                in_bits[j] |= (level & 1) << i;
            }
        }
        self.pio[b].sm_loop_run(n, lp, k, &in_bits);
        let pio = &self.pio[b];
        let (v, d) = (pio.pin_values() & own, pio.pin_dirs() & own);
        self.pins = (self.pins.0 & !own | v, self.pins.1 & !own | d);
        let next = x + k * lp.period;
        self.sm_clock[b][n] = next;
        Some(next)
    }

    /// Runs state machine `n` of PIO block `b`, due at cycle `t`, and the converters that
    /// see its pins ([`Ahead`]: `adcs`, `dacs`), ahead of the rest of the machine: its
    /// instructions one by one ([`Pio::sm_tick`], [`Pio::sm_skip`]), a bit loop's times
    /// round in one step ([`Io::run_loop`]), until one that touches more than itself and
    /// its pins ([`Pio::sm_local`]) or cycle `run.to`. Nothing else sees what it does
    /// meanwhile, nor does anything else change what it does: its pins are its own, what it
    /// reads its converters', and its FIFOs untouched by it. In an advance that does not
    /// settle, it is held at a bit loop's head that ends after `run.to` ([`Io::may_hold`],
    /// [`Io::behind`]). Returns its next cycle (its clock when held).
    fn run_ahead(
        &mut self,
        (b, n): (usize, usize),
        (adcs, dacs, own): (u32, u32, u32),
        t: u64,
        run: &Run,
    ) -> u64 {
        let to = run.to;
        // It reads no input but its own ADCs' (or constant ones: none).
        let own_in = |io: &Io, x: u64| io.own_in(adcs, b, x, run);
        let heads = self.ahead.as_ref().map_or(0, |a| a.heads[b][n]);
        let mut x = t;
        while x < to && self.pio[b].sm_local(n) {
            let pc = self.pio[b].sm_pc(n);
            if heads & (1 << pc) != 0 && self.pio[b].sm_fast(n).is_some() {
                // The plan is the ahead's, which the loop leaves alone.
                let ahead = self.ahead.take();
                let plan = ahead
                    .as_ref()
                    .and_then(|a| a.loops.iter().find(|p| p.sm == (b, n) && p.lp.head == pc));
                let hold = plan.and_then(|p| match run.settle {
                    true => None,
                    false => self.may_hold(p, (adcs, own), x, to),
                });
                if let Some(until) = hold {
                    // Held at the head until an advance reaches the loop's end or settles.
                    self.behind |= 1 << (4 * b + n);
                    self.held_until[b][n] = until;
                    self.ahead = ahead;
                    return x;
                }
                let done = plan.and_then(|p| self.run_loop(p, (adcs, own), x, run));
                self.ahead = ahead;
                if let Some(next) = done {
                    x = next;
                    continue;
                }
            }
            let seen = match self.pio[b].sm_reads_pins(n) {
                true => self.pio[b].seen(own_in(self, x.wrapping_sub(2)), own_in(self, x)),
                false => 0,
            };
            let before = (self.pio[b].pin_values(), self.pio[b].pin_dirs());
            let fast = self.pio[b].sm_fast(n).filter(|&c| x + c <= to);
            match fast {
                Some(c) => {
                    self.pio[b].sm_exec(n, seen);
                    self.sm_clock[b][n] = x + c;
                }
                None => {
                    self.pio[b].sm_tick(1 << n, seen);
                    self.sm_clock[b][n] = x + 1;
                }
            }
            let after = (self.pio[b].pin_values(), self.pio[b].pin_dirs());
            if after != before {
                let (v, d) = (after.0 & own, after.1 & own);
                self.pins = (self.pins.0 & !own | v, self.pins.1 & !own | d);
                let now = self.pins;
                for (k, a) in self.adcs.iter_mut().enumerate() {
                    if adcs & (1 << k) != 0 {
                        let was = a.gpio_in();
                        a.observe(x, now.0, now.1);
                        if a.gpio_in() != was {
                            log_change(&mut self.sdo_log[k], x + 1, a.gpio_in());
                        }
                    }
                }
                for (k, d) in self.dacs.iter_mut().enumerate() {
                    if dacs & (1 << k) != 0 {
                        d.observe(x, now.0, now.1);
                    }
                }
            }
            if let Some(c) = fast {
                x += c;
                continue;
            }
            let Some(k) = self.pio[b].sm_idle(n) else {
                return u64::MAX;
            };
            let next = x + 1 + k;
            let skipped = next.min(to) - (x + 1);
            self.pio[b].sm_skip(n, skipped);
            self.sm_clock[b][n] = x + 1 + skipped;
            x = next;
        }
        x
    }

    /// [`Io::advance`] by events: the next cycle anything can happen is the present one
    /// while the DMA is not quiet ([`Dma::quiet`]: it has a transfer to move or issue),
    /// else the first in which a state machine runs an instruction ([`Io::sm_next`]), and
    /// in that cycle only those state machines run ([`Pio::sm_tick`]); the cycles between
    /// are applied to each state machine when it runs next or at the end ([`Pio::sm_skip`]),
    /// and the synchronisers' flops follow from the inputs' changes ([`Io::sdo_log`]). A
    /// state machine's next cycle stands until it runs, the DMA moves one of its block's
    /// FIFOs, or (for one stalled on a FIFO, whose side-set must already be on the pins)
    /// another state machine of its block changes a pin; the DMA's quietness until the DMA
    /// ticks or a FIFO level changes. A converter sees the pins only when one of its own
    /// changed (its `observe` does nothing otherwise). A state machine that drives its
    /// converters alone runs ahead of the rest with them ([`Io::run_ahead`]).
    fn advance_by_events(&mut self, to: u64, mem: &mut Memory, settle: bool) {
        if self.behind == 0 && to <= self.idle.0 && self.idle.0 != 0 {
            #[cfg(debug_assertions)]
            let slow = check_this_skip().then(|| {
                let mut io = Box::new(self.clone());
                io.idle = Idle(0);
                io.advance_by_events(to, mem, settle);
                io
            });
            self.skip_idle(to);
            #[cfg(debug_assertions)]
            if let Some(slow) = slow {
                assert!(
                    *self == *slow,
                    "an idle advance differs from the run it skips"
                );
            }
            return;
        }
        let wins = [[self.dma_wins(0), self.dma_wins(1)]; 2];
        let start = self.cycle;
        let mut flops = [self.pio[0].sync(), self.pio[1].sync()];
        let epochs = [self.pio[0].config_epoch(), self.pio[1].config_epoch()];
        if self.ahead.as_ref().is_none_or(|a| a.epochs != epochs) {
            self.ahead = Some(std::sync::Arc::new(self.find_ahead()));
        }
        let ahead = self.ahead.as_ref().map_or([[None; 4]; 2], |a| a.sm);
        self.sdo_log.resize_with(self.adcs.len(), Vec::new);
        if to <= start && (self.behind == 0 || !settle) {
            // Nothing to run (a core's access to a bank the DMA may reach, in a cycle the
            // machine has reached already: about half the calls): every state machine's
            // clock is where the last advance left it, at `start` (or behind it, held), and
            // so are the flops.
            debug_assert!(
                (0..8).all(|i| self.behind & (1 << i) != 0 || self.sm_clock[i / 4][i % 4] == start)
            );
            return;
        }
        let to = to.max(start);
        // The ADCs of the state machines held behind keep their logs (from before their
        // clocks); the others' start here.
        let held_adcs = (0..8)
            .filter(|&i| self.behind & (1 << i) != 0)
            .fold(0, |m, i| m | ahead[i / 4][i % 4].map_or(0, |(a, ..)| a));
        for (k, (log, a)) in self.sdo_log.iter_mut().zip(&self.adcs).enumerate() {
            if held_adcs & (1 << k) == 0 {
                log.clear();
                log.push((start, a.gpio_in()));
            }
        }
        let mut next = [[u64::MAX; 4]; 2];
        for (b, nb) in next.iter_mut().enumerate() {
            for (n, x) in nb.iter_mut().enumerate() {
                *x = self.sm_next(b, n);
            }
        }
        // The state machines held behind go on first, from their clocks (before `start`):
        // nothing else sees them, nor changes what they do (`Io::run_ahead`). Then the
        // flops at `start` take their ADCs' outputs as they now are before it.
        let behind = std::mem::take(&mut self.behind);
        if behind != 0 {
            let lens: Vec<usize> = self.sdo_log.iter().map(Vec::len).collect();
            for i in (0..8).filter(|&i| behind & (1 << i) != 0) {
                let (b, n) = (i / 4, i % 4);
                let Some(conv) = ahead[b][n] else {
                    continue;
                };
                if !settle && to < self.held_until[b][n] {
                    // Still inside its loop's span: held on, as it was.
                    self.behind |= 1 << i;
                    next[b][n] = u64::MAX;
                    continue;
                }
                let run = Run {
                    start,
                    to,
                    flops: &flops,
                    settle,
                    logs: true,
                };
                let x = self.run_ahead((b, n), conv, self.sm_clock[b][n], &run);
                next[b][n] = match self.behind & (1 << i) {
                    0 => x,
                    _ => u64::MAX,
                };
            }
            for (k, log) in self.sdo_log.iter().enumerate() {
                if held_adcs & (1 << k) == 0 {
                    continue;
                }
                let pin = 1u32 << self.adcs[k].pins().sdo;
                for (f, c) in [(0, start.wrapping_sub(1)), (1, start.wrapping_sub(2))] {
                    if let Some(&(_, v)) = log[lens[k]..].iter().rev().find(|&&(at, _)| at <= c) {
                        for fb in &mut flops {
                            fb[f] = fb[f] & !pin | v;
                        }
                    }
                }
            }
        }
        let run = Run {
            start,
            to,
            flops: &flops,
            settle,
            logs: false,
        };
        // The DMA's quietness and the FIFO levels it was found at.
        let mut dma_quiet: Option<([u32; 2], bool)> = None;
        // The next cycle anything can happen in, when the run stops before it.
        let mut idle = 0;
        while self.cycle < to {
            let c = self.cycle;
            let levels = [self.pio[0].levels(), self.pio[1].levels()];
            let quiet = match dma_quiet {
                Some((at, q)) if at == levels => q,
                _ => {
                    let port = Port::new(mem, &mut self.pio, &mut self.dma_claim, wins);
                    let q = self.dma.quiet(&port);
                    dma_quiet = Some((levels, q));
                    q
                }
            };
            let t = match quiet {
                false => c,
                true => next
                    .iter()
                    .flatten()
                    .copied()
                    .min()
                    .unwrap_or(u64::MAX)
                    .max(c),
            };
            if t >= to {
                idle = t;
                break;
            }
            if !quiet {
                // The FIFOs are as the cycles before left them: the state machines behind
                // their clocks run no instruction, so move none.
                let mut port = Port::new(mem, &mut self.pio, &mut self.dma_claim, wins);
                self.dma.tick(t, &mut port);
                let touched = port.touched;
                dma_quiet = None;
                for (b, nb) in next.iter_mut().enumerate() {
                    if touched & (1 << b) != 0 {
                        for (n, x) in nb.iter_mut().enumerate() {
                            if self.behind & (1 << (4 * b + n)) == 0 {
                                *x = self.sm_resync(b, n, t);
                            }
                        }
                    }
                }
            }
            for (b, nb) in next.iter_mut().enumerate() {
                let mut mask = 0u8;
                for (n, x) in nb.iter_mut().enumerate() {
                    if *x > t {
                        continue;
                    }
                    let skipped = t - self.sm_clock[b][n];
                    self.pio[b].sm_skip(n, skipped);
                    self.sm_clock[b][n] = t;
                    match ahead[b][n] {
                        Some(conv) if self.pio[b].sm_local(n) => {
                            *x = self.run_ahead((b, n), conv, t, &run);
                            if self.behind & (1 << (4 * b + n)) != 0 {
                                *x = u64::MAX;
                            }
                        }
                        _ => mask |= 1 << n,
                    }
                }
                if mask == 0 {
                    continue;
                }
                let pins = (self.pio[b].pin_values(), self.pio[b].pin_dirs());
                let seen = self.pio[b].seen(
                    self.inputs_at(t.wrapping_sub(2), start, &flops, b),
                    self.inputs_at(t, start, &flops, b),
                );
                self.pio[b].sm_tick(mask, seen);
                let moved = pins != (self.pio[b].pin_values(), self.pio[b].pin_dirs());
                for (n, x) in nb.iter_mut().enumerate() {
                    if mask & (1 << n) != 0 {
                        self.sm_clock[b][n] = t + 1;
                        *x = self.sm_next(b, n);
                    } else if moved && *x == u64::MAX && self.behind & (1 << (4 * b + n)) == 0 {
                        // A FIFO stall holds only while its side-set is on the pins.
                        *x = self.sm_resync(b, n, t + 1);
                    }
                }
            }
            self.observe_changed(t);
            self.cycle = t + 1;
        }
        self.cycle = self.cycle.max(to);
        let end = self.cycle;
        for b in 0..2 {
            for n in 0..4 {
                if self.behind & (1 << (4 * b + n)) != 0 {
                    continue;
                }
                self.held_until[b][n] = 0;
                let skipped = end.saturating_sub(self.sm_clock[b][n]);
                self.pio[b].sm_skip(n, skipped);
                self.sm_clock[b][n] = end;
            }
            let flops = [
                self.inputs_at(end.wrapping_sub(1), start, &flops, b),
                self.inputs_at(end.wrapping_sub(2), start, &flops, b),
            ];
            self.pio[b].set_sync(flops);
        }
        self.gpio_in = self.adc_levels();
        let held_adcs = (0..8)
            .filter(|&i| self.behind & (1 << i) != 0)
            .fold(0, |m, i| m | ahead[i / 4][i % 4].map_or(0, |(a, ..)| a));
        for (k, log) in self.sdo_log.iter_mut().enumerate() {
            if held_adcs & (1 << k) == 0 {
                log.clear();
            }
        }
        self.idle = Idle(if self.behind == 0 { idle } else { 0 });
    }

    /// [`Io::advance_by_events`] to `to` when nothing runs before it ([`Io::idle`], none
    /// held behind): what its run without an event does — every state machine's clock to
    /// `to`, the synchronisers' flops the inputs at `to − 1` and `to − 2` (those at the
    /// start's `− 1` when `to` is the cycle after it), the ADCs' outputs unchanged.
    fn skip_idle(&mut self, to: u64) {
        let start = self.cycle;
        if to <= start {
            return;
        }
        let inputs = self.adc_levels();
        for b in 0..2 {
            for n in 0..4 {
                self.held_until[b][n] = 0;
                let skipped = to.saturating_sub(self.sm_clock[b][n]);
                self.pio[b].sm_skip(n, skipped);
                self.sm_clock[b][n] = to;
            }
            let then = self.pio[b].sync();
            let older = if to == start + 1 { then[0] } else { inputs };
            self.pio[b].set_sync([inputs, older]);
        }
        self.gpio_in = inputs;
        self.cycle = to;
    }

    /// The GPIO input levels the ADCs drive now (their SDO pins).
    fn adc_levels(&self) -> u32 {
        self.adcs.iter().fold(0, |m, a| m | a.gpio_in())
    }

    /// [`Io::observe`] by events: only the converters one of whose pins changed see them;
    /// a change of an ADC's output is logged ([`Io::sdo_log`]).
    fn observe_changed(&mut self, cycle: u64) {
        let now = self.driven();
        if now == self.pins {
            return;
        }
        let changed = (now.0 ^ self.pins.0) | (now.1 ^ self.pins.1);
        self.pins = now;
        for (k, a) in self.adcs.iter_mut().enumerate() {
            if a.pins().observed() & changed != 0 {
                let was = a.gpio_in();
                a.observe(cycle, now.0, now.1);
                if a.gpio_in() != was {
                    log_change(&mut self.sdo_log[k], cycle + 1, a.gpio_in());
                }
            }
        }
        for d in &mut self.dacs {
            if d.pins().observed() & changed != 0 {
                d.observe(cycle, now.0, now.1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tactus_runtime::converters::{ADS8688, DAC8568};

    fn io() -> Io {
        let pins = |b: u32| SpiPins {
            cs: b,
            sclk: b + 1,
            sdi: b + 2,
            sdo: b + 3,
        };
        let config = IoConfig {
            adcs: vec![(&ADS8688, pins(0)), (&ADS8688, pins(4))],
            dacs: vec![(&DAC8568, pins(8))],
        };
        Io::new(&config, 133e6, 100)
    }

    #[test]
    fn a_lazy_end_is_the_machine_with_its_data_words() {
        // A hit's flat list of data words (`board/io_window.rs`, "The lazy end") holds what
        // the machine made from it holds: every word 1 (each slot's width keeps it), but
        // those with no place in the end (an ADC's frame code without a frame) 0.
        let mut live = io();
        let end = EndState::new(io());
        assert_eq!(end.absent.len(), 2, "each ADC's frame code");
        let mut data = Vec::new();
        live.data_words(&mut data);
        data.fill(1);
        let mut lazy = LazyEnd {
            end: std::sync::Arc::new(end),
            back: Rebase { from: 0, to: 0 },
            data,
        };
        lazy.drop_absent();
        live.become_lazy(&lazy);
        let mut made = Vec::new();
        live.data_words(&mut made);
        assert_eq!(made, lazy.data);
        assert_eq!(live.cycle(), lazy.cycle());
    }

    #[test]
    fn each_data_word_is_where_its_slot_says() {
        let mut io = io();
        let mut n = 0u32;
        io.data_slots(&mut |v, _| {
            n += 1;
            *v = n;
        });
        // Every slot read back by number; the one-bit and 16-bit words keep their bits, and
        // the code of a frame under way reads 0 without a frame.
        let mask: Vec<u32> = (0..n as usize)
            .map(|i| match io.locate(i) {
                Some(Slot::Adc(_, 8)) => 0,
                Some(Slot::Adc(_, 10)) => 1,
                Some(Slot::Adc(_, 0..=7)) | Some(Slot::Dac(_, 0..=15)) => 0xffff,
                _ => u32::MAX,
            })
            .collect();
        for (i, m) in mask.iter().enumerate() {
            assert_eq!(io.slot(i), (i as u32 + 1) & m, "slot {i}");
        }
        assert!(io.locate(n as usize).is_none());
        // An ADC's codes where `Board::set_adc_code` writes a lazy end's list.
        for adc in 0..2 {
            for c in 0..8 {
                let at = io.adc_code_slot(adc, c).map(|i| io.locate(i));
                assert_eq!(at, Some(Some(Slot::Adc(adc, c))));
            }
        }
        assert_eq!(
            (io.adc_code_slot(2, 0), io.adc_code_slot(0, 8)),
            (None, None)
        );
        // And set by number, as the visit sees them.
        for i in 0..n as usize {
            io.set_slot(i, 0xdead_0000 | i as u32);
        }
        let mut k = 0usize;
        io.data_slots(&mut |v, _| {
            assert_eq!(*v, (0xdead_0000 | k as u32) & mask[k], "slot {k}");
            k += 1;
        });
        assert_eq!(k, n as usize);
    }

    #[test]
    fn machines_equal_but_for_data_compare_equal() {
        let (mut a, mut b) = (io(), io());
        b.data_slots(&mut |v, _| *v = 0x5a5a_5a5a);
        assert!(a.eq_but_data(&b, Rebase { from: 0, to: 0 }));
        // Cycles compare as the rebase moves them.
        b.rebase(Rebase {
            from: 100,
            to: 1000,
        });
        assert!(!a.eq_but_data(&b, Rebase { from: 0, to: 0 }));
        assert!(a.eq_but_data(
            &b,
            Rebase {
                from: 100,
                to: 1000
            }
        ));
        // A control field differs.
        a.bus_priority = 1;
        assert!(!a.eq_but_data(
            &b,
            Rebase {
                from: 100,
                to: 1000
            }
        ));
    }
}
