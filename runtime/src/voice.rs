//! A synthesized piano-like voice for listening to simulated strikes: a modal model, no
//! recorded samples.
//!
//! Each strike sounds a few partials of the struck string. A stiff string's partials are
//! inharmonic: `f_n = n·f0·√(1 + B·n²)` (Fletcher, "Normal vibration frequencies of a stiff
//! piano string", JASA 36, 1964), with the inharmonicity coefficient `B` rising from about
//! 1e-4 in the bass to about 1e-2 at the top of a piano; we interpolate log-linearly between
//! those end points over A0…C8 (a real scale has a shallow minimum in the tenor, which we
//! ignore). Each partial decays exponentially; the fundamental's 60 dB decay time falls
//! from 20 s at A0 to 1 s at C8 (log-linear), and partial `n` decays `1 + 0.35·(n − 1)` times
//! faster. Partial amplitudes fall as `1/n^p` with `p` from 2 (soft) to 1 (loud): a louder
//! blow is brighter. The amplitude is proportional to the hammer speed at the strike.
//! A 2 ms linear attack avoids a click. When the damper falls (note-off with the sustain
//! pedal up, or the pedal lifted after the note-off) every partial decays with a 60 dB time
//! of [`DAMPED_T60_S`]. Partials above 0.45 of the sample rate are left out.
//!
//! The rendering is a plain sum of damped sines: an instrument maker's sketch, not a piano
//! synthesizer; it exists to hear timing and dynamics.

/// 60 dB decay time after the damper falls, s.
pub const DAMPED_T60_S: f64 = 0.25;

/// Most partials per note.
pub const PARTIALS: usize = 8;

/// Below this fraction of its peak a partial is no longer rendered.
const SILENCE: f64 = 1e-4;

/// One struck note to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Strike {
    /// MIDI key number (69 = A4 = 440 Hz).
    pub key: u8,
    /// Strike time, s.
    pub time_s: f64,
    /// Hammer speed at the strike, m/s (sets the amplitude and the brightness).
    pub speed_mps: f64,
    /// When the damper falls on the string, s (`f64::INFINITY`: never).
    pub damp_s: f64,
}

/// Fundamental frequency of a key in equal temperament, A4 = 440 Hz, Hz.
pub fn fundamental_hz(key: u8) -> f64 {
    440.0 * 2f64.powf((f64::from(key) - 69.0) / 12.0)
}

/// Fletcher's inharmonicity coefficient `B` for a key (see the module documentation).
pub fn inharmonicity(key: u8) -> f64 {
    let u = ((f64::from(key) - 21.0) / 87.0).clamp(0.0, 1.0);
    1e-4 * 100f64.powf(u)
}

/// Frequency of partial `n` (1 = fundamental) of a key, Hz: `n·f0·√(1 + B·n²)`.
pub fn partial_hz(key: u8, n: usize) -> f64 {
    let n = n as f64;
    n * fundamental_hz(key) * (1.0 + inharmonicity(key) * n * n).sqrt()
}

/// 60 dB decay time of partial `n` of a key with the damper up, s.
pub fn t60_s(key: u8, n: usize) -> f64 {
    let u = ((f64::from(key) - 21.0) / 87.0).clamp(0.0, 1.0);
    let t1 = 20.0 * (1.0f64 / 20.0).powf(u);
    t1 / (1.0 + 0.35 * (n as f64 - 1.0))
}

/// When the damper of a note released at `off_s` falls, given the sustain pedal's changes
/// `(time s, down)` in time order: at the note-off if the pedal is up then, else at the next
/// pedal release (never, if the pedal stays down).
pub fn damper_time(off_s: f64, sustain: &[(f64, bool)]) -> f64 {
    let down_at_off = sustain
        .iter()
        .take_while(|(t, _)| *t <= off_s)
        .last()
        .is_some_and(|(_, d)| *d);
    if !down_at_off {
        return off_s;
    }
    sustain
        .iter()
        .find(|(t, d)| *t > off_s && !*d)
        .map_or(f64::INFINITY, |(t, _)| *t)
}

/// The longest buffer [`render`] should be asked for, samples (2²⁷ f32, 512 MiB, 50 minutes
/// at 44.1 kHz): callers check a length from input against it before rendering.
pub const MAX_RENDER_SAMPLES: usize = 1 << 27;

/// The most oscillator steps [`render`] should be asked for (a partial of a strike for one
/// sample is one step; 2³³, tens of seconds): callers check [`render_work`] against it
/// before rendering, so a run whose instrument strikes every sample (tens of thousands of
/// strikes a second, each ringing for seconds) is refused rather than rendered for hours.
/// A 10-minute recital of about 5,000 notes needs a few 10⁸.
pub const MAX_RENDER_WORK: f64 = (1u64 << 33) as f64;

/// The oscillator steps [`render`] takes for `strikes` over `seconds` at `sample_rate_hz`:
/// per strike and partial, the samples until it falls below the silence threshold (or the
/// buffer ends), computed from the decay rates without rendering.
pub fn render_work(strikes: &[Strike], seconds: f64, sample_rate_hz: f64) -> f64 {
    let n = (seconds.max(0.0) * sample_rate_hz).ceil();
    let dt = 1.0 / sample_rate_hz;
    let ln1000 = 1000f64.ln();
    let damped = -ln1000 * dt / DAMPED_T60_S;
    let mut work = 0.0;
    for s in strikes {
        let Some(i0) = first_sample(s.time_s, sample_rate_hz) else {
            continue;
        };
        let i0 = i0 as f64;
        if i0 >= n || s.speed_mps.is_nan() || s.speed_mps <= 0.0 {
            continue;
        }
        let damp_after = match s.damp_s.is_finite() {
            true => (s.damp_s * sample_rate_hz).round().max(i0) - i0,
            false => f64::INFINITY,
        };
        for k in 1..=PARTIALS {
            if partial_hz(s.key, k) >= 0.45 * sample_rate_hz {
                break;
            }
            // ln(env/amp) per sample, before and after the damper.
            let free = -ln1000 * dt / t60_s(s.key, k);
            let silent = SILENCE.ln();
            let steps = match silent / free <= damp_after {
                true => silent / free,
                false => damp_after + (silent - damp_after * free) / damped,
            };
            work += steps.ceil().min(n - i0);
        }
    }
    work
}

/// Renders strikes into a mono buffer of `seconds` at `sample_rate_hz` (unnormalised: a
/// 1 m/s strike's fundamental starts at amplitude about 1). The buffer is allocated whole:
/// check `seconds · sample_rate_hz` against [`MAX_RENDER_SAMPLES`] and [`render_work`]
/// against [`MAX_RENDER_WORK`] first.
pub fn render(strikes: &[Strike], seconds: f64, sample_rate_hz: f64) -> Vec<f32> {
    let n = (seconds.max(0.0) * sample_rate_hz).ceil() as usize;
    let mut buf = vec![0f32; n];
    let dt = 1.0 / sample_rate_hz;
    let ln1000 = 1000f64.ln();
    let attack = (0.002 * sample_rate_hz).max(1.0);
    for s in strikes {
        let Some(i0) = first_sample(s.time_s, sample_rate_hz) else {
            continue;
        };
        if i0 >= n || s.speed_mps.is_nan() || s.speed_mps <= 0.0 {
            continue;
        }
        let damp_i = if s.damp_s.is_finite() {
            first_sample(s.damp_s, sample_rate_hz).unwrap_or(0).max(i0)
        } else {
            usize::MAX
        };
        let loud = (s.speed_mps / 6.0).clamp(0.0, 1.0);
        let p = 2.0 - loud;
        for k in 1..=PARTIALS {
            let f = partial_hz(s.key, k);
            if f >= 0.45 * sample_rate_hz {
                break;
            }
            let amp = s.speed_mps / (k as f64).powf(p);
            // Per-sample decay factors before and after the damper.
            let free = (-ln1000 * dt / t60_s(s.key, k)).exp();
            let damped = (-ln1000 * dt / DAMPED_T60_S).exp();
            // The oscillator as a rotating phasor: cheap and exact in frequency.
            let (sin_w, cos_w) = (2.0 * std::f64::consts::PI * f * dt).sin_cos();
            let (mut re, mut im) = (1.0f64, 0.0f64);
            let mut env = amp;
            let mut i = i0;
            while i < n && env > SILENCE * amp {
                let a = ((i - i0) as f64 + 1.0).min(attack) / attack;
                buf[i] += (env * a * im) as f32;
                let r = re * cos_w - im * sin_w;
                im = re * sin_w + im * cos_w;
                re = r;
                env *= if i >= damp_i { damped } else { free };
                i += 1;
            }
        }
    }
    buf
}

fn first_sample(t: f64, fs: f64) -> Option<usize> {
    (t.is_finite() && t >= 0.0).then(|| (t * fs).round() as usize)
}

/// The factor that puts the peak of `samples` at `headroom` of 16-bit full scale (e.g. 0.9);
/// 0 for silence.
pub fn i16_scale(samples: &[f32], headroom: f64) -> f64 {
    let peak = samples.iter().fold(0f32, |m, &x| m.max(x.abs()));
    if peak > 0.0 {
        headroom.clamp(0.0, 1.0) * f64::from(i16::MAX) / f64::from(peak)
    } else {
        0.0
    }
}

/// One sample as 16-bit PCM with the factor of [`i16_scale`] (rounded, never past ±32767).
pub fn to_i16(x: f32, scale: f64) -> i16 {
    (f64::from(x) * scale).round().clamp(-32767.0, 32767.0) as i16
}

/// Scales samples to 16-bit PCM with the peak at `headroom` of full scale (e.g. 0.9), so
/// nothing clips; silence stays silence.
pub fn normalise_i16(samples: &[f32], headroom: f64) -> Vec<i16> {
    let scale = i16_scale(samples, headroom);
    samples.iter().map(|&x| to_i16(x, scale)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const FS: f64 = 44_100.0;

    #[test]
    fn partials_are_stretched_by_stiffness() {
        assert!((fundamental_hz(69) - 440.0).abs() < 1e-9);
        assert!((fundamental_hz(21) - 27.5).abs() < 1e-9);
        let b = inharmonicity(60);
        assert!(b > 1e-4 && b < 1e-2);
        let f5 = partial_hz(60, 5);
        assert!((f5 - 5.0 * fundamental_hz(60) * (1.0 + 25.0 * b).sqrt()).abs() < 1e-9);
        assert!(f5 > 5.0 * fundamental_hz(60));
        assert!(inharmonicity(108) > inharmonicity(21));
        assert!(t60_s(21, 1) > t60_s(108, 1) && t60_s(60, 2) < t60_s(60, 1));
    }

    /// Energy of the samples in [a, b) s.
    fn energy(x: &[f32], a: f64, b: f64) -> f64 {
        x[(a * FS) as usize..(b * FS) as usize]
            .iter()
            .map(|&v| f64::from(v).powi(2))
            .sum()
    }

    #[test]
    fn louder_strikes_are_louder_and_the_damper_stops_the_sound() {
        let s = |speed, damp_s| Strike {
            key: 60,
            time_s: 0.1,
            speed_mps: speed,
            damp_s,
        };
        let soft = render(&[s(0.5, f64::INFINITY)], 1.0, FS);
        let loud = render(&[s(3.0, f64::INFINITY)], 1.0, FS);
        assert!(energy(&loud, 0.1, 0.3) > 10.0 * energy(&soft, 0.1, 0.3));
        assert_eq!(energy(&soft, 0.0, 0.1), 0.0);
        let damped = render(&[s(3.0, 0.3)], 1.0, FS);
        assert!(energy(&damped, 0.8, 1.0) < 1e-4 * energy(&loud, 0.8, 1.0));
        assert_eq!(energy(&damped, 0.1, 0.3), energy(&loud, 0.1, 0.3));
        // The fundamental is there: zero crossings ≈ 2·f0 per second (partials above it are
        // weaker for a soft blow).
        let w = &soft[(0.2 * FS) as usize..(0.7 * FS) as usize];
        let crossings = w
            .windows(2)
            .filter(|p| (p[0] < 0.0) != (p[1] < 0.0))
            .count();
        let f0 = fundamental_hz(60);
        assert!(
            (crossings as f64 / 0.5 - 2.0 * f0).abs() < 0.25 * 2.0 * f0,
            "{crossings}"
        );
    }

    #[test]
    fn the_sustain_pedal_holds_the_damper_off() {
        let pedal = [(0.0, true), (2.0, false), (3.0, true)];
        assert_eq!(damper_time(1.0, &pedal), 2.0);
        assert_eq!(damper_time(2.5, &pedal), 2.5);
        assert_eq!(damper_time(3.5, &pedal), f64::INFINITY);
        assert_eq!(damper_time(1.0, &[]), 1.0);
    }

    #[test]
    fn normalising_never_clips() {
        let x = [0.0f32, 2.0, -4.0, 1.0];
        let y = normalise_i16(&x, 0.9);
        assert_eq!(y[2], -(0.9f64 * 32767.0).round() as i16);
        assert!(y.iter().all(|&v| v > i16::MIN));
        assert_eq!(normalise_i16(&[0.0; 3], 0.9), vec![0; 3]);
    }
}
