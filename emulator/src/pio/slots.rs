//! What a window's replay and the period memo need of a PIO block (`crate::io::slots`): its
//! data words (the pins' levels, the input synchroniser, each state machine's X, Y, ISR, OSR
//! and FIFO words) named in a fixed order ([`Pio::data_slots`]), the block compared and taken
//! but for them (its `crate::replay::ReplayState`, each field's role declared once), and, while a replay is
//! recorded, the lanes of each data bit (`crate::lanes`: [`PioLanes`]) that the execution
//! (`exec.rs`) moves with the data and fixes where data decides something.

use super::*;
use crate::replay::replay_state;

/// The lanes of a [`Fifo`]'s words (`crate::lanes`), kept as its words are: pushed at the
/// FIFO's length before the push, popped from the front.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct FifoLanes(pub(super) [Word; 8]);

impl FifoLanes {
    /// The lanes of the word pushed onto a FIFO of `len` words.
    pub(super) fn push(&mut self, len: usize, w: Word) {
        if let Some(slot) = self.0.get_mut(len) {
            *slot = w;
        }
    }
    /// The lanes of the word popped from a FIFO that held one.
    pub(super) fn pop(&mut self) -> Word {
        let w = self.0[0];
        self.0.copy_within(1.., 0);
        self.0[7] = CONST;
        w
    }
}

/// A state machine's lanes while a replay is recorded (`crate::lanes`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct SmLanes {
    pub(super) x: Word,
    pub(super) y: Word,
    pub(super) isr: Word,
    pub(super) osr: Word,
    pub(super) tx: FifoLanes,
    pub(super) rx: FifoLanes,
}

/// A block's lanes while a replay is recorded (`crate::lanes`): its state machines', and per
/// GPIO (bit n: GPIO n) the pins' output levels, the input synchroniser's flops and what the
/// state machines see in this cycle.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct PioLanes {
    pub(super) sm: [SmLanes; 4],
    /// The state machines' output levels.
    pub(crate) out: Word,
    pub(super) sync: [Word; 2],
    pub(super) seen: Word,
    /// The GPIO inputs of the coming [`Pio::tick`] (what the converters drive).
    pub(crate) gpio_in: Word,
    /// Per state machine, the levels its instruction of this cycle writes to the pins
    /// ([`Effects`]' `values`).
    pub(super) pend: [Word; 4],
    /// The last word read from an RX FIFO through the bus ([`Pio::read`]), and the next one
    /// written to a TX FIFO ([`Pio::write`]; constants unless a DMA write sets it).
    pub(crate) last_read: Word,
    pub(crate) next_write: Word,
    /// The lanes data decided something with.
    pub(crate) fixed: Vec<Fixed>,
}

impl PioLanes {
    pub(super) fn new() -> Self {
        let sm = SmLanes {
            x: CONST,
            y: CONST,
            isr: CONST,
            osr: CONST,
            tx: FifoLanes([CONST; 8]),
            rx: FifoLanes([CONST; 8]),
        };
        PioLanes {
            sm: std::array::from_fn(|_| sm.clone()),
            out: CONST,
            sync: [CONST; 2],
            seen: CONST,
            gpio_in: CONST,
            pend: [CONST; 4],
            last_read: CONST,
            next_write: CONST,
            fixed: Vec::new(),
        }
    }
}

/// The lanes of an `OUT`'s data ([`StateMachine::out_data`]).
pub(super) fn out_lanes(osr: &Word, count: u32, right: bool) -> Word {
    match (right, count) {
        (_, 32) => *osr,
        (true, _) => lanes::and(osr, (1 << count) - 1),
        (false, _) => lanes::shr(osr, 32 - count),
    }
}

/// The lanes of the OSR after an `OUT` ([`StateMachine::osr_after`]).
pub(super) fn osr_after_lanes(osr: &Word, bits: u32, right: bool) -> Word {
    match (right, bits) {
        (_, 32..) => CONST,
        (true, b) => lanes::shr(osr, b),
        (false, b) => lanes::shl(osr, b),
    }
}

/// The lanes of the ISR after an `IN` of `data`'s lanes ([`StateMachine::shift_in`]).
pub(super) fn shift_in_lanes(isr: &Word, count: u32, data: &Word, right: bool) -> Word {
    let data = match count {
        32 => *data,
        _ => lanes::and(data, (1 << count) - 1),
    };
    match (right, count) {
        (_, 32) => data,
        (true, _) => lanes::select(
            !0u32 << (32 - count),
            &lanes::shl(&data, 32 - count),
            &lanes::shr(isr, count),
        ),
        (false, _) => lanes::select((1 << count) - 1, &data, &lanes::shl(isr, count)),
    }
}

/// The lanes of the pins [`StateMachine::map`] gives for a value with lanes `w`.
pub(super) fn map_lanes(base: u32, count: u32, w: &Word) -> Word {
    let mask = if count >= 32 {
        u32::MAX
    } else {
        (1u32 << count) - 1
    };
    lanes::rotl(&lanes::and(w, mask), base)
}

// The replay's view of a block (`crate::replay::ReplayState`): every field given its role once.
replay_state! { Fifo {
    same: len;
    data: words;
} }

replay_state! { StateMachine {
    same: clkdiv, execctrl, shiftctrl, pinctrl, pc, isr_count, osr_count, delay, exec,
        current, acc, irq_waiting, stalled;
    part: tx, rx;
    data: x, y, isr, osr;
} }

// The lanes are left as they are (none outside a recording).
replay_state! { Pio {
    same: instr, enabled, irq, sync_bypass, out_dirs, config_epoch;
    part: sm;
    data: sync, out_values;
    skip: lanes;
} }

impl Pio {
    /// Sets its `i`-th data word ([`Pio::data_slots`]' order, `i` below [`Pio::SLOTS`]).
    #[inline]
    pub(crate) fn set_slot(&mut self, i: usize, v: u32) {
        if let Some(w) = self.slot_mut(i) {
            *w = v;
        }
    }

    /// Its `i`-th data word ([`Pio::data_slots`]' order; 0 past them).
    #[inline]
    pub(crate) fn slot(&self, i: usize) -> u32 {
        match i {
            0 => self.out_values,
            1 | 2 => self.sync[i - 1],
            _ => {
                let Some(s) = self.sm.get((i - 3) / 20) else {
                    return 0;
                };
                match (i - 3) % 20 {
                    0 => s.x,
                    1 => s.y,
                    2 => s.isr,
                    3 => s.osr,
                    k @ 4..=11 => s.tx.words[k - 4],
                    k => s.rx.words[k - 12],
                }
            }
        }
    }

    #[inline]
    pub(super) fn slot_mut(&mut self, i: usize) -> Option<&mut u32> {
        match i {
            0 => Some(&mut self.out_values),
            1 | 2 => Some(&mut self.sync[i - 1]),
            _ => {
                let s = self.sm.get_mut((i - 3) / 20)?;
                Some(match (i - 3) % 20 {
                    0 => &mut s.x,
                    1 => &mut s.y,
                    2 => &mut s.isr,
                    3 => &mut s.osr,
                    k @ 4..=11 => &mut s.tx.words[k - 4],
                    k => &mut s.rx.words[k - 12],
                })
            }
        }
    }

    /// Its data words' number ([`Pio::data_slots`]).
    pub(crate) const SLOTS: usize = 3 + 4 * 20;

    /// Mixes some of its control state (none of its data words) into `mix`: a cheap first
    /// test of two blocks' equality but for data (`crate::io::Io::quick_key`).
    pub(crate) fn quick_key(&self, mix: &mut impl FnMut(u64)) {
        for s in &self.sm {
            mix(u64::from(s.pc) | u64::from(s.acc) << 8 | u64::from(s.delay) << 40);
            mix(u64::from(s.isr_count)
                | u64::from(s.osr_count) << 8
                | u64::from(s.tx.len) << 16
                | u64::from(s.rx.len) << 24);
        }
        mix(u64::from(self.out_dirs) | u64::from(self.enabled) << 32);
    }

    /// Starts keeping lanes (`crate::lanes`), all constants (`crate::io::Io` gives its data
    /// words theirs through [`Pio::data_slots`]).
    pub(crate) fn start_lanes(&mut self) {
        self.lanes = Some(Box::new(PioLanes::new()));
    }

    /// While lanes are kept: the words of each FIFO past its length, 0 by the FIFOs'
    /// invariant, get constant lanes.
    pub(crate) fn const_fifo_tails(&mut self) {
        let Some(l) = self.lanes.as_deref_mut() else {
            return;
        };
        for (s, sl) in self.sm.iter().zip(&mut l.sm) {
            debug_assert!(s.tx.words[s.tx.len()..].iter().all(|&w| w == 0));
            debug_assert!(s.rx.words[s.rx.len()..].iter().all(|&w| w == 0));
            sl.tx.0[s.tx.len()..].fill(CONST);
            sl.rx.0[s.rx.len()..].fill(CONST);
        }
    }

    /// Its data words in a fixed order, each with its lanes while they are kept (`crate::io::Io::data_slots`):
    /// the pins' output levels, the synchroniser's two flops, then per state machine X, Y,
    /// ISR, OSR and its TX and RX FIFOs' eight words each.
    pub(crate) fn data_slots(&mut self, f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>)) {
        let mut l = self.lanes.as_deref_mut();
        f(
            &mut self.out_values,
            l.as_deref_mut().map(|l| &mut l.out[..]),
        );
        for k in 0..2 {
            f(
                &mut self.sync[k],
                l.as_deref_mut().map(|l| &mut l.sync[k][..]),
            );
        }
        for (n, s) in self.sm.iter_mut().enumerate() {
            let mut sl = l.as_deref_mut().map(|l| &mut l.sm[n]);
            f(&mut s.x, sl.as_deref_mut().map(|l| &mut l.x[..]));
            f(&mut s.y, sl.as_deref_mut().map(|l| &mut l.y[..]));
            f(&mut s.isr, sl.as_deref_mut().map(|l| &mut l.isr[..]));
            f(&mut s.osr, sl.as_deref_mut().map(|l| &mut l.osr[..]));
            for i in 0..8 {
                f(
                    &mut s.tx.words[i],
                    sl.as_deref_mut().map(|l| &mut l.tx.0[i][..]),
                );
            }
            for i in 0..8 {
                f(
                    &mut s.rx.words[i],
                    sl.as_deref_mut().map(|l| &mut l.rx.0[i][..]),
                );
            }
        }
    }
}
