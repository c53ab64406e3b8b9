//! What the window replays and the period memo (`accel/io_window/`) need of the I/O
//! machine: its data words named in a fixed order ([`Io::data_slots`]) and located
//! ([`Io::locate`]), the machine compared and taken but for them (its [`ReplayState`]:
//! every field of it and of its parts given its role once, [`replay_state!`];
//! [`Io::become_but_data`]) with its cycles moved to another time base ([`Io::rebase`]),
//! the lanes of its data bits while a replay is recorded ([`Io::start_lanes`],
//! [`Io::stop_lanes`], [`LaneRec`]), checkpoints to undo a window ([`Io::checkpoint`],
//! [`Io::rewind`]), a period memo's end state and the machine a hit leaves behind
//! ([`EndState`], [`LazyEnd`]), and the parts' records of a stretch ([`IoRecords`]).

use super::*;
use crate::replay::{replay_state, Data, ReplayState, Words};

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
pub(super) struct IoLanes {
    /// The levels driven, as the converters saw them last ([`Io::pins`]).
    pub(super) pin_levels: Word,
    /// The levels the converters drive ([`Io::gpio_in`]).
    pub(super) gpio_in: Word,
    /// Two parts drove data onto one pin: no lane says what it reads.
    pub(super) clash: bool,
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
/// (`crate::lanes`, the period memo of `accel/io_window/`).
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
    pub(super) read_lanes: Word,
    pub(super) write_lanes: Word,
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

/// The machine at some moment, to go back to ([`Io::checkpoint`], [`Io::rewind`]).
pub(crate) struct Checkpoint {
    /// The machine then, its parts without their records.
    pub(crate) io: Box<Io>,
    /// Per ADC, then per DAC, its [`Recorded::record_counts`] then.
    pub(super) counts: Vec<[usize; 2]>,
}

/// How a period memo's hit gives its records' codes (`accel/io_window/`): per ADC its
/// frames' routes, per DAC its updates', and the inputs they read.
#[derive(Clone, Copy)]
pub(crate) struct RecordCodes<'a> {
    pub frames: &'a [Vec<lanes::Route>],
    pub updates: &'a [Vec<lanes::Route>],
    pub inputs: &'a [u32],
}

/// A period memo entry's end state (`accel/io_window/`): the machine at [`Rebase::MEMO`]
/// without its records, and its data slots ([`Io::data_slots`]' order) that have no place in
/// it (a word written there is dropped, and reads 0: an ADC's frame code without a frame).
#[derive(Debug)]
pub(crate) struct EndState {
    pub(crate) io: Io,
    pub(super) absent: Vec<u32>,
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

/// A machine left behind by a period memo's hit (`accel/io_window/`, "The lazy end"): the
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

/// The parts' records of a stretch (a period memo's, `accel/io_window/`; a rest period's,
/// `accel/rest.rs`): per ADC its frames, per DAC its updates, in [`IoConfig`] order.
#[derive(Clone, Debug, Default)]
pub(crate) struct IoRecords {
    pub(super) adcs: Vec<Vec<AdcFrame>>,
    pub(super) dacs: Vec<Vec<DacUpdate>>,
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

// The replay's view of the machine ([`ReplayState`]): every field given its role once, the
// parts' in their own declarations (`crate::pio::slots`, `crate::dma`, `crate::converters`).
// `stepwise` is how the live machine runs, `idle` a note to itself, `touches` its count of
// changes. Its data words ([`Io::data_slots`]): its own two, then its parts' in this order.
replay_state! { Io [kept in lanes: IoLanes] {
    data: pin_levels, gpio_in;
    device: pio, dma, adcs, dacs;
    cycles: cycle, dma_claim, sm_clock, sdo_log, held_until;
    same: gpio_ctrl, pio_pins, bus_priority, held, pin_dirs, reach_banks, ahead, behind;
    live: stepwise;
    hint: idle;
    lanes: lanes;
    skip: touches;
} }

impl Io {
    /// Its identity and count of changes but for its data ([`Touches`]): equal between two
    /// moments only if nothing but its data words changed in between.
    pub(crate) fn touches(&self) -> (u64, u64) {
        (self.touches.id, self.touches.n)
    }

    /// Counts a change but for its data.
    pub(super) fn touch(&mut self) {
        self.touches.n += 1;
    }

    /// Starts keeping lanes (`crate::lanes`) for a recorded replay: each data word's are
    /// its own bits, its slot's number the input ([`Io::data_slots`]). Returns the number
    /// of slots (the first input a DMA read takes).
    pub(crate) fn start_lanes(&mut self) -> u32 {
        self.touch();
        self.lanes = Some(Box::new(IoLanes {
            pin_levels: CONST,
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

    /// [`ReplayState::eq_but_data`] the long way, for debug builds' checks of it: both machines
    /// rebased to `r`'s base, their data words zeroed, their records and how many the
    /// parts keep left out (a board that keeps none meets entries recorded where they
    /// were kept: `accel/io_window/`, [`Io::keep_records`]), compared whole; and every
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
            Some(Slot::Io(0)) => self.pin_levels,
            Some(Slot::Io(_)) => self.gpio_in,
            Some(Slot::Pio(b, j)) => Words::get(&self.pio[b], j),
            Some(Slot::Dma(j)) => Words::get(&self.dma, j),
            Some(Slot::Adc(k, j)) => Words::get(&self.adcs[k], j),
            Some(Slot::Dac(k, j)) => Words::get(&self.dacs[k], j),
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
            Some(Slot::Io(0)) => self.pin_levels = v,
            Some(Slot::Io(_)) => self.gpio_in = v,
            Some(Slot::Pio(b, j)) => Words::set(&mut self.pio[b], j, v),
            Some(Slot::Dma(j)) => Words::set(&mut self.dma, j, v),
            Some(Slot::Adc(k, j)) => Words::set(&mut self.adcs[k], j, v),
            Some(Slot::Dac(k, j)) => Words::set(&mut self.dacs[k], j, v),
            None => {}
        }
    }

    /// The first ADC's first data slot ([`Io::data_slots`]' order): the machine's own two,
    /// both PIO blocks', the DMA's.
    pub(super) const ADC_SLOTS: usize = 2 + 2 * Pio::WORDS + Dma::WORDS;

    /// Where its `i`-th data word lies ([`Io::data_slots`]' order: `replay_state!`'s for
    /// `Io`, and each part's [`Words`]).
    pub(crate) fn locate(&self, i: usize) -> Option<Slot> {
        let pio = 2;
        let dma = pio + 2 * Pio::WORDS;
        let adcs = Self::ADC_SLOTS;
        let dacs = adcs + self.adcs.len() * Ads8688::WORDS;
        let end = dacs + self.dacs.len() * Dac8568::WORDS;
        Some(match i {
            _ if i < pio => Slot::Io(i),
            _ if i < dma => Slot::Pio((i - pio) / Pio::WORDS, (i - pio) % Pio::WORDS),
            _ if i < adcs => Slot::Dma(i - dma),
            _ if i < dacs => Slot::Adc((i - adcs) / Ads8688::WORDS, (i - adcs) % Ads8688::WORDS),
            _ if i < end => Slot::Dac((i - dacs) / Dac8568::WORDS, (i - dacs) % Dac8568::WORDS),
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
        mix(u64::from(self.pin_dirs));
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
    /// PIO blocks', the DMA's, the ADCs' and the DACs' (each part's [`Data`], derived with
    /// its [`ReplayState`] by `replay_state!` from the one list of its fields). A period memo
    /// (`accel/io_window/`) compares machines without them, and gives a recorded replay's by
    /// their routes.
    #[inline]
    pub(crate) fn data_slots(&mut self, f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>)) {
        Data::visit(self, None, f);
    }

    /// The machine as it is now, to go back to with [`Io::rewind`] (a window's undo,
    /// `accel/io_window/`): a clone but for the parts' records (frames, updates,
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
    /// cycles moved by `r`: a period memo's key or end state (`accel/io_window/`).
    pub(crate) fn rebased(&mut self, r: Rebase) -> Box<Io> {
        let mut io = self.checkpoint().io;
        io.rebase(r);
        io
    }

    /// Its cycles moved by `r`, its parts' records not (a period memo's key, end state, or
    /// the live machine compared with one: `accel/io_window/`).
    pub(crate) fn rebase(&mut self, r: Rebase) {
        self.touch();
        self.rebase_cycles(r);
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
    /// words its routes give (`accel/io_window/`).
    pub(crate) fn become_but_data(
        &mut self,
        end: &Io,
        r: Rebase,
        records: &IoRecords,
        codes: Option<RecordCodes>,
    ) {
        self.assign_but_data(end);
        self.rebase(r);
        self.append_records_coded(records, r, codes);
    }

    /// Its data words ([`Io::data_slots`]' order) into `into` (cleared first).
    pub(crate) fn data_words(&mut self, into: &mut Vec<u32>) {
        into.clear();
        self.data_slots(&mut |v, _| into.push(*v));
    }

    /// Becomes what `lazy` stands for (`accel/io_window/`, "The lazy end"): its end moved
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
            .then(|| Self::ADC_SLOTS + adc * Ads8688::WORDS + channel)
    }

    /// Appends `records` moved by `r`, their codes given by `codes` when some, as a run that
    /// recorded them would.
    pub(super) fn append_records_coded(
        &mut self,
        records: &IoRecords,
        r: Rebase,
        codes: Option<RecordCodes>,
    ) {
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
        // A hit's flat list of data words (`accel/io_window/`, "The lazy end") holds what
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
    fn each_data_word_has_its_own_lanes_of_its_width() {
        // `replay_state!` pairs each data field with the lanes field of its name: a recording
        // gives every slot its own bits as its lanes (none shared, none missing), as wide as
        // the word; only the FIFOs' empty words are constants.
        let mut io = io();
        let n = io.start_lanes();
        let at: Vec<Option<Slot>> = (0..n as usize).map(|i| io.locate(i)).collect();
        let mut k = 0u32;
        let mut widths = Vec::new();
        io.data_slots(&mut |_, l| {
            let l = l.expect("lanes while recording");
            widths.push(l.len());
            let fifo =
                matches!(at[k as usize], Some(Slot::Pio(_, j)) if j >= 3 && (j - 3) % 20 >= 4);
            for (b, x) in l.iter().enumerate() {
                let want = match fifo {
                    true => Lane::CONST,
                    false => Lane::input(k, b as u32),
                };
                assert_eq!(*x, want, "slot {k} bit {b}");
            }
            k += 1;
        });
        assert_eq!(k, n);
        for (i, w) in widths.iter().enumerate() {
            let want = match at[i] {
                Some(Slot::Adc(_, 0..=8)) | Some(Slot::Dac(_, 0..=15)) => 16,
                Some(Slot::Adc(_, 10)) => 1,
                _ => 32,
            };
            assert_eq!(*w, want, "slot {i}");
        }
        assert!(io.stop_lanes().is_some());
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
