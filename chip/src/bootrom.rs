//! What the boot ROM does with flash (datasheet 2.8.1): it reads the first 256 bytes of
//! flash (boot2) into the top of SRAM, checks their CRC-32 and enters them.

use crate::memory::SRAM_END;

/// Where the boot ROM copies boot2 and enters it: the last 256 bytes of SRAM5 (pico-bootrom
/// `bootrom/bootrom_main.c`, `BOOT2_BASE = SRAM_END - BOOT2_SIZE_BYTES`).
pub const BOOT2_LOAD: u32 = SRAM_END - BOOT2_SIZE as u32;
/// Bytes of boot2, its CRC-32 in the last four (little endian).
pub const BOOT2_SIZE: usize = 256;
/// The boot ROM's stack top while it runs, and the stack pointer boot2 starts with: it
/// leaves the 256 bytes above it for boot2 (pico-bootrom `bootrom/bootrom.ld`, `_stacktop =
/// ORIGIN(SRAM) + LENGTH(SRAM) - 256`; the ROM's own frames below it are not modelled).
pub const BOOT_ROM_STACK_TOP: u32 = BOOT2_LOAD;

/// The CRC-32 the boot ROM checks over boot2's first 252 bytes: polynomial 0x04c11db7,
/// most significant bit first (no reflection), initial value 0xffffffff, no final XOR
/// (pico-bootrom `bootrom/bootrom_main.c`, `crc32_small(boot2_load, 252, 0xffffffff)`;
/// pico-sdk's `boot_stage2/pad_checksum -s 0xffffffff`, as its CMakeLists.txt runs it,
/// computes the same value with zlib's reflected CRC by reversing the bits of each byte and
/// of the result; it is CRC-32/MPEG-2).
pub fn boot2_crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xffff_ffffu32;
    for &b in bytes {
        crc ^= (b as u32) << 24;
        for _ in 0..8 {
            crc = if crc & 0x8000_0000 != 0 {
                (crc << 1) ^ 0x04c1_1db7
            } else {
                crc << 1
            };
        }
    }
    crc
}

/// What the boot ROM finds in the first 256 bytes of flash: `Ok` when their last word is
/// the CRC-32 of the others ([`boot2_crc32`]), else `Err((computed, stored))`.
pub fn check_boot2(boot2: &[u8; BOOT2_SIZE]) -> Result<(), (u32, u32)> {
    let computed = boot2_crc32(&boot2[..BOOT2_SIZE - 4]);
    let stored = u32::from_le_bytes([boot2[252], boot2[253], boot2[254], boot2[255]]);
    if computed == stored {
        Ok(())
    } else {
        Err((computed, stored))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// pico-sdk's `pad_checksum -s 0xffffffff` formula, written out with zlib's reflected
    /// CRC-32 (what `binascii.crc32` computes): reverse the bits of each byte, CRC from the
    /// seed, undo zlib's final XOR, reverse the result's 32 bits.
    fn pad_checksum(data: &[u8]) -> u32 {
        // binascii.crc32(data, seed ^ 0xffffffff) starts zlib's register at the seed.
        let mut crc = 0xffff_ffffu32;
        for &b in data {
            crc ^= b.reverse_bits() as u32;
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xedb8_8320
                } else {
                    crc >> 1
                };
            }
        }
        (crc ^ 0xffff_ffff ^ 0xffff_ffff).reverse_bits()
    }

    #[test]
    fn the_boot_rom_crc_is_pad_checksums() {
        let mut seed = 0x1234_5678u32;
        for len in [0usize, 1, 3, 252] {
            let data: Vec<u8> = (0..len)
                .map(|_| {
                    seed ^= seed << 13;
                    seed ^= seed >> 17;
                    seed ^= seed << 5;
                    seed as u8
                })
                .collect();
            assert_eq!(boot2_crc32(&data), pad_checksum(&data), "{len} bytes");
        }
        // CRC-32/MPEG-2 of "123456789" (the same parameters): 0x0376e6e7.
        assert_eq!(boot2_crc32(b"123456789"), 0x0376_e6e7);
    }
}
