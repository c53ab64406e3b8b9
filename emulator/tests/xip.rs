//! The boot ROM's flash path and the XIP model (`emulator/src/xip.rs`): the SSI's registers,
//! FIFOs and serial timing as boot2 drives them, the flash chip's status registers and
//! continuous-read mode, which XIP configurations read the flash, the boot ROM's CRC check
//! and entry into boot2, and the timer's reset.

use tactus_emulator::xip::{Xip, XipRead};
use tactus_emulator::{Board, Config, EmuError};
use tactus_rp2040::bootrom::{self, BOOT2_LOAD};
use tactus_rp2040::flash::SR2_QE as QE;
use tactus_rp2040::memory::{FLASH_BASE, SRAM_BASE};
use tactus_rp2040::ssi::reg;

/// A fresh chip behind the SSI at reset, with `array` as the flash.
fn ssi() -> Xip {
    Xip::new(125_000_000)
}

/// Writes `v` to register `off` at `now`.
fn w(x: &mut Xip, now: u64, off: u32, v: u32, array: &[u8]) {
    assert!(x.write(now, off, v, array), "register {off:#x}");
}

/// One standard-SPI command of 8-bit frames from `now`: returns the bytes received and
/// the cycle at which the SSI is idle again (what boot2's `wait_ssi_ready` polls).
fn command(x: &mut Xip, now: u64, bytes: &[u8], array: &[u8]) -> (Vec<u8>, u64) {
    for (i, &b) in bytes.iter().enumerate() {
        w(x, now + i as u64, reg::DR0, b as u32, array);
    }
    let mut t = now + bytes.len() as u64;
    while x.read(t, reg::SR).unwrap() & (reg::SR_BUSY | reg::SR_TFE) != reg::SR_TFE {
        t += 1;
        assert!(t < now + 1_000_000_000, "never idle");
    }
    let got = bytes
        .iter()
        .map(|_| x.read(t, reg::DR0).unwrap() as u8)
        .collect();
    (got, t)
}

/// Standard SPI, 8-bit frames, TX and RX, SCKDV 4, as boot2 sets it up.
fn std_spi(x: &mut Xip, now: u64, array: &[u8]) {
    w(x, now, reg::SSIENR, 0, array);
    w(x, now, reg::BAUDR, 4, array);
    w(x, now, reg::CTRLR0, 7 << 16, array);
    w(x, now, reg::SER, 1, array);
    w(x, now, reg::SSIENR, 1, array);
}

#[test]
fn status_registers_over_standard_spi_with_their_serial_timing() {
    let array = vec![0x5a; 4096];
    let mut x = ssi();
    std_spi(&mut x, 0, &array);
    // 35h and a dummy byte: 16 bits at 4 cycles each, busy until cycle 64 after the start.
    let (got, idle) = command(&mut x, 100, &[0x35, 0x35], &array);
    assert_eq!(got, vec![0xff, 0x00], "SR2 of a fresh chip");
    assert_eq!(idle, 100 + 64);
    // JEDEC ID: Winbond, W25Q16.
    let (got, _) = command(&mut x, 1000, &[0x9f, 0, 0, 0], &array);
    assert_eq!(got, vec![0xff, 0xef, 0x40, 0x15]);
    // 03h read: address 0x000010.
    let (got, _) = command(&mut x, 2000, &[0x03, 0, 0, 0x10, 0, 0], &array);
    assert_eq!(&got[4..], &[0x5a, 0x5a]);
    // A status write without write enable does nothing; with it, QE is set and BUSY
    // holds for 10 ms.
    let (_, t) = command(&mut x, 3000, &[0x01, 0x00, QE], &array);
    assert_eq!(command(&mut x, t + 10, &[0x35, 0], &array).0[1], 0);
    let (_, t) = command(&mut x, 5000, &[0x06], &array);
    let (_, t) = command(&mut x, t + 10, &[0x01, 0x00, QE], &array);
    let (sr1, t2) = command(&mut x, t + 10, &[0x05, 0], &array);
    assert_eq!(sr1[1] & 1, 1, "BUSY during the status write");
    assert!(x.chip.busy(t2));
    let done = t + 1_250_000; // 10 ms at 125 MHz
    assert!(!x.chip.busy(done + 100));
    assert_eq!(command(&mut x, done + 100, &[0x05, 0], &array).0[1], 0);
    assert_eq!(x.chip.sr2, QE);
    // Pushes after the SSI is disabled are dropped; configuration written while enabled
    // is ignored.
    w(&mut x, done + 200, reg::CTRLR0, 3 << 8, &array);
    assert_eq!(x.read(done + 200, reg::CTRLR0), Some(7 << 16));
    assert_eq!(x.read(0, reg::IDR), Some(0x5153_5049));
    assert_eq!(x.read(0, 0x100), None);
}

/// boot2's sequence for continuous quad reads, and the configurations XIP reads the flash
/// with, or refuses with a reason.
#[test]
fn xip_reads_the_flash_only_as_set_up() {
    let mut array = vec![0u8; 4096];
    array[..4].copy_from_slice(&[1, 2, 3, 4]);
    let mut x = ssi();
    assert!(x.xip_read(None).unwrap_err().contains("disabled"));
    std_spi(&mut x, 0, &array);
    assert!(x.xip_read(None).unwrap_err().contains("TMOD is 0"));
    // 03h XIP.
    w(&mut x, 10, reg::SSIENR, 0, &array);
    w(&mut x, 10, reg::CTRLR0, 31 << 16 | 3 << 8, &array);
    w(
        &mut x,
        10,
        reg::SPI_CTRLR0,
        0x03 << 24 | 2 << 8 | 6 << 2,
        &array,
    );
    w(&mut x, 10, reg::SSIENR, 1, &array);
    assert_eq!(x.xip_read(None), Ok(XipRead::Read));
    assert_eq!(x.xip_read(Some(125_000_000)), Ok(XipRead::Read));
    assert!(x
        .xip_read(Some(250_000_000))
        .unwrap_err()
        .contains("above the W25Q16JV's 50 MHz"));
    // Quad without QE: refused.
    let quad = |x: &mut Xip, now: u64, spi: u32| {
        w(x, now, reg::SSIENR, 0, &array);
        w(x, now, reg::CTRLR0, 2 << 21 | 31 << 16 | 3 << 8, &array);
        w(x, now, reg::CTRLR1, 0, &array);
        w(x, now, reg::SPI_CTRLR0, spi, &array);
        w(x, now, reg::SSIENR, 1, &array);
    };
    let enter = 8 << 2 | 4 << 11 | 2 << 8 | reg::TT_1C2A;
    let continuous = 0xa0 << 24 | 8 << 2 | 4 << 11 | reg::TT_2C2A;
    quad(&mut x, 20, 0xeb << 24 | enter);
    assert!(x.xip_read(None).unwrap_err().contains("QE bit clear"));
    x.chip.sr2 = QE;
    assert_eq!(x.xip_read(None), Ok(XipRead::QuadIo));
    // No instruction before continuous-read mode: refused; the dummy EBh read with mode bits
    // 0xa0 enters it (28 serial clocks: 8 instruction, 8 address and mode, 4 dummy, 8 data).
    quad(&mut x, 30, continuous);
    assert!(x
        .xip_read(None)
        .unwrap_err()
        .contains("not in continuous-read mode"));
    quad(&mut x, 40, enter);
    w(&mut x, 50, reg::DR0, 0xeb, &array);
    w(&mut x, 51, reg::DR0, 0xa0, &array);
    assert_eq!(x.read(52, reg::SR).unwrap() & reg::SR_BUSY, reg::SR_BUSY);
    assert_eq!(x.read(51 + 28 * 4, reg::SR).unwrap() & reg::SR_BUSY, 0);
    assert!(x.chip.continuous);
    // The data frame: flash bytes 0-3, the first shifted in most significant.
    assert_eq!(x.read(51 + 28 * 4, reg::DR0), Some(0x0102_0304));
    quad(&mut x, 200, continuous);
    assert_eq!(x.xip_read(None), Ok(XipRead::QuadContinuous));
    // Mode bits that end continuous-read mode: refused.
    quad(&mut x, 300, 8 << 2 | 4 << 11 | reg::TT_2C2A); // mode bits 0x00
    assert!(x.xip_read(None).unwrap_err().contains("mode bits"));
    // Power-on: the chip keeps QE, leaves continuous-read mode; the SSI is at reset.
    x.power_on();
    assert_eq!((x.chip.sr2, x.chip.continuous), (QE, false));
    assert!(x.xip_read(None).is_err());
}

/// A boot2 that only loops: the boot ROM copies it to the top of SRAM5, checks its CRC and
/// enters it with LR = 0; SRAM holds garbage; the XIP window does not read yet.
#[test]
fn the_boot_rom_enters_a_boot2_with_a_good_crc_and_refuses_a_bad_one() {
    let mut b2 = [0u8; 256];
    b2[..2].copy_from_slice(&[0xfe, 0xe7]); // B .
    let crc = bootrom::boot2_crc32(&b2[..252]);
    b2[252..].copy_from_slice(&crc.to_le_bytes());
    let mut board = Board::new(Config::default());
    board.write_bytes(FLASH_BASE, &b2).unwrap();
    board.boot_from_flash().unwrap();
    let c = &board.cores[0];
    assert_eq!((c.r[15], c.r[14], c.r[13]), (BOOT2_LOAD, 0, BOOT2_LOAD));
    let mut copy = [0u8; 256];
    board.read_bytes(BOOT2_LOAD, &mut copy).unwrap();
    assert_eq!(copy, b2);
    let mut low = [0u8; 64];
    board.read_bytes(SRAM_BASE, &mut low).unwrap();
    assert!(
        low.iter().any(|&b| b != 0),
        "SRAM powers up holding garbage"
    );
    let why = board.system.xip_error().unwrap();
    assert!(why.contains("TMOD is 0"), "{why}");
    board.run_for(1000);
    assert_eq!(board.cores[0].r[15], BOOT2_LOAD);

    b2[0] ^= 1;
    board.write_bytes(FLASH_BASE, &b2).unwrap();
    match board.boot_from_flash() {
        Err(EmuError::Boot2Checksum { computed, stored }) => {
            assert_eq!(stored, crc);
            assert_ne!(computed, crc);
        }
        other => panic!("{other:?}"),
    }
}

/// A fetch from flash while the XIP window does not read: a bus fault whose description
/// says why.
#[test]
fn a_fetch_from_an_unready_xip_window_faults_and_says_why() {
    let mut b2 = [0u8; 256];
    // LDR r0, [pc, #0]; BX r0; .word 0x10000101
    b2[..8].copy_from_slice(&[0x00, 0x48, 0x00, 0x47, 0x01, 0x01, 0x00, 0x10]);
    let crc = bootrom::boot2_crc32(&b2[..252]);
    b2[252..].copy_from_slice(&crc.to_le_bytes());
    let mut board = Board::new(Config::default());
    board.write_bytes(FLASH_BASE, &b2).unwrap();
    board.boot_from_flash().unwrap();
    let stop = board.run_for(1000);
    let text = board.describe_stop(&stop);
    assert!(
        text.contains("0x10000100") && text.contains("does not read the flash"),
        "{text}"
    );
}

/// The timer counts from its release from reset (a core's stores to RESETS' SET and CLR
/// aliases).
#[test]
fn the_timer_restarts_when_released_from_reset() {
    use tactus_rp2040::timer::reg as treg;
    let mut board = Board::new(Config {
        clock_hz: 1_000_000,
        ..Config::default()
    });
    // LDR r0, =RESETS SET; LDR r1, =timer bit; STR r1, [r0]; LDR r2, =RESETS CLR;
    // STR r1, [r2]; B .
    let code: [u16; 6] = [0x4802, 0x4903, 0x6001, 0x4a03, 0x6011, 0xe7fe];
    let mut bytes: Vec<u8> = code.iter().flat_map(|h| h.to_le_bytes()).collect();
    for word in [0x4000_e000u32, 1 << 21, 0x4000_f000] {
        bytes.extend(word.to_le_bytes());
    }
    board.write_bytes(SRAM_BASE, &bytes).unwrap();
    board.enter_ram_image(SRAM_BASE | 1);
    assert_eq!(board.system.timer.released_at(), None);
    board.run_for(500);
    let released = board.system.timer.released_at().unwrap();
    assert!((5..40).contains(&released), "{released}");
    let now = board.cycle();
    let t = board.system.timer.read(now, treg::TIMERAWL).unwrap() as u64;
    assert_eq!(t, now - released, "1 µs a cycle at 1 MHz, from the release");
}
