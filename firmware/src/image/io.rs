//! The converter drivers of a board whose file names `[converters]`
//! (`tactus_runtime::converters`): per core one ADC (key positions) and one DAC (motor
//! currents), each clocked by a PIO state machine of the core's own PIO block (core *c*:
//! PIO*c*), its frames moved by the core's own three DMA channels between the PIO FIFOs and
//! the core's own I/O block in SRAM bank 2 + *c* (through the non-striped alias).
//!
//! **Why this shape.** Each core's sensor and DAC words, PIO block, state machines,
//! instruction memory, DMA channels and buffers are its own, so where the cores still meet
//! is named: the DMA's one read and one write port, shared by both cores' channels in
//! round-robin (a transfer of one core's can wait a cycle for the other's), and
//! BUS_PRIORITY, which core 0 sets once at boot. The buffers lie in a bank no other code or
//! data of the image uses while it runs (banks 2 and 3 hold the host's windows above
//! [`IO_OFFSET`] and, below it, a RAM image's re-entry and the pristine copies of its data,
//! which only the boot after a watchdog reset reads: `super::reboot`), so the DMA meets a
//! core's accesses only there: the handler's own reads
//! and writes of its buffers, which wait at most one cycle per DMA access to the bank
//! (the DMA has the higher bus priority) — [`CoreIo::contention`], in the static bound.
//!
//! **A sample.** At each tick the handler's first act starts three DMA sequences, each by
//! one store of its address through a trigger alias (RP2040 datasheet 2.5.2.1): the ADC's
//! results into the next buffer of a ring of three ([`RESULTS`]; not the one the handler
//! reads this sample), the ADC's commands into its state machine's TX FIFO (paced by its DREQ:
//! one frame per command), and the DAC frames the *previous* sample's handler wrote into
//! the DAC state machine's TX FIFO (joined to 8 entries: all of them move at once, before
//! this handler writes any). Then the keys read the results of the burst the previous
//! handler started, sampled during the last period, and write their DAC frames. So a key's
//! position sampled in period *n* − 1 is read by the handler of tick *n* and its answer goes
//! out at tick *n* + 1: race-free by construction, with the check that one burst of ADC
//! frames and one of DAC frames each fit a sample period ([`IoPlan::new`]). The start
//! handler starts the first ADC burst, so the first sample reads a fresh one. The DAC powers
//! up at midscale (0 A), and the DAC buffer starts with midscale frames.
//!
//! **A resting board repeats as a plain one does.** A board whose keys rest comes back to
//! the same state every 1,071 samples at 133 MHz (the tick schedule's 63 and the
//! differentiators' 17; 7,497 at 200 MHz), which the main job's rest replay finds and skips
//! (`tactus_emulator::board`'s rest points) — after emulating one whole period. Two things
//! of the drivers' would double that period, each alternating every sample: two results
//! buffers in turn, and the DMA's round-robin among the low-priority channels, since both
//! cores' results channels, and both their commands channels, become ready in the same
//! cycles. Hence a ring of three results buffers (3 divides 63 and 441), which costs no
//! cycle: each buffer's [`RING_NEXT`] word names the next, and the handler steps the ring
//! with one `LDR` where it flipped a bit with a `MOVS` and an `EORS` (that load may wait
//! for the DMA as the handler's other accesses to the bank do: [`CoreIo::contention`]
//! bounds the waits by the DMA's accesses, not the core's). And channel numbers in which
//! each tie resolves as the last: core 0's results and commands channels 0 and 1, core 1's
//! 4 and 3 ([`dma_channels`]). Served round-robin, a tie goes to the channel after the
//! last served: with core 1's two in the same order as core 0's (3 and 4), every change
//! from a results tie to a commands tie, or back, swapped which core went first, and the
//! number of changes in a sample is odd; with them swapped, every tie goes core 1 first.
//!
//! **Frames** (SPI mode 1, MSB first, chip select high between frames): the ADS8688's are 32
//! SCLKs, a 16-bit command in (`MAN_Ch_n`: frame *i* selects channel *i* + 1 for the next,
//! the last channel 0 again, so frame *i* samples channel *i*) and the result of its own
//! sample out in the last 16; the DAC8568's are 32 bits in: control 0011 (write and update
//! the channel), the channel's address, the 16-bit code (straight binary: the limiter's
//! signed code plus 0x8000) and four don't-care bits. Both state machines run four PIO
//! cycles a bit; each part's clock divider and chip-select padding come from its data sheet
//! (`tactus_runtime::converters`) at the board's clock.
//!
//! **The words the keys see.** A sensor word is `lo + (code << shift)` (`AdcScale`, per
//! sensor from its declared range). Where every sensor of a core has `lo` 0 and one shift
//! of at most 16 (a keyboard of one instrument), the ADC's state machine pushes that word
//! itself ([`adc_program`]'s `direct`) and the keys read it where it lies, as they read a
//! window word without converters; otherwise the handler makes each word of its code (an
//! `LDRH`, an `LSLS`, an `ADDS` from a literal where `lo` is not 0). The DAC's state
//! machine assembles each frame from a word whose header the image wrote and whose low half
//! the handler stores with one `STRH` ([`dac_word`], [`dac_program`]). So on such a core the
//! drivers cost the handler its first 17 to 19 cycles and nothing per key but the DMA's
//! contention.

use super::ImageError;
use crate::board_file::BoardError;
use tactus_compiler::thumb::buffer::CodeBuffer;
use tactus_compiler::thumb::ins as asm;
use tactus_emulator::converters::SpiPins;
use tactus_isa::decode::{Instr, MemOp};
use tactus_rp2040::busctrl::{priority, BUSCTRL_BASE};
use tactus_rp2040::dma::{ctrl as dctrl, reg as dreg, DMA_BASE};
use tactus_rp2040::io_bank0::{FUNCSEL_PIO0, IO_BANK0_BASE};
use tactus_rp2040::memory::SRAM_ALIAS_BASE;
use tactus_rp2040::pio::{reg as preg, PIO0_BASE, PIO1_BASE};
use tactus_runtime::converters::{AdcPart, AdcScale, Converters, DacPart};
use tactus_runtime::keyboard::BoardSpec;

/// Bank offset of each core's I/O block (in bank 2 + core, below the windows at 0xfc00).
pub const IO_OFFSET: u32 = 0xf000;
/// Byte offset in the I/O block of results buffer A (one word per ADC channel), the first
/// of the ring of three ([`RESULTS`]).
pub const RESULTS_A: u32 = 0x00;
/// The ring of results buffers, A, B, C (module documentation, "A sample"): each of
/// [`MAX_CHANNELS`] words and its [`RING_NEXT`] word.
pub const RESULTS: [u32; 3] = [RESULTS_A, 0x24, 0x48];
/// Byte offset from a results buffer of the word holding the next buffer's address in the
/// ring (A's is B's, B's C's, C's A's): past its channels' words.
pub const RING_NEXT: u32 = 4 * MAX_CHANNELS;
/// The ADC command words.
pub const COMMANDS: u32 = 0x6c;
/// The DAC frames (one word per DAC channel): the handler's `r7`.
pub const DAC_FRAMES: u32 = 0x8c;
/// The results buffer the next handler reads (the current burst's).
pub const READ_NEXT: u32 = 0xac;
/// The results buffer this handler reads.
pub const READ_NOW: u32 = 0xb0;
/// Bytes of the I/O block.
pub const IO_BYTES: u32 = 0xb4;
/// Most channels of a part the drivers use (the buffers' size).
pub const MAX_CHANNELS: u32 = 8;

/// DMA channels of core `core`: results, commands, DAC frames — core 1's results and
/// commands channels in the other order than core 0's, so that the DMA's round-robin
/// resolves the two cores' ties the same way every sample (module documentation, "A
/// resting board repeats").
pub fn dma_channels(core: usize) -> [u32; 3] {
    let c = 3 * core as u32;
    match core {
        0 => [c, c + 1, c + 2],
        _ => [c + 1, c, c + 2],
    }
}

/// The handler's DMA trigger stores of core `core` from one base register: the base
/// channel's registers' address, the results channel's `AL2_WRITE_ADDR_TRIG` and the
/// commands channel's `AL3_READ_ADDR_TRIG` offsets from it, and the DAC channel's
/// registers' offset (added to the base before its `AL3_READ_ADDR_TRIG` store).
fn trigger_offsets(core: usize) -> (u32, u16, u16, u8) {
    let [res, cmd, dac] = dma_channels(core);
    let base = res.min(cmd);
    let at = |ch: u32, reg: u32| ((ch - base) * dreg::CH_STRIDE + reg) as u16;
    (
        DMA_BASE + base * dreg::CH_STRIDE,
        at(res, dreg::AL2_WRITE_ADDR_TRIG),
        at(cmd, dreg::AL3_READ_ADDR_TRIG),
        ((dac - base) * dreg::CH_STRIDE) as u8,
    )
}

/// The address of core `core`'s I/O block (bank 2 + core through the non-striped alias).
pub fn io_base(core: usize) -> u32 {
    SRAM_ALIAS_BASE + 0x1_0000 * (2 + core as u32) + IO_OFFSET
}

/// The PIO block of core `core`.
pub fn pio_base(core: usize) -> u32 {
    if core == 0 {
        PIO0_BASE
    } else {
        PIO1_BASE
    }
}

/// A PIO instruction with two side-set bits (`.side_set 2`: SCLK, CS) and three of delay
/// (RP2040 datasheet 3.4: bits 12:11 side-set, 10:8 delay).
fn ins(op: u16, side: u16, delay: u16) -> u16 {
    debug_assert!(side < 4 && delay < 8);
    op | side << 11 | delay << 8
}

/// pioasm's encodings (datasheet 3.4): `pull block`, `push block`, `set x, n`, `out pins, 1`,
/// `in pins, 1`, `jmp x--, addr`, `nop` (`mov y, y`), `set pins, n`, `set pindirs, n`,
/// `jmp addr`, `in null, n`, `out null, n`, `out x, n`, `mov pins, !x`.
mod op {
    pub const PULL_BLOCK: u16 = 0x80a0;
    pub const PUSH_BLOCK: u16 = 0x8020;
    pub const SET_X: u16 = 0xe020;
    pub const OUT_PINS_1: u16 = 0x6001;
    pub const IN_PINS_1: u16 = 0x4001;
    pub const JMP_X_DEC: u16 = 0x0040;
    pub const NOP: u16 = 0xa042;
    pub const SET_PINS: u16 = 0xe000;
    pub const SET_PINDIRS: u16 = 0xe080;
    pub const JMP: u16 = 0x0000;
    pub const IN_NULL: u16 = 0x4060;
    pub const OUT_NULL: u16 = 0x6060;
    pub const OUT_X: u16 = 0x6020;
    pub const MOV_PINS_NOT_X: u16 = 0xa009;
}

/// Side-set values: SCLK bit 0, CS bit 1.
const CS_HIGH: u16 = 0b10;
const SCLK_HIGH: u16 = 0b01;

/// A state machine's program: its words (from `origin` in instruction memory), where it
/// wraps, and its timing in PIO cycles.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PioProgram {
    /// Instruction words.
    pub words: Vec<u16>,
    /// Its first address in the block's instruction memory (the wrap's bottom).
    pub origin: u32,
    /// PIO cycles of one frame, chip select fall to fall, when the next word is waiting.
    pub frame_pio_cycles: u32,
    /// PIO cycles the chip select stays high between two frames.
    pub cs_high_pio_cycles: u32,
    /// PIO cycles from the chip select's fall to the edge that matters: the ADC's 17th
    /// SCLK rise (its result's first bit, after the conversion), the DAC's 32nd SCLK fall
    /// (the channel's update).
    pub edge_pio_cycles: u32,
}

impl PioProgram {
    /// The wrap's top.
    pub fn top(&self) -> u32 {
        self.origin + self.words.len() as u32 - 1
    }
}

/// The chip-select padding of `cycles` PIO cycles high (at least 1): a `pull block` with up
/// to 7 cycles of delay and `nop`s of up to 8 more.
fn padding(cycles: u32) -> Result<Vec<u16>, BoardError> {
    let mut words = vec![ins(
        op::PULL_BLOCK,
        CS_HIGH,
        (cycles.max(1) - 1).min(7) as u16,
    )];
    let mut left = cycles.saturating_sub(8);
    while left > 0 {
        let d = (left - 1).min(7);
        words.push(ins(op::NOP, CS_HIGH, d as u16));
        left -= d + 1;
    }
    if words.len() > 8 {
        return Err(board_err(
            "converters",
            "the chip select's padding needs more than 8 PIO instructions".into(),
        ));
    }
    Ok(words)
}

/// PIO cycles of the ADC program's frame beyond its chip-select padding: 129, or with
/// `direct` 130 (+ 1 with a shift).
fn adc_frame_body(direct: Option<u32>) -> u32 {
    match direct {
        None => 129,
        Some(0) => 130,
        Some(_) => 131,
    }
}

/// The ADC's state machine program at `origin`, chip select high `cs_high` PIO cycles.
/// Without `direct` the word it pushes is the frame's 32 bits as they come (the result in
/// the low half; the handler makes the sensor word of it):
///
/// ```text
///     pull block   side 0b10 [..]  ; CS high, waiting for a command (padding: + nops)
///     set x, 30    side 0b00       ; CS falls: the part samples
/// b:  out pins, 1  side 0b01 [1]   ; SCLK rises: a command bit launched
///     in pins, 1   side 0b00       ; SCLK falls: a result bit latched
///     jmp x--, b   side 0b00
///     out pins, 1  side 0b01 [1]   ; the 32nd bit
///     in pins, 1   side 0b00
///     push block   side 0b00       ; the frame's word to the RX FIFO
/// ```
///
/// With `direct = Some(shift)` (shift ≤ 16) it pushes the sensor word itself, `code <<
/// shift`, which the update reads where it lies:
///
/// ```text
///     pull block   side 0b10 [..]
///     set x, 15    side 0b00       ; CS falls
/// c:  out pins, 1  side 0b01 [1]   ; the 16 command bits
///     jmp x--, c   side 0b00 [1]
///     set x, 15    side 0b00
/// r:  out pins, 1  side 0b01 [1]   ; the 16 result bits (SDI 0)
///     in pins, 1   side 0b00
///     jmp x--, r   side 0b00
///     in null, s   side 0b00       ; (without a shift: none)
///     push block   side 0b00
/// ```
pub fn adc_program(
    origin: u32,
    cs_high: u32,
    direct: Option<u32>,
) -> Result<PioProgram, BoardError> {
    let mut words = padding(cs_high)?;
    let edge = match direct {
        None => {
            words.push(ins(op::SET_X | 30, 0, 0));
            let b = origin + words.len() as u32;
            words.extend([
                ins(op::OUT_PINS_1, SCLK_HIGH, 1),
                ins(op::IN_PINS_1, 0, 0),
                ins(op::JMP_X_DEC | b as u16, 0, 0),
                ins(op::OUT_PINS_1, SCLK_HIGH, 1),
                ins(op::IN_PINS_1, 0, 0),
                ins(op::PUSH_BLOCK, 0, 0),
            ]);
            1 + 16 * 4
        }
        Some(shift) => {
            words.push(ins(op::SET_X | 15, 0, 0));
            let c = origin + words.len() as u32;
            words.extend([
                ins(op::OUT_PINS_1, SCLK_HIGH, 1),
                ins(op::JMP_X_DEC | c as u16, 0, 1),
                ins(op::SET_X | 15, 0, 0),
            ]);
            let r = origin + words.len() as u32;
            words.extend([
                ins(op::OUT_PINS_1, SCLK_HIGH, 1),
                ins(op::IN_PINS_1, 0, 0),
                ins(op::JMP_X_DEC | r as u16, 0, 0),
            ]);
            if shift > 0 {
                words.push(ins(op::IN_NULL | (shift & 31) as u16, 0, 0));
            }
            words.push(ins(op::PUSH_BLOCK, 0, 0));
            1 + 16 * 4 + 1
        }
    };
    Ok(PioProgram {
        words,
        origin,
        frame_pio_cycles: cs_high.max(1) + adc_frame_body(direct),
        cs_high_pio_cycles: cs_high.max(1),
        edge_pio_cycles: edge,
    })
}

/// The DAC's state machine program at `origin`, SYNC high `cs_high` PIO cycles. Each word
/// it takes is a DAC channel's frame header in bits 31:20 (prefix 0000, control, address:
/// [`dac_word`]) and the limiter's signed code in bits 15:0, which the handler stores with
/// one `STRH`; the program sends the header, then the code's sign bit inverted (straight
/// binary: code + 0x8000), its other 15 bits, and four zero don't-care bits:
///
/// ```text
///     pull block   side 0b10 [..]  ; SYNC high, waiting for a word (padding: + nops)
///     set x, 11    side 0b00       ; SYNC falls
/// h:  out pins, 1  side 0b01 [1]   ; the 12 header bits
///     jmp x--, h   side 0b00 [1]
///     out null, 4  side 0b00       ; bits 19:16, not sent
///     out x, 1     side 0b00       ; the code's sign
///     mov pins, !x side 0b01 [1]   ; … inverted
///     set x, 14    side 0b00 [1]
/// d:  out pins, 1  side 0b01 [1]   ; its 15 other bits
///     jmp x--, d   side 0b00 [1]
///     set x, 3     side 0b00
/// f:  set pins, 0  side 0b01 [1]   ; 4 don't-care bits
///     jmp x--, f   side 0b00 [1]   ; the 32nd falls: the channel updates
/// ```
pub fn dac_program(origin: u32, cs_high: u32) -> Result<PioProgram, BoardError> {
    let mut words = padding(cs_high)?;
    words.push(ins(op::SET_X | 11, 0, 0));
    let h = origin + words.len() as u32;
    words.extend([
        ins(op::OUT_PINS_1, SCLK_HIGH, 1),
        ins(op::JMP_X_DEC | h as u16, 0, 1),
        ins(op::OUT_NULL | 4, 0, 0),
        ins(op::OUT_X | 1, 0, 0),
        ins(op::MOV_PINS_NOT_X, SCLK_HIGH, 1),
        ins(op::SET_X | 14, 0, 1),
    ]);
    let d = origin + words.len() as u32;
    words.extend([
        ins(op::OUT_PINS_1, SCLK_HIGH, 1),
        ins(op::JMP_X_DEC | d as u16, 0, 1),
        ins(op::SET_X | 3, 0, 0),
    ]);
    let f = origin + words.len() as u32;
    words.extend([
        ins(op::SET_PINS, SCLK_HIGH, 1),
        ins(op::JMP_X_DEC | f as u16, 0, 1),
    ]);
    Ok(PioProgram {
        words,
        origin,
        frame_pio_cycles: cs_high.max(1) + 132,
        cs_high_pio_cycles: cs_high.max(1),
        edge_pio_cycles: 130,
    })
}

/// One core's converters: pins, the channels its keys use, each ADC channel's scale, its
/// ADC program.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CoreIo {
    /// The ADC's pins.
    pub adc_pins: SpiPins,
    /// The DAC's pins (`sdo` unused: its SDI again).
    pub dac_pins: SpiPins,
    /// Per ADC channel the core's keys read (in channel order), the code → word scale of
    /// its sensor.
    pub scales: Vec<AdcScale>,
    /// DAC channels its keys drive.
    pub dac_channels: u32,
    /// The ADC's program (after the DAC's in the core's PIO block).
    pub adc_program: PioProgram,
    /// Whether its ADC pushes the sensor words themselves (every channel's scale has the
    /// same shift, at most 16, and `lo` 0: [`adc_program`]'s `direct`), which the keys
    /// read where they lie; else the handler makes each word of its code.
    pub direct: bool,
}

impl CoreIo {
    /// ADC channels its keys read.
    pub fn adc_channels(&self) -> u32 {
        self.scales.len() as u32
    }

    /// The most cycles the DMA's accesses to the core's I/O bank make its handler wait in
    /// one sample: one per access (the DMA wins a bank for a cycle, and a core has one
    /// access in flight): a command read and a result write per ADC frame, a frame read
    /// per DAC frame.
    pub fn contention(&self) -> u64 {
        2 * u64::from(self.adc_channels()) + u64::from(self.dac_channels)
    }
}

/// The drivers of an image (module documentation): the parts, the programs and dividers,
/// and each core's converters.
#[derive(Clone, Debug, PartialEq)]
pub struct IoPlan {
    /// The ADC part.
    pub adc: &'static AdcPart,
    /// The DAC part.
    pub dac: &'static DacPart,
    /// The DAC's program (at 0 in each core's PIO block; each core's ADC program follows).
    pub dac_program: PioProgram,
    /// The ADC's and DAC's PIO clock dividers (whole numbers).
    pub adc_div: u32,
    /// The DAC's divider.
    pub dac_div: u32,
    /// Per core.
    pub cores: Vec<CoreIo>,
}

fn board_err(field: &'static str, why: String) -> BoardError {
    BoardError { field, why }
}

/// The shift every scale of `scales` shares when the ADC can push their sensor words
/// directly (`lo` 0, one shift at most 16); `None` otherwise.
fn direct_shift(scales: &[AdcScale]) -> Option<u32> {
    let shift = scales.first().map_or(0, |s| s.shift);
    (shift <= 16 && scales.iter().all(|s| s.lo == 0 && s.shift == shift)).then_some(shift)
}

impl IoPlan {
    /// The drivers for `board`'s converters on a `clock_hz` clock and `q` cycles per sample,
    /// the keys of core *c* reading ADC channels with `scales[c]` and driving `dacs[c]` DAC
    /// channels; `None` for a board without converters.
    ///
    /// Errors: [`ImageError::Board`] naming the field: a part without a driver, pins the
    /// drivers cannot use, more channels than a part has ("more keys than converter
    /// channels"), or timing the parts or the sample period do not allow.
    pub fn new(
        board: &BoardSpec,
        clock_hz: u64,
        q: u64,
        scales: Vec<Vec<AdcScale>>,
        dacs: Vec<u32>,
    ) -> Result<Option<IoPlan>, ImageError> {
        let Some(conv) = &board.converters else {
            return Ok(None);
        };
        conv.check(&board.name, board.cores)
            .map_err(ImageError::Board)?;
        IoPlan::checked(conv, clock_hz, q, scales, dacs)
            .map(Some)
            .map_err(|e| ImageError::Board(e.to_string()))
    }

    /// [`IoPlan::new`] with its errors as a board file's fields (what
    /// `crate::boards::check_drivers` reports): `converters` for the parts or their wiring
    /// (`Converters::check`) or the PIO programs, else `converters.adc` or `converters.dac`.
    ///
    /// Errors: [`BoardError`] naming the field.
    pub fn plan(
        board: &BoardSpec,
        clock_hz: u64,
        q: u64,
        scales: Vec<Vec<AdcScale>>,
        dacs: Vec<u32>,
    ) -> Result<Option<IoPlan>, BoardError> {
        let Some(conv) = &board.converters else {
            return Ok(None);
        };
        conv.check(&board.name, board.cores)
            .map_err(|why| board_err("converters", why))?;
        IoPlan::checked(conv, clock_hz, q, scales, dacs).map(Some)
    }

    /// The plan for converters `conv` that `Converters::check` has accepted (parts the
    /// firmware drives, each core's pins), with errors as in [`IoPlan::plan`].
    fn checked(
        conv: &Converters,
        clock_hz: u64,
        q: u64,
        scales: Vec<Vec<AdcScale>>,
        dacs: Vec<u32>,
    ) -> Result<IoPlan, BoardError> {
        let (Some(adc), Some(dac)) = (conv.adc_part(), conv.dac_part()) else {
            return Err(board_err("converters.adc", "no driver for the part".into()));
        };
        let clock = clock_hz as f64;
        // Four PIO cycles a bit: the divider that keeps SCLK at or below the part's limit.
        let div = |max_hz: f64| (clock / (4.0 * max_hz)).ceil().max(1.0) as u32;
        let (adc_div, dac_div) = (div(adc.sclk_max_hz), div(dac.sclk_max_hz));
        if adc_div > 0xffff || dac_div > 0xffff {
            return Err(board_err(
                "converters.adc",
                "the board's clock is too fast to divide".into(),
            ));
        }
        // The DAC: SYNC high at least sync_high_min_s, strictly; SYNC falling to the first
        // SCLK falling edge (its `set`, then the first bit's two high cycles) at least
        // sync_setup_min_s.
        let dac_cs = (dac.sync_high_min_s * clock / f64::from(dac_div)).floor() as u32 + 1;
        let dac_program = dac_program(0, dac_cs)?;
        let setup = f64::from(3 * dac_div) / clock;
        if setup < dac.sync_setup_min_s {
            return Err(board_err(
                "converters.dac",
                format!(
                    "{}: SYNC falls {:.0} ns before SCLK, under its {:.0} ns",
                    dac.name,
                    setup * 1e9,
                    dac.sync_setup_min_s * 1e9
                ),
            ));
        }
        // The ADC: a frame at most every frame_period_min_s, strictly.
        let min_frame = (adc.frame_period_min_s * clock / f64::from(adc_div)).floor() as u32 + 1;
        let mut cores = Vec::new();
        for (c, (scales, dacs)) in scales.into_iter().zip(dacs).enumerate() {
            let max = adc.channels.min(MAX_CHANNELS);
            if scales.len() as u32 > max {
                return Err(board_err(
                    "converters.adc",
                    format!(
                        "core {c}'s keys read {} sensors, more than the {max} channels of its \
                         {} (one channel per sensor word: fewer keys per core, or more boards)",
                        scales.len(),
                        adc.name
                    ),
                ));
            }
            let max = dac.channels.min(MAX_CHANNELS);
            if dacs > max {
                return Err(board_err(
                    "converters.dac",
                    format!(
                        "core {c}'s keys drive {dacs} motors, more than the {max} channels of \
                         its {}",
                        dac.name
                    ),
                ));
            }
            let direct = direct_shift(&scales);
            let adc_cs = min_frame.saturating_sub(adc_frame_body(direct)).max(1);
            let origin = dac_program.words.len() as u32;
            let adc_program = adc_program(origin, adc_cs, direct)?;
            if origin + adc_program.words.len() as u32 > 32 {
                return Err(board_err(
                    "converters.adc",
                    "the two programs do not fit a PIO block's 32 instructions".into(),
                ));
            }
            // The result is not clocked out before the conversion ends.
            let to_17th = f64::from(adc_program.edge_pio_cycles * adc_div) / clock;
            if to_17th < adc.conversion_max_s {
                return Err(board_err(
                    "converters.adc",
                    format!(
                        "{}: its result would leave {:.0} ns after the sample, before its \
                         {:.0} ns conversion",
                        adc.name,
                        to_17th * 1e9,
                        adc.conversion_max_s * 1e9
                    ),
                ));
            }
            // A burst must end within the period it starts in (module documentation),
            // with the handler's first cycles (START_SLACK) before it.
            let adc_burst = u64::from(adc_program.frame_pio_cycles * adc_div) * scales.len() as u64
                + START_SLACK;
            let dac_burst =
                u64::from(dac_program.frame_pio_cycles * dac_div) * u64::from(dacs) + START_SLACK;
            for (field, burst) in [("converters.adc", adc_burst), ("converters.dac", dac_burst)] {
                if burst > q {
                    return Err(board_err(
                        field,
                        format!(
                            "core {c}: a burst of its frames takes {burst} cycles, more than \
                             the {q} of a sample period (fewer keys per core, or a lower \
                             sample rate)"
                        ),
                    ));
                }
            }
            let pins = |p: &[u32], sdo: u32| SpiPins {
                sclk: p[0],
                cs: p[1],
                sdi: p[2],
                sdo,
            };
            cores.push(CoreIo {
                adc_pins: pins(&conv.adc_pins[c], conv.adc_pins[c][3]),
                dac_pins: pins(&conv.dac_pins[c], conv.dac_pins[c][2]),
                scales,
                dac_channels: dacs,
                adc_program,
                direct: direct.is_some(),
            });
        }
        Ok(IoPlan {
            adc,
            dac,
            dac_program,
            adc_div,
            dac_div,
            cores,
        })
    }

    /// Core `core`'s ADC frame period, system cycles (CS fall to CS fall, commands
    /// waiting); 0 for no such core.
    pub fn adc_frame_cycles(&self, core: usize) -> u64 {
        self.cores.get(core).map_or(0, |c| {
            u64::from(c.adc_program.frame_pio_cycles * self.adc_div)
        })
    }

    /// The DAC's frame period, system cycles.
    pub fn dac_frame_cycles(&self) -> u64 {
        u64::from(self.dac_program.frame_pio_cycles * self.dac_div)
    }

    /// The static latency of a key of core `core` whose position is ADC channel `adc_ch`
    /// and whose motor is DAC channel `dac_ch`, on a sample tick of `tick`: the most
    /// system cycles from the position's sample (its frame's chip select falling) to the
    /// DAC output that answers it (its frame's 32nd SCLK falling edge), two ticks later
    /// (module documentation). Both bursts start a fixed [`TRIGGER_GAP`] apart after a
    /// tick; each word lands in its state machine's TX FIFO the cycle after its trigger
    /// (the DMA's read, then its write; the DAC's may wait [`DMA_SHARED_WAIT`] for the
    /// other core's); a state machine takes it at its next enabled cycle (0 to `div − 1`
    /// cycles: the ADC at once, the DAC last, for the bound), stays in its chip-select
    /// padding, then clocks the frame; frame *k* of a burst follows *k* frame periods after
    /// the first. Two tick periods are at most `2q + ⌈2·rem/den⌉` cycles. 0 for no such
    /// core.
    pub fn latency_cycles(
        &self,
        core: usize,
        adc_ch: u32,
        dac_ch: u32,
        tick: &crate::board_file::Tick,
    ) -> u64 {
        let Some(c) = self.cores.get(core) else {
            return 0;
        };
        let periods =
            2 * u64::from(tick.q) + (2 * u64::from(tick.rem)).div_ceil(u64::from(tick.den.max(1)));
        let (da, dd) = (u64::from(self.adc_div), u64::from(self.dac_div));
        let d = &self.dac_program;
        let dac = TRIGGER_GAP
            + DMA_SHARED_WAIT
            + (dd - 1)
            + u64::from(d.cs_high_pio_cycles + d.edge_pio_cycles) * dd
            + u64::from(dac_ch) * self.dac_frame_cycles();
        let adc = u64::from(c.adc_program.cs_high_pio_cycles) * da
            + u64::from(adc_ch) * self.adc_frame_cycles(core);
        (periods + dac).saturating_sub(adc)
    }

    /// The emulator's wiring of the parts (`tactus_emulator::io::IoConfig`): core 0's ADC
    /// and DAC first.
    pub fn emulator_config(&self) -> tactus_emulator::io::IoConfig {
        tactus_emulator::io::IoConfig {
            adcs: self.cores.iter().map(|c| (self.adc, c.adc_pins)).collect(),
            dacs: self.cores.iter().map(|c| (self.dac, c.dac_pins)).collect(),
        }
    }

    /// Core `core`'s I/O block as the image loads it: the results buffers zero, the
    /// commands, midscale DAC frames, A as the buffer the first handler reads.
    pub fn io_block(&self, core: usize) -> Vec<u8> {
        let c = &self.cores[core];
        let n = c.adc_channels();
        let mut words = vec![0u32; (IO_BYTES / 4) as usize];
        for i in 0..n {
            words[(COMMANDS / 4 + i) as usize] = adc_command((i + 1) % n);
        }
        for ch in 0..c.dac_channels {
            words[(DAC_FRAMES / 4 + ch) as usize] = dac_word(ch, 0);
        }
        let base = io_base(core);
        for (i, &buf) in RESULTS.iter().enumerate() {
            words[((buf + RING_NEXT) / 4) as usize] = base + RESULTS[(i + 1) % RESULTS.len()];
        }
        words[(READ_NEXT / 4) as usize] = base + RESULTS_A;
        words[(READ_NOW / 4) as usize] = base + RESULTS_A;
        words.iter().flat_map(|w| w.to_le_bytes()).collect()
    }
}

/// System cycles from the data phase of the handler's store that starts the ADC's commands
/// to that of its store that starts the DAC frames ([`IoPlan::handler_start`]: `STR`,
/// `ADDS`, `STR`).
pub const TRIGGER_GAP: u64 = 3;

/// Cycles the first transfer of a core's DAC frames may wait for the DMA's read port: the
/// one place the two cores' converters meet. The DAC channels are the only high-priority
/// ones, served round-robin before the others (RP2040 datasheet 2.5.1 and CH_CTRL's
/// HIGH_PRIORITY), so only the other core's DAC channel, triggered in the same cycle, goes
/// first, once. (An ADC burst that starts a cycle late shortens the latency.)
pub const DMA_SHARED_WAIT: u64 = 1;

/// Cycles allowed from the tick to the first frame of a burst (exception entry, the
/// handler's triggers, the DMA's first transfers).
const START_SLACK: u64 = 64;

/// The ADS8688's `MAN_Ch_n` command for channel `ch`, in a frame word's top half (SBAS582,
/// "Command Register Description": 0xC000 + n·0x400).
pub fn adc_command(ch: u32) -> u32 {
    (0xc000 | (ch & 7) << 10) << 16
}

/// The DAC word of channel `ch` carrying the limiter's signed code `code`, as the DAC's
/// state machine takes it ([`dac_program`]): the frame's header in bits 31:20 — prefix
/// 0000, control 0011 (write and update the channel), the channel's address (SBAS430F
/// 8.2.6) — and the code in bits 15:0, stored there by the handler with one `STRH`.
pub fn dac_word(ch: u32, code: i16) -> u32 {
    3 << 24 | (ch & 0xf) << 20 | u32::from(code as u16)
}

/// The code a DAC word carries.
pub fn word_code(word: u32) -> i16 {
    word as u16 as i16
}

/// The 32-bit frame the DAC receives for [`dac_word`]`(ch, code)`: straight binary data
/// `code + 0x8000` in DB19–4, the don't-care bits DB3–0 zero.
pub fn dac_frame(ch: u32, code: i16) -> u32 {
    3 << 24 | (ch & 0xf) << 20 | u32::from((code as u16) ^ 0x8000) << 4
}

/// `[addr] = value` (clobbers r0, r1).
fn store(a: &mut CodeBuffer, addr: u32, value: u32) {
    a.ldr_const(0, addr);
    a.mov_const(1, value);
    a.i(asm::str(1, 0, 0));
}

/// The blocks the drivers use (RESETS bits), which core 0's start-up pulses through reset
/// before it launches core 1, as pico-sdk's drivers do (`super::boot::core_start`).
pub const RESETS: u32 = {
    use tactus_rp2040::resets;
    resets::PIO0 | resets::PIO1 | resets::DMA | resets::IO_BANK0
};

/// What core 0's start-up does for the converters once [`RESETS`] are out of reset, before
/// it launches core 1: the DMA's bus priority above both cores'. Clobbers r0-r1.
pub fn boot(a: &mut CodeBuffer) {
    store(a, BUSCTRL_BASE, priority::DMA_R | priority::DMA_W);
}

impl IoPlan {
    /// Core `core`'s set-up in its reset handler: its pins to its PIO block, the two
    /// programs and state machines, its three DMA channels (enabled, not started), the
    /// state machines started, and `r7` = its DAC frames. Clobbers r0-r2.
    pub fn core_set_up(&self, a: &mut CodeBuffer, core: usize) {
        let c = &self.cores[core];
        let pio = pio_base(core);
        let funcsel = FUNCSEL_PIO0 + core as u32;
        for p in [c.adc_pins, c.dac_pins] {
            for pin in [p.sclk, p.cs, p.sdi, p.sdo] {
                store(a, IO_BANK0_BASE + 8 * pin + 4, funcsel);
            }
        }
        for prog in [&self.dac_program, &c.adc_program] {
            for (i, &w) in prog.words.iter().enumerate() {
                store(
                    a,
                    pio + preg::INSTR_MEM0 + 4 * (prog.origin + i as u32),
                    u32::from(w),
                );
            }
        }
        for (sm, prog, div, pins, fjoin_tx) in [
            (0, &c.adc_program, self.adc_div, c.adc_pins, false),
            (1, &self.dac_program, self.dac_div, c.dac_pins, true),
        ] {
            let r = |off: u32| pio + off + preg::SM_STRIDE * sm;
            store(a, r(preg::SM0_CLKDIV), div << 16);
            store(
                a,
                r(preg::SM0_EXECCTRL),
                prog.top() << 12 | prog.origin << 7,
            );
            // Both shifts left (MSB first), no autopush or autopull; the DAC's TX FIFO
            // joined to 8 entries.
            store(a, r(preg::SM0_SHIFTCTRL), u32::from(fjoin_tx) << 30);
            // CS high and SCLK low, then both driven; SDI driven (datasheet 3.5.6:
            // pico-sdk's pio_sm_set_pins_with_mask as SET instructions through SMx_INSTR).
            store(a, r(preg::SM0_PINCTRL), 2 << 26 | pins.sclk << 5);
            store(a, r(preg::SM0_INSTR), u32::from(op::SET_PINS | 0b10));
            store(a, r(preg::SM0_INSTR), u32::from(op::SET_PINDIRS | 0b11));
            store(a, r(preg::SM0_PINCTRL), 1 << 26 | pins.sdi << 5);
            store(a, r(preg::SM0_INSTR), u32::from(op::SET_PINS));
            store(a, r(preg::SM0_INSTR), u32::from(op::SET_PINDIRS | 1));
            // Side-set SCLK and CS, OUT and SET to SDI, IN from SDO.
            store(
                a,
                r(preg::SM0_PINCTRL),
                2 << 29
                    | 1 << 26
                    | pins.sclk << 10
                    | 1 << 20
                    | pins.sdi << 5
                    | pins.sdi
                    | pins.sdo << 15,
            );
            // To the program's start, CS kept high by this instruction's side-set.
            store(
                a,
                r(preg::SM0_INSTR),
                u32::from(ins(op::JMP, CS_HIGH, 0)) | prog.origin,
            );
        }
        // The DMA channels: results (RX FIFO 0 → a results buffer), commands (→ TX FIFO 0),
        // DAC frames (→ TX FIFO 1), each chained to itself and paced by its DREQ.
        let base = io_base(core);
        let [res, cmd, dac] = dma_channels(core);
        let dreq = 8 * core as u32;
        let word = dctrl::EN | 2 << dctrl::DATA_SIZE_SHIFT;
        for (ch, ctrl, read, write, count) in [
            (
                res,
                dctrl::INCR_WRITE | (dreq + 4) << dctrl::TREQ_SEL_SHIFT,
                pio + preg::RXF0,
                base + RESULTS_A,
                c.adc_channels(),
            ),
            (
                cmd,
                dctrl::INCR_READ | dreq << dctrl::TREQ_SEL_SHIFT,
                base + COMMANDS,
                pio + preg::TXF0,
                c.adc_channels(),
            ),
            (
                dac,
                // High priority: the first frame waits for nothing but the other core's
                // DAC channel on the DMA's read port ([`DMA_SHARED_WAIT`]).
                dctrl::HIGH_PRIORITY | dctrl::INCR_READ | (dreq + 1) << dctrl::TREQ_SEL_SHIFT,
                base + DAC_FRAMES,
                pio + preg::TXF0 + 4,
                c.dac_channels,
            ),
        ] {
            let r = |off: u32| DMA_BASE + ch * dreg::CH_STRIDE + off;
            store(
                a,
                r(dreg::AL1_CTRL),
                word | ctrl | ch << dctrl::CHAIN_TO_SHIFT,
            );
            store(a, r(dreg::READ_ADDR), read);
            store(a, r(dreg::WRITE_ADDR), write);
            store(a, r(dreg::TRANS_COUNT), count);
        }
        // Both state machines run (CTRL.SM_ENABLE), waiting for their first words.
        store(a, pio + preg::CTRL, 0b11);
        a.ldr_const(7, base + DAC_FRAMES);
    }

    /// The start handler's part (at the start alarm, `q` cycles before the first tick): the
    /// first ADC burst, into buffer A (which the first handler reads). Needs `r7`; clobbers
    /// r0, r1.
    pub fn start_burst(&self, a: &mut CodeBuffer, core: usize) {
        let (base, res, cmd, _) = trigger_offsets(core);
        a.ldr_const(0, base);
        a.i(asm::mov(1, 7));
        a.i(asm::subs_imm(1, 1, (DAC_FRAMES - RESULTS_A) as u8));
        a.i(asm::str(1, 0, res));
        a.i(asm::adds_imm(1, 1, COMMANDS as u8));
        a.i(asm::str(1, 0, cmd));
    }

    /// The byte offset in a results buffer of core `core`'s *burst mark*, when its keys read
    /// the ADC: the word of its last channel, which the burst's last transfer writes.
    ///
    /// **The burst check** (docs/firmware.md, "Faults": an ADC that stops answering, its
    /// DREQ gone, so that the results channel's burst never finishes): before each burst
    /// starts, the handler writes the mark, `r7` (the core's DAC frames' SRAM address),
    /// into that word of the buffer the burst fills, and the next handler, which reads that
    /// buffer, finds the mark still there exactly when the burst did not finish (the DMA
    /// writes the channels in order, the last one last). No burst writes the mark: a
    /// direct word is `code << shift` (its low `shift` bits 0, below 2^(16 + shift)),
    /// which the mark (`0x2102_f08c` or `0x2103_f08c`: bits 2, 3 and 7 set) never is; a
    /// converter that answers words of its own (not `direct`) would have to answer that
    /// word exactly, in its last channel. The check costs the handler a load, a store, a
    /// compare and an untaken branch (6 cycles, and at most two waits for the DMA at the
    /// bank, inside [`CoreIo::contention`]'s bound, which counts the DMA's accesses) and
    /// reads no DMA register, which the emulator's windows could not run ahead of.
    /// `None` for a core whose keys read no ADC channel.
    pub fn burst_mark(&self, core: usize) -> Option<u16> {
        let n = self.cores.get(core)?.adc_channels();
        (n > 0).then(|| (4 * (n - 1)) as u16)
    }

    /// The handler's first act (module documentation): `r6` = this sample's results (kept
    /// for [`restore_r6`] with `keep_now`), the next ADC burst into the other buffer, the
    /// commands, the last sample's DAC frames; with `mark` (the burst check, which the
    /// image makes with the sensor check) and a [`IoPlan::burst_mark`], r2 = this sample's
    /// mark word, to be compared with `r7`. Needs `r7`; clobbers r0-r2. At the time of writing 20 cycles (with the I/O bank's
    /// accesses through the bus: each may wait for the DMA, [`CoreIo::contention`]).
    pub fn handler_start(&self, a: &mut CodeBuffer, core: usize, keep_now: bool, mark: bool) {
        let (base, res, cmd, dac) = trigger_offsets(core);
        let from_r7 = |off: u32| (off - DAC_FRAMES) as u16;
        a.ldr_const(0, base);
        a.i(asm::ldr(6, 7, from_r7(READ_NEXT)));
        if keep_now {
            // For `restore_r6`.
            a.i(asm::str(6, 7, from_r7(READ_NOW)));
        }
        // The next buffer in the ring: one load, as many cycles as the `MOVS`, `EORS` that
        // flipped between two buffers.
        a.i(asm::ldr(1, 6, RING_NEXT as u16));
        if let Some(last) = self.burst_mark(core).filter(|_| mark) {
            // The burst check ([`IoPlan::burst_mark`]): r2 = this sample's last result, the
            // next buffer's marked before its burst starts.
            a.i(asm::ldr(2, 6, last));
            a.i(asm::str(7, 1, last));
        }
        a.i(asm::str(1, 7, from_r7(READ_NEXT)));
        a.i(asm::str(1, 0, res));
        a.i(asm::mov(1, 7));
        a.i(asm::subs_imm(1, 1, (DAC_FRAMES - COMMANDS) as u8));
        a.i(asm::str(1, 0, cmd));
        a.i(asm::adds_imm(0, 0, dac));
        a.i(asm::str(7, 0, dreg::AL3_READ_ADDR_TRIG as u16));
    }
}

/// `r6` again = this sample's results buffer (after code that borrowed it). Needs `r7`.
pub fn restore_r6(a: &mut CodeBuffer) {
    a.i(asm::ldr(6, 7, (READ_NOW - DAC_FRAMES) as u16));
}

/// `r0` = the sensor word of ADC channel `ch` of this sample's results (`r6`), as `scale`
/// makes it of the code (a core whose ADC does not push the words themselves,
/// [`CoreIo::direct`]). Clobbers r1.
pub fn read_sensor(a: &mut CodeBuffer, ch: u32, scale: &AdcScale) {
    a.i(Instr::MemImm {
        op: MemOp::Ldrh,
        rt: 0,
        rn: 6,
        imm: (4 * ch) as u16,
    });
    if scale.shift > 0 {
        a.i(asm::lsls(0, 0, scale.shift as u8));
    }
    if scale.lo != 0 {
        a.ldr_const(1, scale.lo as u32);
        a.i(asm::adds(0, 0, 1));
    }
}

/// Stores the limiter's code in `r0` into DAC channel `ch`'s word of the core's DAC words
/// (`r7`): one `STRH` under the word's header ([`dac_word`]), as a DAC word without
/// converters is one `STR`.
pub fn write_dac(a: &mut CodeBuffer, ch: u32) {
    a.i(Instr::MemImm {
        op: MemOp::Strh,
        rt: 0,
        rn: 7,
        imm: (4 * ch) as u16,
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_carry_the_codes_and_programs_their_padding() {
        for code in [i16::MIN, -1, 0, 1, 1234, i16::MAX] {
            let w = dac_word(5, code);
            assert_eq!(word_code(w), code);
            let f = dac_frame(5, code);
            assert_eq!(f >> 24, 3);
            assert_eq!(f >> 20 & 0xf, 5);
            assert_eq!((f >> 4 & 0xffff) as u16, (code as u16).wrapping_add(0x8000));
            assert_eq!(f & 0xfff0_0000, w & 0xfff0_0000, "the header as stored");
        }
        assert_eq!(adc_command(5) >> 16, 0xd400);
        // The pads: a pull with its delay, nops beyond 8 cycles.
        let p = adc_program(0, 4, None).unwrap();
        assert_eq!(p.words.len(), 8);
        assert_eq!(p.words[0], 0x80a0 | 0b10 << 11 | 3 << 8);
        assert_eq!(p.frame_pio_cycles, 133);
        let p = adc_program(20, 4, Some(15)).unwrap();
        assert_eq!(p.words.len(), 10);
        assert_eq!(p.words[8], 0x4060 | 15, "in null, 15");
        assert_eq!(p.frame_pio_cycles, 4 + 131);
        assert_eq!(adc_program(20, 4, Some(0)).unwrap().words.len(), 9);
        let p = dac_program(0, 11).unwrap();
        assert_eq!(p.words.len(), 14);
        assert_eq!(p.words[1], 0xa042 | 0b10 << 11 | 2 << 8);
        assert_eq!(p.words[4], 0x0040 | 3 | 1 << 8, "jmp x--, 3 [1]");
        assert_eq!(
            p.words[7],
            0xa009 | 0b01 << 11 | 1 << 8,
            "mov pins, !x side 1 [1]"
        );
        assert_eq!(p.top(), 13);
        assert!(padding(80).is_err());
    }
}
