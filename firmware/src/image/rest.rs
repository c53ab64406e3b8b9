//! The rest replay of [`super::ImageRun`]: a board whose sensor words stop changing is run
//! until its state repeats, then its samples are given from the recorded period instead of
//! being emulated, until the words change; the board then jumps over the whole periods
//! ([`tactus_emulator::Board::skip_periods`]) and runs the rest of the last one, exactly.
//!
//! **The period** of the shipped firmware at rest: the tick schedule's remainder repeats
//! after `den` samples (`super::glue::Tick`: 63 at 133 MHz and 44.1 kHz) and each
//! differentiator ring's write position after its length (`2·WINDOW + 1` = 17,
//! `tactus_runtime::differentiator`): every `lcm` of the two samples (1,071 at 133 MHz,
//! 24 ms) the board's state repeats but for the cores' sample counters, which the handler
//! only increments and the board never otherwise reads (`super::glue`, the handler's end):
//! they are the rest points' counters (with the budgets below). An image whose state repeats with another period
//! (a program settling more slowly) simply does not repeat at this one: the check fails and
//! the board is emulated.
//!
//! With converters, the lcm with the ring of three results buffers (the same 1,071 samples at
//! 133 MHz: `super::io`, "A resting board repeats"), times what makes its cycles whole PIO
//! clock divider periods (`super::run`'s `rest_period`).
//!
//! **Budgets.** Each key's limiter keeps a time budget (`tactus_runtime::limiter`) that a
//! key at rest still moves: after a loud note it earns one unit a sample back to the full
//! budget (17,640 units, 0.4 s, for the shipped limiter); a key held at the keybed above its
//! rated current spends `recovery` a sample until it is spent, then cycles through
//! `recovery + 1` samples. So the budget words are counters of the rest points too, and a
//! period over which one grew by one a sample (below the full budget: every sample took the
//! same path) or fell by `recovery` a sample (above rated with budget) is replayed only for as
//! many samples as keep it on that path (`super::run`'s `replay_room`); the replay then ends
//! as if the words had changed, and the next try records the budget's new path. A try
//! compares its end with up to [`max_periods`] earlier starts, so a cycling budget's board
//! repeats after 5 periods (5,355 samples).
//!
//! **Flow.** After [`SETTLE`] samples with the same sensor words a rest point is taken, the
//! samples' outputs recorded, and a point a period later; a state equal to one of the last
//! points' ([`tactus_emulator::Board::period`]) starts the replay, else the recording goes
//! on. While the words stay, each sample is the recorded one of its place in the
//! period, the board parked at the period's end. When they change (or the board is asked
//! for), `k` whole periods are skipped and the remaining `r` samples run on the board, each
//! checked against its recording (a difference is an error, never a silent result).
//! Test: `firmware/tests/rest.rs` (boards replaying against boards running every sample,
//! with converters, and with a key held at the keybed and released).

use super::sample::SampleOut;
use tactus_emulator::{Period, RestPoint};

/// Samples with the same sensor words before the first rest point (the rings fill in 17).
pub const SETTLE: u64 = 64;

/// Where the rest replay stands.
pub(super) enum Phase {
    /// Waiting for [`SETTLE`] samples with the same sensor words.
    Watching,
    /// A rest point taken after the sample that ended the wait (or the last try); the
    /// outputs of the samples since.
    Recording {
        /// The rest points taken, each with the number of samples recorded before it (the
        /// first 0): one a period.
        starts: Vec<(Box<RestPoint>, usize)>,
        /// The first `filled` are the samples since the first start (the rest kept from an
        /// earlier try, to reuse).
        outs: Vec<SampleOut>,
        filled: usize,
        /// Every key's out words after each of those samples, flat.
        words: Vec<u32>,
    },
    /// The board parked at `period`'s end (after sample `parked_at`); `given` samples given
    /// from `outs` (and `words`) since; `sensors` the words of the rest.
    Replaying {
        period: Box<Period>,
        outs: Vec<SampleOut>,
        words: Vec<u32>,
        sensors: Vec<i32>,
        parked_at: u64,
        given: u64,
        /// The most samples it may give (the budgets' room, `super::run`'s `replay_room`).
        room: u64,
    },
    /// No rest points until the sensor words change (the board refused one: the error).
    Refused(String),
}

/// The replay's state in an [`super::ImageRun`].
pub(super) struct Rest {
    /// Whether the replay is on ([`super::ImageRun::set_rest_replay`]).
    pub on: bool,
    /// Samples of the period tried.
    pub period: usize,
    /// The sensor words of the last sample and how many samples in a row had them.
    pub last: Vec<i32>,
    pub same: u64,
    pub phase: Phase,
    /// Samples given from recordings and periods skipped so far (reports, tests).
    pub given: u64,
    pub skipped: u64,
    /// The longest period replayed, samples, and the replays a budget's room ended.
    pub longest: usize,
    pub room_ends: u64,
    /// A recording's buffers kept for the next (their allocations reused): every buffer a
    /// recording made stays here or in the phase ([`Rest::keep_spare`]), so that a board
    /// clones a [`SampleOut`] (a dozen vectors) only for a recording longer than any
    /// before.
    pub spare: Vec<SampleOut>,
    /// The largest out-words buffer a recording used, kept for the next (empty).
    pub spare_words: Vec<u32>,
}

impl Rest {
    /// Off, for an image whose period at rest is `period` samples.
    pub fn new(period: usize) -> Rest {
        Rest {
            on: false,
            period: period.max(1),
            last: Vec::new(),
            same: 0,
            phase: Phase::Watching,
            given: 0,
            skipped: 0,
            longest: 0,
            room_ends: 0,
            spare: Vec::new(),
            spare_words: Vec::new(),
        }
    }

    /// Whether samples are given from a recording now.
    pub fn replaying(&self) -> bool {
        matches!(self.phase, Phase::Replaying { .. })
    }

    /// Whether the next sample can be given from the recording being replayed.
    pub fn can_give(&self) -> bool {
        matches!(self.phase, Phase::Replaying { given, room, .. } if given < room)
    }

    /// The next sample of the recording being replayed (an empty one when none is:
    /// call only when [`Rest::replaying`]).
    pub fn give(&mut self) -> &SampleOut {
        match &mut self.phase {
            Phase::Replaying { outs, given, .. } if !outs.is_empty() => {
                let i = (*given % outs.len() as u64) as usize;
                *given += 1;
                self.given += 1;
                &outs[i]
            }
            _ => &NONE,
        }
    }

    /// Gives up to `most` samples of the recording being replayed, as as many
    /// [`Rest::give`]s would (no more than its room), while `take` accepts each (the first
    /// it refuses is not given); returns how many it gave (none when nothing is replayed).
    pub fn give_while(&mut self, most: u64, mut take: impl FnMut(&SampleOut) -> bool) -> u64 {
        let Phase::Replaying {
            outs, given, room, ..
        } = &mut self.phase
        else {
            return 0;
        };
        let len = outs.len();
        if len == 0 {
            return 0;
        }
        let most = most.min(room.saturating_sub(*given));
        let mut i = (*given % len as u64) as usize;
        let mut n = 0;
        while n < most {
            if !take(&outs[i]) {
                break;
            }
            n += 1;
            i += 1;
            if i == len {
                i = 0;
            }
        }
        *given += n;
        self.given += n;
        n
    }

    /// Keeps `outs` (a recording's or a replay's buffers, done with) among the spare ones.
    pub fn keep_spare(&mut self, mut outs: Vec<SampleOut>) {
        outs.append(&mut self.spare);
        self.spare = outs;
    }

    /// Keeps a recording's or a replay's buffers, done with: its samples among the spare
    /// ones ([`Rest::keep_spare`]), its out words as the spare buffer when it is the
    /// largest yet.
    pub fn keep_buffers(&mut self, outs: Vec<SampleOut>, mut words: Vec<u32>) {
        self.keep_spare(outs);
        if words.capacity() > self.spare_words.capacity() {
            words.clear();
            self.spare_words = words;
        }
    }

    /// Back to watching, as if no sample had been seen (the buffers kept).
    pub fn forget(&mut self) {
        if let Phase::Recording { outs, words, .. } | Phase::Replaying { outs, words, .. } =
            std::mem::replace(&mut self.phase, Phase::Watching)
        {
            self.keep_buffers(outs, words);
        }
        self.last.clear();
        self.same = 0;
    }

    /// Counts a sample with `sensors`: true when they are the last sample's.
    pub fn note(&mut self, sensors: &[i32]) -> bool {
        if self.last == sensors {
            self.same += 1;
            true
        } else {
            self.last.clear();
            self.last.extend_from_slice(sensors);
            self.same = 1;
            false
        }
    }
}

/// The most periods of `period` samples a try compares its end with (the rest points
/// kept): a key held above its rated current at rest makes its limiter's budget cycle
/// through `recovery + 1` samples (`recovery` samples of the spent path earning one unit
/// each, then one spending `recovery`: `tactus_runtime::limiter`), so a board whose period
/// is not a multiple of that repeats only after `recovery + 1` periods (5 for the shipped
/// limiter); but no more than [`MAX_RECORDED`] samples are kept (at least one period: a
/// board at 200 MHz with converters, 22,491 samples a period, tries one period at a time).
pub fn max_periods(limiter: &tactus_runtime::limiter::LimiterConstants, period: usize) -> usize {
    let cycle = (limiter.recovery.clamp(0, 7) + 1) as usize;
    cycle.min(MAX_RECORDED / period.max(1)).max(1)
}

/// The most samples a recording keeps across the periods it tries ([`max_periods`]):
/// each a [`SampleOut`] of a few hundred bytes on an eight-key board.
pub const MAX_RECORDED: usize = 16_384;

/// What [`Rest::give`] gives when nothing is replayed.
static NONE: SampleOut = SampleOut {
    force: Vec::new(),
    current_ua: Vec::new(),
    dac: Vec::new(),
    drives: Vec::new(),
    events: Vec::new(),
    core_cycles: Vec::new(),
    handler_runs: Vec::new(),
    misses: Vec::new(),
    stalls: Vec::new(),
};

/// Least common multiple (0 when either is 0).
pub fn lcm(a: u64, b: u64) -> u64 {
    if a == 0 || b == 0 {
        0
    } else {
        a / crate::board_file::gcd(a, b) * b
    }
}
