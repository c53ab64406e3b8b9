//! The board's fault record: what the firmware writes when a check trips, where the host
//! reads it, and how it outlives a watchdog reset (docs/firmware.md, "Faults").
//!
//! **Why two words per core.** Each core checks its own keys, in its own SRAM bank (the
//! cores share no bank after the boot, `super`'s "Memory"), so each core keeps its own
//! record in its control block: the *fault word* at [`super::glue::ctrl::FAULT`] and the
//! *fault time* at [`super::glue::ctrl::FAULT_AT`], the next word. A core writes them only
//! on the path of a trip, which skips the key's model, so they cost the proven budget
//! nothing. The board's record is both cores' pairs; `keys.json` names each core's pair
//! (`cores[c].fault`).
//!
//! **The fault word** (32 bits, [`FaultWord`]):
//!
//! | bits  | field | meaning |
//! |-------|-------|---------|
//! | 0–7   | kind  | the last trip's [`FaultKind`] code (0: no trip since power-on) |
//! | 8–15  | key   | the tripped key's window slot (`KeySpec::slot`: on a keyboard's board the key's index in the board's key order, `keys.json`'s order; the host maps it to the MIDI number); [`NO_KEY`] for a fault of the whole board |
//! | 16–31 | trips | trips on this core since power-on, modulo 65,536 |
//!
//! **The fault time** is the core's sample count ([`super::glue::ctrl::SAMPLES`]) at the
//! last trip: samples since the sample loop started, after the last reset.
//!
//! **The reset word** (the record's third word, [`super::glue::ctrl::RESET_CAUSE`]) is why
//! the board last booted, as each core's reset handler read it: WATCHDOG.REASON (bits 1:0)
//! | VREG_AND_CHIP_RESET.CHIP_RESET (bits 8, 16, 20), raw ([`ResetCause::of`] decodes it).
//! It is what a brown-out leaves: SRAM and the scratch registers are lost with the supply,
//! so the trips before it are gone, but the boot after it records a power-on or brown-out
//! boot (CHIP_RESET.HAD_POR, REASON 0). The RP2040 cannot tell a brown-out from a first
//! power-on, and neither can the firmware: the host, which knows the board ran before,
//! reports the brown-out. Written at every boot, no cycle of the sample interrupt.
//!
//! **Across a watchdog reset.** SRAM is reloaded (from flash) or restored (a RAM image's
//! re-entry, [`super::reboot`]) at boot, so every trip also writes the core's pair to the
//! watchdog's scratch registers (datasheet 4.7: SCRATCH0–7 keep their values through a
//! watchdog reset, a power-on or brown-out reset clears them): core *c*'s fault word to
//! SCRATCH(2*c*), its time to SCRATCH(2*c* + 1) ([`scratch`]; SCRATCH4–7 are the boot
//! ROM's).
//!
//! **The watchdog** ([`super::Program::watchdog`]; docs/firmware.md, "Faults"). Core 0's
//! start handler enables it, at the start alarm (so a long start-up of many keys' `init`s
//! cannot outlast it): SCRATCH5–7 for the boot ROM's watchdog entry into the RAM image's
//! re-entry, then SCRATCH4 = the word the entry stub wrote ([`super::boot::BOOT_SOURCE`]):
//! on a RAM image's boot the ROM's entry magic ([`tactus_rp2040::watchdog::BOOT_MAGIC`]),
//! so that after a reset the ROM enters the re-entry, which restores the image's data and
//! boots it again ([`super::reboot`]); on a boot from flash [`NON_REBOOT_MAGIC`], so that
//! after a reset the ROM boots from flash again, boot2 copying a clean image into SRAM.
//! Either way the next start-up finds SCRATCH4 = [`NON_REBOOT_MAGIC`] (the re-entry writes
//! it over the one the ROM cleared) and knows that the watchdog, not the boot ROM, reset
//! the board, as pico-sdk's `watchdog_enable_caused_reboot` tells it. Then LOAD =
//! [`WATCHDOG_LOAD`], CTRL's ENABLE set. Core 0's handler feeds it (LOAD again) at the end
//! of each sample of its *feeding class* in which core 1's sample count is its own or one
//! less (core 1 finished the sample before or finishes it now); on a one-core image each
//! sample of the class. Where core 0's keys take turns (`glue::Turns`, the sensor check)
//! the feeding class is one class of those samples, the one whose longest gap `G` is the
//! smallest (`glue::Turns::feed_class`: grand88's boards `G` = 4 at 133 MHz, 5 at 200 MHz),
//! when `G` samples are within [`MAX_FEED_GAP_US`]; otherwise (and with one class) every
//! sample feeds, `G` = 1 (`FirmwareImage::feed_gap`). So a core that stops finishing its
//! samples (a hung update, an interrupt that never returns) stops the feeds, and the
//! watchdog resets the board [`WATCHDOG_PERIOD_US`] after the last feed. The last feed
//! came at the latest in the hang's own sample (core 1 hung, one sample behind at core 0's
//! feed) and at the earliest in the sample of the class before it, at most `G` samples
//! before: the reset comes at most 1 ms and one sample after the hang began, as with a
//! feed every sample, and more than 1 ms less `G` samples after it (1 ms less a sample
//! with `G` = 1). A healthy board feeds at least every `G` samples, within
//! [`MAX_FEED_GAP_US`]: three quarters of the period or more to spare. Each core's reset
//! handler copies its
//! scratch pair back into its control block before the sample loop; core 0's, when REASON
//! is TIMER (FORCE: a HardFault's reset, below) and SCRATCH4 holds [`NON_REBOOT_MAGIC`], first (before core 1's launch) records
//! one more trip of kind [`FaultKind::Watchdog`] (key [`NO_KEY`], time 0) over the pair of
//! the core that stopped: core 1's when its scratch fault word holds [`BEHIND`] (set by
//! core 0's handler in place of the feed while core 1 was more than a sample behind), else
//! its own, with the key field [`NO_KEY`] for the moment. Each core's reset handler then
//! names the key (below) in its pair before it copies it. A brown-out clears
//! SRAM and the scratch registers: a flash image boots as at power-on, a RAM image is gone
//! and the boot ROM waits in USB boot, the DACs at zero.
//!
//! **Which key hung** (no cycle of the sample interrupt: read at boot). The handler has no
//! loop, and its cost is proven within the period, so a core stops finishing its samples
//! only inside a key's update (a loop that never ends; a fault exception it raises resets
//! the board at once instead, below). Every update's first instruction is the compiler's `PUSH {…, LR}`
//! (`tactus_compiler::thumb::emit`), and the handler pushes nothing (`super::glue`), so the
//! update pushes the return address into its call site at the same place for every key of
//! the core: the word below the exception frame on the handler's stack, the core's
//! *return slot* ([`return_slot`]). SRAM survives a watchdog reset (datasheet 4.7) and
//! nothing the boot runs before the reset handler writes there: the boot ROM uses no stack
//! before its watchdog entry (pico-bootrom `bootrom_rt0.S`, "We DO NOT use any stack prior
//! to possible watchdog entry"), a RAM image's re-entry none, and on a boot from flash the
//! boot ROM's frames and boot2 lie above core 1's stack ([`super::boot2`]; core 1's stack
//! top is [`CORE1_STACK_RESERVE`] below the end of SRAM) and the flash reset handler's
//! stack is SRAM5's top, not core 0's SRAM4. So each core's reset handler, finding a
//! watchdog trip whose key field is still [`NO_KEY`] on its own pair, reads its return
//! slot and looks the value up in its table of call sites (each `BL`'s return address and
//! its key's window slot, in its data after the keys' rest images): a match names that
//! key, anything else [`UNKNOWN_KEY`] (a fault exception of the handler's own code, whose
//! frame overwrites the slot). Then, after its keys' `init`s (whose frames may reach the
//! slot), it clears the slot, so that the word a later reset finds was pushed by an update
//! of this boot or is 0 (no update entered: [`UNKNOWN_KEY`]). What the slot cannot tell
//! apart: a core that stopped *between* two updates names the key it called last; only a
//! handler over its proven budget (a board the budget rejects) could stop there.
//!
//! **A HardFault** (a fault exception: an unaligned store of a key whose ring position a
//! flipped bit left no multiple of 4, a bus fault, an undefined instruction) does not wait
//! for the watchdog's count. Each core's HardFault handler (with the watchdog;
//! `glue::checks::hard_fault_handler`) records one more [`FaultKind::HardFault`] trip on
//! its pair, in its control block and its scratch registers (key [`NO_KEY`], time the
//! core's sample count), and writes the watchdog's CTRL.TRIGGER: the chip resets at once
//! (REASON.FORCE), the DACs cleared by the reset, instead of the core hanging in `B .` with
//! its motors at their last codes for the watchdog's period. Core 0's reset handler counts
//! a [`FaultKind::Watchdog`] trip for REASON.TIMER only, so the HardFault's is the record;
//! each core's reset handler names its key from the return slot as a hung key's (the
//! HardFault's exception frame lies below the faulting update's pushed return address; a
//! fault in the handler's own code overwrites the slot with its frame: [`UNKNOWN_KEY`]).
//! Off the sample path: no cycle of the proven bound. Without the watchdog the HardFault
//! vector is the default handler, `B .`.

/// Kinds of fault, the low byte of the fault word. The codes are stable (the host and the
/// emulator's fault report decode them): new kinds take new codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum FaultKind {
    /// No trip since power-on (the word is 0).
    None = 0,
    /// A sensor word outside its declared range (`sensor key: m in [lo, hi]`, the raw
    /// words of the sensor's fixed-point format): an open or shorted sensor wire reads the
    /// ADC's code 0 or full scale, a converter that stops answering reads all ones. On a
    /// board without converters the checked word is the sensor window's; on a converter
    /// board (`rp2040_io`) it is the word made of the ADC code (`lo + code << shift`).
    SensorRange = 1,
    /// A sensor word that moved further in one sample than the key's physics allows
    /// ([`max_step_raw`]): a jump, a noise burst, an open or short that strikes mid-travel.
    SensorRate = 2,
    /// A key's state word outside its range, as the state check sees it: a mode byte that
    /// is no variant of its mode (`glue::SensorCheck::modes`; a flipped bit in SRAM: the
    /// one state word the update keeps and reads out of range; docs/firmware.md, "Faults").
    StateRange = 3,
    /// The board came back from a watchdog reset (REASON.TIMER or REASON.FORCE set at
    /// boot): a core hung, or stopped finishing its samples, for [`WATCHDOG_PERIOD_US`].
    Watchdog = 4,
    /// A converter core's ADC burst that did not finish within its sample (the burst
    /// check, [`super::io::IoPlan::burst_mark`]): an ADC that stopped answering, its DREQ
    /// gone. Key [`NO_KEY`]: every key of the core; the fault time is the stall's latest
    /// sample, and a stall counts one trip however long it lasts.
    AdcStall = 5,
    /// A fault exception on the core (HardFault: an unaligned access — a key's ring
    /// position a flipped bit left no multiple of 4 —, a bus fault, an undefined
    /// instruction): its handler recorded it (key [`NO_KEY`] until the reset handler names
    /// the key whose update faulted, as a hung key's: "Which key hung"; time the core's
    /// sample count) and reset the board at once through the watchdog's CTRL.TRIGGER
    /// (`glue::checks::hard_fault_handler`), the DACs cleared by the reset.
    HardFault = 6,
}

impl FaultKind {
    /// Every kind, by code.
    pub const ALL: [FaultKind; 7] = [
        FaultKind::None,
        FaultKind::SensorRange,
        FaultKind::SensorRate,
        FaultKind::StateRange,
        FaultKind::Watchdog,
        FaultKind::AdcStall,
        FaultKind::HardFault,
    ];

    /// The kind of code `code`, if it is one.
    pub fn from_code(code: u8) -> Option<FaultKind> {
        FaultKind::ALL.get(usize::from(code)).copied()
    }

    /// Its code, the fault word's low byte.
    pub fn code(self) -> u8 {
        self as u8
    }

    /// Its name in reports (`sensor-range`, …).
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::None => "none",
            FaultKind::SensorRange => "sensor-range",
            FaultKind::SensorRate => "sensor-rate",
            FaultKind::StateRange => "state-range",
            FaultKind::Watchdog => "watchdog",
            FaultKind::AdcStall => "adc-stall",
            FaultKind::HardFault => "hard-fault",
        }
    }
}

/// Why the board last booted: the reset word decoded (module documentation, "The reset
/// word"). A watchdog reset leaves CHIP_RESET as it was and a chip-level reset clears
/// REASON, so REASON decides first (`tactus_rp2040::vreg::HAD_POR`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCause {
    /// The word is 0: no reset handler recorded one (an image older than the word, or a
    /// board whose SRAM was lost and did not boot again).
    Unrecorded,
    /// A power-on or a brown-out (CHIP_RESET.HAD_POR, REASON 0): the RP2040 does not tell
    /// them apart.
    PowerOn,
    /// The RUN pin (CHIP_RESET.HAD_RUN, REASON 0).
    RunPin,
    /// The debug port's PSM restart (CHIP_RESET.HAD_PSM_RESTART, REASON 0).
    DebugPort,
    /// The watchdog: its count reached 0 (REASON.TIMER) or CTRL.TRIGGER (REASON.FORCE).
    Watchdog,
    /// Bits that are none of these.
    Other(u32),
}

impl ResetCause {
    /// The cause of a reset word (REASON | CHIP_RESET).
    pub fn of(word: u32) -> ResetCause {
        use tactus_rp2040::vreg::{HAD_POR, HAD_PSM_RESTART, HAD_RUN};
        use tactus_rp2040::watchdog::{REASON_FORCE, REASON_TIMER};
        if word & (REASON_TIMER | REASON_FORCE) != 0 {
            ResetCause::Watchdog
        } else if word & HAD_POR != 0 {
            ResetCause::PowerOn
        } else if word & HAD_RUN != 0 {
            ResetCause::RunPin
        } else if word & HAD_PSM_RESTART != 0 {
            ResetCause::DebugPort
        } else if word == 0 {
            ResetCause::Unrecorded
        } else {
            ResetCause::Other(word)
        }
    }

    /// Its name in the fault file's `boot` column: `power-on`, `watchdog`, ….
    pub fn name(self) -> &'static str {
        match self {
            ResetCause::Unrecorded => "unrecorded",
            ResetCause::PowerOn => "power-on",
            ResetCause::RunPin => "run-pin",
            ResetCause::DebugPort => "debug-port",
            ResetCause::Watchdog => "watchdog",
            ResetCause::Other(_) => "other",
        }
    }

    /// In reports: `a power-on or brown-out`, `the watchdog`, ….
    pub fn text(self) -> String {
        match self {
            ResetCause::Unrecorded => "not recorded".into(),
            ResetCause::PowerOn => "a power-on or brown-out".into(),
            ResetCause::RunPin => "the RUN pin".into(),
            ResetCause::DebugPort => "the debug port".into(),
            ResetCause::Watchdog => "the watchdog".into(),
            ResetCause::Other(w) => format!("reset word {w:#010x}"),
        }
    }
}

/// The key field of a fault that is no key's (a board's fault; a watchdog trip's until the
/// reset handler names its key).
pub const NO_KEY: u8 = 0xff;

/// The key field of a watchdog trip whose hung key the reset handler could not name: the
/// core's return slot held no return address of an update call (module documentation,
/// "Which key hung").
pub const UNKNOWN_KEY: u8 = 0xfe;

/// Bytes between core 1's stack top and the end of SRAM: boot2's 256 bytes
/// ([`tactus_rp2040::bootrom::BOOT2_LOAD`]) and 768 below them for the boot ROM's own
/// frames on a boot from flash (its stack starts at boot2's load address, pico-bootrom
/// `bootrom.ld`; its path to boot2, `main` and `_flash_boot`, nests a few calls), so that
/// neither reaches core 1's return slot ([`return_slot`]). Core 1's stack keeps 3 KiB.
pub const CORE1_STACK_RESERVE: u32 = 1024;

/// The return slot of a core whose stack top is `stack_top`: the word where an update pushes
/// its return address (module documentation, "Which key hung"), below the 8-word exception
/// frame the sample interrupt's entry pushes at the idle loop's stack pointer, the stack
/// top (8-byte aligned: no padding word, ARMv6-M ARM B1.5.7).
pub fn return_slot(stack_top: u32) -> u32 {
    stack_top - 32 - 4
}

/// The bit of core 1's fault word in the watchdog's scratch register that core 0's handler
/// sets at the end of a sample in which it does not feed the watchdog because core 1 is
/// more than a sample behind (`glue::checks::mark_behind`): after the reset, the watchdog's
/// trip is counted on core 1's record, not core 0's, and the bit cleared. Bit 7 of the
/// kind byte, which no kind's code uses. A board within its budget never sets it: core 1
/// finishes each sample within the sample.
pub const BEHIND: u32 = 0x80;

/// One core's fault record as the host reads it: the fault word and the fault time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FaultWord {
    /// The last trip's kind (`None` when the code is not a kind's: then `code` says it).
    pub kind: Option<FaultKind>,
    /// The fault word's low byte as read.
    pub code: u8,
    /// The tripped key's window slot (on a keyboard's board its index in the board's key
    /// order), [`NO_KEY`] for none.
    pub key: u8,
    /// Trips since power-on, modulo 65,536.
    pub trips: u16,
    /// The core's sample count at the last trip.
    pub at_sample: u32,
    /// The record's reset word (module documentation, "The reset word"; 0 when not read).
    pub reset_word: u32,
}

impl FaultWord {
    /// Decodes a fault word and its time word.
    pub fn decode(word: u32, at_sample: u32) -> FaultWord {
        let code = word as u8;
        FaultWord {
            kind: FaultKind::from_code(code),
            code,
            key: (word >> 8) as u8,
            trips: (word >> 16) as u16,
            at_sample,
            reset_word: 0,
        }
    }

    /// Decodes a whole record: the fault word, the fault time and the reset word.
    pub fn decode_record(record: [u32; 3]) -> FaultWord {
        FaultWord {
            reset_word: record[2],
            ..FaultWord::decode(record[0], record[1])
        }
    }

    /// Why the board last booted, by the reset word.
    pub fn reset_cause(&self) -> ResetCause {
        ResetCause::of(self.reset_word)
    }

    /// The fault word of a record (the inverse of [`FaultWord::decode`] for its first word).
    pub fn encode(kind: FaultKind, key: u8, trips: u16) -> u32 {
        u32::from(kind.code()) | u32::from(key) << 8 | u32::from(trips) << 16
    }

    /// Whether any check ever tripped (the trip count, or a kind, is not 0).
    pub fn tripped(&self) -> bool {
        self.trips != 0 || self.code != 0
    }
}

/// The watchdog's period, µs: 1 ms, 44 samples at 44.1 kHz. A healthy board feeds it at
/// least every [`MAX_FEED_GAP_US`] (every 4 samples on grand88's boards at 133 MHz, where
/// core 0's keys take turns; every sample otherwise), so the period has a four-fold margin
/// or more over the time between feeds and over the start-up between the enabling store
/// and the first feed (tens of µs, `start_alarm_us`, and the first sample of the feeding
/// class); a hung core holds its motor's last DAC code (at most the limiter's peak) for at
/// most this long and a sample before the reset sets it to zero.
pub const WATCHDOG_PERIOD_US: u32 = 1000;

/// The longest time between two feeds of the watchdog on a healthy board, µs, when core 0
/// feeds it in one class of its samples only (`glue::Turns::feed_class`): a quarter of
/// [`WATCHDOG_PERIOD_US`], so that the feeds keep a four-fold margin over the period (11
/// samples at 44.1 kHz; grand88's boards feed every 4 samples at most at 133 MHz, every 5
/// at 200 MHz). A board whose turns would leave a longer gap feeds every sample.
pub const MAX_FEED_GAP_US: u32 = WATCHDOG_PERIOD_US / 4;

/// The value written to the watchdog's LOAD for [`WATCHDOG_PERIOD_US`]: twice the period,
/// since the RP2040's watchdog counts down twice per 1 µs tick (erratum RP2040-E1; the
/// pico-sdk's `watchdog_enable` doubles its value the same way).
pub const WATCHDOG_LOAD: u32 = 2 * WATCHDOG_PERIOD_US;

/// SCRATCH4's value while a flash-booted image's watchdog runs, and after a RAM image's
/// re-entry: pico-sdk's `WATCHDOG_NON_REBOOT_MAGIC` (`hardware_watchdog/watchdog.c`), which
/// is not the boot ROM's entry magic ([`tactus_rp2040::watchdog::BOOT_MAGIC`]): after a
/// reset the boot ROM boots from flash, and the firmware knows its own watchdog fired.
pub const NON_REBOOT_MAGIC: u32 = 0x6ab7_3121;

/// The scratch registers that keep core `core`'s pair across a watchdog reset: (fault
/// word's, fault time's) index n of SCRATCHn.
pub fn scratch(core: usize) -> (u32, u32) {
    let c = 2 * core as u32;
    (c, c + 1)
}

/// The largest speed of a key's (or a pen's) sensed point the checks allow, m/s. A struck
/// *fff* key is met by the finger at up to 3 m/s (`tactus_runtime::player`'s fastest
/// struck level; Askenfelt & Jansson, JASA 88(1), 1990, measured 0.3–0.5 m/s at *mf*,
/// seldom above 1 m/s at *f*), and a thrown key runs ahead of the finger; twice the
/// fastest finger leaves that margin. At 44.1 kHz it is 136 µm per sample, 1.4 % of a
/// 10 mm key's travel.
pub const MAX_SPEED_MPS: f64 = 6.0;

/// The time a tripped key's sensor must read plausibly before the key plays again, in
/// samples at `fs` Hz: 100 ms (4,410 at 44.1 kHz), longer than a wire's contact bounce or
/// a noise burst, short enough to give a key back before the next phrase.
pub fn recovery_samples(fs: f64) -> u32 {
    (fs * 0.1).round().clamp(1.0, f64::from(u16::MAX)) as u32
}

/// The sensor noise the checks allow, as a fraction of the sensor's declared span: every
/// reading may lie up to this far from the true position, either way (uniform, peak),
/// independently each sample. For a 10 mm piano key ±0.2 mm a sample, so two readings a
/// sample apart may differ by 0.4 mm (17.6 m/s of apparent speed at 44.1 kHz) more than
/// the key moved. Declared here and nowhere else: it is the noisiest sensor the budget
/// corpus drives a key with ([`crate::corpus::noisy`]'s top level, `noisy-press-2.0%`),
/// and the noise of a Hall or optical key sensor through a 12-bit ADC is below it (a
/// 10 mm travel over 4,096 codes is 2.4 µm a code: 2 % is ±80 codes). A noisier sensor
/// must be filtered before the firmware, or its keys trip (`sensor-rate`).
pub const SENSOR_NOISE_FRACTION: f64 = 0.02;

/// The largest change of a sensor word over `samples` samples at `fs` Hz (the longest gap
/// between two checks of a key, `glue::Turns`) that the checks accept as plausible: the
/// key's physics ([`MAX_SPEED_MPS`]) over that time plus the sensor's noise on both
/// readings (2 × [`SENSOR_NOISE_FRACTION`] of the span). A sensor whose raw words span
/// `[lo, hi]` for `span_m` metres (its declared range) moves `(hi − lo) / span_m` raw
/// units per metre. For a 10 mm key checked every sample: 136 µm + 400 µm = 536 µm; every
/// 5 samples: 680 µm + 400 µm = 1,080 µm. At least 1.
pub fn max_step_raw(lo: i32, hi: i32, span_m: f64, fs: f64, samples: u32) -> u32 {
    let span_raw = f64::from(hi) - f64::from(lo);
    let per_m = span_raw / span_m.max(1e-9);
    let physics = per_m * MAX_SPEED_MPS * f64::from(samples.max(1)) / fs;
    let noise = 2.0 * SENSOR_NOISE_FRACTION * span_raw;
    (physics + noise)
        .ceil()
        .clamp(1.0, f64::from(u32::MAX >> 2)) as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fault_words_round_trip() {
        for kind in FaultKind::ALL {
            let w = FaultWord::encode(kind, 60, 65535);
            let d = FaultWord::decode(w, 12345);
            assert_eq!(d.kind, Some(kind));
            assert_eq!((d.key, d.trips, d.at_sample), (60, 65535, 12345));
        }
        assert_eq!(FaultWord::decode(0x2a, 0).kind, None);
        assert!(!FaultWord::decode(0, 0).tripped());
    }

    #[test]
    fn reset_words_decode_reason_first() {
        // A watchdog reset of a board that powered on: HAD_POR still set, REASON decides.
        assert_eq!(ResetCause::of(0x101), ResetCause::Watchdog);
        assert_eq!(ResetCause::of(0x102), ResetCause::Watchdog);
        assert_eq!(ResetCause::of(0x100), ResetCause::PowerOn);
        assert_eq!(ResetCause::of(0x1_0000), ResetCause::RunPin);
        assert_eq!(ResetCause::of(0x10_0000), ResetCause::DebugPort);
        assert_eq!(ResetCause::of(0), ResetCause::Unrecorded);
        assert_eq!(ResetCause::of(0x8), ResetCause::Other(8));
    }

    #[test]
    fn a_piano_key_reading_moves_536_um_per_sample_at_most() {
        // 10 mm in Q37 (raw words per metre 2^37): 136 µm of motion at 6 m/s, 2 × 0.2 mm
        // of noise.
        let hi = (0.01f64 * 2f64.powi(37)) as i32;
        let l = max_step_raw(0, hi, 0.01, 44100.0, 1);
        let um = f64::from(l) / 2f64.powi(37) * 1e6;
        assert!((um - 536.05).abs() < 0.01, "{um} µm");
        assert_eq!(recovery_samples(44100.0), 4410);
        assert_eq!(WATCHDOG_LOAD, 2000);
    }
}
