//! The pointer in the view's panes: the camera ray through a window position, in the pane under
//! it (each pane is a whole camera view of its own world), and the state of a grab.

use super::camera::OrbitCamera;
use super::compare::{self, Layout};
use super::grab::DragPlane;
use super::window::ViewRect;
use glam::DVec3;

/// A camera ray through a pane.
#[derive(Debug, Clone, Copy)]
pub struct PaneRay {
    /// The world the pane shows (the opaque one in a ghost overlay).
    pub lane: usize,
    pub pane: [f32; 4],
    pub origin: DVec3,
    pub dir: DVec3,
}

/// The ray through window position `p` in the pane under it, for a view showing `lanes` worlds.
pub fn ray_at(
    camera: &OrbitCamera,
    view: ViewRect,
    lanes: usize,
    layout: Layout,
    p: (f64, f64),
) -> Option<PaneRay> {
    let panes = compare::panes(view.0, lanes, layout);
    let pane = panes.iter().find(|pane| ViewRect(pane.rect).contains(p))?;
    let (origin, dir) = ray_in(camera, pane.rect, p);
    Some(PaneRay {
        lane: pane.lanes[0],
        pane: pane.rect,
        origin,
        dir,
    })
}

/// The ray through window position `p` of the camera drawing into `pane` (it may lie outside).
pub fn ray_in(camera: &OrbitCamera, pane: [f32; 4], p: (f64, f64)) -> (DVec3, DVec3) {
    let [x, y, w, h] = pane.map(|v| v as f64);
    camera.ray(p.0 - x, p.1 - y, w.max(1.0), h.max(1.0))
}

/// A grab under way: the plane its target moves on and the pane it started in.
#[derive(Debug, Clone, Copy)]
pub struct GrabDrag {
    pub plane: DragPlane,
    pub pane: [f32; 4],
}
