//! Keyboard layouts and boards as data files (TOML), so a user can describe their own.
//!
//! A **layout** says which instrument sits on which keys, how params vary across them, and
//! — optionally — on which boards the keys sit (a keyboard is a set of boards, each a
//! microcontroller with a few keys; `tactus budget` plans them when the layout does not):
//!
//! ```toml
//! name = "grand88"
//! board_kind = "rp2040"         # optional: a built-in board or a board file (default rp2040)
//! [[range]]
//! keys = [21, 108]              # MIDI key numbers, inclusive (A0 … C8)
//! instrument = "grand_piano"    # a built-in name or a path relative to the layout file
//! params = { G = "0.15 N" }     # overrides for every key of the range
//! grade = [ { param = "M_h", from = "11 g", to = "3.5 g" } ]   # linear from first to last key
//! [[board]]                     # optional, all or none: contiguous key ranges, inclusive
//! keys = [21, 22]
//! ```
//!
//! A **board** kind gives the machine: clock, cores, sample rate (see `boards/rp2040.toml`).
//! What a key costs on it is not a board field: the budget prices each board's actual
//! sample interrupt (`tactus_firmware::boards`).
//!
//! Errors name the file and the field (TOML's own messages carry line and column).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A keyboard layout.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Layout {
    /// Layout name.
    pub name: String,
    /// The board kind the keys run on: a built-in board name or a board file (relative to
    /// the layout file); `None`: the command's default.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board_kind: Option<String>,
    /// Key ranges, in any order, not overlapping.
    #[serde(rename = "range")]
    pub ranges: Vec<KeyRange>,
    /// The boards, each a contiguous range of keys; empty: to be planned.
    #[serde(rename = "board", default, skip_serializing_if = "Vec::is_empty")]
    pub boards: Vec<BoardKeys>,
}

/// One board of a layout: the keys wired to it.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BoardKeys {
    /// First and last MIDI key, inclusive (exactly two numbers).
    #[serde(deserialize_with = "pair")]
    pub keys: [u8; 2],
}

/// `[first, last]`: exactly two key numbers (a TOML array of another length is an error,
/// not truncated).
fn pair<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[u8; 2], D::Error> {
    let v: Vec<u8> = Vec::deserialize(d)?;
    match v.as_slice() {
        [a, b] => Ok([*a, *b]),
        _ => Err(serde::de::Error::custom(format!(
            "`keys` must be [first, last] (two MIDI key numbers), got {} numbers",
            v.len()
        ))),
    }
}

/// One range of keys with one instrument.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct KeyRange {
    /// First and last MIDI key, inclusive (exactly two numbers).
    #[serde(deserialize_with = "pair")]
    pub keys: [u8; 2],
    /// Built-in instrument name or a path (relative to the layout file).
    pub instrument: String,
    /// Param overrides for every key: name → value with unit (`"0.15 N"`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub params: BTreeMap<String, String>,
    /// Params graded linearly from the first key to the last.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub grade: Vec<Grade>,
}

/// A param graded linearly across a key range.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Grade {
    /// Param name.
    pub param: String,
    /// Value at the range's first key, with unit (`"11 g"`).
    pub from: String,
    /// Value at the range's last key, same unit (`"3.5 g"`).
    pub to: String,
}

/// One key's instrument and overrides, resolved from a layout.
#[derive(Clone, Debug, PartialEq)]
pub struct KeyAssignment {
    /// MIDI key number.
    pub key: u8,
    /// Instrument (built-in name or path resolved against the layout's folder).
    pub instrument: String,
    /// `--param`-style overrides: (name, value with unit).
    pub params: Vec<(String, String)>,
}

/// A board kind as a board file describes it (`boards/*.toml`): the machine, nothing about
/// the code (what a key costs is the static analysis of the board's actual sample
/// interrupt). Not the emulated machine (`tactus_emulator::Board`) nor the budget report's
/// summary of it (`tactus_firmware::verdict::BoardKind`).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BoardSpec {
    /// Board name.
    pub name: String,
    /// Core clock, Hz.
    pub clock_hz: f64,
    /// Number of cores that run key updates (1 to [`MAX_CORES`]).
    pub cores: u32,
    /// Sensor sample rate, Hz.
    pub sample_rate_hz: f64,
    /// The core voltage the firmware sets before it switches the clock to the PLL, V
    /// (the RP2040's regulator, VREG.VSEL: 0.80 to 1.30 V in 0.05 V steps); absent, the
    /// regulator stays at its reset value, 1.10 V. The RP2040 needs 1.15 V above 133 MHz
    /// (pico-sdk 2.1.1, for its 200 MHz clock).
    #[serde(default)]
    pub core_voltage_v: Option<f64>,
    /// The converters the firmware drives (per core one ADC for the key positions and one
    /// DAC for the motor currents, [`crate::converters`]); absent, the firmware leaves the
    /// sensor and DAC words in SRAM for the host (the emulator's own harness) to fill and
    /// read.
    #[serde(default)]
    pub converters: Option<crate::converters::Converters>,
}

/// Most cores a board file may declare (the RP2040 image runs on 1 or 2; a larger count
/// is rejected when the board is read rather than allocated for).
pub const MAX_CORES: u32 = 64;

impl BoardSpec {
    /// The board's ADC and DAC parts, when its file names converters (the reader checked
    /// that the firmware drives both).
    pub fn converter_parts(
        &self,
    ) -> Option<(
        &'static crate::converters::AdcPart,
        &'static crate::converters::DacPart,
    )> {
        let c = self.converters.as_ref()?;
        Some((c.adc_part()?, c.dac_part()?))
    }

    /// Cycles available per sample per core: the shortest interval between two sample
    /// ticks, [`deadline_cycles`] (3,015 at 133 MHz and 44.1 kHz).
    pub fn cycles_per_sample(&self) -> u64 {
        deadline_cycles(self.clock_hz, self.sample_rate_hz)
    }

    /// [`Board::core_voltage_v`] in millivolts (the reader checked it is a whole number of
    /// 50 mV steps).
    pub fn core_mv(&self) -> Option<u32> {
        self.core_voltage_v.map(|v| (v * 1000.0).round() as u32)
    }
}

/// Cycles from one sample tick to the next in the worst case, for a `clock_hz` core clock
/// and an `fs_hz` sample rate (both positive; the board file's reader checks them):
/// `⌊clock/fs⌋`. The firmware's sample tick is each core's SysTick counting the processor
/// clock, its period alternating between `⌊clock/fs⌋` and one cycle more so that tick `n`
/// falls on cycle `first + ⌊n·clock/fs⌋` ([`tick_cycle`]; `firmware/src/image/glue.rs`,
/// `Tick`): the shorter period is the deadline (3,015 cycles at 133 MHz and 44.1 kHz,
/// whose mean period is 3,015.87; 4,535 at 200 MHz). The one definition of the per-sample
/// deadline: the budget, the board planner, the image's run, the ELF runner and
/// `tactus play` all use it.
pub fn deadline_cycles(clock_hz: f64, fs_hz: f64) -> u64 {
    let whole = |v: f64| v.fract() == 0.0 && (1.0..=u64::MAX as f64 / 2.0).contains(&v);
    if whole(clock_hz) && whole(fs_hz) {
        clock_hz as u64 / fs_hz as u64
    } else {
        (clock_hz / fs_hz).floor() as u64
    }
}

/// Core clock cycle of sample tick `n` when tick 0 is at cycle `first`:
/// `first + ⌊n·clock/fs⌋` (`fs_hz` > 0), as each core's SysTick ticks
/// ([`deadline_cycles`]).
pub fn tick_cycle(first: u64, n: u64, clock_hz: u64, fs_hz: u32) -> u64 {
    first + (n as u128 * clock_hz as u128 / u128::from(fs_hz.max(1))) as u64
}

/// The first core clock cycle at which the RP2040 timer (1 MHz) reads `us` microseconds,
/// at a `clock_hz` core clock: `⌈us · clock / 10⁶⌉`.
pub fn cycle_at_us(us: u64, clock_hz: u64) -> u64 {
    (us as u128 * clock_hz as u128).div_ceil(1_000_000) as u64
}

/// The largest layout, board file or key map read, bytes: far beyond any real one (an
/// 88-key layout with a board per key is a few KB), and a bound on what a mistaken path
/// (`/dev/zero`, a recording) can make a command hold.
pub const MAX_TEXT_BYTES: u64 = 1 << 20;

/// Reads a small text file (a layout, a board file, a key map) of at most
/// [`MAX_TEXT_BYTES`], without reading more than that whatever the file claims.
///
/// Errors: a message naming the file (it cannot be read, is longer, or is not UTF-8).
pub fn read_text(path: &Path) -> Result<String, String> {
    crate::files::read_text_bounded(path, MAX_TEXT_BYTES, "a layout, board file or key map")
        .map_err(|e| e.to_string())
}

fn read(path: &Path) -> Result<String, String> {
    read_text(path)
}

/// Parses a board from TOML text; `name` is used in errors. The fields only: a board the
/// firmware can be built for is checked by `tactus_firmware::boards::read_board`, the one
/// reader of a board file, which starts here.
pub fn parse_board(text: &str, name: &str) -> Result<BoardSpec, String> {
    let b: BoardSpec = toml::from_str(text).map_err(|e| {
        let e = e.to_string();
        match ["io_cycles_per_key", "isr_overhead_cycles"]
            .iter()
            .find(|f| e.contains(*f))
        {
            Some(f) => format!(
                "{name}: `{f}` is no longer a board field: the budget prices each board's \
                 actual sample interrupt (delete the line)"
            ),
            None => format!("{name}: {e}"),
        }
    })?;
    for (field, v) in [
        ("clock_hz", b.clock_hz),
        ("sample_rate_hz", b.sample_rate_hz),
    ] {
        if !(v.is_finite() && v > 0.0) {
            return Err(format!(
                "{name}: `{field}` must be a positive number, got {v}"
            ));
        }
    }
    if b.cores == 0 || b.cores > MAX_CORES {
        return Err(format!(
            "{name}: `cores` must be 1 to {MAX_CORES}, got {}",
            b.cores
        ));
    }
    if b.clock_hz > 1e12 || b.sample_rate_hz < 1.0 {
        return Err(format!(
            "{name}: need `clock_hz` ≤ 1 THz and `sample_rate_hz` ≥ 1 Hz, got {} and {}",
            b.clock_hz, b.sample_rate_hz
        ));
    }
    if let Some(v) = b.core_voltage_v {
        let steps = v * 20.0;
        if !(0.8..=1.3).contains(&v) || (steps - steps.round()).abs() > 1e-6 {
            return Err(format!(
                "{name}: `core_voltage_v` must be one of the RP2040 regulator's voltages, 0.80 \
                 to 1.30 V in steps of 0.05 V (VREG.VSEL, RP2040 datasheet 2.10.7), got {v}"
            ));
        }
    }
    if b.sample_rate_hz > b.clock_hz {
        return Err(format!(
            "{name}: `sample_rate_hz` ({}) exceeds `clock_hz` ({})",
            b.sample_rate_hz, b.clock_hz
        ));
    }
    if let Some(c) = &b.converters {
        c.check(name, b.cores)?;
    }
    Ok(b)
}

/// Reads a layout file and resolves it key by key. Errors name the file and the field.
pub fn read_layout(path: &Path) -> Result<(Layout, Vec<KeyAssignment>), String> {
    let name = path.display().to_string();
    let layout = parse_layout(&read(path)?, &name)?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let keys = assign(&layout, &name, &dir)?;
    Ok((layout, keys))
}

/// Parses a layout from TOML text; `name` is used in errors.
pub fn parse_layout(text: &str, name: &str) -> Result<Layout, String> {
    toml::from_str(text).map_err(|e| format!("{name}: {e}"))
}

/// `layout` as a layout file: `header` as comment lines (each line of it, control
/// characters escaped, so no name can end a comment early), then the TOML. The text is
/// read back before it is returned: what `--write-plan` writes, `budget` and `play` read as
/// the same layout.
///
/// Errors: a layout TOML cannot hold (never for a [`Layout`] read from a file), or text
/// that does not read back as `layout` (a bug, reported rather than written).
pub fn layout_text(layout: &Layout, header: &str) -> Result<String, String> {
    let body = toml::to_string(layout).map_err(|e| format!("cannot write the layout: {e}"))?;
    let mut text = String::new();
    for line in header.lines() {
        text.push_str("# ");
        text.extend(line.chars().flat_map(|c| match c.is_control() {
            true => c.escape_debug().collect::<Vec<_>>(),
            false => vec![c],
        }));
        text.push('\n');
    }
    text.push_str(&body);
    match parse_layout(&text, "the written layout") {
        Ok(back) if back == *layout => Ok(text),
        Ok(_) => Err("the written layout reads back differently".into()),
        Err(e) => Err(format!("the written layout does not read back: {e}")),
    }
}

/// Resolves a layout to one assignment per key, sorted by key. Instrument paths that exist
/// relative to `dir` are made relative to it; other names are kept (built-ins).
pub fn assign(layout: &Layout, name: &str, dir: &Path) -> Result<Vec<KeyAssignment>, String> {
    if layout.ranges.is_empty() {
        return Err(format!(
            "{name}: `range`: the layout lists no keys (it needs at least one `[[range]]` with \
             `keys = [first, last]` and an `instrument`)"
        ));
    }
    let mut out: BTreeMap<u8, (usize, KeyAssignment)> = BTreeMap::new();
    for (ri, r) in layout.ranges.iter().enumerate() {
        let [a, b] = r.keys;
        if a > b || b > 127 {
            return Err(format!("{name}: range {}: `keys` must be [first, last] with first ≤ last ≤ 127, got [{a}, {b}]", ri + 1));
        }
        let local: PathBuf = dir.join(&r.instrument);
        let instrument = if local.exists() {
            local.display().to_string()
        } else if r.instrument.contains(['/', '\\']) || r.instrument.ends_with(".tactus") {
            // A path that does not exist is an error, never a built-in of the same stem.
            return Err(format!(
                "{name}: range {}: `instrument` = {:?}: no such file ({} does not exist; \
                 built-in instruments are named without a path or extension)",
                ri + 1,
                r.instrument,
                local.display()
            ));
        } else {
            r.instrument.clone()
        };
        let grades: Vec<(String, f64, f64, String)> = r
            .grade
            .iter()
            .map(|g| {
                let (x, ux) = split_value(&g.from).ok_or_else(|| {
                    format!(
                        "{name}: range {}: grade `{}`: `from` = {:?} is not a finite number with a unit",
                        ri + 1,
                        g.param,
                        g.from
                    )
                })?;
                let (y, uy) = split_value(&g.to).ok_or_else(|| {
                    format!(
                        "{name}: range {}: grade `{}`: `to` = {:?} is not a finite number with a unit",
                        ri + 1,
                        g.param,
                        g.to
                    )
                })?;
                if ux != uy {
                    return Err(format!(
                        "{name}: range {}: grade `{}`: `from` is in {ux:?} but `to` in {uy:?}",
                        ri + 1,
                        g.param
                    ));
                }
                Ok((g.param.clone(), x, y, ux))
            })
            .collect::<Result<_, String>>()?;
        for k in a..=b {
            if let Some((other, _)) = out.get(&k) {
                return Err(format!(
                    "{name}: key {k} is in range {} and range {}",
                    other + 1,
                    ri + 1
                ));
            }
            let mut params: Vec<(String, String)> = r
                .params
                .iter()
                .map(|(p, v)| (p.clone(), v.clone()))
                .collect();
            let u = if b == a {
                0.0
            } else {
                f64::from(k - a) / f64::from(b - a)
            };
            for (p, x, y, unit) in &grades {
                let v = x + (y - x) * u;
                if !v.is_finite() {
                    return Err(format!(
                        "{name}: range {}: grade `{p}`: the value at key {k} is beyond f64 \
                         (from {x:e} to {y:e})",
                        ri + 1
                    ));
                }
                params.push((p.clone(), format!("{v} {unit}").trim().to_string()));
            }
            out.insert(
                k,
                (
                    ri,
                    KeyAssignment {
                        key: k,
                        instrument: instrument.clone(),
                        params,
                    },
                ),
            );
        }
    }
    Ok(out.into_values().map(|(_, a)| a).collect())
}

/// The one rule of which keys share a program: keys with the same instrument and the same
/// params (name and value, in order) are one *set*. Returns, in the order of each set's
/// first key in `keys`, what `make` gives for that first key, and for every key the index of
/// its set. `make` runs once per set, so a set is lowered (and its diagnostics reported)
/// once however many keys it has.
///
/// Used by `tactus_host::keyboard::compile` (the toolchain's keyboard) and
/// `tactus_firmware::image::compile_layout` (the firmware's tests and benches), so both
/// share the same programs among the same keys.
///
/// Errors: the first error `make` returns, unchanged.
pub fn group_sets<'k, T, E>(
    keys: &'k [KeyAssignment],
    mut make: impl FnMut(&'k KeyAssignment) -> Result<T, E>,
) -> Result<(Vec<T>, Vec<usize>), E> {
    type Id<'a> = (&'a str, &'a [(String, String)]);
    let mut seen: BTreeMap<Id, usize> = BTreeMap::new();
    let mut sets = Vec::new();
    let mut index = Vec::with_capacity(keys.len());
    for k in keys {
        let id = (k.instrument.as_str(), k.params.as_slice());
        let i = match seen.get(&id) {
            Some(&i) => i,
            None => {
                sets.push(make(k)?);
                seen.insert(id, sets.len() - 1);
                sets.len() - 1
            }
        };
        index.push(i);
    }
    Ok((sets, index))
}

/// The layout's explicit boards checked against its resolved `keys`: per `[[board]]`, in
/// file order, the MIDI keys on it (ascending). `None` when the layout lists no boards (they
/// are to be planned).
///
/// Errors name the file and the board: `keys` not `[first, last]` with first ≤ last ≤ 127,
/// two boards sharing a key, a board with no key of the layout, a key of the layout on no
/// board.
pub fn board_keys(
    layout: &Layout,
    name: &str,
    keys: &[KeyAssignment],
) -> Result<Option<Vec<Vec<u8>>>, String> {
    if layout.boards.is_empty() {
        return Ok(None);
    }
    let mut owner: BTreeMap<u8, usize> = BTreeMap::new();
    let mut out = Vec::with_capacity(layout.boards.len());
    for (bi, b) in layout.boards.iter().enumerate() {
        let [lo, hi] = b.keys;
        if lo > hi || hi > 127 {
            return Err(format!(
                "{name}: board {}: `keys` must be [first, last] with first ≤ last ≤ 127, got [{lo}, {hi}]",
                bi + 1
            ));
        }
        for k in lo..=hi {
            if let Some(o) = owner.insert(k, bi) {
                return Err(format!(
                    "{name}: board {} and board {} overlap: key {k} is on both",
                    o + 1,
                    bi + 1
                ));
            }
        }
        let on: Vec<u8> = keys
            .iter()
            .map(|a| a.key)
            .filter(|k| (lo..=hi).contains(k))
            .collect();
        if on.is_empty() {
            return Err(format!(
                "{name}: board {} (keys [{lo}, {hi}]) holds no key of the layout",
                bi + 1
            ));
        }
        out.push(on);
    }
    if let Some(a) = keys.iter().find(|a| !owner.contains_key(&a.key)) {
        return Err(format!(
            "{name}: key {} (range of `{}`) is on no board: every key needs a `[[board]]`, or \
             list none and let `tactus budget` plan them",
            a.key, a.instrument
        ));
    }
    Ok(Some(out))
}

/// Splits `"11 g"` into (11, "g"); `"0.9"` into (0.9, ""); `None` when the number is not
/// one, or beyond f64 (`"1e400 g"`).
fn split_value(s: &str) -> Option<(f64, String)> {
    let s = s.trim();
    let end = s
        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+' | 'e' | 'E')))
        .unwrap_or(s.len());
    let (num, unit) = s.split_at(end);
    let v: f64 = num.trim().parse().ok().filter(|v: &f64| v.is_finite())?;
    Some((v, unit.trim().to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    const GRAND: &str = r#"
name = "grand88"
[[range]]
keys = [21, 108]
instrument = "grand_piano"
params = { G = "0.15 N" }
grade = [ { param = "M_h", from = "11 g", to = "3.5 g" } ]
"#;

    #[test]
    fn layout_resolves_per_key_with_grading() {
        let l = parse_layout(GRAND, "g.toml").unwrap();
        let keys = assign(&l, "g.toml", Path::new(".")).unwrap();
        assert_eq!(keys.len(), 88);
        assert_eq!(
            keys[0].params,
            vec![("G".into(), "0.15 N".into()), ("M_h".into(), "11 g".into())]
        );
        assert_eq!(keys[87].params[1], ("M_h".into(), "3.5 g".into()));
        let mid: f64 = keys[44].params[1].1.trim_end_matches(" g").parse().unwrap();
        assert!(mid < 11.0 && mid > 3.5);
    }

    #[test]
    fn keys_with_equal_instrument_and_params_share_a_set_made_once() {
        let key = |key, instrument: &str, p: &[(&str, &str)]| KeyAssignment {
            key,
            instrument: instrument.into(),
            params: p
                .iter()
                .map(|(n, v)| (n.to_string(), v.to_string()))
                .collect(),
        };
        let keys = [
            key(21, "grand_piano", &[("M_h", "11 g")]),
            key(22, "harpsichord", &[]),
            key(23, "grand_piano", &[("M_h", "11 g")]),
            key(24, "grand_piano", &[("M_h", "9 g")]),
            key(25, "harpsichord", &[]),
        ];
        let mut made = Vec::new();
        let (sets, index) = group_sets(&keys, |k| {
            made.push(k.key);
            Ok::<_, ()>(k.key)
        })
        .unwrap();
        assert_eq!(
            sets,
            [21, 22, 24],
            "one set per distinct pair, in first-key order"
        );
        assert_eq!(index, [0, 1, 0, 2, 1]);
        assert_eq!(made, [21, 22, 24], "made once per set");
        // The first error stops the grouping and is returned as it is.
        let e = group_sets(&keys, |k| if k.key == 24 { Err(k.key) } else { Ok(()) });
        assert_eq!(e, Err(24));
    }

    #[test]
    fn bad_layouts_name_file_and_field() {
        let e = parse_layout(
            "name = \"x\"\n[[range]]\nkeys = [1, 2]\ninstrumnt = \"p\"\n",
            "bad.toml",
        )
        .unwrap_err();
        assert!(e.contains("bad.toml") && e.contains("instrumnt"), "{e}");
        let l = parse_layout(
            "name = \"x\"\n[[range]]\nkeys = [60, 50]\ninstrument = \"p\"\n",
            "rev.toml",
        )
        .unwrap();
        let e = assign(&l, "rev.toml", Path::new(".")).unwrap_err();
        assert!(e.contains("rev.toml") && e.contains("keys"), "{e}");
        let two = "name = \"x\"\n[[range]]\nkeys = [1, 5]\ninstrument = \"a\"\n[[range]]\nkeys = [5, 6]\ninstrument = \"b\"\n";
        let e = assign(
            &parse_layout(two, "o.toml").unwrap(),
            "o.toml",
            Path::new("."),
        )
        .unwrap_err();
        assert!(e.contains("key 5"), "{e}");
        let g = "name = \"x\"\n[[range]]\nkeys = [1, 5]\ninstrument = \"a\"\ngrade = [{ param = \"m\", from = \"1 g\", to = \"2 kg\" }]\n";
        let e = assign(
            &parse_layout(g, "u.toml").unwrap(),
            "u.toml",
            Path::new("."),
        )
        .unwrap_err();
        assert!(e.contains("`from` is in"), "{e}");
    }

    #[test]
    fn shipped_layouts_and_boards_load() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let (l, keys) = read_layout(&root.join("instruments/layouts/grand88.toml")).unwrap();
        assert_eq!(
            (l.name.as_str(), keys.len(), keys[0].key, keys[87].key),
            ("grand88", 88, 21, 108)
        );
        let (_, keys) =
            read_layout(&root.join("instruments/layouts/split_harpsichord_piano.toml")).unwrap();
        assert_eq!(
            keys.iter()
                .filter(|k| k.instrument == "harpsichord_2x8")
                .count(),
            44
        );
        assert_eq!(
            keys.iter()
                .filter(|k| k.instrument == "grand_piano")
                .count(),
            44
        );
        let board = |name: &str| {
            let text = read_text(&root.join(format!("boards/{name}.toml"))).unwrap();
            parse_board(&text, name).unwrap().cycles_per_sample()
        };
        assert_eq!(board("rp2040"), 3015);
        assert_eq!(board("rp2040_200mhz"), 4535);
        let e = read_text(&root.join("boards/none.toml")).unwrap_err();
        assert!(e.contains("none.toml") && e.contains("cannot read"), "{e}");
    }

    #[test]
    fn boards_check_their_fields() {
        let ok = "name = \"rp2040\"\nclock_hz = 133e6\ncores = 2\nsample_rate_hz = 44100\n";
        assert_eq!(parse_board(ok, "b.toml").unwrap().cycles_per_sample(), 3015);
        let e = parse_board(&ok.replace("cores = 2", "cores = 0"), "b.toml").unwrap_err();
        assert!(e.contains("b.toml") && e.contains("cores"), "{e}");
        let e = parse_board(
            &ok.replace("clock_hz = 133e6", "clock_hz = \"fast\""),
            "c.toml",
        )
        .unwrap_err();
        assert!(e.contains("c.toml") && e.contains("clock_hz"), "{e}");
        let e = parse_board(&ok.replace("cores = 2", "cores = 4294967295"), "b.toml").unwrap_err();
        assert!(e.contains("b.toml") && e.contains("cores"), "{e}");
        // The core voltage: absent, or one of the regulator's 50 mV steps.
        assert_eq!(parse_board(ok, "b.toml").unwrap().core_mv(), None);
        let v = |text: &str| parse_board(&format!("{ok}core_voltage_v = {text}\n"), "v.toml");
        assert_eq!(v("1.15").unwrap().core_mv(), Some(1150));
        assert_eq!(v("0.8").unwrap().core_mv(), Some(800));
        for bad in ["1.17", "1.35", "0.75", "nan", "\"high\""] {
            let e = v(bad).unwrap_err();
            assert!(
                e.contains("v.toml") && e.contains("core_voltage_v"),
                "{bad}: {e}"
            );
        }
        // Issue 19 class 6: a clock whose cycles per sample exceed any integer was reported as
        // "over by 8446744073709552191"; it is now an error naming the field.
        let e = parse_board(&ok.replace("133e6", "1e30"), "huge.toml").unwrap_err();
        assert!(e.contains("huge.toml") && e.contains("clock_hz"), "{e}");
        let e = parse_board(&format!("{ok}io_cycles_per_key = 163\n"), "old.toml").unwrap_err();
        assert!(e.contains("old.toml") && e.contains("no longer"), "{e}");
        // Converters: parts the firmware drives, by name; anything else names the field.
        let pins =
            "adc_pins = [[2, 3, 4, 5], [10, 11, 12, 13]]\ndac_pins = [[6, 7, 8], [14, 15, 16]]\n";
        let conv = |adc: &str, dac: &str| {
            parse_board(
                &format!("{ok}[converters]\nadc = \"{adc}\"\ndac = \"{dac}\"\n{pins}"),
                "io.toml",
            )
        };
        let b = conv("ADS8688", "DAC8568").unwrap();
        let (adc, dac) = b.converter_parts().unwrap();
        assert_eq!((adc.channels, dac.channels), (8, 8));
        assert_eq!(parse_board(ok, "b.toml").unwrap().converter_parts(), None);
        let e = conv("PCM3168A", "DAC8568").unwrap_err();
        assert!(e.contains("io.toml") && e.contains("converters.adc"), "{e}");
        let e = conv("ADS8688", "AD5686R").unwrap_err();
        assert!(e.contains("io.toml") && e.contains("converters.dac"), "{e}");
        let e = parse_board(
            &format!("{ok}[converters]\nadc = \"ADS8688\"\n"),
            "half.toml",
        )
        .unwrap_err();
        assert!(e.contains("half.toml") && e.contains("dac"), "{e}");
        let e = parse_board(
            &format!("{ok}[converters]\nadc = \"ADS8688\"\ndac = \"DAC8568\"\n{pins}sclk = 1\n"),
            "extra.toml",
        )
        .unwrap_err();
        assert!(e.contains("extra.toml") && e.contains("sclk"), "{e}");
        // Pins: a set per core, each a GPIO once.
        let e = parse_board(
            &format!(
                "{ok}[converters]\nadc = \"ADS8688\"\ndac = \"DAC8568\"\n{}",
                pins.replace("[14, 15, 16]", "[14, 15, 2]")
            ),
            "pins.toml",
        )
        .unwrap_err();
        assert!(
            e.contains("pins.toml") && e.contains("converters.dac_pins"),
            "{e}"
        );
    }

    fn layout_with(boards: &str) -> Result<Option<Vec<Vec<u8>>>, String> {
        let text =
            format!("name = \"x\"\n[[range]]\nkeys = [60, 63]\ninstrument = \"hammond\"\n{boards}");
        let l = parse_layout(&text, "l.toml")?;
        let keys = assign(&l, "l.toml", Path::new("."))?;
        board_keys(&l, "l.toml", &keys)
    }

    #[test]
    fn explicit_boards_are_checked_against_the_keys() {
        assert_eq!(layout_with("").unwrap(), None);
        let two = "[[board]]\nkeys = [60, 61]\n[[board]]\nkeys = [62, 63]\n";
        assert_eq!(
            layout_with(two).unwrap(),
            Some(vec![vec![60, 61], vec![62, 63]])
        );
        let e =
            layout_with("[[board]]\nkeys = [60, 62]\n[[board]]\nkeys = [62, 63]\n").unwrap_err();
        assert!(
            e.contains("l.toml") && e.contains("overlap") && e.contains("key 62"),
            "{e}"
        );
        let e = layout_with("[[board]]\nkeys = [60, 62]\n").unwrap_err();
        assert!(
            e.contains("l.toml") && e.contains("key 63") && e.contains("no board"),
            "{e}"
        );
        let e =
            layout_with("[[board]]\nkeys = [60, 63]\n[[board]]\nkeys = [70, 72]\n").unwrap_err();
        assert!(e.contains("board 2") && e.contains("no key"), "{e}");
        let e = layout_with("[[board]]\nkeys = [63, 60]\n").unwrap_err();
        assert!(e.contains("board 1") && e.contains("first ≤ last"), "{e}");
        let e = layout_with("[[board]]\nkeys = [60, 61, 63]\n").unwrap_err();
        assert!(e.contains("l.toml") && e.contains("two"), "{e}");
    }

    #[test]
    fn ranges_need_exactly_two_keys_and_missing_paths_are_errors() {
        let e = parse_layout(
            "name = \"x\"\n[[range]]\nkeys = [1, 2, 3]\ninstrument = \"p\"\n",
            "three.toml",
        )
        .unwrap_err();
        assert!(e.contains("three.toml") && e.contains("3 numbers"), "{e}");
        let l = parse_layout(
            "name = \"x\"\n[[range]]\nkeys = [1, 2]\ninstrument = \"no/such/grand_piano.tactus\"\n",
            "missing.toml",
        )
        .unwrap();
        let e = assign(&l, "missing.toml", Path::new(".")).unwrap_err();
        assert!(
            e.contains("missing.toml") && e.contains("no such file"),
            "{e}"
        );
    }

    #[test]
    fn a_layout_with_boards_round_trips_through_toml() {
        let text = "name = \"x\"\nboard_kind = \"rp2040\"\n[[range]]\nkeys = [60, 63]\ninstrument = \"hammond\"\n[[board]]\nkeys = [60, 63]\n";
        let l = parse_layout(text, "r.toml").unwrap();
        let back = parse_layout(&toml::to_string(&l).unwrap(), "r2.toml").unwrap();
        assert_eq!(l, back);
        assert_eq!(back.board_kind.as_deref(), Some("rp2040"));
    }

    #[test]
    fn the_tick_schedule_alternates_the_deadline_and_one_more_with_the_exact_mean() {
        for (clock, fs) in [
            (133_000_000u64, 44_100u32),
            (200_000_000, 44_100),
            (20_000_000, 44_100),
            (48_000_000, 8_000),
        ] {
            let d = deadline_cycles(clock as f64, fs as f64);
            assert_eq!(d, clock / fs as u64);
            let mut shortest = u64::MAX;
            for n in 0..fs as u64 {
                let gap = tick_cycle(7, n + 1, clock, fs) - tick_cycle(7, n, clock, fs);
                assert!(gap == d || gap == d + 1, "{clock}/{fs}: tick {n}: {gap}");
                shortest = shortest.min(gap);
            }
            assert_eq!(shortest, d, "{clock}/{fs}");
            // One second of ticks is exactly one second of cycles.
            assert_eq!(tick_cycle(7, fs as u64, clock, fs), 7 + clock);
        }
        assert_eq!(deadline_cycles(133e6, 44100.0), 3015);
        assert_eq!(deadline_cycles(200e6, 44100.0), 4535);
        assert_eq!(
            deadline_cycles(133.5e6, 44100.5),
            (133.5e6f64 / 44100.5).floor() as u64
        );
    }
}
