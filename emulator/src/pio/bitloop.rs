//! Bit loops (the SPI drivers' `OUT`/`IN` … `JMP X--` loops: [`BitLoop`]) found in a state
//! machine's program and run as many times round as fit in one step, with what they do to
//! the pins of each converter on them ([`LoopClock`]): what `crate::io`'s run ahead takes
//! in bulk instead of cycle by cycle, with the same results.

use super::*;

/// Most instructions of a [`BitLoop`], its `JMP X--` included.
pub const LOOP_MAX: usize = 8;

/// One instruction of a [`BitLoop`], decoded once.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct LoopStep {
    /// The instruction word (what SMx_INSTR reads after it).
    pub(super) word: u16,
    /// System cycles from the start of a time round to this instruction's.
    pub(super) at: u64,
    /// The pins `SET PINS` sets (mask, levels).
    pub(super) set: (u32, u32),
    /// The pins its side-set sets (mask, levels): they win over the instruction's own.
    pub(super) side: (u32, u32),
    /// `OUT`'s bit count (0: not an `OUT`), the pins it sets (0 for `OUT NULL`), and the
    /// bits a time round shifts out of the OSR before it.
    pub(super) out: u32,
    pub(super) out_mask: u32,
    pub(super) out_at: u32,
    /// `IN`'s bit count (0: not an `IN`), and whether it reads the pins (`IN PINS, 1`; else
    /// `IN NULL`).
    pub(super) inn: u32,
    pub(super) in_pins: bool,
}

/// A bit loop of a state machine: `OUT PINS`/`OUT NULL`, `IN PINS, 1`/`IN NULL`, `SET
/// PINS` and `NOP` (`MOV Y, Y`), each with any side-set and delay, ending in a `JMP X--`
/// back to the first (the SPI drivers' bit loops), with no wrap inside, on a state machine
/// with an integer clock divider, no autopush or autopull and side-set to the pin levels.
/// It touches nothing but the pins, X, the OSR and the ISR, and each time round runs the
/// same instructions at the same system cycles from its start (the divider's accumulator
/// comes back to where it was after each): so the level of a pin at each instruction of
/// any time round is known before it runs ([`Pio::sm_loop_pin`]), which pins it toggles
/// when is fixed ([`BitLoop::clock`]), and `k` times round are one step
/// ([`Pio::sm_loop_run`]). Found by [`Pio::sm_loop`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BitLoop {
    /// Its first instruction's address (the `JMP`'s target).
    pub head: u32,
    /// The `JMP X--`'s address.
    pub(super) jmp: u32,
    /// System cycles of one time round.
    pub period: u64,
    pub(super) len: usize,
    pub(super) steps: [LoopStep; LOOP_MAX],
    /// Bits shifted out of the OSR each time round, and into the ISR.
    pub(super) out_bits: u64,
    pub(super) in_bits: u32,
    /// `OUT PINS`' pins: PINCTRL's OUT_BASE and OUT_COUNT.
    pub(super) out_map: (u32, u32),
    /// The pin `IN PINS, 1` reads: PINCTRL's IN_BASE.
    pub in_pin: u32,
}

/// What a [`BitLoop`] does to an SPI part's chip select, clock and data pins each time
/// round ([`BitLoop::clock`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoopClock {
    /// The chip select's level throughout (`None`: the loop does not write it), which it
    /// must have at the loop's entry ([`LoopClock::holds`]).
    pub cs: Option<bool>,
    /// The clock's level at the start and end of each time round (`None`: the loop does
    /// not write it), which it must have at the loop's entry.
    pub sclk: Option<bool>,
    /// With the clock low at the start: the steps of its one rise and its one fall (the
    /// data pin written at or before the fall's); `None` when the clock does not move.
    pub edges: Option<(usize, usize)>,
}

impl LoopClock {
    /// Whether the pin levels `values` at the loop's entry are the ones it assumes.
    pub fn holds(&self, pins: (u32, u32), values: u32) -> bool {
        let at = |p: u32, l: Option<bool>| l.is_none_or(|l| (values >> p & 1 != 0) == l);
        at(pins.0, self.cs) && at(pins.1, self.sclk)
    }
}

impl BitLoop {
    /// System cycles from the start of a time round to step `j`'s instruction.
    pub fn at(&self, j: usize) -> u64 {
        self.steps[j].at
    }

    /// The steps that read a pin (`IN PINS, 1`).
    pub fn reads(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.len).filter(|&j| self.steps[j].in_pins)
    }

    /// What the loop does to the pins `cs`, `sclk` and `sdi` of an SPI part: its chip
    /// select held at one level, its clock either left alone or low at each time round's
    /// start and end with one rise and then one fall in between, and its data pin written
    /// at or before the fall's step ([`LoopClock`]); `None` when it does more (a pin set
    /// from data but the data pin, a second clock edge, a select that moves).
    pub fn clock(&self, cs: u32, sclk: u32, sdi: u32) -> Option<LoopClock> {
        let steps = &self.steps[..self.len];
        // The level step `st` gives pin `p`: Some(Some(level)), Some(None) from data.
        let write = |st: &LoopStep, p: u32| -> Option<Option<bool>> {
            let bit = 1u32 << p;
            if st.side.0 & bit != 0 {
                Some(Some(st.side.1 & bit != 0))
            } else if st.out_mask & bit != 0 {
                Some(None)
            } else if st.set.0 & bit != 0 {
                Some(Some(st.set.1 & bit != 0))
            } else {
                None
            }
        };
        let mut cs_level = None;
        for st in steps {
            match write(st, cs) {
                None => {}
                Some(None) => return None,
                Some(Some(l)) if cs_level.is_some_and(|c| c != l) => return None,
                Some(l) => cs_level = l,
            }
        }
        let mut sclk_level = None;
        for st in steps {
            match write(st, sclk) {
                None => {}
                Some(None) => return None,
                Some(l) => sclk_level = l,
            }
        }
        let (mut rise, mut fall) = (None, None);
        if let Some(mut level) = sclk_level {
            for (j, st) in steps.iter().enumerate() {
                let Some(Some(l)) = write(st, sclk) else {
                    continue;
                };
                match (level, l) {
                    (false, true) if rise.is_none() => rise = Some(j),
                    (true, false) if fall.is_none() && rise.is_some() => fall = Some(j),
                    (a, b) if a == b => {}
                    _ => return None,
                }
                level = l;
            }
        }
        let edges = match (rise, fall) {
            (None, None) => None,
            (Some(r), Some(f)) => {
                steps[..=f].iter().find(|st| write(st, sdi).is_some())?;
                Some((r, f))
            }
            _ => return None,
        };
        Some(LoopClock {
            cs: cs_level,
            sclk: sclk_level,
            edges,
        })
    }
}

impl Pio {
    /// The bit loop ([`BitLoop`]) whose first instruction is at `head` in state machine
    /// `n`'s program, as its configuration stands (until the next [`Pio::config_epoch`]);
    /// `None` when the instructions from `head` are not one.
    pub fn sm_loop(&self, n: usize, head: u32) -> Option<BitLoop> {
        let s = &self.sm[n];
        let div = s.divisor();
        if !div.is_multiple_of(256) || s.autopull() || s.autopush() || s.side_pindir() {
            return None;
        }
        let int = u64::from(div / 256);
        let (out_base, out_count) = (bits(s.pinctrl, 0, 5), bits(s.pinctrl, 20, 6));
        let (set_base, set_count) = (bits(s.pinctrl, 5, 5), bits(s.pinctrl, 26, 3));
        let out_mask = StateMachine::map(out_base, out_count, 0).0;
        let mut steps = [LoopStep::default(); LOOP_MAX];
        let (mut pc, mut at, mut out_bits, mut in_bits) = (head & 31, 0u64, 0u32, 0u32);
        for (j, step) in steps.iter_mut().enumerate() {
            let word = self.instr[pc as usize];
            let ins = u32::from(word);
            let (arg1, arg2) = (bits(ins, 5, 3), bits(ins, 0, 5));
            let (side, delay) = s.side_set(word);
            *step = LoopStep {
                word,
                at,
                side,
                ..LoopStep::default()
            };
            at += int * u64::from(1 + delay);
            match ins >> 13 {
                // JMP X-- back to the head ends it.
                0 if arg1 == 2 && arg2 == head & 31 => {
                    return Some(BitLoop {
                        head: head & 31,
                        jmp: pc,
                        period: at,
                        len: j + 1,
                        steps,
                        out_bits: u64::from(out_bits),
                        in_bits,
                        out_map: (out_base, out_count),
                        in_pin: bits(s.pinctrl, 15, 5),
                    });
                }
                // OUT PINS, OUT NULL.
                3 if arg1 == 0 || arg1 == 3 => {
                    step.out = count32(arg2);
                    step.out_at = out_bits;
                    step.out_mask = if arg1 == 0 { out_mask } else { 0 };
                    out_bits += step.out;
                }
                // IN PINS, 1; IN NULL.
                2 if (arg1 == 0 && arg2 == 1) || arg1 == 3 => {
                    step.inn = count32(arg2);
                    step.in_pins = arg1 == 0;
                    in_bits += step.inn;
                }
                // SET PINS.
                7 if arg1 == 0 => step.set = StateMachine::map(set_base, set_count, arg2),
                // NOP (MOV Y, Y).
                5 if ins & 0xff == 0x42 => {}
                _ => return None,
            }
            if pc == s.wrap_top() {
                return None;
            }
            pc = (pc + 1) & 31;
        }
        None
    }

    /// How many times round a [`BitLoop`] of state machine `n` goes from here, this one
    /// included: its X + 1.
    pub fn sm_loop_left(&self, n: usize) -> u64 {
        u64::from(self.sm[n].x) + 1
    }

    /// The levels of `pin` (as [`Pio::pin_values`] gives it, whatever its direction) after
    /// step `j` of the first `k` times round (1 ≤ k ≤ 64; bit i: time round i, from 0: the
    /// one state machine `n` is at, at the head) of `lp`, its loop, from the last write to it
    /// among steps `0..=j`; `None` when none writes it.
    pub fn sm_loop_pin(&self, n: usize, lp: &BitLoop, k: u64, j: usize, pin: u32) -> Option<u64> {
        let s = &self.sm[n];
        let bit = 1u32 << pin;
        let st = lp.steps[..=j]
            .iter()
            .rev()
            .find(|st| (st.side.0 | st.out_mask | st.set.0) & bit != 0)?;
        let all = |level: u32| match level & bit {
            0 => 0,
            _ => u64::MAX >> (64 - k),
        };
        if st.side.0 & bit != 0 {
            return Some(all(st.side.1));
        }
        if st.out_mask == 0 {
            return Some(all(st.set.1));
        }
        let right = s.out_right();
        if lp.out_bits == 1 {
            // One bit out a time round: time round i's level is the OSR's bit at `at ± i`
            // (zeros once it is shifted past), so the k levels are a shifted (right) or
            // bit-reversed (left) run of the OSR.
            let d = pin.wrapping_sub(lp.out_map.0) & 31;
            let osr = u64::from(s.osr);
            let levels = match right {
                // Past the OUT's bits: its pins beyond them get 0.
                _ if d >= st.out => 0,
                // Time round i takes bit d + out_at + i.
                true => osr.checked_shr(d + st.out_at).unwrap_or(0),
                // Time round i takes bit (32 − out + d − out_at) − i.
                false => match (32 - st.out + d).checked_sub(st.out_at) {
                    Some(top) if top < 32 => u64::from((s.osr << (31 - top)).reverse_bits()),
                    _ => 0,
                },
            };
            return Some(levels & (u64::MAX >> (64 - k)));
        }
        Some((0..k).fold(0, |m, i| {
            let shifted = u64::from(st.out_at) + i * lp.out_bits;
            let osr = StateMachine::osr_after(s.osr, shifted, right);
            let data = StateMachine::out_data(osr, st.out, right);
            let level = StateMachine::map(lp.out_map.0, lp.out_map.1, data).1 & bit;
            m | u64::from(level != 0) << i
        }))
    }

    /// Runs `k` times round (1 ≤ k ≤ 64, at most [`Pio::sm_loop_left`]) of `lp`, the bit
    /// loop state machine `n` is at the head of, due this cycle with nothing pending
    /// ([`Pio::sm_fast`]); `in_bits[j]` holds, bit i, what step j's `IN PINS, 1` reads in
    /// time round i. What as many [`Pio::sm_exec`]s of its instructions do: X counted down,
    /// the OSR and ISR shifted, the pins as the last time round leaves them, PC at the head
    /// again or past the `JMP` when X ran out, the divider's accumulator where it was.
    pub fn sm_loop_run(&mut self, n: usize, lp: &BitLoop, k: u64, in_bits: &[u64; LOOP_MAX]) {
        debug_assert!(
            self.lanes.is_none(),
            "lanes are kept on the stepwise path only"
        );
        debug_assert!((1..=64).contains(&k) && k <= self.sm_loop_left(n));
        let mut values = self.out_values;
        let s = &mut self.sm[n];
        let set = |old: u32, (m, v): (u32, u32)| old & !m | v;
        let right = s.out_right();
        // The last time round's pin writes, its OUTs' data from the OSR as it stands before
        // it (the shifts of several OUTs add up: `StateMachine::osr_after`).
        let before_last = (k - 1) * lp.out_bits;
        for st in &lp.steps[..lp.len] {
            if st.out_mask != 0 {
                let osr = StateMachine::osr_after(s.osr, before_last + u64::from(st.out_at), right);
                let data = StateMachine::out_data(osr, st.out, right);
                values = set(values, StateMachine::map(lp.out_map.0, lp.out_map.1, data));
            }
            values = set(set(values, st.set), st.side);
        }
        let shifted = k * lp.out_bits;
        s.osr = StateMachine::osr_after(s.osr, shifted, right);
        s.osr_count = (u64::from(s.osr_count) + shifted).min(32) as u32;
        if lp.in_bits == 1 {
            // One bit in a time round: the k bits in one shift, the last 32 of them all the
            // ISR holds once k reaches 32.
            let j = lp.steps[..lp.len]
                .iter()
                .position(|st| st.inn > 0)
                .unwrap_or(0);
            let bits = match lp.steps[j].in_pins {
                true => in_bits[j] & (u64::MAX >> (64 - k)),
                false => 0,
            };
            let last = (bits >> k.saturating_sub(32)) as u32;
            s.isr = match (s.in_right(), k) {
                (true, 32..) => last,
                (true, _) => (s.isr >> k) | (last << (32 - k)),
                (false, 32..) => last.reverse_bits(),
                (false, _) => (s.isr << k) | (last.reverse_bits() >> (32 - k)),
            };
            s.isr_count = (u64::from(s.isr_count) + k).min(32) as u32;
        } else if lp.in_bits > 0 {
            for i in 0..k {
                for (j, st) in lp.steps[..lp.len].iter().enumerate() {
                    if st.inn > 0 {
                        let data = match st.in_pins {
                            true => (in_bits[j] >> i) as u32 & 1,
                            false => 0,
                        };
                        s.shift_in(st.inn, data);
                    }
                }
            }
        }
        let x = s.x;
        s.x = x.wrapping_sub(k as u32);
        if k == u64::from(x) + 1 {
            s.pc = lp.jmp;
            s.advance();
        } else {
            s.pc = lp.head;
        }
        s.current = lp.steps[lp.len - 1].word;
        s.stalled = None;
        s.delay = 0;
        self.out_values = values;
    }
}
