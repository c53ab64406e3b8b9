//! Running the I/O machine by events (module documentation of [`super`], "By events"):
//! [`Io::advance`] from event to event, the state machines that alone drive their
//! converters run ahead of the rest ([`Io::run_ahead`]) and their bit loops in bulk
//! ([`Io::run_loop`]), the stretches in which nothing happens skipped ([`Io::skip_idle`]);
//! and the reference it is tested against, every part ticked every cycle
//! ([`Io::advance_stepwise`]). The converters see the pins when one of theirs changed
//! ([`Io::observe`]), with the pins' lanes while a replay is recorded.

use super::*;

/// What an advance found of the next cycle anything can happen in (the DMA quiet, no state
/// machine due before it, none held behind): until then an advance only moves the clocks
/// ([`Io::skip_idle`]). 0 when unknown; moved with the machine's cycles ([`Io::rebase`]),
/// kept by a clone and its rewind, forgotten by everything else that changes the machine (a
/// register access, a reset, the host's access to the parts: [`crate::Board::io_mut`]). A
/// note of the machine's to itself, not its state: machines that differ only in it are
/// equal.
#[derive(Clone, Copy, Default)]
pub(super) struct Idle(pub(super) u64);

impl crate::replay::Cycles for Idle {
    fn eq_at(&self, other: &Self, r: crate::replay::Rebase) -> bool {
        r.at(self.0) == other.0
    }
    fn move_by(&mut self, r: crate::replay::Rebase) {
        self.0 = r.at(self.0);
    }
}

/// In debug builds one idle skip in this many (per thread) is checked against the full run
/// it skips (`Io::advance_by_events`): checking every one made the tests that run converter
/// boards ten times slower.
#[cfg(debug_assertions)]
pub(super) const IDLE_CHECK_EVERY: u32 = 16;

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

/// Which state machines may run ahead of the rest ([`Io::run_ahead`]), and the converters
/// each drives.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Ahead {
    /// The blocks' [`Pio::config_epoch`] it was found at.
    pub(super) epochs: [u64; 2],
    /// Per block and state machine: `None`, or the ADCs and the DACs (bit k: the k-th)
    /// that see its pins and no other state machine's, and the pins it drives.
    pub(super) sm: [[Option<(u32, u32, u32)>; 4]; 2],
    /// Per block and state machine, the addresses (bit a) at which one of `loops` starts.
    pub(super) heads: [[u32; 4]; 2],
    /// The bit loops of the state machines that may run ahead, with their converters' edges
    /// ([`Io::run_loop`]).
    pub(super) loops: Vec<LoopPlan>,
}

/// What a run ahead ([`Io::run_ahead`]) needs of the advance it is part of.
pub(super) struct Run<'f> {
    /// The cycle the advance started at, and its end.
    pub(super) start: u64,
    pub(super) to: u64,
    /// The synchroniser flops at `start`.
    pub(super) flops: &'f [[u32; 2]; 2],
    /// Whether the advance settles (every state machine brought to `to`), or may leave one
    /// behind at a bit loop's head ([`Io::behind`]).
    pub(super) settle: bool,
    /// Whether the state machine reads its inputs from the ADCs' logs alone ([`Io::own_in`]).
    pub(super) logs: bool,
}

/// A bit loop ([`BitLoop`]) of a state machine that may run ahead, and what it does to the
/// pins of each of its converters ([`BitLoop::clock`]): what [`Io::run_loop`] runs in one
/// step.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct LoopPlan {
    /// The PIO block and state machine.
    pub(super) sm: (usize, usize),
    pub(super) lp: BitLoop,
    /// Per ADC and per DAC it drives (their indices), the loop's clock on its pins.
    pub(super) adcs: Vec<(usize, LoopClock)>,
    pub(super) dacs: Vec<(usize, LoopClock)>,
}

/// The clock edges (steps of the rise and the fall) of `c` that a part on pins `p` sees
/// with the pins `view` (levels, directions) at the loop's entry: with its select driven
/// low and its clock driven; none otherwise.
pub(super) fn loop_edges(c: &LoopClock, p: SpiPins, view: (u32, u32)) -> Option<(usize, usize)> {
    let selected = view.1 >> p.cs & 1 != 0 && view.0 >> p.cs & 1 == 0;
    c.edges.filter(|_| selected && view.1 >> p.sclk & 1 != 0)
}

/// The level an ADC's output log (`Io::sdo_log`: (first cycle, levels) at each change,
/// in cycle order) gives for cycle `x`: its last entry from `x` or before, 0 before the
/// first.
pub(super) fn level_at(log: &[(u64, u32)], x: u64) -> u32 {
    match log.partition_point(|&(since, _)| since <= x) {
        0 => 0,
        i => log[i - 1].1,
    }
}

/// Logs an ADC's output change to `levels` from cycle `since` (the log in cycle order,
/// as [`level_at`] needs it).
pub(super) fn log_change(log: &mut Vec<(u64, u32)>, since: u64, levels: u32) {
    debug_assert!(log.last().is_none_or(|&(s, _)| s <= since));
    log.push((since, levels));
}

impl Io {
    /// The pins as the PIOs drive them through IO_BANK0: (levels, directions).
    pub(super) fn driven(&self) -> (u32, u32) {
        let [m0, m1] = self.pio_pins;
        let (p0, p1) = (&self.pio[0], &self.pio[1]);
        (
            (p0.pin_values() & m0) | (p1.pin_values() & m1),
            (p0.pin_dirs() & m0) | (p1.pin_dirs() & m1),
        )
    }

    /// Shows the converters the pins after `cycle` if they changed.
    pub(super) fn observe(&mut self, cycle: u64) {
        let now = self.driven();
        if self.lanes.is_some() {
            return self.observe_lanes(cycle, now);
        }
        if now == self.pins() {
            return;
        }
        self.set_pins(now);
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
    pub(super) fn observe_lanes(&mut self, cycle: u64, now: (u32, u32)) {
        let [m0, m1] = self.pio_pins;
        let out = |p: &Pio| p.lanes.as_ref().map_or(CONST, |l| l.out_values);
        let pins = lanes::select(m0, &out(&self.pio[0]), &lanes::and(&out(&self.pio[1]), m1));
        let Some(l) = self.lanes.as_deref_mut() else {
            return;
        };
        l.pin_levels = pins;
        if now == (self.pin_levels, self.pin_dirs) {
            return;
        }
        (self.pin_levels, self.pin_dirs) = now;
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
    pub(super) fn advance_stepwise(&mut self, to: u64, mem: &mut Memory) {
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
    pub(super) fn inputs_at(&self, x: u64, start: u64, flops: &[[u32; 2]; 2], b: usize) -> u32 {
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
    pub(super) fn sm_resync(&mut self, b: usize, n: usize, at: u64) -> u64 {
        let skipped = at.saturating_sub(self.sm_clock[b][n]);
        self.pio[b].sm_skip(n, skipped);
        self.sm_clock[b][n] = self.sm_clock[b][n].max(at);
        self.sm_next(b, n)
    }

    /// The next cycle state machine `n` of PIO block `b` runs an instruction, from its
    /// state at its clock ([`Pio::sm_idle`]); `u64::MAX` for never.
    pub(super) fn sm_next(&self, b: usize, n: usize) -> u64 {
        self.pio[b]
            .sm_idle(n)
            .map_or(u64::MAX, |k| self.sm_clock[b][n].saturating_add(k))
    }

    /// Which state machines may run ahead ([`Ahead`]): an enabled state machine whose pins
    /// (as IO_BANK0 gives them to its block) no other enabled one writes; whose
    /// converters (those seeing any of them) see only those pins; which reads no input
    /// another converter drives; and whose converters' outputs no other state machine
    /// reads.
    pub(super) fn find_ahead(&self) -> Ahead {
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
    pub(super) fn own_in(&self, adcs: u32, b: usize, x: u64, run: &Run) -> u32 {
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
    pub(super) fn may_hold(
        &self,
        plan: &LoopPlan,
        (adcs, own): (u32, u32),
        x: u64,
        to: u64,
    ) -> Option<u64> {
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
    pub(super) fn loop_ready(&self, plan: &LoopPlan, own: u32) -> Option<(u32, u32)> {
        let ((b, _), lp) = (plan.sm, &plan.lp);
        let pio = &self.pio[b];
        let (values, dirs) = (pio.pin_values(), pio.pin_dirs());
        let view = (
            self.pin_levels & !own | values & own,
            self.pin_dirs & !own | dirs & own,
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
    pub(super) fn run_loop(
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
        self.set_pins((self.pin_levels & !own | v, self.pin_dirs & !own | d));
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
    pub(super) fn run_ahead(
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
                self.set_pins((self.pin_levels & !own | v, self.pin_dirs & !own | d));
                let now = self.pins();
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
    pub(super) fn advance_by_events(&mut self, to: u64, mem: &mut Memory, settle: bool) {
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
    pub(super) fn skip_idle(&mut self, to: u64) {
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
    pub(super) fn adc_levels(&self) -> u32 {
        self.adcs.iter().fold(0, |m, a| m | a.gpio_in())
    }

    /// [`Io::observe`] by events: only the converters one of whose pins changed see them;
    /// a change of an ADC's output is logged ([`Io::sdo_log`]).
    pub(super) fn observe_changed(&mut self, cycle: u64) {
        let now = self.driven();
        if now == self.pins() {
            return;
        }
        let changed = (now.0 ^ self.pin_levels) | (now.1 ^ self.pin_dirs);
        self.set_pins(now);
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
