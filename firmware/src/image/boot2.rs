//! The second-stage boot loader (boot2) of a flash image: the first 256 bytes of flash.
//!
//! At power-on the boot ROM reads them over slow serial 03h reads into the top of SRAM5
//! ([`BOOT2_LOAD`]), checks that their last word is the CRC-32 of the other 252
//! ([`tactus_rp2040::bootrom::boot2_crc32`]) and enters them with LR = 0 (RP2040 datasheet
//! 2.8.1; pico-bootrom `bootrom_main.c`, `_flash_boot`). Their job is to make the flash fast
//! to read and to enter the image. This one does what pico-sdk's `boot2_w25q080.S` does for
//! the W25Q-family flash of the Raspberry Pi Pico (written anew here with the project's
//! encoder):
//!
//! 1. SSI disabled, serial clock at clk_sys / [`SCKDV`], RX sample delay 1, the flash
//!    selected; standard SPI, 8-bit frames, TX and RX.
//! 2. Status register 2 read (35h); if it is not just QE (0x02), write enable (06h) and a
//!    status write of SR1 = 0, SR2 = QE (01h 00h 02h), then status register 1 polled (05h)
//!    until BUSY clears (the non-volatile write takes about 10 ms: only on a factory-fresh
//!    chip).
//! 3. A dummy quad I/O read (EBh, address 0, mode bits 0xa0) through the SSI in quad EEPROM
//!    mode (32-bit frames, instruction on one wire, 24 address and 8 mode bits and the data
//!    on four, 4 dummy clocks): the mode bits put the chip in continuous-read mode.
//! 4. The SSI set to translate each XIP access into address + mode bits 0xa0 on four wires
//!    with no instruction (continuous read), and enabled.
//! 5. If LR was not 0 (called as a function), return; else point VTOR at the image's vector
//!    table at [`FLASH_VECTORS`], load SP from its first word and jump to its second (the
//!    image's flash reset handler, `super::flash_image`).
//!
//! All position independent (PC-relative literals and branches), using r0–r3 and the
//! stack only.

use super::ImageError;
use tactus_compiler::thumb::buffer::{Assembled, CodeBuffer, LongBranch};
use tactus_compiler::thumb::ins::{self as asm, cond};
use tactus_isa::decode::{AluOp, Instr, MemOp};
use tactus_rp2040::bootrom::{self, BOOT2_LOAD, BOOT2_SIZE};
use tactus_rp2040::flash::SR2_QE;
use tactus_rp2040::memory::FLASH_BASE;
use tactus_rp2040::ssi::{reg as ssi, XIP_SSI_BASE};

/// Where boot2 vectors into the image: the vector table after it in flash.
pub const FLASH_VECTORS: u32 = FLASH_BASE + BOOT2_SIZE as u32;
/// System clock cycles per serial clock (SSI BAUDR): pico-sdk 2.1.1's default for
/// `boot2_w25q080` (`PICO_FLASH_SPI_CLKDIV` 4), within the flash's 133 MHz at a 200 MHz
/// clk_sys.
pub const SCKDV: u32 = 4;
/// SR2's quad-enable bit, the value written to SR2.
const QE: u32 = SR2_QE as u32;
/// The mode bits that keep the flash in continuous-read mode (W25Q16JV: M5–4 = 10).
const MODE_CONTINUOUS: u32 = 0xa0;
/// The M0+'s VTOR.
const VTOR: u32 = 0xe000_ed08;
/// SYSm of MSP for `MSR`.
const MSP: u8 = 8;

/// `[r3 + off] = value` for an SSI register (clobbers r1, and r2 beyond `STR`'s reach).
fn ssi_store(a: &mut CodeBuffer, off: u32, value: u32) {
    a.mov_const(1, value);
    if off <= 124 {
        a.i(asm::str(1, 3, off as u16));
    } else {
        a.mov_const(2, off);
        a.i(Instr::MemReg {
            op: MemOp::Str,
            rt: 1,
            rn: 3,
            rm: 2,
        });
    }
}

/// boot2's code (module documentation), assembled at [`BOOT2_LOAD`].
///
/// Errors: [`ImageError::Assemble`].
pub fn code() -> Result<Assembled, ImageError> {
    let mut a = CodeBuffer::new(LongBranch::Refuse);
    let (read_sreg, wait_ready, skip, poll, vector) =
        (a.label(), a.label(), a.label(), a.label(), a.label());
    a.i(asm::push_lr(0));
    a.ldr_const(3, XIP_SSI_BASE);
    // 1. Standard SPI, 8-bit frames, TX and RX.
    ssi_store(&mut a, ssi::SSIENR, 0);
    ssi_store(&mut a, ssi::BAUDR, SCKDV);
    ssi_store(&mut a, ssi::RX_SAMPLE_DLY, 1);
    ssi_store(
        &mut a,
        ssi::CTRLR0,
        7 << 16 | ssi::FRF_STD << 21 | ssi::TMOD_TX_AND_RX << 8,
    );
    ssi_store(&mut a, ssi::SER, 1);
    ssi_store(&mut a, ssi::SSIENR, 1);
    // 2. QE, unless already set.
    a.i(asm::movs(0, 0x35));
    a.bl(read_sreg);
    a.i(asm::movs(2, QE as u8));
    a.i(asm::cmp(0, 2));
    a.bc(cond::EQ, skip);
    ssi_store(&mut a, ssi::DR0, 0x06);
    a.bl(wait_ready);
    a.i(asm::ldr(1, 3, ssi::DR0 as u16));
    ssi_store(&mut a, ssi::DR0, 0x01);
    ssi_store(&mut a, ssi::DR0, 0);
    ssi_store(&mut a, ssi::DR0, QE);
    a.bl(wait_ready);
    for _ in 0..3 {
        a.i(asm::ldr(1, 3, ssi::DR0 as u16));
    }
    a.bind(poll);
    a.i(asm::movs(0, 0x05));
    a.bl(read_sreg);
    a.i(asm::movs(1, 1));
    a.i(asm::alu(AluOp::Tst, 0, 1));
    a.bc(cond::NE, poll);
    a.bind(skip);
    // 3. The dummy EBh read with mode bits 0xa0.
    ssi_store(&mut a, ssi::SSIENR, 0);
    ssi_store(
        &mut a,
        ssi::CTRLR0,
        ssi::FRF_QUAD << 21 | 31 << 16 | ssi::TMOD_EEPROM_READ << 8,
    );
    ssi_store(&mut a, ssi::CTRLR1, 0);
    ssi_store(
        &mut a,
        ssi::SPI_CTRLR0,
        8 << 2 | 4 << 11 | 2 << 8 | ssi::TT_1C2A,
    );
    ssi_store(&mut a, ssi::SSIENR, 1);
    ssi_store(&mut a, ssi::DR0, 0xeb);
    ssi_store(&mut a, ssi::DR0, MODE_CONTINUOUS);
    a.bl(wait_ready);
    // 4. Continuous-read XIP: address and mode bits on four wires, no instruction.
    ssi_store(&mut a, ssi::SSIENR, 0);
    ssi_store(
        &mut a,
        ssi::SPI_CTRLR0,
        MODE_CONTINUOUS << 24 | 8 << 2 | 4 << 11 | ssi::TT_2C2A,
    );
    ssi_store(&mut a, ssi::SSIENR, 1);
    // 5. Return, or enter the image.
    a.i(Instr::Pop { list: 1 });
    a.i(asm::cmp_imm(0, 0));
    a.bc(cond::EQ, vector);
    a.i(Instr::Bx { rm: 0 });
    a.bind(vector);
    a.ldr_const(0, FLASH_VECTORS);
    a.ldr_const(1, VTOR);
    a.i(asm::str(0, 1, 0));
    a.i(Instr::Ldm { rn: 0, list: 0b11 });
    a.i(Instr::Msr { sysm: MSP, rn: 0 });
    a.i(Instr::Bx { rm: 1 });
    // read_sreg: r0 = the command; returns the status byte in r0 (command and a dummy
    // byte out, the answer to the dummy kept).
    a.bind(read_sreg);
    a.i(asm::push_lr(0b10));
    a.i(asm::str(0, 3, ssi::DR0 as u16));
    a.i(asm::str(0, 3, ssi::DR0 as u16));
    a.bl(wait_ready);
    a.i(asm::ldr(0, 3, ssi::DR0 as u16));
    a.i(asm::ldr(0, 3, ssi::DR0 as u16));
    a.i(asm::pop_pc(0b10));
    // wait_ready: until the TX FIFO is empty and the SSI is not busy.
    let top = a.label();
    a.bind(wait_ready);
    a.i(asm::push_lr(0b11));
    a.bind(top);
    a.i(asm::ldr(1, 3, ssi::SR as u16));
    a.i(asm::movs(0, ssi::SR_TFE as u8));
    a.i(asm::alu(AluOp::Tst, 1, 0));
    a.bc(cond::EQ, top);
    a.i(asm::movs(0, ssi::SR_BUSY as u8));
    a.i(asm::alu(AluOp::Tst, 1, 0));
    a.bc(cond::NE, top);
    a.i(asm::pop_pc(0b11));
    a.pool();
    Ok(a.finish_code(BOOT2_LOAD)?)
}

/// boot2 as it goes into flash: [`code`] padded with zeros to 252 bytes and followed by its
/// CRC-32, little endian.
///
/// Errors: [`ImageError::Assemble`], also when the code passes 252 bytes.
pub fn bytes() -> Result<[u8; BOOT2_SIZE], ImageError> {
    let text = code()?.text;
    if text.len() > BOOT2_SIZE - 4 {
        return Err(ImageError::Assemble(format!(
            "boot2 takes {} bytes, more than the {} before its CRC",
            text.len(),
            BOOT2_SIZE - 4
        )));
    }
    let mut out = [0u8; BOOT2_SIZE];
    out[..text.len()].copy_from_slice(&text);
    let crc = bootrom::boot2_crc32(&out[..BOOT2_SIZE - 4]);
    out[BOOT2_SIZE - 4..].copy_from_slice(&crc.to_le_bytes());
    Ok(out)
}
