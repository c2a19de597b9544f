//! An orbit camera: a target point, yaw and pitch around it, a distance. Math in f64, handed to the
//! GPU as an f32 view-projection matrix.

use crate::World;
use glam::{DMat4, DVec3, DVec4, Mat4, Vec3};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitCamera {
    pub target: DVec3,
    /// Radians around +y; 0 looks along -z (eye on +z).
    pub yaw: f64,
    /// Radians above the horizon.
    pub pitch: f64,
    pub distance: f64,
    /// Vertical field of view, radians.
    pub fov_y: f64,
    /// Radius of the scene, for the far plane.
    pub scene_radius: f64,
}

impl Default for OrbitCamera {
    fn default() -> Self {
        OrbitCamera {
            target: DVec3::ZERO,
            yaw: 35f64.to_radians(),
            pitch: 25f64.to_radians(),
            distance: 10.0,
            fov_y: 45f64.to_radians(),
            scene_radius: 10.0,
        }
    }
}

/// Steepest pitch, radians above or below the horizon (88.8 degrees): at 90 the view direction
/// lies along the up vector and the view turns about itself.
pub const MAX_PITCH: f64 = 1.55;

/// What the shaders need from the camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraMatrices {
    pub view_proj: Mat4,
    pub eye: Vec3,
}

/// Axis-aligned box around every body, stretched down to the ground (y = 0) so that the ground
/// under falling bodies is in view.
pub fn scene_bounds(world: &World) -> (DVec3, DVec3) {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for b in world.body_aabbs() {
        if b.min.is_finite() && b.max.is_finite() {
            lo = lo.min(b.min);
            hi = hi.max(b.max);
        }
    }
    if !lo.is_finite() || !hi.is_finite() {
        return (DVec3::splat(-1.0), DVec3::splat(1.0));
    }
    lo.y = lo.y.min(0.0);
    hi.y = hi.y.max(0.0);
    (lo, hi)
}

/// Distances the camera may be at, zoomed or given: beyond them the depth range, in the `f32`
/// the GPU takes, leaves nothing to draw (`--camera 0,20,1e300` recorded empty frames).
pub const DISTANCE_RANGE: (f64, f64) = (1e-3, 1e7);

/// Largest coordinate a given camera target may have: within the `f32` the GPU takes, with
/// room for the distance.
pub const TARGET_LIMIT: f64 = 1e30;

impl OrbitCamera {
    /// Keeps the angles, points at the scene and backs off until it all fits.
    pub fn frame(&mut self, world: &World, aspect: f64) {
        let (lo, hi) = scene_bounds(world);
        self.target = (lo + hi) / 2.0;
        let radius = ((hi - lo).length() / 2.0).max(1e-3);
        self.scene_radius = radius;
        let half_fov_y = self.fov_y / 2.0;
        let half_fov_x = (half_fov_y.tan() * aspect.max(1e-3)).atan();
        self.distance = radius / half_fov_y.min(half_fov_x).sin() * 1.08;
    }

    pub fn eye(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        self.target + self.distance * DVec3::new(cp * sy, sp, cp * cy)
    }

    fn near_far(&self) -> (f64, f64) {
        let near = (self.distance * 0.02).max(1e-4);
        let far = self.distance + 4.0 * self.scene_radius + 10.0 * near;
        (near, far)
    }

    pub fn view_proj_f64(&self, aspect: f64) -> DMat4 {
        let (near, far) = self.near_far();
        // Right-handed, depth 0..1 (what wgpu expects).
        let view = glam::dcamera::rh::view::look_at_mat4(self.eye(), self.target, DVec3::Y);
        let proj =
            glam::dcamera::rh::proj::directx::perspective(self.fov_y, aspect.max(1e-6), near, far);
        proj * view
    }

    pub fn matrices(&self, aspect: f64) -> CameraMatrices {
        CameraMatrices {
            view_proj: self.view_proj_f64(aspect).as_mat4(),
            eye: self.eye().as_vec3(),
        }
    }

    /// Pixel coordinates (origin top left, x right, y down) of a world point in a `width` x
    /// `height` image, or None when it is behind the camera.
    pub fn project(&self, p: DVec3, width: f64, height: f64) -> Option<(f64, f64)> {
        let clip = self.view_proj_f64(width / height) * p.extend(1.0);
        if clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        Some(((ndc.x + 1.0) / 2.0 * width, (1.0 - ndc.y) / 2.0 * height))
    }

    /// The ray through pixel position `(x, y)` (continuous coordinates: the centre of pixel
    /// (i, j) is (i + 0.5, j + 0.5)): origin and unit direction.
    pub fn ray(&self, x: f64, y: f64, width: f64, height: f64) -> (DVec3, DVec3) {
        let inverse = self.view_proj_f64(width / height).inverse();
        let ndc_x = 2.0 * x / width - 1.0;
        let ndc_y = 1.0 - 2.0 * y / height;
        let unproject = |z: f64| {
            let p: DVec4 = inverse * DVec4::new(ndc_x, ndc_y, z, 1.0);
            p.truncate() / p.w
        };
        let near = unproject(0.0);
        let far = unproject(1.0);
        (near, (far - near).normalize())
    }

    /// Orbit by a mouse drag of `(dx, dy)` pixels.
    pub fn orbit(&mut self, dx: f64, dy: f64) {
        self.yaw -= dx * 0.008;
        self.pitch = (self.pitch + dy * 0.008).clamp(-MAX_PITCH, MAX_PITCH);
    }

    /// Move the target in the view plane by a drag of `(dx, dy)` pixels in a view `height` pixels
    /// tall.
    pub fn pan(&mut self, dx: f64, dy: f64, height: f64) {
        let forward = (self.target - self.eye()).normalize();
        let right = forward.cross(DVec3::Y).normalize_or(DVec3::X);
        let up = right.cross(forward);
        let units_per_pixel = 2.0 * self.distance * (self.fov_y / 2.0).tan() / height.max(1.0);
        self.target += (-dx * right + dy * up) * units_per_pixel;
    }

    /// Zoom by `steps` wheel notches (positive = closer).
    pub fn zoom(&mut self, steps: f64) {
        let (closest, farthest) = DISTANCE_RANGE;
        self.distance = (self.distance * 0.88f64.powf(steps)).clamp(closest, farthest);
    }

    /// Parses `YAW,PITCH[,DISTANCE[,X,Y,Z]]` (degrees, scene units) over a framed camera.
    pub fn apply_spec(&mut self, spec: &str) -> Result<(), String> {
        let values: Result<Vec<f64>, _> =
            spec.split(',').map(|s| s.trim().parse::<f64>()).collect();
        let values = values.map_err(|e| {
            format!("--camera '{spec}': {e}; expected YAW,PITCH[,DISTANCE[,X,Y,Z]] in degrees")
        })?;
        if !matches!(values.len(), 2 | 3 | 6) || values.iter().any(|v| !v.is_finite()) {
            return Err(format!(
                "--camera '{spec}': expected YAW,PITCH[,DISTANCE[,X,Y,Z]] (2, 3 or 6 finite numbers)"
            ));
        }
        // Past 90 degrees the camera would stand on its head; up to it, it stops at MAX_PITCH
        // (95 was taken as 88.8 without a word).
        if values[1].abs() > 90.0 {
            return Err(format!(
                "--camera '{spec}': the pitch must lie in -90..=90 degrees (from below to straight \
                 down), got {}; the steepest view is {:.1}",
                crate::io::echoed(values[1]),
                MAX_PITCH.to_degrees()
            ));
        }
        self.yaw = values[0].to_radians();
        self.pitch = values[1].to_radians().clamp(-MAX_PITCH, MAX_PITCH);
        if values.len() >= 3 {
            let (closest, farthest) = DISTANCE_RANGE;
            if !(closest..=farthest).contains(&values[2]) {
                return Err(format!(
                    "--camera '{spec}': the distance must be from {closest:e} to {farthest:e} scene units"
                ));
            }
            self.distance = values[2];
        }
        if values.len() == 6 {
            // In the `f32` the GPU takes, a target past 3.4e38 is infinite and every frame
            // blank (`--camera 0,30,10,1e39,0,0`).
            if values[3..].iter().any(|v| v.abs() > TARGET_LIMIT) {
                return Err(format!(
                    "--camera '{spec}': the target's coordinates must lie within {TARGET_LIMIT:e} scene units"
                ));
            }
            self.target = DVec3::new(values[3], values[4], values[5]);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pitch past the vertical is refused; one up to it is taken at the steepest view.
    #[test]
    fn camera_specs_refuse_a_pitch_past_the_vertical() {
        let mut camera = OrbitCamera::default();
        let error = camera.apply_spec("30,95").unwrap_err();
        assert!(
            error.contains("the pitch must lie in -90..=90 degrees"),
            "{error}"
        );
        assert!(camera.apply_spec("30,-90.5").is_err());
        camera.apply_spec("30,90").unwrap();
        assert_eq!(camera.pitch, MAX_PITCH);
        camera.apply_spec("30,-45").unwrap();
        assert!((camera.pitch + 45f64.to_radians()).abs() < 1e-15);
    }

    #[test]
    fn ray_and_projection_agree() {
        let cam = OrbitCamera {
            target: DVec3::new(1.0, 2.0, 3.0),
            distance: 20.0,
            ..Default::default()
        };
        let p = DVec3::new(2.0, 3.5, 1.0);
        let (x, y) = cam.project(p, 640.0, 360.0).unwrap();
        let (o, d) = cam.ray(x, y, 640.0, 360.0);
        let closest = o + d * (p - o).dot(d);
        assert!((closest - p).length() < 1e-9);
        let (cx, cy) = cam.project(cam.target, 640.0, 360.0).unwrap();
        assert!((cx - 320.0).abs() < 1e-9 && (cy - 180.0).abs() < 1e-9);
    }

    #[test]
    fn camera_spec() {
        let mut cam = OrbitCamera::default();
        cam.apply_spec("90,10,50,1,2,3").unwrap();
        assert_eq!(cam.distance, 50.0);
        assert_eq!(cam.target, DVec3::new(1.0, 2.0, 3.0));
        assert!(cam.apply_spec("1").is_err());
        assert!(cam.apply_spec("a,b").is_err());
        let nan = cam.apply_spec("NaN,25").unwrap_err();
        assert!(nan.contains("2, 3 or 6 finite numbers"), "{nan}");
        let far = cam.apply_spec("0,20,1e300").unwrap_err();
        assert!(far.contains("from 1e-3 to 1e7"), "{far}");
        let off = cam.apply_spec("0,30,10,1e39,0,0").unwrap_err();
        assert!(off.contains("within 1e30 scene units"), "{off}");
        cam.apply_spec("0,30,10,1e30,0,0").unwrap();
        assert!(cam.matrices(1.0).view_proj.is_finite());
    }

    /// At either end of the distance range the GPU's `f32` matrix still puts the target inside
    /// the depth range; past it (1e300) it does not.
    #[test]
    fn target_is_drawn_across_the_distance_range() {
        let depth_of_target = |distance: f64| {
            let cam = OrbitCamera {
                target: DVec3::new(3.0, 1.0, -2.0),
                distance,
                scene_radius: 5.0,
                ..Default::default()
            };
            let clip = cam.matrices(16.0 / 9.0).view_proj * cam.target.as_vec3().extend(1.0);
            clip.z / clip.w
        };
        let (closest, farthest) = DISTANCE_RANGE;
        for distance in [closest, 1.0, farthest] {
            let depth = depth_of_target(distance);
            assert!((0.0..=1.0).contains(&depth), "{distance}: {depth}");
            let mut cam = OrbitCamera::default();
            cam.apply_spec(&format!("0,20,{distance}")).unwrap();
            assert_eq!(cam.distance, distance);
        }
        assert!(!(0.0..=1.0).contains(&depth_of_target(1e300)));
    }
}
