//! Rest points: a board's state apart from the passage of time, and the jump of its clock
//! over whole periods of a run that repeats.
//!
//! **Why.** A keyboard's board whose keys rest reads the same sensor words sample after
//! sample, and its firmware settles into a cycle: every word it keeps comes back to the same
//! value after a whole number of samples (on the shipped firmware the tick schedule's
//! remainder repeats after 63 samples at 133 MHz and the differentiator rings' write
//! positions after 17, so the board repeats after 1,071 samples, 24 ms), but for counters
//! that only ever grow (the handler's sample count). Emulating those repeats is most of a
//! performance's work: at rest a board is idle 90 % of the demo's samples.
//!
//! **What.** [`Board::rest_point`] takes everything that decides what the board does next —
//! SRAM, both cores' registers, flags, modes, run states and NVIC/SysTick, SIO, the timer,
//! the clocks' registers, the watchdog (its count and the cycles since it was loaded), the
//! XIP block — with every cycle-valued field taken relative to
//! the earlier core's cycle (a cycle before it, which nothing can tell from another, as
//! "past"), and apart from words the caller names as counters. Two rest points with equal
//! states make a [`Period`]; [`Board::skip_periods`] then moves a board whose state equals
//! the period's end forward by whole periods: every cycle-valued field by the period's
//! cycles, the counters, instruction counts, contention stalls and profile entries by the
//! period's increase of each.
//!
//! **Why that is exact.** A board's run is a pure function of its state and of the host's
//! writes (module documentation, "Lock-step"), and the emulator's state depends on time only
//! through differences of cycles, except the timer's count, which is absolute: a period over
//! which a core read the count ([`crate::timer::Timer::count_reads`]) is refused, and so is,
//! while a SysTick counts the timer's 1 µs pulses, one whose cycles are not a whole number of
//! microseconds (the pulses' phase). So when the
//! state at the period's end equals the state at its start, running it again from the end
//! with the same host writes at the same times gives the same run shifted by the period, and
//! by induction so do the runs after it: skipping `k` periods gives what running them would
//! (the same SRAM, registers, cycles, instruction counts). The caller's part: between the
//! period's points and over the skipped periods the host writes what it wrote over the period
//! (at rest: the same sensor words each sample), and every word it names as a counter is one
//! the board only increments and never otherwise reads (the image's sample count), which
//! the emulator cannot see. What the board's memoized calls, compiled code and decode caches
//! hold is not state: they give the same results whatever they hold.
//!
//! **Converters.** A board with converter I/O ([`crate::io`]) adds the I/O machine to its
//! state: the PIOs, the DMA and the converters at the pins, each cycle of theirs relative to
//! the earlier core's cycle ([`crate::io::Io::rebased`]; the machine is settled to the
//! board's cycle at the end of each run). The parts' records — the frames and updates seen
//! at the pins, which only grow (to [`crate::converters::MAX_KEPT`]) — are not state: the
//! period keeps those of its run, and a skip appends them for each period skipped, moved to
//! its cycles, as running it would have recorded them. A period in which a converter's
//! timing was breached is refused.
//!
//! Refused (an error saying why): a debugger attached, core 1's launch under way, a timer
//! alarm armed, a profiled call open.
//! Test: `firmware/tests/rest.rs` (a keyboard board replaying and skipping periods against the
//! same board running every sample: every output, SRAM byte, cycle and register equal).

use super::*;
use crate::io::slots::IoRecords;
use crate::io::Io;
use crate::replay::Rebase;

/// The state of a board at an instant apart from time and counters (compared), with the
/// board's clocks and counts then (not compared). Made by [`Board::rest_point`].
#[derive(Clone, Debug)]
pub struct RestPoint {
    /// SRAM, the counter words zeroed.
    sram: Vec<u8>,
    /// Every other part of the state, each cycle relative to `now` (debug formatted: a
    /// field added to a part is compared without anyone listing it).
    parts: String,
    /// The earlier core's cycle.
    now: u64,
    instructions: [u64; 2],
    stalls: [u64; 2],
    /// Per profile, each core's entries.
    entries: Vec<[u64; 2]>,
    count_reads: u64,
    /// The watchdog's reads of its count and feeds near its firing (not state: a period
    /// with either is refused, `crate::watchdog`, "Exactness").
    watchdog_reads: (u64, u64),
    /// Whether a core's SysTick counts the timer's 1 µs pulses (CLKSOURCE = 0): the
    /// pulses' phase is then state.
    on_us_grid: bool,
    /// The counter words: SRAM offset and value.
    counters: Vec<(usize, u32)>,
    /// The converter I/O, if any: its machine without records, its cycles moved to
    /// [`Rebase::MEMO`] from `now` (compared), and its parts' record counts (not compared).
    io: Option<(Box<Io>, Vec<[usize; 2]>)>,
}

impl RestPoint {
    /// Whether the two points' states are equal (their times and counts aside).
    pub fn same_state(&self, other: &RestPoint) -> bool {
        self.parts == other.parts
            && self.sram == other.sram
            && self.entries.len() == other.entries.len()
            && self.counters.len() == other.counters.len()
            && (self.counters.iter().zip(&other.counters)).all(|(a, b)| a.0 == b.0)
            && match (&self.io, &other.io) {
                (Some(a), Some(b)) => a.0 == b.0,
                (None, None) => true,
                _ => false,
            }
    }
}

/// A run between two rest points of equal state: what one more period adds.
#[derive(Clone, Debug)]
pub struct Period {
    /// The point at the period's end.
    end: RestPoint,
    cycles: u64,
    instructions: [u64; 2],
    stalls: [u64; 2],
    entries: Vec<[u64; 2]>,
    /// Per counter word, its increase over the period (mod 2^32).
    counters: Vec<u32>,
    /// The converters' records of the period, their cycles moved to [`Rebase::MEMO`] from
    /// its start (none without converters).
    io_records: Option<IoRecords>,
}

impl Period {
    /// Cycles of one period.
    pub fn cycles(&self) -> u64 {
        self.cycles
    }

    /// Per counter word (in [`Board::rest_point`]'s order), its increase over one period
    /// (mod 2^32).
    pub fn counter_increases(&self) -> &[u32] {
        &self.counters
    }

    /// Per counter word, its value at the period's end.
    pub fn counters_at_end(&self) -> impl Iterator<Item = u32> + '_ {
        self.end.counters.iter().map(|c| c.1)
    }
}

/// `t` relative to `now`, every cycle before `now` one value (a claim, a divider result or
/// a BUSY end before the earlier core's cycle decides nothing from then on).
fn relative(t: u64, now: u64) -> u64 {
    if t == u64::MAX {
        u64::MAX
    } else if t < now {
        u64::MAX - 1
    } else {
        t - now
    }
}

impl Drive<'_> {
    /// The period from `start` to `end`, two rest points of this board, `end` its point
    /// now ([`Board::rest_point`]): with converters, their records since `start` are the
    /// period's.
    ///
    /// Errors (as text): the states differ, no time passed, a core read the timer's count
    /// between them, a SysTick counts the 1 µs pulses and the period is not a whole
    /// number of microseconds at the board's clock, a converter's timing was breached or
    /// its records taken ([`crate::io::Io`]'s records drained) between them.
    pub(crate) fn period(&mut self, start: &RestPoint, end: &RestPoint) -> Result<Period, String> {
        self.m.system.io_unlazy();
        let clock_hz = self.cfg.clock_hz;
        if !start.same_state(end) {
            return Err("the board's state at the two points differs".into());
        }
        let cycles = end.now.checked_sub(start.now).filter(|&c| c > 0);
        let Some(cycles) = cycles else {
            return Err("the second point is not later than the first".into());
        };
        if end.count_reads != start.count_reads {
            return Err("a core read the timer's count during the period".into());
        }
        if end.watchdog_reads != start.watchdog_reads {
            return Err(
                "a core read the watchdog's count, or fed it within two ticks of its firing, \
                 during the period"
                    .into(),
            );
        }
        if start.on_us_grid
            && (clock_hz == 0 || !(cycles as u128 * 1_000_000).is_multiple_of(clock_hz as u128))
        {
            return Err(format!(
                "{cycles} cycles are not a whole number of microseconds at {clock_hz} Hz"
            ));
        }
        let io_records = match (&start.io, self.m.system.io.as_mut()) {
            (Some((_, counts)), Some(io)) => {
                let now = io.record_counts();
                if (now.iter().zip(counts)).any(|(n, c)| n[0] < c[0] || n[1] < c[1]) {
                    return Err("the converters' records were taken during the period".into());
                }
                let r = Rebase {
                    from: start.now,
                    to: Rebase::MEMO,
                };
                let Some(records) = io.records_since(counts, r) else {
                    return Err("a converter's timing was breached during the period".into());
                };
                Some(records)
            }
            (None, None) => None,
            _ => return Err("the converter I/O was attached during the period".into()),
        };
        let d2 = |a: [u64; 2], b: [u64; 2]| [b[0].wrapping_sub(a[0]), b[1].wrapping_sub(a[1])];
        Ok(Period {
            end: end.clone(),
            cycles,
            instructions: d2(start.instructions, end.instructions),
            stalls: d2(start.stalls, end.stalls),
            entries: (start.entries.iter().zip(&end.entries))
                .map(|(&a, &b)| d2(a, b))
                .collect(),
            counters: (start.counters.iter().zip(&end.counters))
                .map(|(a, b)| b.1.wrapping_sub(a.1))
                .collect(),
            io_records,
        })
    }

    /// The board's state now as a [`RestPoint`], the SRAM words at `counters` (offsets of
    /// aligned words from [`tactus_rp2040::memory::SRAM_BASE`]) taken as counters (module
    /// documentation).
    ///
    /// Errors (as text): a debugger attached, core 1's launch under way, a timer alarm
    /// armed, a profiled call open, a counter offset outside SRAM or unaligned.
    pub(crate) fn rest_point(&mut self, counters: &[usize]) -> Result<RestPoint, String> {
        self.m.system.io_unlazy();
        if self.m.launch.is_some() {
            return Err("core 1's launch is under way".into());
        }
        if self.m.system.timer.next_event != u64::MAX {
            return Err("a timer alarm is armed".into());
        }
        if self.prof.profiles_mut().iter().any(|p| p.is_open()) {
            return Err("a profiled call is open".into());
        }
        let now = self.m.cores[0].cycle.min(self.m.cores[1].cycle);
        let mut sram = self.m.system.sram.clone();
        let mut words = Vec::with_capacity(counters.len());
        for &o in counters {
            let Some(w) = sram.get_mut(o..o.wrapping_add(4)).filter(|_| o % 4 == 0) else {
                return Err(format!("counter offset {o:#x} is not a word of SRAM"));
            };
            words.push((o, u32::from_le_bytes([w[0], w[1], w[2], w[3]])));
            w.fill(0);
        }
        let io = self.m.system.io.as_mut().map(|io| {
            let r = Rebase {
                from: now,
                to: Rebase::MEMO,
            };
            (io.rebased(r), io.record_counts())
        });
        // Every field of the system, so that a new one needs a decision here.
        let System {
            rom: _,   // read-only to the cores
            flash: _, // the model programs no flash: read-only to the cores
            sram: _,
            sio,
            timer,
            sysctl,
            watchdog,
            xip,
            xip_answers,
            bank_claim,
            contention_stalls,
            irq_epoch: _,  // when to recompute the interrupt lines: a cache
            code_pages: _, // the decode cache's pages
            code_epoch: _, // the decode cache's generation
            allowed_banks,
            io: _,      // below
            io_lazy: _, // none: made the live machine first (`System::io_unlazy`)
            io_banks,
            io_journal,
            io_rec,
        } = &self.m.system;
        let mut sio = sio.clone();
        for d in &mut sio.divider {
            d.ready_at = relative(d.ready_at, now);
        }
        let mut xip = xip.clone();
        xip.move_time(&mut |t| relative(t, now));
        let claims = bank_claim.map(|c| c.map(|t| relative(t, now)));
        let cores = self.m.cores.each_ref().map(|c| {
            let Core {
                id,
                r,
                n,
                z,
                c: carry,
                v,
                thumb,
                ipsr,
                primask,
                control,
                other_sp,
                nvic,
                cycle,
                state,
                event,
                instructions: _, // a count
                last: _,         // a trace
                fault,
            } = c;
            let mut nvic = nvic.clone();
            nvic.syst_next = relative(nvic.syst_next, now);
            format!(
                "{id} {r:?} {n} {z} {carry} {v} {thumb} {ipsr} {primask} {control} \
                 {other_sp} {nvic:?} {} {state:?} {event} {fault:?}",
                cycle - now
            )
        });
        let watchdog_state = watchdog.rest_state(now);
        let parts = format!(
            "{cores:?} {sio:?} {timer:?} {sysctl:?} {watchdog_state} {xip:?} {xip_answers} \
             {claims:?} {allowed_banks} {io_banks} {io_journal:?} {io_rec:?}"
        );
        Ok(RestPoint {
            io,
            sram,
            parts,
            now,
            instructions: [self.m.cores[0].instructions, self.m.cores[1].instructions],
            stalls: *contention_stalls,
            entries: self
                .prof
                .profiles_mut()
                .iter()
                .map(|p| p.entries())
                .collect(),
            count_reads: timer.count_reads,
            watchdog_reads: (watchdog.time_reads, watchdog.close_calls),
            on_us_grid: self
                .m
                .cores
                .iter()
                .any(|c| c.nvic.syst_csr & 0b101 == 0b001),
            counters: words,
        })
    }

    /// Moves the board forward by `periods` whole periods of `period` without running them:
    /// what running them would give when the host writes over them what it wrote over the
    /// period (module documentation). The board's state now must equal the state at the
    /// period's end ([`RestPoint::same_state`], checked here: the board is then on the
    /// repeating run).
    ///
    /// Errors (as text): the state differs (or [`Board::rest_point`]'s), or the cycles
    /// overflow. Nothing is changed on an error.
    pub(crate) fn skip_periods(&mut self, period: &Period, periods: u64) -> Result<(), String> {
        self.m.system.io_unlazy();
        let counters: Vec<usize> = period.end.counters.iter().map(|c| c.0).collect();
        let here = self.rest_point(&counters)?;
        if !here.same_state(&period.end) {
            return Err("the board is not at the period's state".into());
        }
        let k = periods;
        let Some(delta) = period.cycles.checked_mul(k).filter(|d| {
            self.m
                .cores
                .iter()
                .all(|c| c.cycle.checked_add(*d).is_some())
        }) else {
            return Err("the skipped cycles overflow".into());
        };
        let now = here.now;
        let later = |t: u64| {
            if t == u64::MAX || t < now {
                t
            } else {
                t + delta
            }
        };
        for (i, c) in self.m.cores.iter_mut().enumerate() {
            c.cycle += delta;
            c.instructions = c
                .instructions
                .wrapping_add(period.instructions[i].wrapping_mul(k));
            c.nvic.syst_next = later(c.nvic.syst_next);
        }
        let sys = &mut self.m.system;
        for claims in &mut sys.bank_claim {
            for t in claims.iter_mut() {
                *t = later(*t);
            }
        }
        for d in &mut sys.sio.divider {
            d.ready_at = later(d.ready_at);
        }
        sys.xip.move_time(&mut |t| later(t));
        sys.watchdog.move_later(delta);
        for i in 0..2 {
            sys.contention_stalls[i] =
                (sys.contention_stalls[i]).wrapping_add(period.stalls[i].wrapping_mul(k));
        }
        for (p, d) in self.prof.profiles_mut().iter_mut().zip(&period.entries) {
            p.add_entries([d[0].wrapping_mul(k), d[1].wrapping_mul(k)]);
        }
        for (&(o, _), &d) in period.end.counters.iter().zip(&period.counters) {
            let w = &mut sys.sram[o..o + 4];
            let v = u32::from_le_bytes([w[0], w[1], w[2], w[3]]);
            w.copy_from_slice(&v.wrapping_add(d.wrapping_mul(k as u32)).to_le_bytes());
        }
        if let Some(io) = sys.io.as_mut() {
            io.rebase(Rebase {
                from: now,
                to: now + delta,
            });
            if let Some(records) = period.io_records.as_ref().filter(|r| !r.is_empty()) {
                // Each skipped period's records at its cycles, until the parts keep no more.
                for j in 0..k {
                    if io.records_full() {
                        break;
                    }
                    let r = Rebase {
                        from: Rebase::MEMO,
                        to: now + j * period.cycles,
                    };
                    io.append_records(records, r);
                }
            }
        }
        self.a.window_at = later(self.a.window_at);
        // The interrupt lines are recomputed at the next run (the timer and SIO are as
        // they were).
        self.a.lines_epoch = u64::MAX;
        Ok(())
    }
}
