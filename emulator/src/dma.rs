//! The RP2040 DMA controller (at 0x50000000; RP2040 datasheet section 2.5): twelve channels,
//! each with its four control registers seen through four aliases, transfer-count reloads,
//! triggers, null triggers and chaining, paced by a data request (DREQ) or a pacing timer
//! or unpaced, sharing one read port and one write port by round-robin with high-priority
//! channels first.
//!
//! This is the model issue 40's converter drivers run on: a board's sample interrupt must
//! find fresh sensor words in SRAM that a channel copied out of a PIO RX FIFO, and leave
//! DAC words that another channel feeds into a PIO TX FIFO. What the proof needs of it is
//! when each transfer touches the bus (its SRAM bank accesses compete with the cores') and
//! that pacing never over- or under-runs a peripheral FIFO. The model is stepped once per
//! system clock cycle ([`Dma::tick`]) against a [`DmaPort`], which performs its bus
//! accesses (with their wait states) and reports the peripherals' FIFO room; its registers
//! are read and written through [`Dma::read`] and [`Dma::write`] (offsets of datasheet
//! 2.5.7); its two interrupt lines are [`Dma::irq0`] and [`Dma::irq1`].
//!
//! What each cycle does, in this order:
//! - **The read port** issues one transfer a cycle for the channel the scheduler picks
//!   (2.5.1: "one read access and one write access ... every clock cycle"), advancing its
//!   read and write addresses by the data size (with the ring wrap of `RING_SIZE` on the
//!   address `RING_SEL` names). Its data waits in a transfer FIFO of
//!   [`TRANSFER_FIFO_DEPTH`] entries for the write port; a full FIFO holds the read port.
//!   A transfer's write is never in the same cycle as its read.
//! - **The write port** performs the oldest transfer whose read has completed: one write a
//!   cycle, held for its wait states. When it lands, the channel's transfer count
//!   (`TRANS_COUNT` as read) drops by one; the channel's last write ends its sequence:
//!   BUSY clears, its interrupt flag rises unless `IRQ_QUIET`, and `CHAIN_TO` (unless it
//!   names the channel itself) is triggered (2.5.2.2); the chained channel's first read
//!   is on the next cycle.
//! - **Scheduling** (2.5.1 and the `HIGH_PRIORITY` field): among the channels that are
//!   enabled, busy, have transfers left to issue and a credit, every high-priority channel
//!   is served once in a round before a single low-priority one, round-robin within each
//!   class.
//! - **Pacing** by the credit scheme of 2.5.3.2: the DMA keeps as many transfers of a
//!   channel in flight as its peripheral has room for. A channel paced by DREQ `n` may
//!   issue while [`DmaPort::dreq_room`] exceeds its transfers not yet landed at the
//!   peripheral (a TX DREQ's transfer lands with its write, an RX DREQ's with its read);
//!   so a 4-word PIO TX FIFO takes four writes back to back, and never a fifth before one
//!   leaves. The pacing timers (`TIMER0`–`TIMER3`, TREQ 0x3b–0x3e, 2.5.5.1) give a credit
//!   each time a fractional X/Y accumulator passes Y (at most one a cycle); TREQ 0x3f is
//!   unpaced.
//! - **Triggers** (2.5.2.1): writing a trigger alias starts an enabled channel that is not
//!   busy (a busy channel ignores it); `TRANS_COUNT` written without a trigger sets the
//!   reload value each start copies, `TRANS_COUNT_TRIG` sets and uses it at once. Writing
//!   zero to a trigger alias is a null trigger: it starts nothing, and raises the channel's
//!   interrupt flag if `IRQ_QUIET` is set (2.5.2.3). `MULTI_CHAN_TRIGGER` starts several.
//!   A channel started with a count of zero ends its sequence on the next cycle (this
//!   model's choice; the datasheet does not say).
//! - **Errors**: a read or write the port faults sets `READ_ERROR` or `WRITE_ERROR` (and
//!   `AHB_ERROR`), ends the channel's sequence without chaining, and raises its interrupt
//!   flag (2.5.7, CTRL's `AHB_ERROR`: "The channel halts when it encounters any bus
//!   error, and always raises its channel IRQ flag").
//!
//! Not modelled: the sniffer (`SNIFF_CTRL`, `SNIFF_DATA`), `CHAN_ABORT`'s in-flight wait
//! (an abort here ends the channel at once, dropping its queued transfers), the
//! `FIFO_LEVELS` and debug counters beyond `DBG_TCR`. On the bus (`crate::io`), a board
//! with converters runs it against SRAM and the two PIO blocks.

use crate::lanes::{Lane, Word, CONST};
use tactus_rp2040::dma::{ctrl, dreq_is_rx, reg, CHANNELS, TREQ_PERMANENT, TREQ_TIMER0};

/// Entries of the transfer data FIFO between the read and the write port: a read is not
/// issued while it is full. The datasheet gives the structure (2.5.1, an address FIFO and
/// a transfer data FIFO between the two bus masters), not this depth; two keeps one read
/// and one write every cycle with one cycle between a transfer's read and its write.
pub const TRANSFER_FIFO_DEPTH: usize = 2;

/// What the DMA touches: the bus, through its own two masters, and the DREQ side of the
/// peripherals.
pub trait DmaPort {
    /// Reads `size` bytes (1, 2 or 4, aligned) at `addr` in `cycle`: (zero-extended value,
    /// wait states). Errors: a bus fault.
    fn read(
        &mut self,
        cycle: u64,
        addr: u32,
        size: u32,
    ) -> Result<(u32, u32), crate::bus::BusFault>;
    /// Writes the low `size` bytes of `value` at `addr` in `cycle`: wait states. Errors: a
    /// bus fault.
    fn write(
        &mut self,
        cycle: u64,
        addr: u32,
        size: u32,
        value: u32,
    ) -> Result<u32, crate::bus::BusFault>;
    /// How many transfers DREQ `n` (0–0x3a) can take now: a TX FIFO's free entries, an RX
    /// FIFO's level; 0 for a DREQ nothing drives.
    fn dreq_room(&self, n: u32) -> u32;
    /// While lanes are kept (a recorded replay, `crate::lanes`): the lanes of the value the
    /// last [`DmaPort::read`] returned. Constants by default.
    #[doc(hidden)]
    fn read_lanes(&mut self) -> crate::lanes::Word {
        crate::lanes::CONST
    }
    /// While lanes are kept: the lanes of the value the next [`DmaPort::write`] writes.
    /// Ignored by default.
    #[doc(hidden)]
    fn write_lanes(&mut self, _lanes: &crate::lanes::Word) {}
}

/// One channel's registers and sequence state.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
struct Channel {
    read_addr: u32,
    write_addr: u32,
    /// Transfers left in the sequence (TRANS_COUNT as read): dropped as each write lands.
    remaining: u32,
    /// Transfers of the sequence not yet issued.
    to_issue: u32,
    /// TRANS_COUNT as last written: what the next start copies.
    reload: u32,
    /// CTRL's writable fields and the error flags (BUSY is derived).
    ctrl: u32,
    busy: bool,
    /// Transfers issued that have not yet reached the pacing peripheral.
    in_flight: u32,
    /// A sequence started with nothing to transfer ends on the next tick.
    empty_start: bool,
}

impl Channel {
    fn size(&self) -> u32 {
        1 << ((self.ctrl >> ctrl::DATA_SIZE_SHIFT) & 3).min(2)
    }

    fn treq(&self) -> u32 {
        (self.ctrl >> ctrl::TREQ_SEL_SHIFT) & 0x3f
    }

    fn chain_to(&self) -> usize {
        ((self.ctrl >> ctrl::CHAIN_TO_SHIFT) & 0xf) as usize
    }

    /// `addr` advanced by one transfer, within the ring when `ring` applies to it.
    fn advance(&self, addr: u32, ring: bool) -> u32 {
        let next = addr.wrapping_add(self.size());
        let bits = (self.ctrl >> ctrl::RING_SIZE_SHIFT) & 0xf;
        if ring && bits > 0 {
            let mask = (1u32 << bits) - 1;
            (addr & !mask) | (next & mask)
        } else {
            next
        }
    }
}

/// A transfer between the two ports: read, waiting for the write port.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Transfer {
    channel: usize,
    addr: u32,
    size: u32,
    value: u32,
    /// The first cycle its write may be performed.
    ready: u64,
}

/// The transfer data FIFO ([`TRANSFER_FIFO_DEPTH`] entries), kept in place (a copy, not an
/// allocation, when the DMA is cloned): the oldest first in `t[..len]`, the rest default.
#[derive(Clone, Copy, Default, PartialEq, Eq)]
struct Queue {
    t: [Transfer; TRANSFER_FIFO_DEPTH],
    len: usize,
}

impl std::fmt::Debug for Queue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(&self.t[..self.len]).finish()
    }
}

impl Queue {
    fn len(&self) -> usize {
        self.len
    }
    fn is_empty(&self) -> bool {
        self.len == 0
    }
    fn front(&self) -> Option<&Transfer> {
        self.t[..self.len].first()
    }
    fn pop_front(&mut self) {
        if self.len > 0 {
            self.t.copy_within(1.., 0);
            self.len -= 1;
            self.t[self.len] = Transfer::default();
        }
    }
    /// Appends `t`; the read port checks the room first.
    fn push_back(&mut self, t: Transfer) {
        debug_assert!(self.len < TRANSFER_FIFO_DEPTH);
        if let Some(slot) = self.t.get_mut(self.len) {
            *slot = t;
            self.len += 1;
        }
    }
    fn retain(&mut self, keep: impl Fn(&Transfer) -> bool) {
        let mut q = Queue::default();
        for t in self.t[..self.len].iter().filter(|t| keep(t)) {
            q.push_back(*t);
        }
        *self = q;
    }
}

/// The DMA controller. See the module documentation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Dma {
    ch: [Channel; CHANNELS],
    intr: u32,
    inte: [u32; 2],
    intf: [u32; 2],
    /// Pacing timers: (X, Y) and their accumulators and pending credits.
    timer: [(u32, u32); 4],
    timer_acc: [u32; 4],
    timer_credit: [u32; 4],
    /// Transfers read, waiting for the write port (oldest first).
    queue: Queue,
    /// The first cycle the read port and the write port are free again.
    read_free: u64,
    write_free: u64,
    /// Round-robin positions: the last high- and low-priority channel served, and the
    /// high-priority channels served in this round.
    last_high: usize,
    last_low: usize,
    round_served: u32,
    /// The lanes of the transfers' values while a replay is recorded (`crate::lanes`);
    /// `None` otherwise.
    pub(crate) lanes: Option<Box<DmaLanes>>,
}

/// The DMA's lanes while a replay is recorded (`crate::lanes`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct DmaLanes {
    /// The lanes of the transfers' values, in the queue's order.
    queue: [Word; TRANSFER_FIFO_DEPTH],
}

// The replay's view of the controller ([`ReplayState`]): every field given its role once.
// Its data words (`crate::io::Io::data_slots`): the values of the transfer FIFO's entries.
crate::replay::replay_state! { Dma [kept in lanes: DmaLanes, words] {
    same: ch, intr, inte, intf, timer, timer_acc, timer_credit, last_high, last_low,
        round_served;
    cycles: read_free, write_free;
    part: queue;
    lanes: lanes;
} }

/// The transfer FIFO: each transfer's value a data word, its ready cycle a cycle while it
/// is queued (the entries past the queue's length are compared as they are).
impl crate::replay::ReplayState for Queue {
    fn eq_but_data(&self, other: &Queue, r: crate::replay::Rebase) -> bool {
        self.len == other.len
            && (self.t.iter().zip(&other.t).enumerate()).all(|(i, (a, b))| {
                let ready = match i < self.len {
                    true => r.at(a.ready),
                    false => a.ready,
                };
                a.channel == b.channel && a.addr == b.addr && a.size == b.size && ready == b.ready
            })
    }
    fn assign_but_data(&mut self, other: &Queue) {
        let values = self.t.map(|t| t.value);
        *self = *other;
        for (t, v) in self.t.iter_mut().zip(values) {
            t.value = v;
        }
    }
    fn rebase_cycles(&mut self, r: crate::replay::Rebase) {
        for t in &mut self.t[..self.len] {
            t.ready = r.at(t.ready);
        }
    }
}

/// The transfers' values, in the FIFO's order (the entries past its length too).
impl crate::replay::Data for Queue {
    type Lanes = [Word; TRANSFER_FIFO_DEPTH];
    #[inline]
    fn visit(
        &mut self,
        lanes: Option<&mut Self::Lanes>,
        f: &mut impl FnMut(&mut u32, Option<&mut [Lane]>),
    ) {
        let mut l = lanes;
        for (i, t) in self.t.iter_mut().enumerate() {
            f(&mut t.value, l.as_deref_mut().map(|l| &mut l[i][..]));
        }
    }
}

impl crate::replay::Words for Queue {
    const WORDS: usize = TRANSFER_FIFO_DEPTH;
    #[inline]
    fn get(&self, i: usize) -> u32 {
        self.t.get(i).map_or(0, |t| t.value)
    }
    #[inline]
    fn set(&mut self, i: usize, v: u32) {
        if let Some(t) = self.t.get_mut(i) {
            t.value = v;
        }
    }
}

impl Default for Dma {
    fn default() -> Self {
        Self::new()
    }
}

impl Dma {
    /// The DMA out of reset: every channel idle with CTRL 0 but `CHAIN_TO` naming itself
    /// (datasheet reset values), no interrupt flags.
    pub fn new() -> Self {
        let ch = std::array::from_fn(|n| Channel {
            ctrl: (n as u32) << ctrl::CHAIN_TO_SHIFT,
            ..Channel::default()
        });
        Dma {
            ch,
            intr: 0,
            inte: [0; 2],
            intf: [0; 2],
            timer: [(0, 0); 4],
            timer_acc: [0; 4],
            timer_credit: [0; 4],
            queue: Queue::default(),
            read_free: 0,
            write_free: 0,
            last_high: CHANNELS - 1,
            last_low: CHANNELS - 1,
            round_served: 0,
            lanes: None,
        }
    }

    /// Mixes some of its control state (none of its data words) into `mix`: a cheap first
    /// test of two controllers' equality but for data (`crate::io::Io::quick_key`).
    pub(crate) fn quick_key(&self, r: crate::replay::Rebase, mix: &mut impl FnMut(u64)) {
        mix(r.at(self.read_free) ^ r.at(self.write_free).rotate_left(32));
        mix(self.last_high as u64 | (self.last_low as u64) << 8 | (self.queue.len as u64) << 16);
        for c in &self.ch {
            mix(u64::from(c.read_addr) | u64::from(c.write_addr) << 32);
            mix(u64::from(c.remaining) | u64::from(c.busy) << 32);
        }
    }

    /// Starts keeping lanes (`crate::lanes`), all constants (`crate::io::Io` gives its data
    /// words theirs through [`crate::replay::Data`]).
    pub(crate) fn start_lanes(&mut self) {
        self.lanes = Some(Box::new(DmaLanes {
            queue: [CONST; TRANSFER_FIFO_DEPTH],
        }));
    }

    /// The queue without the transfers `drop` names, their lanes with them.
    fn drop_transfers(&mut self, drop: impl Fn(&Transfer) -> bool) {
        if let Some(l) = self.lanes.as_deref_mut() {
            let mut kept = [CONST; TRANSFER_FIFO_DEPTH];
            let mut k = 0;
            for (i, t) in self.queue.t[..self.queue.len].iter().enumerate() {
                if !drop(t) {
                    kept[k] = l.queue[i];
                    k += 1;
                }
            }
            l.queue = kept;
        }
        self.queue.retain(|t| !drop(t));
    }

    /// DMA_IRQ_0: a raw or forced flag of a channel enabled in INTE0.
    pub fn irq0(&self) -> bool {
        self.ints(0) != 0
    }

    /// DMA_IRQ_1: as [`Dma::irq0`] with INTE1 and INTF1.
    pub fn irq1(&self) -> bool {
        self.ints(1) != 0
    }

    fn ints(&self, i: usize) -> u32 {
        (self.intr | self.intf[i]) & self.inte[i]
    }

    /// Whether channel `n` is in a transfer sequence (CTRL's BUSY).
    pub fn busy(&self, n: usize) -> bool {
        self.ch.get(n).is_some_and(|c| c.busy)
    }

    /// Whether nothing is left to do: no channel busy and no transfer between the ports.
    /// A caller may skip [`Dma::tick`] while this holds and no register is written.
    pub fn idle(&self) -> bool {
        self.queue.is_empty() && self.ch.iter().all(|c| !c.busy)
    }

    /// Whether ticking the DMA changes nothing while the DREQs `port` reports stay as they
    /// are: no transfer between the ports, no sequence started empty, no pacing timer
    /// running (its accumulator moves every cycle), and no channel ready to issue. A caller
    /// may then skip [`Dma::tick`] until a register is written or a DREQ changes.
    pub fn quiet(&self, port: &dyn DmaPort) -> bool {
        self.queue.is_empty()
            && self.timer.iter().all(|&(x, y)| x == 0 || y == 0)
            && (0..CHANNELS).all(|n| !self.ch[n].empty_start && !self.ready(n, port))
    }

    /// The addresses every enabled channel may read or write before software next writes
    /// a DMA register: per channel and direction `(first address, bytes)` from its current
    /// address — one transfer's bytes where it does not increment, the ring where it wraps,
    /// its transfers left (or the reload count, a restart's) where it increments, and
    /// `u64::MAX` bytes for an incrementing channel that chains to another (a chain may
    /// restart it from where it stopped, again and again).
    pub fn reach(&self) -> impl Iterator<Item = (u32, u64)> + '_ {
        self.ch
            .iter()
            .enumerate()
            .filter(|(_, c)| c.ctrl & ctrl::EN != 0)
            .flat_map(|(n, c)| {
                let ring_bits = (c.ctrl >> ctrl::RING_SIZE_SHIFT) & 0xf;
                let ring_write = c.ctrl & ctrl::RING_SEL != 0;
                let count = u64::from(c.to_issue.max(c.reload));
                let size = u64::from(c.size());
                [
                    (c.read_addr, c.ctrl & ctrl::INCR_READ != 0, !ring_write),
                    (c.write_addr, c.ctrl & ctrl::INCR_WRITE != 0, ring_write),
                ]
                .map(|(addr, incr, ringed)| {
                    if !incr {
                        (addr, size)
                    } else if ringed && ring_bits > 0 {
                        (addr & !((1u32 << ring_bits) - 1), 1u64 << ring_bits)
                    } else if c.chain_to() != n {
                        (addr, u64::MAX)
                    } else {
                        (addr, size * count.max(1))
                    }
                })
            })
    }

    fn ctrl_value(&self, n: usize) -> u32 {
        let c = &self.ch[n];
        let err = c.ctrl & (ctrl::READ_ERROR | ctrl::WRITE_ERROR);
        c.ctrl | u32::from(c.busy) << 24 | if err != 0 { ctrl::AHB_ERROR } else { 0 }
    }

    /// Reads register `offset` (datasheet 2.5.7; unknown offsets read 0).
    pub fn read(&mut self, offset: u32) -> u32 {
        if offset < reg::CH_STRIDE * CHANNELS as u32 {
            let n = (offset / reg::CH_STRIDE) as usize;
            let c = &self.ch[n];
            return match Self::field(offset % reg::CH_STRIDE) {
                Field::ReadAddr => c.read_addr,
                Field::WriteAddr => c.write_addr,
                Field::TransCount => c.remaining,
                Field::Ctrl => self.ctrl_value(n),
            };
        }
        match offset {
            reg::INTR => self.intr,
            reg::INTE0 => self.inte[0],
            reg::INTF0 => self.intf[0],
            reg::INTS0 => self.ints(0),
            reg::INTE1 => self.inte[1],
            reg::INTF1 => self.intf[1],
            reg::INTS1 => self.ints(1),
            o if (reg::TIMER0..reg::TIMER0 + 16).contains(&o) => {
                let (x, y) = self.timer[((o - reg::TIMER0) / 4) as usize];
                x << 16 | y
            }
            reg::N_CHANNELS => CHANNELS as u32,
            o if o >= reg::DBG_TCR
                && o < reg::DBG_TCR + reg::CH_STRIDE * CHANNELS as u32
                && (o - reg::DBG_TCR).is_multiple_of(reg::CH_STRIDE) =>
            {
                self.ch[((o - reg::DBG_TCR) / reg::CH_STRIDE) as usize].reload
            }
            _ => 0,
        }
    }

    /// Which register an offset within a channel's block is (table of aliases, 2.5.2.1).
    fn field(o: u32) -> Field {
        const ALIASES: [[Field; 4]; 4] = {
            use Field::*;
            [
                [ReadAddr, WriteAddr, TransCount, Ctrl],
                [Ctrl, ReadAddr, WriteAddr, TransCount],
                [Ctrl, TransCount, ReadAddr, WriteAddr],
                [Ctrl, WriteAddr, TransCount, ReadAddr],
            ]
        };
        ALIASES[(o / 16) as usize & 3][(o % 16 / 4) as usize]
    }

    /// Writes register `offset` (datasheet 2.5.7): a channel register through any alias,
    /// the alias's last word a trigger; the interrupt registers, the pacing timers,
    /// `MULTI_CHAN_TRIGGER` and `CHAN_ABORT`. Unknown offsets are ignored.
    pub fn write(&mut self, offset: u32, value: u32) {
        if offset < reg::CH_STRIDE * CHANNELS as u32 {
            let n = (offset / reg::CH_STRIDE) as usize;
            let within = offset % reg::CH_STRIDE;
            let field = Self::field(within);
            let c = &mut self.ch[n];
            match field {
                Field::ReadAddr => c.read_addr = value,
                Field::WriteAddr => c.write_addr = value,
                Field::TransCount => c.reload = value,
                Field::Ctrl => {
                    // The error flags are write-one-to-clear; the rest as written.
                    let errors = c.ctrl & (ctrl::READ_ERROR | ctrl::WRITE_ERROR) & !value;
                    c.ctrl = value & ctrl::WRITABLE | errors;
                }
            }
            if within % 16 == 12 {
                if value == 0 {
                    // A null trigger (2.5.2.3).
                    if self.ch[n].ctrl & ctrl::IRQ_QUIET != 0 {
                        self.intr |= 1 << n;
                    }
                } else {
                    // TRANS_COUNT_TRIG: the written count is used at once.
                    self.trigger(n);
                }
            }
            return;
        }
        match offset {
            reg::INTR | reg::INTS0 | reg::INTS1 => self.intr &= !value,
            reg::INTE0 => self.inte[0] = value & 0xfff,
            reg::INTF0 => self.intf[0] = value & 0xfff,
            reg::INTE1 => self.inte[1] = value & 0xfff,
            reg::INTF1 => self.intf[1] = value & 0xfff,
            o if (reg::TIMER0..reg::TIMER0 + 16).contains(&o) => {
                let t = ((o - reg::TIMER0) / 4) as usize;
                self.timer[t] = (value >> 16, value & 0xffff);
                self.timer_acc[t] = 0;
            }
            reg::MULTI_CHAN_TRIGGER => {
                for n in 0..CHANNELS {
                    if value & (1 << n) != 0 {
                        self.trigger(n);
                    }
                }
            }
            reg::CHAN_ABORT => {
                for n in 0..CHANNELS {
                    if value & (1 << n) != 0 {
                        let c = &mut self.ch[n];
                        (c.busy, c.remaining, c.to_issue, c.in_flight) = (false, 0, 0, 0);
                        c.empty_start = false;
                    }
                }
                self.drop_transfers(|t| value & (1 << t.channel) != 0);
            }
            _ => {}
        }
    }

    /// Starts channel `n`'s sequence if it is enabled and not busy (2.5.2: "Triggering a
    /// channel which is already running has no effect").
    fn trigger(&mut self, n: usize) {
        let c = &mut self.ch[n];
        if c.ctrl & ctrl::EN == 0 || c.busy {
            return;
        }
        c.busy = true;
        c.remaining = c.reload;
        c.to_issue = c.reload;
        c.in_flight = 0;
        c.empty_start = c.reload == 0;
    }

    /// Ends channel `n`'s sequence: its interrupt flag unless `IRQ_QUIET`, then its chain.
    fn complete(&mut self, n: usize) {
        let c = &mut self.ch[n];
        c.busy = false;
        c.empty_start = false;
        if c.ctrl & ctrl::IRQ_QUIET == 0 {
            self.intr |= 1 << n;
        }
        let next = c.chain_to();
        if next != n && next < CHANNELS {
            self.trigger(next);
        }
    }

    /// Ends channel `n`'s sequence on a bus error (`flag`): no chain, its interrupt flag
    /// always (2.5.7).
    fn fault(&mut self, n: usize, flag: u32) {
        let c = &mut self.ch[n];
        c.ctrl |= flag;
        (c.busy, c.to_issue, c.in_flight) = (false, 0, 0);
        c.empty_start = false;
        self.intr |= 1 << n;
        self.drop_transfers(|t| t.channel == n);
    }

    /// Whether channel `n` may issue a transfer this cycle.
    fn ready(&self, n: usize, port: &dyn DmaPort) -> bool {
        let c = &self.ch[n];
        if !c.busy || c.ctrl & ctrl::EN == 0 || c.to_issue == 0 {
            return false;
        }
        match c.treq() {
            TREQ_PERMANENT => true,
            t if t >= TREQ_TIMER0 => self.timer_credit[(t - TREQ_TIMER0) as usize] > 0,
            dreq => port.dreq_room(dreq) > c.in_flight,
        }
    }

    /// The channel the read port serves this cycle: every ready high-priority channel once
    /// a round, round-robin, then one ready low-priority channel, which ends the round.
    fn schedule(&mut self, port: &dyn DmaPort) -> Option<usize> {
        // The ready channels and the high-priority ones, a bit each (`ready` reads only).
        let (mut ready, mut high) = (0u32, 0u32);
        for n in 0..CHANNELS {
            ready |= u32::from(self.ready(n, port)) << n;
            high |= u32::from(self.ch[n].ctrl & ctrl::HIGH_PRIORITY != 0) << n;
        }
        // The first channel of `mask` after `last` in round-robin order (`last + 1` up,
        // then from 0 to `last`).
        let next_after = |last: usize, mask: u32| -> Option<usize> {
            let after = mask & !((2u32 << last) - 1);
            match (after, mask) {
                (_, 0) => None,
                (0, m) => Some(m.trailing_zeros() as usize),
                (a, _) => Some(a.trailing_zeros() as usize),
            }
        };
        let served = self.round_served;
        if let Some(n) = next_after(self.last_high, ready & high & !served) {
            self.last_high = n;
            self.round_served |= 1 << n;
            return Some(n);
        }
        self.round_served = 0;
        if let Some(n) = next_after(self.last_low, ready & !high) {
            self.last_low = n;
            return Some(n);
        }
        // No low-priority channel: a new round of the high-priority ones.
        let n = next_after(self.last_high, ready & high)?;
        self.last_high = n;
        self.round_served = 1 << n;
        Some(n)
    }

    /// Advances the DMA one system clock cycle, `cycle`: the pacing timers, then the read
    /// port, then the write port (see the module documentation).
    pub fn tick(&mut self, cycle: u64, port: &mut dyn DmaPort) {
        for t in 0..4 {
            let (x, y) = self.timer[t];
            if y == 0 || x == 0 {
                continue;
            }
            self.timer_acc[t] += x;
            if self.timer_acc[t] >= y {
                self.timer_acc[t] -= y;
                self.timer_credit[t] = self.timer_credit[t].saturating_add(1);
            }
        }
        // Sequences started empty end now.
        for n in 0..CHANNELS {
            if self.ch[n].empty_start {
                self.complete(n);
            }
        }
        if cycle >= self.read_free && self.queue.len() < TRANSFER_FIFO_DEPTH {
            if let Some(n) = self.schedule(&*port) {
                self.read_port(cycle, n, port);
            }
        }
        if cycle >= self.write_free {
            if let Some(t) = self.queue.front().copied().filter(|t| t.ready <= cycle) {
                self.queue.pop_front();
                if let Some(l) = self.lanes.as_deref_mut() {
                    let l = &mut l.queue;
                    let w = l[0];
                    l.copy_within(1.., 0);
                    l[TRANSFER_FIFO_DEPTH - 1] = CONST;
                    port.write_lanes(&w);
                }
                match port.write(cycle, t.addr, t.size, t.value) {
                    Ok(wait) => {
                        self.write_free = cycle + 1 + u64::from(wait);
                        let c = &mut self.ch[t.channel];
                        let treq = c.treq();
                        if treq < TREQ_TIMER0 && !dreq_is_rx(treq) {
                            c.in_flight = c.in_flight.saturating_sub(1);
                        }
                        c.remaining = c.remaining.saturating_sub(1);
                        if c.remaining == 0 && c.busy {
                            self.complete(t.channel);
                        }
                    }
                    Err(_) => self.fault(t.channel, ctrl::WRITE_ERROR),
                }
            }
        }
    }

    /// The read port issues channel `n`'s next transfer in `cycle`.
    fn read_port(&mut self, cycle: u64, n: usize, port: &mut dyn DmaPort) {
        let c = &self.ch[n];
        let (size, from, to) = (c.size(), c.read_addr, c.write_addr);
        match port.read(cycle, from, size) {
            Ok((value, wait)) => {
                let ring_write = c.ctrl & ctrl::RING_SEL != 0;
                let value = if c.ctrl & ctrl::BSWAP != 0 {
                    match size {
                        2 => u32::from((value as u16).swap_bytes()),
                        4 => value.swap_bytes(),
                        _ => value,
                    }
                } else {
                    value
                };
                if let Some(l) = self.lanes.as_deref_mut() {
                    let mut w = port.read_lanes();
                    if self.ch[n].ctrl & ctrl::BSWAP != 0 {
                        w = match size {
                            2 => std::array::from_fn(|i| match i {
                                0..=15 => w[i ^ 8],
                                _ => Lane::CONST,
                            }),
                            4 => std::array::from_fn(|i| w[i ^ 24]),
                            _ => w,
                        };
                    }
                    if let Some(slot) = l.queue.get_mut(self.queue.len()) {
                        *slot = w;
                    }
                }
                let c = &mut self.ch[n];
                if c.ctrl & ctrl::INCR_READ != 0 {
                    c.read_addr = c.advance(from, !ring_write);
                }
                if c.ctrl & ctrl::INCR_WRITE != 0 {
                    c.write_addr = c.advance(to, ring_write);
                }
                c.to_issue -= 1;
                let treq = c.treq();
                match treq {
                    TREQ_PERMANENT => {}
                    t if t >= TREQ_TIMER0 => self.timer_credit[(t - TREQ_TIMER0) as usize] -= 1,
                    t if !dreq_is_rx(t) => c.in_flight += 1,
                    _ => {}
                }
                self.read_free = cycle + 1 + u64::from(wait);
                self.queue.push_back(Transfer {
                    channel: n,
                    addr: to,
                    size,
                    value,
                    ready: self.read_free,
                });
            }
            Err(_) => self.fault(n, ctrl::READ_ERROR),
        }
    }
}

/// A channel register, whatever alias it is reached through.
#[derive(Clone, Copy, Debug)]
enum Field {
    ReadAddr,
    WriteAddr,
    TransCount,
    Ctrl,
}
