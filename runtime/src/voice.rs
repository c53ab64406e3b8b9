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

/// The most oscillator steps a rendering of `samples` samples should be asked for (a
/// partial of a strike for one sample is one step): 2³³ (tens of seconds), or 256 a sample
/// on average for a longer piece, so that a recital's bound grows with it while a run whose
/// instrument strikes every sample (tens of thousands of strikes a second, each ringing for
/// seconds) is refused rather than rendered for hours. Callers check [`render_work`]
/// against it before rendering. A 10-minute recital of about 5,000 notes needs a few 10⁸
/// (about 10 a sample).
pub fn max_render_work(samples: f64) -> f64 {
    ((1u64 << 33) as f64).max(256.0 * samples)
}

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
/// 1 m/s strike's fundamental starts at amplitude about 1): [`Renderer`] in one block,
/// allocated whole (4 bytes a sample: a long piece streams through [`Renderer`] instead).
/// Check [`render_work`] against [`max_render_work`] first.
pub fn render(strikes: &[Strike], seconds: f64, sample_rate_hz: f64) -> Vec<f32> {
    let mut r = Renderer::new(strikes, seconds, sample_rate_hz);
    let mut buf = Vec::new();
    r.next_block(r.samples(), &mut buf);
    buf
}

/// One partial of one strike, sounding: a rotating phasor (cheap and exact in frequency)
/// under its envelope.
#[derive(Clone, Copy, Debug)]
struct Partial {
    /// Its strike's index in the renderer's list, and its number: the order in which the
    /// partials add into a sample.
    order: (usize, usize),
    /// Its strike's first sample, and the next sample it renders.
    i0: usize,
    i: usize,
    /// The sample the damper falls at (`usize::MAX`: never).
    damp_i: usize,
    amp: f64,
    env: f64,
    re: f64,
    im: f64,
    sin_w: f64,
    cos_w: f64,
    /// Per-sample decay factors before and after the damper.
    free: f64,
    damped: f64,
}

/// Renders strikes block by block (a streaming [`render`]): the same samples bit for bit —
/// each sample the sum of the same partials in the same order (strike by strike as listed,
/// partial by partial) — holding only the partials still sounding, so a recital of any
/// length renders in the memory of a block. Blocks run from sample 0 to
/// `seconds · sample_rate_hz`; the time it takes is [`render_work`]'s.
#[derive(Clone, Debug)]
pub struct Renderer<'s> {
    strikes: &'s [Strike],
    /// The strikes' indexes by first sample (strikes never sounding left out), and how many
    /// of them have started.
    starts: Vec<(usize, usize)>,
    started: usize,
    sounding: Vec<Partial>,
    n: usize,
    at: usize,
    fs: f64,
}

impl<'s> Renderer<'s> {
    /// A renderer of `strikes` over `seconds` at `sample_rate_hz`, before its first block.
    pub fn new(strikes: &'s [Strike], seconds: f64, sample_rate_hz: f64) -> Self {
        let n = (seconds.max(0.0) * sample_rate_hz).ceil() as usize;
        let mut starts: Vec<(usize, usize)> = (strikes.iter().enumerate())
            .filter(|(_, s)| !s.speed_mps.is_nan() && s.speed_mps > 0.0)
            .filter_map(|(j, s)| first_sample(s.time_s, sample_rate_hz).map(|i0| (i0, j)))
            .filter(|&(i0, _)| i0 < n)
            .collect();
        starts.sort_unstable();
        Renderer {
            strikes,
            starts,
            started: 0,
            sounding: Vec::new(),
            n,
            at: 0,
            fs: sample_rate_hz,
        }
    }

    /// Samples in all.
    pub fn samples(&self) -> usize {
        self.n
    }

    /// The partials of strike `j`, from its first sample `i0`.
    fn partials(&self, j: usize, i0: usize) -> impl Iterator<Item = Partial> + '_ {
        let s = &self.strikes[j];
        let dt = 1.0 / self.fs;
        let ln1000 = 1000f64.ln();
        let damp_i = if s.damp_s.is_finite() {
            first_sample(s.damp_s, self.fs).unwrap_or(0).max(i0)
        } else {
            usize::MAX
        };
        let loud = (s.speed_mps / 6.0).clamp(0.0, 1.0);
        let p = 2.0 - loud;
        (1..=PARTIALS)
            .map(move |k| (k, partial_hz(s.key, k)))
            .take_while(|&(_, f)| f < 0.45 * self.fs)
            .map(move |(k, f)| {
                let amp = s.speed_mps / (k as f64).powf(p);
                let (sin_w, cos_w) = (2.0 * std::f64::consts::PI * f * dt).sin_cos();
                Partial {
                    order: (j, k),
                    i0,
                    i: i0,
                    damp_i,
                    amp,
                    env: amp,
                    re: 1.0,
                    im: 0.0,
                    sin_w,
                    cos_w,
                    free: (-ln1000 * dt / t60_s(s.key, k)).exp(),
                    damped: (-ln1000 * dt / DAMPED_T60_S).exp(),
                }
            })
    }

    /// The next block of at most `most` samples into `out` (cleared first); false, `out`
    /// empty, when every sample has been given.
    pub fn next_block(&mut self, most: usize, out: &mut Vec<f32>) -> bool {
        out.clear();
        let end = self.at.saturating_add(most.max(1)).min(self.n);
        if self.at >= end {
            return false;
        }
        // The strikes starting in the block join the sounding, in their order.
        let mut joined = false;
        while let Some(&(i0, j)) = self.starts.get(self.started).filter(|s| s.0 < end) {
            let new: Vec<Partial> = self.partials(j, i0).collect();
            self.sounding.extend(new);
            self.started += 1;
            joined = true;
        }
        if joined {
            self.sounding.sort_by_key(|p| p.order);
        }
        out.resize(end - self.at, 0.0);
        let attack = (0.002 * self.fs).max(1.0);
        let (at, n) = (self.at, self.n);
        for p in &mut self.sounding {
            let mut i = p.i.max(at);
            while i < end && i < n && p.env > SILENCE * p.amp {
                let a = ((i - p.i0) as f64 + 1.0).min(attack) / attack;
                out[i - at] += (p.env * a * p.im) as f32;
                let r = p.re * p.cos_w - p.im * p.sin_w;
                p.im = p.re * p.sin_w + p.im * p.cos_w;
                p.re = r;
                p.env *= if i >= p.damp_i { p.damped } else { p.free };
                i += 1;
            }
            p.i = i;
        }
        self.sounding.retain(|p| p.i < n && p.env > SILENCE * p.amp);
        self.at = end;
        true
    }
}

fn first_sample(t: f64, fs: f64) -> Option<usize> {
    (t.is_finite() && t >= 0.0).then(|| (t * fs).round() as usize)
}

/// The factor that puts the peak of `samples` at `headroom` of 16-bit full scale (e.g. 0.9);
/// 0 for silence.
pub fn i16_scale(samples: &[f32], headroom: f64) -> f64 {
    peak_scale(peak(samples, 0.0), headroom)
}

/// The largest magnitude of `samples` and `so_far`.
pub fn peak(samples: &[f32], so_far: f32) -> f32 {
    samples.iter().fold(so_far, |m, &x| m.max(x.abs()))
}

/// The factor that puts `peak` at `headroom` of 16-bit full scale; 0 for silence.
pub fn peak_scale(peak: f32, headroom: f64) -> f64 {
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

    /// The whole-buffer rendering [`Renderer`] streams, written directly (strike by strike
    /// as listed, each partial over its whole life): the specification the blocks must
    /// match bit for bit.
    fn direct(strikes: &[Strike], seconds: f64, fs: f64) -> Vec<f32> {
        let n = (seconds * fs).ceil() as usize;
        let mut buf = vec![0f32; n];
        let (dt, ln1000, attack) = (1.0 / fs, 1000f64.ln(), (0.002 * fs).max(1.0));
        for s in strikes {
            let Some(i0) = first_sample(s.time_s, fs).filter(|&i| i < n) else {
                continue;
            };
            if s.speed_mps.is_nan() || s.speed_mps <= 0.0 {
                continue;
            }
            let damp_i = match s.damp_s.is_finite() {
                true => first_sample(s.damp_s, fs).unwrap_or(0).max(i0),
                false => usize::MAX,
            };
            let p = 2.0 - (s.speed_mps / 6.0).clamp(0.0, 1.0);
            for k in (1..=PARTIALS).take_while(|&k| partial_hz(s.key, k) < 0.45 * fs) {
                let amp = s.speed_mps / (k as f64).powf(p);
                let free = (-ln1000 * dt / t60_s(s.key, k)).exp();
                let damped = (-ln1000 * dt / DAMPED_T60_S).exp();
                let (sin_w, cos_w) =
                    (2.0 * std::f64::consts::PI * partial_hz(s.key, k) * dt).sin_cos();
                let (mut re, mut im, mut env) = (1.0f64, 0.0f64, amp);
                let mut i = i0;
                while i < n && env > SILENCE * amp {
                    let a = ((i - i0) as f64 + 1.0).min(attack) / attack;
                    buf[i] += (env * a * im) as f32;
                    (re, im) = (re * cos_w - im * sin_w, re * sin_w + im * cos_w);
                    env *= if i >= damp_i { damped } else { free };
                    i += 1;
                }
            }
        }
        buf
    }

    /// Blocks of any size give the whole rendering bit for bit, strikes listed out of time
    /// order, overlapping, damped and not, one past the end and one never sounding included.
    #[test]
    fn blocks_render_the_whole_bit_for_bit() {
        let strikes: Vec<Strike> = (0..40)
            .map(|j| Strike {
                key: 21 + (j * 37 % 88) as u8,
                time_s: (j * 7919 % 173) as f64 / 100.0,
                speed_mps: [0.2, 1.0, 4.0, 0.0][j % 4],
                damp_s: if j % 3 == 0 {
                    f64::INFINITY
                } else {
                    0.05 * j as f64
                },
            })
            .chain([Strike {
                key: 60,
                time_s: 9.0,
                speed_mps: 1.0,
                damp_s: f64::INFINITY,
            }])
            .collect();
        let whole = render(&strikes, 2.0, FS);
        assert_eq!(whole.len(), 88_200);
        // The first sample whose bits differ, if any.
        let differ = |a: &[f32], b: &[f32]| {
            (a.len() != b.len())
                .then_some(a.len().min(b.len()))
                .or_else(|| (a.iter().zip(b)).position(|(x, y)| x.to_bits() != y.to_bits()))
        };
        assert_eq!(differ(&whole, &direct(&strikes, 2.0, FS)), None);
        assert!(whole.iter().filter(|x| **x != 0.0).count() > 80_000);
        for block in [1, 441, 4096, 100_000] {
            let mut r = Renderer::new(&strikes, 2.0, FS);
            let (mut all, mut buf) = (Vec::new(), Vec::new());
            while r.next_block(block, &mut buf) {
                assert!(buf.len() <= block);
                all.extend_from_slice(&buf);
            }
            assert_eq!(differ(&all, &whole), None, "blocks of {block}");
            assert!(r.sounding.len() <= 8 * 40);
        }
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
