//! Semi-implicit (symplectic) Euler: velocities first, then positions from the new velocities;
//! orientations by the quaternion exponential of the world angular velocity.

use crate::sim::body::RigidBody;
use crate::sim::parallel;
use crate::sim::settings::{RotationIntegrator, Settings};
use glam::{DMat3, DQuat, DVec3};
use rayon::prelude::*;

/// Advances every movable body by `dt`. Fixed and quarantined bodies are skipped.
pub fn integrate_bodies(bodies: &mut [RigidBody], settings: &Settings, dt: f64) {
    parallel::for_each(bodies.par_iter_mut(), 256, |body| {
        if body.is_dynamic() {
            integrate_body(body, settings, dt);
        }
    });
}

/// The coursework's update of one body: velocity, then pose (with the skeleton's `QExp` cutoff).
pub fn integrate_body(body: &mut RigidBody, settings: &Settings, dt: f64) {
    body.linear_velocity += dt * settings.gravity;
    integrate_pose(body, settings.rotation_integrator, dt, true);
}

/// Position from the (new) linear velocity, orientation by the rotation integrator. With
/// `qexp_cutoff`, the coursework integrator skips half-angles below [`QEXP_CUTOFF`] as the
/// skeleton does; the opt-in integrators always rotate exactly.
pub fn integrate_pose(
    body: &mut RigidBody,
    integrator: RotationIntegrator,
    dt: f64,
    qexp_cutoff: bool,
) {
    body.position += dt * body.linear_velocity;
    match integrator {
        RotationIntegrator::Coursework if qexp_cutoff => {
            body.orientation = coursework_rotate_by(body.orientation, body.angular_velocity, dt);
        }
        RotationIntegrator::Coursework => {
            body.orientation = rotate_by(body.orientation, body.angular_velocity, dt);
        }
        RotationIntegrator::Gyroscopic => {
            body.angular_velocity = gyroscopic_step(body, dt);
            body.orientation = rotate_by(body.orientation, body.angular_velocity, dt);
        }
        // Without spin there is nothing to turn (skipped: free fall at scale is mostly this).
        RotationIntegrator::AngularMomentum if body.angular_velocity == DVec3::ZERO => {}
        // With equal principal moments `w = I^-1 L` is constant: the exact motion is a turn at
        // `w` (the generated tetrahedra and octahedra: two of the three generated shapes).
        RotationIntegrator::AngularMomentum if body.inertia.is_isotropic() => {
            body.orientation = rotate_by(body.orientation, body.angular_velocity, dt);
        }
        RotationIntegrator::AngularMomentum => {
            // Torque-free: world angular momentum L is constant over the step. Rotate by the
            // angular velocity at the half-step orientation (explicit midpoint, second order),
            // then read the new angular velocity off L: |L| and L are kept exactly. Tensors are
            // applied in body frame (`q I q^-1 v`), cheaper than forming `R I R^T`.
            let q = body.orientation;
            let momentum = q * (body.inertia.to_mat3() * (q.inverse() * body.angular_velocity));
            let half = rotate_by(q, body.angular_velocity, 0.5 * dt);
            let w_half = inverse_inertia_at(body, half, momentum);
            body.orientation = rotate_by(q, w_half, dt);
            body.angular_velocity = inverse_inertia_at(body, body.orientation, momentum);
        }
    }
}

/// Half-angles below this are no rotation at all in the coursework's `QExp` (`nv < 10e-6`).
pub const QEXP_CUTOFF: f64 = 1e-5;

/// [`rotate_by`] as the coursework's skeleton does it: no rotation when the half-angle
/// `|w| dt / 2` is below [`QEXP_CUTOFF`].
pub fn coursework_rotate_by(q: DQuat, angular_velocity: DVec3, dt: f64) -> DQuat {
    if (0.5 * dt * angular_velocity).length() < QEXP_CUTOFF {
        return q;
    }
    rotate_by(q, angular_velocity, dt)
}

/// `I(q)^-1 v`: the world inverse inertia at orientation `q` applied to `v`.
fn inverse_inertia_at(body: &RigidBody, q: DQuat, v: DVec3) -> DVec3 {
    q * (body.inverse_inertia.to_mat3() * (q.inverse() * v))
}

/// `normalise(exp((0, dt/2 w)) q)` with `exp((0, theta u)) = (cos theta, sin theta u)`:
/// a rotation by `|w| dt` about `w`, applied on the left (world frame).
pub fn rotate_by(q: DQuat, angular_velocity: DVec3, dt: f64) -> DQuat {
    let half = 0.5 * dt * angular_velocity;
    let theta = half.length();
    if theta == 0.0 {
        return q;
    }
    let axis = half / theta;
    let (sin, cos) = theta.sin_cos();
    let exp = DQuat::from_xyzw(sin * axis.x, sin * axis.y, sin * axis.z, cos);
    (exp * q).normalize()
}

/// Implicit Euler on Euler's equations `I dw/dt + w x I w = 0` in body frame, linearised by one
/// Newton step (Catto, GDC 2015, "Numerical Methods"): conserves |L| far better than explicit
/// schemes and is stable for fast, asymmetric spins.
fn gyroscopic_step(body: &RigidBody, dt: f64) -> DVec3 {
    let q = body.orientation;
    let inertia = body.inertia.to_mat3();
    let w0 = q.inverse() * body.angular_velocity;
    let f = dt * w0.cross(inertia * w0);
    let jacobian = inertia + dt * (skew(w0) * inertia - skew(inertia * w0));
    let det = jacobian.determinant();
    if !det.is_finite() || det.abs() < 1e-300 {
        return body.angular_velocity;
    }
    let w = w0 - jacobian.inverse() * f;
    q * w
}

fn skew(v: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, v.z, -v.y),
        DVec3::new(-v.z, 0.0, v.x),
        DVec3::new(v.y, -v.x, 0.0),
    )
}
