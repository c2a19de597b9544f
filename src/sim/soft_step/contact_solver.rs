//! Contact constraints of the soft-step solver: per manifold point a normal impulse (clamped
//! non-negative, soft position correction, speculative when apart) and Coulomb friction in two
//! tangent directions clamped to the disc `mu * normal impulse`; accumulated impulses are
//! warm-started from the previous step by feature key.

use super::manifold::{GROUND, Manifold};
use super::softness::Softness;
use super::solver_body::{SolverBody, pair_mut};
use glam::DVec3;

/// One direction `d` of a contact point's Jacobian, kept for the step: the angular parts
/// `r_i x d` and the angular response `I_i^-1 (r_i x d)` to a unit impulse (the arms and
/// inertias are those of the step's start), so a row costs a few dot products.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Direction {
    ang1: DVec3,
    ang2: DVec3,
    inv1: DVec3,
    inv2: DVec3,
}

impl Direction {
    /// The direction `d` at arms `r1`, `r2`, and its effective mass (zero if nothing moves).
    fn new(b1: &SolverBody, r1: DVec3, b2: &SolverBody, r2: DVec3, d: DVec3) -> (Self, f64) {
        let (ang1, ang2) = (r1.cross(d), r2.cross(d));
        let (inv1, inv2) = (b1.inverse_inertia * ang1, b2.inverse_inertia * ang2);
        let k = b1.inverse_mass + b2.inverse_mass + ang1.dot(inv1) + ang2.dot(inv2);
        let mass = if k > 0.0 { 1.0 / k } else { 0.0 };
        (
            Self {
                ang1,
                ang2,
                inv1,
                inv2,
            },
            mass,
        )
    }

    /// Relative velocity of the points along `d` (body 2 against body 1).
    #[inline]
    pub fn velocity(&self, d: DVec3, b1: &SolverBody, b2: &SolverBody) -> f64 {
        d.dot(b2.linear_velocity - b1.linear_velocity) + self.ang2.dot(b2.angular_velocity)
            - self.ang1.dot(b1.angular_velocity)
    }

    /// Applies `impulse` along `d` to body 2 and its opposite to body 1.
    #[inline]
    pub fn apply(&self, d: DVec3, impulse: f64, b1: &mut SolverBody, b2: &mut SolverBody) {
        b1.linear_velocity -= (b1.inverse_mass * impulse) * d;
        b1.angular_velocity -= impulse * self.inv1;
        b2.linear_velocity += (b2.inverse_mass * impulse) * d;
        b2.angular_velocity += impulse * self.inv2;
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactPoint {
    /// Arms from the centres of mass to the point, world space, at the start of the step.
    pub r1: DVec3,
    pub r2: DVec3,
    /// The Jacobian rows along the normal and the two tangents.
    pub along_normal: Direction,
    pub along_tangents: [Direction; 2],
    /// Separation at the start of the step (negative: penetration).
    pub separation: f64,
    pub normal_mass: f64,
    pub tangent_mass: [f64; 2],
    /// Accumulated impulses.
    pub normal_impulse: f64,
    /// What the restitution pass added to the normal impulse (not carried to the next step:
    /// warm starting it would push the bodies apart again in every substep).
    pub restitution_impulse: f64,
    pub tangent_impulse: [f64; 2],
    /// Largest normal impulse of the step: the point really touched.
    pub max_normal_impulse: f64,
    /// Energy of the approach along the normal at the moment of impact (see
    /// [`impact_energy`]), recorded by the substep that stopped the approach; zero when none.
    pub impact_energy: f64,
    pub key: u64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactConstraint {
    /// Solver body indices (the ground is the last, static one).
    pub body1: usize,
    pub body2: usize,
    /// From body 1 to body 2.
    pub normal: DVec3,
    pub tangents: [DVec3; 2],
    pub friction: f64,
    pub restitution: f64,
    /// Impacts slower than this do not bounce.
    pub restitution_threshold: f64,
    /// Relative acceleration of the bodies along the normal from gravity alone.
    pub normal_acceleration: f64,
    pub softness: Softness,
    /// This constraint's points: `points[first..first + count]`.
    pub first: usize,
    pub count: usize,
}

/// What one manifold point carries to the next step.
#[derive(Debug, Clone, Copy, PartialEq)]
struct CachedPoint {
    key: u64,
    normal_impulse: f64,
    /// The friction impulse as a world vector, so a turned tangent basis does not turn it.
    friction_impulse: DVec3,
}

/// Impulses of last step's manifold points, sorted by body pair (one flat list: no allocation
/// per pair).
#[derive(Debug, Clone, Default)]
pub struct ContactCache {
    entries: Vec<((usize, usize), CachedPoint)>,
}

impl ContactCache {
    fn lookup(&self, pair: (usize, usize), key: u64) -> Option<&CachedPoint> {
        let first = self.entries.partition_point(|(p, _)| *p < pair);
        self.entries[first..]
            .iter()
            .take_while(|(p, _)| *p == pair)
            .map(|(_, c)| c)
            .find(|c| c.key == key)
    }

    /// Keeps this step's impulses (and forgets pairs no longer in contact).
    pub fn store(
        &mut self,
        manifolds: &[Manifold],
        constraints: &[ContactConstraint],
        points: &[ContactPoint],
    ) {
        self.entries.clear();
        for (m, c) in manifolds.iter().zip(constraints) {
            for p in &points[c.first..c.first + c.count] {
                let friction_impulse =
                    p.tangent_impulse[0] * c.tangents[0] + p.tangent_impulse[1] * c.tangents[1];
                self.entries.push((
                    (m.body1, m.body2),
                    CachedPoint {
                        key: p.key,
                        normal_impulse: p.normal_impulse,
                        friction_impulse,
                    },
                ));
            }
        }
        self.entries.sort_by_key(|(pair, _)| *pair);
    }

    /// Number of points remembered.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }
}

/// Two unit tangents completing the normal to a right-handed basis, the same for the same
/// normal from step to step.
pub fn tangent_basis(n: DVec3) -> [DVec3; 2] {
    let helper = if n.x.abs() < 0.57735 {
        DVec3::X
    } else {
        DVec3::Y
    };
    let t1 = n.cross(helper).normalize();
    [t1, n.cross(t1)]
}

/// The contact's share of the step: `softness` for the biased pass, the restitution, friction
/// and gravity the bodies feel, and the substep length.
pub struct ContactParams {
    pub softness: Softness,
    pub static_softness: Softness,
    pub friction: f64,
    pub restitution: f64,
    pub restitution_threshold: f64,
    pub gravity: DVec3,
}

/// The energy of the approach along the normal per unit effective mass, `E = v^2/2 - a s`
/// for separation `s` (clamped at zero), normal velocity `v` and the relative normal
/// acceleration `a` that gravity gives the bodies. The substeps kick velocities by half a
/// substep of gravity before and after moving the bodies (velocity Verlet), which is exact
/// under constant acceleration: measured in the substep that stops the approach, with the gap
/// still open then, `E` is what the approach carries at the moment of impact, so a bounce that
/// leaves `e^2 E` gives apex ratios of exactly `e^2` at any step (a bounce from the velocity at
/// the start of the step loses `a s` to the gap, which grows with dt). Measured from the
/// manifold's velocities before its impulses, points that touch together bounce together:
/// the restitution then reflects the compression, which keeps energy (e = 1).
pub fn impact_energy(separation: f64, normal_velocity: f64, normal_acceleration: f64) -> f64 {
    0.5 * normal_velocity * normal_velocity - normal_acceleration * separation.max(0.0)
}

/// The normal velocity after the bounce, `v > 0` with `v^2/2 - a s = e^2 E` at the separation
/// `s` the step ends at.
pub fn bounce_velocity(energy: f64, restitution: f64, separation: f64, a: f64) -> f64 {
    let twice = 2.0 * (restitution * restitution * energy + a * separation);
    if twice > 0.0 { twice.sqrt() } else { 0.0 }
}

/// Builds the contact constraints of this step's manifolds into `constraints` and `points`
/// (cleared first), warm-started from `cache`; `positions[i]` is body i's centre of mass.
pub fn prepare(
    manifolds: &[Manifold],
    positions: &[(DVec3, glam::DQuat)],
    bodies: &[SolverBody],
    cache: &ContactCache,
    params: &ContactParams,
    (constraints, points): (&mut Vec<ContactConstraint>, &mut Vec<ContactPoint>),
) {
    let ground = bodies.len() - 1;
    constraints.clear();
    points.clear();
    for m in manifolds {
        let i = if m.body1 == GROUND { ground } else { m.body1 };
        let j = m.body2;
        let (b1, b2) = (&bodies[i], &bodies[j]);
        let n = m.normal;
        let tangents = tangent_basis(n);
        let acceleration = |b: &SolverBody| {
            if b.inverse_mass > 0.0 {
                params.gravity
            } else {
                DVec3::ZERO
            }
        };
        let normal_acceleration = n.dot(acceleration(b2) - acceleration(b1));
        let softness = if b1.inverse_mass == 0.0 || b2.inverse_mass == 0.0 {
            params.static_softness
        } else {
            params.softness
        };
        let first = points.len();
        for mp in m.points() {
            let r1 = if i == ground {
                DVec3::ZERO
            } else {
                mp.point - positions[i].0
            };
            let r2 = mp.point - positions[j].0;
            let (along_normal, normal_mass) = Direction::new(b1, r1, b2, r2, n);
            let (t1, tangent_mass1) = Direction::new(b1, r1, b2, r2, tangents[0]);
            let (t2, tangent_mass2) = Direction::new(b1, r1, b2, r2, tangents[1]);
            let cached = cache.lookup((m.body1, m.body2), mp.key);
            points.push(ContactPoint {
                r1,
                r2,
                along_normal,
                along_tangents: [t1, t2],
                separation: mp.separation,
                normal_mass,
                tangent_mass: [tangent_mass1, tangent_mass2],
                normal_impulse: cached.map_or(0.0, |c| c.normal_impulse),
                restitution_impulse: 0.0,
                tangent_impulse: cached.map_or([0.0; 2], |c| {
                    [
                        c.friction_impulse.dot(tangents[0]),
                        c.friction_impulse.dot(tangents[1]),
                    ]
                }),
                max_normal_impulse: 0.0,
                impact_energy: 0.0,
                key: mp.key,
            });
        }
        constraints.push(ContactConstraint {
            body1: i,
            body2: j,
            normal: n,
            tangents,
            friction: params.friction,
            restitution: params.restitution,
            restitution_threshold: params.restitution_threshold,
            normal_acceleration,
            softness,
            first,
            count: points.len() - first,
        });
    }
}

/// Applies the accumulated impulses (warm starting), once per substep.
pub fn warm_start(
    constraints: &[ContactConstraint],
    points: &[ContactPoint],
    bodies: &mut [SolverBody],
) {
    for c in constraints {
        let (b1, b2) = pair_mut(bodies, c.body1, c.body2);
        for p in &points[c.first..c.first + c.count] {
            p.along_normal.apply(c.normal, p.normal_impulse, b1, b2);
            for k in 0..2 {
                p.along_tangents[k].apply(c.tangents[k], p.tangent_impulse[k], b1, b2);
            }
        }
    }
}

/// One Gauss-Seidel pass over the contacts. With `use_bias` penetration is corrected softly
/// (at most `max_push` speed); without (the relax pass) the velocities are made rigid. A point
/// still apart may close its gap within the substep but no more (speculative contact).
pub fn solve(
    constraints: &[ContactConstraint],
    points: &mut [ContactPoint],
    bodies: &mut [SolverBody],
    inv_h: f64,
    use_bias: bool,
    max_push: f64,
) {
    for c in constraints {
        let (b1, b2) = pair_mut(bodies, c.body1, c.body2);
        let n = c.normal;
        let soft = if use_bias {
            c.softness
        } else {
            Softness::RIGID
        };
        let contact_points = &mut points[c.first..c.first + c.count];
        // The normal velocities before any of this manifold's impulses: the approach speeds of
        // points that touch together.
        let mut approach = [0.0; super::manifold::MAX_POINTS];
        for (v, p) in approach.iter_mut().zip(contact_points.iter()) {
            *v = p.along_normal.velocity(n, b1, b2);
        }
        for (p, &approach) in contact_points.iter_mut().zip(&approach) {
            let moved = b2.point_displacement(p.r2) - b1.point_displacement(p.r1);
            let s = p.separation + n.dot(moved);
            let (bias, mass_scale, impulse_scale) = if s > 0.0 {
                (s * inv_h, 1.0, 0.0)
            } else if use_bias {
                (
                    (soft.bias_rate * s).max(-max_push),
                    soft.mass_scale,
                    soft.impulse_scale,
                )
            } else {
                (0.0, 1.0, 0.0)
            };
            let vn = p.along_normal.velocity(n, b1, b2);
            let impulse =
                -p.normal_mass * mass_scale * (vn + bias) - impulse_scale * p.normal_impulse;
            let total = (p.normal_impulse + impulse).max(0.0);
            let delta = total - p.normal_impulse;
            p.normal_impulse = total;
            p.max_normal_impulse = p.max_normal_impulse.max(total);
            if total > 0.0 && approach < 0.0 {
                // The biased pass comes after the first half kick of gravity: undo it to measure
                // the state at the substep boundary, where the energy is exactly invariant.
                let a = c.normal_acceleration;
                let kick = if use_bias { 0.5 * a / inv_h } else { 0.0 };
                let energy = impact_energy(s, approach - kick, a);
                p.impact_energy = p.impact_energy.max(energy);
            }
            p.along_normal.apply(n, delta, b1, b2);
        }
        for p in contact_points.iter_mut() {
            solve_friction(c, p, b1, b2);
        }
    }
}

/// Coulomb friction at one point: both tangent impulses at once, clamped to the disc of radius
/// `mu` times the normal impulse.
fn solve_friction(
    c: &ContactConstraint,
    p: &mut ContactPoint,
    b1: &mut SolverBody,
    b2: &mut SolverBody,
) {
    let old = p.tangent_impulse;
    let mut new = [0, 1]
        .map(|k| old[k] - p.tangent_mass[k] * p.along_tangents[k].velocity(c.tangents[k], b1, b2));
    let limit = c.friction * p.normal_impulse;
    let length = (new[0] * new[0] + new[1] * new[1]).sqrt();
    if length > limit {
        let scale = if length > 0.0 { limit / length } else { 0.0 };
        new = [new[0] * scale, new[1] * scale];
    }
    p.tangent_impulse = new;
    for k in 0..2 {
        p.along_tangents[k].apply(c.tangents[k], new[k] - old[k], b1, b2);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn impact_energy_is_invariant_in_free_flight() {
        // Half kick, drift, half kick: exact under constant acceleration.
        let (a, h) = (-9.8, 0.005);
        let (mut s, mut v) = (20.0, 0.0);
        let e0 = impact_energy(s, v, a);
        while s + h * (v + 0.5 * a * h) > 0.0 {
            v += 0.5 * a * h;
            s += h * v;
            v += 0.5 * a * h;
            let e = impact_energy(s, v, a);
            assert!((e - e0).abs() < 1e-12 * e0, "{e} vs {e0}");
        }
    }

    #[test]
    fn bounce_keeps_e_squared_of_the_energy() {
        let a = -9.8;
        for e in [1.0, 0.8, 0.5, 0.0] {
            let energy = 196.0;
            let v = bounce_velocity(energy, e, 0.0, a);
            assert!(
                (impact_energy(0.0, v, a) - e * e * energy).abs() < 1e-9,
                "e {e}"
            );
        }
    }
}
