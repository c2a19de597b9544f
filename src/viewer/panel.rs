//! The egui side panel: controls, the comparison, the rewind timeline, every simulation setting,
//! live statistics and plots; and the overlay over the 3D view with each pane's label.

use super::compare::{self, Layout};
use super::labels::{LABEL_MARGIN, Label, label_width};
use super::renderer::DrawOptions;
use super::session::{Lane, Session};
use crate::sim::settings::Solver;
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
    /// One state back / forward in the history (Left / Right).
    StepBack,
    StepForward,
    /// To entry k of the history (the timeline slider).
    Seek(usize),
    /// Compare with the settings of a preset or of command-line flags.
    Compare(String),
    StopComparing,
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
    /// The compare field: a preset (`accurate`, `coursework`) and/or settings flags.
    pub compare_spec: String,
    pub compare_error: Option<String>,
    /// Which world's settings the settings section edits when comparing.
    pub edit_lane: usize,
    /// The camera keeps the selected body at the centre.
    pub follow: bool,
    /// The panel is hidden (H): the view takes the whole window, as a small window needs.
    pub hidden: bool,
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
            compare_spec: "accurate".into(),
            compare_error: None,
            edit_lane: 0,
            follow: false,
            hidden: false,
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
        if !state.hidden {
            egui::Panel::right("controls")
                .frame(frame)
                .default_size(360.0)
                .size_range(260.0..=640.0)
                .show(ui, |ui| {
                    actions = show(ui, session, state, info);
                });
        }
        view = ui.available_rect_before_wrap();
        overlay(ui.ctx(), view, session, (state, info.recording));
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
    let section = |ui: &mut egui::Ui, title: &str, add: &mut dyn FnMut(&mut egui::Ui)| {
        egui::CollapsingHeader::new(title)
            .default_open(true)
            .show(ui, |ui| add(ui));
    };
    egui::ScrollArea::vertical()
        .auto_shrink([true, false])
        .show(ui, |ui| {
            ui.heading("tumble");
            playback_controls(ui, session.playing, &mut actions);
            recording_controls(ui, state, info.recording, &mut actions);
            if let Some(message) = &state.message {
                ui.label(RichText::new(message).small());
            }
            ui.separator();
            scene_picker(ui, session, state, &mut actions);
            ui.separator();
            section(ui, "Compare", &mut |ui| {
                compare_ui(ui, session, state, &mut actions)
            });
            section(ui, "Rewind", &mut |ui| {
                timeline_ui(ui, session, &mut actions)
            });
            section(ui, "Simulation settings", &mut |ui| {
                lane_settings_ui(ui, session, state)
            });
            section(ui, "Display", &mut |ui| display_ui(ui, session, state));
            section(ui, "Statistics", &mut |ui| {
                statistics_ui(ui, session, info, state.edit_lane)
            });
            section(ui, "Energy and constraint violation", &mut |ui| {
                plots_ui(ui, session)
            });
            section(ui, "Selected body", &mut |ui| {
                selection_ui(ui, session, state.draw.selected)
            });
            ui.separator();
            ui.small(
                "Drag: orbit · right/middle drag or shift-drag: pan · wheel: zoom · \
                 click: pick a body · ctrl-drag: grab a body",
            );
            ui.small(
                "Space play/pause · S step · Left/Right back/forward (paused) · R reset · \
                 F frame · P screenshot · H hide this panel · Esc deselect · drop a scene or \
                 mesh file to open it",
            );
        });
    actions
}

/// Starting and ending a comparison, its layout, and why a spec was refused.
fn compare_ui(
    ui: &mut egui::Ui,
    session: &Session,
    state: &mut PanelState,
    actions: &mut Vec<Action>,
) {
    ui.horizontal(|ui| {
        let edit = ui.add(
            egui::TextEdit::singleline(&mut state.compare_spec)
                .hint_text("accurate / --solver coursework --dt 0.01")
                .desired_width(190.0),
        );
        let enter = edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
        let label = if session.comparing() {
            "Restart"
        } else {
            "Compare"
        };
        if ui
            .button(label)
            .on_hover_text(
                "Step a second world of the scene with these settings alongside, from the start",
            )
            .clicked()
            || enter
        {
            actions.push(Action::Compare(state.compare_spec.trim().to_string()));
        }
        if session.comparing() && ui.button("Stop").clicked() {
            actions.push(Action::StopComparing);
        }
    });
    if let Some(error) = &state.compare_error {
        ui.colored_label(Color32::from_rgb(255, 110, 110), error);
    }
    if session.comparing() {
        ui.horizontal(|ui| {
            ui.radio_value(&mut state.draw.layout, Layout::SideBySide, "side by side");
            ui.radio_value(&mut state.draw.layout, Layout::Ghost, "overlaid (ghost)");
        });
        for (k, lane) in session.lanes.iter().enumerate() {
            ui.label(format!(
                "{}: {}",
                compare::lane_name(k),
                compare::settings_label(&lane.world.settings)
            ));
        }
    }
}

/// The history: a slider over its states, what it spans, and its memory budget.
fn timeline_ui(ui: &mut egui::Ui, session: &mut Session, actions: &mut Vec<Action>) {
    let timeline = &session.timeline;
    let mut index = timeline.cursor();
    let last = timeline.len().saturating_sub(1);
    let first_step = timeline.step_at(0).unwrap_or(0);
    let slider = egui::Slider::new(&mut index, 0..=last.max(1))
        .custom_formatter(move |v, _| format!("step {}", first_step + v as u64))
        .show_value(true);
    if ui
        .add_enabled(last > 0, slider)
        .on_hover_text(
            "Scrub the history (pauses); resuming from a past state drops the states after it",
        )
        .changed()
    {
        actions.push(Action::Seek(index));
    }
    ui.horizontal(|ui| {
        if ui.button("<").on_hover_text("Left arrow").clicked() {
            actions.push(Action::StepBack);
        }
        if ui.button(">").on_hover_text("Right arrow").clicked() {
            actions.push(Action::StepForward);
        }
        let span = timeline.span();
        ui.label(format!(
            "{:.2} s, steps {}..{}, {:.1} MiB",
            span.seconds,
            span.first_step,
            span.last_step,
            span.bytes as f64 / (1 << 20) as f64
        ));
    });
    let mut mib = (session.timeline.budget() >> 20) as u64;
    ui.horizontal(|ui| {
        ui.label("memory budget");
        let budget = egui::DragValue::new(&mut mib)
            .range(1..=65536)
            .suffix(" MiB");
        if ui.add(budget).changed() {
            session.timeline.set_budget((mib as usize) << 20);
        }
    });
}

/// The settings of the first world, or of the one picked when comparing.
fn lane_settings_ui(ui: &mut egui::Ui, session: &mut Session, state: &mut PanelState) {
    if session.comparing() {
        ui.horizontal(|ui| {
            ui.label("edit");
            for k in 0..session.lanes.len() {
                ui.radio_value(
                    &mut state.edit_lane,
                    k,
                    format!("world {}", compare::lane_name(k)),
                );
            }
        });
    }
    let lane = state.edit_lane.min(session.lanes.len() - 1);
    settings_ui(ui, &mut session.lanes[lane].world.settings);
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
            ui.label(recording_label(path, frames));
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

/// What the view shows, how the camera follows, and the grab's stiffness.
fn display_ui(ui: &mut egui::Ui, session: &mut Session, state: &mut PanelState) {
    let draw = &mut state.draw;
    ui.checkbox(&mut draw.shadows, "Shadows")
        .on_hover_text("From the key light: a 2048² shadow map with 3x3 filtering");
    ui.checkbox(&mut draw.grid, "Ground");
    ui.checkbox(&mut draw.constraints, "Constraint segments")
        .on_hover_text(
            "Green within bounds, through yellow to red at 10% of the rest length outside them",
        );
    ui.checkbox(&mut draw.contacts, "Contact points and normals");
    ui.checkbox(&mut draw.fixed_bodies, "Fixed bodies")
        .on_hover_text("Walls, slopes and anchors; hide them to see into a pile's bin");
    ui.add_enabled(
        draw.selected.is_some(),
        egui::Checkbox::new(&mut state.follow, "Camera follows the selected body"),
    );
    ui.add(
        egui::Slider::new(&mut session.grab_hertz, 0.5..=20.0)
            .logarithmic(true)
            .text("grab stiffness (Hz)"),
    )
    .on_hover_text(
        "Natural frequency of the ctrl-drag spring, critically damped; its force scales with \
         the body's mass (at most a quarter of the substep rate)",
    );
}

fn scene_picker(
    ui: &mut egui::Ui,
    session: &mut Session,
    state: &mut PanelState,
    actions: &mut Vec<Action>,
) {
    let scene = session.scene();
    let mut choice = scene.clone();
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
    if choice != scene {
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
    watch_ui(ui, session);
    let world = session.world();
    warnings_ui(ui, &world.warnings);
    ui.label(format!(
        "{} bodies ({} fixed), {} shapes, {} distance constraints",
        world.bodies.len(),
        world.bodies.iter().filter(|b| b.fixed).count(),
        world.shapes.len(),
        // Each record is a lower and an upper inequality.
        world.constraints.len() / 2
    ));
}

/// The scene's load warnings (a file's records out of step, a mesh that is not convex, a
/// constraint between fixed bodies, a body that starts inside another or below the ground),
/// the first few in full: a window shows no terminal.
fn warnings_ui(ui: &mut egui::Ui, warnings: &[String]) {
    const SHOWN: usize = 3;
    let amber = Color32::from_rgb(240, 190, 80);
    for w in warnings.iter().take(SHOWN) {
        ui.colored_label(amber, format!("warning: {w}"));
    }
    if warnings.len() > SHOWN {
        ui.colored_label(amber, format!("... and {} more", warnings.len() - SHOWN));
    }
}

/// The reload toggle and the files it watches.
fn watch_ui(ui: &mut egui::Ui, session: &mut Session) {
    let files: Vec<String> = session
        .watched_files()
        .map(|f| f.display().to_string())
        .collect();
    if files.is_empty() {
        return;
    }
    ui.checkbox(&mut session.auto_reload, "Reload when the files change")
        .on_hover_text(files.join("\n"));
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
        full_substeps_from,
        rotation_integrator,
        sleep,
        broad_phase,
        constraint_schedule,
    } = settings;
    enum_choice(ui, "solver", solver);
    // The sliders clamp only what is dragged: a value from the command line beyond a slider's
    // range (`view --dt 0.08`, `--friction 2`) was clamped to it in the first frame, unsaid.
    let edits = egui::SliderClamping::Edits;
    ui.add(
        egui::Slider::new(restitution, 0.0..=1.0)
            .clamping(edits)
            .text("restitution"),
    );
    ui.add(
        egui::Slider::new(friction, 0.0..=1.5)
            .clamping(edits)
            .text("friction"),
    )
    .on_hover_text("Coulomb friction coefficient (soft-step solver; the coursework has none)");
    ui.add(
        egui::Slider::new(time_step, 0.0005..=0.05)
            .clamping(edits)
            .logarithmic(true)
            .text("time step (s)"),
    );
    ui.add(
        egui::Slider::new(max_iterations, 1..=100_000)
            .clamping(edits)
            .logarithmic(true)
            .text("max iterations"),
    )
    .on_hover_text(
        "The coursework's maxIterations: a step makes at most ceil(K / M) constraint visits, \
         M = number of inequality constraints (two per record)",
    );
    ui.add(
        egui::Slider::new(tolerance, 1e-6..=0.1)
            .clamping(edits)
            .logarithmic(true)
            .text("tolerance"),
    );
    ui.add(
        egui::Slider::new(substeps, 1..=32)
            .clamping(edits)
            .text("substeps"),
    );
    ui.add(
        egui::Slider::new(full_substeps_from, 0.0..=0.05)
            .clamping(edits)
            .text("all substeps from dt"),
    )
    .on_hover_text(
        "A shorter step takes proportionally fewer substeps, down to half, so they stay \
             about as long as at this step (soft-step solver; 0: always all)",
    );
    ui.add(
        egui::Slider::new(restitution_threshold, 0.0..=5.0)
            .clamping(edits)
            .text("restitution threshold"),
    )
    .on_hover_text("Contacts closing slower than this (units/s) bounce with e = 0 (0: off)");
    ui.horizontal(|ui| {
        ui.label("gravity");
        ui.add(egui::DragValue::new(&mut gravity.x).speed(0.1).prefix("x "));
        ui.add(egui::DragValue::new(&mut gravity.y).speed(0.1).prefix("y "));
        ui.add(egui::DragValue::new(&mut gravity.z).speed(0.1).prefix("z "));
    });
    ui.checkbox(skip_separating_contacts, "skip separating contacts")
        .on_hover_text("No impulse for contacts whose bodies already separate (coursework solver)");
    ui.checkbox(sleep, "sleep")
        .on_hover_text("Islands resting for half a second sleep until touched (soft-step solver)");
    ui.checkbox(contact_patches, "contact patches")
        .on_hover_text(
            "Contacts act on the whole contact patch, not at one deepest point: under the \
             centre of mass of the body resting there, on the ground or on another body \
             (coursework solver)",
        );
    enum_choice(ui, "rotation integrator", rotation_integrator);
    enum_choice(ui, "broad phase", broad_phase).on_hover_text(
        "How the coursework solver finds candidate pairs (the soft step always uses the grid)",
    );
    enum_choice(ui, "constraint schedule", constraint_schedule);
}

/// Buttons that replace every setting but the time step by a preset.
fn preset_buttons(ui: &mut egui::Ui, settings: &mut Settings) {
    ui.horizontal(|ui| {
        if ui
            .button("Coursework defaults")
            .on_hover_text("The coursework's method and settings (the time step kept)")
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
                "--accurate: the soft step, 4 substeps (all of them from dt 0.01), the angular-momentum \
                 integrator, restitution threshold 0.5, friction 0.5, sleeping (the time step kept)",
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
fn enum_choice<T: Choice>(ui: &mut egui::Ui, label: &str, value: &mut T) -> egui::Response {
    egui::ComboBox::from_label(label)
        .selected_text(value.name())
        .show_ui(ui, |ui| {
            for &variant in T::ALL {
                ui.selectable_value(value, variant, variant.name())
                    .on_hover_text(variant.help());
            }
        })
        .response
}

/// Frame, stepping and world statistics; when comparing, of the world whose settings are edited.
fn statistics_ui(ui: &mut egui::Ui, session: &Session, info: &FrameInfo, lane: usize) {
    let lane = lane.min(session.lanes.len() - 1);
    if session.comparing() {
        ui.label(format!(
            "world {} (pick it under Simulation settings)",
            compare::lane_name(lane)
        ));
    }
    egui::Grid::new("stats")
        .num_columns(2)
        .striped(false)
        .show(ui, |ui| {
            frame_rows(ui, info);
            stepping_rows(ui, session, &session.lanes[lane]);
            world_rows(ui, &session.lanes[lane]);
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
fn stepping_rows(ui: &mut egui::Ui, session: &Session, lane: &Lane) {
    let world = &lane.world;
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
    stat(ui, "steps this frame", format!("{}", lane.frame_steps));
    let steps = lane.frame_steps.max(1) as f64;
    let solver = lane.world.settings.solver;
    for (stage, seconds) in (lane.frame_timings.iter()).filter(|(s, _)| s.runs_under(solver)) {
        stat(
            ui,
            &format!("  {}", stage.name().replace('_', " ")),
            format!("{:.3} ms/step", 1e3 * seconds / steps),
        );
    }
    stat(
        ui,
        "  total",
        format!("{:.3} ms/step", 1e3 * lane.frame_timings.total() / steps),
    );
}

/// The constraint work of the last step: the coursework's visits and budget, or whether the
/// soft step's projections held its joint groups.
fn constraint_rows(ui: &mut egui::Ui, solver: Solver, last: &crate::StepStats) {
    let alarm = |text: &str| RichText::new(text).color(Color32::from_rgb(255, 110, 110));
    if solver == Solver::SoftStep {
        match last.joint_projections_cut_short {
            0 => stat(ui, "joint groups", "held"),
            n => stat(
                ui,
                "joint groups",
                alarm(&format!("{n} not held (raise substeps)")),
            ),
        }
        if last.joint_groups_relaxed > 0 {
            let n = last.joint_groups_relaxed;
            let text = format!("{n} over-braced: Gauss-Seidel, within a few %");
            stat(ui, "joint solve", alarm(&text));
        }
        return;
    }
    stat(
        ui,
        "constraint visits",
        format!(
            "{} ({} corrections)",
            last.constraint_visits, last.constraint_corrections
        ),
    );
    if last.budget_hit {
        stat(ui, "budget", alarm("ran out (raise max iterations)"));
    } else {
        stat(ui, "budget", "enough");
    }
}

/// Bodies, contacts, substeps and constraint work of the last step, energy, and frozen bodies.
fn world_rows(ui: &mut egui::Ui, lane: &Lane) {
    let world = &lane.world;
    let last = &lane.last;
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
    // The soft step takes more than the setting's where contacts need them (dt over 0.02).
    stat(ui, "substeps", format!("{}", last.substeps));
    if !world.constraints.is_empty() {
        constraint_rows(ui, world.settings.solver, last);
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

/// Total energy and largest constraint violation over the last seconds, one curve per world.
fn plots_ui(ui: &mut egui::Ui, session: &Session) {
    let curves = |value: fn(&super::session::Sample) -> f64| {
        session
            .lanes
            .iter()
            .enumerate()
            .map(move |(k, lane)| {
                let points: PlotPoints = lane.plot.iter().map(|s| [s.time, value(s)]).collect();
                let name = format!(
                    "{}: {}",
                    compare::lane_name(k),
                    compare::settings_label(&lane.world.settings)
                );
                Line::new(name, points).color(compare::lane_color(k))
            })
            .collect::<Vec<_>>()
    };
    let legend = session.comparing();
    let plot = |id: &str, label: &str| {
        let plot = Plot::new(id.to_string())
            .height(90.0)
            .allow_zoom(false)
            .allow_drag(false)
            .allow_scroll(false)
            .y_axis_label(label.to_string())
            // Figures enough to tell the ticks apart (the energy axis read 11500000000).
            .y_axis_formatter(|mark, _| {
                let figures = crate::io::tick_figures(mark.value, mark.step_size);
                crate::io::significant(mark.value, figures)
            });
        if legend {
            plot.legend(egui_plot::Legend::default())
        } else {
            plot
        }
    };
    plot("energy_plot", "energy").show(ui, |p| {
        for line in curves(|s| s.energy) {
            p.line(line);
        }
    });
    plot("violation_plot", "max violation")
        .include_y(0.0)
        .show(ui, |p| {
            for line in curves(|s| s.violation) {
                p.line(line);
            }
        });
}

fn selection_ui(ui: &mut egui::Ui, session: &Session, selected: Option<usize>) {
    let Some(index) = selected.filter(|&i| i < session.world().bodies.len()) else {
        ui.weak("Click a body to inspect it.");
        return;
    };
    let world = session.world();
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
                    RichText::new("frozen: blew up (non-finite or absurdly fast)")
                        .color(Color32::from_rgb(255, 110, 110)),
                );
            }
        });
}

/// Over the 3D view: in the top left corner of each pane the world's label when comparing, and
/// over the first the scene, time, play or rewind state, the sim/real ratio when the simulation
/// falls behind, the grab's force and the picked body; with the panel hidden, the recording
/// and the last message it would show, and the key that shows it again.
pub fn overlay(
    ctx: &egui::Context,
    view: egui::Rect,
    session: &Session,
    (state, recording): (&PanelState, Option<(&str, u64)>),
) {
    let rect = [view.min.x, view.min.y, view.width(), view.height()];
    let panes = compare::panes(rect, session.lanes.len(), state.draw.layout);
    let painter = ctx.layer_painter(egui::LayerId::background());
    for pane in &panes[1..] {
        let x = pane.rect[0];
        painter.vline(
            x,
            view.y_range(),
            egui::Stroke::new(2.0, Color32::from_gray(90)),
        );
    }
    for (k, pane) in panes.iter().enumerate() {
        let corner = egui::pos2(pane.rect[0], pane.rect[1]) + egui::Vec2::from(LABEL_MARGIN);
        egui::Area::new(egui::Id::unique(("view_overlay", k)))
            .fixed_pos(corner)
            .interactable(false)
            .show(ctx, |ui| {
                // Lines longer than their pane end in "..." rather than run into the next pane
                // or under the panel.
                ui.set_max_width(label_width(pane.rect[2]));
                ui.style_mut().wrap_mode = Some(egui::TextWrapMode::Truncate);
                if k == 0 {
                    status_lines(ui, session);
                    if state.hidden {
                        hidden_panel_lines(ui, state, recording);
                    }
                }
                if session.comparing() {
                    for &k in &pane.lanes {
                        let lane = &session.lanes[k];
                        Label::of_lane(k, &lane.world, &lane.last, pane.lanes.len() > 1).show(ui);
                    }
                }
                if k == 0 {
                    selection_lines(ui, session, state);
                }
            });
    }
}

/// "REC path: N frames", in red: the panel's record row and, with the panel hidden, the view's
/// corner.
fn recording_label(path: &str, frames: u64) -> RichText {
    let text = format!(
        "REC {path}: {}",
        crate::io::counted(frames, "frame", "frames")
    );
    RichText::new(text).color(Color32::from_rgb(255, 90, 90))
}

/// What the hidden panel would show of a recording and its last message, and the key that
/// shows it.
fn hidden_panel_lines(ui: &mut egui::Ui, state: &PanelState, recording: Option<(&str, u64)>) {
    if let Some((path, frames)) = recording {
        ui.label(recording_label(path, frames));
    }
    if let Some(message) = &state.message {
        ui.label(
            RichText::new(message)
                .small()
                .color(Color32::from_gray(210)),
        );
    }
    ui.label(
        RichText::new("H: show the panel")
            .small()
            .color(Color32::from_gray(160)),
    );
}

/// The scene and time, paused or rewound, and the sim/real ratio when behind.
fn status_lines(ui: &mut egui::Ui, session: &Session) {
    let world = session.world();
    let timeline = &session.timeline;
    let state = if !timeline.at_end() {
        format!(
            "  (rewound: {} of {} states)",
            timeline.cursor() + 1,
            timeline.len()
        )
    } else if session.playing {
        String::new()
    } else {
        "  (paused)".into()
    };
    ui.label(
        RichText::new(format!(
            "{}  t = {:.2} s{state}",
            session.scene(),
            world.time
        ))
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
}

/// The grab's force and the picked body's mass and velocities.
fn selection_lines(ui: &mut egui::Ui, session: &Session, state: &PanelState) {
    let world = session.world();
    if let Some((_, force)) = super::grab::force(world, session.lanes[0].last.substeps) {
        let text = if session.playing {
            format!("grab: force {:.4e}", force.length())
        } else {
            "grab: moving the body (paused)".to_string()
        };
        ui.label(RichText::new(text).color(Color32::from_rgb(140, 240, 255)));
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
}
