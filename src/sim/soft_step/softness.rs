//! Soft constraints (Catto, "Solver2D", 2024; Box2D v3's `b2MakeSoft`): a constraint corrected
//! like a damped spring of natural frequency `hertz` and damping ratio `zeta`, expressed as a
//! bias rate on the position error and scales on the mass and on the accumulated impulse, so a
//! stiff constraint is stable at any mass ratio and step.

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Softness {
    /// Velocity bias per unit of position error (1/s).
    pub bias_rate: f64,
    /// Scale on the effective mass in the impulse.
    pub mass_scale: f64,
    /// Scale on the accumulated impulse subtracted from the new one.
    pub impulse_scale: f64,
}

impl Softness {
    /// With `omega = 2 pi hertz`, `a1 = 2 zeta + h omega`, `a2 = h omega a1`, `a3 = 1 / (1 + a2)`:
    /// bias rate `omega / a1`, mass scale `a2 a3`, impulse scale `a3`. Zero hertz is a rigid
    /// constraint with no position correction.
    pub fn new(hertz: f64, zeta: f64, h: f64) -> Self {
        if hertz <= 0.0 || h <= 0.0 {
            return Self::RIGID;
        }
        let omega = 2.0 * std::f64::consts::PI * hertz;
        let a1 = 2.0 * zeta + h * omega;
        let a2 = h * omega * a1;
        let a3 = 1.0 / (1.0 + a2);
        Self {
            bias_rate: omega / a1,
            mass_scale: a2 * a3,
            impulse_scale: a3,
        }
    }

    /// `(bias, mass scale, impulse scale)` of one solve of an inequality whose position error is
    /// `c` (>= 0 when satisfied). While it is still satisfied it may close the gap within the
    /// substep and no more (a speculative constraint, rigid); violated, the soft pass pushes
    /// back at the soft rate but at most `max_push`, the other passes only make it rigid.
    pub fn coefficients(
        &self,
        c: f64,
        inv_h: f64,
        use_bias: bool,
        max_push: f64,
    ) -> (f64, f64, f64) {
        if c > 0.0 {
            (c * inv_h, 1.0, 0.0)
        } else if use_bias {
            (
                (self.bias_rate * c).max(-max_push),
                self.mass_scale,
                self.impulse_scale,
            )
        } else {
            (0.0, 1.0, 0.0)
        }
    }

    /// No softness and no position correction: the relax pass.
    pub const RIGID: Softness = Softness {
        bias_rate: 0.0,
        mass_scale: 1.0,
        impulse_scale: 0.0,
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steady_state_deflection_is_that_of_a_spring() {
        // Unit mass under a constant load per unit mass `a`, solved as the soft step does it:
        // warm start with the accumulated impulse, one soft solve, move. The error settles where
        // the bias balances the load: at -a / omega^2, as a spring of that frequency would.
        let (hertz, zeta, h, a) = (30.0, 10.0, 1.0 / 240.0, 9.8);
        let soft = Softness::new(hertz, zeta, h);
        let (mut c, mut lambda) = (0.0f64, 0.0f64);
        for _ in 0..20_000 {
            let mut v = -a * h + lambda;
            let impulse = -soft.mass_scale * (v + soft.bias_rate * c) - soft.impulse_scale * lambda;
            lambda += impulse;
            v += impulse;
            c += h * v;
        }
        let omega = 2.0 * std::f64::consts::PI * hertz;
        let expected = -a / (omega * omega);
        assert!(
            (c - expected).abs() < 1e-6 * expected.abs(),
            "{c} vs {expected}"
        );
        assert!((lambda - a * h).abs() < 1e-12);
        assert!((soft.mass_scale + soft.impulse_scale - 1.0).abs() < 1e-15);
    }
}
