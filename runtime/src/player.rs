//! The force-driven player: a finger pushes a key with a force profile, the instrument's
//! commanded force pushes back, and the key moves by Newton's law — the closed loop of
//! MIKEY's second validation experiment (key and finger mass, a finger force profile, the
//! commanded instrument force opposing, integrated at the sample rate) instead of a
//! prescribed key trajectory. The structure follows that experiment; the finger's mass and
//! force profiles below are our own choices, not the paper's numbers.
//!
//! **The law.** Key travel `x` (m, at the key front, 0 = rest, `dip` = key bottom) and its
//! speed `v` (m/s) obey
//!
//! ```text
//! m · dv/dt = f_finger(t) − f_instrument(x, history)
//! ```
//!
//! with `m` the mass of the key and the finger together referred to the key front (kg),
//! `f_finger` the finger's push (N, positive down) and `f_instrument` the force the
//! instrument commands (N, positive up: the grand piano's weight term `G` is positive, so a
//! key that nobody pushes rises back). One step per sample, semi-implicit (symplectic) Euler
//! at the sample rate: `v ← v + dt·(f_finger − f_instrument)/m`, then `x ← x + dt·v`.
//! The key stops are inelastic: travel is clamped to `[0, dip]` and the speed into a stop is
//! zeroed (the key bed and the rest rail are felt).
//!
//! The instrument sees only `x` (its sensor) and computes its force from it; the force of
//! sample `n` moves the key to its travel of sample `n + 1`, so the loop has the one-sample
//! delay of the real board (ADC read → force → DAC).
//!
//! **The finger.** A [`Stroke`] is one press: the force rises as a raised cosine over
//! [`FingerConfig::rise_s`] to its peak, stays there for the push (until the expected
//! strike), falls to a holding force [`FingerConfig::hold_n`] that keeps the key down until
//! the note-off, and is removed at the note-off (the finger lifts: force 0). A [`ForceProfile`]
//! is the strokes of one key in time order; a stroke that starts while the key is still
//! rising re-strikes from a half-released key.
//!
//! **Numbers.** MIKEY does not publish the finger's mass; [`FingerConfig::default`] uses
//! 30 g at the key front (a fingertip's effective mass is of the order of 10–20 g and the
//! key's own, beyond what an instrument simulates, about 10 g) — an assumption of ours, to be
//! set per experiment.
//!
//! **A pianist's touch** ([`Touch`]). The lumped key and finger above is what a weight or a
//! held finger needs. A pianist meets the key in two ways (W. Goebl, R. Bresin and A.
//! Galembo, "Touch and temporal behavior of grand piano actions", JASA 118(2), 2005): a
//! *pressed* touch starts with the finger resting on the key and pushes it down; a *struck*
//! touch arrives with the finger already moving and hits the key, then pushes. The finger
//! and the key are then two bodies ([`ForcePlayer::with_fingertip`], [`Fingertip`]): the
//! key (its own mass at the key front) and the finger (its effective mass), joined by the
//! fingertip's pulp, a spring and a damper that can only push. A struck finger meets the key
//! with its speed and the pulp throws the key ahead of it within a few milliseconds; a
//! pressed finger starts on the key at rest. Both then push with a force rising as a raised
//! cosine over [`Touch::rise_s`] to [`Touch::push_n`]. [`Touch::at`] gives the touches of a
//! dynamic level from *pp* to *fff* ([`Dynamic`]); their numbers and sources are on
//! [`Touch::at`] and [`Fingertip::default`].

/// The finger and key as the player sees them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FingerConfig {
    /// Key and finger mass referred to the key front, kg.
    pub mass_kg: f64,
    /// Rise time of a stroke's force from 0 to its peak (raised cosine), s.
    pub rise_s: f64,
    /// Force that holds the key down between the push and the note-off, N.
    pub hold_n: f64,
}

impl Default for FingerConfig {
    /// 30 g, 5 ms rise, 1.2 N hold (above the grand piano's ≈ 0.5 N down-weight, so a held
    /// key stays down).
    fn default() -> Self {
        FingerConfig {
            mass_kg: 0.030,
            rise_s: 0.005,
            hold_n: 1.2,
        }
    }
}

/// One press of a finger on a key.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stroke {
    /// When the finger starts pushing, s.
    pub start_s: f64,
    /// Peak force of the push, N.
    pub peak_n: f64,
    /// When the push ends and the holding force takes over, s (≥ `start_s`).
    pub push_end_s: f64,
    /// When the finger lifts (force 0), s (≥ `push_end_s`).
    pub lift_s: f64,
}

/// The finger force on one key over time: its strokes, in time order.
#[derive(Clone, Debug, PartialEq)]
pub struct ForceProfile {
    config: FingerConfig,
    strokes: Vec<Stroke>,
}

impl ForceProfile {
    /// A profile from strokes (sorted here by start time). A stroke's push and hold are cut
    /// short by the start of the next one.
    pub fn new(config: FingerConfig, mut strokes: Vec<Stroke>) -> Self {
        strokes.sort_by(|a, b| a.start_s.total_cmp(&b.start_s));
        ForceProfile { config, strokes }
    }

    /// The strokes, by start time.
    pub fn strokes(&self) -> &[Stroke] {
        &self.strokes
    }

    /// The finger's force at time `t` (s), N (positive pushes the key down).
    pub fn force(&self, t: f64) -> f64 {
        let i = self.strokes.partition_point(|s| s.start_s <= t);
        if i == 0 {
            return 0.0;
        }
        let s = &self.strokes[i - 1];
        let c = &self.config;
        if t >= s.lift_s {
            return 0.0;
        }
        let since = t - s.start_s;
        let push = if since < c.rise_s {
            let u = since / c.rise_s;
            s.peak_n * 0.5 * (1.0 - (std::f64::consts::PI * u).cos())
        } else {
            s.peak_n
        };
        if t < s.push_end_s {
            push
        } else {
            // The push relaxes to the holding force over one rise time.
            let u = ((t - s.push_end_s) / c.rise_s).min(1.0);
            push + (c.hold_n - push) * u
        }
    }
}

/// How a finger meets the key (Goebl, Bresin and Galembo 2005's two kinds of touch).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TouchKind {
    /// The finger rests on the key at rest, then pushes it down.
    Pressed,
    /// The finger arrives moving and hits the key, then pushes it down.
    Struck,
}

impl TouchKind {
    /// `pressed` or `struck`.
    pub fn name(self) -> &'static str {
        match self {
            TouchKind::Pressed => "pressed",
            TouchKind::Struck => "struck",
        }
    }
}

/// A dynamic level, from *pianissimo* to *fortississimo*.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Dynamic {
    /// *pianissimo*
    Pp,
    /// *piano*
    P,
    /// *mezzo-piano*
    Mp,
    /// *mezzo-forte*
    Mf,
    /// *forte*
    F,
    /// *fortissimo*
    Ff,
    /// *fortississimo*
    Fff,
}

impl Dynamic {
    /// Every level, softest first.
    pub const ALL: [Dynamic; 7] = [
        Dynamic::Pp,
        Dynamic::P,
        Dynamic::Mp,
        Dynamic::Mf,
        Dynamic::F,
        Dynamic::Ff,
        Dynamic::Fff,
    ];

    /// `pp`, `p`, `mp`, `mf`, `f`, `ff`, `fff`.
    pub fn name(self) -> &'static str {
        match self {
            Dynamic::Pp => "pp",
            Dynamic::P => "p",
            Dynamic::Mp => "mp",
            Dynamic::Mf => "mf",
            Dynamic::F => "f",
            Dynamic::Ff => "ff",
            Dynamic::Fff => "fff",
        }
    }

    /// The level named `name` ([`Dynamic::name`]).
    pub fn from_name(name: &str) -> Option<Dynamic> {
        Dynamic::ALL.into_iter().find(|d| d.name() == name)
    }

    /// 0 for *pp* … 6 for *fff*.
    fn index(self) -> usize {
        self as usize
    }
}

/// Pressed pushes of the levels, N, *pp* … *fff*: from 0.8 N, "for a force of about 0.8 N
/// the key takes about 150 ms to touch the keybed" (A. Askenfelt, ed., *Five Lectures on
/// the Acoustics of the Piano*, 1990), to 50 N, the peak key force a haptic grand key was
/// sized for (B. Timmermans, B. Dehez, P. Fisette, Machines 8(4), 2020: 50 N within 20 ms;
/// Tactus DESIGN.md), log-spaced (each level about twice the last).
pub const PRESSED_PUSH_N: [f64; 7] = [0.8, 1.6, 3.2, 6.3, 12.6, 25.0, 50.0];

/// Finger speeds at the key of the struck levels, m/s, *pp* … *fff*, log-spaced from
/// 0.1 to 3 m/s. No measured finger speed at the key was found to source them; they are
/// chosen so that the key's speeds span the peak key speeds of A. Askenfelt and E. Jansson
/// ("From touch to string vibrations", JASA 88(1), 1990: 0.3–0.5 m/s at *mf*, seldom above
/// 1 m/s at *f*) and beyond, to the fastest keys of a struck *fff*.
pub const STRUCK_SPEED_MPS: [f64; 7] = [0.1, 0.18, 0.31, 0.55, 0.96, 1.7, 3.0];

/// Rise time of a pressed touch's push (a raised cosine from 0 to its peak), s, at every
/// level. No measured rise of a pianist's finger force was found (nor per-level rise
/// times); 25 ms is calibrated against W. Goebl, R. Bresin and A. Galembo ("Touch and
/// temporal behavior of grand piano actions", JASA 118(2), 2005, as quoted by
/// discourse.zynthian.org, "Latencies pianists intuitively learn to handle"): "the whole
/// striking procedure needs roughly 20 ms less time with a struck touch compared to the
/// pressed touch, both with almost identical sound intensities". The struck touches, whose
/// push is whole at the contact, rest on their own numbers ([`STRUCK_SPEED_MPS`],
/// [`STRUCK_FINGER_KG`]); against them, over `tactus regulate`'s sweep on the grand piano
/// at grand88's 11, 8 and 3.5 g hammers, a pressed push rising over 20 ms reached the
/// string 18.6, 18.2 and 17.7 ms later at equal hammer speed, over 25 ms 21.3, 20.9 and
/// 20.3 ms, over 40 ms 30.0, 30.9 and 27.9 ms (issue 70). So the dynamic sheet's "struck
/// sooner than pressed" is this constant's calibration, not an independent check of the
/// action. (It was 20 ms, read off DESIGN.md's "peak key forces up to ≈ 50 N within
/// 20 ms", the haptic key's actuator sizing of B. Timmermans, B. Dehez and P. Fisette,
/// Machines 8(4), 2020: how fast the instrument's force must follow, not how fast a finger
/// pushes. With it the pressed touches' travel times fell below W. Goebl's fitted travel
/// times at the light treble hammers: 0.77 of the fit at 3.5 g.)
pub const PUSH_RISE_S: f64 = 0.025;

/// The finger's effective mass at the key front in a pressed touch, kg: the fingertip's,
/// [`Fingertip::default`]'s 20 g.
pub const PRESSED_FINGER_KG: f64 = 0.020;

/// The effective mass at the fingertip of a struck touch, kg: the finger thrown with the
/// hand from the wrist. Our estimate from the hand's anthropometry (a hand of about 0.45 kg
/// turning about the wrist with a radius of gyration of about 6 cm, its fingertip about
/// 12 cm out: 0.45·(6/12)² ≈ 0.11 kg); no measured value was found.
pub const STRUCK_FINGER_KG: f64 = 0.1;

/// One touch of a key: how the finger meets it and how hard it then pushes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Touch {
    /// Pressed or struck.
    pub kind: TouchKind,
    /// The finger's speed when it meets the key, m/s (0 for a pressed touch).
    pub contact_mps: f64,
    /// The push after the finger meets the key (peak of a raised-cosine rise), N.
    pub push_n: f64,
    /// Rise time of the push, s.
    pub rise_s: f64,
    /// The finger's effective mass at the key front, kg ([`PRESSED_FINGER_KG`],
    /// [`STRUCK_FINGER_KG`]).
    pub finger_kg: f64,
}

impl Touch {
    /// The touch of `kind` at `level`: a pressed touch pushes [`PRESSED_PUSH_N`] of its
    /// level; a struck touch arrives at [`STRUCK_SPEED_MPS`] of its level and then pushes as
    /// the pressed touch of the same level, whole at the contact; a pressed push rises over
    /// [`PUSH_RISE_S`].
    pub fn at(kind: TouchKind, level: Dynamic) -> Touch {
        let i = level.index();
        match kind {
            TouchKind::Pressed => Touch::pressed(PRESSED_PUSH_N[i]),
            TouchKind::Struck => Touch::struck(STRUCK_SPEED_MPS[i]),
        }
    }

    /// A pressed touch pushing `push_n` N (a [`PRESSED_FINGER_KG`] finger, rising over
    /// [`PUSH_RISE_S`]).
    pub fn pressed(push_n: f64) -> Touch {
        Touch {
            kind: TouchKind::Pressed,
            contact_mps: 0.0,
            push_n,
            rise_s: PUSH_RISE_S,
            finger_kg: PRESSED_FINGER_KG,
        }
    }

    /// A struck touch: a [`STRUCK_FINGER_KG`] finger meets the key at `speed_mps`, pushing
    /// as the levels push at its speed (log–log between the levels of [`STRUCK_SPEED_MPS`]
    /// and [`PRESSED_PUSH_N`], held beyond the ends): the push rose on the way down, and is
    /// whole at the contact (`rise_s` 0).
    pub fn struck(speed_mps: f64) -> Touch {
        let (sp, pu) = (&STRUCK_SPEED_MPS, &PRESSED_PUSH_N);
        let s = speed_mps.clamp(sp[0], sp[6]);
        let i = sp.partition_point(|&v| v < s).clamp(1, 6);
        let u = (s.ln() - sp[i - 1].ln()) / (sp[i].ln() - sp[i - 1].ln());
        let push = (pu[i - 1].ln() + u * (pu[i].ln() - pu[i - 1].ln())).exp();
        Touch {
            kind: TouchKind::Struck,
            contact_mps: speed_mps,
            push_n: push,
            // The push rose while the finger came down (it is what sped the finger): it is
            // whole when the finger meets the key.
            rise_s: 0.0,
            finger_kg: STRUCK_FINGER_KG,
        }
    }

    /// Reads a touch as `tactus sim --touch` takes it: `pressed:8N`, `struck:2.5m/s`,
    /// `pressed:pp` or `struck:fff` (a level, [`Touch::at`]); a number with its unit (`N`
    /// for a pressed push, `m/s` for a struck speed), spaces allowed before the unit.
    ///
    /// Errors: a message saying what is wrong and what is accepted.
    pub fn parse(text: &str) -> Result<Touch, String> {
        const FORMS: &str = "pressed:FORCE N, struck:SPEED m/s, or pressed:LEVEL / struck:LEVEL with LEVEL one of pp, p, mp, mf, f, ff, fff";
        let (kind, value) = text
            .split_once(':')
            .ok_or_else(|| format!("touch `{text}`: expected {FORMS}"))?;
        let kind = match kind.trim() {
            "pressed" => TouchKind::Pressed,
            "struck" => TouchKind::Struck,
            other => {
                return Err(format!(
                    "touch `{text}`: `{other}` is no kind of touch (pressed or struck)"
                ))
            }
        };
        let value = value.trim();
        if let Some(level) = Dynamic::from_name(value) {
            return Ok(Touch::at(kind, level));
        }
        let unit = match kind {
            TouchKind::Pressed => "N",
            TouchKind::Struck => "m/s",
        };
        let number = value.strip_suffix(unit).map(str::trim).ok_or_else(|| {
            format!(
                "touch `{text}`: a {} touch takes a number in {unit} or a level (pp … fff)",
                kind.name()
            )
        })?;
        let x: f64 = number
            .parse()
            .map_err(|_| format!("touch `{text}`: `{number}` is not a number"))?;
        let (lo, hi) = match kind {
            TouchKind::Pressed => (0.0, 200.0),
            TouchKind::Struck => (0.0, 10.0),
        };
        if !(x > lo && x <= hi) {
            return Err(format!(
                "touch `{text}`: {x} {unit} is outside (0, {hi}] {unit}"
            ));
        }
        Ok(match kind {
            TouchKind::Pressed => Touch::pressed(x),
            TouchKind::Struck => Touch::struck(x),
        })
    }

    /// The push `since_s` seconds after the finger met the key, N (0 before; a raised
    /// cosine rising to [`Touch::push_n`] over [`Touch::rise_s`], then held).
    pub fn push_at(&self, since_s: f64) -> f64 {
        if since_s < 0.0 {
            return 0.0;
        }
        if since_s >= self.rise_s || self.rise_s <= 0.0 {
            return self.push_n;
        }
        self.push_n * 0.5 * (1.0 - (std::f64::consts::PI * since_s / self.rise_s).cos())
    }

    /// The touch as `--touch` writes it (`struck:2.5m/s`, `pressed:8N`), to three
    /// significant digits.
    pub fn label(&self) -> String {
        match self.kind {
            TouchKind::Pressed => format!("pressed:{}N", three_digits(self.push_n)),
            TouchKind::Struck => format!("struck:{}m/s", three_digits(self.contact_mps)),
        }
    }
}

/// One key moved by a finger against the instrument's force (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct ForcePlayer {
    /// Key travel, m (0 = rest, `dip_m` = bottom).
    pub x_m: f64,
    /// Key speed, m/s (positive down).
    pub v_mps: f64,
    dip_m: f64,
    mass_kg: f64,
    dt_s: f64,
    /// The finger as a body of its own ([`ForcePlayer::with_fingertip`]); `None`: the
    /// finger is lumped into the key's mass and its push acts on the key directly.
    finger: Option<FingerBody>,
}

/// The fingertip between a finger and a key: the finger's effective mass, the key's own
/// mass, and the pulp that joins them while they touch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fingertip {
    /// The finger's effective mass moving with the fingertip, at the key front, kg.
    pub finger_kg: f64,
    /// The key's own mass at the key front, beyond what the instrument simulates, kg.
    pub key_kg: f64,
    /// Stiffness of the fingertip's pulp, N/m.
    pub pulp_n_per_m: f64,
    /// Damping of the pulp, N·s/m.
    pub pulp_ns_per_m: f64,
}

impl Default for Fingertip {
    /// A 20 g finger on a 10 g key (the lumped [`FingerConfig::default`]'s 30 g split as its
    /// documentation splits it); a pulp of 20 N/mm with 8 N·s/m. The fingertip's impedance
    /// is of that order in the literature (effective masses of grams to tens of grams,
    /// dampings of a few N·s/m, a pulp that stiffens to tens of N/mm under forces of
    /// newtons: V. Hajian and R. Howe, "Identification of the mechanical impedance at the
    /// human finger tip", J. Biomech. Eng. 119(1), 1997; E. Serina, C. Mote and D. Rempel,
    /// "Force response of the fingertip pulp to repeated compression", J. Biomech. 30(10),
    /// 1997; cited from memory, their tables not read here). The pulp is linear here, stiff
    /// enough that a 50 N push compresses it 2.5 mm; finger and key ring on it at about
    /// 275 Hz, far below the 44.1 kHz step.
    fn default() -> Self {
        Fingertip {
            finger_kg: 0.020,
            key_kg: 0.010,
            pulp_n_per_m: 20_000.0,
            pulp_ns_per_m: 8.0,
        }
    }
}

/// The finger as a body: where it is, how fast it moves, whether it is on the key.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FingerBody {
    tip: Fingertip,
    /// Finger travel at the key front, m (the key's surface is at `x_m`).
    y_m: f64,
    /// Finger speed, m/s (positive down).
    u_mps: f64,
    /// The finger touches the key or pushes towards it (placed, not lifted).
    down: bool,
    /// Pulp force of the last step, N.
    contact_n: f64,
}

impl ForcePlayer {
    /// A key at rest with dip `dip_m` (m), mass `mass_kg` (kg, key + finger at the key
    /// front), stepped at `sample_rate_hz`.
    pub fn new(dip_m: f64, mass_kg: f64, sample_rate_hz: f64) -> Self {
        ForcePlayer {
            x_m: 0.0,
            v_mps: 0.0,
            dip_m,
            mass_kg,
            dt_s: 1.0 / sample_rate_hz,
            finger: None,
        }
    }

    /// A key at rest with dip `dip_m` (m) and its own mass `tip.key_kg`, and a finger of
    /// `tip.finger_kg` off the key until [`ForcePlayer::place_finger`]: the two-body touch
    /// of the module documentation, stepped at `sample_rate_hz`.
    pub fn with_fingertip(dip_m: f64, tip: Fingertip, sample_rate_hz: f64) -> Self {
        ForcePlayer {
            finger: Some(FingerBody {
                tip,
                y_m: 0.0,
                u_mps: 0.0,
                down: false,
                contact_n: 0.0,
            }),
            ..ForcePlayer::new(dip_m, tip.key_kg, sample_rate_hz)
        }
    }

    /// The finger meets the key now, moving down at `speed_mps` (0: a pressed touch, the
    /// finger laid on the key; more: a struck touch). No effect on a lumped player.
    pub fn place_finger(&mut self, speed_mps: f64) {
        let x = self.x_m;
        if let Some(f) = &mut self.finger {
            f.y_m = x;
            f.u_mps = if speed_mps.is_finite() {
                speed_mps
            } else {
                0.0
            };
            f.down = true;
        }
    }

    /// The finger leaves the key (its push no longer reaches it). No effect on a lumped
    /// player, whose push the caller sets to 0.
    pub fn lift_finger(&mut self) {
        if let Some(f) = &mut self.finger {
            f.down = false;
            f.contact_n = 0.0;
        }
    }

    /// The force of the fingertip on the key in the last step, N (the push itself on a
    /// lumped player: `None` then).
    pub fn contact_n(&self) -> Option<f64> {
        self.finger.map(|f| f.contact_n)
    }

    /// The key's dip, m (its bed).
    pub fn dip_m(&self) -> f64 {
        self.dip_m
    }

    /// The finger's speed, m/s (`None` on a lumped player).
    pub fn finger_speed_mps(&self) -> Option<f64> {
        self.finger.map(|f| f.u_mps)
    }

    /// One sample: the finger pushes with `finger_n` (N, down), the instrument with
    /// `instrument_n` (N, up). Returns the new key travel, m (semi-implicit Euler, travel
    /// clamped to `[0, dip]`, speed into a stop zeroed).
    ///
    /// With a fingertip ([`ForcePlayer::with_fingertip`]), `finger_n` pushes the finger, not
    /// the key: the pulp's force `k·δ + c·δ'` (δ the finger's travel beyond the key's
    /// surface, positive only while they touch, never pulling) moves the key; a lifted
    /// finger pushes nothing.
    pub fn step(&mut self, finger_n: f64, instrument_n: f64) -> f64 {
        let (x, v, dt) = (self.x_m, self.v_mps, self.dt_s);
        let on_key = match &mut self.finger {
            None => finger_n,
            Some(f) if !f.down => 0.0,
            Some(f) => {
                let t = f.tip;
                let depth = f.y_m - x;
                let pulp = if depth > 0.0 {
                    (t.pulp_n_per_m * depth + t.pulp_ns_per_m * (f.u_mps - v)).max(0.0)
                } else {
                    0.0
                };
                let push = if finger_n.is_finite() { finger_n } else { 0.0 };
                f.u_mps += dt * (push - pulp) / t.finger_kg;
                f.y_m += dt * f.u_mps;
                f.contact_n = pulp;
                pulp
            }
        };
        let f = on_key - instrument_n;
        let a = if f.is_finite() { f / self.mass_kg } else { 0.0 };
        self.v_mps += self.dt_s * a;
        self.x_m += self.dt_s * self.v_mps;
        if self.x_m <= 0.0 {
            self.x_m = 0.0;
            self.v_mps = self.v_mps.max(0.0);
        } else if self.x_m >= self.dip_m {
            self.x_m = self.dip_m;
            self.v_mps = self.v_mps.min(0.0);
        }
        self.x_m
    }
}

/// `x` to three significant digits, without trailing zeros (`2.5`, `0.552`, `50`).
fn three_digits(x: f64) -> String {
    if !(x.is_finite() && x > 0.0) {
        return format!("{x}");
    }
    let decimals = (2 - x.log10().floor() as i32).max(0) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

/// How long a [`TouchPlay`] keeps pushing after the key first reaches its bed, s (a
/// pianist's push does not stop at the instant of the key bottom).
pub const PUSH_AFTER_BOTTOM_S: f64 = 0.030;

/// The longest a [`TouchPlay`] pushes before it relaxes, s, bed or not (a push too weak to
/// take the key down is a push that failed).
pub const MAX_PUSH_S: f64 = 0.6;

/// One [`Touch`] played on a key from rest, sample by sample, with a two-body finger
/// ([`ForcePlayer::with_fingertip`]): the finger meets the key `start_s` in, pushes (the
/// touch's rising push) until [`PUSH_AFTER_BOTTOM_S`] after the key first reaches its bed
/// (or [`MAX_PUSH_S`]), relaxes over [`PUSH_RISE_S`] to `hold_n` (or stays at a push
/// weaker than that), which holds the key down, and lifts at `lift_s`. The touch's finger
/// mass ([`Touch::finger_kg`]) replaces the fingertip's. `tactus sim --touch` and `tactus regulate`'s dynamic sheet
/// both play touches through it.
#[derive(Clone, Debug, PartialEq)]
pub struct TouchPlay {
    touch: Touch,
    player: ForcePlayer,
    dt_s: f64,
    /// Samples stepped so far.
    n: usize,
    start_s: f64,
    lift_s: f64,
    hold_n: f64,
    /// When the key first reached its bed, s.
    bottom_s: Option<f64>,
    /// The finger's push of the last step, N.
    push_n: f64,
}

impl TouchPlay {
    /// `touch` on a key of dip `dip_m` (m) with the fingertip `tip`, stepped at
    /// `sample_rate_hz`: the finger meets the key at `start_s`, holds it down with `hold_n`
    /// after the push, lifts at `lift_s` (s).
    pub fn new(
        touch: Touch,
        dip_m: f64,
        tip: Fingertip,
        sample_rate_hz: f64,
        start_s: f64,
        hold_n: f64,
        lift_s: f64,
    ) -> Self {
        let tip = Fingertip {
            finger_kg: touch.finger_kg,
            ..tip
        };
        TouchPlay {
            touch,
            player: ForcePlayer::with_fingertip(dip_m, tip, sample_rate_hz),
            dt_s: 1.0 / sample_rate_hz,
            n: 0,
            start_s,
            lift_s,
            hold_n,
            bottom_s: None,
            push_n: 0.0,
        }
    }

    /// Key travel for the next sample, m.
    pub fn key_m(&self) -> f64 {
        self.player.x_m
    }

    /// The player (key and finger) as it stands.
    pub fn player(&self) -> &ForcePlayer {
        &self.player
    }

    /// When the key first reached its bed, s from the start.
    pub fn bottom_s(&self) -> Option<f64> {
        self.bottom_s
    }

    /// The finger's push of the last step, N (its muscles', not the pulp's force on the key:
    /// [`ForcePlayer::contact_n`]).
    pub fn push_n(&self) -> f64 {
        self.push_n
    }

    /// One sample: the instrument answered the last travel with `instrument_n` (N, up); the
    /// finger pushes and the key moves. Returns the key travel of the next sample, m.
    pub fn step(&mut self, instrument_n: f64) -> f64 {
        let t = self.n as f64 * self.dt_s;
        if self.n == (self.start_s / self.dt_s).round() as usize {
            self.player.place_finger(self.touch.contact_mps);
        }
        if self.n == (self.lift_s / self.dt_s).round() as usize {
            self.player.lift_finger();
        }
        let since = t - self.start_s;
        let relax_at = self
            .bottom_s
            .map_or(self.start_s + MAX_PUSH_S, |b| b + PUSH_AFTER_BOTTOM_S)
            .min(self.start_s + MAX_PUSH_S);
        let push = if t < relax_at {
            self.touch.push_at(since)
        } else {
            // Down to the holding force, never up to it: a push weaker than the hold
            // lets go of the key as it was.
            let u = ((t - relax_at) / PUSH_RISE_S).min(1.0);
            let from = self.touch.push_at(relax_at - self.start_s);
            from + (self.hold_n.min(from) - from) * u
        };
        self.push_n = if t >= self.lift_s || since < 0.0 {
            0.0
        } else {
            push
        };
        let x = self.player.step(self.push_n, instrument_n);
        self.n += 1;
        if self.bottom_s.is_none() && x >= self.player.dip_m {
            self.bottom_s = Some(self.n as f64 * self.dt_s);
        }
        x
    }
}

/// Finger force and lead time for a wanted hammer speed, from measured single strokes.
///
/// Each level is one stroke of peak force `peak_n` on a key at rest, measured on the
/// instrument: `lead_s`, the time from the start of the push to the strike, and `speed_mps`,
/// the strike's hammer speed. [`Calibration::for_speed`] interpolates (log–log) between the
/// levels, so a player can aim at a hammer speed and start early enough to strike on time.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// (peak force N, lead s, hammer speed m/s), by increasing speed.
    levels: Vec<(f64, f64, f64)>,
}

impl Calibration {
    /// A calibration from measured levels (peak N, lead s, speed m/s). Levels that did not
    /// strike are left out by the caller; levels whose speed does not exceed every weaker
    /// level's are dropped, so the table is monotonic. `None` when fewer than two remain.
    pub fn new(mut levels: Vec<(f64, f64, f64)>) -> Option<Self> {
        levels.retain(|l| l.0 > 0.0 && l.1 >= 0.0 && l.2 > 0.0);
        levels.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut kept: Vec<(f64, f64, f64)> = Vec::new();
        for l in levels {
            if kept.last().is_none_or(|k| l.2 > k.2) {
                kept.push(l);
            }
        }
        (kept.len() >= 2).then_some(Calibration { levels: kept })
    }

    /// The levels kept: (peak force N, lead s, hammer speed m/s), by increasing speed.
    pub fn levels(&self) -> &[(f64, f64, f64)] {
        &self.levels
    }

    /// (peak force N, lead s) for a hammer speed (m/s); clamped to the measured range.
    pub fn for_speed(&self, speed_mps: f64) -> (f64, f64) {
        let l = &self.levels;
        let s = speed_mps.clamp(l[0].2, l[l.len() - 1].2);
        let i = l.partition_point(|k| k.2 < s).clamp(1, l.len() - 1);
        let (a, b) = (l[i - 1], l[i]);
        let u = (s.ln() - a.2.ln()) / (b.2.ln() - a.2.ln());
        let peak = (a.0.ln() + u * (b.0.ln() - a.0.ln())).exp();
        let lead = a.1 + u * (b.1 - a.1);
        (peak, lead)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FS: f64 = 44_100.0;

    /// A toy instrument: a 0.5 N weight and a 20 N/m return spring (the key pushes up).
    fn toy(x: f64) -> f64 {
        0.5 + 20.0 * x
    }

    /// Runs a key under `profile` against [`toy`] for `seconds`; returns travel per sample.
    fn run(profile: &ForceProfile, seconds: f64) -> Vec<f64> {
        let mut p = ForcePlayer::new(0.010, 0.030, FS);
        (0..(seconds * FS) as usize)
            .map(|i| {
                let t = i as f64 / FS;
                let x = p.x_m;
                p.step(profile.force(t), toy(x));
                x
            })
            .collect()
    }

    fn stroke(peak: f64) -> ForceProfile {
        ForceProfile::new(
            FingerConfig::default(),
            vec![Stroke {
                start_s: 0.01,
                peak_n: peak,
                push_end_s: 0.2,
                lift_s: 0.3,
            }],
        )
    }

    fn time_to_bottom(x: &[f64]) -> Option<f64> {
        x.iter().position(|&x| x >= 0.010).map(|i| i as f64 / FS)
    }

    #[test]
    fn a_stronger_push_bottoms_sooner_and_the_key_returns_when_released() {
        let weak = run(&stroke(1.0), 0.6);
        let strong = run(&stroke(4.0), 0.6);
        let (tw, ts) = (
            time_to_bottom(&weak).unwrap(),
            time_to_bottom(&strong).unwrap(),
        );
        assert!(ts < tw, "strong {ts} s, weak {tw} s");
        // Free fall under constant net force: t = sqrt(2·dip·m / F_net) gives the order.
        assert!(ts > 0.01 && ts < 0.01 + 0.02, "{ts}");
        // Held down while the hold force exceeds the instrument's force at the bottom …
        let at = |x: &[f64], t: f64| x[(t * FS) as usize];
        assert_eq!(at(&strong, 0.25), 0.010);
        // … and back at rest after the finger lifts at 0.3 s.
        assert_eq!(at(&strong, 0.59), 0.0);
        assert!(at(&strong, 0.31) > 0.0);
        // Never outside the stops.
        assert!(strong.iter().all(|&x| (0.0..=0.010).contains(&x)));
    }

    #[test]
    fn no_push_no_motion_and_a_push_below_the_weight_does_not_move_the_key() {
        assert!(run(&stroke(0.0), 0.1).iter().all(|&x| x == 0.0));
        let mut p = ForceProfile::new(FingerConfig::default(), vec![]);
        assert_eq!(p.force(1.0), 0.0);
        p = stroke(0.4); // below the 0.5 N weight
        p.config = FingerConfig {
            hold_n: 0.4,
            ..FingerConfig::default()
        };
        assert!(run(&p, 0.4).iter().all(|&x| x == 0.0));
    }

    #[test]
    fn a_restrike_starts_from_a_half_released_key() {
        let cfg = FingerConfig::default();
        let p = ForceProfile::new(
            cfg,
            vec![
                Stroke {
                    start_s: 0.0,
                    peak_n: 4.0,
                    push_end_s: 0.05,
                    lift_s: 0.1,
                },
                Stroke {
                    start_s: 0.115,
                    peak_n: 4.0,
                    push_end_s: 0.2,
                    lift_s: 0.3,
                },
            ],
        );
        let x = run(&p, 0.3);
        let lowest = x[(0.1 * FS) as usize..(0.2 * FS) as usize]
            .iter()
            .fold(f64::INFINITY, |a, &b| a.min(b));
        assert!(lowest > 0.0 && lowest < 0.010, "{lowest}");
        assert_eq!(x[(0.18 * FS) as usize], 0.010);
    }

    #[test]
    fn force_profile_shape() {
        let p = stroke(3.0);
        assert_eq!(p.force(0.0), 0.0);
        assert!((p.force(0.01 + 0.0025) - 1.5).abs() < 1e-9);
        assert_eq!(p.force(0.1), 3.0);
        assert!((p.force(0.25) - FingerConfig::default().hold_n).abs() < 1e-12);
        assert_eq!(p.force(0.3), 0.0);
    }

    /// A struck finger on a free key (no instrument force, the stops far away): the pulp's
    /// force acts on both bodies, equal and opposite, so the momentum the finger brings,
    /// `m_f · v0`, is shared and kept exactly, sample after sample; the pulp throws the key
    /// ahead, and once they part (the damper pulls nothing) key and finger keep their speeds.
    #[test]
    fn a_struck_finger_shares_its_momentum_with_the_key() {
        let tip = Fingertip::default();
        let mut p = ForcePlayer::with_fingertip(1.0, tip, FS);
        p.place_finger(2.0);
        let momentum =
            |p: &ForcePlayer| tip.finger_kg * p.finger_speed_mps().unwrap() + tip.key_kg * p.v_mps;
        let m0 = momentum(&p);
        assert!((m0 - 0.040).abs() < 1e-15);
        for _ in 0..(0.02 * FS) as usize {
            p.step(0.0, 0.0);
            assert!((momentum(&p) - m0).abs() < 1e-12, "{}", momentum(&p));
        }
        // Parted: the key runs ahead of the finger, faster than the common speed 4/3 m/s.
        assert_eq!(p.contact_n(), Some(0.0));
        let (u, v) = (p.finger_speed_mps().unwrap(), p.v_mps);
        assert!(
            v > m0 / (tip.finger_kg + tip.key_kg) && u < v,
            "finger {u}, key {v}"
        );
        // A lumped player has no finger to place.
        let mut lumped = ForcePlayer::new(0.01, 0.03, FS);
        lumped.place_finger(2.0);
        assert_eq!((lumped.v_mps, lumped.contact_n()), (0.0, None));
    }

    /// A pressed finger pushing a free key with a constant force: once the pulp has settled
    /// both move as one, accelerating at `F / (m_f + m_k)`; the pulp then carries the key's
    /// share, `F · m_k / (m_f + m_k)`. A lifted finger pushes nothing.
    #[test]
    fn a_pressed_finger_pushes_finger_and_key_as_one() {
        let tip = Fingertip::default();
        let mut p = ForcePlayer::with_fingertip(1.0, tip, FS);
        p.place_finger(0.0);
        let m = tip.finger_kg + tip.key_kg;
        let n = (0.05 * FS) as usize;
        for _ in 0..n {
            p.step(3.0, 0.0);
        }
        let v0 = p.v_mps;
        p.step(3.0, 0.0);
        let a = (p.v_mps - v0) * FS;
        assert!(
            (a - 3.0 / m).abs() < 0.01 * 3.0 / m,
            "{a} m/s², {} expected",
            3.0 / m
        );
        let share = 3.0 * tip.key_kg / m;
        assert!(
            (p.contact_n().unwrap() - share).abs() < 0.01,
            "{:?}",
            p.contact_n()
        );
        p.lift_finger();
        let v = p.v_mps;
        p.step(3.0, 0.0);
        assert_eq!(p.v_mps, v);
    }

    #[test]
    fn touches_parse_and_name_their_levels() {
        let t = Touch::parse("struck:2.5m/s").unwrap();
        assert_eq!((t.kind, t.contact_mps), (TouchKind::Struck, 2.5));
        // Between the levels' speeds, the push between their pushes.
        assert!(
            t.push_n > PRESSED_PUSH_N[5] && t.push_n < PRESSED_PUSH_N[6],
            "{t:?}"
        );
        let t = Touch::parse("pressed: 8 N").unwrap();
        assert_eq!(
            (t.kind, t.contact_mps, t.push_n),
            (TouchKind::Pressed, 0.0, 8.0)
        );
        assert_eq!(
            Touch::parse("struck:fff").unwrap(),
            Touch::at(TouchKind::Struck, Dynamic::Fff)
        );
        assert_eq!(Touch::parse("pressed:pp").unwrap().push_n, 0.8);
        for bad in [
            "struck",
            "hit:2m/s",
            "struck:2N",
            "pressed:2m/s",
            "pressed:-1N",
            "struck:x m/s",
            "struck:99m/s",
            "pressed:loud",
        ] {
            assert!(Touch::parse(bad).is_err(), "{bad}");
        }
        assert!(Touch::parse("hit:2m/s")
            .unwrap_err()
            .contains("pressed or struck"));
        // The push rises as a raised cosine and holds.
        let t = Touch::pressed(10.0);
        assert_eq!(t.push_at(-0.001), 0.0);
        assert!((t.push_at(0.5 * PUSH_RISE_S) - 5.0).abs() < 1e-12);
        assert_eq!(t.push_at(1.0), 10.0);
    }

    /// A touch played against [`toy`]: the key goes down, is held at its bed by the holding
    /// force, and returns when the finger lifts; the harder touch bottoms sooner, and a
    /// struck touch of a level sooner than the pressed one.
    #[test]
    fn a_touch_play_bottoms_holds_and_lifts() {
        let play = |touch: Touch| {
            let mut t = TouchPlay::new(touch, 0.010, Fingertip::default(), FS, 0.01, 1.2, 0.4);
            let mut x = Vec::new();
            for _ in 0..(0.6 * FS) as usize {
                let at = t.key_m();
                x.push(at);
                t.step(toy(at));
            }
            (t.bottom_s().unwrap(), x)
        };
        let (soft, x) = play(Touch::at(TouchKind::Pressed, Dynamic::P));
        let (loud, _) = play(Touch::at(TouchKind::Pressed, Dynamic::F));
        let (struck, _) = play(Touch::at(TouchKind::Struck, Dynamic::F));
        assert!(struck < loud && loud < soft, "{struck} {loud} {soft}");
        assert_eq!(x[(0.35 * FS) as usize], 0.010);
        assert_eq!(x[(0.59 * FS) as usize], 0.0);
        assert!(x.iter().all(|&x| (0.0..=0.010).contains(&x)));
    }

    #[test]
    fn calibration_interpolates_and_drops_non_monotonic_levels() {
        let c = Calibration::new(vec![
            (1.0, 0.10, 0.5),
            (4.0, 0.03, 4.0),
            (2.0, 0.05, 2.0),
            (3.0, 0.04, 1.5), // slower than the 2 N level: dropped
        ])
        .unwrap();
        assert_eq!(c.levels().len(), 3);
        let (f, lead) = c.for_speed(1.0);
        assert!(
            f > 1.0 && f < 2.0 && lead > 0.05 && lead < 0.10,
            "{f} {lead}"
        );
        assert_eq!(c.for_speed(100.0), (4.0, 0.03));
        assert_eq!(c.for_speed(0.0), (1.0, 0.10));
        assert!(Calibration::new(vec![(1.0, 0.1, 0.5)]).is_none());
    }
}
