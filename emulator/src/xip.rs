//! The execute-in-place (XIP) path to the external QSPI flash: the SSI (a Synopsys
//! DW_apb_ssi, RP2040 datasheet 4.10) at `tactus_rp2040::ssi::XIP_SSI_BASE` and the flash chip behind it, as
//! far as the boot ROM's flash path and a second-stage boot loader (boot2) use them —
//! functionally, with the serial clock's timing where firmware can see it (the SSI's
//! `SR.BUSY` while a transfer shifts).
//!
//! **Why a model at all.** A board boots from flash through three programs (datasheet 2.8.1):
//! the boot ROM reads the first 256 bytes of flash over plain 03h serial reads into SRAM,
//! checks their CRC-32 (`tactus_rp2040::bootrom::boot2_crc32`) and enters them; that boot2 sets the SSI and the
//! flash chip up for XIP; then the core fetches code and data from the flash window at
//! 0x10000000 through the XIP cache. Whether the third step works depends on what boot2
//! left in the SSI's registers and the chip's state — a boot2 that forgets the chip's QE
//! bit, leaves the SSI in TX-and-RX mode or sends the wrong read command makes the chip
//! answer garbage. So the model keeps the SSI's registers and the chip's status registers
//! and read mode, and [`Xip::xip_read`] decides from them whether an XIP access reads the
//! flash array: when it would not, the emulator refuses the access (a bus fault, and
//! [`Xip::xip_read`] says why), where the chip would hand the core whatever the
//! misconfigured transfer clocked in.
//!
//! **The SSI.** Registers as in datasheet 4.10.13. CTRLR0, CTRLR1, BAUDR and SPI_CTRLR0
//! take writes only while the SSI is disabled (SSIENR = 0), as the DW_apb_ssi databook
//! says; disabling it empties both FIFOs and ends any transfer. Writes to DR0 push frames:
//! * TMOD = TX and RX, standard SPI: each frame (DFS_32 + 1 bits, whole bytes) is shifted
//!   out most significant bit first while the chip's answer is shifted in; the answer
//!   enters the RX FIFO when the frame has shifted. Frames pushed before the previous one
//!   has shifted out keep chip select low: one command. Chip select rises when the TX FIFO
//!   is empty and the last frame has shifted (the end of a command for the chip: a write
//!   enable or status write takes effect then).
//! * TMOD = EEPROM read in quad mode (the "enhanced" SPI of datasheet 4.10.10): the
//!   instruction (when INST_L is not 0) and then the address are pushed; the address starts
//!   the transfer: instruction, address and mode bits, WAIT_CYCLES dummy clocks, NDF + 1
//!   data frames into the RX FIFO.
//!
//! A frame of `n` bits on `w` wires takes `n / w` serial clocks of `SCKDV` system clock
//! cycles each (BAUDR). Other modes (dual SPI, TX-only, RX-only, a standard EEPROM read
//! through DR0, frames that are not whole bytes) are not modelled: such a push is dropped
//! and [`Xip::problem`] says so.
//!
//! **The flash chip** is a 2 MB Winbond W25Q16JV (the Raspberry Pi Pico's; its
//! datasheet, rev. F, gives the commands below): status registers 1 (BUSY, WEL) and 2 (QE:
//! quad enable), the commands 01h (write status 1 and 2), 31h (write status 2), 04h/06h
//! (write disable/enable), 05h/35h/15h (read status 1/2/3), 9Fh (JEDEC ID), 03h (read), 0Bh
//! (fast read), 6Bh (fast read quad output), EBh (fast read quad I/O, with continuous-read
//! mode: mode bits 0b10xx_xxxx after the address make the next command skip its
//! instruction) and FFh (continuous-read mode reset). A status-register write keeps BUSY
//! set for [`STATUS_WRITE_NS`]. The chip powers up as it leaves the factory: QE clear
//! (the W25Q16JV…IQ parts), so boot2 must set it before reading in quad mode; QE is
//! non-volatile and survives [`Xip::power_on`]. Programming and erasing the array are not
//! modelled (the array is what the host writes: a UF2 download or `Board::load_elf`).
//!
//! **Not modelled:** the XIP cache (and its 16 KB of cache-as-SRAM) and the timing of XIP
//! accesses (a flash load or fetch costs what an SRAM one does; the per-sample code runs
//! from SRAM after the image copies itself, so no budget depends on it), the XIP aliases
//! other than 0x10000000, the pad and IO controls of the QSPI pins, the SSI's interrupts and
//! DMA requests, the chip's power-down, erase, program and security commands.

use std::collections::VecDeque;
use tactus_rp2040::bootrom::BOOT2_SIZE;
use tactus_rp2040::flash::SR2_QE as QE;
use tactus_rp2040::ssi::{reg, FIFO_DEPTH};

/// The W25Q16JV's status-register write time tW, typical (datasheet rev. F, 9.6: 10 ms
/// typical, 15 ms maximum), in nanoseconds.
pub const STATUS_WRITE_NS: u64 = 10_000_000;

/// The W25Q16JV behind the SSI (module documentation).
#[derive(Clone, Debug)]
pub struct FlashChip {
    /// Status register 1 without BUSY (bit 1 WEL; bits 7:2 block protection, kept as
    /// written).
    pub sr1: u8,
    /// Status register 2 (bit 1 QE, non-volatile).
    pub sr2: u8,
    /// Status register 3.
    pub sr3: u8,
    /// Continuous-read mode: the next command is an EBh read without its instruction.
    pub continuous: bool,
    /// Cycle until which a status-register write keeps BUSY set.
    busy_until: u64,
    /// Chip select is low (a command is in progress).
    selected: bool,
    /// The first bytes of the command in progress and how many bytes it has had.
    head: [u8; 8],
    count: usize,
}

/// SR1's write-enable latch.
const WEL: u8 = 1 << 1;
/// The W25Q16JV's JEDEC ID: manufacturer (Winbond), memory type, capacity (2^21 bytes).
const JEDEC_ID: [u8; 3] = [0xef, 0x40, 0x15];

impl Default for FlashChip {
    /// A chip as it leaves the factory: every status bit clear (QE too), not in
    /// continuous-read mode.
    fn default() -> Self {
        FlashChip {
            sr1: 0,
            sr2: 0,
            sr3: 0,
            continuous: false,
            busy_until: 0,
            selected: false,
            head: [0; 8],
            count: 0,
        }
    }
}

impl FlashChip {
    /// Whether a status-register write is in progress at cycle `now`.
    pub fn busy(&self, now: u64) -> bool {
        now < self.busy_until
    }

    /// Chip select falls: a command starts.
    fn select(&mut self) {
        self.selected = true;
        self.count = 0;
    }

    /// One byte of a standard-SPI command in: the byte shifted out at the same time.
    fn exchange(&mut self, mosi: u8, array: &[u8], now: u64) -> u8 {
        let i = self.count;
        if let Some(h) = self.head.get_mut(i) {
            *h = mosi;
        }
        self.count = i.saturating_add(1);
        if i == 0 {
            return 0xff; // the instruction shifts in; the output is not driven
        }
        let cmd = self.head[0];
        let status = matches!(cmd, 0x05 | 0x35 | 0x15);
        if self.continuous || (self.busy(now) && !status) {
            // In continuous-read mode the chip takes these bits as an address on four
            // wires; while busy it ignores everything but the status reads.
            return 0xff;
        }
        let read_at = |skip: usize| -> u8 {
            if i < skip || array.is_empty() {
                return 0xff;
            }
            let addr = u32::from_be_bytes([0, self.head[1], self.head[2], self.head[3]]) as usize;
            array[(addr + (i - skip)) % array.len()]
        };
        match cmd {
            0x05 => self.sr1 | self.busy(now) as u8,
            0x35 => self.sr2,
            0x15 => self.sr3,
            0x9f => JEDEC_ID.get(i - 1).copied().unwrap_or(0xff),
            0x03 => read_at(4),
            0x0b => read_at(5),
            _ => 0xff,
        }
    }

    /// Chip select rises at cycle `at`: the command ends, and a write enable, disable or
    /// status write takes effect.
    fn deselect(&mut self, at: u64, cycles_per_ns: impl Fn(u64) -> u64) {
        if !self.selected {
            return;
        }
        self.selected = false;
        if self.count == 0 || self.busy(at) {
            return;
        }
        if self.continuous {
            // FFh (continuous-read mode reset): eight clocks of ones ends the mode.
            if self.head[0] == 0xff {
                self.continuous = false;
            }
            return;
        }
        let (cmd, n) = (self.head[0], self.count);
        match cmd {
            0x06 if n == 1 => self.sr1 |= WEL,
            0x04 if n == 1 => self.sr1 &= !WEL,
            0x01 if self.sr1 & WEL != 0 && (2..=3).contains(&n) => {
                self.sr1 = self.head[1] & 0xfc;
                if n == 3 {
                    self.sr2 = self.head[2];
                }
                self.busy_until = at + cycles_per_ns(STATUS_WRITE_NS);
            }
            0x31 if self.sr1 & WEL != 0 && n == 2 => {
                self.sr2 = self.head[1];
                self.sr1 &= !WEL;
                self.busy_until = at + cycles_per_ns(STATUS_WRITE_NS);
            }
            _ => {}
        }
    }
}

/// One frame in flight or received: the cycle it completes and its word.
#[derive(Clone, Copy, Debug)]
struct Frame {
    /// Cycle its first bit shifts (it has left the TX FIFO then).
    start: u64,
    /// Cycle its last bit has shifted.
    done: u64,
    word: u32,
}

/// How an XIP access reads the flash: the command the SSI sends per access.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum XipRead {
    /// 03h, one wire, no dummy clocks.
    Read,
    /// 0Bh, one wire, eight dummy clocks.
    FastRead,
    /// 6Bh: instruction and address on one wire, data on four.
    QuadOutput,
    /// EBh: instruction on one wire, address, mode bits and data on four.
    QuadIo,
    /// EBh in continuous-read mode: address and mode bits on four wires, no instruction.
    QuadContinuous,
}

/// The SSI and the flash chip (module documentation).
#[derive(Clone, Debug)]
pub struct Xip {
    ctrlr0: u32,
    ctrlr1: u32,
    ssienr: u32,
    ser: u32,
    baudr: u32,
    rx_sample_dly: u32,
    spi_ctrlr0: u32,
    txd_drive_edge: u32,
    /// Frames pushed and not yet received, in order (TX side: `start` > now is in the TX
    /// FIFO).
    tx: VecDeque<Frame>,
    /// Frames received, in order (visible once `done` ≤ now).
    rx: VecDeque<Frame>,
    /// The instruction pushed for an enhanced EEPROM read, waiting for its address.
    instruction: Option<u32>,
    /// Cycle the last transfer's last bit shifts.
    busy_until: u64,
    /// System clock, Hz (the emulated clock: the serial clock is this / SCKDV).
    clock_hz: u64,
    /// The flash chip.
    pub chip: FlashChip,
    /// The last push the model does not cover (module documentation), for error messages.
    pub problem: Option<String>,
}

impl Xip {
    /// Applies `f` to every cycle the SSI and the flash chip hold (frames in flight or
    /// received, the chip's BUSY end): `Board::skip_periods` moves them with the clock.
    pub(crate) fn move_time(&mut self, f: &mut dyn FnMut(u64) -> u64) {
        self.busy_until = f(self.busy_until);
        self.chip.busy_until = f(self.chip.busy_until);
        for fr in self.tx.iter_mut().chain(self.rx.iter_mut()) {
            fr.start = f(fr.start);
            fr.done = f(fr.done);
        }
    }

    /// The SSI at reset (every register at its reset value, SPI_CTRLR0.XIP_CMD 03h) with a
    /// factory-fresh chip, clocked at `clock_hz`.
    pub fn new(clock_hz: u64) -> Self {
        Xip {
            ctrlr0: 0,
            ctrlr1: 0,
            ssienr: 0,
            ser: 0,
            baudr: 0,
            rx_sample_dly: 0,
            spi_ctrlr0: 0x0300_0000,
            txd_drive_edge: 0,
            tx: VecDeque::new(),
            rx: VecDeque::new(),
            instruction: None,
            busy_until: 0,
            clock_hz: clock_hz.max(1),
            chip: FlashChip::default(),
            problem: None,
        }
    }

    /// The SSI configured for plain 03h XIP reads, as pico-sdk's `boot2_generic_03h`
    /// leaves it: what a board that was not booted through the boot ROM (an image loaded
    /// by a debugger) finds, so that its flash reads.
    pub fn configured_03h(clock_hz: u64) -> Self {
        let mut x = Xip::new(clock_hz);
        x.ctrlr0 = 31 << 16 | reg::TMOD_EEPROM_READ << 8;
        x.spi_ctrlr0 = 0x03 << 24 | 2 << 8 | 6 << 2 | reg::TT_1C1A;
        x.baudr = 4;
        x.ser = 1;
        x.ssienr = 1;
        x
    }

    /// Power-on: the SSI back to its reset state and the chip out of any command or
    /// continuous-read mode (its non-volatile status bits, QE among them, stay).
    pub fn power_on(&mut self) {
        let chip = FlashChip {
            sr1: self.chip.sr1 & !WEL,
            sr2: self.chip.sr2,
            sr3: self.chip.sr3,
            ..FlashChip::default()
        };
        *self = Xip {
            chip,
            ..Xip::new(self.clock_hz)
        };
    }

    /// What the boot ROM's flash path does before it reads boot2 (pico-bootrom
    /// `bootrom/program_flash_generic.c`: `flash_exit_xip` takes the chip out of
    /// continuous-read mode, `flash_init_spi` sets standard SPI, 8-bit frames, TX and RX,
    /// SCKDV 6, the flash selected) and after (`flash_read_data`: 03h reads). Returns the
    /// first [`BOOT2_SIZE`] bytes of `array` as those reads return them.
    pub fn boot_rom_read_boot2(&mut self, array: &[u8]) -> [u8; BOOT2_SIZE] {
        self.chip.continuous = false;
        self.ssienr = 0;
        self.tx.clear();
        self.rx.clear();
        self.baudr = 6;
        self.ctrlr0 = 7 << 16 | reg::FRF_STD << 21 | reg::TMOD_TX_AND_RX << 8;
        self.ser = 1;
        self.ssienr = 1;
        let mut out = [0xff; BOOT2_SIZE];
        for (i, b) in out.iter_mut().enumerate() {
            if let Some(&v) = array.get(i) {
                *b = v;
            }
        }
        out
    }

    fn enabled(&self) -> bool {
        self.ssienr & 1 != 0
    }

    /// System clock cycles per serial clock: SCKDV with bit 0 ignored (datasheet 4.10.13:
    /// even values only), 0 when the serial clock is off.
    fn sckdv(&self) -> u64 {
        (self.baudr & 0xfffe) as u64
    }

    fn cycles_of_ns(clock_hz: u64) -> impl Fn(u64) -> u64 {
        move |ns| (ns as u128 * clock_hz as u128).div_ceil(1_000_000_000) as u64
    }

    /// Chip select rises once everything pushed has shifted (module documentation).
    fn settle(&mut self, now: u64) {
        if self.chip.selected && now >= self.busy_until && self.tx_level(now) == 0 {
            let c = Xip::cycles_of_ns(self.clock_hz);
            self.chip.deselect(self.busy_until, c);
        }
        while self.tx.front().is_some_and(|f| f.done <= now) {
            if let Some(f) = self.tx.pop_front() {
                self.rx.push_back(f);
            }
        }
        while self.rx.len() > FIFO_DEPTH {
            self.rx.pop_front(); // overflow: the oldest frame is lost
        }
    }

    fn tx_level(&self, now: u64) -> usize {
        self.tx.iter().filter(|f| f.start > now).count()
    }

    fn rx_level(&self, now: u64) -> usize {
        self.rx.iter().filter(|f| f.done <= now).count()
    }

    /// Reads register `off` at cycle `now`; `None` for an offset with no register.
    pub fn read(&mut self, now: u64, off: u32) -> Option<u32> {
        self.settle(now);
        Some(match off {
            reg::CTRLR0 => self.ctrlr0,
            reg::CTRLR1 => self.ctrlr1,
            reg::SSIENR => self.ssienr,
            reg::SER => self.ser,
            reg::BAUDR => self.baudr,
            reg::TXFLR => self.tx_level(now) as u32,
            reg::RXFLR => self.rx_level(now) as u32,
            reg::SR => {
                let (txl, rxl) = (self.tx_level(now), self.rx_level(now));
                let mut sr = 0;
                if now < self.busy_until {
                    sr |= reg::SR_BUSY;
                }
                if txl < FIFO_DEPTH {
                    sr |= reg::SR_TFNF;
                }
                if txl == 0 {
                    sr |= reg::SR_TFE;
                }
                if rxl > 0 {
                    sr |= reg::SR_RFNE;
                }
                if rxl >= FIFO_DEPTH {
                    sr |= reg::SR_RFF;
                }
                sr
            }
            reg::DR0 => {
                if self.rx.front().is_some_and(|f| f.done <= now) {
                    self.rx.pop_front().map_or(0, |f| f.word)
                } else {
                    0 // underflow
                }
            }
            reg::IDR => 0x5153_5049,
            reg::SSI_VERSION_ID => 0x3430_312a,
            reg::RX_SAMPLE_DLY => self.rx_sample_dly,
            reg::SPI_CTRLR0 => self.spi_ctrlr0,
            reg::TXD_DRIVE_EDGE => self.txd_drive_edge,
            // MWCR, the FIFO thresholds, interrupt and DMA registers: not modelled, 0.
            0x0c | 0x18 | 0x1c | 0x2c..=0x54 => 0,
            _ => return None,
        })
    }

    /// Writes register `off` at cycle `now` with the flash `array` behind; false for an
    /// offset with no register.
    pub fn write(&mut self, now: u64, off: u32, value: u32, array: &[u8]) -> bool {
        self.settle(now);
        let configurable = !self.enabled();
        match off {
            reg::CTRLR0 if configurable => self.ctrlr0 = value,
            reg::CTRLR1 if configurable => self.ctrlr1 = value & 0xffff,
            reg::BAUDR if configurable => self.baudr = value & 0xffff,
            reg::SPI_CTRLR0 if configurable => self.spi_ctrlr0 = value,
            reg::CTRLR0 | reg::CTRLR1 | reg::BAUDR | reg::SPI_CTRLR0 => {} // ignored while enabled
            reg::SSIENR => {
                if value & 1 == 0 && self.enabled() {
                    // Disabling halts any transfer and empties both FIFOs.
                    let c = Xip::cycles_of_ns(self.clock_hz);
                    self.chip.deselect(now.min(self.busy_until), c);
                    self.tx.clear();
                    self.rx.clear();
                    self.instruction = None;
                    self.busy_until = self.busy_until.min(now);
                }
                self.ssienr = value & 1;
            }
            reg::SER => self.ser = value & 1,
            reg::RX_SAMPLE_DLY => self.rx_sample_dly = value & 0xff,
            reg::TXD_DRIVE_EDGE => self.txd_drive_edge = value & 0xff,
            reg::DR0 => {
                if self.enabled() {
                    self.push(now, value, array);
                }
            }
            0x0c | 0x18 | 0x1c | 0x2c | 0x4c..=0x54 => {}
            _ => return false,
        }
        true
    }

    fn note(&mut self, what: String) {
        self.problem = Some(what);
    }

    /// A frame written to DR0 (module documentation).
    fn push(&mut self, now: u64, word: u32, array: &[u8]) {
        let sckdv = self.sckdv();
        let (tmod, frf) = ((self.ctrlr0 >> 8) & 3, (self.ctrlr0 >> 21) & 3);
        let bits = ((self.ctrlr0 >> 16) & 31) + 1;
        if sckdv == 0 || self.ser & 1 == 0 {
            self.note(
                "a frame pushed with the serial clock off (BAUDR) or no slave selected (SER)"
                    .into(),
            );
            return;
        }
        if self.tx.len() >= 2 * FIFO_DEPTH {
            self.note("the TX FIFO overflowed".into());
            return;
        }
        match (tmod, frf) {
            (reg::TMOD_TX_AND_RX, reg::FRF_STD) if bits.is_multiple_of(8) => {
                if !self.chip.selected {
                    self.chip.select();
                }
                let start = now.max(self.busy_until);
                let mut answer = 0u32;
                for k in (0..bits / 8).rev() {
                    let out = self.chip.exchange((word >> (8 * k)) as u8, array, start);
                    answer = answer << 8 | out as u32;
                }
                let done = start + bits as u64 * sckdv;
                self.tx.push_back(Frame {
                    start,
                    done,
                    word: answer,
                });
                self.busy_until = done;
            }
            (reg::TMOD_EEPROM_READ, reg::FRF_QUAD) => self.push_quad_read(now, word, array),
            _ => self.note(format!(
                "a DR0 push with TMOD {tmod}, SPI_FRF {frf} and {bits}-bit frames: the model \
                 covers TX-and-RX standard SPI in whole bytes and quad EEPROM reads"
            )),
        }
    }

    /// An enhanced-SPI EEPROM read through DR0 (module documentation).
    fn push_quad_read(&mut self, now: u64, word: u32, array: &[u8]) {
        let s = self.spi_ctrlr0;
        let inst_bits = [0u64, 4, 8, 16][((s >> 8) & 3) as usize];
        if inst_bits != 0 && self.instruction.is_none() {
            self.instruction = Some(word);
            return;
        }
        let instruction = self.instruction.take();
        let addr_bits = 4 * ((s >> 2) & 15) as u64;
        let wait = ((s >> 11) & 31) as u64;
        let tt = s & 3;
        let frames = (self.ctrlr1 & 0xffff) as u64 + 1;
        let bits = ((self.ctrlr0 >> 16) & 31) as u64 + 1;
        // The chip sees a new command: this transfer is its own chip-select period.
        self.settle(now.max(self.busy_until));
        let start = now.max(self.busy_until);
        let inst_clocks = if tt == reg::TT_2C2A {
            inst_bits / 4
        } else {
            inst_bits
        };
        let clocks = inst_clocks + addr_bits / 4 + wait + frames * bits / 4;
        let done = start + clocks * self.sckdv();
        let data = self.quad_command(instruction, word, addr_bits, wait, tt);
        self.chip.select();
        self.chip.head[0] = 0xeb;
        self.chip.count = 1;
        let mut addr = match data {
            Ok(a) => Some(a),
            Err(why) => {
                self.note(why);
                None
            }
        };
        // Frames beyond the RX FIFO's depth overflow it (lost, as on the chip).
        for k in 0..frames.min(FIFO_DEPTH as u64) {
            let w = match (addr.as_mut(), array.is_empty()) {
                (Some(a), false) => {
                    let mut v = 0u32;
                    for _ in 0..bits.div_ceil(8) {
                        v = v << 8 | array[*a % array.len()] as u32;
                        *a += 1;
                    }
                    // The first byte shifted in is the frame's most significant.
                    v
                }
                _ => u32::MAX,
            };
            self.tx.push_back(Frame {
                start: if k == 0 { start } else { done },
                done,
                word: w,
            });
        }
        self.busy_until = done;
    }

    /// What a quad read with `instruction`, the address frame `frame` of `addr_bits` bits
    /// and `wait` dummy clocks does to the chip: `Ok(byte address)` when it reads the array
    /// (and the chip's continuous-read mode follows the mode bits), else why not.
    fn quad_command(
        &mut self,
        instruction: Option<u32>,
        frame: u32,
        addr_bits: u64,
        wait: u64,
        tt: u32,
    ) -> Result<usize, String> {
        if self.chip.sr2 & QE == 0 {
            return Err(
                "a quad read with the flash's QE bit clear (IO2 and IO3 are WP# and HOLD#)".into(),
            );
        }
        match (instruction, self.chip.continuous) {
            (Some(_), true) => {
                return Err("an instruction sent while the flash is in continuous-read mode (it takes it as address bits)".into())
            }
            (None, false) => {
                return Err("no instruction sent, but the flash is not in continuous-read mode".into())
            }
            (Some(i), false) if i & 0xff != 0xeb || tt != reg::TT_1C2A => {
                return Err(format!(
                    "quad EEPROM read with instruction {:#04x} and TRANS_TYPE {tt}: the model covers EBh with the address on four wires",
                    i & 0xff
                ))
            }
            _ => {}
        }
        if addr_bits != 32 || wait != 4 {
            return Err(format!(
                "an EBh read with {addr_bits} address and mode bits and {wait} dummy clocks: the W25Q16JV takes 24 + 8 and 4"
            ));
        }
        self.chip.continuous = frame & 0x30 == 0x20;
        Ok((frame >> 8) as usize)
    }

    /// How an XIP access reads the flash with the SSI and chip as they are, or why it would
    /// not read the array (module documentation). `clk_sys_hz` is the programmed system
    /// clock when known (the flash's serial clock limit is then checked: 50 MHz for 03h,
    /// 133 MHz otherwise, W25Q16JV datasheet 9.6).
    pub fn xip_read(&self, clk_sys_hz: Option<u64>) -> Result<XipRead, String> {
        if !self.enabled() {
            return Err("the SSI is disabled (SSIENR = 0)".into());
        }
        if self.ser & 1 == 0 {
            return Err("the SSI selects no flash (SER = 0)".into());
        }
        let (tmod, frf, dfs) = (
            (self.ctrlr0 >> 8) & 3,
            (self.ctrlr0 >> 21) & 3,
            (self.ctrlr0 >> 16) & 31,
        );
        if tmod != reg::TMOD_EEPROM_READ {
            return Err(format!(
                "CTRLR0.TMOD is {tmod}: XIP needs EEPROM read (3), which sends the read command"
            ));
        }
        if dfs != 31 {
            return Err(format!(
                "CTRLR0.DFS_32 is {dfs}: XIP reads 32-bit frames (31)"
            ));
        }
        let sckdv = self.sckdv();
        if sckdv == 0 {
            return Err("BAUDR is 0: the serial clock is off".into());
        }
        let s = self.spi_ctrlr0;
        let (tt, addr_l, inst_l, wait, cmd) =
            (s & 3, (s >> 2) & 15, (s >> 8) & 3, (s >> 11) & 31, s >> 24);
        let mode = match frf {
            reg::FRF_STD => {
                if self.chip.continuous {
                    return Err("the flash is in continuous-read mode but the SSI sends a single-wire command".into());
                }
                match (tt, inst_l, addr_l, cmd, wait) {
                    (reg::TT_1C1A, 2, 6, 0x03, 0) => XipRead::Read,
                    (reg::TT_1C1A, 2, 6, 0x0b, 8) => XipRead::FastRead,
                    _ => {
                        return Err(format!(
                            "single-wire XIP with command {cmd:#04x}, TRANS_TYPE {tt}, INST_L {inst_l}, \
                             ADDR_L {addr_l} and {wait} dummy clocks: the flash answers 03h (8-bit \
                             instruction, 24-bit address, no dummy clocks) or 0Bh (8 dummy clocks)"
                        ))
                    }
                }
            }
            reg::FRF_QUAD => {
                if self.chip.sr2 & QE == 0 {
                    return Err(
                        "quad XIP with the flash's QE bit clear: IO2 and IO3 are WP# and HOLD#"
                            .into(),
                    );
                }
                match (tt, inst_l, addr_l, wait) {
                    (reg::TT_2C2A, 0, 8, 4) if self.chip.continuous && cmd & 0x30 == 0x20 => {
                        XipRead::QuadContinuous
                    }
                    (reg::TT_2C2A, 0, 8, 4) if self.chip.continuous => {
                        return Err(format!(
                            "continuous quad XIP with mode bits {cmd:#04x}: they end continuous-read \
                             mode after the first read (0b10xx_xxxx keeps it)"
                        ))
                    }
                    (_, 0, _, _) if !self.chip.continuous => {
                        return Err("quad XIP without an instruction, but the flash is not in continuous-read \
                                    mode (an EBh read with mode bits 0xa0 enters it)"
                            .into())
                    }
                    _ if self.chip.continuous => {
                        return Err("the flash is in continuous-read mode but the SSI sends an instruction".into())
                    }
                    (reg::TT_1C2A, 2, 8, 4) if cmd == 0xeb => XipRead::QuadIo,
                    (reg::TT_1C1A, 2, 6, 8) if cmd == 0x6b => XipRead::QuadOutput,
                    _ => {
                        return Err(format!(
                            "quad XIP with command {cmd:#04x}, TRANS_TYPE {tt}, INST_L {inst_l}, ADDR_L \
                             {addr_l} and {wait} dummy clocks: the model covers EBh (24-bit address and \
                             8 mode bits on four wires, 4 dummy clocks) with or without continuous-read \
                             mode, and 6Bh"
                        ))
                    }
                }
            }
            _ => {
                return Err(format!(
                    "CTRLR0.SPI_FRF is {frf}: dual-SPI XIP is not modelled"
                ))
            }
        };
        if let Some(clk) = clk_sys_hz {
            let sck = clk / sckdv;
            let max = if mode == XipRead::Read {
                50_000_000
            } else {
                133_000_000
            };
            if sck > max {
                return Err(format!(
                    "the flash's serial clock would be {:.1} MHz (clk_sys {:.1} MHz / SCKDV {sckdv}), \
                     above the W25Q16JV's {} MHz for this read",
                    sck as f64 / 1e6,
                    clk as f64 / 1e6,
                    max / 1_000_000
                ));
            }
        }
        Ok(mode)
    }
}
