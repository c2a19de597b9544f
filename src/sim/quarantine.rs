//! The pose check that ends every step: a body whose state went non-finite or absurdly fast is
//! frozen at its last finite pose, so NaN never reaches other bodies through contacts or
//! constraints.

use super::body::RigidBody;
use super::parallel;
use glam::{DQuat, DVec3};
use rayon::prelude::*;

/// Speeds above this are treated as a blown-up state and quarantined.
pub const ABSURD_SPEED: f64 = 1e12;

#[derive(Debug, Clone, Default)]
pub struct Quarantine {
    /// Each body's last pose known finite: the pose it begins the next step at.
    last_good: Vec<(DVec3, DQuat)>,
}

impl Quarantine {
    pub fn new(bodies: &[RigidBody]) -> Self {
        Self {
            last_good: bodies.iter().map(|b| (b.position, b.orientation)).collect(),
        }
    }

    /// The poses the bodies begin the step at, one per body, for a solver that measures its
    /// bodies' motion from them (the soft step, which records each body's again before it
    /// moves it: the same pose, unless an edit between steps moved the body).
    pub fn step_start(&mut self, bodies: &[RigidBody]) -> &mut [(DVec3, DQuat)] {
        let known = self.last_good.len().min(bodies.len());
        self.last_good.truncate(known);
        let added = bodies[known..].iter().map(|b| (b.position, b.orientation));
        self.last_good.extend(added);
        &mut self.last_good
    }

    pub fn heap_bytes(&self) -> usize {
        self.last_good.capacity() * std::mem::size_of::<(DVec3, DQuat)>()
    }

    /// Freezes the bodies that blew up since the last check and appends their indices to
    /// `frozen`.
    /// Sleeping bodies are skipped: the solver did not move them.
    pub fn check(&mut self, bodies: &mut [RigidBody], frozen: &mut Vec<usize>) {
        let items = bodies.par_iter_mut().zip(&mut self.last_good).enumerate();
        parallel::extend_filter_map(frozen, items, 1024, |(index, (body, last_good))| {
            if body.quarantined || body.asleep {
                return None;
            }
            let limit = ABSURD_SPEED * ABSURD_SPEED;
            let absurd = body.linear_velocity.length_squared() > limit
                || body.angular_velocity.length_squared() > limit;
            if body.is_finite() && !absurd {
                *last_good = (body.position, body.orientation);
                return None;
            }
            (body.position, body.orientation) = *last_good;
            body.linear_velocity = DVec3::ZERO;
            body.angular_velocity = DVec3::ZERO;
            body.quarantined = true;
            Some(index)
        });
    }
}
