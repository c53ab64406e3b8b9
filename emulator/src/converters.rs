//! The board's SPI converters at the pins (issue 40): the ADC and the DAC that the
//! firmware's PIO drivers clock frames through, modelled edge by edge and checked against
//! their data sheets' timing, the numbers of `tactus_runtime::converters` (one definition
//! of each part). [`Dac8568`] is documented at its type.
//!
//! [`Ads8688`] is TI's 8-channel 16-bit SAR ADC (SBAS582) in SPI mode 1 (CPOL 0, CPHA 1:
//! data launched on SCLK rising edges, latched on falling edges), as its "Data Acquisition
//! Example" gives a frame: CS falling samples the selected channel; the first 16 SCLK
//! falling edges latch the 16-bit command on SDI, which selects the channel of the *next*
//! frame (AUTO_RST restarts the sequence at channel 0, NO_OP advances it in auto mode or
//! keeps the manual channel, MAN_Ch_n selects n); from the 17th rising edge the result of
//! this frame's sample leaves on SDO, MSB first, 32 SCLKs in all. The part powers up on
//! channel 0 in manual mode.
//!
//! Every frame is recorded ([`AdcFrame`]) and every breach of the part's timing is a
//! [`TimingViolation`] naming the cycle and the limit: SCLK faster than `sclk_max_hz`, two
//! CS falling edges closer than `frame_period_min_s` (the 500 kS/s throughput), a result
//! clocked out before `conversion_max_s` has passed since its sample, a frame that is not
//! `frame_bits` SCLKs. A firmware whose frames break the part's timing is an error the
//! emulator reports, not a silent success.
//!
//! The model is pin-level and stepped by its caller: [`Ads8688::observe`] after each system
//! cycle with the pins the RP2040 drives, [`Ads8688::gpio_in`] for the level it drives back.
//! Not modelled: the programmable input ranges and the other register commands (recorded,
//! no effect), SDO's launch delay (the level changes with the edge's cycle), the analogue
//! front end (a channel's code is what [`Ads8688::set_code`] last gave).

use crate::lanes::{self, Fixed, Lane, Word, CONST};
use tactus_runtime::converters::AdcPart;

mod clear;

/// A 16-bit code's lanes (`crate::lanes`), bit 0 first.
pub(crate) type Lanes16 = [Lane; 16];

/// A code of constants.
const CONST16: Lanes16 = [Lane::CONST; 16];

/// An ADC's lanes while a replay is recorded (`crate::lanes`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct AdcLanes {
    codes: [Lanes16; 8],
    /// The code of the frame under way.
    frame: Lanes16,
    shift_in: Word,
    sdo: Lane,
    /// The level on SDI at the pins, as [`Ads8688::observe_lanes`] was last given it.
    sdi: Lane,
    /// The codes of the frames recorded since the lanes were started, in order.
    pub(crate) frames: Vec<Lanes16>,
    /// The lanes data decided something with.
    pub(crate) fixed: Vec<Fixed>,
}

impl AdcLanes {
    /// The lane of the level it drives on SDO.
    pub(crate) fn sdo_lane(&self) -> Lane {
        self.sdo
    }
}

/// A DAC's lanes while a replay is recorded (`crate::lanes`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct DacLanes {
    input: [Lanes16; 8],
    output: [Lanes16; 8],
    shift: Word,
    sdi: Lane,
    /// The codes of the updates recorded since the lanes were started, in order.
    pub(crate) updates: Vec<Lanes16>,
    /// The lanes data decided something with.
    pub(crate) fixed: Vec<Fixed>,
}

/// A part's SPI lines seen with their lanes `l` (levels of the pins driven `values` on
/// `dirs`): CS and SCLK decide edges, so their lanes are fixed into `fixed`; returns SDI's
/// lane (an undriven SDI reads low, a constant).
fn spi_lanes(pins: &SpiPins, values: u32, dirs: u32, l: &Word, fixed: &mut Vec<Fixed>) -> Lane {
    let mut w = *l;
    let edges = (1 << pins.cs | 1 << pins.sclk) & dirs;
    lanes::fix(&mut w, values, edges, fixed);
    match dirs >> pins.sdi & 1 {
        0 => Lane::CONST,
        _ => w[pins.sdi as usize & 31],
    }
}

/// The pins of an SPI converter (GPIO numbers, 0–29).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpiPins {
    /// Chip select, active low (CS on the ADS8688, SYNC on the DAC8568).
    pub cs: u32,
    /// Serial clock.
    pub sclk: u32,
    /// Data into the part (the RP2040's MOSI).
    pub sdi: u32,
    /// Data out of the part (the RP2040's MISO); unused by a DAC.
    pub sdo: u32,
}

impl SpiPins {
    /// The pins whose levels and directions the part sees (CS, SCLK, SDI): nothing else
    /// at the pins changes what it does.
    pub fn observed(&self) -> u32 {
        1 << self.cs | 1 << self.sclk | 1 << self.sdi
    }
}

/// The select and clock levels an SPI part saw last, from which [`SpiLines::edges`] finds
/// the edges of the next cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct SpiLines {
    cs_low: bool,
    sclk_high: bool,
}

/// The edges an SPI part sees in one cycle, and its SDI level then.
struct Edges {
    cs_fell: bool,
    cs_rose: bool,
    /// SCLK edges count only while the part is selected.
    sclk_rose: bool,
    sclk_fell: bool,
    sdi: bool,
}

impl SpiLines {
    /// The select and clock levels of `pins` given the driven `values` and `dirs` (as
    /// [`SpiLines::edges`] reads them).
    fn of(pins: &SpiPins, values: u32, dirs: u32) -> SpiLines {
        let level = |p: u32| values & dirs & (1 << p) != 0;
        SpiLines {
            cs_low: dirs & (1 << pins.cs) != 0 && !level(pins.cs),
            sclk_high: level(pins.sclk),
        }
    }

    /// Whether the pins driven `values` and `dirs` are where a part on `pins` that saw
    /// `self` last saw them: then they show it no edge.
    fn sees(&self, pins: &SpiPins, values: u32, dirs: u32) -> bool {
        *self == SpiLines::of(pins, values, dirs)
    }

    /// The edges on `pins` given the levels the RP2040 drives (`values`) on the pins it
    /// drives (`dirs`): an undriven CS reads high (the board's pull-up keeps the part
    /// deselected while the RP2040 boots), an undriven SCLK or SDI low.
    fn edges(&mut self, pins: &SpiPins, values: u32, dirs: u32) -> Edges {
        let level = |p: u32| values & dirs & (1 << p) != 0;
        let SpiLines { cs_low, sclk_high } = SpiLines::of(pins, values, dirs);
        let e = Edges {
            cs_fell: cs_low && !self.cs_low,
            cs_rose: !cs_low && self.cs_low,
            sclk_rose: cs_low && sclk_high && !self.sclk_high,
            sclk_fell: cs_low && !sclk_high && self.sclk_high,
            sdi: level(pins.sdi),
        };
        *self = SpiLines { cs_low, sclk_high };
        e
    }
}

/// The SCLK rate of edges `cycles` apart on a system clocked at `clock_hz`, when it is over
/// `max_hz`.
fn sclk_too_fast(clock_hz: f64, max_hz: f64, cycles: u64) -> Option<f64> {
    let hz = clock_hz / cycles as f64;
    (hz > max_hz).then_some(hz)
}

/// One frame the ADC saw, CS low to CS high.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdcFrame {
    /// The system cycle of its CS falling edge (the sample instant).
    pub cs_fall: u64,
    /// The channel it sampled.
    pub channel: u8,
    /// The code it sampled (sent in this frame's last 16 SCLKs).
    pub code: u16,
    /// The 16-bit command latched on SDI (0 when the frame had fewer than 16 SCLKs).
    pub command: u16,
    /// The SCLK rising edges it had.
    pub sclks: u32,
}

impl AdcFrame {
    /// The level SDO shows after the frame's `sclks`-th rise, of a `frame_bits`-SCLK frame:
    /// rises 17…32 (of 32) launch the code, MSB first; low otherwise.
    fn sdo(&self, frame_bits: u32) -> bool {
        let half = frame_bits / 2;
        self.sclks > half
            && self.sclks <= frame_bits
            && (self.code >> (frame_bits - self.sclks)) & 1 != 0
    }
}

/// The low `n` bits of `sdi` (1 ≤ n ≤ 64), bit 0 the first latched, as a shift register
/// holds them after `n` shifts: bit 0 the most significant (the bulk clocking of
/// [`Ads8688::clock_bits`] and [`Dac8568::clock_bits`]).
fn msb_first(sdi: u64, n: u32) -> u64 {
    (sdi & (u64::MAX >> (64 - n))).reverse_bits() >> (64 - n)
}

/// A breach of a converter's data-sheet timing.
#[derive(Clone, Debug, PartialEq)]
pub struct TimingViolation {
    /// The system cycle it was seen at.
    pub cycle: u64,
    /// What was breached, with the measured value and the limit.
    pub what: String,
}

/// The ADS8688 at the pins. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct Ads8688 {
    part: &'static AdcPart,
    pins: SpiPins,
    clock_hz: f64,
    /// The code each channel reads.
    codes: [u16; 8],
    /// The channel the next frame samples; whether the sequencer advances on NO_OP.
    next: u8,
    auto: bool,
    /// CS and SCLK as last seen.
    lines: SpiLines,
    /// The level it drives on SDO.
    sdo: bool,
    /// The frame under way.
    frame: Option<AdcFrame>,
    falling: u32,
    shift_in: u32,
    last_rise: Option<u64>,
    last_cs_fall: Option<u64>,
    frames: Vec<AdcFrame>,
    violations: Vec<TimingViolation>,
    /// The most frames it keeps ([`MAX_KEPT`], or 0: [`Recorded::set_kept`]).
    kept: usize,
    /// Its lanes while a replay is recorded (`crate::lanes`); `None` otherwise.
    pub(crate) lanes: Option<Box<AdcLanes>>,
}

/// A part's records — frames or updates, and timing violations — which only grow until
/// the host drains them: a checkpoint of the I/O ([`crate::io::Io::checkpoint`]) keeps their
/// counts instead of copying them.
pub(crate) trait Recorded: Clone {
    /// What it records besides violations.
    type Item: Clone;

    /// Its records.
    fn records(&mut self) -> (&mut Vec<Self::Item>, &mut Vec<TimingViolation>);

    /// The most frames or updates it keeps.
    fn kept(&self) -> usize;

    /// Keeps at most `max` frames or updates from now on ([`MAX_KEPT`] at most; 0: none,
    /// for a run that never reads them). Timing violations are kept as before.
    fn set_kept(&mut self, max: usize);

    /// Whether it keeps no more frames or updates ([`Recorded::kept`] of them already).
    fn is_full(&mut self) -> bool {
        let max = self.kept();
        self.records().0.len() >= max
    }

    /// How many of each it has recorded.
    fn record_counts(&mut self) -> [usize; 2] {
        let (items, violations) = self.records();
        [items.len(), violations.len()]
    }

    /// A clone without its records.
    fn without_records(&mut self) -> Self {
        let (items, violations) = self.records();
        let kept = (std::mem::take(items), std::mem::take(violations));
        let copy = self.clone();
        let (items, violations) = self.records();
        (*items, *violations) = kept;
        copy
    }

    /// The records after the first `counts` ([`Recorded::record_counts`]), or `None` when
    /// a violation is among them.
    fn records_since(&mut self, counts: [usize; 2]) -> Option<Vec<Self::Item>> {
        let (items, violations) = self.records();
        (violations.len() == counts[1]).then(|| items[counts[0].min(items.len())..].to_vec())
    }

    /// Its records, taken out (for debug builds' `Io::check_eq_but_data`).
    #[cfg(debug_assertions)]
    fn take_records(&mut self) -> (Vec<Self::Item>, Vec<TimingViolation>) {
        let (items, violations) = self.records();
        (std::mem::take(items), std::mem::take(violations))
    }

    /// Appends `items` to its records as a run that recorded them would ([`MAX_KEPT`]).
    fn append_records(&mut self, items: impl IntoIterator<Item = Self::Item>) {
        let max = self.kept();
        let (list, _) = self.records();
        // Past its most nothing is kept: the items are not even made.
        for i in items.into_iter().take(max.saturating_sub(list.len())) {
            list.push(i);
        }
    }

    /// Back to `then` (from [`Recorded::without_records`]), its records those of now cut
    /// to `counts` ([`Recorded::record_counts`] then).
    fn rewind(&mut self, then: Self, counts: [usize; 2]) {
        let (items, violations) = self.records();
        let (mut items, mut violations) = (std::mem::take(items), std::mem::take(violations));
        items.truncate(counts[0]);
        violations.truncate(counts[1]);
        *self = then;
        let (i, v) = self.records();
        (*i, *v) = (items, violations);
    }
}

/// The most frames, updates and violations kept (a bound on what a long run holds).
pub const MAX_KEPT: usize = 1 << 16;

/// Appends `item` to `list` while it holds fewer than [`MAX_KEPT`].
fn keep<T>(list: &mut Vec<T>, item: T) {
    if list.len() < MAX_KEPT {
        list.push(item);
    }
}

// The replay's view of the parts ([`crate::replay::ReplayState`]): every field given its
// role once. Their records (frames, updates, breaches), which only grow, are not state.
// Their data words (`crate::io::Io::data_slots`), in order: an ADC's eight channels' codes,
// the code of the frame under way (0 without one), the command shifting in, the SDO level;
// a DAC's eight input registers, its eight output registers, the frame shifting in.
crate::replay::replay_state! { Ads8688 [kept in lanes: AdcLanes, words] {
    same: part, pins, clock_hz, next, auto, lines, falling;
    cycles: last_rise, last_cs_fall;
    data: codes;
    part: frame;
    data: shift_in, sdo;
    lanes: lanes;
    skip: frames, violations, kept;
} }

crate::replay::replay_state! { Dac8568 [kept in lanes: DacLanes, words] {
    same: part, pins, clock_hz, lines, bits;
    cycles: sync_fell, sync_rose, last_fall;
    data: input, output, shift;
    lanes: lanes;
    skip: updates, violations, kept;
} }

/// The frame under way: its code a data word (a live frame's stays on assignment, 0 where
/// there was none), its CS fall a cycle.
impl crate::replay::ReplayState for Option<AdcFrame> {
    fn eq_but_data(&self, other: &Self, r: crate::replay::Rebase) -> bool {
        match (self, other) {
            (None, None) => true,
            (Some(a), Some(b)) => {
                r.at(a.cs_fall) == b.cs_fall
                    && a.channel == b.channel
                    && a.command == b.command
                    && a.sclks == b.sclks
            }
            _ => false,
        }
    }
    fn assign_but_data(&mut self, other: &Self) {
        let code = self.as_ref().map_or(0, |f| f.code);
        *self = other.clone().map(|f| AdcFrame { code, ..f });
    }
    fn rebase_cycles(&mut self, r: crate::replay::Rebase) {
        if let Some(f) = self {
            f.cs_fall = r.at(f.cs_fall);
        }
    }
}

/// The code of the frame under way: a data word that reads 0 without a frame, where a
/// word written is dropped.
impl crate::replay::Data for Option<AdcFrame> {
    type Lanes = Lanes16;
    #[inline]
    fn visit(
        &mut self,
        lanes: Option<&mut Lanes16>,
        f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>),
    ) {
        let mut v = crate::replay::Words::get(self, 0);
        f(&mut v, lanes.map(|l| &mut l[..]));
        crate::replay::Words::set(self, 0, v);
    }
}

impl crate::replay::Words for Option<AdcFrame> {
    const WORDS: usize = 1;
    #[inline]
    fn get(&self, _: usize) -> u32 {
        self.as_ref().map_or(0, |f| u32::from(f.code))
    }
    #[inline]
    fn set(&mut self, _: usize, v: u32) {
        if let Some(f) = self {
            f.code = v as u16;
        }
    }
}

impl Recorded for Ads8688 {
    type Item = AdcFrame;
    fn kept(&self) -> usize {
        self.kept
    }
    fn set_kept(&mut self, max: usize) {
        self.kept = max.min(MAX_KEPT);
    }
    fn records(&mut self) -> (&mut Vec<AdcFrame>, &mut Vec<TimingViolation>) {
        (&mut self.frames, &mut self.violations)
    }
}

impl Ads8688 {
    /// An ADC of `part` (its timing limits) on `pins`, on a system clocked at `clock_hz`,
    /// every channel reading code 0.
    pub fn new(part: &'static AdcPart, pins: SpiPins, clock_hz: f64) -> Self {
        Ads8688 {
            part,
            pins,
            clock_hz,
            codes: [0; 8],
            next: 0,
            auto: false,
            lines: SpiLines::default(),
            sdo: false,
            frame: None,
            falling: 0,
            shift_in: 0,
            last_rise: None,
            last_cs_fall: None,
            frames: Vec::new(),
            violations: Vec::new(),
            kept: MAX_KEPT,
            lanes: None,
        }
    }

    /// Sets the code `channel` (0–7; others are ignored) reads from now on.
    pub fn set_code(&mut self, channel: usize, code: u16) {
        if let Some(c) = self.codes.get_mut(channel) {
            *c = code;
        }
    }

    /// Its pins.
    pub fn pins(&self) -> SpiPins {
        self.pins
    }

    /// The GPIO input levels the part drives (its SDO pin), to OR into the RP2040's inputs.
    pub fn gpio_in(&self) -> u32 {
        u32::from(self.sdo) << self.pins.sdo
    }

    /// The frames seen so far (at most [`MAX_KEPT`]).
    pub fn frames(&self) -> &[AdcFrame] {
        &self.frames
    }

    /// The timing breaches seen so far (at most [`MAX_KEPT`]).
    pub fn violations(&self) -> &[TimingViolation] {
        &self.violations
    }

    /// The frames seen since the last call (at most [`MAX_KEPT`]), removed: a long run's
    /// trace drains them as it goes.
    pub fn take_frames(&mut self) -> Vec<AdcFrame> {
        std::mem::take(&mut self.frames)
    }

    fn violate(&mut self, cycle: u64, what: String) {
        keep(&mut self.violations, TimingViolation { cycle, what });
    }

    fn seconds(&self, cycles: u64) -> f64 {
        cycles as f64 / self.clock_hz
    }

    /// Starts keeping lanes (`crate::lanes`), all constants (`crate::io::Io` gives its
    /// data words theirs through [`crate::replay::Data`]).
    pub(crate) fn start_lanes(&mut self) {
        self.lanes = Some(Box::new(AdcLanes {
            codes: [CONST16; 8],
            frame: CONST16,
            shift_in: CONST,
            sdo: Lane::CONST,
            sdi: Lane::CONST,
            frames: Vec::new(),
            fixed: Vec::new(),
        }));
    }

    /// [`Ads8688::observe`] with the lanes of the pins' levels, `l`, while lanes are kept.
    pub(crate) fn observe_lanes(&mut self, cycle: u64, values: u32, dirs: u32, l: &Word) {
        if let Some(a) = self.lanes.as_deref_mut() {
            a.sdi = spi_lanes(&self.pins, values, dirs, l, &mut a.fixed);
        }
        self.observe(cycle, values, dirs);
    }

    /// Sees the pins after system cycle `cycle`: `values` the levels the RP2040 drives and
    /// `dirs` the pins it drives (bit n: GPIO n). An undriven CS reads high (the board's
    /// pull-up), an undriven SCLK or SDI low.
    pub fn observe(&mut self, cycle: u64, values: u32, dirs: u32) {
        let e = self.lines.edges(&self.pins, values, dirs);
        if e.cs_fell {
            self.cs_fall(cycle);
        }
        if e.cs_rose {
            self.cs_rise(cycle);
        }
        if e.sclk_rose {
            self.rise(cycle, true);
        }
        if e.sclk_fell {
            self.fall(e.sdi);
        }
    }

    /// Whether the pins driven `values` and `dirs` (as [`Ads8688::observe`] takes them) are
    /// where it saw them last: then they show it no edge.
    pub fn sees(&self, values: u32, dirs: u32) -> bool {
        self.lines.sees(&self.pins, values, dirs)
    }

    /// The SCLK rate of rises `cycles` apart, when it is over the part's maximum.
    fn sclk_too_fast(&self, cycles: u64) -> Option<f64> {
        sclk_too_fast(self.clock_hz, self.part.sclk_max_hz, cycles)
    }

    /// Whether [`Ads8688::clock_bits`] may clock the frame under way with rises `period`
    /// cycles apart: the part selected with SCLK low as it last saw them, and that rate
    /// within its maximum.
    pub fn clocks_ok(&self, period: u64) -> bool {
        self.lines.cs_low
            && !self.lines.sclk_high
            && self.frame.is_some()
            && self.sclk_too_fast(period).is_none()
    }

    /// `k` SCLK periods (1 ≤ k ≤ 64) of the frame under way, CS low throughout: a rise at
    /// `first + i·period` and a fall `fall` cycles later (0 < fall < period) latching bit
    /// i of `sdi`, for i in 0..k. Exactly what [`Ads8688::observe`] does with them edge by
    /// edge (the rate checked once for the equal periods: [`Ads8688::clocks_ok`], which
    /// must hold); returns the level it drives on SDO after each rise (bit i: the i-th).
    pub fn clock_bits(&mut self, first: u64, fall: u64, period: u64, k: u32, sdi: u64) -> u64 {
        debug_assert!(self.clocks_ok(period) && (1..=64).contains(&k) && fall < period);
        debug_assert!(self.lanes.is_none(), "lanes are kept edge by edge only");
        let (half, bits) = (self.part.frame_bits / 2, self.part.frame_bits);
        // The rises, then the falls: a rise reads only the frame's count and code, which no
        // fall writes, and a fall only the frame's channel, which no rise writes, so the
        // two interleaved (as the edges come) and apart give the same.
        let mut sdo = 0u64;
        let mut i = 0;
        while i < k {
            let f = match self.frame.as_mut() {
                // Rises that check nothing (not the first, whose rate is checked against
                // the last rise before, nor the result's first, which checks the
                // conversion), up to the next that does or the run's end, at once:
                // `rise`'s count and SDO — low up to the frame's half, then the code's
                // bits, most significant first, low past the frame's end.
                Some(f) if i > 0 && f.sclks != half => f,
                _ => {
                    self.rise(first + u64::from(i) * period, i == 0);
                    sdo |= u64::from(self.sdo) << i;
                    i += 1;
                    continue;
                }
            };
            let s0 = f.sclks;
            let m = match s0 < half {
                true => (half - s0).min(k - i),
                false => k - i,
            };
            // The code's bits the rises after the half launch: bit j of the stretch is
            // the code's bit `bits − s0 − 1 − j` while that is one.
            let left = bits.saturating_sub(s0).min(64);
            let n = left.min(m);
            if s0 > half && n > 0 {
                let code = u64::from(f.code) & (u64::MAX >> (64 - left));
                sdo |= (msb_first(code, left) & (u64::MAX >> (64 - n))) << i;
            }
            f.sclks += m;
            self.sdo = f.sdo(bits);
            i += m;
        }
        // The falls: the command's bits that remain taken at once (the first latched the
        // most significant), as `fall` takes them one by one; the ones after it change
        // nothing.
        let n = k.min(half.saturating_sub(self.falling));
        if n > 0 {
            let bits = msb_first(sdi, n);
            self.shift_in = ((u64::from(self.shift_in) << n) | bits) as u32;
            self.falling += n;
            if self.falling == half {
                self.command_latched();
            }
        }
        self.last_rise = Some(first + u64::from(k - 1) * period);
        sdo
    }

    fn cs_fall(&mut self, cycle: u64) {
        if let Some(prev) = self.last_cs_fall {
            let t = self.seconds(cycle - prev);
            if t < self.part.frame_period_min_s {
                self.violate(
                    cycle,
                    format!(
                        "{}: CS falling edges {:.3} µs apart, under the {:.3} µs of its {:.0} kS/s",
                        self.part.name,
                        t * 1e6,
                        self.part.frame_period_min_s * 1e6,
                        1e-3 / self.part.frame_period_min_s
                    ),
                );
            }
        }
        self.last_cs_fall = Some(cycle);
        let channel = self.next;
        self.frame = Some(AdcFrame {
            cs_fall: cycle,
            channel,
            code: self.codes[channel as usize],
            command: 0,
            sclks: 0,
        });
        self.falling = 0;
        self.shift_in = 0;
        self.last_rise = None;
        self.sdo = false;
        if let Some(l) = self.lanes.as_deref_mut() {
            l.frame = l.codes[channel as usize & 7];
            l.shift_in = CONST;
            l.sdo = Lane::CONST;
        }
    }

    fn cs_rise(&mut self, cycle: u64) {
        self.sdo = false;
        // The frame is kept (and its code's lanes with it) while there is room.
        let room = !self.is_full();
        if let Some(l) = self.lanes.as_deref_mut() {
            l.sdo = Lane::CONST;
            if self.frame.is_some() && room {
                l.frames.push(l.frame);
            }
        }
        if let Some(f) = self.frame.take() {
            if f.sclks != self.part.frame_bits {
                self.violate(
                    cycle,
                    format!(
                        "{}: a frame of {} SCLKs, not {}",
                        self.part.name, f.sclks, self.part.frame_bits
                    ),
                );
            }
            if room {
                self.frames.push(f);
            }
        }
    }

    /// An SCLK rise at `cycle`; its rate checked against the last with `check_rate` (else
    /// known to be within it).
    fn rise(&mut self, cycle: u64, check_rate: bool) {
        let Some(mut f) = self.frame.take() else {
            return;
        };
        if let Some(prev) = self.last_rise.filter(|_| check_rate) {
            if let Some(hz) = self.sclk_too_fast(cycle - prev) {
                self.violate(
                    cycle,
                    format!(
                        "{}: SCLK at {:.2} MHz, over its {:.2} MHz",
                        self.part.name,
                        hz / 1e6,
                        self.part.sclk_max_hz / 1e6
                    ),
                );
            }
        }
        self.last_rise = Some(cycle);
        f.sclks += 1;
        // The result's first rise: the conversion must be over.
        if f.sclks == self.part.frame_bits / 2 + 1 {
            let t = self.seconds(cycle - f.cs_fall);
            if t < self.part.conversion_max_s {
                self.violate(
                    cycle,
                    format!(
                        "{}: result clocked out {:.0} ns after its sample, before the {:.0} ns conversion",
                        self.part.name,
                        t * 1e9,
                        self.part.conversion_max_s * 1e9
                    ),
                );
            }
        }
        self.sdo = f.sdo(self.part.frame_bits);
        if let Some(l) = self.lanes.as_deref_mut() {
            // The code's bit that `AdcFrame::sdo` shows, or a constant low.
            let bits = self.part.frame_bits;
            let half = bits / 2;
            l.sdo = match f.sclks > half && f.sclks <= bits {
                true => (l.frame.get((bits - f.sclks) as usize)).map_or(Lane::CONST, |x| *x),
                false => Lane::CONST,
            };
        }
        self.frame = Some(f);
    }

    fn fall(&mut self, sdi: bool) {
        let half = self.part.frame_bits / 2;
        if self.falling < half {
            if let Some(l) = self.lanes.as_deref_mut() {
                l.shift_in = lanes::shl(&l.shift_in, 1);
                l.shift_in[0] = l.sdi;
            }
            self.shift_in = self.shift_in << 1 | u32::from(sdi);
            self.falling += 1;
            if self.falling == half {
                self.command_latched();
            }
        }
    }

    /// The frame's command is in (its `frame_bits / 2`-th fall): the frame keeps it and the
    /// part obeys it.
    fn command_latched(&mut self) {
        let command = self.shift_in as u16;
        if let Some(l) = self.lanes.as_deref_mut() {
            // The part obeys it: what it selects depends on its bits.
            lanes::fix(&mut l.shift_in, self.shift_in, 0xffff, &mut l.fixed);
        }
        if let Some(f) = self.frame.as_mut() {
            f.command = command;
        }
        self.command(command);
    }

    /// The command register (SBAS582, "Command Register Description"): AUTO_RST 0xA000,
    /// MAN_Ch_n 0xC000 + n·0x400, NO_OP 0x0000; the others leave the channel as it is.
    fn command(&mut self, command: u16) {
        let current = self.frame.as_ref().map_or(self.next, |f| f.channel);
        match command {
            0xa000 => {
                self.auto = true;
                self.next = 0;
            }
            0x0000 if self.auto => self.next = (current + 1) % self.part.channels.clamp(1, 8) as u8,
            0x0000 => self.next = current,
            c if c & 0xe000 == 0xc000 && c & 0x3ff == 0 => {
                self.auto = false;
                self.next = ((c >> 10) & 7) as u8;
            }
            _ => {}
        }
    }
}

/// One DAC output change: the channel's output register took `code` at `cycle`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DacUpdate {
    /// The system cycle of the frame's 32nd SCLK falling edge.
    pub cycle: u64,
    /// The channel (0–7, A–H).
    pub channel: u8,
    /// Its new code (straight binary).
    pub code: u16,
}

/// The DAC8568 at the pins: TI's 8-channel 16-bit DAC (SBAS430F), SPI with data latched on
/// SCLK falling edges, 32-bit frames (8.2.6: prefix DB31–28, control DB27–24, address
/// DB23–20, data DB19–4, feature bits DB3–0). Modelled controls: 0000 write input register
/// n, 0001 update DAC register n from its input register, 0010 write input register n and
/// update all, 0011 write and update n; address 1111 is every channel. A write takes effect
/// on the 32nd falling edge; SYNC rising before it abandons the frame (a violation). The
/// outputs power up at midscale (the DAC8568's B and D grades; with the board's
/// transconductance amplifier centred there, 0 A). Timing checked against
/// `tactus_runtime::converters::DAC8568`: SCLK ≤ 50 MHz, SYNC high ≥ 80 ns between frames,
/// SYNC falling to the first SCLK falling edge ≥ 13 ns. Not modelled: LDAC, CLR, power
/// down, the internal reference and the other controls (recorded, no effect).
#[derive(Clone, Debug, PartialEq)]
pub struct Dac8568 {
    part: &'static tactus_runtime::converters::DacPart,
    pins: SpiPins,
    clock_hz: f64,
    input: [u16; 8],
    output: [u16; 8],
    lines: SpiLines,
    bits: u32,
    shift: u32,
    sync_fell: Option<u64>,
    sync_rose: Option<u64>,
    last_fall: Option<u64>,
    updates: Vec<DacUpdate>,
    violations: Vec<TimingViolation>,
    /// The most updates it keeps ([`MAX_KEPT`], or 0: [`Recorded::set_kept`]).
    kept: usize,
    /// Its lanes while a replay is recorded (`crate::lanes`); `None` otherwise.
    pub(crate) lanes: Option<Box<DacLanes>>,
}

impl Recorded for Dac8568 {
    type Item = DacUpdate;
    fn kept(&self) -> usize {
        self.kept
    }
    fn set_kept(&mut self, max: usize) {
        self.kept = max.min(MAX_KEPT);
    }
    fn records(&mut self) -> (&mut Vec<DacUpdate>, &mut Vec<TimingViolation>) {
        (&mut self.updates, &mut self.violations)
    }
}

impl Dac8568 {
    /// A DAC of `part` on `pins` (its `sdo` unused), on a system clocked at `clock_hz`,
    /// every output at midscale.
    pub fn new(
        part: &'static tactus_runtime::converters::DacPart,
        pins: SpiPins,
        clock_hz: f64,
    ) -> Self {
        Dac8568 {
            part,
            pins,
            clock_hz,
            input: [0x8000; 8],
            output: [0x8000; 8],
            lines: SpiLines::default(),
            bits: 0,
            shift: 0,
            sync_fell: None,
            sync_rose: None,
            last_fall: None,
            updates: Vec::new(),
            violations: Vec::new(),
            kept: MAX_KEPT,
            lanes: None,
        }
    }

    /// Its pins.
    pub fn pins(&self) -> SpiPins {
        self.pins
    }

    /// The output codes of channels A–H.
    pub fn outputs(&self) -> [u16; 8] {
        self.output
    }

    /// The output changes so far (at most [`MAX_KEPT`]).
    pub fn updates(&self) -> &[DacUpdate] {
        &self.updates
    }

    /// The timing breaches so far (at most [`MAX_KEPT`]).
    pub fn violations(&self) -> &[TimingViolation] {
        &self.violations
    }

    /// The output changes since the last call (at most [`MAX_KEPT`]), removed.
    pub fn take_updates(&mut self) -> Vec<DacUpdate> {
        std::mem::take(&mut self.updates)
    }

    fn violate(&mut self, cycle: u64, what: String) {
        keep(&mut self.violations, TimingViolation { cycle, what });
    }

    /// Starts keeping lanes (`crate::lanes`), all constants (`crate::io::Io` gives its
    /// data words theirs through [`crate::replay::Data`]).
    pub(crate) fn start_lanes(&mut self) {
        self.lanes = Some(Box::new(DacLanes {
            input: [CONST16; 8],
            output: [CONST16; 8],
            shift: CONST,
            sdi: Lane::CONST,
            updates: Vec::new(),
            fixed: Vec::new(),
        }));
    }

    /// [`Dac8568::observe`] with the lanes of the pins' levels, `l`, while lanes are kept.
    pub(crate) fn observe_lanes(&mut self, cycle: u64, values: u32, dirs: u32, l: &Word) {
        if let Some(d) = self.lanes.as_deref_mut() {
            d.sdi = spi_lanes(&self.pins, values, dirs, l, &mut d.fixed);
        }
        self.observe(cycle, values, dirs);
    }

    /// Sees the pins after system cycle `cycle` (as [`Ads8688::observe`]: an undriven SYNC
    /// reads high).
    pub fn observe(&mut self, cycle: u64, values: u32, dirs: u32) {
        let e = self.lines.edges(&self.pins, values, dirs);
        let name = self.part.name;
        if e.cs_fell {
            if let Some(rose) = self.sync_rose {
                let t = (cycle - rose) as f64 / self.clock_hz;
                if t < self.part.sync_high_min_s {
                    self.violate(
                        cycle,
                        format!(
                            "{name}: SYNC high {:.0} ns between frames, under its {:.0} ns",
                            t * 1e9,
                            self.part.sync_high_min_s * 1e9
                        ),
                    );
                }
            }
            self.sync_fell = Some(cycle);
            self.bits = 0;
            self.shift = 0;
            self.last_fall = None;
            if let Some(l) = self.lanes.as_deref_mut() {
                l.shift = CONST;
            }
        }
        if e.cs_rose {
            self.sync_rose = Some(cycle);
            if self.bits != 0 && self.bits < self.part.frame_bits {
                self.violate(
                    cycle,
                    format!(
                        "{name}: SYNC rose after {} SCLKs, before the {}th: the write is lost",
                        self.bits, self.part.frame_bits
                    ),
                );
            }
        }
        if e.sclk_fell {
            self.fall(cycle, e.sdi);
        }
    }

    /// Whether the pins driven `values` and `dirs` (as [`Dac8568::observe`] takes them) are
    /// where it saw them last: then they show it no edge.
    pub fn sees(&self, values: u32, dirs: u32) -> bool {
        self.lines.sees(&self.pins, values, dirs)
    }

    /// The SCLK rate of falls `cycles` apart, when it is over the part's maximum.
    fn sclk_too_fast(&self, cycles: u64) -> Option<f64> {
        sclk_too_fast(self.clock_hz, self.part.sclk_max_hz, cycles)
    }

    /// Whether [`Dac8568::clock_bits`] may clock a frame with falls `period` cycles apart:
    /// the part selected with SCLK low as it last saw them, and that rate within its
    /// maximum.
    pub fn clocks_ok(&self, period: u64) -> bool {
        self.lines.cs_low && !self.lines.sclk_high && self.sclk_too_fast(period).is_none()
    }

    /// `k` SCLK periods (1 ≤ k ≤ 64), SYNC low throughout: a fall at `first + i·period`
    /// latching bit i of `sdi`, for i in 0..k (the rises between change nothing). Exactly
    /// what [`Dac8568::observe`] does with them edge by edge (the rate checked once for the
    /// equal periods: [`Dac8568::clocks_ok`], which must hold).
    pub fn clock_bits(&mut self, first: u64, period: u64, k: u32, sdi: u64) {
        debug_assert!(self.clocks_ok(period) && (1..=64).contains(&k));
        debug_assert!(self.lanes.is_none(), "lanes are kept edge by edge only");
        self.fall(first, sdi & 1 != 0);
        // The other k − 1 falls without their checks (the rate known to be within the
        // part's): as `latch` one by one, the frame's bits that remain taken at once.
        let n = (k - 1).min(self.part.frame_bits.saturating_sub(self.bits));
        if n > 0 {
            self.take_bits(n, msb_first(sdi >> 1, n), first + u64::from(n) * period);
        }
        self.last_fall = Some(first + u64::from(k - 1) * period);
    }

    /// An SCLK fall at `cycle` latching `sdi`.
    fn fall(&mut self, cycle: u64, sdi: bool) {
        let name = self.part.name;
        match self.last_fall {
            Some(prev) => {
                if let Some(hz) = self.sclk_too_fast(cycle - prev) {
                    self.violate(
                        cycle,
                        format!(
                            "{name}: SCLK at {:.2} MHz, over its {:.2} MHz",
                            hz / 1e6,
                            self.part.sclk_max_hz / 1e6
                        ),
                    );
                }
            }
            None => {
                let t = self
                    .sync_fell
                    .map_or(f64::INFINITY, |f| (cycle - f) as f64 / self.clock_hz);
                if t < self.part.sync_setup_min_s {
                    self.violate(
                        cycle,
                        format!(
                            "{name}: first SCLK falling edge {:.0} ns after SYNC fell, under its {:.0} ns",
                            t * 1e9,
                            self.part.sync_setup_min_s * 1e9
                        ),
                    );
                }
            }
        }
        self.last_fall = Some(cycle);
        self.latch(cycle, sdi);
    }

    /// The frame's next bit, `sdi`, latched at an SCLK fall at `cycle` (past the frame's
    /// bits, nothing): the 32nd writes the frame.
    fn latch(&mut self, cycle: u64, sdi: bool) {
        if self.bits >= self.part.frame_bits {
            return;
        }
        if let Some(l) = self.lanes.as_deref_mut() {
            l.shift = lanes::shl(&l.shift, 1);
            l.shift[0] = l.sdi;
        }
        self.take_bits(1, u64::from(sdi), cycle);
    }

    /// `n` more bits of the frame (at most those it lacks), `bits`' low `n` with the first
    /// latched the most significant, the last at `cycle`: the 32nd writes the frame.
    fn take_bits(&mut self, n: u32, bits: u64, cycle: u64) {
        self.shift = ((u64::from(self.shift) << n) | bits) as u32;
        self.bits += n;
        if self.bits == self.part.frame_bits {
            self.write(cycle, self.shift);
            if let Some(l) = self.lanes.as_deref_mut() {
                l.shift = CONST;
            }
            // The frame's bits are spent: nothing reads them again before the next SYNC
            // fall clears them, so the part's state no longer carries the frame's data
            // (two DACs that wrote different words are then equal, as a period memo's
            // key or a rest point compares them).
            self.shift = 0;
        }
    }

    /// The input registers of `channels` (bit c: channel c) take `data`.
    fn write_inputs(&mut self, channels: u8, data: u16, lanes: Option<Lanes16>) {
        for (c, input) in self.input.iter_mut().enumerate() {
            if channels & (1 << c) != 0 {
                *input = data;
                if let (Some(l), Some(d)) = (self.lanes.as_deref_mut(), lanes) {
                    l.input[c] = d;
                }
            }
        }
    }

    /// A whole frame (8.2.6, Table 2 "Control Matrix").
    fn write(&mut self, cycle: u64, word: u32) {
        let control = (word >> 24) & 0xf;
        let address = (word >> 20) & 0xf;
        let data = ((word >> 4) & 0xffff) as u16;
        // The lanes of the data bits; the control and address bits decide what happens.
        let data_lanes = self.lanes.as_deref_mut().map(|l| {
            lanes::fix(&mut l.shift, word, 0x0ff0_0000, &mut l.fixed);
            let mut d = CONST16;
            d.copy_from_slice(&l.shift[4..20]);
            d
        });
        // Channels as bits (bit c: channel c).
        let channels: u8 = match address {
            0..=7 => 1 << address,
            15 => 0xff,
            _ => 0,
        };
        let mut changed = 0u8;
        match control {
            0 => self.write_inputs(channels, data, data_lanes),
            1 => changed = channels,
            2 => {
                self.write_inputs(channels, data, data_lanes);
                changed = 0xff;
            }
            3 => {
                self.write_inputs(channels, data, data_lanes);
                changed = channels;
            }
            _ => {}
        }
        for c in (0..8).filter(|c| changed & (1 << c) != 0) {
            // The update is kept (and its code's lanes with it) while there is room.
            let room = !self.is_full();
            if let Some(l) = self.lanes.as_deref_mut() {
                l.output[c] = l.input[c];
                if room {
                    l.updates.push(l.output[c]);
                }
            }
            self.output[c] = self.input[c];
            let code = self.output[c];
            if room {
                self.updates.push(DacUpdate {
                    cycle,
                    channel: c as u8,
                    code,
                });
            }
        }
    }
}
