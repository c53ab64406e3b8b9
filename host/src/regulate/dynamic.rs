//! The dynamic sheet: the action as a pianist meets it, at speed. A sweep of pressed and
//! struck touches (`tactus_runtime::player::Touch`, played with a two-body finger by
//! `TouchPlay`) from below the softest that reaches the string to a struck *fff*, each
//! measured from the finger's first contact with the key: when and how fast the hammer
//! reaches the string (the instrument's strike event), when the key reaches its bed, and the
//! key's peak speed on the way.
//!
//! Why the figures look the way they do: they are the measures of the published studies of
//! real grand actions, so that a sheet reads against them directly. W. Goebl, R. Bresin and
//! A. Galembo ("Touch and temporal behavior of grand piano actions", JASA 118(2), 2005; three
//! grands, pressed and struck touch, more than 2,300 tones) measured the travel time from
//! the finger–key contact to the hammer–string contact against the maximum hammer velocity,
//! the key-bottom contact relative to the hammer–string contact, and struck against pressed
//! touch; A. Askenfelt and E. Jansson ("From touch to string vibrations", JASA 88(1), 1990,
//! and 90(5), 1991) the hammer's speed against the key's. A figure that needs a strike
//! (every one here) is left out of an instrument that emits none, with a note.
//!
//! The published fit beside the travel times is W. Goebl's ("Melody lead in piano
//! performance: expressive device or artifact?", JASA 110(1), 2001), from a Bösendorfer
//! SE290's records, which the 2005 study replicated: `t = 89.16 ms · (v / 1 m/s)^−0.570`
//! ([`travel_time_fit_s`]). Its constants are quoted from memory of the paper and remain
//! unconfirmed: searched for four times (issue 70), the stored texts give only the papers'
//! abstracts and first pages. What they do confirm: the 2005 study's abstract (OFAI
//! TR-2005-01) says the 2001 function, "derived from a computer-controlled piano", "was
//! replicated", and the first page of Goebl, Bresin and Galembo's SMAC 2003 paper that it
//! was "approximated from data of an internal chip of a Bösendorfer SE290 reproducing
//! system"; neither gives the constants. The band drawn around it is the fit ± 20 ms, the difference
//! the 2005 study reports between pressed and struck touch at equal hammer speed ("the whole
//! striking procedure needs roughly 20 ms less time with a struck touch").

use super::{Figure, Key, Measured};
use tactus_compiler::sim::Engine;
use tactus_runtime::player::{
    Dynamic, Fingertip, Touch, TouchKind, TouchPlay, PRESSED_PUSH_N, STRUCK_SPEED_MPS,
};

/// Pushes of the pressed touches of the sweep, N: 16 log-spaced from 0.4 N (below the
/// softest level, `PRESSED_PUSH_N`'s 0.8 N *pp*) to 50 N (*fff*).
pub fn pressed_pushes() -> Vec<f64> {
    log_spaced(0.4, 50.0, 16)
}

/// `n` values from `lo` to `hi`, log-spaced, each to three significant digits (so that a
/// touch's label names it exactly).
fn log_spaced(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (lo.ln() + (hi.ln() - lo.ln()) * i as f64 / (n - 1) as f64).exp())
        .map(|x| {
            let scale = 10f64.powi(2 - x.log10().floor() as i32);
            (x * scale).round() / scale
        })
        .collect()
}

/// Finger speeds of the struck touches of the sweep, m/s: 16 log-spaced from 0.05 m/s to
/// 3 m/s (*fff*, `STRUCK_SPEED_MPS`), each pushing as `Touch::struck` has it.
pub fn struck_speeds() -> Vec<f64> {
    log_spaced(0.05, 3.0, 16)
}

/// When the finger meets the key in a sweep's run, s.
pub const CONTACT_S: f64 = 0.005;

/// How long a sweep's run lasts at most, s (a push too weak to reach the string in this long
/// does not strike).
pub const RUN_S: f64 = 0.8;

/// Goebl's fitted travel time (finger–key contact to hammer–string contact) for a hammer
/// speed `speed_mps` (m/s), s: `89.16 ms · v^−0.570` (see the module documentation for its
/// source and how sure we are of its constants).
pub fn travel_time_fit_s(speed_mps: f64) -> f64 {
    0.08916 * speed_mps.powf(-0.570)
}

/// Half-width of the band drawn around the fit, s (the 2005 study's ≈ 20 ms between pressed
/// and struck touch at equal hammer speed).
pub const FIT_BAND_S: f64 = 0.020;

/// What one touch of the sweep did; times from the finger's first contact with the key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TouchRun {
    /// The touch.
    pub touch: Touch,
    /// Its first strike: (travel time s, hammer or plectrum speed m/s).
    pub strike: Option<(f64, f64)>,
    /// When the key first reached its bed, s.
    pub bottom_s: Option<f64>,
    /// The key's highest speed from the contact to the strike (or to the end of the run
    /// without one), m/s.
    pub peak_key_mps: f64,
    /// The key's speed when it lets the hammer go: as it passes the let-off travel of a
    /// hammer action (where the jack escapes on the quasi-static dip), or at the strike of
    /// an instrument without one, m/s (`NaN` when neither happened).
    pub release_key_mps: f64,
}

impl TouchRun {
    /// Key bottom minus string contact, s (positive: the key bottoms after the strike).
    pub fn bottom_offset_s(&self) -> Option<f64> {
        Some(self.bottom_s? - self.strike?.0)
    }

    /// Hammer speed over the key's speed when it let the hammer go
    /// ([`TouchRun::release_key_mps`]).
    pub fn speed_ratio(&self) -> Option<f64> {
        let (_, v) = self.strike?;
        (self.release_key_mps > 0.0).then(|| v / self.release_key_mps)
    }
}

/// Plays `touch` on a copy of the key at rest `rest` of dip `dip_m` and reads what it did.
///
/// Errors: the engine's non-finite force.
pub(super) fn play<E: Engine + Clone>(
    rest: &Key<E>,
    touch: Touch,
    dip_m: f64,
    letoff_m: Option<f64>,
) -> Result<TouchRun, String> {
    let mut key = rest.clone();
    let fs = key.fs;
    let mut t = TouchPlay::new(
        touch,
        dip_m,
        Fingertip::default(),
        fs,
        CONTACT_S,
        tactus_runtime::player::FingerConfig::default().hold_n,
        RUN_S,
    );
    let contact = (CONTACT_S * fs).round() as usize;
    let mut run = TouchRun {
        touch,
        strike: None,
        bottom_s: None,
        peak_key_mps: 0.0,
        release_key_mps: f64::NAN,
    };
    for n in 0..(RUN_S * fs) as usize {
        let x = t.key_m();
        key.at(x)?;
        if run.release_key_mps.is_nan() && letoff_m.is_some_and(|l| x >= l) {
            run.release_key_mps = t.player().v_mps;
        }
        if run.strike.is_none() {
            if let Some(v) = key.struck {
                run.strike = Some(((n - contact.min(n)) as f64 / fs, v));
                if letoff_m.is_none() {
                    run.release_key_mps = t.player().v_mps;
                }
            }
        }
        if run.strike.is_none() {
            run.peak_key_mps = run.peak_key_mps.max(t.player().v_mps);
        }
        run.bottom_s = t.bottom_s().map(|b| b - contact as f64 / fs);
        if run.strike.is_some() && run.bottom_s.is_some() {
            break;
        }
        t.step(key.force);
    }
    Ok(run)
}

/// The sweep: every pressed push of [`pressed_pushes`] and every struck speed of
/// [`struck_speeds`], in that order. `letoff_m`: the key travel where the jack escapes on the quasi-static dip, for a hammer
/// action.
///
/// Errors: the engine's non-finite force.
pub(super) fn sweep<E: Engine + Clone>(
    rest: &Key<E>,
    dip_m: f64,
    letoff_m: Option<f64>,
) -> Result<Vec<TouchRun>, String> {
    let touches = pressed_pushes()
        .into_iter()
        .map(Touch::pressed)
        .chain(struck_speeds().into_iter().map(Touch::struck));
    touches.map(|t| play(rest, t, dip_m, letoff_m)).collect()
}

/// The runs of `kind` that struck, by hammer speed.
fn struck(runs: &[TouchRun], kind: TouchKind) -> Vec<&TouchRun> {
    let mut r: Vec<&TouchRun> = runs
        .iter()
        .filter(|r| r.touch.kind == kind && r.strike.is_some())
        .collect();
    r.sort_by(|a, b| speed(a).total_cmp(&speed(b)));
    r
}

fn speed(r: &TouchRun) -> f64 {
    r.strike.map_or(f64::NAN, |s| s.1)
}

/// Log–log interpolation of the travel time of `runs` (sorted by hammer speed) at hammer
/// speed `v`, s; `None` outside their speeds.
fn travel_at(runs: &[&TouchRun], v: f64) -> Option<f64> {
    let pts: Vec<(f64, f64)> = runs.iter().filter_map(|r| r.strike).collect();
    let i = pts.windows(2).position(|w| w[0].1 <= v && v <= w[1].1)?;
    let ((t0, v0), (t1, v1)) = (pts[i], pts[i + 1]);
    if v1 <= v0 {
        return Some(t0);
    }
    let u = (v.ln() - v0.ln()) / (v1.ln() - v0.ln());
    Some((t0.ln() + u * (t1.ln() - t0.ln())).exp())
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// The dynamic figures of a sweep (see [`Figure`]'s dynamic variants), and notes for the
/// ones left out.
/// `hammer_action`: the instrument is a hammer action (`hammer_pos` and a strike), to
/// which Goebl's fitted travel times belong; a plucked key has no such fit.
pub(super) fn figures(
    runs: &[TouchRun],
    dip_m: f64,
    hammer_action: bool,
) -> (Vec<Measured>, Vec<String>) {
    let mut out = Vec::new();
    let mut notes = Vec::new();
    let all: Vec<&TouchRun> = runs.iter().filter(|r| r.strike.is_some()).collect();
    if all.is_empty() {
        notes.push(format!(
            "dynamic sheet: none of the {} touches (pressed 0.4–50 N, struck 0.05–3 m/s) strikes (no `strike` or `pluck` event, or none fires)",
            runs.len()
        ));
        return (out, notes);
    }
    let pressed = struck(runs, TouchKind::Pressed);
    let struck_runs = struck(runs, TouchKind::Struck);
    let sweep_text = format!(
        "over {} pressed touches (0.4–50 N) and {} struck ones (0.05–3 m/s, then pushing), each from the finger's first contact with the key at rest (a {:.0} g finger on a {:.0} g key through the fingertip's pulp; `tactus sim --touch`)",
        pressed_pushes().len(),
        struck_speeds().len(),
        Fingertip::default().finger_kg * 1e3,
        Fingertip::default().key_kg * 1e3,
    );
    let softest = all
        .iter()
        .min_by(|a, b| speed(a).total_cmp(&speed(b)))
        .copied();
    let loudest = all
        .iter()
        .max_by(|a, b| speed(a).total_cmp(&speed(b)))
        .copied();
    if let Some(s) = softest {
        out.push(Measured {
            figure: Figure::HammerSpeedMin,
            value: speed(s),
            how: format!(
                "least strike speed {sweep_text}; the softest that struck: {}",
                s.touch.label()
            ),
        });
    }
    if let Some(l) = loudest {
        out.push(Measured {
            figure: Figure::HammerSpeedMax,
            value: speed(l),
            how: format!(
                "greatest strike speed of the sweep; the loudest: {}",
                l.touch.label()
            ),
        });
    }
    // The ratio over p–f: the touches of levels p to f (pressed 1.6–12.6 N, struck
    // 0.18–0.96 m/s: `PRESSED_PUSH_N`, `STRUCK_SPEED_MPS`).
    let (p, f) = (Dynamic::P as usize, Dynamic::F as usize);
    let in_p_f = |r: &&TouchRun| match r.touch.kind {
        TouchKind::Pressed => (PRESSED_PUSH_N[p]..=PRESSED_PUSH_N[f]).contains(&r.touch.push_n),
        TouchKind::Struck => {
            (STRUCK_SPEED_MPS[p]..=STRUCK_SPEED_MPS[f]).contains(&r.touch.contact_mps)
        }
    };
    let ratios: Vec<f64> = all
        .iter()
        .copied()
        .filter(in_p_f)
        .filter_map(|r| r.speed_ratio())
        .collect();
    if !ratios.is_empty() {
        let how = "hammer speed at the string / the key's speed as it lets the hammer go (passing the let-off travel of the quasi-static dip; at the strike without a let-off), over the touches of levels p to f (pressed 1.6–12.6 N, struck 0.18–0.96 m/s)";
        out.push(Measured {
            figure: Figure::SpeedRatioMin,
            value: ratios.iter().copied().fold(f64::INFINITY, f64::min),
            how: format!("least {how}"),
        });
        out.push(Measured {
            figure: Figure::SpeedRatioMax,
            value: ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            how: format!("greatest {how}"),
        });
    }
    // Travel time against the published fit: the pressed touches' median ratio.
    let fit_ratios: Vec<f64> = pressed
        .iter()
        .filter_map(|r| r.strike)
        .map(|(t, v)| t / travel_time_fit_s(v))
        .collect();
    if !hammer_action {
        notes.push("travel time / Goebl fit: the fit is a grand piano action's (hammer speed against travel time); this instrument has no hammer".to_string());
    } else if let Some(m) = median(fit_ratios) {
        out.push(Measured {
            figure: Figure::TravelTimeToFit,
            value: m,
            how: "median of (travel time from the finger's contact to the strike) / Goebl's fit at the same hammer speed, 89.16 ms·v^−0.570 (JASA 110(1), 2001), over the pressed touches that strike".to_string(),
        });
    }
    // Struck against pressed at equal hammer speed: the pressed time minus the struck time,
    // each interpolated (log–log) at the struck touches' speeds inside the pressed range.
    let sooner: Vec<f64> = struck_runs
        .iter()
        .filter_map(|r| {
            let (t, v) = r.strike?;
            Some(travel_at(&pressed, v)? - t)
        })
        .collect();
    match median(sooner.clone()) {
        Some(m) => out.push(Measured {
            figure: Figure::StruckSooner,
            value: m * 1e3,
            how: format!(
                "median, over the {} struck touches whose hammer speed a pressed one also reaches, of the pressed touch's travel time at that speed (log–log between pressed touches) minus the struck touch's",
                sooner.len()
            ),
        }),
        None => notes.push(
            "struck sooner than pressed: no struck touch's hammer speed lies within the pressed touches'"
                .to_string(),
        ),
    }
    // Key bottom against string contact.
    let offsets: Vec<(f64, f64)> = all
        .iter()
        .filter_map(|r| Some((speed(r), r.bottom_offset_s()?)))
        .collect();
    let mut by_speed = offsets.clone();
    by_speed.sort_by(|a, b| a.0.total_cmp(&b.0));
    if let (Some(soft), Some(loud)) = (by_speed.first(), by_speed.last()) {
        out.push(Measured {
            figure: Figure::KeyBottomSoft,
            value: soft.1 * 1e3,
            how: format!(
                "key bottom ({:.1} mm) minus string contact of the softest touch that strikes and bottoms ({:.2} m/s; positive: the key bottoms after the strike)",
                dip_m * 1e3,
                soft.0
            ),
        });
        out.push(Measured {
            figure: Figure::KeyBottomLoud,
            value: loud.1 * 1e3,
            how: format!(
                "key bottom minus string contact of the loudest touch ({:.2} m/s; negative: the key bottoms before the strike)",
                loud.0
            ),
        });
    }
    // Where the offset crosses zero: the first change of sign, from the soft side, by hammer
    // speed (linear between the two touches around it).
    let crossing = by_speed
        .windows(2)
        .find(|w| w[0].1 > 0.0 && w[1].1 <= 0.0)
        .map(|w| {
            let ((v0, o0), (v1, o1)) = (w[0], w[1]);
            v0 + (v1 - v0) * o0 / (o0 - o1)
        });
    match crossing {
        Some(v) => out.push(Measured {
            figure: Figure::KeyBottomCrossing,
            value: v,
            how: "hammer speed where key bottom minus string contact first changes sign (after → before), linear between the two touches around it, by hammer speed over every touch".to_string(),
        }),
        None => notes.push(
            "key bottom crossing: the key bottom does not move from after the string contact to before it over the sweep"
                .to_string(),
        ),
    }
    (out, notes)
}

/// The sweep as CSV: `kind,touch,travel time [ms],hammer speed [m/s],key bottom [ms],key
/// bottom - strike [ms],peak key speed [m/s],key speed at let-off [m/s],Goebl fit [ms]`, one
/// row per touch (empty cells where it did not strike, bottom or let off).
pub fn runs_csv(runs: &[TouchRun]) -> String {
    let mut s = String::from("kind,touch,travel time [ms],hammer speed [m/s],key bottom [ms],key bottom - strike [ms],peak key speed [m/s],key speed at let-off [m/s],Goebl fit [ms]\n");
    let ms = |x: Option<f64>| x.map(|x| format!("{:.3}", x * 1e3)).unwrap_or_default();
    for r in runs {
        s.push_str(&format!(
            "{},{},{},{},{},{},{:.4},{},{}\n",
            r.touch.kind.name(),
            r.touch.label(),
            ms(r.strike.map(|s| s.0)),
            r.strike.map(|s| format!("{:.4}", s.1)).unwrap_or_default(),
            ms(r.bottom_s),
            ms(r.bottom_offset_s()),
            r.peak_key_mps,
            if r.release_key_mps.is_nan() {
                String::new()
            } else {
                format!("{:.4}", r.release_key_mps)
            },
            ms(r.strike.map(|s| travel_time_fit_s(s.1))),
        ));
    }
    s
}
