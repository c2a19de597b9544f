//! Rigid bodies: the state the simulation advances and the constants it needs.

use super::shape::Shape;
use super::sym_mat3::SymMat3;
use glam::{DMat3, DQuat, DVec3};

/// The fields every stage reads come first, in two cache lines (`repr(C)` keeps the order):
/// the loops over all bodies at scale are bound by memory, not arithmetic.
#[derive(Debug, Clone, PartialEq)]
#[repr(C)]
pub struct RigidBody {
    /// Centre of mass in world space (the coursework's `COM`).
    pub position: DVec3,
    /// Unit quaternion from body to world space.
    pub orientation: DQuat,
    pub linear_velocity: DVec3,
    /// World-space angular velocity.
    pub angular_velocity: DVec3,
    /// Fixed bodies have zero inverse mass and inverse inertia and never move.
    pub fixed: bool,
    /// Set when the body's state went non-finite or absurd. From then on it is a fixed body at
    /// its last finite pose: it never moves, other bodies' contacts ignore it (it may sit inside
    /// them), and its distance constraints hold their other body to it as to a fixed anchor.
    pub quarantined: bool,
    /// Resting with its island (soft-step solver): not integrated, not solved, until a
    /// contact with a moving body, a constraint to one, a grab or a settings change wakes it.
    pub asleep: bool,
    /// Moved at the sleep speed or faster in its last step, or has not been measured since it
    /// was made or woken (soft-step solver): it wakes sleeping bodies it comes near.
    pub moving: bool,
    /// Seconds the body and its island have rested (soft-step solver).
    pub sleep_time: f64,
    /// Velocity when its rest began (soft-step solver; see [`crate::sim::soft_step::sleep`]).
    pub rest_velocity: DVec3,
    pub inverse_mass: f64,
    /// Index of the body's shape in [`crate::World::shapes`].
    pub shape: usize,
    pub density: f64,
    pub mass: f64,
    /// Inertia tensor about the centre of mass, body frame.
    pub inertia: SymMat3,
    /// Inverse inertia tensor, body frame (the coursework's `invIT`).
    pub inverse_inertia: SymMat3,
}

impl RigidBody {
    /// A body of `density` on a shape of `volume` and unit-density inertia `unit_inertia`.
    pub fn new(
        shape: usize,
        volume: f64,
        unit_inertia: DMat3,
        density: f64,
        fixed: bool,
        position: DVec3,
        orientation: DQuat,
    ) -> Self {
        let (mass, inverse_mass, inertia, inverse_inertia) = if fixed {
            (f64::INFINITY, 0.0, unit_inertia * density, DMat3::ZERO)
        } else {
            let inertia = unit_inertia * density;
            (
                density * volume,
                1.0 / (density * volume),
                inertia,
                inertia.inverse(),
            )
        };
        Self {
            shape,
            density,
            fixed,
            position,
            orientation,
            linear_velocity: DVec3::ZERO,
            angular_velocity: DVec3::ZERO,
            mass,
            inverse_mass,
            inertia: SymMat3::from_mat3(inertia),
            inverse_inertia: SymMat3::from_mat3(inverse_inertia),
            quarantined: false,
            asleep: false,
            moving: true,
            sleep_time: 0.0,
            rest_velocity: DVec3::ZERO,
        }
    }

    /// Awake and unrested, as a body just made.
    pub fn wake(&mut self) {
        self.asleep = false;
        self.moving = true;
        self.sleep_time = 0.0;
    }

    /// The ground plane's stand-in in contact resolution: immovable, at rest.
    pub fn ground() -> Self {
        Self::new(
            usize::MAX,
            0.0,
            DMat3::ZERO,
            0.0,
            true,
            DVec3::ZERO,
            DQuat::IDENTITY,
        )
    }

    /// A body of `density` on `shape` (index `shape_index` in the world's shapes).
    pub fn on_shape(
        shape: &Shape,
        shape_index: usize,
        density: f64,
        fixed: bool,
        position: DVec3,
        orientation: DQuat,
    ) -> Self {
        Self::new(
            shape_index,
            shape.volume,
            shape.unit_inertia,
            density,
            fixed,
            position,
            orientation,
        )
    }

    /// Whether contacts and constraints may move this body.
    pub fn is_dynamic(&self) -> bool {
        !self.fixed && !self.quarantined
    }

    /// Whether the soft step integrates and solves this body this step.
    pub fn is_awake(&self) -> bool {
        self.is_dynamic() && !self.asleep
    }

    pub fn rotation(&self) -> DMat3 {
        DMat3::from_quat(self.orientation)
    }

    /// World inverse inertia `R Iinv R^T` (the coursework's `get_curr_inv_IT`).
    pub fn world_inverse_inertia(&self) -> DMat3 {
        let r = self.rotation();
        r * self.inverse_inertia.to_mat3() * r.transpose()
    }

    /// World inertia `R I R^T`.
    pub fn world_inertia(&self) -> DMat3 {
        let r = self.rotation();
        r * self.inertia.to_mat3() * r.transpose()
    }

    /// A body-space point in world space: `R(q) p + COM` (the coursework's `currV`).
    /// Every stage that needs a current vertex calls this one function, so all agree to the bit.
    #[inline]
    pub fn world_point(&self, local: DVec3) -> DVec3 {
        self.orientation * local + self.position
    }

    /// Velocity of the material point at world-space arm `r` from the centre of mass.
    #[inline]
    pub fn point_velocity(&self, arm: DVec3) -> DVec3 {
        self.linear_velocity + self.angular_velocity.cross(arm)
    }

    /// Inverse mass as seen by contacts and constraints (zero for frozen bodies too).
    pub fn effective_inverse_mass(&self) -> f64 {
        if self.quarantined {
            0.0
        } else {
            self.inverse_mass
        }
    }

    pub fn effective_world_inverse_inertia(&self) -> DMat3 {
        if self.quarantined {
            DMat3::ZERO
        } else {
            self.world_inverse_inertia()
        }
    }

    /// Whether the pose and the velocities are finite. `x - x` is 0 for a finite `x` and NaN
    /// for an infinite or NaN one, so one sum tests all thirteen components without a branch
    /// each (the pose check runs this on every body every step).
    #[allow(clippy::eq_op)] // `x - x` on purpose, see above
    pub fn is_finite(&self) -> bool {
        let (p, v, w, q) = (
            self.position,
            self.linear_velocity,
            self.angular_velocity,
            self.orientation,
        );
        let vectors = (p - p) + (v - v) + (w - w);
        let quaternion = (q.x - q.x) + (q.y - q.y) + (q.z - q.z) + (q.w - q.w);
        vectors.x + vectors.y + vectors.z + quaternion == 0.0
    }

    /// Kinetic (linear and angular) plus gravitational potential energy; zero for fixed bodies.
    pub fn energy(&self, gravity: DVec3) -> f64 {
        if self.fixed {
            return 0.0;
        }
        let w = self.angular_velocity;
        0.5 * self.mass * self.linear_velocity.length_squared()
            + 0.5 * w.dot(self.world_inertia() * w)
            - self.mass * gravity.dot(self.position)
    }
}

/// Whether any of `bodies` is awake: a scene with none cannot move by itself.
pub fn any_awake(bodies: &[RigidBody]) -> bool {
    bodies.iter().any(RigidBody::is_awake)
}

/// Asks the cache for body `i`'s first fields, through its shape index (160 bytes: its pose and
/// shape index, which a contact test reads first, and what lies between them; a hint: nothing
/// changes, and nothing happens for an index out of range).
#[inline(always)]
pub fn prefetch_pose(bodies: &[RigidBody], i: usize) {
    if let Some(body) = bodies.get(i) {
        let hot = std::mem::offset_of!(RigidBody, shape) + std::mem::size_of::<usize>();
        super::buffer::prefetch_bytes((body as *const RigidBody).cast(), hot);
    }
}

/// Whether two bodies can collide: not when either is frozen, nor when both are fixed.
pub fn may_collide(a: &RigidBody, b: &RigidBody) -> bool {
    flags_may_collide(collision_flags(a), collision_flags(b))
}

/// What [`may_collide`] reads of a body in one byte (bit 0 frozen, bit 1 fixed): a broad phase
/// over many bodies filters its pairs from a compact array instead of the bodies themselves
/// (at scatter-100000 reading two bodies per candidate pair missed the cache every time).
pub fn collision_flags(body: &RigidBody) -> u8 {
    body.quarantined as u8 | (body.fixed as u8) << 1
}

/// [`may_collide`] on two bodies' [`collision_flags`].
pub fn flags_may_collide(a: u8, b: u8) -> bool {
    (a | b) & 1 == 0 && a & b & 2 == 0
}
