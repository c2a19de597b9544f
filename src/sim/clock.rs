//! Simulated time, counted in steps rather than summed.

/// Simulated time as `origin + steps * dt`, where `origin` is the time at which the time step
/// last changed (or the time was set): a running sum of `dt` gathers a rounding each step, so
/// that 198 steps of 0.02 read 3.960000000000003 s, where this reads 3.96 (from an origin of 0,
/// `steps * dt` rounded once; from another, twice).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SimClock {
    origin: f64,
    steps: u64,
    dt: f64,
}

impl SimClock {
    /// The time this clock has counted to.
    pub fn now(&self) -> f64 {
        match self.steps {
            0 => self.origin,
            steps => self.origin + steps as f64 * self.dt,
        }
    }

    /// The time one step of `dt` after `time`: counted on from this clock's origin where `time`
    /// is where it stands and `dt` its step, else from `time` (a new step length, or a time set
    /// from outside).
    pub fn advance(&mut self, time: f64, dt: f64) -> f64 {
        if time.to_bits() != self.now().to_bits() || dt.to_bits() != self.dt.to_bits() {
            *self = SimClock {
                origin: time,
                steps: 0,
                dt,
            };
        }
        self.steps += 1;
        self.now()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Steps of one length read as their count times it, rounded once (the running sum drifts
    /// off); a change of length counts on from where the time stood; a time set from outside
    /// is counted on from.
    #[test]
    fn time_is_steps_times_the_step_rounded_once() {
        let (mut clock, mut time, mut sum) = (SimClock::default(), 0.0, 0.0);
        for n in 1..=198 {
            time = clock.advance(time, 0.02);
            sum += 0.02;
            assert_eq!(time, n as f64 * 0.02);
        }
        assert_eq!(time, 3.96);
        assert_ne!(sum, 3.96, "the running sum it replaces: {sum}");
        for n in 1..=10 {
            time = clock.advance(time, 0.01);
            assert_eq!(time, 3.96 + n as f64 * 0.01);
        }
        time = clock.advance(1.5, 0.01);
        assert_eq!(time, 1.5 + 0.01);
    }
}
