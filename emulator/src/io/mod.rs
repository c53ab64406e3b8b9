//! The board's converter I/O on the bus (issue 40): the two PIO blocks ([`crate::pio`]), the
//! DMA controller ([`crate::dma`]), the GPIO function select of IO_BANK0, the bus fabric's
//! BUS_PRIORITY, and the SPI converters at the pins ([`crate::converters`]), as one machine
//! the cores reach through their registers and, by the DMA, through SRAM.
//!
//! A board without converters has no [`Io`] ([`crate::system::System::io`] is `None`): none
//! of this costs it anything but a test of that `None` on the general path.
//!
//! **Registers** (RP2040 datasheet 2.2): the DMA at 0x50000000, PIO0 at 0x50200000, PIO1
//! at 0x50300000 (AHB-Lite peripherals: a core's access takes no wait state, as an SRAM
//! access, [`AHB_PERIPHERAL_WAIT`]), IO_BANK0 at 0x40014000 (GPIOn_CTRL's FUNCSEL: 6 gives
//! the pad to PIO0, 7 to PIO1; other fields stored, no effect) and BUSCTRL at 0x40030000
//! (BUS_PRIORITY), each with the atomic XOR, SET and CLR aliases at +0x1000, +0x2000 and
//! +0x3000 (2.1.2). RESETS holds PIO0 (bit 10), PIO1 (11), DMA (2), IO_BANK0 (5) and
//! BUSCTRL (1): a block put into reset returns to its reset state, and an access to a block
//! held in reset is a bus fault (the emulator's way of refusing it; the chip's bus would
//! stall). Interrupts of the DMA and the PIOs do not reach the NVIC (not modelled).
//!
//! **The machine's cycle.** Each system cycle, in this order: the DMA ticks (its read and
//! write ports against SRAM and the PIO FIFOs, paced by the PIOs' DREQs: PIO0 TX0–3 are
//! DREQ 0–3, RX0–3 4–7, PIO1 8–15 likewise); both PIO blocks tick with the GPIO inputs the
//! converters drive; the converters see the pins if any driven level or direction changed.
//! A pin is driven by PIO *b* when its FUNCSEL is PIO *b*'s and the state machines set it
//! as an output; an undriven CS reads high (the board's pull-up).
//!
//! **By events.** The machine runs lazily: [`crate::system::System`] advances it to a cycle
//! only when a core accesses one of its registers or an SRAM bank its DMA may touch, and
//! the board at the end of each run. Inside a run it goes from event to event
//! (`Io::advance_by_events`): while the DMA has nothing it could do ([`Dma::quiet`]), the
//! next cycle anything can happen is the first in which a state machine runs an
//! instruction ([`Pio::sm_idle`]: the cycles its clock divider skips and those of a pending
//! delay change nothing else), and only the state machines due then run ([`Pio::sm_tick`]);
//! each has its own clock, brought forward in one step ([`Pio::sm_skip`]) when something
//! needs it. A state machine that alone drives its converters runs ahead of the rest with
//! them (`Io::run_ahead`), and a bit loop of its program ([`crate::pio::BitLoop`]: the SPI
//! drivers' `OUT`/`IN` … `JMP X--` loops) as many times round as fit in one step, its
//! converters taking the clock edges in bulk (`Io::run_loop`). The cores' accesses to the
//! DMA's banks need only the DMA as of their cycle: there (`Io::advance` without
//! `settle`) such a state machine at a loop's head that ends later stays behind, held at its
//! clock, and runs the loop whole in a later advance (`Io::behind`); every other advance
//! settles it first. A converter sees the pins when one of its own changed. An advance
//! that stops before anything happens notes the cycle of the next event; the advances
//! that end before it (most of a window's replay: the cores' accesses come in clusters)
//! only move the clocks (`Io::skip_idle`, one in 16 checked against the full run in debug
//! builds).
//! The reference it is tested against ticks everything every cycle ([`Io::stepwise`]).
//!
//! **The DMA against the cores.** The DMA's two masters (read and write ports) arbitrate
//! for SRAM banks with the cores (a bank serves one master a cycle). With DMA_R and DMA_W
//! both high in BUS_PRIORITY and the core's bit low, the DMA wins: a core access to a bank
//! the DMA claims in that cycle waits a cycle (and again while it claims it). Otherwise the
//! core wins and the DMA waits a cycle (the round-robin among masters of equal priority is
//! not modelled: the core wins such ties). The DMA's read master wins over its write master
//! in one cycle. To see the DMA's accesses in cycle order, every core access to a bank an
//! enabled channel may reach ([`Dma::reach`], recomputed at each DMA register write) leaves
//! the fast path ([`crate::system::System::allowed_banks`]) and advances the machine first; the
//! block engine's unconfined code, which does not check banks, does not run while an
//! [`Io`] is attached. The cores' accesses are served in the lock-step's issue order: an
//! access whose data phase is earlier than one of the other core's already served finds the
//! machine where that one left it. Where the DMA wins against both cores, the cores run in
//! windows ahead of the machine (`accel/window.rs`), which then replays their accesses to
//! its banks and their stores to its registers in that order, the window undone where the
//! lock-step run would have differed (`accel/io_window/`); a replay whose control
//! repeats a recorded one's takes its effect instead, with its own data (the period memo
//! there). For it the machine names its data words (`Io::data_slots`: the state
//! machines' registers and FIFO words, the pins' levels, the DMA's transfers in flight, the
//! parts' codes and registers), compares and takes states but for them
//! (`Io::eq_but_data`, `Io::become_but_data`) and, while a replay is recorded, keeps each
//! data bit's lane through the stepwise run (`crate::lanes`, `LaneRec`).
//!
//! Not modelled: the DMA reaching peripherals other than the PIO FIFOs (its own registers,
//! APB), the DMA's and PIOs' interrupts, GPIO overrides, pads, and the SIO's GPIO outputs.

use crate::bus::{load_le, store_le, BusFault};
use crate::converters::{AdcFrame, Ads8688, Dac8568, DacUpdate, Recorded, SpiPins};
use crate::dma::{Dma, DmaPort};
use crate::lanes::{self, Fixed, Lane, Word, CONST};
use crate::pio::{BitLoop, LoopClock, Pio, LOOP_MAX};
use crate::replay::Rebase;
use tactus_rp2040::busctrl::{priority, BUSCTRL_BASE};
use tactus_rp2040::dma::DMA_BASE;
use tactus_rp2040::io_bank0::{FUNCSEL_NULL, GPIOS, IO_BANK0_BASE};
use tactus_rp2040::memory::{sram_location, BANKS};
use tactus_rp2040::pio::{PIO0_BASE, PIO1_BASE};
use tactus_rp2040::resets;
use tactus_runtime::converters::{AdcPart, DacPart};

/// Wait states of a core's access to a DMA or PIO register (AHB-Lite peripherals,
/// datasheet 2.1: not behind the APB bridge).
pub const AHB_PERIPHERAL_WAIT: u32 = 0;

/// RESETS bits of the blocks here (datasheet 2.14.3).
pub(crate) mod events;
pub(crate) mod port;
pub(crate) mod slots;

use events::{Ahead, Idle};
use port::{banks_of, Memory, Port};
use slots::{IoLanes, LaneOp, LaneRec};

const IO_RESETS: u32 =
    resets::BUSCTRL | resets::DMA | resets::IO_BANK0 | resets::PIO0 | resets::PIO1;

/// The converters a board carries, with their pins: what [`crate::Board::attach_io`] wires.
#[derive(Clone, Debug, Default)]
pub struct IoConfig {
    /// ADCs (key positions), each with its pins.
    pub adcs: Vec<(&'static AdcPart, SpiPins)>,
    /// DACs (motor currents), each with its pins (`sdo` unused).
    pub dacs: Vec<(&'static DacPart, SpiPins)>,
}

/// The I/O machine. See the module documentation.
#[derive(Clone, Debug, PartialEq)]
pub struct Io {
    /// PIO0 and PIO1.
    pub pio: [Pio; 2],
    /// The DMA controller.
    pub dma: Dma,
    /// The ADCs at their pins, in [`IoConfig::adcs`] order.
    pub adcs: Vec<Ads8688>,
    /// The DACs at their pins, in [`IoConfig::dacs`] order.
    pub dacs: Vec<Dac8568>,
    /// The first cycle not yet run.
    cycle: u64,
    gpio_ctrl: [u32; GPIOS],
    /// Per PIO block, the pins whose FUNCSEL is its.
    pio_pins: [u32; 2],
    bus_priority: u32,
    /// The blocks held in reset (RESETS bits of [`resets::ALL`]).
    held: u32,
    /// Driven levels as the converters saw them last (a data word).
    pin_levels: u32,
    /// Driven directions as the converters saw them last.
    pin_dirs: u32,
    /// The levels the converters drive (their SDO pins).
    gpio_in: u32,
    /// Per DMA master (read, write), the last cycle it claimed each SRAM bank.
    dma_claim: [[u64; BANKS]; 2],
    /// SRAM banks an enabled channel may reach ([`Dma::reach`]).
    reach_banks: u8,
    /// Tick every cycle, never skipping a quiet stretch: the reference the skipping is
    /// tested against (`tests/io.rs`, the firmware's `tests/converters.rs`). Results never
    /// depend on it.
    pub stepwise: bool,
    /// Per PIO block and state machine, the first cycle not yet applied to it: behind
    /// [`Io::cycle`] only inside [`Io::advance`], while the cycles between change nothing
    /// in it but its clock divider and delay ([`Pio::sm_skip`]).
    sm_clock: [[u64; 4]; 2],
    /// Inside [`Io::advance`], per ADC the GPIO inputs it drives from the cycle it started
    /// at: (first cycle, levels) at each change, oldest first; the synchronisers' flops
    /// follow from them.
    sdo_log: Vec<Vec<(u64, u32)>>,
    /// Per PIO block and state machine, what [`Io::run_ahead`] may run of it, found for the
    /// blocks' configuration epochs ([`Pio::config_epoch`]) and the I/O's register writes;
    /// shared, not copied, by a clone ([`Io::checkpoint`]).
    ahead: Option<std::sync::Arc<Ahead>>,
    /// The state machines held at the head of a bit loop behind [`Io::cycle`] (bit 4b + n),
    /// at their clocks, by an advance that did not settle ([`Io::advance`]): nothing sees
    /// them until they run on; [`Io::sdo_log`] keeps their ADCs' outputs meanwhile.
    behind: u8,
    /// Per PIO block and state machine held behind, the cycle its loop ends at: until an
    /// advance reaches it (or settles), it stays held without a look.
    held_until: [[u64; 4]; 2],
    /// The cycle before which nothing runs, as the last advance found it (`Io::skip_idle`).
    idle: Idle,
    /// The lanes of the pins' levels and of the GPIO inputs while a replay is recorded
    /// (`crate::lanes`); `None` otherwise.
    lanes: Option<Box<IoLanes>>,
    /// Which machine this is and how often it has been changed but for its data
    /// ([`Io::touches`]).
    touches: Touches,
}

/// A machine's identity (unique in the process) and a count of its changes but for its
/// data: a period memo knows from it that the machine is still as its last replay left it
/// (`accel/io_window/`). A note, not state: machines that differ only in it are equal.
#[derive(Clone, Copy)]
struct Touches {
    id: u64,
    n: u64,
}

impl Touches {
    /// A new machine's.
    fn new() -> Touches {
        static IDS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        Touches {
            id: IDS.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            n: 0,
        }
    }
}

impl PartialEq for Touches {
    fn eq(&self, _: &Touches) -> bool {
        true
    }
}

impl std::fmt::Debug for Touches {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Touches")
    }
}

impl Io {
    /// The driven levels and directions as the converters saw them last.
    #[inline]
    fn pins(&self) -> (u32, u32) {
        (self.pin_levels, self.pin_dirs)
    }

    #[inline]
    fn set_pins(&mut self, (levels, dirs): (u32, u32)) {
        (self.pin_levels, self.pin_dirs) = (levels, dirs);
    }

    /// The machine out of reset, on a system clocked at `clock_hz`, with `config`'s
    /// converters at their pins; its clock at `cycle`.
    pub fn new(config: &IoConfig, clock_hz: f64, cycle: u64) -> Io {
        Io {
            pio: [Pio::new(), Pio::new()],
            dma: Dma::new(),
            adcs: config
                .adcs
                .iter()
                .map(|&(part, pins)| Ads8688::new(part, pins, clock_hz))
                .collect(),
            dacs: config
                .dacs
                .iter()
                .map(|&(part, pins)| Dac8568::new(part, pins, clock_hz))
                .collect(),
            cycle,
            gpio_ctrl: [FUNCSEL_NULL; GPIOS],
            pio_pins: [0; 2],
            bus_priority: 0,
            held: 0,
            pin_levels: 0,
            pin_dirs: 0,
            gpio_in: 0,
            dma_claim: [[u64::MAX; BANKS]; 2],
            reach_banks: 0,
            stepwise: false,
            sm_clock: [[cycle; 4]; 2],
            sdo_log: Vec::new(),
            ahead: None,
            behind: 0,
            held_until: [[0; 4]; 2],
            idle: Idle(0),
            lanes: None,
            touches: Touches::new(),
        }
    }

    /// Whether its parts keep their frames and updates (at most
    /// [`crate::converters::MAX_KEPT`] each, the default) or none (for a run that never
    /// reads them: `tactus play` without an I/O trace). Results never depend on it; the
    /// parts' timing violations are kept either way.
    pub fn keep_records(&mut self, on: bool) {
        let max = if on { crate::converters::MAX_KEPT } else { 0 };
        self.adcs.iter_mut().for_each(|a| a.set_kept(max));
        self.dacs.iter_mut().for_each(|d| d.set_kept(max));
    }

    /// The RP2040's side reset at `cycle` by a watchdog reset (PSM.WDSEL, `crate::watchdog`):
    /// the PIOs, the DMA, IO_BANK0 and BUSCTRL at their power-on values, the pins undriven;
    /// the converters at the pins keep their state, but the DACs are cleared
    /// ([`Dac8568::clear`], the board's CLR wiring). The machine must have run to `cycle`.
    pub(crate) fn chip_reset(&mut self, cycle: u64) {
        let fresh = Io::new(&IoConfig::default(), 0.0, cycle);
        let old = std::mem::replace(self, fresh);
        self.adcs = old.adcs;
        self.dacs = old.dacs;
        self.stepwise = old.stepwise;
        self.touches = old.touches;
        for d in &mut self.dacs {
            d.clear(cycle);
        }
        self.forget_idle();
    }

    /// Forgets what the last advance found of the cycles ahead ([`Idle`]): a caller that
    /// may change the machine through its public fields.
    pub(crate) fn forget_idle(&mut self) {
        self.idle = Idle(0);
        self.touch();
    }

    /// After the host changed its data words (an ADC's codes: [`crate::Board::set_adc_code`]):
    /// what the last advance found of the cycles ahead no longer holds (an ADC's output
    /// follows its codes), but its control state is as it was, so a period memo still
    /// knows where it is (no touch, unlike [`Io::forget_idle`]).
    pub(crate) fn data_changed(&mut self) {
        self.idle = Idle(0);
    }

    /// The first cycle the machine has not run yet.
    pub fn cycle(&self) -> u64 {
        self.cycle
    }

    /// Whether a state machine is held behind its cycle ([`Io::advance`] without settling).
    pub(crate) fn is_behind(&self) -> bool {
        self.behind != 0
    }

    /// SRAM banks an enabled DMA channel may reach before the next DMA register write.
    pub fn reach_banks(&self) -> u8 {
        self.reach_banks
    }

    /// Whether the DMA's masters win a bank against core `core` (module documentation).
    pub fn dma_wins(&self, core: usize) -> bool {
        let p = self.bus_priority;
        let dma_high = p & priority::DMA_R != 0 && p & priority::DMA_W != 0;
        let core_bit = if core == 0 {
            priority::PROC0
        } else {
            priority::PROC1
        };
        dma_high && p & core_bit == 0
    }

    /// Whether a DMA master claimed `bank` in `cycle`.
    pub(crate) fn dma_claims(&self, bank: usize, cycle: u64) -> bool {
        self.dma_claim[0][bank] == cycle || self.dma_claim[1][bank] == cycle
    }

    /// Whether a core's store to `addr` (one of this machine's registers, [`Io::owns`])
    /// would be taken now: its block is not held in reset.
    pub(crate) fn accepts(&self, addr: u32) -> bool {
        Self::owns(addr) && self.held & Self::reset_bit(addr & !0x3fff) == 0
    }

    /// Whether `addr` (any atomic alias) is one of this machine's registers.
    pub fn owns(addr: u32) -> bool {
        let base = addr & !0x3fff;
        matches!(
            base,
            DMA_BASE | PIO0_BASE | PIO1_BASE | IO_BANK0_BASE | BUSCTRL_BASE
        )
    }

    /// The RESETS bit of the block at `base`.
    fn reset_bit(base: u32) -> u32 {
        match base {
            DMA_BASE => resets::DMA,
            PIO0_BASE => resets::PIO0,
            PIO1_BASE => resets::PIO1,
            IO_BANK0_BASE => resets::IO_BANK0,
            _ => resets::BUSCTRL,
        }
    }

    /// The register at `addr` (any alias) without side effects where reading has some (a
    /// PIO RX FIFO reads 0 here).
    fn peek(&mut self, base: u32, off: u32) -> u32 {
        match base {
            DMA_BASE => self.dma.read(off),
            PIO0_BASE | PIO1_BASE if (0x20..0x30).contains(&off) => 0,
            PIO0_BASE => self.pio[0].read(off),
            PIO1_BASE => self.pio[1].read(off),
            IO_BANK0_BASE => self.gpio_read(off),
            _ => self.busctrl_read(off),
        }
    }

    fn gpio_read(&self, off: u32) -> u32 {
        let n = (off / 8) as usize;
        match (n < GPIOS, off % 8) {
            (true, 4) => self.gpio_ctrl[n],
            // GPIOn_STATUS: OUTTOPAD (bit 9), OETOPAD (13), INFROMPAD (17).
            (true, 0) => {
                let bit = |m: u32| (m >> n) & 1;
                bit(self.pin_levels) << 9 | bit(self.pin_dirs) << 13 | bit(self.gpio_in) << 17
            }
            _ => 0,
        }
    }

    fn busctrl_read(&self, off: u32) -> u32 {
        match off {
            0 => self.bus_priority,
            // BUS_PRIORITY_ACK: the new priorities are in force at once here.
            4 => 1,
            _ => 0,
        }
    }

    /// A core reads the register at `addr` (the machine run up to the access's cycle);
    /// `None` for a block held in reset (a bus fault).
    pub(crate) fn read(&mut self, addr: u32) -> Option<u32> {
        self.idle = Idle(0);
        self.touch();
        let base = addr & !0x3fff;
        if self.held & Self::reset_bit(base) != 0 {
            return None;
        }
        let off = addr & 0xfff;
        Some(match base {
            DMA_BASE => self.dma.read(off),
            PIO0_BASE => self.pio[0].read(off),
            PIO1_BASE => self.pio[1].read(off),
            _ => self.peek(base, off),
        })
    }

    /// A core writes the register at `addr` (any alias); false for a block held in reset.
    pub(crate) fn write(&mut self, addr: u32, value: u32) -> bool {
        self.idle = Idle(0);
        self.touch();
        let base = addr & !0x3fff;
        if self.held & Self::reset_bit(base) != 0 {
            return false;
        }
        let off = addr & 0xfff;
        let value = match (addr >> 12) & 3 {
            0 => value,
            alias => {
                let old = self.peek(base, off);
                match alias {
                    1 => old ^ value,
                    2 => old | value,
                    _ => old & !value,
                }
            }
        };
        match base {
            DMA_BASE => {
                self.dma.write(off, value);
                self.reach_banks = self.dma.reach().fold(0, |m, (a, len)| m | banks_of(a, len));
            }
            PIO0_BASE => self.pio[0].write(off, value),
            PIO1_BASE => self.pio[1].write(off, value),
            IO_BANK0_BASE => {
                self.ahead = None;
                let n = (off / 8) as usize;
                if n < GPIOS && off % 8 == 4 {
                    self.gpio_ctrl[n] = value & 0x3303_331f;
                    self.refresh_funcsel();
                }
            }
            _ => {
                if off == 0 {
                    self.bus_priority = value & 0x1111;
                }
            }
        }
        true
    }

    fn refresh_funcsel(&mut self) {
        self.pio_pins = [0; 2];
        for (n, c) in self.gpio_ctrl.iter().enumerate() {
            match c & 0x1f {
                6 => self.pio_pins[0] |= 1 << n,
                7 => self.pio_pins[1] |= 1 << n,
                _ => {}
            }
        }
    }

    /// RESETS now holds `held` (its RESET register): a block newly put into reset returns
    /// to its reset state.
    pub(crate) fn set_resets(&mut self, held: u32) {
        self.idle = Idle(0);
        self.touch();
        let held = held & IO_RESETS;
        let entering = held & !self.held;
        self.ahead = None;
        if entering & resets::PIO0 != 0 {
            self.pio[0] = Pio::new();
        }
        if entering & resets::PIO1 != 0 {
            self.pio[1] = Pio::new();
        }
        if entering & resets::DMA != 0 {
            self.dma = Dma::new();
            self.reach_banks = 0;
        }
        if entering & resets::IO_BANK0 != 0 {
            self.gpio_ctrl = [FUNCSEL_NULL; GPIOS];
            self.refresh_funcsel();
        }
        if entering & resets::BUSCTRL != 0 {
            self.bus_priority = 0;
        }
        self.held = held;
    }
}
