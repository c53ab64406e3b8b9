//! The one time origin of a play run.
//!
//! A performance whose first notes start sooner than their strokes need is run from a
//! lead-in before its 0 s (`lead_in` whole samples), so the run's own samples count from the
//! start of the lead-in while everything reported — strikes, traces, the trace window, the
//! notes the player rushed, fault times and `--fault` windows, resets, the cycles plot's
//! axis, the spans — is in the performance's own time. A [`Timeline`] is owned by the run
//! and every output converts through it; nothing else adds or subtracts the lead-in.

/// A run's clock: its sample rate and the samples it runs before the performance's 0 s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timeline {
    /// Sample rate, Hz.
    pub fs: f64,
    /// Samples run before the performance's 0 s (0: the run starts at it).
    pub lead_in: u64,
}

impl Timeline {
    /// A run at `fs` Hz that starts `lead_in` samples before the performance's 0 s.
    pub fn new(fs: f64, lead_in: u64) -> Timeline {
        Timeline { fs, lead_in }
    }

    /// A run that starts at the performance's 0 s (a calibration stroke, `emu run`).
    pub fn at_zero(fs: f64) -> Timeline {
        Timeline::new(fs, 0)
    }

    /// The lead-in, s.
    pub fn lead_in_s(&self) -> f64 {
        self.lead_in as f64 / self.fs
    }

    /// The time of the run's sample `n` (from 0 at the run's start) in the performance's
    /// time, s: negative in the lead-in.
    pub fn sample_to_performance_s(&self, n: u64) -> f64 {
        (n as f64 - self.lead_in as f64) / self.fs
    }

    /// The run's time (from 0 at its start, what the players' motions are planned in) of
    /// the performance's time `t_s`, s.
    pub fn performance_to_run_s(&self, t_s: f64) -> f64 {
        t_s + self.lead_in_s()
    }

    /// The performance's time of the run's time `t_s`, s.
    pub fn run_to_performance_s(&self, t_s: f64) -> f64 {
        t_s - self.lead_in_s()
    }

    /// The run's sample of the performance's sample `n` (a `--fault` window's).
    pub fn performance_sample_to_run(&self, n: u64) -> u64 {
        n.saturating_add(self.lead_in)
    }

    /// The performance's sample of the run's sample `n` (a fault word's, a reset's): one in
    /// the lead-in counts as the performance's first, 0.
    pub fn run_sample_to_performance(&self, n: u64) -> u64 {
        n.saturating_sub(self.lead_in)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lead_in_moves_the_run_s_samples_back_to_the_performance_s_time() {
        let t = Timeline::new(44_100.0, 441);
        assert_eq!(t.lead_in_s(), 0.01);
        assert_eq!(t.sample_to_performance_s(0), -0.01);
        assert_eq!(t.sample_to_performance_s(441), 0.0);
        assert_eq!(t.sample_to_performance_s(441 + 44_100), 1.0);
        assert_eq!(t.performance_to_run_s(0.5), 0.51);
        assert_eq!(t.run_to_performance_s(t.performance_to_run_s(0.25)), 0.25);
        assert_eq!(t.performance_sample_to_run(4410), 4851);
        assert_eq!(t.run_sample_to_performance(4851), 4410);
        assert_eq!(t.run_sample_to_performance(100), 0);
        let z = Timeline::at_zero(44_100.0);
        assert_eq!(z.sample_to_performance_s(4410), 0.1);
        assert_eq!(z.run_sample_to_performance(7), 7);
    }
}
