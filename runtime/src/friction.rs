//! Friction characteristics as functions, for plotting and for checking an instrument's
//! friction term against its source: Bilbao's φ(v, a), the one the rubbing and bowing
//! instruments write in the language (`instruments/rubbed_bank.tactus`,
//! `instruments/bowed_string.tactus`); `tactus plot friction` draws it.

/// The default values of `a`, s²/m²: Onofrei et al. 2023's range, 0.01 to 15000.
pub const DEFAULT_A: [f64; 4] = [0.01, 1.0, 100.0, 15000.0];

/// Uniform grid points over [−v_max, v_max] (the extremes ±1/√(2a) inside it are added).
pub const GRID: usize = 4001;

/// Bilbao's friction characteristic φ(v, a) = √(2a)·v·exp(−a·v² + ½), dimensionless, for
/// relative velocity `v` (m/s) and `a` (s²/m²): odd in `v`, extremes ±1 at `v = ±1/√(2a)`
/// (Bilbao, Numerical Sound Synthesis, 2009; Onofrei, Fontana, Serafin 2023, eq. of the
/// rubbing and bowing models).
pub fn bilbao_phi(v: f64, a: f64) -> f64 {
    (2.0 * a).sqrt() * v * (-a * v * v + 0.5).exp()
}

/// The relative velocity (m/s) of φ's positive extreme, `1/√(2a)` for `a` in s²/m² (where
/// `d φ/dv ∝ 1 − 2a·v²` vanishes; Bilbao 2009).
pub fn bilbao_peak_velocity(a: f64) -> f64 {
    1.0 / (2.0 * a).sqrt()
}

/// The sample velocities for `a_values`: a uniform grid over [−v_max, v_max] plus every
/// extreme ±1/√(2a) that falls inside it, sorted.
pub fn velocities(a_values: &[f64], v_max: f64) -> Vec<f64> {
    let mut v: Vec<f64> = (0..GRID)
        .map(|i| -v_max + 2.0 * v_max * i as f64 / (GRID - 1) as f64)
        .collect();
    for &a in a_values {
        let peak = bilbao_peak_velocity(a);
        if peak <= v_max {
            v.push(peak);
            v.push(-peak);
        }
    }
    v.sort_by(f64::total_cmp);
    v.dedup();
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phi_is_odd_with_its_extremes_at_one_over_root_2a() {
        for a in DEFAULT_A {
            let peak = 1.0 / (2.0 * a).sqrt();
            assert!((bilbao_phi(peak, a) - 1.0).abs() < 1e-12, "a = {a}");
            assert!((bilbao_phi(-peak, a) + 1.0).abs() < 1e-12, "a = {a}");
            assert!(bilbao_phi(peak * 1.01, a) < 1.0 && bilbao_phi(peak * 0.99, a) < 1.0);
            assert_eq!(bilbao_phi(0.3, a), -bilbao_phi(-0.3, a));
        }
        let v = velocities(&[1.0], 1.0);
        assert!(v.contains(&(1.0 / 2f64.sqrt())) && v.windows(2).all(|w| w[0] < w[1]));
        assert_eq!(v.len(), GRID + 2);
    }
}
