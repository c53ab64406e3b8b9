//! The image in flash, as pico-sdk's `copy_to_ram` binaries are: it boots from flash and
//! runs from SRAM.
//!
//! **Layout** (from [`FLASH_BASE`]):
//! * 0x000: boot2 ([`super::boot2`]), 256 bytes with the boot ROM's CRC;
//! * 0x100 ([`FLASH_VECTORS`], where boot2 vectors into the image): a vector table of four
//!   words — the stack pointer (the top of SRAM), the flash reset handler, and NMI and
//!   HardFault, both a branch to themselves —, the flash reset handler and its literals;
//! * the copy table: per piece of the SRAM image three words, its bytes' flash address,
//!   its SRAM address and the SRAM address after it;
//! * the pieces' bytes, each from a word boundary: every segment of the
//!   [`FirmwareImage`] (the entry stub, per core its code and its data) as
//!   [`FirmwareImage::segments`] gives it, so the SRAM image is the RAM image's, byte for
//!   byte, at the same addresses.
//!
//! **The flash reset handler** copies each piece word by word (`LDM`/`STM`, so a piece's
//! last word is filled up to 4 bytes with zeros: [`FirmwareImage::flash_image`] checks that
//! no other piece needs those bytes) and then jumps to the RAM image's entry stub at its
//! flash entry ([`super::boot::ENTRY_FROM_FLASH`], 0x20000004), which marks the boot as
//! one from flash ([`super::boot::BOOT_SOURCE`]: a watchdog reset then boots from flash
//! again, not through the RAM image's re-entry, `super::reboot`) and enters core 0's reset
//! handler as after a RAM UF2 (`super::boot`): from there on, the same code at the same
//! addresses as the RAM image,
//! so the sample interrupt's WCET, cycles and outputs are the RAM image's. Only core 0 runs
//! it; core 1 waits in the boot ROM until core 0's reset handler launches it.
//!
//! Nothing the image needs is left in flash once it is copied: after the clock set-up
//! the firmware never reads the flash again, so the XIP path's timing (untimed in the
//! emulator, `tactus_emulator::xip`) affects how long the board takes to boot, never a
//! sample.

use super::boot::{copy_pieces, ENTRY_FROM_FLASH};
use super::boot2::{self, FLASH_VECTORS};
use super::{FirmwareImage, ImageError};
use tactus_compiler::thumb::buffer::{CodeBuffer, LongBranch};
use tactus_isa::decode::Instr;
use tactus_rp2040::memory::{sram_location, FLASH_BASE, FLASH_SIZE, SRAM_END};

/// One piece of the SRAM image in flash.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FlashPiece {
    /// Where its bytes are in flash.
    pub flash: u32,
    /// Where the flash reset handler copies them (the segment's address).
    pub ram: u32,
    /// Its bytes (the segment's, unpadded).
    pub len: u32,
}

/// A flash image (module documentation).
#[derive(Clone, Debug)]
pub struct FlashImage {
    /// Its bytes from [`FLASH_BASE`].
    pub bytes: Vec<u8>,
    /// The pieces, in [`FirmwareImage::segments`] order.
    pub pieces: Vec<FlashPiece>,
    /// Bytes of boot2's code (before its zero padding and CRC).
    pub boot2_code: usize,
    /// The flash reset handler (Thumb bit clear).
    pub reset: u32,
    /// Literal data in the flash code after [`FLASH_VECTORS`] (address, length): the
    /// vector table, pools, the copy table.
    pub data: Vec<(u32, u32)>,
    /// Literal data in boot2 (offset, length).
    pub boot2_data: Vec<(usize, usize)>,
    /// Where the copy table starts and ends.
    pub table: (u32, u32),
}

/// Words of the flash vector table.
const FLASH_VECTOR_WORDS: u32 = 4;

impl FirmwareImage {
    /// The image in flash (module documentation).
    ///
    /// Errors: [`ImageError::Assemble`] when boot2 or the flash reset handler does not
    /// assemble, two pieces' word-rounded ranges overlap or the image passes the 2 MB of
    /// flash (an SRAM image cannot).
    pub fn flash_image(&self) -> Result<FlashImage, ImageError> {
        let boot2 = boot2::code()?;
        let boot2_bytes = boot2::bytes()?;
        self.check_word_rounding()?;
        let code_at = FLASH_VECTORS + 4 * FLASH_VECTOR_WORDS;
        // The handler refers to the table by address: assemble it once to size it (its
        // literal values do not change its size), then at the final addresses.
        let handler = |table: u32, end: u32| -> Result<_, ImageError> {
            let mut a = CodeBuffer::new(LongBranch::Refuse);
            let halt = a.label();
            copy_pieces(&mut a, table, end);
            a.ldr_const(0, ENTRY_FROM_FLASH | 1);
            a.i(Instr::Bx { rm: 0 });
            a.bind(halt);
            a.b(halt);
            a.pool();
            Ok((a.finish_code(code_at)?, halt))
        };
        let (sized, _) = handler(0x1000_0000, 0x1000_0004)?;
        let table = (code_at + sized.text.len() as u32).next_multiple_of(4);
        let table_end = table + 12 * self.segments.len() as u32;
        let (code, halt) = handler(table, table_end)?;
        if code.text.len() != sized.text.len() {
            return Err(ImageError::Assemble(
                "the flash reset handler changed size with its table's address".into(),
            ));
        }
        let halt_at = code.labels[halt.index()];
        let mut pieces = Vec::with_capacity(self.segments.len());
        let mut at = table_end;
        for (ram, data) in &self.segments {
            pieces.push(FlashPiece {
                flash: at,
                ram: *ram,
                len: data.len() as u32,
            });
            at += (data.len() as u32).next_multiple_of(4);
        }
        let total = at - FLASH_BASE;
        if total > FLASH_SIZE {
            return Err(ImageError::Assemble(format!(
                "the flash image takes {total} bytes, more than the {FLASH_SIZE} of flash"
            )));
        }
        let mut bytes = vec![0u8; total as usize];
        let put = |bytes: &mut Vec<u8>, addr: u32, data: &[u8]| {
            let o = (addr - FLASH_BASE) as usize;
            bytes[o..o + data.len()].copy_from_slice(data);
        };
        put(&mut bytes, FLASH_BASE, &boot2_bytes);
        for (i, w) in [SRAM_END, code_at | 1, halt_at | 1, halt_at | 1]
            .into_iter()
            .enumerate()
        {
            put(&mut bytes, FLASH_VECTORS + 4 * i as u32, &w.to_le_bytes());
        }
        put(&mut bytes, code_at, &code.text);
        for (i, p) in pieces.iter().enumerate() {
            let end = p.ram + p.len.next_multiple_of(4);
            for (j, w) in [p.flash, p.ram, end].into_iter().enumerate() {
                put(
                    &mut bytes,
                    table + 12 * i as u32 + 4 * j as u32,
                    &w.to_le_bytes(),
                );
            }
            put(&mut bytes, p.flash, &self.segments[i].1);
        }
        let mut data = vec![(FLASH_VECTORS, 4 * FLASH_VECTOR_WORDS)];
        data.extend(
            code.data
                .iter()
                .map(|&(o, n)| (code_at + o as u32, n as u32)),
        );
        data.push((table, table_end - table));
        Ok(FlashImage {
            bytes,
            pieces,
            boot2_code: boot2.text.len(),
            reset: code_at,
            data,
            boot2_data: boot2.data,
            table: (table, table_end),
        })
    }

    /// The flash reset handler copies whole words: each segment's last word is filled up
    /// with zeros, which must not land on another segment's bytes.
    fn check_word_rounding(&self) -> Result<(), ImageError> {
        let mut bytes: Vec<(usize, usize)> = Vec::new(); // (SRAM offset, segment)
        for (i, (addr, data)) in self.segments.iter().enumerate() {
            if addr % 4 != 0 {
                return Err(ImageError::Assemble(format!(
                    "segment {i} at {addr:#010x} is not word aligned"
                )));
            }
            for k in 0..(data.len() as u32).next_multiple_of(4) {
                let a = addr + k;
                let (off, _) = sram_location(a).ok_or_else(|| {
                    ImageError::Assemble(format!("segment {i}: {a:#010x} is not SRAM"))
                })?;
                bytes.push((off, i));
            }
        }
        bytes.sort_unstable();
        match bytes.windows(2).find(|w| w[0].0 == w[1].0) {
            Some(w) => Err(ImageError::Assemble(format!(
                "segments {} and {} share SRAM byte {:#x} once rounded to words",
                w[0].1, w[1].1, w[0].0
            ))),
            None => Ok(()),
        }
    }
}
