//! The converters a board's firmware drives: the data-sheet facts of each part the image has
//! a driver for, and the one mapping between a key's position and an ADC code.
//!
//! A force-feedback key needs a position reading and a motor command every sample. The
//! RP2040's own ADC (four inputs, 12 bits, 500 kS/s in all) cannot give six or eight keys
//! 44,100 readings a second each, so a board names external converters in its file
//! (`[converters]`, [`Converters`]): per core one multi-channel SAR ADC for the key
//! positions and one multi-channel DAC for the motor currents, each on its own PIO state
//! machine. The parts are SPI converters rather than a TDM audio codec (MIKEY used a PC
//! sound-board codec): an audio codec's inputs are AC-coupled (a high-pass filter of a few
//! hertz, and its delta-sigma decimation filter delays a sample by tens of samples), while
//! a key resting half-way down is a DC level that must read the same for seconds, and a
//! control loop wants the sample of *now*. A SAR ADC samples at an edge its master chooses
//! (the chip select) and converts in under a microsecond.
//!
//! The numbers here are the data sheets' (each field says where from); the firmware's
//! frame timing ([`AdcPart::frame_period_min_s`], the SCLK limits) and the emulator's device
//! models check against the same fields, so a frame the firmware sends faster than the part
//! allows is an error in the emulator, not a silent success.
//!
//! **Positions as codes.** A key's sensor word is the travel in the program's Q-format
//! (`tactus_compiler::fixed`), 32 bits; the ADC gives 16. The analogue front end scales the
//! key's travel (the sensor's declared range) onto the ADC's input range so that one code
//! step is `2^shift` LSB of the sensor word ([`AdcScale`]): the firmware turns a code into
//! the word with one shift (and an add when the range does not start at 0), and every host
//! engine that plays "through the converters" quantises a position the same way, so the
//! emulated board and the host see the same key positions bit for bit.

use serde::{Deserialize, Serialize};

/// A multi-channel SAR ADC the firmware drives over SPI (position sensors).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdcPart {
    /// The part's name as a board file gives it.
    pub name: &'static str,
    /// Input channels (key position sensors) per chip.
    pub channels: u32,
    /// Resolution, bits.
    pub bits: u32,
    /// Bits per SPI frame (chip select low): the 16-bit command in, then the 16-bit
    /// conversion result out.
    pub frame_bits: u32,
    /// Highest SCLK frequency, Hz.
    pub sclk_max_hz: f64,
    /// Longest conversion, s: the result must be complete by the 16th SCLK falling edge of
    /// its frame, which the SCLK limit guarantees.
    pub conversion_max_s: f64,
    /// Shortest interval between two frames' chip-select falling edges (the sample
    /// instants), s: the aggregate throughput's reciprocal.
    pub frame_period_min_s: f64,
    /// SPI mode: clock polarity and phase (CPOL, CPHA).
    pub spi_mode: (u8, u8),
    /// Where the numbers come from.
    pub source: &'static str,
}

/// A multi-channel DAC the firmware drives over SPI (motor currents, through a
/// transconductance amplifier per key).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DacPart {
    /// The part's name as a board file gives it.
    pub name: &'static str,
    /// Output channels (motors) per chip.
    pub channels: u32,
    /// Resolution, bits.
    pub bits: u32,
    /// Bits per SPI frame (SYNC low); the output updates on the frame's last SCLK falling
    /// edge.
    pub frame_bits: u32,
    /// Highest SCLK frequency, Hz.
    pub sclk_max_hz: f64,
    /// Shortest SYNC high time between two frames, s.
    pub sync_high_min_s: f64,
    /// Shortest setup from SYNC falling to the first SCLK falling edge, s.
    pub sync_setup_min_s: f64,
    /// SPI mode: clock polarity and phase (CPOL, CPHA).
    pub spi_mode: (u8, u8),
    /// Where the numbers come from.
    pub source: &'static str,
}

/// TI ADS8688: 8 channels, 16 bits, 500 kS/s in all, DC-coupled single-supply inputs
/// (0 to 5.12 V with the 1.25 × VREF range), SPI with an auto-scan sequencer.
///
/// Data sheet TI SBAS582 (ADS8684/ADS8688): "Timing Requirements: Serial Interface"
/// (f_SCLK ≤ 17 MHz), "Electrical Characteristics" (t_CONV ≤ 850 ns; 500 kS/s maximum
/// throughput, hence ≥ 2 µs from one CS falling edge to the next), "Data Acquisition
/// Example" (the input is sampled at the CS falling edge; the 16-bit command is latched on
/// the first 16 SCLK falling edges; the result of the same frame's sample leaves MSB first
/// from the 16th falling edge, so a frame is 32 SCLKs), "Multiplexer" (in AUTO_RST mode the
/// channel advances on every CS falling edge through the enabled channels). SPI mode 1.
pub const ADS8688: AdcPart = AdcPart {
    name: "ADS8688",
    channels: 8,
    bits: 16,
    frame_bits: 32,
    sclk_max_hz: 17e6,
    conversion_max_s: 850e-9,
    frame_period_min_s: 2e-6,
    spi_mode: (0, 1),
    source: "TI SBAS582 (ADS8684/ADS8688): Timing Requirements, Electrical Characteristics, \
             Data Acquisition Example",
};

/// TI DAC8568: 8 channels, 16 bits, 50 MHz SPI, straight binary, 32-bit frames.
///
/// Data sheet TI SBAS430F (DAC7568/DAC8168/DAC8568): 7.3 "Timing Requirements" (t2 SCLK
/// cycle ≥ 20 ns; t4 SYNC high ≥ 80 ns; t5 SYNC to SCLK falling edge setup ≥ 13 ns; t8
/// SCLK falling edge to SYNC rising ≥ 10 ns), 8.2.6 "Input Shift Register" (32 bits:
/// prefix DB31–DB28, control DB27–DB24, address DB23–DB20, data DB19–DB4, feature bits
/// DB3–DB0, ignored for a data write), pin functions (data clocked in on SCLK falling
/// edges, "the DAC output updates following the 32nd clock"), 8.2.8 "Power-on Reset to Zero
/// Scale or Midscale" (a midscale part holds every motor at 0 A until the first frame).
/// With an external 2.5 V reference on VREFIN nothing needs setting up at boot.
pub const DAC8568: DacPart = DacPart {
    name: "DAC8568",
    channels: 8,
    bits: 16,
    frame_bits: 32,
    sclk_max_hz: 50e6,
    sync_high_min_s: 80e-9,
    sync_setup_min_s: 13e-9,
    spi_mode: (0, 1),
    source: "TI SBAS430F (DAC8568): 7.3 Timing Requirements, 8.2.6 Input Shift Register",
};

/// Every ADC the firmware has a driver for.
pub const ADCS: &[AdcPart] = &[ADS8688];

/// Every DAC the firmware has a driver for.
pub const DACS: &[DacPart] = &[DAC8568];

/// A board's converters as its file names them: per core one ADC (key positions) and one
/// DAC (motor currents), each on its own PIO state machine of the core's PIO block (core 0
/// PIO0, core 1 PIO1), with the GPIO pins they are wired to.
///
/// ```toml
/// [converters]
/// adc = "ADS8688"   # per core: 8 position channels, 16 bits
/// dac = "DAC8568"   # per core: 8 motor channels, 16 bits
/// # per core, core 0 first: [SCLK, CS, SDI, SDO] and [SCLK, SYNC, SDI]; CS (SYNC) is SCLK + 1,
/// # the pair a state machine's side-set drives
/// adc_pins = [[2, 3, 4, 5], [10, 11, 12, 13]]
/// dac_pins = [[6, 7, 8], [14, 15, 16]]
/// ```
///
/// Key *k* of a core (in the order the image places its keys) reads ADC channel *k* and
/// drives DAC channel *k*; a key with several sensors (a pen) or force words takes as many
/// consecutive channels.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(deny_unknown_fields)]
pub struct Converters {
    /// The ADC part, one of [`ADCS`] by name.
    pub adc: String,
    /// The DAC part, one of [`DACS`] by name.
    pub dac: String,
    /// Per core, the ADC's GPIOs: SCLK, CS, SDI (the RP2040's MOSI), SDO (its MISO).
    pub adc_pins: Vec<[u32; 4]>,
    /// Per core, the DAC's GPIOs: SCLK, SYNC, SDI.
    pub dac_pins: Vec<[u32; 3]>,
}

/// GPIOs of the RP2040 (pins 0–29).
pub const GPIOS: u32 = 30;

impl Converters {
    /// The ADC part (`None` for a name no driver exists for; the board reader rejects it).
    pub fn adc_part(&self) -> Option<&'static AdcPart> {
        ADCS.iter().find(|p| p.name.eq_ignore_ascii_case(&self.adc))
    }

    /// The DAC part (`None` for a name no driver exists for; the board reader rejects it).
    pub fn dac_part(&self) -> Option<&'static DacPart> {
        DACS.iter().find(|p| p.name.eq_ignore_ascii_case(&self.dac))
    }

    /// Checks that the firmware drives both parts and that the pins can be wired as its
    /// drivers need on a board of `cores` cores: one set per core, GPIOs 0–29, CS (SYNC)
    /// next above SCLK (the side-set pair), no pin used twice. Errors name `file` and the
    /// field.
    pub fn check(&self, file: &str, cores: u32) -> Result<(), String> {
        let names = |l: &[&str]| l.join(", ");
        if self.adc_part().is_none() {
            return Err(format!(
                "{file}: `converters.adc` = {:?}: the firmware has no driver for that ADC \
                 (it drives: {})",
                self.adc,
                names(&ADCS.iter().map(|p| p.name).collect::<Vec<_>>())
            ));
        }
        if self.dac_part().is_none() {
            return Err(format!(
                "{file}: `converters.dac` = {:?}: the firmware has no driver for that DAC \
                 (it drives: {})",
                self.dac,
                names(&DACS.iter().map(|p| p.name).collect::<Vec<_>>())
            ));
        }
        let mut used = std::collections::BTreeMap::new();
        let sets = self
            .adc_pins
            .iter()
            .map(|p| ("adc_pins", &p[..], ["SCLK", "CS", "SDI", "SDO"].as_slice()))
            .chain(
                self.dac_pins
                    .iter()
                    .map(|p| ("dac_pins", &p[..], ["SCLK", "SYNC", "SDI"].as_slice())),
            );
        for (field, n) in [
            ("adc_pins", self.adc_pins.len()),
            ("dac_pins", self.dac_pins.len()),
        ] {
            if n != cores as usize {
                return Err(format!(
                    "{file}: `converters.{field}` has {n} pin sets; the board has {cores} \
                     cores, each with its own converters (one set per core, core 0 first)"
                ));
            }
        }
        for (core, (field, pins, names)) in sets.enumerate() {
            let core = core % cores.max(1) as usize;
            for (&pin, name) in pins.iter().zip(names) {
                if pin >= GPIOS {
                    return Err(format!(
                        "{file}: `converters.{field}`: core {core}'s {name} on GPIO {pin}; \
                         the RP2040 has GPIOs 0 to {}",
                        GPIOS - 1
                    ));
                }
                if let Some(other) = used.insert(pin, format!("core {core}'s {field} {name}")) {
                    return Err(format!(
                        "{file}: `converters.{field}`: GPIO {pin} is core {core}'s {name} \
                         and {other}"
                    ));
                }
            }
            if pins[1] != pins[0] + 1 {
                return Err(format!(
                    "{file}: `converters.{field}`: core {core}'s {} is GPIO {}, SCLK GPIO {}: \
                     the driver's state machine drives them as a side-set pair, so {} must \
                     be GPIO {}",
                    names[1],
                    pins[1],
                    pins[0],
                    names[1],
                    pins[0] + 1
                ));
            }
        }
        Ok(())
    }
}

/// How a sensor word and an ADC code correspond: the analogue front end maps the sensor's
/// declared range onto the ADC's codes so that code `c` reads as the sensor word
/// `lo + (c << shift)` (`lo` and the raw range from the program's format). `shift` is the
/// smallest that covers the whole range with the ADC's codes, so a key is read to within
/// `2^shift` LSB of its word (at least half the ADC's codes span the range).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AdcScale {
    /// The sensor word of code 0 (the range's lower end), raw.
    pub lo: i32,
    /// Left shift from a code to a word step.
    pub shift: u32,
    /// The largest code the range holds (`(hi − lo) >> shift`).
    pub max_code: u32,
}

impl AdcScale {
    /// The scale of a sensor whose raw words span `[lo, hi]` (`lo ≤ hi`) on a `bits`-bit
    /// ADC (1 to 31 bits).
    pub fn new(lo: i32, hi: i32, bits: u32) -> AdcScale {
        let span = (i64::from(hi) - i64::from(lo)).max(0) as u64;
        let full = (1u64 << bits.clamp(1, 31)) - 1;
        let mut shift = 0;
        while full << shift < span {
            shift += 1;
        }
        AdcScale {
            lo,
            shift,
            max_code: (span >> shift) as u32,
        }
    }

    /// The code the ADC gives for a key whose exact sensor word is `word`: the nearest code
    /// step, within the range.
    pub fn code(&self, word: i32) -> u32 {
        let off = (i64::from(word) - i64::from(self.lo)).max(0);
        let half = if self.shift == 0 {
            0
        } else {
            1i64 << (self.shift - 1)
        };
        (((off + half) >> self.shift) as u32).min(self.max_code)
    }

    /// The sensor word the firmware makes of `code`: `lo + (code << shift)`.
    pub fn word(&self, code: u32) -> i32 {
        (i64::from(self.lo) + (i64::from(code.min(self.max_code)) << self.shift)) as i32
    }

    /// `word` as the ADC and the firmware deliver it: [`AdcScale::word`] of
    /// [`AdcScale::code`].
    pub fn quantise(&self, word: i32) -> i32 {
        self.word(self.code(word))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scales_cover_the_range_with_the_fewest_shifts() {
        // A 10 mm key in Q37 (0.01 · 2^37 ≈ 1.37e9 raw): 2^15 per code, 41943 codes.
        let hi = (0.01f64 * 2f64.powi(37)) as i32;
        let s = AdcScale::new(0, hi, 16);
        assert_eq!(s.shift, 15);
        assert!(s.max_code > 32768 && s.max_code < 65536, "{s:?}");
        assert_eq!(s.word(s.max_code), (s.max_code as i32) << 15);
        assert!(s.word(s.max_code) <= hi);
        // Nearest step, clamped to the range.
        assert_eq!(s.code(0), 0);
        assert_eq!(s.code((1 << 15) - 1), 1);
        assert_eq!(s.code((1 << 14) - 1), 0);
        assert_eq!(s.code(i32::MAX), s.max_code);
        assert_eq!(s.code(-5), 0);
        for w in [0, 1, 12345, 1 << 20, hi / 3, hi] {
            let q = s.quantise(w);
            assert!((q - w).abs() <= 1 << 14, "{w} → {q}");
            assert_eq!(s.quantise(q), q);
        }
        // A narrow range needs no shift and loses nothing.
        let n = AdcScale::new(-100, 900, 16);
        assert_eq!((n.shift, n.max_code), (0, 1000));
        assert_eq!(n.quantise(123), 123);
        // The whole i32 range.
        let w = AdcScale::new(i32::MIN, i32::MAX, 16);
        assert_eq!(w.shift, 17);
        assert_eq!(
            i64::from(w.word(w.max_code)),
            i64::from(i32::MIN) + (i64::from(w.max_code) << 17)
        );
    }

    #[test]
    fn converters_name_the_parts_the_firmware_drives() {
        let ok = Converters {
            adc: "ADS8688".into(),
            dac: "dac8568".into(),
            adc_pins: vec![[2, 3, 4, 5], [10, 11, 12, 13]],
            dac_pins: vec![[6, 7, 8], [14, 15, 16]],
        };
        assert!(ok.check("b.toml", 2).is_ok());
        assert_eq!(ok.adc_part(), Some(&ADS8688));
        let bad = Converters {
            adc: "PCM3168A".into(),
            ..ok.clone()
        };
        let e = bad.check("b.toml", 2).unwrap_err();
        assert!(
            e.contains("b.toml") && e.contains("converters.adc") && e.contains("ADS8688"),
            "{e}"
        );
        let bad = Converters {
            dac: "AD5686R".into(),
            ..ok.clone()
        };
        let e = bad.check("b.toml", 2).unwrap_err();
        assert!(e.contains("converters.dac") && e.contains("DAC8568"), "{e}");
        // Pins: one set per core, in range, CS next to SCLK, each pin once.
        let e = ok.check("b.toml", 1).unwrap_err();
        assert!(e.contains("`converters.adc_pins` has 2 pin sets"), "{e}");
        let mut bad = ok.clone();
        bad.dac_pins[1] = [14, 15, 30];
        let e = bad.check("b.toml", 2).unwrap_err();
        assert!(
            e.contains("converters.dac_pins") && e.contains("GPIO 30"),
            "{e}"
        );
        let mut bad = ok.clone();
        bad.adc_pins[0] = [2, 4, 3, 5];
        let e = bad.check("b.toml", 2).unwrap_err();
        assert!(
            e.contains("converters.adc_pins") && e.contains("must be GPIO 3"),
            "{e}"
        );
        let mut bad = ok;
        bad.dac_pins[0] = [6, 7, 5];
        let e = bad.check("b.toml", 2).unwrap_err();
        assert!(
            e.contains("GPIO 5 is core 0's SDI and core 0's adc_pins SDO"),
            "{e}"
        );
    }
}
