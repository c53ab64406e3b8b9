//! The figures of the regulation sheet: what each one is, its unit and how it is named on the
//! sheet. The static figures are what a technician reads off an action with weights and a
//! ruler; the dynamic ones (hammer speeds, travel times, key bottom against string contact)
//! what a player meets at speed ([`super::dynamic`]).

/// A figure of the regulation sheet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Figure {
    /// Least constant weight that takes the key from rest down (to the let-off zone on a
    /// hammer action, else to the key bed), gf.
    DownWeight,
    /// Most constant weight under which a key held at the bottom still returns to rest, gf.
    UpWeight,
    /// `(down − up) / 2`, gf.
    Friction,
    /// `(down + up) / 2`, gf.
    BalanceWeight,
    /// Least constant weight that takes the key from rest through let-off to the key bed,
    /// gf (hammer actions).
    LetoffWeight,
    /// Least amount by which the quasi-static force going down exceeds the force going up
    /// over 20–70 % of the dip, gf.
    Hysteresis,
    /// Least amount by which the quasi-static force going down exceeds the force going up
    /// from 10 % of the dip to the let-off zone (or the bottom), gf.
    HysteresisToLetoff,
    /// Largest travel of a key held at half its dip by the balance weight, over
    /// [`super::CREEP_S`] from the moment the finger lets the weight hold it, mm.
    Creep,
    /// Key travel from rest to the key bed, mm.
    KeyDip,
    /// Hammer distance from the string when the jack escapes (slow dip), mm.
    LetOff,
    /// How far the hammer falls after let-off onto the repetition lever (slow dip), mm.
    Drop,
    /// Key travel after let-off to the key bed, mm.
    Aftertouch,
    /// Hammer travel from rest to the string, mm.
    BlowDistance,
    /// Hammer distance from the string where the back-check holds it after a blow with
    /// the key held down, mm.
    BackCheck,
    /// Time from the start of a *pp* push to the key bed, ms.
    KeyBottomPp,
    /// Time from the start of an *ff* push to the key bed, ms.
    KeyBottomFf,
    /// Hammer (or plectrum) speed at the strike of a *pp* push, m/s.
    StrikeSpeedPp,
    /// Hammer (or plectrum) speed at the strike of an *ff* push, m/s.
    StrikeSpeedFf,
    /// Fastest repetition that strikes every note, notes per second.
    Repetition,
    /// Least hammer (or plectrum) speed at the string over the dynamic sweep: the softest
    /// touch that strikes, m/s ([`super::dynamic`]).
    HammerSpeedMin,
    /// Greatest hammer speed over the dynamic sweep: the loudest, m/s.
    HammerSpeedMax,
    /// Least hammer speed / the key's peak speed over the touches of levels *p* to *f*.
    SpeedRatioMin,
    /// Greatest hammer speed / the key's peak speed over *p* to *f*.
    SpeedRatioMax,
    /// Median travel time (finger contact to string contact) of the pressed touches over
    /// the published fit's at the same hammer speed.
    TravelTimeToFit,
    /// Pressed minus struck travel time at equal hammer speed, ms (median).
    StruckSooner,
    /// Key bottom minus string contact at the softest touch that strikes, ms.
    KeyBottomSoft,
    /// Key bottom minus string contact at the loudest touch, ms.
    KeyBottomLoud,
    /// Hammer speed where key bottom minus string contact changes sign, m/s.
    KeyBottomCrossing,
}

impl Figure {
    /// Every figure, in the sheet's order.
    pub const ALL: [Figure; 28] = [
        Figure::DownWeight,
        Figure::UpWeight,
        Figure::Friction,
        Figure::BalanceWeight,
        Figure::LetoffWeight,
        Figure::Hysteresis,
        Figure::HysteresisToLetoff,
        Figure::Creep,
        Figure::KeyDip,
        Figure::LetOff,
        Figure::Drop,
        Figure::Aftertouch,
        Figure::BlowDistance,
        Figure::BackCheck,
        Figure::KeyBottomPp,
        Figure::KeyBottomFf,
        Figure::StrikeSpeedPp,
        Figure::StrikeSpeedFf,
        Figure::Repetition,
        Figure::HammerSpeedMin,
        Figure::HammerSpeedMax,
        Figure::SpeedRatioMin,
        Figure::SpeedRatioMax,
        Figure::TravelTimeToFit,
        Figure::StruckSooner,
        Figure::KeyBottomSoft,
        Figure::KeyBottomLoud,
        Figure::KeyBottomCrossing,
    ];

    /// Whether the figure belongs to the dynamic sheet (the touch sweep of [`super::dynamic`]).
    pub fn is_dynamic(self) -> bool {
        self >= Figure::HammerSpeedMin
    }

    /// The figure's name in a spec file and in JSON (`down_weight`).
    pub fn key(self) -> &'static str {
        match self {
            Figure::DownWeight => "down_weight",
            Figure::UpWeight => "up_weight",
            Figure::Friction => "friction",
            Figure::BalanceWeight => "balance_weight",
            Figure::LetoffWeight => "letoff_weight",
            Figure::Hysteresis => "hysteresis",
            Figure::HysteresisToLetoff => "hysteresis_to_letoff",
            Figure::Creep => "creep",
            Figure::KeyDip => "key_dip",
            Figure::LetOff => "let_off",
            Figure::Drop => "drop",
            Figure::Aftertouch => "aftertouch",
            Figure::BlowDistance => "blow_distance",
            Figure::BackCheck => "back_check",
            Figure::KeyBottomPp => "key_bottom_pp",
            Figure::KeyBottomFf => "key_bottom_ff",
            Figure::StrikeSpeedPp => "strike_speed_pp",
            Figure::StrikeSpeedFf => "strike_speed_ff",
            Figure::Repetition => "repetition",
            Figure::HammerSpeedMin => "hammer_speed_min",
            Figure::HammerSpeedMax => "hammer_speed_max",
            Figure::SpeedRatioMin => "speed_ratio_min",
            Figure::SpeedRatioMax => "speed_ratio_max",
            Figure::TravelTimeToFit => "travel_time_to_fit",
            Figure::StruckSooner => "struck_sooner",
            Figure::KeyBottomSoft => "key_bottom_soft",
            Figure::KeyBottomLoud => "key_bottom_loud",
            Figure::KeyBottomCrossing => "key_bottom_crossing",
        }
    }

    /// The figure named `key` ([`Figure::key`]).
    pub fn from_key(key: &str) -> Option<Figure> {
        Figure::ALL.into_iter().find(|f| f.key() == key)
    }

    /// The figure's unit as printed (`gf`, `mm`, `ms`, `m/s`, `notes/s`, `×` for a ratio).
    pub fn unit(self) -> &'static str {
        match self {
            Figure::DownWeight
            | Figure::UpWeight
            | Figure::Friction
            | Figure::BalanceWeight
            | Figure::LetoffWeight
            | Figure::Hysteresis
            | Figure::HysteresisToLetoff => "gf",
            Figure::Creep
            | Figure::KeyDip
            | Figure::LetOff
            | Figure::Drop
            | Figure::Aftertouch
            | Figure::BlowDistance
            | Figure::BackCheck => "mm",
            Figure::KeyBottomPp
            | Figure::KeyBottomFf
            | Figure::StruckSooner
            | Figure::KeyBottomSoft
            | Figure::KeyBottomLoud => "ms",
            Figure::StrikeSpeedPp
            | Figure::StrikeSpeedFf
            | Figure::HammerSpeedMin
            | Figure::HammerSpeedMax
            | Figure::KeyBottomCrossing => "m/s",
            Figure::Repetition => "notes/s",
            Figure::SpeedRatioMin | Figure::SpeedRatioMax | Figure::TravelTimeToFit => "×",
        }
    }

    /// The figure's name as the sheet prints it (`down-weight`).
    pub fn title(self) -> &'static str {
        match self {
            Figure::DownWeight => "down-weight",
            Figure::UpWeight => "up-weight",
            Figure::Friction => "friction",
            Figure::BalanceWeight => "balance weight",
            Figure::LetoffWeight => "weight through let-off",
            Figure::Hysteresis => "down − up, 20–70 % dip",
            Figure::HysteresisToLetoff => "down − up, to let-off",
            Figure::Creep => "creep held still, 1 s",
            Figure::KeyDip => "key dip",
            Figure::LetOff => "let-off",
            Figure::Drop => "drop",
            Figure::Aftertouch => "aftertouch",
            Figure::BlowDistance => "blow distance",
            Figure::BackCheck => "back-check",
            Figure::KeyBottomPp => "key bottom, pp",
            Figure::KeyBottomFf => "key bottom, ff",
            Figure::StrikeSpeedPp => "strike speed, pp",
            Figure::StrikeSpeedFf => "strike speed, ff",
            Figure::Repetition => "fastest repetition",
            Figure::HammerSpeedMin => "softest strike",
            Figure::HammerSpeedMax => "loudest strike",
            Figure::SpeedRatioMin => "hammer/key speed, p–f, min",
            Figure::SpeedRatioMax => "hammer/key speed, p–f, max",
            Figure::TravelTimeToFit => "travel time / Goebl fit",
            Figure::StruckSooner => "struck sooner than pressed",
            Figure::KeyBottomSoft => "key bottom − strike, soft",
            Figure::KeyBottomLoud => "key bottom − strike, loud",
            Figure::KeyBottomCrossing => "key bottom = strike at",
        }
    }
}
