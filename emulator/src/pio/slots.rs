//! What a window's replay and the period memo need of a PIO block (`crate::io::slots`): its
//! data words (the pins' levels, the input synchroniser, each state machine's X, Y, ISR, OSR
//! and FIFO words) in a fixed order, the block compared and taken but for them (its
//! `crate::replay::Data` and `ReplayState`, both from each field's role declared once), and,
//! while a replay is recorded, the lanes of each data bit (`crate::lanes`: [`PioLanes`],
//! each at its data field's name) that the execution (`exec.rs`) moves with the data and
//! fixes where data decides something.

use super::*;
use crate::replay::replay_state;

/// The lanes of a [`Fifo`]'s words (`crate::lanes`), kept as its words are: pushed at the
/// FIFO's length before the push, popped from the front.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct FifoLanes {
    pub(super) words: [Word; 8],
}

impl FifoLanes {
    /// The lanes of the word pushed onto a FIFO of `len` words.
    pub(super) fn push(&mut self, len: usize, w: Word) {
        if let Some(slot) = self.words.get_mut(len) {
            *slot = w;
        }
    }
    /// The lanes of the word popped from a FIFO that held one.
    pub(super) fn pop(&mut self) -> Word {
        let w = self.words[0];
        self.words.copy_within(1.., 0);
        self.words[7] = CONST;
        w
    }

    /// Every word constant (an empty FIFO's).
    pub(super) const CONST: FifoLanes = FifoLanes { words: [CONST; 8] };
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
    pub(crate) out_values: Word,
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
            tx: FifoLanes::CONST,
            rx: FifoLanes::CONST,
        };
        PioLanes {
            sm: std::array::from_fn(|_| sm.clone()),
            out_values: CONST,
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

// The replay's view of a block (`crate::replay::ReplayState`): every field given its role
// once. Its data words (`crate::io::Io::data_slots`), in order: the pins' output levels, the
// synchroniser's two flops, then per state machine X, Y, ISR, OSR and its TX and RX FIFOs'
// eight words each.
replay_state! { Fifo [given: FifoLanes, words] {
    same: len;
    data: words;
} }

replay_state! { StateMachine [given: SmLanes, words] {
    same: clkdiv, execctrl, shiftctrl, pinctrl, pc, isr_count, osr_count, delay, exec,
        current, acc, irq_waiting, stalled;
    data: x, y, isr, osr;
    part: tx, rx;
} }

// The lanes are left as they are (none outside a recording).
replay_state! { Pio [kept in lanes: PioLanes, words] {
    same: instr, enabled, irq, sync_bypass, out_dirs, config_epoch;
    data: out_values, sync;
    part: sm;
    skip: lanes;
} }

impl Pio {
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
    /// words theirs through [`crate::replay::Data`]).
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
            sl.tx.words[s.tx.len()..].fill(CONST);
            sl.rx.words[s.rx.len()..].fill(CONST);
        }
    }
}
