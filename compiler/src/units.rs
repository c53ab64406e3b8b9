//! Physical dimensions and the unit table.
//!
//! A dimension is a vector of integer exponents over the SI base quantities a touch profile
//! needs: length (m), mass (kg), time (s) and electric current (A). Angles are dimensionless,
//! as in SI (the radian is m/m), so `l2 * theta` with `l2` in metres and `theta` in radians is
//! a length, exactly as in the MIKEY equations. Every literal carries a unit; the unit's scale
//! converts it to SI when the literal is lexed, so the IR and every engine work in SI only.
//!
//! Source: BIPM, *The International System of Units* (SI Brochure, 9th ed., 2019), tables 2–4
//! for the derived units and prefixes used here.

use std::fmt;

/// Exponents of (length, mass, time, current) — `m^L kg^M s^T A^I`.
///
/// `Dim::NONE` is a pure number. Multiplication adds exponents, division subtracts them;
/// addition, comparison and `min`/`max` require equal dimensions.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Dim(pub [i8; 4]);

impl Dim {
    /// A pure number (also radians).
    pub const NONE: Dim = Dim([0, 0, 0, 0]);
    /// Metres.
    pub const LENGTH: Dim = Dim([1, 0, 0, 0]);
    /// Kilograms.
    pub const MASS: Dim = Dim([0, 1, 0, 0]);
    /// Seconds.
    pub const TIME: Dim = Dim([0, 0, 1, 0]);
    /// Amperes.
    pub const CURRENT: Dim = Dim([0, 0, 0, 1]);
    /// Newtons, kg·m/s².
    pub const FORCE: Dim = Dim([1, 1, -2, 0]);
    /// Metres per second.
    pub const VELOCITY: Dim = Dim([1, 0, -1, 0]);
    /// Hertz, 1/s.
    pub const FREQUENCY: Dim = Dim([0, 0, -1, 0]);

    /// The dimension raised to an integer power.
    pub fn powi(self, n: i32) -> Dim {
        Dim(std::array::from_fn(|i| {
            (self.0[i] as i32 * n).clamp(i8::MIN as i32, i8::MAX as i32) as i8
        }))
    }
    /// The square root, if every exponent is even.
    pub fn sqrt(self) -> Option<Dim> {
        if self.0.iter().all(|e| e % 2 == 0) {
            Some(Dim(std::array::from_fn(|i| self.0[i] / 2)))
        } else {
            None
        }
    }
    /// Whether this is a pure number.
    pub fn is_none(self) -> bool {
        self == Dim::NONE
    }
    /// The conventional name of the quantity, when it has one ("force", "velocity", …).
    pub fn quantity_name(self) -> Option<&'static str> {
        NAMED
            .iter()
            .find(|(d, _, _)| *d == self)
            .map(|(_, _, q)| *q)
    }
    /// The SI unit to print for this dimension (e.g. `N`, `N*s/m`, `kg*m^2`).
    pub fn unit_string(self) -> String {
        if let Some((_, u, _)) = NAMED.iter().find(|(d, _, _)| *d == self) {
            return u.to_string();
        }
        let names = ["m", "kg", "s", "A"];
        let mut num = Vec::new();
        let mut den = Vec::new();
        for (e, n) in self.0.iter().zip(names) {
            let term = |e: i32| {
                if e == 1 {
                    n.to_string()
                } else {
                    format!("{n}^{e}")
                }
            };
            match e.cmp(&0) {
                std::cmp::Ordering::Greater => num.push(term(i32::from(*e))),
                // In i32: the exponents saturate at i8::MIN, whose negation is no i8.
                std::cmp::Ordering::Less => den.push(term(-i32::from(*e))),
                std::cmp::Ordering::Equal => {}
            }
        }
        let num = if num.is_empty() {
            "1".to_string()
        } else {
            num.join("*")
        };
        if den.is_empty() {
            num
        } else {
            format!("{num}/{}", den.join("/"))
        }
    }
}

impl std::ops::Mul for Dim {
    type Output = Dim;
    /// The product dimension (exponents added).
    fn mul(self, o: Dim) -> Dim {
        Dim(std::array::from_fn(|i| self.0[i].saturating_add(o.0[i])))
    }
}

impl std::ops::Div for Dim {
    type Output = Dim;
    /// The quotient dimension (exponents subtracted).
    fn div(self, o: Dim) -> Dim {
        Dim(std::array::from_fn(|i| self.0[i].saturating_sub(o.0[i])))
    }
}

impl fmt::Debug for Dim {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.unit_string())
    }
}

impl fmt::Display for Dim {
    /// Prints the unit and, when known, the quantity: `N (force)`, `1 (dimensionless)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.quantity_name() {
            Some(q) => write!(f, "{} ({q})", self.unit_string()),
            None => write!(f, "{}", self.unit_string()),
        }
    }
}

/// Dimensions with a conventional unit spelling and quantity name, for messages.
const NAMED: &[(Dim, &str, &str)] = &[
    (Dim::NONE, "1", "dimensionless"),
    (Dim::LENGTH, "m", "length"),
    (Dim::MASS, "kg", "mass"),
    (Dim::TIME, "s", "time"),
    (Dim::CURRENT, "A", "current"),
    (Dim::FORCE, "N", "force"),
    (Dim::VELOCITY, "m/s", "velocity"),
    (Dim([1, 0, -2, 0]), "m/s^2", "acceleration"),
    (Dim::FREQUENCY, "1/s", "frequency or angular velocity"),
    (Dim([0, 0, -2, 0]), "1/s^2", "angular acceleration"),
    (Dim([0, 1, -2, 0]), "N/m", "stiffness"),
    (Dim([0, 1, -1, 0]), "N*s/m", "damping"),
    (Dim([2, 1, -2, 0]), "N*m", "torque or energy"),
    (Dim([2, 1, -1, 0]), "N*m*s", "rotational damping"),
    (Dim([2, 1, 0, 0]), "kg*m^2", "moment of inertia"),
    (Dim([2, 1, -3, -1]), "V", "voltage"),
    (Dim([2, 1, -2, -1]), "N*m/A", "torque constant"),
    (Dim([1, 1, -2, -1]), "N/A", "force constant"),
    (Dim([2, 1, -3, 0]), "W", "power"),
];

/// One entry of the unit table: a spelling, its dimension and its scale to SI.
#[derive(Clone, Copy, Debug)]
pub struct Unit {
    /// How it is written in source, e.g. `mm`.
    pub name: &'static str,
    /// Its dimension.
    pub dim: Dim,
    /// Multiply a value in this unit by `scale` to get SI (`mm` → 1e-3).
    pub scale: f64,
}

const DEG: f64 = std::f64::consts::PI / 180.0;

/// Every unit the language knows. Prefixed forms are listed explicitly (no general prefix
/// rule) so that a one-letter name like `m` cannot be misread as a prefix.
pub const UNITS: &[Unit] = &[
    Unit {
        name: "m",
        dim: Dim::LENGTH,
        scale: 1.0,
    },
    Unit {
        name: "cm",
        dim: Dim::LENGTH,
        scale: 1e-2,
    },
    Unit {
        name: "mm",
        dim: Dim::LENGTH,
        scale: 1e-3,
    },
    Unit {
        name: "um",
        dim: Dim::LENGTH,
        scale: 1e-6,
    },
    Unit {
        name: "kg",
        dim: Dim::MASS,
        scale: 1.0,
    },
    Unit {
        name: "g",
        dim: Dim::MASS,
        scale: 1e-3,
    },
    Unit {
        name: "mg",
        dim: Dim::MASS,
        scale: 1e-6,
    },
    Unit {
        name: "s",
        dim: Dim::TIME,
        scale: 1.0,
    },
    Unit {
        name: "ms",
        dim: Dim::TIME,
        scale: 1e-3,
    },
    Unit {
        name: "us",
        dim: Dim::TIME,
        scale: 1e-6,
    },
    Unit {
        name: "A",
        dim: Dim::CURRENT,
        scale: 1.0,
    },
    Unit {
        name: "mA",
        dim: Dim::CURRENT,
        scale: 1e-3,
    },
    Unit {
        name: "N",
        dim: Dim::FORCE,
        scale: 1.0,
    },
    Unit {
        name: "mN",
        dim: Dim::FORCE,
        scale: 1e-3,
    },
    Unit {
        name: "Hz",
        dim: Dim::FREQUENCY,
        scale: 1.0,
    },
    Unit {
        name: "kHz",
        dim: Dim::FREQUENCY,
        scale: 1e3,
    },
    Unit {
        name: "rad",
        dim: Dim::NONE,
        scale: 1.0,
    },
    Unit {
        name: "mrad",
        dim: Dim::NONE,
        scale: 1e-3,
    },
    Unit {
        name: "deg",
        dim: Dim::NONE,
        scale: DEG,
    },
    Unit {
        name: "J",
        dim: Dim([2, 1, -2, 0]),
        scale: 1.0,
    },
    Unit {
        name: "W",
        dim: Dim([2, 1, -3, 0]),
        scale: 1.0,
    },
    Unit {
        name: "V",
        dim: Dim([2, 1, -3, -1]),
        scale: 1.0,
    },
    Unit {
        name: "Pa",
        dim: Dim([-1, 1, -2, 0]),
        scale: 1.0,
    },
];

/// Looks a unit up by its spelling.
pub fn lookup(name: &str) -> Option<&'static Unit> {
    UNITS.iter().find(|u| u.name == name)
}

/// The unit spellings, for "did you mean" hints.
pub fn unit_names() -> impl Iterator<Item = &'static str> {
    UNITS.iter().map(|u| u.name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derived_dimensions() {
        let n = lookup("N").unwrap().dim;
        let m = lookup("m").unwrap().dim;
        let s = lookup("s").unwrap().dim;
        assert_eq!((n * s / m).unit_string(), "N*s/m");
        assert_eq!((n / m).quantity_name(), Some("stiffness"));
        assert_eq!((m / s / s).unit_string(), "m/s^2");
        assert_eq!(Dim([3, 0, -1, 2]).unit_string(), "m^3*A^2/s");
        assert_eq!(Dim([2, 0, 0, 0]).sqrt(), Some(Dim::LENGTH));
        assert_eq!(Dim::LENGTH.sqrt(), None);
    }
}
