//! UF2 files for the RP2040's USB boot ROM (BOOTSEL drag-and-drop): a flash image
//! ([`rp2040_flash`], what `tactus build` writes) or a RAM-only one ([`rp2040_ram`], for
//! development).
//!
//! **Format** (microsoft/uf2 `README.md`, "File format"): 512-byte blocks, each a 32-byte
//! header — magic `0x0A324655`, magic `0x9E5D5157`, flags, target address, payload size,
//! block number, block count, family ID (with flag `0x00002000`, "familyID present") — then
//! 476 bytes of data and the final magic `0x0AB16F30`, all little endian. The RP2040 boot
//! ROM takes only blocks with the family ID present and equal to [`RP2040_FAMILY_ID`],
//! without the "not main flash" flag, with a 256-byte payload (pico-bootrom
//! `bootrom/virtual_disk.c`, `vd_write_block`), so every block carries 256 bytes.
//!
//! **Flash.** The per-sample code must run from SRAM (a flash fetch through the XIP cache
//! has no bounded latency, and the WCET is priced for zero-wait SRAM), so the flash image
//! holds a second-stage boot loader and copies itself to SRAM before anything else
//! (`super::image::flash_image`). The boot ROM writes flash blocks (256-byte payloads at
//! 256-byte aligned addresses from 0x10000000, erasing each 4 KB sector first) and reboots
//! into the image; it survives a power cycle.
//!
//! **RAM.** A RAM image, like pico-sdk's `no_flash` binaries, is loaded by the boot ROM
//! straight where it runs and started at its lowest address (`super::image::boot`): no
//! flash wear, but it is gone at power-off — the board must be put in BOOTSEL mode and the
//! file copied again after each power-up (or loaded by `picotool load`, or over SWD).
//!
//! **Striped addresses.** The boot ROM accepts RAM blocks only in 0x20000000–0x20042000
//! (`is_address_ram`: the striped SRAM and the scratch banks), not in the non-striped
//! alias at 0x21000000 where the image keeps each core's code and data in its own bank.
//! The RP2040 stripes SRAM0–3 word by word (datasheet 2.6.1: striped word *w* is word
//! *w* / 4 of bank *w* mod 4), so the same physical bytes are written through the striped
//! alias: [`striped_image`] turns the image's segments into one contiguous striped range,
//! with [`tactus_rp2040::memory::sram_location`], the one definition of the
//! mapping.

use tactus_rp2040::memory::{sram_location, FLASH_BASE, SRAM_BASE, SRAM_END};

/// First magic number (`"UF2\n"`).
pub const MAGIC_START0: u32 = 0x0A32_4655;
/// Second magic number.
pub const MAGIC_START1: u32 = 0x9E5D_5157;
/// Final magic number.
pub const MAGIC_END: u32 = 0x0AB1_6F30;
/// Flag: the header's last word is a family ID.
pub const FLAG_FAMILY_ID_PRESENT: u32 = 0x0000_2000;
/// The RP2040's family ID (microsoft/uf2 `utils/uf2families.json`).
pub const RP2040_FAMILY_ID: u32 = 0xe48b_ff56;
/// Payload bytes per block, the only size the RP2040 boot ROM accepts.
pub const PAYLOAD: usize = 256;
/// Block size in bytes.
pub const BLOCK: usize = 512;

/// Why a RAM image cannot be written as a UF2.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Uf2Error {
    /// A segment byte outside SRAM (striped, scratch or the non-striped alias).
    NotRam {
        /// The address.
        addr: u32,
    },
    /// Two segments write the same physical SRAM byte.
    Overlap {
        /// The striped address of the byte.
        addr: u32,
    },
}

impl std::fmt::Display for Uf2Error {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Uf2Error::NotRam { addr } => write!(
                f,
                "{addr:#010x} is not SRAM: a RAM-only UF2 writes only 0x20000000-0x20042000 \
                 (and the non-striped alias through it)"
            ),
            Uf2Error::Overlap { addr } => {
                write!(f, "two segments write SRAM byte {addr:#010x} (striped)")
            }
        }
    }
}

impl std::error::Error for Uf2Error {}

/// The striped SRAM address of the byte at `addr` (striped, scratch or non-striped alias).
pub fn striped_address(addr: u32) -> Option<u32> {
    sram_location(addr).map(|(off, _)| SRAM_BASE + off as u32)
}

/// The segments `(address, bytes)` as one contiguous range of striped SRAM: (its start,
/// its bytes), from the lowest byte written to the highest, rounded out to whole
/// [`PAYLOAD`]s (bytes no segment writes are 0).
///
/// Errors: [`Uf2Error::NotRam`], [`Uf2Error::Overlap`].
pub fn striped_image(segments: &[(u32, Vec<u8>)]) -> Result<(u32, Vec<u8>), Uf2Error> {
    let mut bytes: Vec<(u32, u8)> = Vec::new();
    for (base, data) in segments {
        for (i, &b) in data.iter().enumerate() {
            let addr = base.wrapping_add(i as u32);
            let s = striped_address(addr).ok_or(Uf2Error::NotRam { addr })?;
            bytes.push((s, b));
        }
    }
    bytes.sort_unstable_by_key(|b| b.0);
    if let Some(w) = bytes.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(Uf2Error::Overlap { addr: w[0].0 });
    }
    let (Some(lo), Some(hi)) = (bytes.first(), bytes.last()) else {
        return Ok((SRAM_BASE, Vec::new()));
    };
    let start = lo.0 & !(PAYLOAD as u32 - 1);
    let end = (hi.0 + 1).next_multiple_of(PAYLOAD as u32).min(SRAM_END);
    let mut out = vec![0u8; (end - start) as usize];
    for (a, b) in bytes {
        out[(a - start) as usize] = b;
    }
    Ok((start, out))
}

/// `payload` at `start` as UF2 blocks of [`PAYLOAD`] bytes (the last one zero-padded)
/// with `family` present in every block.
pub fn write(start: u32, payload: &[u8], family: u32) -> Vec<u8> {
    let n = payload.len().div_ceil(PAYLOAD);
    let mut out = Vec::with_capacity(n * BLOCK);
    for (i, chunk) in payload.chunks(PAYLOAD).enumerate() {
        let header = [
            MAGIC_START0,
            MAGIC_START1,
            FLAG_FAMILY_ID_PRESENT,
            start + (i * PAYLOAD) as u32,
            PAYLOAD as u32,
            i as u32,
            n as u32,
            family,
        ];
        for w in header {
            out.extend(w.to_le_bytes());
        }
        out.extend(chunk);
        out.resize(out.len() + (476 - chunk.len()), 0);
        out.extend(MAGIC_END.to_le_bytes());
    }
    out
}

/// A RAM-only RP2040 UF2 of `segments` ([`striped_image`] then [`write`] with
/// [`RP2040_FAMILY_ID`]).
///
/// Errors: those of [`striped_image`].
pub fn rp2040_ram(segments: &[(u32, Vec<u8>)]) -> Result<Vec<u8>, Uf2Error> {
    let (start, bytes) = striped_image(segments)?;
    Ok(write(start, &bytes, RP2040_FAMILY_ID))
}

/// A flash UF2 of `bytes` (a flash image from 0x10000000): [`write`] at [`FLASH_BASE`] with
/// [`RP2040_FAMILY_ID`], the last block zero-padded.
pub fn rp2040_flash(bytes: &[u8]) -> Vec<u8> {
    write(FLASH_BASE, bytes, RP2040_FAMILY_ID)
}
