//! A regulation spec: the range each figure of the sheet must lie in, read from a TOML file
//! (`instruments/specs/concert_grand.toml`), and the verdict of a sheet against it.
//!
//! The file is data a technician can read: a `name`, then one line per figure, named as
//! [`Figure::key`], with a `min`, a `max` or both, in the figure's unit ([`Figure::unit`]:
//! grams-force, millimetres, milliseconds, m/s, notes per second). Each range's source
//! belongs in a comment beside it.
//!
//! ```toml
//! name = "regulated concert grand"
//! down_weight = { min = 47, max = 52 }   # gf; Stanwood, PTG Journal 1996
//! hysteresis = { min = 10 }              # gf
//! ```
//!
//! A figure the spec names but the sheet could not measure fails its verdict: the spec asks
//! for it.

use super::{Figure, Sheet};

/// The largest spec file read, bytes.
pub const MAX_SPEC_BYTES: u64 = 1 << 20;

/// The allowed range of one figure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// Which figure.
    pub figure: Figure,
    /// Least allowed value, in the figure's unit.
    pub min: Option<f64>,
    /// Greatest allowed value, in the figure's unit.
    pub max: Option<f64>,
}

impl Range {
    /// Whether `value` lies in the range (bounds included).
    pub fn holds(&self, value: f64) -> bool {
        self.min.is_none_or(|lo| value >= lo) && self.max.is_none_or(|hi| value <= hi)
    }

    /// The range as printed: `47 – 52`, `≥ 10`, `≤ 0.05`.
    pub fn text(&self) -> String {
        match (self.min, self.max) {
            (Some(lo), Some(hi)) => format!("{lo} – {hi}"),
            (Some(lo), None) => format!("≥ {lo}"),
            (None, Some(hi)) => format!("≤ {hi}"),
            (None, None) => "any".to_string(),
        }
    }
}

/// A regulation spec.
#[derive(Clone, Debug, PartialEq)]
pub struct Spec {
    /// What it specifies (`regulated concert grand`).
    pub name: String,
    /// The ranges, in [`Figure::ALL`] order.
    pub ranges: Vec<Range>,
}

/// One figure's verdict.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    /// The range asked for.
    pub range: Range,
    /// The measured value (`None`: not measured).
    pub value: Option<f64>,
}

impl Verdict {
    /// Whether the figure was measured and lies in its range.
    pub fn holds(&self) -> bool {
        self.value.is_some_and(|v| self.range.holds(v))
    }
}

/// Reads a spec file.
///
/// Errors (naming the file): unreadable, larger than [`MAX_SPEC_BYTES`], or what
/// [`parse`] rejects.
pub fn read(path: &std::path::Path) -> Result<Spec, String> {
    let name = path.display().to_string();
    let text = tactus_runtime::files::read_text_bounded(path, MAX_SPEC_BYTES, "a spec")
        .map_err(|e| format!("spec {e}"))?;
    parse(&text, &name)
}

/// Parses a spec's text; `file` names it in errors.
///
/// Errors (naming the file and the field): not TOML; no `name`; a key that is no figure
/// (the figures are listed); a range that is not a table of `min`/`max` numbers, has
/// neither, has another field, a non-finite bound, or `min > max`.
pub fn parse(text: &str, file: &str) -> Result<Spec, String> {
    let table: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| format!("spec `{file}`: {}", e.message()))?;
    let name = match table.get("name") {
        Some(toml::Value::String(s)) => s.clone(),
        Some(_) => return Err(format!("spec `{file}`: `name` must be a string")),
        None => return Err(format!("spec `{file}`: no `name`")),
    };
    let mut ranges = Vec::new();
    for (key, value) in &table {
        if key == "name" {
            continue;
        }
        let figure = Figure::from_key(key).ok_or_else(|| {
            let known: Vec<&str> = Figure::ALL.iter().map(|f| f.key()).collect();
            format!(
                "spec `{file}`: `{key}` is no figure of the sheet (figures: {})",
                known.join(", ")
            )
        })?;
        let toml::Value::Table(t) = value else {
            return Err(format!(
                "spec `{file}`: `{key}` must be a table `{{ min = …, max = … }}` (in {})",
                figure.unit()
            ));
        };
        let bound = |which: &str| -> Result<Option<f64>, String> {
            match t.get(which) {
                None => Ok(None),
                Some(toml::Value::Integer(i)) => Ok(Some(*i as f64)),
                Some(toml::Value::Float(x)) if x.is_finite() => Ok(Some(*x)),
                Some(_) => Err(format!(
                    "spec `{file}`: `{key}.{which}` must be a finite number (in {})",
                    figure.unit()
                )),
            }
        };
        let (min, max) = (bound("min")?, bound("max")?);
        if let Some(other) = t.keys().find(|k| *k != "min" && *k != "max") {
            return Err(format!(
                "spec `{file}`: `{key}.{other}`: a range has only `min` and `max`"
            ));
        }
        match (min, max) {
            (None, None) => {
                return Err(format!(
                    "spec `{file}`: `{key}` has neither `min` nor `max`"
                ))
            }
            (Some(lo), Some(hi)) if lo > hi => {
                return Err(format!(
                    "spec `{file}`: `{key}`: min {lo} is greater than max {hi}"
                ))
            }
            _ => {}
        }
        ranges.push(Range { figure, min, max });
    }
    ranges.sort_by_key(|r| r.figure);
    Ok(Spec { name, ranges })
}

/// The verdict of `sheet` against every range of `spec`, in the spec's order.
pub fn check(sheet: &Sheet, spec: &Spec) -> Vec<Verdict> {
    spec.ranges
        .iter()
        .map(|r| Verdict {
            range: *r,
            value: sheet.get(r.figure),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::regulate::{ForceLoop, Measured};

    #[test]
    fn a_spec_parses_and_judges_a_sheet() {
        let spec = parse(
            "name = \"x\"\nup_weight = { min = 22, max = 27 }\ndown_weight = { min = 47.5 }\ncreep = { max = 0.05 }\nrepetition = { min = 8 }\n",
            "x.toml",
        )
        .unwrap();
        assert_eq!(spec.name, "x");
        assert_eq!(
            spec.ranges.iter().map(|r| r.figure).collect::<Vec<_>>(),
            [
                Figure::DownWeight,
                Figure::UpWeight,
                Figure::Creep,
                Figure::Repetition
            ]
        );
        let sheet = Sheet {
            instrument: "k".into(),
            figures: vec![
                Measured {
                    figure: Figure::DownWeight,
                    value: 47.5,
                    how: String::new(),
                },
                Measured {
                    figure: Figure::UpWeight,
                    value: 27.01,
                    how: String::new(),
                },
                Measured {
                    figure: Figure::Creep,
                    value: 0.01,
                    how: String::new(),
                },
            ],
            notes: vec![],
            force_loop: ForceLoop::default(),
            touches: vec![],
        };
        let v = check(&sheet, &spec);
        assert_eq!(
            v.iter().map(Verdict::holds).collect::<Vec<_>>(),
            [true, false, true, false],
            "{v:?}"
        );
        assert_eq!(v[3].value, None);
        assert_eq!(v[1].range.text(), "22 – 27");
        assert_eq!(v[2].range.text(), "≤ 0.05");
    }

    #[test]
    fn bad_specs_name_the_file_and_the_field() {
        let err = |t: &str| parse(t, "s.toml").unwrap_err();
        assert!(err("down_weight = { min = 1 }").contains("no `name`"));
        assert!(err("name = 3").contains("`name` must be a string"));
        let e = err("name = \"x\"\ndownweight = { min = 1 }");
        assert!(
            e.contains("`downweight` is no figure") && e.contains("down_weight"),
            "{e}"
        );
        assert!(err("name = \"x\"\ncreep = 3").contains("must be a table"));
        assert!(err("name = \"x\"\ncreep = {}").contains("neither"));
        assert!(err("name = \"x\"\ncreep = { min = 2, max = 1 }").contains("greater than"));
        assert!(err("name = \"x\"\ncreep = { mn = 2 }").contains("`creep.mn`"));
        assert!(err("name = \"x\"\ncreep = { max = \"1 mm\" }").contains("finite number"));
        assert!(err("name = \"x\"\ncreep = { max = nan }").contains("finite number"));
        assert!(err("name = ").starts_with("spec `s.toml`"));
    }
}
