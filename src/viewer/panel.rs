//! The egui side panel: controls, every simulation setting, live statistics and plots; and the
//! overlay over the 3D view.

use super::renderer::DrawOptions;
use super::session::Session;
use crate::sim::{Choice, Settings};
use egui::{Color32, RichText};
use egui_plot::{Line, Plot, PlotPoints};

/// What the panel asks the app to do after this frame's UI.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    TogglePlay,
    Step,
    Reset,
    FrameScene,
    Screenshot,
    /// Load a built-in scene name or a file path.
    Load(String),
    StartRecording,
    StopRecording,
}

/// Panel state that lives across frames.
pub struct PanelState {
    pub draw: DrawOptions,
    pub open_path: String,
    pub load_error: Option<String>,
    /// Last status line (screenshot written, recording saved, ...).
    pub message: Option<String>,
    pub record_path: String,
    pub record_fps: f64,
}

impl Default for PanelState {
    fn default() -> Self {
        let record_path = if super::record::ffmpeg_on_path() {
            "tumble-recording.mp4"
        } else {
            "tumble-recording.gif"
        };
        PanelState {
            draw: DrawOptions::default(),
            open_path: String::new(),
            load_error: None,
            message: None,
            record_path: record_path.into(),
            record_fps: 30.0,
        }
    }
}

/// Read-only facts for the panel.
pub struct FrameInfo<'a> {
    /// Mean seconds between frames and spent rendering, over recent frames.
    pub frame_interval: f64,
    pub frame_work: f64,
    pub adapter: &'a str,
    pub msaa: u32,
    pub draw_calls: usize,
    /// Output path and frames so far while recording.
    pub recording: Option<(&'a str, u64)>,
}

/// One frame of the UI.
pub struct UiFrame {
    pub output: egui::FullOutput,
    pub actions: Vec<Action>,
    /// What the panel leaves of the window, in points: the 3D view.
    pub view: egui::Rect,
}

/// Runs egui for one frame: the panel on the right, the overlay over the rest, which is the 3D
/// view.
pub fn run(
    ctx: &egui::Context,
    input: egui::RawInput,
    session: &mut Session,
    state: &mut PanelState,
    info: &FrameInfo,
) -> UiFrame {
    let mut actions = Vec::new();
    let mut view = egui::Rect::NOTHING;
    let output = ctx.run_ui(input, |ui| {
        // No fill: the window is cleared to the panel colour before egui draws, which spares
        // software rasterisers a window-high quad every frame.
        let frame = egui::Frame::side_top_panel(ui.style()).fill(egui::Color32::TRANSPARENT);
        egui::Panel::right("controls")
            .frame(frame)
            .default_size(360.0)
            .size_range(260.0..=640.0)
            .show(ui, |ui| {
                actions = show(ui, session, state, info);
            });
        view = ui.available_rect_before_wrap();
        overlay(ui.ctx(), view, session, state);
    });
    UiFrame {
        output,
        actions,
        view,
    }
}

fn stat(ui: &mut egui::Ui, name: &str, value: impl Into<egui::WidgetText>) {
    ui.label(name);
    ui.label(value);
    ui.end_row();
}

/// Draws the panel into `ui` and returns the actions requested.
pub fn show(
    ui: &mut egui::Ui,
    session: &mut Session,
    state: &mut PanelState,
    info: &FrameInfo,
) -> Vec<Action> {
    let mut actions = Vec::new();
    egui::ScrollArea::vertical().auto_shrink([true, false]).show(ui, |ui| {
        ui.heading("tumble");
        playback_controls(ui, session.playing, &mut actions);
        recording_controls(ui, state, info.recording, &mut actions);
        if let Some(message) = &state.message {
            ui.label(RichText::new(message).small());
        }
        ui.separator();

        scene_picker(ui, session, state, &mut actions);
        ui.separator();

        egui::CollapsingHeader::new("Simulation settings").default_open(true).show(ui, |ui| settings_ui(ui, &mut session.world.settings));

        egui::CollapsingHeader::new("Display").default_open(true).show(ui, |ui| display_ui(ui, &mut state.draw));

        egui::CollapsingHeader::new("Statistics").default_open(true).show(ui, |ui| statistics_ui(ui, session, info));

        egui::CollapsingHeader::new("Energy and constraint violation").default_open(true).show(ui, |ui| plots_ui(ui, session));

        egui::CollapsingHeader::new("Selected body").default_open(true).show(ui, |ui| selection_ui(ui, session, state.draw.selected));

        ui.separator();
        ui.small("Drag: orbit · right/middle drag or shift-drag: pan · wheel: zoom · click: pick a body");
        ui.small("Space play/pause · S step · R reset · F frame · P screenshot · Esc deselect");
    });
    actions
}

/// Play/pause, step, reset, frame and screenshot buttons, with their keys as hover text.
fn playback_controls(ui: &mut egui::Ui, playing: bool, actions: &mut Vec<Action>) {
    ui.horizontal(|ui| {
        let label = if playing { "Pause" } else { "Play" };
        if ui.button(label).on_hover_text("Space").clicked() {
            actions.push(Action::TogglePlay);
        }
        if ui.button("Step").on_hover_text("S").clicked() {
            actions.push(Action::Step);
        }
        if ui.button("Reset").on_hover_text("R").clicked() {
            actions.push(Action::Reset);
        }
        if ui.button("Frame").on_hover_text("F").clicked() {
            actions.push(Action::FrameScene);
        }
        if ui
            .button("Screenshot")
            .on_hover_text("P: PNG of the window")
            .clicked()
        {
            actions.push(Action::Screenshot);
        }
    });
}

/// While recording: a stop button and the frame count; otherwise the record button with the
/// output path and frame rate.
fn recording_controls(
    ui: &mut egui::Ui,
    state: &mut PanelState,
    recording: Option<(&str, u64)>,
    actions: &mut Vec<Action>,
) {
    ui.horizontal(|ui| match recording {
        Some((path, frames)) => {
            if ui.button("Stop recording").clicked() {
                actions.push(Action::StopRecording);
            }
            ui.colored_label(
                Color32::from_rgb(255, 90, 90),
                format!("REC {path}: {frames} frames"),
            );
        }
        None => {
            if ui
                .button("Record")
                .on_hover_text(
                    "Record the 3D view: .mp4 (ffmpeg), .gif, or a directory for PNG frames; \
                     frames are taken every 1/fps of simulated time",
                )
                .clicked()
            {
                actions.push(Action::StartRecording);
            }
            ui.add(egui::TextEdit::singleline(&mut state.record_path).desired_width(150.0));
            ui.add(
                egui::DragValue::new(&mut state.record_fps)
                    .range(1.0..=120.0)
                    .suffix(" fps"),
            );
        }
    });
}

fn display_ui(ui: &mut egui::Ui, draw: &mut DrawOptions) {
    ui.checkbox(&mut draw.grid, "Ground grid");
    ui.checkbox(&mut draw.constraints, "Constraint segments")
        .on_hover_text(
            "Green within bounds, through yellow to red at 10% of the rest length outside them",
        );
    ui.checkbox(&mut draw.contacts, "Contact points and normals");
}

fn scene_picker(
    ui: &mut egui::Ui,
    session: &Session,
    state: &mut PanelState,
    actions: &mut Vec<Action>,
) {
    let mut choice = session.scene.clone();
    ui.horizontal(|ui| {
        ui.label("Scene");
        egui::ComboBox::from_id_salt("scene")
            .selected_text(choice.clone())
            .show_ui(ui, |ui| {
                for (name, _) in crate::BUILTIN_SCENES {
                    ui.selectable_value(&mut choice, name.to_string(), *name);
                }
            });
    });
    if choice != session.scene {
        actions.push(Action::Load(choice));
    }
    ui.horizontal(|ui| {
        let edit = ui.add(
            egui::TextEdit::singleline(&mut state.open_path)
                .hint_text("path/to/X-scene.txt")
                .desired_width(180.0),
        );
        let enter = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
        if (ui.button("Open").clicked() || enter) && !state.open_path.trim().is_empty() {
            actions.push(Action::Load(state.open_path.trim().to_string()));
        }
    });
    if let Some(error) = &state.load_error {
        ui.colored_label(Color32::from_rgb(255, 110, 110), error);
    }
    let world = &session.world;
    ui.label(format!(
        "{} bodies ({} fixed), {} shapes, {} constraints",
        world.bodies.len(),
        world.bodies.iter().filter(|b| b.fixed).count(),
        world.shapes.len(),
        world.constraints.len()
    ));
}

/// Every field of [`Settings`]. The destructuring has no `..`: a new setting in the core does
/// not compile until it has a control here.
fn settings_ui(ui: &mut egui::Ui, settings: &mut Settings) {
    preset_buttons(ui, settings);
    let Settings {
        solver,
        time_step,
        restitution,
        max_iterations,
        tolerance,
        gravity,
        friction,
        skip_separating_contacts,
        restitution_threshold,
        contact_patches,
        substeps,
        rotation_integrator,
        sleep,
        broad_phase,
        constraint_schedule,
    } = settings;
    enum_choice(ui, "solver", solver);
    ui.add(egui::Slider::new(restitution, 0.0..=1.0).text("restitution"));
    ui.add(egui::Slider::new(friction, 0.0..=1.5).text("friction"))
        .on_hover_text("Coulomb friction coefficient (soft-step solver; the coursework has none)");
    ui.add(
        egui::Slider::new(time_step, 0.0005..=0.05)
            .logarithmic(true)
            .text("time step (s)"),
    );
    ui.add(
        egui::Slider::new(max_iterations, 1..=100_000)
            .logarithmic(true)
            .text("max iterations"),
    )
    .on_hover_text(
        "The coursework's maxIterations: a step makes at most ceil(K / M) constraint visits, \
         M = number of inequality constraints (two per record)",
    );
    ui.add(
        egui::Slider::new(tolerance, 1e-6..=0.1)
            .logarithmic(true)
            .text("tolerance"),
    );
    ui.add(egui::Slider::new(substeps, 1..=32).text("substeps"));
    ui.add(egui::Slider::new(restitution_threshold, 0.0..=5.0).text("restitution threshold"))
        .on_hover_text("Contacts closing slower than this (units/s) bounce with e = 0 (0: off)");
    ui.horizontal(|ui| {
        ui.label("gravity");
        ui.add(egui::DragValue::new(&mut gravity.x).speed(0.1).prefix("x "));
        ui.add(egui::DragValue::new(&mut gravity.y).speed(0.1).prefix("y "));
        ui.add(egui::DragValue::new(&mut gravity.z).speed(0.1).prefix("z "));
    });
    ui.checkbox(skip_separating_contacts, "skip separating contacts")
        .on_hover_text("No impulse for contacts whose bodies already separate");
    ui.checkbox(sleep, "sleep")
        .on_hover_text("Islands resting for half a second sleep until touched (soft-step solver)");
    ui.checkbox(contact_patches, "contact patches")
        .on_hover_text(
            "Contacts act at the centroid of the contact patch, not at one deepest point",
        );
    enum_choice(ui, "rotation integrator", rotation_integrator);
    enum_choice(ui, "broad phase", broad_phase);
    enum_choice(ui, "constraint schedule", constraint_schedule);
}

/// Buttons that replace every setting but the time step by a preset.
fn preset_buttons(ui: &mut egui::Ui, settings: &mut Settings) {
    ui.horizontal(|ui| {
        if ui
            .button("Coursework defaults")
            .on_hover_text("Settings::default(): reproduces the coursework")
            .clicked()
        {
            *settings = Settings {
                time_step: settings.time_step,
                ..Settings::default()
            };
        }
        if ui
            .button("Accurate preset")
            .on_hover_text(
                "Settings::accurate(): the best combination found by the accuracy benchmark",
            )
            .clicked()
        {
            *settings = Settings {
                time_step: settings.time_step,
                ..Settings::accurate()
            };
        }
    });
}

/// A combo box over every value of a settings enum (new values appear by themselves).
fn enum_choice<T: Choice>(ui: &mut egui::Ui, label: &str, value: &mut T) {
    egui::ComboBox::from_label(label)
        .selected_text(value.name())
        .show_ui(ui, |ui| {
            for &variant in T::ALL {
                ui.selectable_value(value, variant, variant.name())
                    .on_hover_text(variant.help());
            }
        });
}

fn statistics_ui(ui: &mut egui::Ui, session: &Session, info: &FrameInfo) {
    egui::Grid::new("stats")
        .num_columns(2)
        .striped(false)
        .show(ui, |ui| {
            frame_rows(ui, info);
            stepping_rows(ui, session);
            world_rows(ui, session);
            stat(
                ui,
                "draw calls",
                format!("{} for bodies, {}x MSAA", info.draw_calls, info.msaa),
            );
        });
    ui.add(egui::Label::new(RichText::new(format!("GPU: {}", info.adapter)).small()).wrap());
}

/// Frame interval and rendering work.
fn frame_rows(ui: &mut egui::Ui, info: &FrameInfo) {
    let fps = if info.frame_interval > 0.0 {
        1.0 / info.frame_interval
    } else {
        0.0
    };
    stat(
        ui,
        "frame time",
        format!("{:.1} ms ({fps:.0} fps)", 1e3 * info.frame_interval),
    );
    stat(
        ui,
        "CPU per frame",
        format!("{:.1} ms", 1e3 * info.frame_work),
    );
}

/// Simulated time, the pace against real time, and this frame's steps with their stage timings.
fn stepping_rows(ui: &mut egui::Ui, session: &Session) {
    let world = &session.world;
    stat(
        ui,
        "simulated",
        format!("{:.3} s, step {}", world.time, world.step_count),
    );
    match session.ratio() {
        Some(r) if session.playing && (r < 0.97 || session.behind) => {
            stat(
                ui,
                "sim / real",
                RichText::new(format!("{r:.2}x (cannot keep up)"))
                    .color(Color32::from_rgb(255, 170, 60)),
            );
        }
        Some(r) if session.playing => stat(ui, "sim / real", format!("{r:.2}x")),
        _ => stat(
            ui,
            "sim / real",
            if session.playing { "-" } else { "paused" },
        ),
    }
    stat(ui, "steps this frame", format!("{}", session.frame_steps));
    let steps = session.frame_steps.max(1) as f64;
    for (stage, seconds) in session.frame_timings.iter() {
        stat(
            ui,
            &format!("  {}", stage.name().replace('_', " ")),
            format!("{:.3} ms/step", 1e3 * seconds / steps),
        );
    }
    stat(
        ui,
        "  total",
        format!("{:.3} ms/step", 1e3 * session.frame_timings.total() / steps),
    );
}

/// Bodies, contacts and constraint work of the last step, energy, and frozen bodies.
fn world_rows(ui: &mut egui::Ui, session: &Session) {
    let world = &session.world;
    let last = &session.last;
    stat(ui, "bodies", format!("{}", world.bodies.len()));
    stat(
        ui,
        "contacts",
        format!(
            "{} body-body, {} ground",
            last.contacts, last.ground_contacts
        ),
    );
    stat(
        ui,
        "deepest penetration",
        format!("{:.4}", last.max_penetration),
    );
    if !world.constraints.is_empty() {
        stat(
            ui,
            "constraint visits",
            format!(
                "{} ({} corrections)",
                last.constraint_visits, last.constraint_corrections
            ),
        );
        if last.budget_hit {
            stat(
                ui,
                "budget",
                RichText::new("ran out (raise max visits)").color(Color32::from_rgb(255, 110, 110)),
            );
        } else {
            stat(ui, "budget", "enough");
        }
    }
    stat(ui, "total energy", format!("{:.6e}", world.total_energy()));
    let quarantined = world.bodies.iter().filter(|b| b.quarantined).count();
    if quarantined > 0 {
        stat(
            ui,
            "frozen (non-finite)",
            RichText::new(format!("{quarantined}")).color(Color32::from_rgb(255, 110, 110)),
        );
    }
}

fn plots_ui(ui: &mut egui::Ui, session: &Session) {
    let energy: PlotPoints = session.history.iter().map(|s| [s.time, s.energy]).collect();
    Plot::new("energy_plot")
        .height(90.0)
        .allow_zoom(false)
        .allow_drag(false)
        .allow_scroll(false)
        .y_axis_label("energy")
        .show(ui, |plot| plot.line(Line::new("total energy", energy)));
    let violation: PlotPoints = session
        .history
        .iter()
        .map(|s| [s.time, s.violation])
        .collect();
    Plot::new("violation_plot")
        .height(90.0)
        .allow_zoom(false)
        .allow_drag(false)
        .allow_scroll(false)
        .include_y(0.0)
        .y_axis_label("max violation")
        .show(ui, |plot| {
            plot.line(
                Line::new("max constraint violation", violation)
                    .color(Color32::from_rgb(240, 120, 60)),
            )
        });
}

fn selection_ui(ui: &mut egui::Ui, session: &Session, selected: Option<usize>) {
    let Some(index) = selected.filter(|&i| i < session.world.bodies.len()) else {
        ui.weak("Click a body to inspect it.");
        return;
    };
    let world = &session.world;
    let body = &world.bodies[index];
    let v3 = |v: glam::DVec3| format!("({:.3}, {:.3}, {:.3})", v.x, v.y, v.z);
    egui::Grid::new("selected")
        .num_columns(2)
        .striped(false)
        .show(ui, |ui| {
            stat(
                ui,
                "body",
                format!(
                    "{index} ({})",
                    world
                        .shape_names
                        .get(body.shape)
                        .map_or("?", |s| s.as_str())
                ),
            );
            stat(
                ui,
                "mass",
                if body.fixed {
                    "fixed".to_string()
                } else {
                    format!("{:.4}", body.mass)
                },
            );
            stat(ui, "position", v3(body.position));
            stat(ui, "velocity", v3(body.linear_velocity));
            stat(ui, "speed", format!("{:.4}", body.linear_velocity.length()));
            stat(ui, "angular velocity", v3(body.angular_velocity));
            if body.quarantined {
                stat(
                    ui,
                    "state",
                    RichText::new("frozen: went non-finite")
                        .color(Color32::from_rgb(255, 110, 110)),
                );
            }
        });
}

/// A few lines over the top left corner of the 3D view: time, play state, the sim/real ratio
/// when the simulation falls behind, and the picked body.
pub fn overlay(ctx: &egui::Context, view: egui::Rect, session: &Session, state: &PanelState) {
    egui::Area::new(egui::Id::unique("view_overlay"))
        .fixed_pos(view.min + egui::vec2(10.0, 8.0))
        .interactable(false)
        .show(ctx, |ui| {
            ui.style_mut().wrap_mode = Some(egui::TextWrapMode::Extend);
            let world = &session.world;
            let play = if session.playing { "" } else { "  (paused)" };
            ui.label(
                RichText::new(format!("{}  t = {:.2} s{play}", session.scene, world.time))
                    .color(Color32::from_gray(210)),
            );
            if session.playing
                && let Some(r) = session.ratio()
                && (r < 0.97 || session.behind)
            {
                ui.label(
                    RichText::new(format!("simulation at {r:.2}x real time (cannot keep up)"))
                        .color(Color32::from_rgb(255, 170, 60)),
                );
            }
            if let Some(index) = state.draw.selected.filter(|&i| i < world.bodies.len()) {
                let b = &world.bodies[index];
                let v3 = |v: glam::DVec3| format!("({:.2}, {:.2}, {:.2})", v.x, v.y, v.z);
                let mass = if b.fixed {
                    "fixed".to_string()
                } else {
                    format!("{:.3}", b.mass)
                };
                ui.label(
                    RichText::new(format!(
                        "body {index}: mass {mass}\nvelocity {}\nangular velocity {}",
                        v3(b.linear_velocity),
                        v3(b.angular_velocity)
                    ))
                    .color(Color32::from_rgb(255, 220, 120)),
                );
            }
        });
}
