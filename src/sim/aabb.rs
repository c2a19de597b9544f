//! Axis-aligned bounding boxes of bodies, bounded from each body's pose and its body-space box
//! (never by transforming vertices).

use super::body::RigidBody;
use super::shape::Shape;
use glam::{DMat3, DVec3};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: DVec3,
    pub max: DVec3,
}

impl Aabb {
    /// Contains nothing and overlaps nothing.
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::INFINITY,
        max: DVec3::NEG_INFINITY,
    };

    pub fn overlaps(&self, other: &Aabb) -> bool {
        self.min.cmple(other.max).all() && other.min.cmple(self.max).all()
    }

    /// Whether `inner` lies inside this box.
    pub fn contains(&self, inner: &Aabb) -> bool {
        self.min.cmple(inner.min).all() && inner.max.cmple(self.max).all()
    }

    /// The smallest box containing both.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// The box grown by `margin` on every side.
    pub fn fattened(&self, margin: f64) -> Aabb {
        Aabb {
            min: self.min - DVec3::splat(margin),
            max: self.max + DVec3::splat(margin),
        }
    }

    /// This box and the same box moved by `shift` (the space it sweeps when translated).
    pub fn swept(&self, shift: DVec3) -> Aabb {
        Aabb {
            min: self.min.min(self.min + shift),
            max: self.max.max(self.max + shift),
        }
    }
}

/// A box containing the body's hull at its current pose: the body-space box rotated, then boxed
/// (`|R| h`), padded by a relative 1e-9 so rounding can never make it smaller than the vertices'.
pub fn body_aabb(body: &RigidBody, shape: &Shape) -> Aabb {
    let r = body.rotation();
    let abs = DMat3::from_cols(r.x_axis.abs(), r.y_axis.abs(), r.z_axis.abs());
    // The box centre by the same matrix (not the quaternion again): the box moves by rounding
    // only, far inside its padding.
    let center = r * shape.local_box_center + body.position;
    let pad =
        1e-9 * (shape.local_box_half_extents.max_element() + center.abs().max_element()) + 1e-12;
    let half = abs * shape.local_box_half_extents + DVec3::splat(pad);
    Aabb {
        min: center - half,
        max: center + half,
    }
}
