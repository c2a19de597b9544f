//! The wgpu scene renderer shared by the window, the recorder and the tests.
//!
//! Static data is uploaded once per scene ([`SceneData`]): one flat-shaded vertex buffer per
//! distinct shape (vertices duplicated per face, carrying the face normal), the ground plane and
//! grid. Each frame uploads, for each world shown (one, or two compared: a `layer` each), only
//! the bodies' poses as instance data (quaternion, centre of mass, colour) plus a few lines
//! (constraints, contacts, the grab). The vertex shader computes `R(q) v + COM` in f32, the
//! core's formula, and each shape is one instanced draw. With shadows, each world's bodies are
//! first drawn into its shadow map from the key light (`shadow.rs`).
//!
//! Pipelines live in `pipelines.rs`, line geometry in `overlay.rs`, depth and MSAA attachments
//! in `targets.rs`; the test-only GPU readback extends [`Renderer`] from `readback.rs`.

use super::camera::{CameraMatrices, OrbitCamera, scene_bounds};
use super::compare::{self, Layout};
use super::gpu::{Gpu, Image, NoGpu, Offscreen, buffer_init};
use super::labels::{Label, LabelPainter};
use super::layer::{Layer, vertex_usage};
use super::overlay;
use super::palette;
use super::pipelines::{Globals, ScenePipelines};
pub use super::pipelines::{InstanceData, MeshVertex};
use super::shadow::{self, SHADOW_SIZE};
pub use super::targets::DEPTH_FORMAT;
use super::targets::SceneAttachments;
use crate::{Shape, World};
use glam::DVec3;
use std::ops::Range;

/// What to draw besides the bodies, and how.
#[derive(Debug, Clone, PartialEq)]
pub struct DrawOptions {
    /// Ground plane and grid at y = 0.
    pub grid: bool,
    /// Constraint segments coloured by violation.
    pub constraints: bool,
    /// Contact points and normals at the current poses.
    pub contacts: bool,
    /// Fixed bodies (a pile's bin, a slope); hidden, the view sees into a bin from any side.
    pub fixed_bodies: bool,
    /// Highlighted body.
    pub selected: Option<usize>,
    /// Unlit: every body in its exact palette colour, no shadows (for tests).
    pub flat: bool,
    /// Shadows from the key light on the ground and the bodies.
    pub shadows: bool,
    /// How compared worlds share the view.
    pub layout: Layout,
}

impl Default for DrawOptions {
    fn default() -> Self {
        DrawOptions {
            grid: true,
            constraints: true,
            contacts: false,
            fixed_bodies: true,
            selected: None,
            flat: false,
            shadows: true,
            layout: Layout::SideBySide,
        }
    }
}

/// A shape's flat-shaded mesh on the GPU.
pub(super) struct ShapeMesh {
    pub(super) buffer: wgpu::Buffer,
    pub(super) vertex_count: u32,
    /// Rest-vertex index of each buffer vertex.
    pub(super) source_vertex: Vec<u32>,
}

impl ShapeMesh {
    /// Three vertices per triangle, each with the face normal.
    fn new(device: &wgpu::Device, shape: &Shape, usage: wgpu::BufferUsages) -> ShapeMesh {
        let mut vertices = Vec::with_capacity(3 * shape.triangles.len());
        let mut source_vertex = Vec::with_capacity(3 * shape.triangles.len());
        for tri in &shape.triangles {
            let [a, b, c] = tri.map(|i| shape.rest_vertices[i as usize]);
            let normal = (b - a)
                .cross(c - a)
                .normalize_or_zero()
                .as_vec3()
                .to_array();
            for &i in tri {
                vertices.push(MeshVertex {
                    position: shape.rest_vertices[i as usize].as_vec3().to_array(),
                    normal,
                });
                source_vertex.push(i);
            }
        }
        ShapeMesh {
            buffer: buffer_init(device, "shape mesh", bytemuck::cast_slice(&vertices), usage),
            vertex_count: vertices.len() as u32,
            source_vertex,
        }
    }
}

/// What a scene uploads once: its shapes' meshes, the draw order, colours, constraint groups
/// and the ground.
pub(super) struct SceneData {
    pub(super) meshes: Vec<ShapeMesh>,
    /// Body indices grouped by shape; `shape_ranges[s]` is shape `s`'s slice of it.
    pub(super) order: Vec<u32>,
    pub(super) shape_ranges: Vec<Range<u32>>,
    pub(super) base_colors: Vec<[f32; 3]>,
    /// Constraint indices drawn as one segment (a file record's lower and upper bound).
    pub(super) constraint_groups: Vec<Vec<usize>>,
    ground_buffer: Option<wgpu::Buffer>,
    ground_plane: Range<u32>,
    ground_grid: Range<u32>,
    /// Half the ground's side: the shadow map covers it.
    ground_extent: f64,
    /// Size of the scene, for the length of contact normals and markers.
    pub(super) scale: f64,
}

impl SceneData {
    fn empty() -> SceneData {
        SceneData {
            meshes: Vec::new(),
            order: Vec::new(),
            shape_ranges: Vec::new(),
            base_colors: Vec::new(),
            constraint_groups: Vec::new(),
            ground_buffer: None,
            ground_plane: 0..0,
            ground_grid: 0..0,
            ground_extent: 1.0,
            scale: 1.0,
        }
    }

    fn new(device: &wgpu::Device, world: &World, usage: wgpu::BufferUsages) -> SceneData {
        let (order, shape_ranges) = group_by_shape(world);
        let (lo, hi) = scene_bounds(world);
        let ground = overlay::ground(lo, hi);
        SceneData {
            meshes: world
                .shapes
                .iter()
                .map(|shape| ShapeMesh::new(device, shape, usage))
                .collect(),
            order,
            shape_ranges,
            base_colors: world
                .bodies
                .iter()
                .enumerate()
                .map(|(i, b)| palette::linear(palette::body_srgb(i, b.fixed)))
                .collect(),
            constraint_groups: overlay::constraint_groups(world),
            ground_buffer: Some(buffer_init(
                device,
                "ground",
                bytemuck::cast_slice(&ground.vertices),
                wgpu::BufferUsages::VERTEX,
            )),
            ground_plane: ground.plane,
            ground_grid: ground.grid,
            ground_extent: ground.extent,
            scale: (hi - lo).length().max(1e-3),
        }
    }

    /// The box the shadow map must cover: the ground and every body of `worlds`.
    fn shadow_bounds(&self, worlds: &[&World]) -> (DVec3, DVec3) {
        let e = self.ground_extent;
        let (mut lo, mut hi) = (DVec3::new(-e, 0.0, -e), DVec3::new(e, 0.0, e));
        for world in worlds {
            let (a, b) = scene_bounds(world);
            lo = lo.min(a);
            hi = hi.max(b);
        }
        (lo, hi)
    }
}

pub struct Renderer {
    pub color_format: wgpu::TextureFormat,
    pub sample_count: u32,
    /// Vertex buffers also bind as storage, for the GPU readback's compute pass.
    pub(super) storage: bool,
    pub(super) pipelines: ScenePipelines,
    pub(super) scene: SceneData,
    /// One per world shown; the first `shown` are drawn this frame.
    pub(super) layers: Vec<Layer>,
    shown: usize,
    layout: Layout,
    draw_grid: bool,
    /// Shadow maps are drawn and sampled this frame.
    shadows: bool,
    attachments: Option<SceneAttachments>,
}

/// Body indices sorted by shape, and each shape's range in that order: one instanced draw per
/// shape.
fn group_by_shape(world: &World) -> (Vec<u32>, Vec<Range<u32>>) {
    let mut order: Vec<u32> = (0..world.bodies.len() as u32).collect();
    order.sort_by_key(|&i| world.bodies[i as usize].shape);
    let mut shape_ranges = vec![0..0; world.shapes.len()];
    let mut start = 0;
    while start < order.len() {
        let shape = world.bodies[order[start] as usize].shape;
        let mut end = start;
        while end < order.len() && world.bodies[order[end] as usize].shape == shape {
            end += 1;
        }
        shape_ranges[shape] = start as u32..end as u32;
        start = end;
    }
    (order, shape_ranges)
}

impl Renderer {
    /// Pipelines for rendering into `color_format` (MSAA 4x when the adapter supports it).
    pub fn new(gpu: &Gpu, color_format: wgpu::TextureFormat) -> Renderer {
        let device = &gpu.device;
        let sample_count = gpu.sample_count(color_format);
        let storage = gpu.has_compute();
        let pipelines = ScenePipelines::new(device, color_format, sample_count);
        let first = Layer::new(device, &pipelines, storage);
        Renderer {
            color_format,
            sample_count,
            storage,
            pipelines,
            scene: SceneData::empty(),
            layers: vec![first],
            shown: 1,
            layout: Layout::SideBySide,
            draw_grid: true,
            shadows: false,
            attachments: None,
        }
    }

    /// Uploads the static data of a (new) scene: shape meshes, colours, ground grid.
    pub fn set_world(&mut self, device: &wgpu::Device, world: &World) {
        self.scene = SceneData::new(device, world, vertex_usage(self.storage));
        for layer in &mut self.layers {
            layer.forget_sizes();
        }
    }

    /// (Re)creates the depth and MSAA targets for a `width` x `height` colour target.
    pub fn resize(&mut self, device: &wgpu::Device, width: u32, height: u32) {
        let (width, height) = (width.max(1), height.max(1));
        if self
            .attachments
            .as_ref()
            .is_some_and(|a| a.fits(width, height))
        {
            return;
        }
        self.attachments = Some(SceneAttachments::new(
            device,
            width,
            height,
            self.sample_count,
            self.color_format,
        ));
    }

    /// Uploads this frame's camera, light, and each world's body poses and lines. `worlds` are
    /// the world shown and, when comparing, the others (of the same scene); `camera` is built for
    /// the aspect of one pane ([`compare::pane_aspect`]).
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        worlds: &[&World],
        camera: &CameraMatrices,
        options: &DrawOptions,
    ) {
        self.shadows = options.shadows && !options.flat;
        let globals = self.globals(worlds, camera, options);
        queue.write_buffer(&self.pipelines.globals, 0, bytemuck::bytes_of(&globals));
        while self.layers.len() < worlds.len() {
            let layer = Layer::new(device, &self.pipelines, self.storage);
            self.layers.push(layer);
        }
        let eye = camera.eye.as_dvec3();
        for (layer, world) in self.layers.iter_mut().zip(worlds) {
            layer.prepare(device, queue, world, &self.scene, eye, options);
        }
        self.shown = worlds.len().max(1);
        self.layout = options.layout;
        self.draw_grid = options.grid;
    }

    /// The uniform block: camera, key light, and the shadow map's projection fitted to the
    /// ground and the bodies of `worlds`.
    fn globals(
        &self,
        worlds: &[&World],
        camera: &CameraMatrices,
        options: &DrawOptions,
    ) -> Globals {
        let light = shadow::light_direction().as_vec3();
        let (lo, hi) = self.scene.shadow_bounds(worlds);
        let (light_view_proj, texel) = shadow::light_view_proj(lo, hi);
        Globals {
            view_proj: camera.view_proj.to_cols_array_2d(),
            light_view_proj: light_view_proj.as_mat4().to_cols_array_2d(),
            light: [
                light.x,
                light.y,
                light.z,
                if options.flat { 1.0 } else { 0.0 },
            ],
            eye: [camera.eye.x, camera.eye.y, camera.eye.z, 1.0],
            shadow: [
                if self.shadows { 1.0 } else { 0.0 },
                1.0 / SHADOW_SIZE as f32,
                (1.5 * texel) as f32,
                0.0,
            ],
        }
    }

    /// Draws the shadow maps (when on), then clears `target` and draws the scene into it, within
    /// `viewport` (x, y, width, height in pixels) when given, split into panes when comparing.
    /// [`Self::resize`] must have been called with `target`'s size.
    pub fn draw(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        viewport: Option<[f32; 4]>,
    ) {
        let panes = self.panes(viewport);
        if self.shadows {
            for pane in &panes {
                self.layers[pane.lanes[0]].draw_shadow(encoder, &self.pipelines, &self.scene);
            }
        }
        let mut pass = self.begin_scene_pass(encoder, target);
        for pane in &panes {
            let [x, y, w, h] = pane.rect;
            if w < 1.0 || h < 1.0 {
                continue;
            }
            pass.set_viewport(x, y, w, h, 0.0, 1.0);
            self.draw_pane(&mut pass, &pane.lanes);
        }
    }

    /// The panes of `viewport` (the whole target when None) for the worlds shown.
    fn panes(&self, viewport: Option<[f32; 4]>) -> Vec<compare::Pane> {
        let rect = viewport.unwrap_or_else(|| {
            let a = self.attachments.as_ref();
            let (w, h) = a.map_or((1, 1), |a| (a.width, a.height));
            [0.0, 0.0, w as f32, h as f32]
        });
        compare::panes(rect, self.shown, self.layout)
    }

    /// One pane: the ground under the first world's shadows, its bodies, the others as ghosts,
    /// and its lines.
    fn draw_pane(&self, pass: &mut wgpu::RenderPass<'_>, lanes: &[usize]) {
        let main = &self.layers[lanes[0]];
        let pipelines = &self.pipelines;
        let surfaces = if self.shadows {
            &pipelines.shadowed
        } else {
            &pipelines.unshadowed
        };
        pass.set_bind_group(0, &pipelines.globals_bind_group, &[]);
        pass.set_bind_group(1, &main.shadow.bind_group, &[]);
        if self.draw_grid
            && let Some(ground) = &self.scene.ground_buffer
        {
            pass.set_vertex_buffer(0, ground.slice(..));
            pass.set_pipeline(&surfaces.ground);
            pass.draw(self.scene.ground_plane.clone(), 0..1);
            pass.set_pipeline(&surfaces.grid);
            pass.draw(self.scene.ground_grid.clone(), 0..1);
        }
        pass.set_pipeline(&surfaces.bodies);
        main.draw_bodies(pass, &self.scene);
        main.draw_lines(pass, pipelines);
        for &ghost in &lanes[1..] {
            pass.set_pipeline(&surfaces.ghosts);
            self.layers[ghost].draw_bodies(pass, &self.scene);
        }
    }

    /// The scene pass into `target`: cleared to the background, through the MSAA buffer
    /// (resolved into `target`, then discarded) when there is one; depth cleared and discarded.
    fn begin_scene_pass<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
    ) -> wgpu::RenderPass<'e> {
        let attachments = self
            .attachments
            .as_ref()
            .expect("Renderer::resize before Renderer::draw");
        let background = palette::linear(palette::BACKGROUND_SRGB);
        let clear = wgpu::Color {
            r: background[0] as f64,
            g: background[1] as f64,
            b: background[2] as f64,
            a: 1.0,
        };
        let (view, resolve_target, store) = match &attachments.msaa {
            Some(msaa) => (msaa, Some(target), wgpu::StoreOp::Discard),
            None => (target, None, wgpu::StoreOp::Store),
        };
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("scene"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(clear),
                    store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &attachments.depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// Number of draw calls [`Self::draw`] issues for the bodies of one world (one per shape
    /// in use).
    pub fn body_draw_calls(&self) -> usize {
        self.scene
            .meshes
            .iter()
            .zip(&self.scene.shape_ranges)
            .filter(|(m, r)| !r.is_empty() && m.vertex_count > 0)
            .count()
    }

    /// The instance data of the last [`Self::prepare`] of world `layer`, in body order.
    pub fn instance_in(&self, layer: usize, body: usize) -> Option<InstanceData> {
        let instances = &self.layers.get(layer)?.instances;
        self.scene
            .order
            .iter()
            .position(|&b| b as usize == body)
            .and_then(|k| instances.get(k).copied())
    }

    /// The instance data of the last [`Self::prepare`] of the first world, in body order.
    pub fn instance_of(&self, body: usize) -> Option<InstanceData> {
        self.instance_in(0, body)
    }
}

/// The renderer with its own device and an offscreen colour target: what `tumble record` and
/// the tests use.
pub struct OffscreenRenderer {
    pub gpu: Gpu,
    pub renderer: Renderer,
    /// `Rgba8Unorm`, drawn into through its sRGB view (the bytes of an sRGB target), so that
    /// labels can be painted in gamma space as egui wants.
    pub target: Offscreen,
    labels: Option<LabelPainter>,
}

impl OffscreenRenderer {
    /// Fails with [`NoGpu`] without an adapter or with one that cannot view
    /// a texture in another format, or with the device's error when the frame's buffers do not
    /// fit its memory.
    pub fn new(world: &World, width: u32, height: u32) -> anyhow::Result<OffscreenRenderer> {
        let gpu = Gpu::headless()?;
        // The target is drawn through an sRGB view of its plain bytes. OpenGL ES adapters
        // (wgpu's fallback where no Vulkan driver is installed) cannot: the failure read "this
        // GPU cannot make frames of 640x360", as if the size were at fault.
        if !(gpu.adapter.get_downlevel_capabilities().flags)
            .contains(wgpu::DownlevelFlags::VIEW_FORMATS)
        {
            return Err(NoGpu(format!(
                "{} cannot draw into a texture through a view of another format, which the frames need",
                gpu.description()
            ))
            .into());
        }
        let format = wgpu::TextureFormat::Rgba8Unorm;
        let mut renderer = Renderer::new(&gpu, format.add_srgb_suffix());
        renderer.set_world(&gpu.device, world);
        // Out of memory, the textures are invalid, and so are the views made of them.
        let memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let invalid = gpu.device.push_error_scope(wgpu::ErrorFilter::Validation);
        renderer.resize(&gpu.device, width, height);
        let target = Offscreen::new(&gpu.device, width, height, format);
        let invalid = pollster::block_on(invalid.pop());
        if let Some(error) = pollster::block_on(memory.pop()) {
            anyhow::bail!("frames of {width}x{height} do not fit the GPU's memory: {error}");
        }
        if let Some(error) = invalid {
            anyhow::bail!("this GPU cannot make frames of {width}x{height}: {error}");
        }
        Ok(OffscreenRenderer {
            gpu,
            renderer,
            target,
            labels: None,
        })
    }

    /// Renders the world as seen by `camera` and reads the picture back.
    pub fn render(
        &mut self,
        world: &World,
        camera: &OrbitCamera,
        options: &DrawOptions,
    ) -> anyhow::Result<Image> {
        self.render_worlds(&[world], camera, options, &[])
    }

    /// Renders compared worlds (panes side by side, or ghosts) with `labels` over them, and
    /// reads the picture back.
    pub fn render_worlds(
        &mut self,
        worlds: &[&World],
        camera: &OrbitCamera,
        options: &DrawOptions,
        labels: &[Label],
    ) -> anyhow::Result<Image> {
        let (width, height) = (self.target.width, self.target.height);
        let aspect =
            compare::pane_aspect(width as f64, height as f64, worlds.len(), options.layout);
        let gpu = &self.gpu;
        self.renderer.prepare(
            &gpu.device,
            &gpu.queue,
            worlds,
            &camera.matrices(aspect),
            options,
        );
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        self.renderer
            .draw(&mut encoder, &self.target.srgb_view, None);
        if !labels.is_empty() {
            let format = self.target.format;
            let painter = self
                .labels
                .get_or_insert_with(|| LabelPainter::new(&gpu.device, format));
            painter.paint(
                gpu,
                &mut encoder,
                &self.target.view,
                (width, height),
                labels,
            );
        }
        self.target.copy_to_buffer(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        self.target.read(&gpu.device)
    }
}
