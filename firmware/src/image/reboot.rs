//! A RAM image's way back after a watchdog reset: the boot ROM's watchdog entry into a
//! re-entry that restores the image's data from a pristine copy kept in the image.
//!
//! **Why.** A RAM image (a UF2 or a debugger's load into SRAM, no flash) has nothing for the
//! boot ROM to boot from flash: after a reset whose SCRATCH4 is not the ROM's entry magic
//! it would wait in USB boot, the motors at zero for good. But a watchdog reset keeps SRAM
//! (RP2040 datasheet 4.7; `tactus_emulator`'s `machine/reset.rs`), and the boot ROM enters
//! any code the scratch registers name (pico-bootrom `bootrom/bootrom_rt0.S`, `check_wdog`:
//! SCRATCH4 = 0xb007c0d3, SCRATCH5 = entry ^ −SCRATCH4, SCRATCH6 = the stack pointer,
//! SCRATCH7 = the entry; it clears SCRATCH4 and `BLX`es the entry; pico-sdk's
//! `watchdog_reboot` writes them so). The code survived the run; the data did not stay as
//! the image left it (key states, limiter budgets, counters, the sensor checks' words, the
//! converters' buffers): so the image keeps a pristine copy of every data segment, and the
//! entry restores them before the image starts as after its first load.
//!
//! **Arming** (core 0's start handler, `super::glue::Feed::entry`, where it enables the
//! watchdog): SCRATCH5-7 for [`REENTRY`] with SP = core 0's stack top, then SCRATCH4 =
//! the word at [`super::boot::BOOT_SOURCE`], which the entry stub writes on every boot:
//! the ROM's magic on a RAM image's boot when [`plan`] found room for the copies, pico-sdk's
//! `WATCHDOG_NON_REBOOT_MAGIC` ([`super::fault::NON_REBOOT_MAGIC`]) on a boot from flash.
//! So a flash image keeps booting from flash after a reset (boot2 and the flash reset
//! handler copy code and data from flash: a cleaner start than this entry, which cannot
//! mend code; both could take this entry, but the flash path restores more).
//!
//! **The re-entry** ([`REENTRY`], core 0 in Thumb state from the boot ROM; core 1 waits in
//! the boot ROM's launch protocol, as after any reset): copies each pristine copy over its
//! segment ([`super::boot::copy_pieces`], the flash reset handler's loop: 7 cycles a word at
//! the clock the reset left, on the chip the ring oscillator, before the reset handler sets
//! the clocks up), writes SCRATCH4 = `WATCHDOG_NON_REBOOT_MAGIC`
//! (the ROM cleared it), and jumps to the entry stub at [`super::boot::ENTRY`]. From there
//! the boot is a RAM image's first: the clocks, core 1's launch, the keys' `init`s; core 0's
//! reset handler sees REASON set and SCRATCH4 = the non-reboot magic, so it counts a
//! [`super::fault::FaultKind::Watchdog`] trip over the fault record SCRATCH0-3 kept
//! (`super::fault`, "Across a watchdog reset"), exactly as after a boot from flash.
//!
//! **What it does not mend.** Code changed in SRAM (a flipped bit in an instruction, the
//! emulator's injected hang, `super::run`'s `FaultKind::Hang`) stays changed: a fault that
//! persists in the code resets the board again after each boot, every reset counted and
//! the motors at zero meanwhile; only a boot from flash reloads the code. A brown-out
//! clears SRAM, the image with it: a RAM image then truly waits in USB boot (the run says
//! so, `super::run`'s resets).
//!
//! **Where** (the image's free SRAM): the re-entry's code at [`REENTRY`] in SRAM2, then
//! its copy table, then the copies, each in SRAM2 or else SRAM3, from their first 256-byte
//! page past the entry stub's reserve up to the converters' I/O blocks ([`COPY_END`]):
//! banks no core's code or data uses (`super`'s "Memory": the windows' rows above and, on a
//! converter board, the I/O blocks at `super::io::IO_OFFSET`).

use super::boot::{self, copy_pieces};
use super::fault::NON_REBOOT_MAGIC;
use super::{FirmwareImage, ImageError};
use tactus_compiler::thumb::buffer::{CodeBuffer, LongBranch};
use tactus_isa::decode::Instr;
use tactus_rp2040::memory::SRAM_ALIAS_BASE;
use tactus_rp2040::watchdog::{reg as wreg, WATCHDOG_BASE};

/// The re-entry's address (SCRATCH7 without its Thumb bit): SRAM2's second 256-byte page
/// (its first holds the entry stub's words and [`super::boot::BOOT_SOURCE`]).
pub const REENTRY: u32 = SRAM_ALIAS_BASE + 0x2_0000 + 2 * boot::ENTRY_RESERVE;
/// Bytes kept for the re-entry's code and literal pool; its copy table follows.
const CODE_BYTES: u32 = 64;
/// Bank offset past the last byte a copy may take in SRAM2 and SRAM3: the converters' I/O
/// blocks (`super::io::IO_OFFSET`), below the windows' rows.
pub const COPY_END: u32 = super::io::IO_OFFSET;

/// One restore of the re-entry: a data segment and its pristine copy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Restore {
    /// The segment's address.
    pub to: u32,
    /// Its copy's address.
    pub copy: u32,
    /// Its bytes (a multiple of 4).
    pub len: u32,
}

/// The re-entry of an image: its segments (the code, the table and the copies in SRAM2,
/// more copies in SRAM3 where SRAM2 is full) and its restores.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reboot {
    /// The segments to add to the image's.
    pub segments: Vec<(u32, Vec<u8>)>,
    /// What the re-entry copies, in order.
    pub restores: Vec<Restore>,
    /// Where the re-entry's literal pool starts; its copy table and the copies follow
    /// (data, for an ELF's `$d` mapping symbol).
    pub pool: u32,
}

impl Reboot {
    /// Bytes of SRAM the re-entry takes (its code, table and copies).
    pub fn bytes(&self) -> u32 {
        self.segments.iter().map(|s| s.1.len() as u32).sum()
    }

    /// The address of the pristine copy of the `len` data bytes at `at`, when a restore
    /// covers them all.
    pub fn copy_of(&self, at: u32, len: u32) -> Option<u32> {
        (self.restores.iter())
            .find(|r| at >= r.to && at + len <= r.to + r.len)
            .map(|r| r.copy + (at - r.to))
    }
}

impl FirmwareImage {
    /// The RAM image's re-entry after a watchdog reset (module documentation: the boot
    /// ROM's watchdog entry restores its data from pristine copies and boots it again), or
    /// why it has none (no watchdog, no room for the copies): then a watchdog reset leaves
    /// a RAM image in USB boot. A flash image boots from flash again either way.
    pub fn ram_reboot(&self) -> Result<&Reboot, &str> {
        self.reentry.as_ref().map_err(String::as_str)
    }
}

/// The last step of an image's build: with the watchdog on, the re-entry restoring the
/// data segments at `data_at` ([`plan`]) added to `segments`; then the entry stub, first of
/// `segments` (core 0's vector table at `vectors`), made for it ([`super::boot::entry_stub`]:
/// a RAM image's boot arms the boot ROM's entry only when there is a re-entry). Returns the
/// re-entry, or why there is none.
///
/// Errors: [`ImageError::Assemble`].
pub(super) fn finish(
    segments: &mut Vec<(u32, Vec<u8>)>,
    data_at: &[u32],
    watchdog: bool,
    vectors: u32,
) -> Result<Result<Reboot, String>, ImageError> {
    let data: Vec<(u32, &[u8])> = (segments.iter())
        .filter(|(at, _)| data_at.contains(at))
        .map(|(at, d)| (*at, d.as_slice()))
        .collect();
    let reentry = match watchdog {
        true => plan(&data)?,
        false => Err("the image runs no watchdog".into()),
    };
    let ram_source = match &reentry {
        Ok(r) => {
            segments.extend(r.segments.iter().cloned());
            tactus_rp2040::watchdog::BOOT_MAGIC
        }
        Err(_) => NON_REBOOT_MAGIC,
    };
    let stub = boot::entry_stub(vectors, ram_source)?;
    match segments.first_mut() {
        Some(first) if first.0 == boot::ENTRY => first.1 = stub,
        _ => segments.insert(0, (boot::ENTRY, stub)),
    }
    Ok(reentry)
}

/// The re-entry restoring `data` (the image's data segments: each core's control block,
/// records and states, and its I/O block), or why there is none: a copy that fits neither
/// SRAM2 nor SRAM3 below [`COPY_END`] (the image then stays in USB boot after a watchdog
/// reset, as a RAM image without this entry would), or a segment whose length is not a
/// whole number of words.
///
/// Errors: [`ImageError::Assemble`] when the re-entry does not assemble in its bytes.
pub fn plan(data: &[(u32, &[u8])]) -> Result<Result<Reboot, String>, ImageError> {
    let bank = |b: u32| SRAM_ALIAS_BASE + 0x1_0000 * b;
    let table = REENTRY + CODE_BYTES;
    let table_end = table + 12 * data.len() as u32;
    // Per bank (2, 3): where its next copy goes, and the copies' bytes from its start.
    let mut next = [table_end, bank(3) + boot::ENTRY_RESERVE];
    let start = next;
    let mut bytes = [Vec::new(), Vec::new()];
    let mut restores = Vec::with_capacity(data.len());
    for &(to, d) in data {
        let len = d.len() as u32;
        if !len.is_multiple_of(4) {
            return Ok(Err(format!(
                "the data segment at {to:#010x} is {len} bytes, not whole words"
            )));
        }
        let Some(i) = (0..2).find(|&i| next[i] + len <= bank(2 + i as u32) + COPY_END) else {
            return Ok(Err(format!(
                "no room for a pristine copy of the {len} bytes of data at {to:#010x} in \
                 SRAM2 or SRAM3 (below bank offset {COPY_END:#x})"
            )));
        };
        restores.push(Restore {
            to,
            copy: next[i],
            len,
        });
        bytes[i].extend_from_slice(d);
        next[i] += len;
    }
    let (code, pool) = reentry(table, table_end)?;
    let mut first = code;
    first.resize(CODE_BYTES as usize, 0);
    for r in &restores {
        for w in [r.copy, r.to, r.to + r.len] {
            first.extend(w.to_le_bytes());
        }
    }
    let [b2, b3] = bytes;
    first.extend(b2);
    let mut segments = vec![(REENTRY, first)];
    if !b3.is_empty() {
        segments.push((start[1], b3));
    }
    Ok(Ok(Reboot {
        segments,
        restores,
        pool,
    }))
}

/// The re-entry's code (module documentation) for the copy table from `table` to `end`,
/// and the address of its literal pool.
///
/// Errors: [`ImageError::Assemble`], also when it passes its [`CODE_BYTES`].
fn reentry(table: u32, end: u32) -> Result<(Vec<u8>, u32), ImageError> {
    let mut a = CodeBuffer::new(LongBranch::Refuse);
    copy_pieces(&mut a, table, end);
    a.ldr_const(0, WATCHDOG_BASE + wreg::SCRATCH0 + 16);
    a.ldr_const(1, NON_REBOOT_MAGIC);
    a.i(tactus_compiler::thumb::ins::str(1, 0, 0));
    a.ldr_const(0, boot::ENTRY | 1);
    a.i(Instr::Bx { rm: 0 });
    a.pool();
    let out = a.finish_code(REENTRY)?;
    let pool = REENTRY + out.data.first().map_or(0, |d| d.0 as u32);
    let text = out.text;
    if text.len() as u32 > CODE_BYTES {
        return Err(ImageError::Assemble(format!(
            "the re-entry takes {} bytes, more than its {CODE_BYTES}",
            text.len()
        )));
    }
    Ok((text, pool))
}
