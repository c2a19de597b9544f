//! Comparing two settings on the same scene: how each world is labelled, and how the 3D view is
//! split between them (side by side, one pane each, sharing the camera; or one pane with the
//! second world as a translucent ghost).

use crate::sim::settings::Solver;
use crate::{Settings, StepStats, World};

/// How compared worlds share the view.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Layout {
    /// One pane per world, left to right.
    #[default]
    SideBySide,
    /// One pane: the first world opaque, the others as translucent ghosts.
    Ghost,
}

/// A part of the view and the worlds (lane indices) it shows; the first is drawn opaque, the
/// rest as ghosts.
#[derive(Debug, Clone, PartialEq)]
pub struct Pane {
    /// x, y, width, height (pixels or points, as the view rectangle given).
    pub rect: [f32; 4],
    pub lanes: Vec<usize>,
}

/// Splits the view `rect` for `lanes` worlds: whole for one world or a ghost overlay, else in
/// equal columns.
pub fn panes(rect: [f32; 4], lanes: usize, layout: Layout) -> Vec<Pane> {
    let lanes = lanes.max(1);
    if lanes == 1 || layout == Layout::Ghost {
        return vec![Pane {
            rect,
            lanes: (0..lanes).collect(),
        }];
    }
    let [x, y, w, h] = rect;
    let width = w / lanes as f32;
    (0..lanes)
        .map(|k| {
            // Whole pixels at the seams, so the two halves neither overlap nor leave a gap.
            let left = (x + k as f32 * width).round();
            let right = if k + 1 == lanes {
                x + w
            } else {
                (x + (k + 1) as f32 * width).round()
            };
            Pane {
                rect: [left, y, (right - left).max(1.0), h],
                lanes: vec![k],
            }
        })
        .collect()
}

/// Width over height of each pane of a `width` x `height` view.
pub fn pane_aspect(width: f64, height: f64, lanes: usize, layout: Layout) -> f64 {
    let columns = if layout == Layout::Ghost {
        1
    } else {
        lanes.max(1)
    };
    width / columns as f64 / height.max(1e-9)
}

/// "A", "B": the worlds of a comparison.
pub fn lane_name(lane: usize) -> char {
    (b'A' + lane.min(25) as u8) as char
}

/// Colour of world `lane`'s label and curves.
pub fn lane_color(lane: usize) -> egui::Color32 {
    [
        egui::Color32::from_rgb(110, 170, 255),
        egui::Color32::from_rgb(255, 150, 70),
        egui::Color32::from_rgb(140, 220, 120),
    ][lane % 3]
}

/// A compared world's own statistics in one short line: time, energy, contacts and the cost of
/// its last step.
pub fn lane_statistics(world: &World, last: &StepStats) -> String {
    format!(
        "t {:.2} s · E {:.4e} · {} contacts · {:.2} ms/step",
        world.time,
        world.total_energy(),
        last.contacts + last.ground_contacts,
        1e3 * last.timings.total()
    )
}

/// A short name for `settings`: the preset of its solver ("coursework" for the defaults,
/// "accurate" for the soft-step preset) followed by the settings that differ from it.
pub fn settings_label(settings: &Settings) -> String {
    let (name, preset) = match settings.solver {
        Solver::Coursework => ("coursework", Settings::default()),
        Solver::SoftStep => ("accurate", Settings::accurate()),
    };
    let (Ok(serde_json::Value::Object(ours)), Ok(serde_json::Value::Object(base))) = (
        serde_json::to_value(settings),
        serde_json::to_value(&preset),
    ) else {
        return name.to_string();
    };
    let mut label = name.to_string();
    for (key, value) in &ours {
        if base.get(key) != Some(value) {
            let key = if key == "time_step" { "dt" } else { key };
            label += &format!(", {} {}", key.replace('_', " "), show_value(value));
        }
    }
    label
}

/// A settings value as typed: numbers without trailing zeros, enum names in kebab case.
fn show_value(value: &serde_json::Value) -> String {
    match value {
        serde_json::Value::String(s) => s.replace('_', "-"),
        serde_json::Value::Array(items) => {
            let items: Vec<String> = items.iter().map(show_value).collect();
            format!("({})", items.join(", "))
        }
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_name_the_preset_and_the_differences() {
        assert_eq!(settings_label(&Settings::default()), "coursework");
        assert_eq!(settings_label(&Settings::accurate()), "accurate");
        let s = Settings {
            time_step: 0.01,
            ..Settings::default()
        };
        assert_eq!(settings_label(&s), "coursework, dt 0.01");
        let s = Settings {
            substeps: 8,
            ..Settings::accurate()
        };
        assert_eq!(settings_label(&s), "accurate, substeps 8");
    }

    #[test]
    fn side_by_side_panes_tile_the_view() {
        let panes = panes([10.0, 20.0, 801.0, 600.0], 2, Layout::SideBySide);
        assert_eq!(panes.len(), 2);
        assert_eq!(panes[0].rect[0], 10.0);
        assert_eq!(panes[0].rect[0] + panes[0].rect[2], panes[1].rect[0]);
        assert_eq!(panes[1].rect[0] + panes[1].rect[2], 811.0);
        assert_eq!(panes[1].lanes, vec![1]);
        let ghost = super::panes([0.0, 0.0, 800.0, 600.0], 2, Layout::Ghost);
        assert_eq!(ghost[0].lanes, vec![0, 1]);
        assert!((pane_aspect(800.0, 600.0, 2, Layout::SideBySide) - 800.0 / 1200.0).abs() < 1e-12);
    }
}
