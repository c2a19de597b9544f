//! Grabbing a body with the mouse: the picked point is pulled towards the cursor by the core's
//! [`Grab`], a critically damped spring whose force scales with the body's effective mass (so
//! light and heavy bodies follow alike), applied by both solvers every (sub)step. The cursor
//! moves the target on the plane through the picked point facing the camera. While paused there
//! is no step to act through, so the body's pose is moved instead.

use crate::World;
use crate::sim::Grab;
use glam::DVec3;

/// Default natural frequency of the grab spring (Hz); the core caps it at a quarter of the
/// substep rate.
pub const DEFAULT_HERTZ: f64 = 4.0;

/// The plane a grabbed point moves on: through the point, facing the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DragPlane {
    point: DVec3,
    normal: DVec3,
}

impl DragPlane {
    /// Through `point`, normal to the camera's viewing direction `forward`.
    pub fn facing(point: DVec3, forward: DVec3) -> DragPlane {
        DragPlane {
            point,
            normal: forward.normalize_or(DVec3::Z),
        }
    }

    /// Where the ray from `origin` along `dir` meets the plane, if it does in front of it.
    pub fn hit(&self, origin: DVec3, dir: DVec3) -> Option<DVec3> {
        let along = dir.dot(self.normal);
        if along.abs() < 1e-12 {
            return None;
        }
        let t = (self.point - origin).dot(self.normal) / along;
        (t > 0.0).then(|| origin + t * dir)
    }
}

/// Starts pulling `local_point` (body space) of `body` towards `target`. False when the body
/// does not exist or cannot move.
pub fn attach(
    world: &mut World,
    body: usize,
    local_point: DVec3,
    target: DVec3,
    hertz: f64,
) -> bool {
    if !world.bodies.get(body).is_some_and(|b| b.is_dynamic()) {
        return false;
    }
    world.grab = Some(Grab {
        body,
        local_point,
        target,
        hertz,
    });
    wake(world, body);
    true
}

/// Makes a grabbed body take part in the next steps: it and the island it sleeps in wake
/// (every grab path calls this; the step wakes a grabbed body too, but a body moved while
/// paused and let go before the next step was left asleep, and so were the bodies it held up).
pub fn wake(world: &mut World, body: usize) {
    world.wake_island(body);
}

/// Moves the grab's target (and its stiffness).
pub fn retarget(world: &mut World, target: DVec3, hertz: f64) {
    if let Some(grab) = &mut world.grab {
        grab.target = target;
        grab.hertz = hertz;
        let body = grab.body;
        wake(world, body);
    }
}

/// Puts the grabbed body where its grabbed point is at the target, keeping its orientation and
/// velocities (the paused drag).
pub fn place(world: &mut World) {
    let Some(grab) = world.grab else { return };
    if let Some(body) = world.bodies.get_mut(grab.body)
        && body.is_dynamic()
    {
        body.position = grab.target - body.orientation * grab.local_point;
        // Moved: the sleepers it is put among wake in the next step.
        body.moving = true;
    }
    wake(world, grab.body);
}

/// The grabbed point in world space and the spring's force on it over the next (sub)step, for
/// display. `last_substeps` is what the last step took (the soft step takes more than the
/// setting's in a step that begins touching at dt above 0.02; 0 for a step skipped at rest,
/// then the setting's count is used).
pub fn force(world: &World, last_substeps: u32) -> Option<(DVec3, DVec3)> {
    let grab = world.grab?;
    let body = world.bodies.get(grab.body)?;
    let settings = &world.settings;
    let substeps = if last_substeps > 0 {
        last_substeps
    } else {
        settings.substeps
    };
    let h = settings.time_step / substeps.max(1) as f64;
    let velocities = (body.linear_velocity, body.angular_velocity);
    let (arm, impulse) = grab.impulse(body, velocities, h)?;
    Some((body.position + arm, impulse / h))
}

/// The grabbed point of a world with a grab, and its target: the line drawn between them.
pub fn line(world: &World) -> Option<(DVec3, DVec3)> {
    let grab = world.grab?;
    let body = world.bodies.get(grab.body)?;
    Some((body.world_point(grab.local_point), grab.target))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drag_plane_faces_the_camera() {
        let plane = DragPlane::facing(DVec3::new(1.0, 2.0, 3.0), DVec3::new(0.0, 0.0, -2.0));
        let hit = plane
            .hit(DVec3::new(5.0, 5.0, 10.0), DVec3::new(0.0, 0.0, -1.0))
            .unwrap();
        assert_eq!(hit, DVec3::new(5.0, 5.0, 3.0));
        assert!(plane.hit(DVec3::new(0.0, 0.0, 10.0), DVec3::Z).is_none());
        assert!(plane.hit(DVec3::ZERO, DVec3::X).is_none());
    }
}
