//! One RP2040 PIO block (PIO0 at 0x50200000, PIO1 at 0x50300000; RP2040 datasheet
//! chapter 3): four state machines sharing 32 instruction words, each with its clock
//! divider, scratch registers X and Y, shift registers ISR and OSR with their counters and
//! autopush/autopull, 4-word TX and RX FIFOs (joinable to 8), side-set and delay, the eight
//! IRQ flags, and the GPIO they drive and sample.
//!
//! This is the model issue 40's converter drivers run on: a board's firmware clocks its
//! SPI ADC and DAC frames out of state machines (`tactus_runtime::converters`), so the
//! emulator must give each frame's edges at the cycle the chip would. The model is stepped
//! once per system clock cycle ([`Pio::tick`]) with the GPIO input levels of that cycle; it
//! returns nothing, and the pins it drives are read with [`Pio::pin_values`] and
//! [`Pio::pin_dirs`]. Its registers are read and written through [`Pio::read`] and
//! [`Pio::write`] (offsets of datasheet 3.7); the DMA request lines are [`Pio::tx_dreq`] and
//! [`Pio::rx_dreq`] (datasheet 2.5.3.1: TX while the TX FIFO is not full, RX while the RX
//! FIFO is not empty).
//!
//! What each cycle does, as datasheet 3.4 and 3.5 give it:
//! - The clock divider (SMx_CLKDIV, INT + FRAC/256, INT 0 meaning 65536) enables the state
//!   machine on average once every INT + FRAC/256 cycles: a first-order fractional divider
//!   (an accumulator of 256 a cycle against the divisor). Its phase after CLKDIV_RESTART is
//!   this model's choice; the datasheet does not give it.
//! - On an enabled cycle, a pending delay counts down; otherwise the instruction at PC (or
//!   one forced through SMx_INSTR, OUT EXEC or MOV EXEC, which moves PC only if it jumps)
//!   runs. Its side-set is asserted whether or not it stalls (3.5.1); a stalled
//!   instruction runs again on the next enabled cycle and its delay starts only once it
//!   completes; PC advances through the wrap (EXECCTRL WRAP_TOP → WRAP_BOTTOM).
//! - Autopull and autopush follow the pseudocode of 3.5.4.1 and 3.5.4.2: an OUT with the
//!   OSR at its threshold refills it and stalls that cycle (an empty OSR cannot be filled
//!   and shifted out in one cycle), and on every other cycle an OSR at its threshold refills
//!   from a non-empty TX FIFO; an IN that reaches the push threshold with the RX FIFO full
//!   stalls (modelled as not shifting until the push can happen, so its retry is the same
//!   instruction).
//! - GPIO inputs pass a two-flop synchroniser (3.5.6.3) unless INPUT_SYNC_BYPASS has the
//!   pin: a state machine sees a level two cycles after it is applied.
//! - When several state machines write one pin in a cycle, the highest-numbered wins
//!   (3.5.6.1).
//!
//! Not modelled yet: the interrupt outputs (IRQ0/IRQ1 INTE/INTF/INTS), FDEBUG's stall and
//! overflow flags, EXECCTRL's OUT_STICKY and INLINE_OUT_EN. On the bus, `crate::io` runs
//! both blocks, skipping stretches in which every enabled state machine stalls without
//! effect ([`Pio::quiet`], [`Pio::skip`]).

use crate::lanes::{self, Fixed, Lane, Word, CONST};
use tactus_rp2040::pio::{reg, CLKDIV_RESET, EXECCTRL_RESET, PINCTRL_RESET, SHIFTCTRL_RESET};

/// Bits `lo..lo+n` of `v`.
fn bits(v: u32, lo: u32, n: u32) -> u32 {
    (v >> lo) & ((1u32 << n) - 1)
}

/// A bit count field where 0 means 32.
fn count32(c: u32) -> u32 {
    if c == 0 {
        32
    } else {
        c
    }
}

/// A FIFO of up to 8 words, kept in place (a copy, not an allocation, when the machine is
/// cloned: a window's checkpoint, `crate::io::Io::checkpoint`): the oldest first in
/// `words[..len]`, the rest 0, so that equal contents are equal states.
#[derive(Clone, Copy, Default, PartialEq, Eq)]
struct Fifo {
    words: [u32; 8],
    len: u8,
}

impl std::fmt::Debug for Fifo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Fifo")
            .field("words", &&self.words[..self.len()])
            .finish()
    }
}

impl Fifo {
    fn len(&self) -> usize {
        usize::from(self.len)
    }
    fn is_empty(&self) -> bool {
        self.len == 0
    }
    fn pop(&mut self) -> Option<u32> {
        if self.len == 0 {
            return None;
        }
        let w = self.words[0];
        self.words.copy_within(1.., 0);
        self.words[7] = 0;
        self.len -= 1;
        Some(w)
    }
    /// Appends `w`; a caller checks the depth first (at most 8: the FIFOs joined).
    fn push(&mut self, w: u32) {
        debug_assert!(self.len() < 8);
        let len = self.len();
        if let Some(slot) = self.words.get_mut(len) {
            *slot = w;
            self.len += 1;
        }
    }
    fn clear(&mut self) {
        *self = Fifo::default();
    }
}

/// The lanes of a [`Fifo`]'s words (`crate::lanes`), kept as its words are: pushed at the
/// FIFO's length before the push, popped from the front.
#[derive(Clone, Debug, PartialEq, Eq)]
struct FifoLanes([Word; 8]);

impl FifoLanes {
    /// The lanes of the word pushed onto a FIFO of `len` words.
    fn push(&mut self, len: usize, w: Word) {
        if let Some(slot) = self.0.get_mut(len) {
            *slot = w;
        }
    }
    /// The lanes of the word popped from a FIFO that held one.
    fn pop(&mut self) -> Word {
        let w = self.0[0];
        self.0.copy_within(1.., 0);
        self.0[7] = CONST;
        w
    }
}

/// A state machine's lanes while a replay is recorded (`crate::lanes`).
#[derive(Clone, Debug, PartialEq, Eq)]
struct SmLanes {
    x: Word,
    y: Word,
    isr: Word,
    osr: Word,
    tx: FifoLanes,
    rx: FifoLanes,
}

/// A block's lanes while a replay is recorded (`crate::lanes`): its state machines', and per
/// GPIO (bit n: GPIO n) the pins' output levels, the input synchroniser's flops and what the
/// state machines see in this cycle.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct PioLanes {
    sm: [SmLanes; 4],
    /// The state machines' output levels.
    pub(crate) out: Word,
    sync: [Word; 2],
    seen: Word,
    /// The GPIO inputs of the coming [`Pio::tick`] (what the converters drive).
    pub(crate) gpio_in: Word,
    /// Per state machine, the levels its instruction of this cycle writes to the pins
    /// ([`Effects`]' `values`).
    pend: [Word; 4],
    /// The last word read from an RX FIFO through the bus ([`Pio::read`]), and the next one
    /// written to a TX FIFO ([`Pio::write`]; constants unless a DMA write sets it).
    pub(crate) last_read: Word,
    pub(crate) next_write: Word,
    /// The lanes data decided something with.
    pub(crate) fixed: Vec<Fixed>,
}

impl PioLanes {
    fn new() -> Self {
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
fn out_lanes(osr: &Word, count: u32, right: bool) -> Word {
    match (right, count) {
        (_, 32) => *osr,
        (true, _) => lanes::and(osr, (1 << count) - 1),
        (false, _) => lanes::shr(osr, 32 - count),
    }
}

/// The lanes of the OSR after an `OUT` ([`StateMachine::osr_after`]).
fn osr_after_lanes(osr: &Word, bits: u32, right: bool) -> Word {
    match (right, bits) {
        (_, 32..) => CONST,
        (true, b) => lanes::shr(osr, b),
        (false, b) => lanes::shl(osr, b),
    }
}

/// The lanes of the ISR after an `IN` of `data`'s lanes ([`StateMachine::shift_in`]).
fn shift_in_lanes(isr: &Word, count: u32, data: &Word, right: bool) -> Word {
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
fn map_lanes(base: u32, count: u32, w: &Word) -> Word {
    let mask = if count >= 32 {
        u32::MAX
    } else {
        (1u32 << count) - 1
    };
    lanes::rotl(&lanes::and(w, mask), base)
}

/// One state machine.
#[derive(Clone, Debug, PartialEq, Eq)]
struct StateMachine {
    clkdiv: u32,
    execctrl: u32,
    shiftctrl: u32,
    pinctrl: u32,
    pc: u32,
    x: u32,
    y: u32,
    isr: u32,
    osr: u32,
    isr_count: u32,
    osr_count: u32,
    tx: Fifo,
    rx: Fifo,
    /// Delay cycles left of the last instruction.
    delay: u32,
    /// An instruction to run instead of the one at PC (SMx_INSTR, OUT/MOV EXEC).
    exec: Option<u16>,
    /// The instruction last executed or stalled (SMx_INSTR reads it).
    current: u16,
    /// The clock divider's accumulator, in 1/256 cycle.
    acc: u32,
    /// An `IRQ … wait` that has set its flag and waits for it to clear.
    irq_waiting: bool,
    /// The last enabled cycle ran an instruction that stalled, with these pin effects (its
    /// side-set): what [`Pio::quiet`] needs to know that running it again changes nothing.
    stalled: Option<Effects>,
}

impl StateMachine {
    /// Whether it equals `other` but for its data words (X, Y, ISR, OSR, the FIFOs'
    /// words): every other field named.
    fn eq_but_data(&self, other: &StateMachine) -> bool {
        let StateMachine {
            clkdiv,
            execctrl,
            shiftctrl,
            pinctrl,
            pc,
            x: _,
            y: _,
            isr: _,
            osr: _,
            isr_count,
            osr_count,
            tx,
            rx,
            delay,
            exec,
            current,
            acc,
            irq_waiting,
            stalled,
        } = self;
        *clkdiv == other.clkdiv
            && *execctrl == other.execctrl
            && *shiftctrl == other.shiftctrl
            && *pinctrl == other.pinctrl
            && *pc == other.pc
            && *isr_count == other.isr_count
            && *osr_count == other.osr_count
            && tx.len == other.tx.len
            && rx.len == other.rx.len
            && *delay == other.delay
            && *exec == other.exec
            && *current == other.current
            && *acc == other.acc
            && *irq_waiting == other.irq_waiting
            && *stalled == other.stalled
    }

    /// Becomes `other` but for its data words, which stay: every other field named.
    fn assign_but_data(&mut self, other: &StateMachine) {
        let StateMachine {
            clkdiv,
            execctrl,
            shiftctrl,
            pinctrl,
            pc,
            x: _,
            y: _,
            isr: _,
            osr: _,
            isr_count,
            osr_count,
            tx,
            rx,
            delay,
            exec,
            current,
            acc,
            irq_waiting,
            stalled,
        } = other;
        self.clkdiv = *clkdiv;
        self.execctrl = *execctrl;
        self.shiftctrl = *shiftctrl;
        self.pinctrl = *pinctrl;
        self.pc = *pc;
        self.isr_count = *isr_count;
        self.osr_count = *osr_count;
        self.tx.len = tx.len;
        self.rx.len = rx.len;
        self.delay = *delay;
        self.exec = *exec;
        self.current = *current;
        self.acc = *acc;
        self.irq_waiting = *irq_waiting;
        self.stalled = *stalled;
    }

    fn new() -> Self {
        StateMachine {
            clkdiv: CLKDIV_RESET,
            execctrl: EXECCTRL_RESET,
            shiftctrl: SHIFTCTRL_RESET,
            pinctrl: PINCTRL_RESET,
            pc: 0,
            x: 0,
            y: 0,
            isr: 0,
            osr: 0,
            isr_count: 0,
            osr_count: 32,
            tx: Fifo::default(),
            rx: Fifo::default(),
            delay: 0,
            exec: None,
            current: 0,
            acc: 0,
            irq_waiting: false,
            stalled: None,
        }
    }

    /// The FIFO depths (TX, RX): 4 each, or 8 and 0 when joined (SHIFTCTRL FJOIN_TX bit 30,
    /// FJOIN_RX bit 31).
    fn depths(&self) -> (usize, usize) {
        match (self.shiftctrl >> 30) & 3 {
            1 => (8, 0),
            2 => (0, 8),
            _ => (4, 4),
        }
    }
    fn tx_full(&self) -> bool {
        self.tx.len() >= self.depths().0
    }
    fn rx_full(&self) -> bool {
        self.rx.len() >= self.depths().1
    }
    fn autopush(&self) -> bool {
        self.shiftctrl & (1 << 16) != 0
    }
    fn autopull(&self) -> bool {
        self.shiftctrl & (1 << 17) != 0
    }
    fn in_right(&self) -> bool {
        self.shiftctrl & (1 << 18) != 0
    }
    fn out_right(&self) -> bool {
        self.shiftctrl & (1 << 19) != 0
    }
    fn push_thresh(&self) -> u32 {
        count32(bits(self.shiftctrl, 20, 5))
    }
    fn pull_thresh(&self) -> u32 {
        count32(bits(self.shiftctrl, 25, 5))
    }
    fn wrap_top(&self) -> u32 {
        bits(self.execctrl, 12, 5)
    }
    fn wrap_bottom(&self) -> u32 {
        bits(self.execctrl, 7, 5)
    }
    fn sideset_count(&self) -> u32 {
        bits(self.pinctrl, 29, 3)
    }
    fn side_en(&self) -> bool {
        self.execctrl & (1 << 30) != 0
    }
    fn side_pindir(&self) -> bool {
        self.execctrl & (1 << 29) != 0
    }

    /// Instruction `ins`'s side-set as (mask, levels) of the pins it sets ((0, 0) for none)
    /// and its delay (datasheet 3.5.1: the delay/side-set field's SIDESET_COUNT high bits,
    /// the first an enable with SIDE_EN).
    fn side_set(&self, ins: u16) -> ((u32, u32), u32) {
        let field = bits(u32::from(ins), 8, 5);
        let count = self.sideset_count();
        let delay_bits = 5 - count.min(5);
        let delay = bits(field, 0, delay_bits);
        let side_bits = if self.side_en() {
            count.saturating_sub(1)
        } else {
            count
        };
        let side_on = !self.side_en() || (count > 0 && field & (1 << 4) != 0);
        if side_on && side_bits > 0 {
            let side = bits(field >> delay_bits, 0, side_bits);
            (
                StateMachine::map(bits(self.pinctrl, 10, 5), side_bits, side),
                delay,
            )
        } else {
            ((0, 0), delay)
        }
    }

    /// The `count` bits an `OUT` takes from an OSR holding `osr` (0 < count ≤ 32), shifting
    /// left (MSB first) or right (datasheet 3.5.4).
    fn out_data(osr: u32, count: u32, right: bool) -> u32 {
        match (right, count) {
            (_, 32) => osr,
            (true, _) => osr & ((1 << count) - 1),
            (false, _) => osr >> (32 - count),
        }
    }

    /// An OSR holding `osr` after `bits` bits have been shifted out of it (any number: the
    /// shifts of several `OUT`s add up, zeros coming in).
    fn osr_after(osr: u32, bits: u64, right: bool) -> u32 {
        match (right, bits) {
            (_, 32..) => 0,
            (true, b) => osr >> b,
            (false, b) => osr << b,
        }
    }

    /// An `OUT` of `count` bits (0 < count ≤ 32) without autopull: the data, the OSR shifted
    /// and its counter saturating at 32.
    fn shift_out(&mut self, count: u32) -> u32 {
        let right = self.out_right();
        let data = StateMachine::out_data(self.osr, count, right);
        self.osr = StateMachine::osr_after(self.osr, u64::from(count), right);
        self.osr_count = (self.osr_count + count).min(32);
        data
    }

    /// An `IN` of the low `count` bits of `data` (0 < count ≤ 32) without autopush: the ISR
    /// shifted and its counter saturating at 32.
    fn shift_in(&mut self, count: u32, data: u32) {
        let data = if count == 32 {
            data
        } else {
            data & ((1 << count) - 1)
        };
        self.isr = match (self.in_right(), count) {
            (_, 32) => data,
            (true, _) => (self.isr >> count) | (data << (32 - count)),
            (false, _) => (self.isr << count) | data,
        };
        self.isr_count = (self.isr_count + count).min(32);
    }

    /// The divisor in 1/256 cycle (INT 0 is 65536).
    fn divisor(&self) -> u32 {
        let int = self.clkdiv >> 16;
        let frac = bits(self.clkdiv, 8, 8);
        let int = if int == 0 { 65_536 } else { int };
        int * 256 + frac
    }

    /// The pins of `value` (a word whose low `count` bits go to pins `base..`, wrapping at
    /// 32) as (mask, levels).
    fn map(base: u32, count: u32, value: u32) -> (u32, u32) {
        let mask = if count >= 32 {
            u32::MAX
        } else {
            (1u32 << count) - 1
        };
        ((mask).rotate_left(base), (value & mask).rotate_left(base))
    }

    /// OUT's and MOV's destinations 0 (the OUT pins), 1 (X) and 2 (Y).
    fn write_pins_x_y(&mut self, dest: u32, v: u32, fx: &mut Effects) -> Flow {
        match dest {
            0 => {
                let (base, count) = (bits(self.pinctrl, 0, 5), bits(self.pinctrl, 20, 6));
                fx.values = StateMachine::map(base, count, v);
            }
            1 => self.x = v,
            _ => self.y = v,
        }
        Flow::Next
    }

    fn advance(&mut self) {
        self.pc = if self.pc == self.wrap_top() {
            self.wrap_bottom()
        } else {
            (self.pc + 1) & 31
        };
    }

    fn restart(&mut self) {
        self.stalled = None;
        self.isr = 0;
        self.isr_count = 0;
        self.osr_count = 32;
        self.delay = 0;
        self.exec = None;
        self.irq_waiting = false;
    }
}

/// What one instruction did to the pins in a cycle: (mask, levels) written to the pin
/// values and directions by the instruction (OUT, SET, MOV) and by its side-set, which
/// wins where both write a pin (datasheet 3.5.6.1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Effects {
    values: (u32, u32),
    dirs: (u32, u32),
    side_values: (u32, u32),
    side_dirs: (u32, u32),
}

/// Most instructions of a [`BitLoop`], its `JMP X--` included.
pub const LOOP_MAX: usize = 8;

/// One instruction of a [`BitLoop`], decoded once.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct LoopStep {
    /// The instruction word (what SMx_INSTR reads after it).
    word: u16,
    /// System cycles from the start of a time round to this instruction's.
    at: u64,
    /// The pins `SET PINS` sets (mask, levels).
    set: (u32, u32),
    /// The pins its side-set sets (mask, levels): they win over the instruction's own.
    side: (u32, u32),
    /// `OUT`'s bit count (0: not an `OUT`), the pins it sets (0 for `OUT NULL`), and the
    /// bits a time round shifts out of the OSR before it.
    out: u32,
    out_mask: u32,
    out_at: u32,
    /// `IN`'s bit count (0: not an `IN`), and whether it reads the pins (`IN PINS, 1`; else
    /// `IN NULL`).
    inn: u32,
    in_pins: bool,
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
    jmp: u32,
    /// System cycles of one time round.
    pub period: u64,
    len: usize,
    steps: [LoopStep; LOOP_MAX],
    /// Bits shifted out of the OSR each time round, and into the ISR.
    out_bits: u64,
    in_bits: u32,
    /// `OUT PINS`' pins: PINCTRL's OUT_BASE and OUT_COUNT.
    out_map: (u32, u32),
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

/// One PIO block. See the module documentation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pio {
    instr: [u16; 32],
    sm: [StateMachine; 4],
    /// SM_ENABLE bits.
    enabled: u32,
    irq: u8,
    sync_bypass: u32,
    /// The synchroniser's two flops: what the state machines see is `sync[1]`.
    sync: [u32; 2],
    /// Pin output levels and directions as the state machines left them.
    out_values: u32,
    out_dirs: u32,
    /// Register writes other than to a TX FIFO or the IRQ flags, counted: what
    /// [`Pio::sm_pins`] answers changes only with it.
    config_epoch: u64,
    /// Its lanes while a replay is recorded (`crate::lanes`); `None` otherwise.
    pub(crate) lanes: Option<Box<PioLanes>>,
}

impl Default for Pio {
    fn default() -> Self {
        Self::new()
    }
}

impl Pio {
    /// A PIO block out of reset: every state machine disabled, its registers at their reset
    /// values, the FIFOs empty, pins low and inputs.
    pub fn new() -> Self {
        Pio {
            instr: [0; 32],
            sm: std::array::from_fn(|_| StateMachine::new()),
            enabled: 0,
            irq: 0,
            sync_bypass: 0,
            sync: [0; 2],
            out_values: 0,
            out_dirs: 0,
            config_epoch: 0,
            lanes: None,
        }
    }

    /// The output levels the state machines drive (bit n: GPIO n), whatever the pin's
    /// direction.
    pub fn pin_values(&self) -> u32 {
        self.out_values
    }

    /// The pin directions the state machines set (bit n: GPIO n is an output).
    pub fn pin_dirs(&self) -> u32 {
        self.out_dirs
    }

    /// Whether state machine `sm` (0–3) requests a DMA write: its TX FIFO is not full.
    pub fn tx_dreq(&self, sm: usize) -> bool {
        self.sm.get(sm).is_some_and(|s| !s.tx_full())
    }

    /// Whether state machine `sm` (0–3) requests a DMA read: its RX FIFO is not empty.
    pub fn rx_dreq(&self, sm: usize) -> bool {
        self.sm.get(sm).is_some_and(|s| !s.rx.is_empty())
    }

    /// How many more words state machine `sm`'s TX FIFO takes now (its free entries; 0 for
    /// no such machine): the DMA's credits on its TX DREQ (datasheet 2.5.3.2).
    pub fn tx_room(&self, sm: usize) -> u32 {
        self.sm
            .get(sm)
            .map_or(0, |s| s.depths().0.saturating_sub(s.tx.len()) as u32)
    }

    /// How many words state machine `sm`'s RX FIFO holds (0 for no such machine): the DMA's
    /// credits on its RX DREQ.
    pub fn rx_level(&self, sm: usize) -> u32 {
        self.sm.get(sm).map_or(0, |s| s.rx.len() as u32)
    }

    /// Whether running the block changes nothing while its FIFOs, its IRQ flags and the GPIO
    /// inputs stay as they are: every enabled state machine is stalled (on its last enabled
    /// cycle) on an instruction that stalls again without touching any state — `PULL
    /// block` or an autopulling `OUT` on an empty TX FIFO, `PUSH block` or an autopushing
    /// `IN` on a full RX FIFO, an unmet `WAIT`, an `IRQ wait` whose flag is still set — and
    /// whose side-set leaves the pins as they are. Then only the clock dividers and the input
    /// synchroniser move, which [`Pio::skip`] does in one step. (The caller keeps the FIFOs,
    /// flags and inputs as they are: nothing else runs against the block meanwhile.)
    pub fn quiet(&self) -> bool {
        (0..4).all(|n| self.enabled & (1 << n) == 0 || self.stable_stall(n))
    }

    /// How many of the coming system cycles change nothing while the FIFOs stay as they
    /// are but the clock dividers and pending delays: until the first in which an enabled
    /// state machine that is not stalled on a FIFO ([`Pio::quiet`]'s `PULL`/`OUT` on an
    /// empty TX FIFO, `PUSH`/`IN` on a full RX FIFO) runs an instruction — its next enabled
    /// cycle, or the one after its delay's (0: the next cycle); `u64::MAX` when there is
    /// none. [`Pio::skip`] advances the block over them exactly.
    pub fn idle_cycles(&self) -> u64 {
        let mut idle = u64::MAX;
        for n in 0..4 {
            if self.enabled & (1 << n) == 0 {
                continue;
            }
            let s = &self.sm[n];
            if self.fifo_stall(n) {
                continue;
            }
            // The enabled cycle that runs an instruction: the next one, or after a pending
            // delay the (delay + 1)-th, when its delay cycles do nothing else (no forced
            // instruction, no autopull that could refill the OSR meanwhile).
            let j = match s.delay > 0 && s.exec.is_none() && !s.autopull() {
                true => u64::from(s.delay) + 1,
                false => 1,
            };
            // The first k ≥ 0 with acc + 256·(k + 1) ≥ j·divisor.
            let k = (j * u64::from(s.divisor()) - u64::from(s.acc)).div_ceil(256) - 1;
            idle = idle.min(k);
        }
        idle
    }

    /// Whether state machine `n` is stalled on a FIFO as [`Pio::quiet`] says: `PULL` or an
    /// autopulling `OUT` on an empty TX FIFO, `PUSH` or an autopushing `IN` on a full RX
    /// FIFO; it stalls again, without effect, until that FIFO changes.
    fn fifo_stall(&self, n: usize) -> bool {
        matches!(u32::from(self.sm[n].current) >> 13, 2..=4) && self.stable_stall(n)
    }

    /// Whether state machine `n` is stalled as [`Pio::quiet`] says.
    fn stable_stall(&self, n: usize) -> bool {
        let s = &self.sm[n];
        let Some(fx) = s.stalled else {
            return false;
        };
        if s.delay > 0 || s.exec.is_some() || self.instr[s.pc as usize] != s.current {
            return false;
        }
        let unchanged = |old: u32, (m, v): (u32, u32)| old & !m | v == old;
        if !unchanged(self.out_values, fx.side_values) || !unchanged(self.out_dirs, fx.side_dirs) {
            return false;
        }
        // A stalled cycle other than an OUT's or IN's may autopull (`background_pull`).
        let refills = s.autopull() && s.osr_count >= s.pull_thresh() && !s.tx.is_empty();
        // Each case: the instruction's stall condition holds now (a stall that refilled
        // the OSR, say, does not repeat).
        let ins = u32::from(s.current);
        let if_flag = ins & 0x40 != 0;
        match ins >> 13 {
            // WAIT: its condition is re-evaluated against the same flags and inputs.
            1 => !refills,
            // IN stalls only autopushing into a full RX FIFO.
            2 => {
                let after = (s.isr_count + count32(bits(ins, 0, 5))).min(32);
                s.autopush() && after >= s.push_thresh() && s.rx_full()
            }
            // OUT stalls only autopulling from an empty TX FIFO.
            3 => s.autopull() && s.osr_count >= s.pull_thresh() && s.tx.is_empty(),
            // PULL block on an empty TX FIFO; PUSH block on a full RX FIFO.
            4 if ins & 0x80 != 0 => s.tx.is_empty() && !(if_flag && s.osr_count < s.pull_thresh()),
            4 => s.rx_full() && !(if_flag && s.isr_count < s.push_thresh()) && !refills,
            // IRQ wait: its flag still set.
            6 => s.irq_waiting && !refills,
            _ => false,
        }
    }

    /// Advances a [`Pio::quiet`] block `cycles` system cycles, or any block at most
    /// [`Pio::idle_cycles`], with the GPIO inputs `gpio_in` throughout: exactly what as many
    /// [`Pio::tick`]s would do (the clock dividers' accumulators, the pending delays, the
    /// synchroniser; the stalled instructions change nothing, the others do not run).
    pub fn skip(&mut self, cycles: u64, gpio_in: u32) {
        debug_assert!(
            self.lanes.is_none(),
            "lanes are kept on the stepwise path only"
        );
        match cycles {
            0 => return,
            1 => self.sync = [gpio_in, self.sync[0]],
            _ => self.sync = [gpio_in; 2],
        }
        for n in 0..4 {
            if self.enabled & (1 << n) == 0 {
                continue;
            }
            let s = &mut self.sm[n];
            // acc stays below the divisor (≥ 256, < 2^24): each cycle is acc ← (acc + 256)
            // mod div, and an enabled one when it wraps: one that counts a pending delay
            // down (the skipped cycles end before the instruction after it, `idle_cycles`).
            let div = u64::from(s.divisor());
            let (enabled, acc) = match cycles < 1 << 32 {
                true => {
                    let total = u64::from(s.acc) + 256 * cycles;
                    (total / div, total % div)
                }
                false => {
                    let total = u128::from(s.acc) + 256 * u128::from(cycles);
                    let div = u128::from(div);
                    (
                        (total / div).min(u128::from(u32::MAX)) as u64,
                        (total % div) as u64,
                    )
                }
            };
            s.acc = acc as u32;
            if s.delay > 0 && s.exec.is_none() {
                debug_assert!(enabled <= u64::from(s.delay));
                s.delay -= enabled.min(u64::from(s.delay)) as u32;
            }
        }
    }

    /// How many system cycles from now state machine `n` runs no instruction while its
    /// FIFOs, the block's pins and its instruction memory stay as they are: until its next
    /// enabled cycle, or the one after a pending delay's ([`Pio::idle_cycles`]); `None` when
    /// it runs none at all: disabled, or stalled on a FIFO ([`Pio::quiet`]'s `PULL`/`OUT` on
    /// an empty TX FIFO, `PUSH`/`IN` on a full RX FIFO, side-set already on the pins).
    /// Every other state machine (a `WAIT` or `IRQ` stall among them) runs at each of its
    /// enabled cycles, as [`Pio::tick`] runs it.
    pub fn sm_idle(&self, n: usize) -> Option<u64> {
        if self.enabled & (1 << n) == 0 || self.fifo_stall(n) {
            return None;
        }
        let s = &self.sm[n];
        let j = match s.delay > 0 && s.exec.is_none() && !s.autopull() {
            true => u64::from(s.delay) + 1,
            false => 1,
        };
        Some((j * u64::from(s.divisor()) - u64::from(s.acc)).div_ceil(256) - 1)
    }

    /// Advances state machine `n` over `cycles` system cycles in which it runs no
    /// instruction (at most [`Pio::sm_idle`], or any number when that is `None`): its clock
    /// divider and pending delay, as [`Pio::skip`] does for the block (the input
    /// synchroniser is the caller's: [`Pio::set_sync`]).
    pub fn sm_skip(&mut self, n: usize, cycles: u64) {
        if cycles == 0 || self.enabled & (1 << n) == 0 {
            return;
        }
        let s = &mut self.sm[n];
        let div = s.divisor();
        let enabled = if cycles <= 4 {
            // The usual few cycles: no division.
            let mut fired = 0;
            for _ in 0..cycles {
                s.acc += 256;
                if s.acc >= div {
                    s.acc -= div;
                    fired += 1;
                }
            }
            fired
        } else {
            let total = u128::from(s.acc) + 256 * u128::from(cycles);
            let div = u128::from(div);
            s.acc = (total % div) as u32;
            (total / div).min(u128::from(u32::MAX)) as u64
        };
        if s.delay > 0 && s.exec.is_none() {
            debug_assert!(enabled <= u64::from(s.delay));
            s.delay -= enabled.min(u64::from(s.delay)) as u32;
        }
    }

    /// Runs one system cycle of the state machines in `mask` (bit n: state machine n, each
    /// enabled, brought to this cycle by [`Pio::sm_skip`]), seeing the GPIO inputs `seen`
    /// (through the synchroniser, or direct where bypassed: [`Pio::seen`]): what
    /// [`Pio::tick`] does to them; the others do nothing in this cycle (the caller knows:
    /// [`Pio::sm_idle`]). Their pin writes land in state machine order.
    pub fn sm_tick(&mut self, mask: u8, seen: u32) {
        // A machine that does not run this cycle writes nothing (empty masks).
        let mut all = [Effects::default(); 4];
        for (n, fx) in all.iter_mut().enumerate() {
            if mask & (1 << n) == 0 || self.enabled & (1 << n) == 0 {
                continue;
            }
            let s = &mut self.sm[n];
            s.acc += 256;
            if s.acc < s.divisor() {
                continue;
            }
            s.acc -= s.divisor();
            // A machine stalled on a FIFO that has not changed stalls again without
            // effect ([`Pio::idle_cycles`]): its side-set, re-asserted, is already on the
            // pins, so it writes nothing this cycle either way.
            if let (Some(l), Some(st)) = (self.lanes.as_deref_mut(), self.sm[n].stalled) {
                // Whether it is already there depends on those pins' levels.
                let pins = st.side_values.0;
                lanes::fix(&mut l.out, self.out_values, pins, &mut l.fixed);
            }
            if self.fifo_stall(n) {
                continue;
            }
            *fx = self.execute(n, seen);
        }
        // In state machine order: the highest-numbered writes last and wins.
        for (n, fx) in all.iter().enumerate() {
            self.apply(fx, n);
        }
    }

    /// Counts the register writes that may change [`Pio::sm_pins`] (all but TX FIFO and
    /// IRQ flag writes).
    pub fn config_epoch(&self) -> u64 {
        self.config_epoch
    }

    /// The GPIOs state machine `n` may write (its OUT, SET and side-set pins) and those it
    /// may read (`IN PINS`, `MOV` from `PINS`, `WAIT GPIO`/`PIN`, `JMP PIN`), by its pin
    /// mapping over every word of the instruction memory (bit n: GPIO n); every pin both
    /// ways when an instruction may be forced or executed from data (`OUT EXEC`, `MOV
    /// EXEC`, SMx_INSTR). Until the next [`Pio::config_epoch`].
    pub fn sm_pins(&self, n: usize) -> (u32, u32) {
        let s = &self.sm[n];
        let p = s.pinctrl;
        let ranges = [
            (bits(p, 0, 5), bits(p, 20, 6)),
            (bits(p, 5, 5), bits(p, 26, 3)),
            (
                bits(p, 10, 5),
                match s.side_en() {
                    true => s.sideset_count().saturating_sub(1),
                    false => s.sideset_count(),
                },
            ),
        ];
        let written = ranges.iter().fold(0, |m, &(base, count)| {
            m | StateMachine::map(base, count, 0).0
        });
        let in_base = bits(p, 15, 5);
        let mut read = 0u32;
        let mut any = s.exec.is_some();
        for &w in &self.instr {
            let w = u32::from(w);
            let (arg1, arg2) = (bits(w, 5, 3), bits(w, 0, 5));
            match w >> 13 {
                0 if arg1 == 6 => read |= 1 << bits(s.execctrl, 24, 5),
                1 => match bits(w, 5, 2) {
                    0 => read |= 1 << arg2,
                    1 => read |= 1u32.rotate_left(in_base + arg2),
                    _ => {}
                },
                2 if arg1 == 0 => read |= StateMachine::map(in_base, count32(arg2), 0).0,
                3 if arg1 == 7 => any = true,
                5 if arg1 == 4 => any = true,
                5 if arg2 & 7 == 0 => read = u32::MAX,
                _ => {}
            }
        }
        match any {
            true => (u32::MAX, u32::MAX),
            false => (written, read),
        }
    }

    /// Whether the instruction state machine `n` runs next touches nothing outside itself
    /// and the pins: not a `PUSH`/`PULL`, an `IRQ`, a `WAIT IRQ` or a `MOV` from `STATUS`,
    /// with autopush and autopull off.
    pub fn sm_local(&self, n: usize) -> bool {
        let s = &self.sm[n];
        if s.autopull() || s.autopush() {
            return false;
        }
        let ins = u32::from(s.exec.unwrap_or(self.instr[s.pc as usize]));
        match ins >> 13 {
            4 | 6 => false,
            1 => bits(ins, 5, 2) != 2,
            5 => bits(ins, 0, 3) != 5,
            _ => true,
        }
    }

    /// Whether the instruction state machine `n` runs next reads the GPIO inputs (`IN`
    /// or `MOV` from `PINS`, `WAIT GPIO`/`PIN`, `JMP PIN`): if not, what it is given as
    /// inputs does not matter.
    pub fn sm_reads_pins(&self, n: usize) -> bool {
        let s = &self.sm[n];
        let ins = u32::from(s.exec.unwrap_or(self.instr[s.pc as usize]));
        let (arg1, arg2) = (bits(ins, 5, 3), bits(ins, 0, 5));
        match ins >> 13 {
            0 => arg1 == 6,
            1 => bits(ins, 5, 2) < 2,
            2 => arg1 == 0,
            5 => arg2 & 7 == 0,
            _ => false,
        }
    }

    /// When state machine `n` is due (its divider lets it run this cycle) with nothing
    /// pending, an integer clock divider, no autopush or autopull, and an instruction next
    /// that neither stalls nor forces another (not `WAIT`, `OUT EXEC`, `MOV EXEC`; the
    /// caller has checked [`Pio::sm_local`]): the system cycles from this one to the one
    /// it runs its next instruction in, `INT · (1 + delay)`. [`Pio::sm_exec`] runs it.
    pub fn sm_fast(&self, n: usize) -> Option<u64> {
        let s = &self.sm[n];
        let div = s.divisor();
        if !div.is_multiple_of(256)
            || s.delay > 0
            || s.exec.is_some()
            || s.autopull()
            || s.autopush()
            || s.acc + 256 < div
        {
            return None;
        }
        let ins = u32::from(self.instr[s.pc as usize]);
        let (op, dest) = (ins >> 13, bits(ins, 5, 3));
        if op == 1 || (op == 3 && dest == 7) || (op == 5 && dest == 4) {
            return None;
        }
        let delay_bits = 5 - s.sideset_count().min(5);
        let delay = bits(bits(ins, 8, 5), 0, delay_bits);
        Some(u64::from(div / 256) * u64::from(1 + delay))
    }

    /// Runs state machine `n`'s next instruction as [`Pio::sm_fast`] allows, seeing `seen`,
    /// and the cycles up to the next (its divider's and its delay's, which change nothing
    /// else: the divider's accumulator comes back to where it was): what [`Pio::sm_tick`]
    /// and [`Pio::sm_skip`] do over those cycles.
    pub fn sm_exec(&mut self, n: usize, seen: u32) {
        debug_assert!(
            self.lanes.is_none(),
            "lanes are kept on the stepwise path only"
        );
        let fx = self.execute(n, seen);
        self.apply(&fx, n);
        self.sm[n].delay = 0;
    }

    /// State machine `n`'s program counter.
    pub fn sm_pc(&self, n: usize) -> u32 {
        self.sm[n].pc
    }

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

    /// What the state machines see in a cycle whose GPIO inputs are `now`, when those of
    /// two cycles before were `before`: the synchronised level, or the direct one on the
    /// pins INPUT_SYNC_BYPASS names.
    pub fn seen(&self, before: u32, now: u32) -> u32 {
        (before & !self.sync_bypass) | (now & self.sync_bypass)
    }

    /// The input synchroniser's flops: the GPIO inputs of the last cycle and of the one
    /// before it.
    pub fn sync(&self) -> [u32; 2] {
        self.sync
    }

    /// Sets the input synchroniser's flops ([`Pio::sync`]): where a caller running the
    /// state machines by [`Pio::sm_tick`] leaves them.
    pub fn set_sync(&mut self, flops: [u32; 2]) {
        self.sync = flops;
    }

    /// The FIFO levels (FLEVEL: TX n at bits 8n+3:8n, RX n at 8n+7:8n+4): what the DMA's
    /// DREQs see of the block.
    pub fn levels(&self) -> u32 {
        (0..4).fold(0, |acc, n| {
            let s = &self.sm[n];
            acc | (s.tx.len() as u32) << (8 * n) | (s.rx.len() as u32) << (8 * n + 4)
        })
    }

    /// Whether state machine `sm` (0–3) is enabled (CTRL.SM_ENABLE).
    pub fn enabled(&self, sm: usize) -> bool {
        sm < 4 && self.enabled & (1 << sm) != 0
    }

    /// Reads register `offset` (datasheet 3.7; reading an RXF pops it, an empty one reads
    /// 0; write-only and unknown offsets read 0).
    pub fn read(&mut self, offset: u32) -> u32 {
        if let Some(l) = self.lanes.as_deref_mut() {
            // The lanes of what it reads: an RX FIFO's word, else constants.
            l.last_read = CONST;
            if (reg::RXF0..reg::RXF0 + 16).contains(&offset) {
                let n = ((offset - reg::RXF0) / 4) as usize;
                if !self.sm[n].rx.is_empty() {
                    l.last_read = l.sm[n].rx.pop();
                }
            }
        }
        match offset {
            reg::CTRL => self.enabled,
            reg::FSTAT => (0..4).fold(0, |acc, n| {
                let s = &self.sm[n];
                acc | u32::from(s.rx_full()) << n
                    | u32::from(s.rx.is_empty()) << (8 + n)
                    | u32::from(s.tx_full()) << (16 + n)
                    | u32::from(s.tx.is_empty()) << (24 + n)
            }),
            reg::FLEVEL => self.levels(),
            reg::IRQ => u32::from(self.irq),
            reg::INPUT_SYNC_BYPASS => self.sync_bypass,
            o if (reg::RXF0..reg::RXF0 + 16).contains(&o) => self.sm
                [((o - reg::RXF0) / 4) as usize]
                .rx
                .pop()
                .unwrap_or(0),
            o if (reg::SM0_CLKDIV..reg::SM0_CLKDIV + 4 * reg::SM_STRIDE).contains(&o) => {
                let n = ((o - reg::SM0_CLKDIV) / reg::SM_STRIDE) as usize;
                let s = &self.sm[n];
                match (o - reg::SM0_CLKDIV) % reg::SM_STRIDE {
                    0x00 => s.clkdiv,
                    0x04 => s.execctrl & !(1 << 31) | u32::from(s.exec.is_some()) << 31,
                    0x08 => s.shiftctrl,
                    0x0c => s.pc,
                    0x10 => u32::from(s.current),
                    _ => s.pinctrl,
                }
            }
            _ => 0,
        }
    }

    /// Writes register `offset` (datasheet 3.7; a write to a full TX FIFO is dropped, as
    /// the hardware does, setting a TXOVER flag this model does not keep).
    pub fn write(&mut self, offset: u32, value: u32) {
        if !(reg::TXF0..reg::TXF0 + 16).contains(&offset) && offset != reg::IRQ {
            self.config_epoch += 1;
        }
        if let Some(l) = self.lanes.as_deref_mut() {
            // The lanes of a word into a TX FIFO (what its writer set; constants from a
            // core); the words a restart or a change of FJOIN clears.
            let w = std::mem::replace(&mut l.next_write, CONST);
            match offset {
                o if (reg::TXF0..reg::TXF0 + 16).contains(&o) => {
                    let n = ((o - reg::TXF0) / 4) as usize;
                    if !self.sm[n].tx_full() {
                        l.sm[n].tx.push(self.sm[n].tx.len(), w);
                    }
                }
                reg::CTRL => {
                    for n in 0..4 {
                        if value & (1 << (4 + n)) != 0 {
                            l.sm[n].isr = CONST;
                        }
                    }
                }
                o if (reg::SM0_CLKDIV..reg::SM0_CLKDIV + 4 * reg::SM_STRIDE).contains(&o)
                    && (o - reg::SM0_CLKDIV) % reg::SM_STRIDE == 0x08 =>
                {
                    let n = ((o - reg::SM0_CLKDIV) / reg::SM_STRIDE) as usize;
                    if (self.sm[n].shiftctrl ^ value) >> 30 != 0 {
                        l.sm[n].tx = FifoLanes([CONST; 8]);
                        l.sm[n].rx = FifoLanes([CONST; 8]);
                    }
                }
                _ => {}
            }
        }
        match offset {
            reg::CTRL => {
                self.enabled = value & 0xf;
                for n in 0..4 {
                    if value & (1 << (4 + n)) != 0 {
                        self.sm[n].restart();
                    }
                    if value & (1 << (8 + n)) != 0 {
                        self.sm[n].acc = 0;
                    }
                }
            }
            reg::IRQ => self.irq &= !(value as u8),
            reg::IRQ_FORCE => self.irq |= value as u8,
            reg::INPUT_SYNC_BYPASS => self.sync_bypass = value,
            o if (reg::TXF0..reg::TXF0 + 16).contains(&o) => {
                let s = &mut self.sm[((o - reg::TXF0) / 4) as usize];
                if !s.tx_full() {
                    s.tx.push(value);
                }
            }
            o if (reg::INSTR_MEM0..reg::INSTR_MEM0 + 128).contains(&o) => {
                self.instr[((o - reg::INSTR_MEM0) / 4) as usize] = value as u16;
            }
            o if (reg::SM0_CLKDIV..reg::SM0_CLKDIV + 4 * reg::SM_STRIDE).contains(&o) => {
                let n = ((o - reg::SM0_CLKDIV) / reg::SM_STRIDE) as usize;
                match (o - reg::SM0_CLKDIV) % reg::SM_STRIDE {
                    0x00 => self.sm[n].clkdiv = value & 0xffff_ff00,
                    0x04 => self.sm[n].execctrl = value & 0x7fff_ffff,
                    0x08 => {
                        let s = &mut self.sm[n];
                        // Changing FJOIN discards the FIFOs' data (datasheet 3.5.3).
                        if (s.shiftctrl ^ value) >> 30 != 0 {
                            s.tx.clear();
                            s.rx.clear();
                        }
                        s.shiftctrl = value & 0xffff_0000;
                    }
                    0x0c => {}
                    0x10 => {
                        // Executed at once, on the next enabled cycle or now when disabled.
                        self.sm[n].exec = Some(value as u16);
                        if self.enabled & (1 << n) == 0 {
                            let gpio = self.sync[1];
                            if let Some(l) = self.lanes.as_deref_mut() {
                                l.seen = l.sync[1];
                            }
                            let fx = self.execute(n, gpio);
                            self.apply(&fx, n);
                        }
                    }
                    _ => self.sm[n].pinctrl = value,
                }
            }
            _ => {}
        }
    }

    /// Advances the block one system clock cycle; `gpio_in` is the GPIO input levels of
    /// this cycle (bit n: GPIO n).
    pub fn tick(&mut self, gpio_in: u32) {
        // What the state machines see this cycle: synchronised, or direct where bypassed.
        let seen = (self.sync[1] & !self.sync_bypass) | (gpio_in & self.sync_bypass);
        if let Some(l) = self.lanes.as_deref_mut() {
            l.seen = lanes::select(self.sync_bypass, &l.gpio_in, &l.sync[1]);
            l.sync = [l.gpio_in, l.sync[0]];
        }
        self.sync = [gpio_in, self.sync[0]];
        self.sm_tick(0xf, seen);
    }

    /// Applies state machine `n`'s pin effects `fx`.
    fn apply(&mut self, fx: &Effects, n: usize) {
        let set = |old: u32, (m, v): (u32, u32)| old & !m | v;
        self.out_values = set(set(self.out_values, fx.values), fx.side_values);
        self.out_dirs = set(set(self.out_dirs, fx.dirs), fx.side_dirs);
        if let Some(l) = self.lanes.as_deref_mut() {
            if fx.values.0 != 0 {
                l.out = lanes::select(fx.values.0, &l.pend[n], &l.out);
            }
            if fx.side_values.0 != 0 {
                l.out = lanes::select(fx.side_values.0, &CONST, &l.out);
            }
        }
    }

    /// Whether it equals `other` but for its data words ([`Pio::data_slots`]): every other
    /// field named (a field added must be decided here).
    pub(crate) fn eq_but_data(&self, other: &Pio) -> bool {
        let Pio {
            instr,
            sm,
            enabled,
            irq,
            sync_bypass,
            sync: _,
            out_values: _,
            out_dirs,
            config_epoch,
            lanes: _,
        } = self;
        *instr == other.instr
            && *enabled == other.enabled
            && *irq == other.irq
            && *sync_bypass == other.sync_bypass
            && *out_dirs == other.out_dirs
            && *config_epoch == other.config_epoch
            && sm.iter().zip(&other.sm).all(|(a, b)| a.eq_but_data(b))
    }

    /// Becomes `other` but for its data words ([`Pio::data_slots`]), which stay: every
    /// other field named.
    pub(crate) fn assign_but_data(&mut self, other: &Pio) {
        let Pio {
            instr,
            sm,
            enabled,
            irq,
            sync_bypass,
            sync: _,
            out_values: _,
            out_dirs,
            config_epoch,
            lanes: _,
        } = other;
        self.instr = *instr;
        self.enabled = *enabled;
        self.irq = *irq;
        self.sync_bypass = *sync_bypass;
        self.out_dirs = *out_dirs;
        self.config_epoch = *config_epoch;
        for (a, b) in self.sm.iter_mut().zip(sm) {
            a.assign_but_data(b);
        }
    }

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
    fn slot_mut(&mut self, i: usize) -> Option<&mut u32> {
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

    /// Runs one enabled cycle of state machine `n`, the state machines seeing `gpio`.
    #[inline(always)]
    fn execute(&mut self, n: usize, gpio: u32) -> Effects {
        if self.lanes.is_none() {
            return self.execute_with(n, gpio, &mut None);
        }
        let mut lanes = self.lanes.take();
        if let Some(l) = lanes.as_deref_mut() {
            l.pend[n] = CONST;
        }
        let fx = self.execute_with(n, gpio, &mut lanes);
        self.lanes = lanes;
        fx
    }

    /// [`Pio::execute`] with the block's lanes taken out of it (`None` when not kept).
    #[inline(always)]
    fn execute_with(&mut self, n: usize, gpio: u32, lanes: &mut Option<Box<PioLanes>>) -> Effects {
        let mut fx = Effects::default();
        let forced = self.sm[n].exec.is_some();
        if self.sm[n].delay > 0 && !forced {
            self.sm[n].stalled = None;
            self.sm[n].delay -= 1;
            self.background_pull(n, lanes.as_deref_mut());
            return fx;
        }
        let ins = match self.sm[n].exec.take() {
            Some(i) => i,
            None => self.instr[self.sm[n].pc as usize],
        };
        self.sm[n].current = ins;
        // Side-set and delay (datasheet 3.5.1): asserted even when the instruction stalls.
        let s = &self.sm[n];
        let (side, delay) = s.side_set(ins);
        if s.side_pindir() {
            fx.side_dirs = side;
        } else {
            fx.side_values = side;
        }
        let done = self.run(n, ins, gpio, &mut fx, lanes);
        let s = &mut self.sm[n];
        s.stalled = matches!(done, Flow::Stall).then_some(fx);
        match done {
            Flow::Stall => {
                // The instruction runs again next time (kept as the forced one if it was).
                if forced {
                    s.exec = Some(ins);
                }
                return fx;
            }
            // An instruction run through SMx_INSTR or EXEC leaves PC as it was, unless it
            // jumps (pico-sdk's pio_sm_set_pins runs SETs this way between init and enable).
            Flow::Next if forced => {}
            Flow::Next => s.advance(),
            Flow::Jump(to) => s.pc = to & 31,
            Flow::Stay => {}
        }
        // OUT EXEC and MOV EXEC ignore their own delay (datasheet 3.4.5.2).
        if !matches!(done, Flow::Stay) {
            s.delay = delay;
        }
        fx
    }

    /// Autopull on a cycle that is not an OUT's (datasheet 3.5.4.2).
    fn background_pull(&mut self, n: usize, lanes: Option<&mut PioLanes>) {
        let s = &mut self.sm[n];
        if !s.autopull() {
            return;
        }
        if s.osr_count >= s.pull_thresh() {
            if let Some(w) = s.tx.pop() {
                if let Some(l) = lanes {
                    l.sm[n].osr = l.sm[n].tx.pop();
                }
                s.osr = w;
                s.osr_count = 0;
            }
        }
    }

    /// Executes `ins` on state machine `n`; what happens to PC. Its lanes (`lanes`, when
    /// kept) follow each move of data, and data that decides something is fixed.
    fn run(
        &mut self,
        n: usize,
        ins: u16,
        gpio: u32,
        fx: &mut Effects,
        lanes: &mut Option<Box<PioLanes>>,
    ) -> Flow {
        let ins = u32::from(ins);
        let op = ins >> 13;
        let arg1 = bits(ins, 5, 3);
        let arg2 = bits(ins, 0, 5);
        let sm_n = n as u32;
        let irq_index = |idx: u32| -> u32 {
            // Bit 4 (REL): add the state machine number to the low two bits.
            if idx & 0x10 != 0 {
                (idx & 4) | ((idx + sm_n) & 3)
            } else {
                idx & 7
            }
        };
        let in_base = bits(self.sm[n].pinctrl, 15, 5);
        let pins_in = gpio.rotate_right(in_base);
        // The lanes kept, with this state machine's and what the pins show it.
        let mut lanes = lanes.as_deref_mut();
        let pins_in_lanes = |l: &PioLanes| lanes::rotr(&l.seen, in_base);
        let flow = match op {
            // JMP
            0 => {
                let s = &mut self.sm[n];
                if let Some(l) = lanes.as_deref_mut() {
                    let (sl, fixed) = (&mut l.sm[n], &mut l.fixed);
                    match arg1 {
                        1 | 2 => lanes::fix(&mut sl.x, s.x, u32::MAX, fixed),
                        3 | 4 => lanes::fix(&mut sl.y, s.y, u32::MAX, fixed),
                        5 => {
                            lanes::fix(&mut sl.x, s.x, u32::MAX, fixed);
                            lanes::fix(&mut sl.y, s.y, u32::MAX, fixed);
                        }
                        6 => {
                            let pin = bits(s.execctrl, 24, 5);
                            lanes::fix(&mut l.seen, gpio, 1 << pin, fixed);
                        }
                        _ => {}
                    }
                }
                let take = match arg1 {
                    0 => true,
                    1 => s.x == 0,
                    2 => {
                        let t = s.x != 0;
                        s.x = s.x.wrapping_sub(1);
                        t
                    }
                    3 => s.y == 0,
                    4 => {
                        let t = s.y != 0;
                        s.y = s.y.wrapping_sub(1);
                        t
                    }
                    5 => s.x != s.y,
                    6 => gpio & (1 << bits(s.execctrl, 24, 5)) != 0,
                    _ => s.osr_count < s.pull_thresh(),
                };
                match take {
                    true => Flow::Jump(arg2),
                    false => Flow::Next,
                }
            }
            // WAIT
            1 => {
                let pol = ins & 0x80 != 0;
                let idx = arg2;
                if let Some(l) = lanes.as_deref_mut() {
                    match bits(ins, 5, 2) {
                        0 => lanes::fix(&mut l.seen, gpio, 1 << idx, &mut l.fixed),
                        1 => {
                            let mut w = pins_in_lanes(l);
                            lanes::fix(&mut w, pins_in, 1 << idx, &mut l.fixed);
                        }
                        _ => {}
                    }
                }
                let met = match bits(ins, 5, 2) {
                    0 => (gpio >> idx) & 1 == u32::from(pol),
                    1 => (pins_in >> idx) & 1 == u32::from(pol),
                    2 => {
                        let f = irq_index(idx);
                        let set = self.irq & (1 << f) != 0;
                        if pol && set {
                            // WAIT 1 IRQ clears the flag it waited for.
                            self.irq &= !(1 << f);
                        }
                        set == pol
                    }
                    _ => true,
                };
                match met {
                    true => Flow::Next,
                    false => Flow::Stall,
                }
            }
            // IN
            2 => {
                let c = count32(arg2);
                let s = &self.sm[n];
                let data = match arg1 {
                    0 => pins_in,
                    1 => s.x,
                    2 => s.y,
                    6 => s.isr,
                    7 => s.osr,
                    _ => 0,
                };
                let after = (s.isr_count + c).min(32);
                if s.autopush() && after >= s.push_thresh() && s.rx_full() {
                    Flow::Stall
                } else {
                    let s = &mut self.sm[n];
                    if let Some(l) = lanes.as_deref_mut() {
                        let pins = match arg1 {
                            0 => pins_in_lanes(l),
                            _ => CONST,
                        };
                        let sl = &mut l.sm[n];
                        let data = match arg1 {
                            0 => pins,
                            1 => sl.x,
                            2 => sl.y,
                            6 => sl.isr,
                            7 => sl.osr,
                            _ => CONST,
                        };
                        sl.isr = shift_in_lanes(&sl.isr, c, &data, s.in_right());
                        if s.autopush() && (s.isr_count + c).min(32) >= s.push_thresh() {
                            sl.rx.push(s.rx.len(), sl.isr);
                            sl.isr = CONST;
                        }
                    }
                    s.shift_in(c, data);
                    if s.autopush() && s.isr_count >= s.push_thresh() {
                        s.rx.push(s.isr);
                        s.isr = 0;
                        s.isr_count = 0;
                    }
                    self.background_pull(n, lanes.as_deref_mut());
                    Flow::Next
                }
            }
            // OUT
            3 => {
                let c = count32(arg2);
                let s = &mut self.sm[n];
                if s.autopull() && s.osr_count >= s.pull_thresh() {
                    // Refill (or wait for data), and stall this cycle either way.
                    if let Some(w) = s.tx.pop() {
                        if let Some(l) = lanes.as_deref_mut() {
                            l.sm[n].osr = l.sm[n].tx.pop();
                        }
                        s.osr = w;
                        s.osr_count = 0;
                    }
                    return Flow::Stall;
                }
                let right = s.out_right();
                let data_lanes = lanes.as_deref_mut().map(|l| {
                    let sl = &mut l.sm[n];
                    let d = out_lanes(&sl.osr, c, right);
                    sl.osr = osr_after_lanes(&sl.osr, c, right);
                    d
                });
                let data = s.shift_out(c);
                let (out_base, out_count) = (bits(s.pinctrl, 0, 5), bits(s.pinctrl, 20, 6));
                if let (Some(l), Some(mut d)) = (lanes.as_deref_mut(), data_lanes) {
                    match arg1 {
                        0 => l.pend[n] = map_lanes(out_base, out_count, &d),
                        1 => l.sm[n].x = d,
                        2 => l.sm[n].y = d,
                        // PINDIRS: what the pins are; PC; EXEC: what runs.
                        4 => lanes::fix(&mut d, data, u32::MAX, &mut l.fixed),
                        5 => lanes::fix(&mut d, data, 31, &mut l.fixed),
                        6 => l.sm[n].isr = d,
                        7 => lanes::fix(&mut d, data, 0xffff, &mut l.fixed),
                        _ => {}
                    }
                }
                let flow = match arg1 {
                    0..=2 => s.write_pins_x_y(arg1, data, fx),
                    4 => {
                        fx.dirs = StateMachine::map(out_base, out_count, data);
                        Flow::Next
                    }
                    5 => Flow::Jump(data),
                    6 => {
                        s.isr = data;
                        s.isr_count = c;
                        Flow::Next
                    }
                    7 => {
                        s.exec = Some(data as u16);
                        s.advance();
                        Flow::Stay
                    }
                    _ => Flow::Next,
                };
                // After the shift, refill at once when data is there (3.5.4.2, lines 11–14).
                if s.autopull() && s.osr_count >= s.pull_thresh() {
                    if let Some(w) = s.tx.pop() {
                        if let Some(l) = lanes.as_deref_mut() {
                            l.sm[n].osr = l.sm[n].tx.pop();
                        }
                        s.osr = w;
                        s.osr_count = 0;
                    }
                }
                flow
            }
            // PUSH / PULL
            4 => {
                let if_flag = ins & 0x40 != 0;
                let block = ins & 0x20 != 0;
                let s = &mut self.sm[n];
                let mut sl = lanes.as_deref_mut().map(|l| &mut l.sm[n]);
                if ins & 0x80 == 0 {
                    // PUSH
                    if if_flag && s.isr_count < s.push_thresh() {
                        Flow::Next
                    } else if s.rx_full() {
                        match block {
                            true => Flow::Stall,
                            false => {
                                if let Some(sl) = sl {
                                    sl.isr = CONST;
                                }
                                s.isr = 0;
                                s.isr_count = 0;
                                Flow::Next
                            }
                        }
                    } else {
                        if let Some(sl) = sl {
                            sl.rx.push(s.rx.len(), sl.isr);
                            sl.isr = CONST;
                        }
                        s.rx.push(s.isr);
                        s.isr = 0;
                        s.isr_count = 0;
                        Flow::Next
                    }
                } else if if_flag && s.osr_count < s.pull_thresh() {
                    Flow::Next
                } else {
                    // PULL
                    match s.tx.pop() {
                        Some(w) => {
                            if let Some(sl) = sl.as_deref_mut() {
                                sl.osr = sl.tx.pop();
                            }
                            s.osr = w;
                            s.osr_count = 0;
                            Flow::Next
                        }
                        None if block => Flow::Stall,
                        None => {
                            if let Some(sl) = sl {
                                sl.osr = sl.x;
                            }
                            s.osr = s.x;
                            s.osr_count = 0;
                            Flow::Next
                        }
                    }
                }
            }
            // MOV
            5 => {
                let s = &self.sm[n];
                let src = match arg2 & 7 {
                    0 => pins_in,
                    1 => s.x,
                    2 => s.y,
                    3 => 0,
                    5 => {
                        // STATUS: all ones when the chosen FIFO level is below STATUS_N.
                        let level = bits(s.execctrl, 0, 4) as usize;
                        let below = match s.execctrl & (1 << 4) != 0 {
                            false => s.tx.len() < level,
                            true => s.rx.len() < level,
                        };
                        if below {
                            u32::MAX
                        } else {
                            0
                        }
                    }
                    6 => s.isr,
                    7 => s.osr,
                    _ => 0,
                };
                let v = match bits(ins, 3, 2) {
                    1 => !src,
                    2 => src.reverse_bits(),
                    _ => src,
                };
                if let Some(l) = lanes.as_deref_mut() {
                    let pins = pins_in_lanes(l);
                    let sl = &mut l.sm[n];
                    let src = match arg2 & 7 {
                        0 => pins,
                        1 => sl.x,
                        2 => sl.y,
                        6 => sl.isr,
                        7 => sl.osr,
                        _ => CONST,
                    };
                    let mut w = match bits(ins, 3, 2) {
                        1 => lanes::not(&src),
                        2 => lanes::reverse(&src),
                        _ => src,
                    };
                    let p = s.pinctrl;
                    match arg1 {
                        0 => l.pend[n] = map_lanes(bits(p, 0, 5), bits(p, 20, 6), &w),
                        1 => sl.x = w,
                        2 => sl.y = w,
                        4 => lanes::fix(&mut w, v, 0xffff, &mut l.fixed),
                        5 => lanes::fix(&mut w, v, 31, &mut l.fixed),
                        6 => sl.isr = w,
                        7 => sl.osr = w,
                        _ => {}
                    }
                }
                let s = &mut self.sm[n];
                match arg1 {
                    0..=2 => s.write_pins_x_y(arg1, v, fx),
                    4 => {
                        s.exec = Some(v as u16);
                        s.advance();
                        Flow::Stay
                    }
                    5 => Flow::Jump(v),
                    6 => {
                        s.isr = v;
                        s.isr_count = 0;
                        Flow::Next
                    }
                    7 => {
                        s.osr = v;
                        s.osr_count = 0;
                        Flow::Next
                    }
                    _ => Flow::Next,
                }
            }
            // IRQ
            6 => {
                let f = irq_index(arg2);
                let clear = ins & 0x40 != 0;
                let wait = ins & 0x20 != 0;
                let s = &mut self.sm[n];
                if clear {
                    self.irq &= !(1 << f);
                    Flow::Next
                } else if s.irq_waiting {
                    // Set on an earlier cycle of this instruction: wait for it to clear.
                    match self.irq & (1 << f) != 0 {
                        true => Flow::Stall,
                        false => {
                            s.irq_waiting = false;
                            Flow::Next
                        }
                    }
                } else {
                    self.irq |= 1 << f;
                    match wait {
                        true => {
                            s.irq_waiting = true;
                            Flow::Stall
                        }
                        false => Flow::Next,
                    }
                }
            }
            // SET
            _ => {
                let s = &mut self.sm[n];
                if let Some(l) = lanes.as_deref_mut() {
                    match arg1 {
                        1 => l.sm[n].x = CONST,
                        2 => l.sm[n].y = CONST,
                        _ => {}
                    }
                }
                let (set_base, set_count) = (bits(s.pinctrl, 5, 5), bits(s.pinctrl, 26, 3));
                match arg1 {
                    0 => fx.values = StateMachine::map(set_base, set_count, arg2),
                    1 => s.x = arg2,
                    2 => s.y = arg2,
                    4 => fx.dirs = StateMachine::map(set_base, set_count, arg2),
                    _ => {}
                }
                Flow::Next
            }
        };
        if op != 3 && op != 2 {
            // Every cycle but an OUT's may autopull (PULL and MOV OSR have just set the
            // output count to 0 themselves).
            self.background_pull(n, lanes);
        }
        flow
    }
}

/// What an executed instruction does to PC.
#[derive(Clone, Copy, Debug)]
enum Flow {
    /// It stalled: it runs again next time, PC unchanged, no delay.
    Stall,
    /// PC advances through the wrap.
    Next,
    /// PC is set.
    Jump(u32),
    /// PC was already handled (OUT/MOV EXEC: the next cycle runs the executee).
    Stay,
}
