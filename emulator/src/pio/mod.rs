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

use crate::lanes::{self, Fixed, Word, CONST};
use tactus_rp2040::pio::{reg, CLKDIV_RESET, EXECCTRL_RESET, PINCTRL_RESET, SHIFTCTRL_RESET};

mod bitloop;
mod exec;
pub(crate) mod slots;

pub use bitloop::{BitLoop, LoopClock, LOOP_MAX};
use exec::Flow;
use slots::{map_lanes, osr_after_lanes, out_lanes, shift_in_lanes, FifoLanes, PioLanes};

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
                lanes::fix(&mut l.out_values, self.out_values, pins, &mut l.fixed);
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
                        l.sm[n].tx = FifoLanes::CONST;
                        l.sm[n].rx = FifoLanes::CONST;
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
                l.out_values = lanes::select(fx.values.0, &l.pend[n], &l.out_values);
            }
            if fx.side_values.0 != 0 {
                l.out_values = lanes::select(fx.side_values.0, &CONST, &l.out_values);
            }
        }
    }
}
