//! Mouse and keyboard in the 3D view: left drag orbits, right or middle (or shift) drag pans,
//! ctrl + left drag grabs a body, the wheel zooms, a left click without drag picks a body; and
//! the keyboard shortcuts. Events egui takes (over the panel, or typing in a text field) never
//! reach here.

use super::camera::OrbitCamera;
use super::panel::Action;
use super::window::ViewRect;
use winit::event::{MouseButton, MouseScrollDelta};
use winit::keyboard::{Key, NamedKey};

/// Pixels the cursor may move (in x plus y) before a press counts as a drag, not a click.
const CLICK_SLOP: f64 = 3.0;

struct Drag {
    button: MouseButton,
    start: (f64, f64),
    last: (f64, f64),
    moved: bool,
    /// Started with ctrl: the cursor pulls a grabbed body, the camera stays.
    grab: bool,
}

/// The pointer between events.
#[derive(Default)]
pub struct Pointer {
    /// Cursor position in window pixels, while it is in the window.
    pub cursor: Option<(f64, f64)>,
    drag: Option<Drag>,
    /// Shift held: a left drag pans.
    pub shift: bool,
    /// Ctrl held: a left drag grabs.
    pub ctrl: bool,
}

/// How a button's release ends its drag.
pub enum Release {
    /// A left click that did not move: pick at this window position.
    Pick((f64, f64)),
    /// The end of an orbit or pan, or a click of another button.
    EndDrag,
    /// The end of a grab.
    EndGrab,
}

impl Pointer {
    pub fn dragging(&self) -> bool {
        self.drag.is_some()
    }

    /// Whether a ctrl + left drag (a grab) is under way.
    pub fn grabbing(&self) -> bool {
        self.drag.as_ref().is_some_and(|d| d.grab)
    }

    /// Whether the cursor is over the 3D view.
    pub fn over(&self, view: ViewRect) -> bool {
        self.cursor.is_some_and(|p| view.contains(p))
    }

    /// The cursor moved to `p`: while dragging, orbits or pans `camera` (a view `view_height`
    /// pixels high), or, for a grab, leaves it be. Returns whether something is dragged.
    pub fn moved(&mut self, p: (f64, f64), camera: &mut OrbitCamera, view_height: f64) -> bool {
        self.cursor = Some(p);
        let Some(drag) = &mut self.drag else {
            return false;
        };
        let (dx, dy) = (p.0 - drag.last.0, p.1 - drag.last.1);
        drag.last = p;
        if (p.0 - drag.start.0).abs() + (p.1 - drag.start.1).abs() > CLICK_SLOP {
            drag.moved = true;
        }
        if drag.grab {
            return true;
        }
        let pan = drag.button != MouseButton::Left || self.shift;
        if pan {
            camera.pan(dx, dy, view_height);
        } else {
            camera.orbit(dx, dy);
        }
        true
    }

    /// A button went down: starts a drag when the cursor is over the view, egui did not take the
    /// press (`taken_by_ui`) and no other drag is under way. Returns the cursor position when
    /// the drag is a grab (ctrl + left), for the app to pick the body there.
    pub fn pressed(
        &mut self,
        button: MouseButton,
        view: ViewRect,
        taken_by_ui: bool,
    ) -> Option<(f64, f64)> {
        let p = self.cursor?;
        if taken_by_ui || !view.contains(p) || self.drag.is_some() {
            return None;
        }
        let grab = self.ctrl && button == MouseButton::Left;
        self.drag = Some(Drag {
            button,
            start: p,
            last: p,
            moved: false,
            grab,
        });
        grab.then_some(p)
    }

    /// A button went up: ends the drag it started, if any.
    pub fn released(&mut self, button: MouseButton) -> Option<Release> {
        let drag = self.drag.take_if(|d| d.button == button)?;
        Some(if drag.grab {
            Release::EndGrab
        } else if !drag.moved && button == MouseButton::Left {
            Release::Pick(drag.start)
        } else {
            Release::EndDrag
        })
    }
}

/// Zoom steps of a wheel event: lines, or pixels of a touchpad in 40-pixel steps.
pub fn zoom_steps(delta: MouseScrollDelta) -> f64 {
    match delta {
        MouseScrollDelta::LineDelta(_, y) => y as f64,
        MouseScrollDelta::PixelDelta(p) => p.y / 40.0,
    }
}

/// What a key press asks for.
pub enum Shortcut {
    Action(Action),
    /// Esc: drop the selection.
    Deselect,
    /// H: hide the panel (the view takes the whole window) or show it again.
    TogglePanel,
}

/// Space play/pause, S step, R reset, F frame, P screenshot, H hide or show the panel, Esc
/// deselect, Left / Right one state back / forward in the history.
pub fn shortcut(key: &Key) -> Option<Shortcut> {
    match key {
        Key::Named(NamedKey::Space) => Some(Shortcut::Action(Action::TogglePlay)),
        Key::Named(NamedKey::ArrowLeft) => Some(Shortcut::Action(Action::StepBack)),
        Key::Named(NamedKey::ArrowRight) => Some(Shortcut::Action(Action::StepForward)),
        Key::Named(NamedKey::Escape) => Some(Shortcut::Deselect),
        Key::Character(c) => match c.to_lowercase().as_str() {
            "s" => Some(Shortcut::Action(Action::Step)),
            "r" => Some(Shortcut::Action(Action::Reset)),
            "f" => Some(Shortcut::Action(Action::FrameScene)),
            "p" => Some(Shortcut::Action(Action::Screenshot)),
            "h" => Some(Shortcut::TogglePanel),
            _ => None,
        },
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Keys are read as typed: with or without shift (or caps lock) they ask for the same.
    #[test]
    fn letter_keys_ask_for_their_action_in_either_case() {
        for key in ["h", "H"] {
            let pressed = shortcut(&Key::Character(key.into()));
            assert!(matches!(pressed, Some(Shortcut::TogglePanel)), "{key}");
        }
        for key in ["p", "P"] {
            let pressed = shortcut(&Key::Character(key.into()));
            assert!(
                matches!(pressed, Some(Shortcut::Action(Action::Screenshot))),
                "{key}"
            );
        }
        assert!(shortcut(&Key::Character("q".into())).is_none());
    }
}
