//! Presentation of a frame in the window, in the phases the frame statistics time: upload (the
//! scene's data, egui's triangles and textures), acquire (the window's next image, and the
//! screenshot target), submit (draw, copy, paint egui, present).
//!
//! The scene is drawn once into a texture the size of the 3D view and copied into each target
//! (the window, and the capture for a screenshot) over the panel colour, then egui is painted
//! over it. Where the surface accepts no copies, the scene is drawn straight into each target
//! with the view as viewport instead.

use super::camera::OrbitCamera;
use super::compare;
use super::gpu::Offscreen;
use super::palette;
use super::renderer::DrawOptions;
use super::window::{Gfx, ViewRect};
use crate::World;
use std::time::Duration;

/// What the 3D view shows and where.
#[derive(Clone, Copy)]
pub struct SceneView<'a> {
    pub camera: &'a OrbitCamera,
    pub draw: &'a DrawOptions,
    pub rect: ViewRect,
}

/// A frame after the upload phase, ready to be drawn.
pub struct PreparedFrame {
    /// Where the scene texture goes in the window; None when the scene is drawn straight into
    /// the targets.
    scene_origin: Option<wgpu::Origin3d>,
    ui: UiPaint,
    /// When egui wants the next frame even if nothing happens.
    pub repaint_delay: Option<Duration>,
}

/// egui's output, tessellated, with its new textures uploaded.
struct UiPaint {
    jobs: Vec<egui::ClippedPrimitive>,
    screen: egui_wgpu::ScreenDescriptor,
    /// Its texture changes: `set` uploaded, `free` to drop once the frame is submitted.
    textures: egui::TexturesDelta,
}

/// A texture the frame is drawn into, with its view for egui (the texture's format) and its
/// sRGB view for the scene.
struct Target<'a> {
    texture: &'a wgpu::Texture,
    view: &'a wgpu::TextureView,
    srgb_view: &'a wgpu::TextureView,
}

/// Upload phase: the scene's camera, poses and lines, then egui's output.
pub fn prepare(
    gfx: &mut Gfx,
    worlds: &[&World],
    view: SceneView<'_>,
    ui: egui::FullOutput,
) -> PreparedFrame {
    let scene_origin = prepare_scene(gfx, worlds, view);
    gfx.egui_state
        .handle_platform_output(&gfx.window, ui.platform_output);
    let jobs = gfx.egui_ctx.tessellate(ui.shapes, ui.pixels_per_point);
    for (id, deltas) in &ui.textures_delta.set {
        for delta in deltas {
            gfx.egui_renderer
                .update_texture(&gfx.gpu.device, &gfx.gpu.queue, *id, delta);
        }
    }
    let screen = egui_wgpu::ScreenDescriptor {
        size_in_pixels: [gfx.config.width, gfx.config.height],
        pixels_per_point: ui.pixels_per_point,
    };
    let repaint_delay = ui
        .viewport_output
        .get(&egui::ViewportId::ROOT)
        .map(|v| v.repaint_delay);
    PreparedFrame {
        scene_origin,
        ui: UiPaint {
            jobs,
            screen,
            textures: ui.textures_delta,
        },
        repaint_delay,
    }
}

/// Sizes the scene's targets for the view and uploads what the renderer draws (`worlds`: the
/// world and those compared with it); returns where the scene texture goes in the window (see
/// [`prepare_scene_target`]).
pub fn prepare_scene(
    gfx: &mut Gfx,
    worlds: &[&World],
    view: SceneView<'_>,
) -> Option<wgpu::Origin3d> {
    let origin = prepare_scene_target(gfx, view.rect);
    let (w, h) = view.rect.size();
    let aspect = compare::pane_aspect(w, h, worlds.len(), view.draw.layout);
    gfx.renderer.prepare(
        &gfx.gpu.device,
        &gfx.gpu.queue,
        worlds,
        &view.camera.matrices(aspect),
        view.draw,
    );
    origin
}

/// Sizes the renderer's targets for this frame. With copies into the surface, the scene is
/// drawn into a texture the size of the 3D view (MSAA targets that size too, not the whole
/// window) and its origin in the window is returned; otherwise the targets are window-sized
/// and the scene is drawn with a viewport.
fn prepare_scene_target(gfx: &mut Gfx, view_rect: ViewRect) -> Option<wgpu::Origin3d> {
    let device = &gfx.gpu.device;
    if !gfx.copy_to_surface {
        gfx.renderer
            .resize(device, gfx.config.width, gfx.config.height);
        return None;
    }
    let [x, y, w, h] = view_rect.pixels();
    // Inside the window, even when the panel covers all of it.
    let (x, y) = (x.min(gfx.config.width - 1), y.min(gfx.config.height - 1));
    let (w, h) = (
        w.clamp(1, gfx.config.width - x),
        h.clamp(1, gfx.config.height - y),
    );
    if gfx
        .scene
        .as_ref()
        .is_none_or(|s| s.width != w || s.height != h)
    {
        gfx.scene = Some(Offscreen::new(device, w, h, gfx.config.format));
    }
    gfx.renderer.resize(device, w, h);
    Some(wgpu::Origin3d { x, y, z: 0 })
}

/// Acquire phase: the window's next image, and the screenshot target sized to the window when
/// `screenshot`. No image when the surface timed out, or was outdated or lost (then it is
/// reconfigured for the next frame): the frame still goes into a screenshot.
pub fn acquire(gfx: &mut Gfx, screenshot: bool) -> Option<wgpu::SurfaceTexture> {
    let surface_texture = match gfx.surface.get_current_texture() {
        wgpu::CurrentSurfaceTexture::Success(t) | wgpu::CurrentSurfaceTexture::Suboptimal(t) => {
            Some(t)
        }
        wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
            gfx.surface.configure(&gfx.gpu.device, &gfx.config);
            None
        }
        _ => None,
    };
    if screenshot {
        gfx.ensure_window_capture();
    }
    surface_texture
}

/// Submit phase: draws `frame` into the window's image and, for a screenshot, into the capture
/// (queuing its copy for reading back), submits, presents, and frees egui's old textures.
pub fn submit(
    gfx: &mut Gfx,
    frame: PreparedFrame,
    surface_texture: Option<wgpu::SurfaceTexture>,
    screenshot: bool,
    view_rect: ViewRect,
) {
    let mut encoder = gfx.gpu.device.create_command_encoder(&Default::default());
    let user_buffers = gfx.egui_renderer.update_buffers(
        &gfx.gpu.device,
        &gfx.gpu.queue,
        &mut encoder,
        &frame.ui.jobs,
        &frame.ui.screen,
    );
    let surface_views = surface_texture.as_ref().map(|t| {
        let view = t.texture.create_view(&Default::default());
        let srgb_view = t.texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(gfx.renderer.color_format),
            ..Default::default()
        });
        (view, srgb_view)
    });
    let mut targets = Vec::new();
    if let (Some(t), Some((view, srgb_view))) = (&surface_texture, &surface_views) {
        targets.push(Target {
            texture: &t.texture,
            view,
            srgb_view,
        });
    }
    let capture = gfx.capture.as_ref().filter(|_| screenshot);
    if let Some(capture) = capture {
        targets.push(Target {
            texture: &capture.texture,
            view: &capture.view,
            srgb_view: &capture.srgb_view,
        });
    }
    draw_targets(gfx, &mut encoder, &targets, &frame, view_rect);
    if let Some(capture) = capture {
        capture.copy_to_buffer(&mut encoder);
    }
    gfx.gpu
        .queue
        .submit(user_buffers.into_iter().chain([encoder.finish()]));
    if let Some(texture) = surface_texture {
        gfx.window.pre_present_notify();
        gfx.gpu.queue.present(texture);
    }
    for id in &frame.ui.textures.free {
        gfx.egui_renderer.free_texture(id);
    }
}

/// The scene once into the scene texture (when it is used), then for each target: the scene
/// copied in over the panel colour, or drawn straight in with the view as viewport; egui over it.
fn draw_targets(
    gfx: &Gfx,
    encoder: &mut wgpu::CommandEncoder,
    targets: &[Target<'_>],
    frame: &PreparedFrame,
    view_rect: ViewRect,
) {
    let scene = frame
        .scene_origin
        .and_then(|origin| gfx.scene.as_ref().map(|s| (origin, s)));
    if let Some((_, scene)) = scene
        && !targets.is_empty()
    {
        gfx.renderer.draw(encoder, &scene.srgb_view, None);
    }
    let panel_fill = gfx.egui_ctx.global_style().visuals.panel_fill;
    for target in targets {
        match scene {
            Some((origin, scene)) => {
                clear_pass(encoder, target.view, gfx.config.format, panel_fill);
                copy_scene(encoder, scene, target.texture, origin);
            }
            None => gfx
                .renderer
                .draw(encoder, target.srgb_view, Some(view_rect.0)),
        }
        paint_ui(gfx, encoder, target.view, &frame.ui);
    }
}

/// Copies the scene texture into `texture` at `origin`.
fn copy_scene(
    encoder: &mut wgpu::CommandEncoder,
    scene: &Offscreen,
    texture: &wgpu::Texture,
    origin: wgpu::Origin3d,
) {
    encoder.copy_texture_to_texture(
        scene.texture.as_image_copy(),
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::Extent3d {
            width: scene.width,
            height: scene.height,
            depth_or_array_layers: 1,
        },
    );
}

/// egui's pass over what is already in `view`.
fn paint_ui(gfx: &Gfx, encoder: &mut wgpu::CommandEncoder, view: &wgpu::TextureView, ui: &UiPaint) {
    let mut pass = super::gpu::overlay_pass(encoder, view, "egui").forget_lifetime();
    gfx.egui_renderer.render(&mut pass, &ui.jobs, &ui.screen);
}

/// Clears a target to the background colour.
fn clear_pass(
    encoder: &mut wgpu::CommandEncoder,
    view: &wgpu::TextureView,
    format: wgpu::TextureFormat,
    color: egui::Color32,
) {
    let srgb = [color.r(), color.g(), color.b()].map(|v| v as f32 / 255.0);
    let c = if format.is_srgb() {
        palette::linear(srgb)
    } else {
        srgb
    };
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("clear"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color {
                    r: c[0] as f64,
                    g: c[1] as f64,
                    b: c[2] as f64,
                    a: 1.0,
                }),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
}
