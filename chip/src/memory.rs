//! The address map's memories (datasheet 2.2 Address map, 2.6 Memory): the boot ROM, the
//! XIP flash window, and SRAM — four 64 KB banks striped word by word (bank = address bits
//! 3:2) plus the two 4 KB scratch banks, with the non-striped alias of the four at
//! 0x21000000 (2.6.1). [`sram_location`] is the one mapping from an SRAM address to its
//! physical byte and bank; physical order is the striped view's, so the striped SRAM is
//! one contiguous array.

/// Boot ROM: 0x00000000, 16 KB (datasheet 2.2.1).
pub const ROM_BASE: u32 = 0x0000_0000;
/// Boot ROM size in bytes.
pub const ROM_SIZE: u32 = 16 * 1024;
/// XIP flash window: 0x10000000 (datasheet 2.6.3). The Raspberry Pi Pico's W25Q16JV is
/// 2 MB ([`FLASH_SIZE`]).
pub const FLASH_BASE: u32 = 0x1000_0000;
/// Flash size in bytes (the Pico's 2 MB W25Q16JV).
pub const FLASH_SIZE: u32 = 2 * 1024 * 1024;
/// SRAM: 0x20000000 (striped SRAM0-3, then SRAM4 and SRAM5; datasheet 2.6.2).
pub const SRAM_BASE: u32 = 0x2000_0000;
/// SRAM size in bytes: 4 x 64 KB + 2 x 4 KB.
pub const SRAM_SIZE: u32 = 0x4_2000;
/// SRAM4 (scratch X), 4 KB.
pub const SRAM4_BASE: u32 = 0x2004_0000;
/// SRAM5 (scratch Y), 4 KB.
pub const SRAM5_BASE: u32 = 0x2004_1000;
/// Non-striped alias of SRAM0-3: bank n at `SRAM_ALIAS_BASE + n * 0x10000` (2.6.1).
pub const SRAM_ALIAS_BASE: u32 = 0x2100_0000;
/// Top of SRAM, the default initial stack pointer.
pub const SRAM_END: u32 = SRAM_BASE + SRAM_SIZE;
/// Number of SRAM banks that arbitrate separately: SRAM0-3, SRAM4, SRAM5 (2.6.2).
pub const BANKS: usize = 6;

/// Maps an SRAM address (striped or aliased) to (byte offset from [`SRAM_BASE`] in the
/// striped view's order, bank 0-5); `None` outside SRAM.
#[inline]
pub fn sram_location(addr: u32) -> Option<(usize, usize)> {
    let off = addr.wrapping_sub(SRAM_BASE);
    if off < 0x4_0000 {
        return Some((off as usize, ((off >> 2) & 3) as usize));
    }
    if off < SRAM_SIZE {
        return Some((off as usize, 4 + ((off - 0x4_0000) >> 12) as usize));
    }
    let alias = addr.wrapping_sub(SRAM_ALIAS_BASE);
    if alias < 0x4_0000 {
        let bank = alias >> 16;
        let word = (alias & 0xffff) >> 2;
        let phys = ((word * 4 + bank) << 2) | (alias & 3);
        return Some((phys as usize, bank as usize));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The non-striped alias reaches the same bytes as the striped view (datasheet 2.6.1:
    /// bank n's word w is striped word 4w + n).
    #[test]
    fn the_alias_is_the_striped_view_by_bank() {
        for bank in 0..4u32 {
            for word in [0u32, 1, 77, 0x3fff] {
                let alias = SRAM_ALIAS_BASE + bank * 0x1_0000 + 4 * word + 2;
                let striped = SRAM_BASE + 4 * (4 * word + bank) + 2;
                assert_eq!(sram_location(alias), sram_location(striped));
                assert_eq!(sram_location(alias).map(|l| l.1), Some(bank as usize));
            }
        }
        assert_eq!(sram_location(SRAM4_BASE), Some((0x4_0000, 4)));
        assert_eq!(sram_location(SRAM5_BASE + 0xfff), Some((0x4_1fff, 5)));
        assert_eq!(sram_location(SRAM_END), None);
        assert_eq!(sram_location(SRAM_ALIAS_BASE + 0x4_0000), None);
    }
}
