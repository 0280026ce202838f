//! What the plant shows under the gait being applied, once it has settled: speed, power,
//! mileage with its standard error, largest stress, stored energy.
//!
//! The sums forget with a time constant of [`MEMORY`] (a pipe whose friction changes along the
//! way shows in the measurement), and the mileage's standard error comes from the scatter of the
//! mileage of consecutive [`CHUNK`]s (a uniform pipe under a steady gait has almost none).

/// Forgetting time constant of the measurement, s.
pub const MEMORY: f64 = 1.0;
/// Length of the pieces whose mileages give the standard error, s.
pub const CHUNK: f64 = 0.1;
/// Relative floor of the mileage's standard error (what a measurement of a few periods cannot
/// tell apart).
pub const FLOOR: f64 = 0.002;

/// The measurement of one gait.
#[derive(Debug, Clone, Copy)]
pub struct Meter {
    /// When the gait was applied, s.
    since: f64,
    /// Settling time, s.
    settle: f64,
    /// Forgetting sums of V dt, P dt and dt.
    v: f64,
    p: f64,
    t: f64,
    /// Seconds measured (not forgotten).
    measured: f64,
    /// The current chunk's V dt, P dt, dt.
    chunk: [f64; 3],
    /// The first chunk's mileage, m/J: the sums below are of the chunks' mileage less it, so a
    /// steady gait's scatter is exactly zero (no cancellation of two large sums).
    m0: Option<f64>,
    /// Forgetting sums of the chunks' weight, weight², weight * (mileage - m0),
    /// weight * (mileage - m0)².
    w: f64,
    w2: f64,
    wm: f64,
    wm2: f64,
    /// Largest stress since settled, Pa.
    peak: f64,
    /// Stress at the last step, Pa.
    last: f64,
    /// Stored energy: its forgetting mean, J.
    stored: f64,
    /// Time of the last verdict, s.
    verdict: f64,
}

impl Meter {
    /// A measurement of a gait applied at `since`, settling for `settle` s.
    pub fn new(since: f64, settle: f64) -> Self {
        Self {
            since,
            settle,
            v: 0.0,
            p: 0.0,
            t: 0.0,
            measured: 0.0,
            chunk: [0.0; 3],
            w: 0.0,
            w2: 0.0,
            m0: None,
            wm: 0.0,
            wm2: 0.0,
            peak: 0.0,
            last: 0.0,
            stored: 0.0,
            verdict: f64::NEG_INFINITY,
        }
    }

    /// Takes one step of `h` s that ended at `time` with mean speed `speed`, input power
    /// `power`, largest stress `stress` and stored energy `stored`.
    pub fn observe(&mut self, time: f64, h: f64, speed: f64, power: f64, stress: f64, stored: f64) {
        self.last = stress;
        if time - self.since < self.settle {
            return;
        }
        let f = (-h / MEMORY).exp();
        self.v = f * self.v + speed * h;
        self.p = f * self.p + power * h;
        self.t = f * self.t + h;
        self.stored = if self.measured == 0.0 {
            stored
        } else {
            f * self.stored + (1.0 - f) * stored
        };
        self.measured += h;
        self.peak = self.peak.max(stress);
        let c = &mut self.chunk;
        c[0] += speed * h;
        c[1] += power * h;
        c[2] += h;
        if c[2] >= CHUNK - 0.5 * h {
            let g = (-c[2] / MEMORY).exp();
            self.w *= g;
            self.w2 *= g * g;
            self.wm *= g;
            self.wm2 *= g;
            if c[1] > 0.0 {
                let m = c[0] / c[1] - *self.m0.get_or_insert(c[0] / c[1]);
                self.w += 1.0;
                self.w2 += 1.0;
                self.wm += m;
                self.wm2 += m * m;
            }
            *c = [0.0; 3];
        }
    }

    /// True if a verdict is due at `time`: measured for `measure` s, and `measure` s since the
    /// last one. Marks it given.
    pub fn verdict_due(&mut self, time: f64, measure: f64) -> bool {
        if self.measured + 1e-12 >= measure && time - self.verdict >= measure - 1e-12 {
            self.verdict = time;
            true
        } else {
            false
        }
    }

    /// Mean speed, m/s.
    pub fn speed(&self) -> Option<f64> {
        (self.t > 0.0).then(|| self.v / self.t)
    }

    /// Mean input power, W.
    pub fn power(&self) -> Option<f64> {
        (self.t > 0.0).then(|| self.p / self.t)
    }

    /// Mileage `V / P`, m/J (infinite when the body gives back what it takes and still moves).
    pub fn mileage(&self) -> Option<f64> {
        if self.t <= 0.0 {
            return None;
        }
        Some(if self.p > 0.0 {
            (self.v / self.p).max(0.0)
        } else if self.v > 0.0 {
            f64::INFINITY
        } else {
            0.0
        })
    }

    /// The mileage less `kappa` of its standard errors (relative floor [`FLOOR`]), m/J.
    pub fn mileage_lo(&self, kappa: f64) -> Option<f64> {
        let m = self.mileage()?;
        if !m.is_finite() {
            return Some(m);
        }
        let rel = if self.w > 1.0 && m > 0.0 {
            let mean = self.wm / self.w;
            let var = (self.wm2 / self.w - mean * mean).max(0.0);
            let n_eff = self.w * self.w / self.w2.max(1e-300);
            (var / n_eff).sqrt() / m
        } else {
            0.0
        };
        Some(m * (1.0 - kappa * rel - FLOOR).max(0.0))
    }

    /// Largest stress since the gait settled, Pa.
    pub fn peak(&self) -> f64 {
        self.peak
    }

    /// Stress at the last step, Pa.
    pub fn last_stress(&self) -> f64 {
        self.last
    }

    /// Mean stored energy, J.
    pub fn stored(&self) -> f64 {
        self.stored
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_steady_gait_is_measured_exactly_after_it_settled() {
        let mut m = Meter::new(1.0, 0.5);
        let h = 1e-3;
        for n in 1..=3000 {
            let t = 1.0 + n as f64 * h;
            // a transient before 1.5 s that must not count
            let (v, p) = if t < 1.5 { (9.0, 1.0) } else { (0.05, 2.0) };
            m.observe(t, h, v, p, 1e4, 0.1);
        }
        assert!((m.speed().unwrap() - 0.05).abs() < 1e-12);
        assert!((m.power().unwrap() - 2.0).abs() < 1e-12);
        assert!((m.mileage().unwrap() - 0.025).abs() < 1e-12);
        // no scatter: the bound is the floor only
        let lo = m.mileage_lo(2.0).unwrap();
        assert!((lo - 0.025 * (1.0 - FLOOR)).abs() < 1e-12, "{lo}");
        // from the step that ends at 1.5 s (or the next, as the sum of the steps rounds) to 4 s
        assert!((m.measured - 2.5).abs() <= h + 1e-9, "{}", m.measured);
    }

    #[test]
    fn a_scattered_mileage_has_a_lower_bound_below_its_mean() {
        let mut m = Meter::new(0.0, 0.0);
        let h = 1e-3;
        for n in 1..=2000 {
            let t = n as f64 * h;
            let p = if ((t / CHUNK) as u64).is_multiple_of(2) {
                1.0
            } else {
                3.0
            };
            m.observe(t, h, 0.05, p, 1e4, 0.1);
        }
        let mean = m.mileage().unwrap();
        let lo = m.mileage_lo(2.0).unwrap();
        assert!(lo < mean * (1.0 - FLOOR) - 1e-6, "{lo} against {mean}");
    }
}
