//! What the host does to the machine without cycles: power it on from flash as the boot
//! ROM does, start a core, and read and write memory (ROM, flash, SRAM) as a loader, a
//! harness or a debugger would, costing the cores nothing.

use super::*;
use crate::elf::ElfError;
use std::fmt;
use tactus_rp2040::memory::SRAM_END;

/// A host-side error.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EmuError {
    /// The ELF file could not be loaded.
    Elf(ElfError),
    /// A host access to an address outside ROM, flash and SRAM.
    Unmapped(u32),
    /// No symbol of that name.
    NoSymbol(String),
    /// The boot ROM's check of boot2 failed (`tactus_rp2040::bootrom::check_boot2`).
    Boot2Checksum {
        /// CRC-32 of the first 252 bytes of flash.
        computed: u32,
        /// The word stored after them.
        stored: u32,
    },
}

impl fmt::Display for EmuError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EmuError::Elf(e) => e.fmt(f),
            EmuError::Unmapped(a) => write!(f, "no memory at {a:#010x}"),
            EmuError::NoSymbol(s) => write!(f, "no symbol named `{s}`"),
            EmuError::Boot2Checksum { computed, stored } => write!(
                f,
                "the boot ROM rejects boot2 (the first 256 bytes of flash): their CRC-32 is \
                 {computed:#010x} but the last word says {stored:#010x}; on the chip the ROM \
                 retries 128 times and then starts USB boot (BOOTSEL mode) instead of the image"
            ),
        }
    }
}

impl std::error::Error for EmuError {}

impl From<ElfError> for EmuError {
    fn from(e: ElfError) -> Self {
        EmuError::Elf(e)
    }
}

impl Machine {
    /// Powers the board on from flash, as the boot ROM's flash path does on core 0
    /// (pico-bootrom `bootrom/bootrom_main.c`, `_flash_boot`): the SSI set to plain serial
    /// reads, the flash chip out of continuous-read mode, its first 256 bytes read into the
    /// top of SRAM5 ([`tactus_rp2040::bootrom::BOOT2_LOAD`]) and checked against their CRC-32
    /// ([`tactus_rp2040::bootrom::check_boot2`]), and core 0 entered there in Thumb state with LR = 0
    /// ("entered from the boot ROM": boot2 then enters the image through the vector table at
    /// 0x10000100) and SP at the ROM's stack top. Core 1 stays in the boot ROM's launch
    /// protocol. The flash holds what the host wrote (a UF2's blocks, an ELF's segments).
    ///
    /// SRAM powers up holding garbage: the rest of SRAM is filled with a fixed pseudo-random
    /// pattern, so firmware that relies on zeroed SRAM fails here as on the chip. The boot
    /// ROM's own instructions are not run: core 0 enters boot2 at the board's current cycle.
    ///
    /// Errors: [`EmuError::Boot2Checksum`] (the chip's ROM would retry and start USB boot).
    pub fn boot_from_flash(&mut self) -> Result<(), EmuError> {
        self.fill_power_on_pattern();
        self.system.invalidate_code();
        self.flash_boot()
    }

    /// SRAM as it powers up: a fixed pseudo-random pattern ([`Machine::boot_from_flash`]).
    pub(super) fn fill_power_on_pattern(&mut self) {
        let mut x = 0x2545_f491u32;
        for w in self.system.sram.chunks_mut(4) {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            for (b, v) in w.iter_mut().zip(x.to_le_bytes()) {
                *b = v;
            }
        }
    }

    /// The boot ROM's flash path ([`Machine::boot_from_flash`]) on SRAM as it is.
    pub(super) fn flash_boot(&mut self) -> Result<(), EmuError> {
        self.system.xip.power_on();
        let boot2 = self.system.xip.boot_rom_read_boot2(&self.system.flash);
        self.write_bytes(tactus_rp2040::bootrom::BOOT2_LOAD, &boot2)?;
        self.system.refresh_xip();
        if let Err((computed, stored)) = tactus_rp2040::bootrom::check_boot2(&boot2) {
            return Err(EmuError::Boot2Checksum { computed, stored });
        }
        let core = &mut self.cores[0];
        core.reset_to(
            tactus_rp2040::bootrom::BOOT2_LOAD | 1,
            tactus_rp2040::bootrom::BOOT_ROM_STACK_TOP,
        );
        core.r[14] = 0;
        core.nvic.vtor = 0;
        Ok(())
    }

    /// `stop` in words, with what the emulator knows beyond it: why a refused write was
    /// refused, why a bus fault in the flash window found no flash (the XIP path's state,
    /// `crate::xip`), and where the cores were.
    pub fn describe_stop(&self, stop: &StopReason) -> String {
        let pcs = format!(
            "core pcs {:#010x}, {:#010x}",
            self.cores[0].r[15], self.cores[1].r[15]
        );
        match stop {
            StopReason::Refused { core, why } => format!("core {core}: refused: {why} ({pcs})"),
            StopReason::Fault { core, fault } | StopReason::Lockup { core, fault } => {
                let what = if matches!(stop, StopReason::Fault { .. }) {
                    "HardFault"
                } else {
                    "locked up"
                };
                let mut s = format!("core {core} {what}: {fault}");
                if let crate::core::FaultKind::Bus { addr } = fault.kind {
                    let flash = addr.wrapping_sub(tactus_rp2040::memory::FLASH_BASE)
                        < tactus_rp2040::memory::FLASH_SIZE;
                    if let (true, Some(why)) = (flash, self.system.xip_error()) {
                        s.push_str(&format!(" (the XIP window does not read the flash: {why})"));
                        if let Some(p) = &self.system.xip.problem {
                            s.push_str(&format!(" (the last SSI use not modelled: {p})"));
                        }
                    }
                }
                format!("{s} ({pcs})")
            }
            other => format!("{other:?} ({pcs})"),
        }
    }

    /// Starts core 0 at `entry` (Thumb bit set) with SP at the top of SRAM and VTOR 0 (the
    /// boot ROM's table), as the boot ROM enters a RAM image after a UF2 download: it
    /// reboots through the watchdog with `entry` = the lowest address the UF2 wrote and
    /// SP = 0x20042000 (pico-bootrom `bootrom/virtual_disk.c`,
    /// `safe_reboot(lowest_addr, SRAM_END, …)`; `bootrom/bootrom_rt0.S`, `check_wdog`).
    /// Core 1 stays in the boot ROM's launch protocol.
    pub fn enter_ram_image(&mut self, entry: u32) {
        self.cores[0].reset_to(entry, SRAM_END);
        self.cores[0].nvic.vtor = 0;
    }

    /// Starts `core` from the vector table at `vtor` (SP = word 0, PC = word 1), as the boot
    /// ROM does; the core stops taking part in the launch protocol.
    pub fn boot_from_vectors(&mut self, core: usize, vtor: u32) -> Result<(), EmuError> {
        let sp = self.read_u32(vtor)?;
        let pc = self.read_u32(vtor.wrapping_add(4))?;
        self.start_core(core, pc, sp, vtor);
        Ok(())
    }

    /// Starts `core` at `pc` with stack pointer `sp` and VTOR `vtor`, at the current cycle,
    /// as a debugger would. Core 1 taken from the boot ROM's wait loop this way is started
    /// as if it had never entered it: what the ROM sent core 0 (its handshake 0) is
    /// withdrawn from core 0's RX FIFO. (A launch over the FIFOs keeps the echoes.)
    pub fn start_core(&mut self, core: usize, pc: u32, sp: u32, vtor: u32) {
        if core == 1 && self.launch.is_some() {
            while self.system.sio.fifo_status(0) & 1 != 0 {
                self.system.sio.fifo_pop(0);
            }
        }
        self.start_core_at(core, pc, sp, vtor);
    }

    pub(super) fn start_core_at(&mut self, core: usize, pc: u32, sp: u32, vtor: u32) {
        let now = self.cores[1 - core].cycle.max(self.cores[core].cycle);
        let c = &mut self.cores[core];
        c.cycle = now;
        c.reset_to(pc, sp);
        c.nvic.vtor = vtor;
        if core == 1 {
            self.launch = None;
        }
    }

    /// Reads bytes without side effects or cycles (ROM, flash, SRAM only).
    pub fn read_bytes(&mut self, addr: u32, out: &mut [u8]) -> Result<(), EmuError> {
        // Words of one SRAM view (the records and windows a harness reads every sample):
        // no address decode per word.
        if let Some((off, stride)) = u32::try_from(out.len())
            .ok()
            .and_then(|n| crate::bus::sram_word_run(addr, n))
        {
            let sram = &self.system.sram;
            for (i, w) in out.chunks_exact_mut(4).enumerate() {
                let o = off as usize + stride as usize * i;
                w.copy_from_slice(&sram[o..o + 4]);
            }
            return Ok(());
        }
        // Whole aligned words map to four consecutive bytes of one memory (the regions and
        // the SRAM banks' words are aligned): one address decode per word.
        if addr & 3 == 0 && out.len().is_multiple_of(4) {
            for (i, w) in out.chunks_exact_mut(4).enumerate() {
                let a = addr.wrapping_add(4 * i as u32);
                let (mem, off) = self.system.backing(a).ok_or(EmuError::Unmapped(a))?;
                w.copy_from_slice(&mem[off..off + 4]);
            }
            return Ok(());
        }
        for (i, b) in out.iter_mut().enumerate() {
            let a = addr.wrapping_add(i as u32);
            let (mem, off) = self.system.backing(a).ok_or(EmuError::Unmapped(a))?;
            *b = mem[off];
        }
        Ok(())
    }

    /// Writes bytes without cycles (ROM, flash, SRAM only), as a loader or DMA would.
    pub fn write_bytes(&mut self, addr: u32, data: &[u8]) -> Result<(), EmuError> {
        self.write_data(addr, data)?;
        self.system.invalidate_code();
        Ok(())
    }

    /// Writes data bytes without cycles and without invalidating decoded code: for buffers
    /// the host refills often (sensor words, arguments). The caller guarantees that no
    /// instruction lives in the range (else the core may run stale code).
    pub fn write_data(&mut self, addr: u32, data: &[u8]) -> Result<(), EmuError> {
        if let Some((off, stride)) = u32::try_from(data.len())
            .ok()
            .and_then(|n| crate::bus::sram_word_run(addr, n))
        {
            let sram = &mut self.system.sram;
            for (i, w) in data.chunks_exact(4).enumerate() {
                let o = off as usize + stride as usize * i;
                sram[o..o + 4].copy_from_slice(w);
            }
            return Ok(());
        }
        // Whole aligned words: one address decode per word, as in `read_bytes`.
        if addr & 3 == 0 && data.len().is_multiple_of(4) {
            for (i, w) in data.chunks_exact(4).enumerate() {
                let a = addr.wrapping_add(4 * i as u32);
                let (mem, off) = self.system.backing(a).ok_or(EmuError::Unmapped(a))?;
                mem[off..off + 4].copy_from_slice(w);
            }
            return Ok(());
        }
        for (i, b) in data.iter().enumerate() {
            let a = addr.wrapping_add(i as u32);
            let (mem, off) = self.system.backing(a).ok_or(EmuError::Unmapped(a))?;
            mem[off] = *b;
        }
        Ok(())
    }

    /// Reads `out.len()` little-endian words from `addr`, `addr + 4`, … (host access, no
    /// cycles): [`Board::read_bytes`] without the byte buffer — a harness reading records
    /// and windows every sample takes the words straight from SRAM when they lie in one
    /// view (striped, SRAM4/5, one bank of the non-striped alias). Errors: as
    /// [`Board::read_bytes`].
    pub fn read_words(&mut self, addr: u32, out: &mut [u32]) -> Result<(), EmuError> {
        let run = u32::try_from(out.len())
            .ok()
            .and_then(|n| n.checked_mul(4))
            .and_then(|len| crate::bus::sram_word_run(addr, len));
        if let Some((off, stride)) = run {
            // One bounds check for the run, then a word per `stride` bytes.
            let (off, stride) = (off as usize, stride as usize);
            let end = off + stride * out.len().saturating_sub(1) + 4;
            if let Some(region) = self.system.sram.get(off..end) {
                for (w, c) in out.iter_mut().zip(region.chunks(stride)) {
                    *w = u32::from_le_bytes([c[0], c[1], c[2], c[3]]);
                }
                return Ok(());
            }
        }
        for (i, w) in out.iter_mut().enumerate() {
            *w = self.read_u32(addr.wrapping_add(4 * i as u32))?;
        }
        Ok(())
    }

    /// Writes `words` little-endian at `addr`, `addr + 4`, … without cycles and, like
    /// [`Board::write_data`], without invalidating decoded code (for the sensor words a
    /// harness refills every sample; no instruction may live there). Errors: as
    /// [`Board::write_data`].
    pub fn write_words(&mut self, addr: u32, words: &[u32]) -> Result<(), EmuError> {
        let run = u32::try_from(words.len())
            .ok()
            .and_then(|n| n.checked_mul(4))
            .and_then(|len| crate::bus::sram_word_run(addr, len));
        if let Some((off, stride)) = run {
            let sram = &mut self.system.sram;
            for (i, w) in words.iter().enumerate() {
                let o = off as usize + stride as usize * i;
                sram[o..o + 4].copy_from_slice(&w.to_le_bytes());
            }
            return Ok(());
        }
        for (i, w) in words.iter().enumerate() {
            self.write_data(addr.wrapping_add(4 * i as u32), &w.to_le_bytes())?;
        }
        Ok(())
    }

    /// Reads a little-endian word (host access).
    pub fn read_u32(&mut self, addr: u32) -> Result<u32, EmuError> {
        let mut b = [0; 4];
        self.read_bytes(addr, &mut b)?;
        Ok(u32::from_le_bytes(b))
    }

    /// Writes a little-endian word (host access).
    pub fn write_u32(&mut self, addr: u32, value: u32) -> Result<(), EmuError> {
        self.write_bytes(addr, &value.to_le_bytes())
    }
}
