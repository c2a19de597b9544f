//! Labels naming compared worlds: a title (the world's letter and settings) over a line of its
//! own statistics. The window's overlay shows them with its egui context; recordings paint them
//! into each frame with an egui context and renderer of their own ([`LabelPainter`]), so a
//! `tumble record --compare` video says which side is which.

use super::compare;
use crate::{StepStats, World};
use egui::{Color32, RichText};

/// Where a pane's labels start, from its top left corner (pixels or points); they end as far
/// from its right edge.
pub const LABEL_MARGIN: [f32; 2] = [10.0, 8.0];

/// The widest a label may be in a pane `pane_width` wide (pixels or points), at least 1.
pub fn label_width(pane_width: f32) -> f32 {
    (pane_width - 2.0 * LABEL_MARGIN[0]).max(1.0)
}

/// A label and where its top left corner goes (pixels of the frame, or points of the window).
#[derive(Debug, Clone, PartialEq)]
pub struct Label {
    pub pos: [f32; 2],
    /// The widest its lines may be: longer ones end in "..." (its pane's width less the margins).
    pub width: f32,
    pub title: String,
    pub color: Color32,
    pub statistics: String,
}

impl Label {
    /// The label of world `lane` (a ghost over the first when `ghost`).
    pub fn of_lane(lane: usize, world: &World, last: &StepStats, ghost: bool) -> Label {
        let role = if ghost && lane > 0 { " (ghost)" } else { "" };
        Label {
            pos: [0.0, 0.0],
            width: f32::INFINITY,
            title: format!(
                "{}{role}: {}",
                compare::lane_name(lane),
                compare::settings_label(&world.settings)
            ),
            color: compare::lane_color(lane),
            statistics: compare::lane_statistics(world, last),
        }
    }

    /// The labels of compared worlds (each with its last step's statistics) in the top left
    /// corners of the panes of a `rect` (x, y, width, height) view; the labels of a ghost
    /// overlay share their pane's corner (and are shown one under the other).
    pub fn for_panes(
        rect: [f32; 4],
        worlds: &[(&World, &StepStats)],
        layout: compare::Layout,
    ) -> Vec<Label> {
        let mut labels = Vec::new();
        for pane in compare::panes(rect, worlds.len(), layout) {
            let ghost = pane.lanes.len() > 1;
            for &k in &pane.lanes {
                let (world, last) = worlds[k];
                let mut label = Label::of_lane(k, world, last, ghost);
                let [x, y] = LABEL_MARGIN;
                label.pos = [pane.rect[0] + x, pane.rect[1] + y];
                label.width = label_width(pane.rect[2]);
                labels.push(label);
            }
        }
        labels
    }

    /// The title and the statistics, in `ui`.
    pub fn show(&self, ui: &mut egui::Ui) {
        ui.label(RichText::new(&self.title).strong().color(self.color));
        ui.label(RichText::new(&self.statistics).color(Color32::from_gray(205)));
    }
}

/// Paints labels over rendered frames with egui.
pub struct LabelPainter {
    ctx: egui::Context,
    renderer: egui_wgpu::Renderer,
    /// egui lays out an area once, invisibly, before it shows it: the first frame runs twice.
    warm: bool,
}

impl LabelPainter {
    /// A painter for targets of `format` (a non-sRGB format: egui blends in gamma space).
    pub fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> LabelPainter {
        let ctx = egui::Context::default();
        ctx.set_visuals(egui::Visuals::dark());
        LabelPainter {
            ctx,
            renderer: egui_wgpu::Renderer::new(device, format, Default::default()),
            warm: false,
        }
    }

    /// Records the painting of `labels` on a dark backing into `target` (`size` pixels), over
    /// what it holds.
    pub fn paint(
        &mut self,
        gpu: &super::Gpu,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        size: (u32, u32),
        labels: &[Label],
    ) {
        // Text a little larger in larger frames. (The context applies a new zoom from its next
        // pass on: read back before it, the first frame's labels were placed at the old one.)
        let zoom = (size.1 as f32 / 400.0).clamp(0.8, 2.0);
        self.ctx.set_zoom_factor(zoom);
        let output = self.run(size, labels, zoom);
        let jobs = self.ctx.tessellate(output.shapes, output.pixels_per_point);
        for (id, deltas) in &output.textures_delta.set {
            for delta in deltas {
                self.renderer
                    .update_texture(&gpu.device, &gpu.queue, *id, delta);
            }
        }
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [size.0, size.1],
            pixels_per_point: output.pixels_per_point,
        };
        // Plain labels register no callbacks, so there are no extra command buffers.
        let _ = self
            .renderer
            .update_buffers(&gpu.device, &gpu.queue, encoder, &jobs, &screen);
        let mut pass = super::gpu::overlay_pass(encoder, target, "labels").forget_lifetime();
        self.renderer.render(&mut pass, &jobs, &screen);
        drop(pass);
        for id in &output.textures_delta.free {
            self.renderer.free_texture(id);
        }
    }

    /// egui's output for the labels on a `size` screen (pixels); labels at the same place
    /// share a backing, one under the other.
    fn run(&mut self, size: (u32, u32), labels: &[Label], zoom: f32) -> egui::FullOutput {
        let input = || egui::RawInput {
            screen_rect: Some(egui::Rect::from_min_size(
                egui::Pos2::ZERO,
                egui::vec2(size.0 as f32, size.1 as f32) / zoom,
            )),
            ..Default::default()
        };
        let show = |ui: &mut egui::Ui| {
            for (k, group) in labels.chunk_by(|a, b| a.pos == b.pos).enumerate() {
                let [x, y] = group[0].pos;
                // Not faded in: a frame is a still, whatever came before it.
                egui::Area::new(egui::Id::unique(("label", k)))
                    .fade_in(false)
                    .fixed_pos(egui::pos2(x, y) / zoom)
                    .show(ui.ctx(), |ui| {
                        // The backing's margins inside the label's width.
                        ui.set_max_width((group[0].width / zoom - 8.0).max(1.0));
                        ui.style_mut().wrap_mode = Some(egui::TextWrapMode::Truncate);
                        egui::Frame::new()
                            .fill(Color32::from_black_alpha(150))
                            .inner_margin(4)
                            .corner_radius(3)
                            .show(ui, |ui| group.iter().for_each(|label| label.show(ui)));
                    });
            }
        };
        if self.warm {
            return self.ctx.run_ui(input(), &show);
        }
        self.warm = true;
        // The layout pass's textures (the font atlas) are uploaded with the frame's.
        let mut textures = self.ctx.run_ui(input(), &show).textures_delta;
        let mut output = self.ctx.run_ui(input(), &show);
        textures.append(std::mem::take(&mut output.textures_delta));
        output.textures_delta = textures;
        output
    }
}
