//! The image's start from reset, as on the chip: the entry the boot ROM jumps to, the
//! clock set-up, and core 1's launch over the SIO FIFOs.
//!
//! **Entry.** The image is RAM-only, like pico-sdk's `no_flash` binaries: after a UF2
//! download into SRAM the boot ROM reboots through the watchdog and enters the image at
//! the *lowest address written*, as Thumb code, with SP = 0x20042000 (pico-bootrom
//! `bootrom/virtual_disk.c`, `_write_uf2_page_complete` → `safe_reboot(lowest_addr,
//! SRAM_END)`; `bootrom_rt0.S`, `check_wdog`). The boot ROM accepts RAM blocks only in
//! 0x20000000–0x20042000 (`is_address_ram`), the striped alias, so the image's lowest
//! address is 0x20000000 and holds [`entry_stub`]: like pico-sdk's `_entry_point`
//! (`crt0.S`, `PICO_NO_FLASH`), it points VTOR at core 0's vector table and enters the
//! reset handler through it with the table's stack pointer.
//!
//! From flash, the boot ROM enters boot2 instead (`super::boot2`), which enters the flash
//! image's reset handler, which copies the image to SRAM and jumps to the entry stub's
//! second entry, [`ENTRY_FROM_FLASH`] (`super::flash_image`): from the stub on, both boots
//! are the same but for the one word the stub writes first, [`BOOT_SOURCE`]: the value core
//! 0's start handler gives SCRATCH4 when it enables the watchdog (`super::reboot`: a RAM
//! image arms the boot ROM's watchdog entry into its re-entry, a flash image boots from
//! flash again).
//!
//! **Clocks** ([`clock_set_up`]): the 12 MHz crystal (XOSC, datasheet 2.16), clk_ref on it;
//! where the board file gives a core voltage, VREG set to it and 1 ms (12,000 crystal
//! cycles) waited for it to settle, as pico-sdk 2.1.1's `runtime_init_clocks` does before
//! it switches clk_sys to a 200 MHz PLL (datasheet 2.10; the RP2040 needs 1.15 V above
//! 133 MHz); PLL_SYS to the board's clock (2.18.2: REFDIV 1, FBDIV, POSTDIV1 × POSTDIV2,
//! from [`tactus_rp2040::pll::pll_sys_dividers`]), clk_sys switched to it through the
//! auxiliary mux (2.15.3.2), the watchdog tick at 12 reference cycles so the timer counts
//! microseconds (4.7.2), and the timer pulsed through reset so it counts from 0 (its
//! ticks are then times from its release that the image schedules). The emulator models
//! these registers minimally (`emulator/src/clocks.rs`) and refuses clk_sys above 133 MHz
//! at a lower voltage.
//!
//! **Core 1** ([`launch_core1`]): pico-sdk's `multicore_launch_core1_raw`
//! (`pico_multicore/multicore.c`): the words 0, 0, 1, vector table, stack pointer, entry
//! point, each sent when the FIFO has room and answered by core 1's boot ROM; before each
//! 0 the RX FIFO is drained and an event signalled (`SEV`: the ROM may be waiting for
//! room); an answer that differs from the word sent restarts the sequence (RP2040
//! datasheet 2.8.2).

use super::ImageError;
use tactus_compiler::thumb::buffer::{CodeBuffer, LongBranch};
use tactus_compiler::thumb::ins::{self as asm, cond};
use tactus_isa::decode::{Hint, Instr};
use tactus_rp2040::clocks::{self, CLOCKS_BASE};
use tactus_rp2040::pll::{self, PLL_SYS_BASE};
use tactus_rp2040::resets::{self, RESETS_BASE};
use tactus_rp2040::sio::{reg as sio, SIO_BASE};
use tactus_rp2040::vreg::{self, VREG_AND_CHIP_RESET_BASE};
use tactus_rp2040::watchdog::{self, WATCHDOG_BASE};
use tactus_rp2040::xosc::{self, XOSC_BASE};
use tactus_rp2040::{ATOMIC_CLR as CLR, ATOMIC_SET as SET};

/// Where the boot ROM enters a RAM image: its lowest address (the entry stub's).
pub const ENTRY: u32 = 0x2000_0000;
/// The entry stub's second entry, where the flash image's reset handler enters it
/// ([`entry_stub`]).
pub const ENTRY_FROM_FLASH: u32 = ENTRY + 4;
/// Bytes reserved for the entry stub at the start of each bank: the stub's 44 bytes at
/// the striped [`ENTRY`] fill the first words of all four banks, and core 0's vector
/// table, 256-aligned for VTOR, starts after them.
pub const ENTRY_RESERVE: u32 = 0x100;
/// Bytes of the entry stub's code; its literal pool follows.
pub const ENTRY_STUB_CODE: u32 = 24;
/// The word the entry stub writes on every boot (in no segment of the image: bank 2's
/// first 256-byte page past the stub's words, which holds nothing else): the value core
/// 0's start handler writes to SCRATCH4 when it enables the watchdog
/// (`super::glue::Feed::entry`). From [`ENTRY`] (a RAM image's boot) the image's choice,
/// [`tactus_rp2040::watchdog::BOOT_MAGIC`] when it can boot again through the boot ROM's
/// watchdog entry (`super::reboot`), else [`super::fault::NON_REBOOT_MAGIC`]; from
/// [`ENTRY_FROM_FLASH`] always [`super::fault::NON_REBOOT_MAGIC`] (a flash image boots
/// from flash again after a reset, boot2 copying a clean image).
pub const BOOT_SOURCE: u32 = tactus_rp2040::memory::SRAM_ALIAS_BASE + 0x2_0000 + ENTRY_RESERVE;
/// The M0+'s VTOR (ARMv6-M B3.2.5; RP2040 datasheet 2.4.8).
const VTOR: u32 = 0xe000_ed08;

/// The settling time waited after raising VREG, in 12 MHz crystal cycles: pico-sdk 2.1.1's
/// `SYS_CLK_VREG_VOLTAGE_AUTO_ADJUST_DELAY_US` (1000 µs) at `XOSC_HZ`.
pub const VREG_SETTLE_XOSC_CYCLES: u32 = 12_000;

/// What core 0's reset handler starts before its keys: the core voltage and PLL dividers
/// of the board's clock and, on a two-core image, core 1's launch words.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Boot {
    /// (FBDIV, POSTDIV1, POSTDIV2) of the board's clock; `None` when no PLL setting gives
    /// it exactly (the image then runs only in the emulator, whose clock is the board's
    /// from power-on: [`super::FirmwareImage::flashable`] says why).
    pub pll: Option<(u32, u32, u32)>,
    /// The VREG.VSEL set before the PLL (the board file's core voltage); `None` leaves the
    /// regulator at its reset value, 1.10 V.
    pub vsel: Option<u32>,
    /// Core 1's vector table, initial stack pointer and entry point (Thumb bit set).
    pub core1: Option<[u32; 3]>,
    /// Whether the image drives converters: core 0 then resets their blocks and sets the
    /// DMA's bus priority before it launches core 1 ([`super::io::boot`]).
    pub io: bool,
}

impl Boot {
    /// The boot of a board clocked at `clock_hz` with the core at `core_mv` (mV; `None`:
    /// the regulator's default; a voltage VSEL cannot make is left at the default too, the
    /// board file's reader rejects those).
    pub fn new(clock_hz: u64, core_mv: Option<u32>, core1: Option<[u32; 3]>) -> Boot {
        Boot {
            pll: pll::pll_sys_dividers(clock_hz),
            vsel: core_mv.and_then(vreg::vsel_of_mv),
            core1,
            io: false,
        }
    }
}

/// The entry stub at [`ENTRY`]: [`BOOT_SOURCE`] = `ram_source` (entered at [`ENTRY`], a
/// RAM image's boot) or [`super::fault::NON_REBOOT_MAGIC`] (entered at
/// [`ENTRY_FROM_FLASH`]), then VTOR = `vectors` (core 0's table), SP = its word 0, jump to
/// its word 1. Returns the assembled bytes: [`ENTRY_STUB_CODE`] bytes of code, then its
/// literal pool.
///
/// Errors: [`ImageError::Assemble`].
pub fn entry_stub(vectors: u32, ram_source: u32) -> Result<Vec<u8>, ImageError> {
    let mut a = CodeBuffer::new(LongBranch::Refuse);
    let (from_flash, common) = (a.label(), a.label());
    a.ldr_const(3, ram_source);
    a.b(common);
    a.bind(from_flash);
    a.ldr_const(3, super::fault::NON_REBOOT_MAGIC);
    a.bind(common);
    a.ldr_const(0, vectors);
    a.ldr_const(1, BOOT_SOURCE);
    a.i(asm::str(3, 1, 0));
    a.ldr_const(1, VTOR);
    a.i(asm::str(0, 1, 0));
    a.i(asm::ldr(1, 0, 0));
    a.i(asm::ldr(2, 0, 4));
    a.i(Instr::MovHi { rd: 13, rm: 1 });
    a.i(Instr::Bx { rm: 2 });
    a.pool();
    let out = a.finish_code(ENTRY)?;
    if out.labels[from_flash.index()] != ENTRY_FROM_FLASH
        || out.data.first().map(|d| d.0 as u32) != Some(ENTRY_STUB_CODE)
    {
        return Err(ImageError::Assemble(
            "the entry stub's flash entry or literal pool moved".into(),
        ));
    }
    let bytes = out.text;
    if bytes.len() as u32 > ENTRY_RESERVE / 4 {
        return Err(ImageError::Assemble(format!(
            "the entry stub takes {} bytes, more than the {} its banks reserve",
            bytes.len(),
            ENTRY_RESERVE / 4
        )));
    }
    Ok(bytes)
}

/// Copies the pieces of a copy table from `table` to `end` (three words a piece: the
/// address of its bytes, the address they go to, and that address's end; both word
/// aligned), word by word (`LDM`/`STM`), in table order: the flash image's copy of itself
/// to SRAM (`super::flash_image`) and a RAM image's restore of its data after a watchdog
/// reset (`super::reboot`). Clobbers r0-r5.
pub fn copy_pieces(a: &mut CodeBuffer, table: u32, end: u32) {
    let (next, word, test, done) = (a.label(), a.label(), a.label(), a.label());
    a.ldr_const(0, table);
    a.ldr_const(3, end);
    a.bind(next);
    a.i(asm::cmp(0, 3));
    a.bc(cond::EQ, done);
    // r1 = the piece's bytes, r2 = where they go, r4 = its end.
    a.i(Instr::Ldm {
        rn: 0,
        list: 0b1_0110,
    });
    a.b(test);
    a.bind(word);
    a.i(Instr::Ldm {
        rn: 1,
        list: 0b10_0000,
    });
    a.i(Instr::Stm {
        rn: 2,
        list: 0b10_0000,
    });
    a.bind(test);
    a.i(asm::cmp(2, 4));
    a.bc(cond::NE, word);
    a.b(next);
    a.bind(done);
}

/// `[addr] = value` (clobbers r0, r1).
fn store(a: &mut CodeBuffer, addr: u32, value: u32) {
    a.ldr_const(0, addr);
    a.mov_const(1, value);
    a.i(asm::str(1, 0, 0));
}

/// Waits until `[addr] & mask == want` (clobbers r0-r2).
fn wait(a: &mut CodeBuffer, addr: u32, mask: u32, want: u32) {
    let top = a.label();
    a.ldr_const(0, addr);
    a.mov_const(2, mask);
    a.bind(top);
    a.i(asm::ldr(1, 0, 0));
    a.i(asm::alu(tactus_isa::decode::AluOp::And, 1, 2));
    if want == 0 {
        a.bc(cond::NE, top);
    } else {
        a.i(asm::cmp(1, 2));
        a.bc(cond::NE, top);
    }
    debug_assert!(want == 0 || want == mask);
}

/// Pulses block `bit` of RESETS and waits until it is out of reset (clobbers r0-r2).
fn pulse_reset(a: &mut CodeBuffer, bit: u32) {
    store(a, RESETS_BASE + SET + resets::reg::RESET, bit);
    store(a, RESETS_BASE + CLR + resets::reg::RESET, bit);
    wait(a, RESETS_BASE + resets::reg::RESET_DONE, bit, bit);
}

/// Sets VREG.VSEL to `vsel` (a read-modify-write, as pico-sdk's `vreg_set_voltage`) and
/// waits [`VREG_SETTLE_XOSC_CYCLES`] cycles of clk_sys (3 per loop: `SUBS`, taken `BNE`).
/// Clobbers r0-r2.
fn set_core_voltage(a: &mut CodeBuffer, vsel: u32) {
    a.ldr_const(0, VREG_AND_CHIP_RESET_BASE + vreg::reg::VREG);
    a.i(asm::ldr(1, 0, 0));
    a.mov_const(2, vreg::VREG_VSEL_BITS);
    a.i(asm::alu(tactus_isa::decode::AluOp::Bic, 1, 2));
    a.mov_const(2, vsel << 4);
    a.i(asm::alu(tactus_isa::decode::AluOp::Orr, 1, 2));
    a.i(asm::str(1, 0, 0));
    let settle = a.label();
    a.mov_const(0, VREG_SETTLE_XOSC_CYCLES / 3);
    a.bind(settle);
    a.i(asm::subs_imm(0, 0, 1));
    a.bc(cond::NE, settle);
}

/// The clock set-up (module documentation); without PLL dividers only the timer's tick
/// and reset. Clobbers r0-r2.
pub fn clock_set_up(a: &mut CodeBuffer, pll: Option<(u32, u32, u32)>, vsel: Option<u32>) {
    if let Some((fbdiv, pd1, pd2)) = pll {
        // XOSC: 1-15 MHz range, start-up delay 1 ms (12 MHz × 1 ms / 256), enable.
        store(
            a,
            XOSC_BASE + xosc::reg::CTRL,
            xosc::CTRL_FREQ_RANGE_1_15MHZ,
        );
        store(a, XOSC_BASE + xosc::reg::STARTUP, 47);
        store(a, XOSC_BASE + xosc::reg::CTRL, xosc::CTRL_ENABLE_1_15MHZ);
        wait(
            a,
            XOSC_BASE + xosc::reg::STATUS,
            xosc::STATUS_STABLE,
            xosc::STATUS_STABLE,
        );
        // clk_sys off the auxiliary mux (to clk_ref), clk_ref to the crystal.
        store(a, CLOCKS_BASE + CLR + clocks::reg::CLK_SYS_CTRL, 1);
        wait(a, CLOCKS_BASE + clocks::reg::CLK_SYS_SELECTED, 1, 1);
        store(a, CLOCKS_BASE + clocks::reg::CLK_REF_CTRL, 2);
        wait(a, CLOCKS_BASE + clocks::reg::CLK_REF_SELECTED, 4, 4);
        // The core voltage the clock needs, settled while clk_sys runs from the crystal.
        if let Some(vsel) = vsel {
            set_core_voltage(a, vsel);
        }
        // PLL_SYS: reset, REFDIV 1, FBDIV, power up the PLL and its VCO, lock, post
        // dividers, power them up.
        pulse_reset(a, resets::PLL_SYS);
        store(a, PLL_SYS_BASE + pll::reg::CS, 1);
        store(a, PLL_SYS_BASE + pll::reg::FBDIV_INT, fbdiv);
        store(a, PLL_SYS_BASE + CLR + pll::reg::PWR, 1 | 1 << 5);
        wait(a, PLL_SYS_BASE + pll::reg::CS, pll::CS_LOCK, pll::CS_LOCK);
        store(a, PLL_SYS_BASE + pll::reg::PRIM, pd1 << 16 | pd2 << 12);
        store(a, PLL_SYS_BASE + CLR + pll::reg::PWR, 1 << 3);
        // clk_sys = PLL_SYS / 1 through the auxiliary mux.
        store(a, CLOCKS_BASE + clocks::reg::CLK_SYS_DIV, 1 << 8);
        store(a, CLOCKS_BASE + clocks::reg::CLK_SYS_CTRL, 0);
        store(a, CLOCKS_BASE + clocks::reg::CLK_SYS_CTRL, 1);
        wait(a, CLOCKS_BASE + clocks::reg::CLK_SYS_SELECTED, 2, 2);
    }
    // The timer: 1 µs ticks from the 12 MHz reference, counting from its release.
    store(
        a,
        WATCHDOG_BASE + watchdog::reg::TICK,
        watchdog::TICK_ENABLE | 12,
    );
    pulse_reset(a, resets::TIMER);
}

/// Launches core 1 at `entry` with `vectors` and `sp` (module documentation). Clobbers
/// r0, r4, r7 and LR.
pub fn launch_core1(a: &mut CodeBuffer, [vectors, sp, entry]: [u32; 3]) {
    let (restart, exchange, done) = (a.label(), a.label(), a.label());
    a.ldr_const(4, SIO_BASE);
    a.bind(restart);
    for w in [0, 0, 1, vectors, sp, entry] {
        if w <= 255 {
            a.i(asm::movs(7, w as u8));
        } else {
            a.ldr_const(7, w);
        }
        a.bl(exchange);
        a.i(asm::cmp(0, 7));
        a.bc(cond::NE, restart);
    }
    a.b(done);
    // exchange: r7 = the word; r0 = core 1's answer.
    let (drain, drained, send, recv) = (a.label(), a.label(), a.label(), a.label());
    a.bind(exchange);
    a.i(asm::cmp_imm(7, 0));
    a.bc(cond::NE, send);
    a.bind(drain);
    a.i(asm::ldr(0, 4, sio::FIFO_ST as u16));
    a.i(asm::lsrs(0, 0, 1)); // VLD → carry
    a.bc(cond::CC, drained);
    a.i(asm::ldr(0, 4, sio::FIFO_RD as u16));
    a.b(drain);
    a.bind(drained);
    a.i(Instr::Hint(Hint::Sev));
    a.bind(send);
    a.i(asm::ldr(0, 4, sio::FIFO_ST as u16));
    a.i(asm::lsrs(0, 0, 2)); // RDY → carry
    a.bc(cond::CC, send);
    a.i(asm::str(7, 4, sio::FIFO_WR as u16));
    a.i(Instr::Hint(Hint::Sev));
    a.bind(recv);
    a.i(asm::ldr(0, 4, sio::FIFO_ST as u16));
    a.i(asm::lsrs(0, 0, 1));
    a.bc(cond::CC, recv);
    a.i(asm::ldr(0, 4, sio::FIFO_RD as u16));
    a.i(Instr::Bx { rm: 14 });
    a.pool();
    a.bind(done);
}

/// What each core's reset handler does first: core 0 sets the clocks up and launches
/// core 1 ([`Boot`]); every core writes its stack canary (`canary` at `stack_bottom`).
/// Clobbers r0-r2, r4, r7, LR.
pub fn core_start(a: &mut CodeBuffer, core: usize, boot: &Boot, stack_bottom: u32, canary: u32) {
    store(a, stack_bottom, canary);
    if core == 0 {
        clock_set_up(a, boot.pll, boot.vsel);
        if boot.io {
            pulse_reset(a, super::io::RESETS);
            super::io::boot(a);
        }
        if let Some(words) = boot.core1 {
            launch_core1(a, words);
        }
    }
    a.pool_inline();
}
