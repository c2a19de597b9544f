//! The wgpu scene renderer shared by the window, the recorder and the tests.
//!
//! Static data is uploaded once per scene: one flat-shaded vertex buffer per distinct shape
//! (vertices duplicated per face, carrying the face normal), the ground plane and grid. Each frame
//! uploads only the bodies' poses as instance data (quaternion, centre of mass, colour) plus a few
//! lines (constraints, contacts). The vertex shader computes `R(q) v + COM` in f32, the core's
//! formula, and each shape is one instanced draw.
//!
//! Pipelines live in `pipelines.rs`, line geometry in `overlay.rs`, depth and MSAA attachments
//! in `targets.rs`; the test-only GPU readback extends [`Renderer`] from `readback.rs`.

use super::camera::{CameraMatrices, OrbitCamera, scene_bounds};
use super::gpu::{Gpu, Image, NoGpu, Offscreen, StreamingBuffer, buffer_init};
use super::overlay::{self, with_alpha};
use super::palette;
use super::pipelines::{Globals, LineVertex, ScenePipelines};
pub use super::pipelines::{InstanceData, MeshVertex};
pub use super::targets::DEPTH_FORMAT;
use super::targets::SceneAttachments;
use crate::{Shape, World};
use glam::Vec3;
use std::ops::Range;

/// What to draw besides the bodies.
#[derive(Debug, Clone, PartialEq)]
pub struct DrawOptions {
    /// Ground plane and grid at y = 0.
    pub grid: bool,
    /// Constraint segments coloured by violation.
    pub constraints: bool,
    /// Contact points and normals at the current poses.
    pub contacts: bool,
    /// Highlighted body.
    pub selected: Option<usize>,
    /// Unlit: every body in its exact palette colour (for tests).
    pub flat: bool,
}

impl Default for DrawOptions {
    fn default() -> Self {
        DrawOptions {
            grid: true,
            constraints: true,
            contacts: false,
            selected: None,
            flat: false,
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

pub struct Renderer {
    pub color_format: wgpu::TextureFormat,
    pub sample_count: u32,
    /// Vertex buffers also bind as storage, for the GPU readback's compute pass.
    pub(super) storage: bool,
    pub(super) pipelines: ScenePipelines,
    pub(super) meshes: Vec<ShapeMesh>,
    /// Body indices grouped by shape; `shape_ranges[s]` is shape `s`'s slice of it.
    pub(super) order: Vec<u32>,
    pub(super) shape_ranges: Vec<Range<u32>>,
    base_colors: Vec<[f32; 3]>,
    /// Constraint indices drawn as one segment (a file record's lower and upper bound).
    constraint_groups: Vec<Vec<usize>>,
    instances: Vec<InstanceData>,
    pub(super) instance_buffer: StreamingBuffer,
    ground_buffer: Option<wgpu::Buffer>,
    ground_plane: Range<u32>,
    ground_grid: Range<u32>,
    lines: Vec<LineVertex>,
    line_buffer: StreamingBuffer,
    /// Lines from this index on are drawn without depth test.
    overlay_start: u32,
    draw_grid: bool,
    /// Size of the scene, for the length of contact normals.
    scene_scale: f64,
    attachments: Option<SceneAttachments>,
}

/// Usage of the mesh and instance buffers: storage too where the readback can bind them.
fn vertex_usage(storage: bool) -> wgpu::BufferUsages {
    wgpu::BufferUsages::VERTEX
        | wgpu::BufferUsages::COPY_DST
        | if storage {
            wgpu::BufferUsages::STORAGE
        } else {
            wgpu::BufferUsages::empty()
        }
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
        Renderer {
            color_format,
            sample_count,
            storage,
            pipelines: ScenePipelines::new(device, color_format, sample_count),
            meshes: Vec::new(),
            order: Vec::new(),
            shape_ranges: Vec::new(),
            base_colors: Vec::new(),
            constraint_groups: Vec::new(),
            instances: Vec::new(),
            instance_buffer: StreamingBuffer::new(device, "instances", vertex_usage(storage)),
            ground_buffer: None,
            ground_plane: 0..0,
            ground_grid: 0..0,
            lines: Vec::new(),
            line_buffer: StreamingBuffer::new(
                device,
                "lines",
                wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            ),
            overlay_start: 0,
            draw_grid: true,
            scene_scale: 1.0,
            attachments: None,
        }
    }

    /// Uploads the static data of a (new) scene: shape meshes, colours, ground grid.
    pub fn set_world(&mut self, device: &wgpu::Device, world: &World) {
        let usage = vertex_usage(self.storage);
        self.meshes = world
            .shapes
            .iter()
            .map(|shape| ShapeMesh::new(device, shape, usage))
            .collect();
        (self.order, self.shape_ranges) = group_by_shape(world);
        self.base_colors = world
            .bodies
            .iter()
            .enumerate()
            .map(|(i, b)| palette::linear(palette::body_srgb(i, b.fixed)))
            .collect();
        self.constraint_groups = overlay::constraint_groups(world);

        let (lo, hi) = scene_bounds(world);
        self.scene_scale = (hi - lo).length().max(1e-3);
        let ground = overlay::ground(lo, hi);
        self.ground_plane = ground.plane;
        self.ground_grid = ground.grid;
        self.ground_buffer = Some(buffer_init(
            device,
            "ground",
            bytemuck::cast_slice(&ground.vertices),
            wgpu::BufferUsages::VERTEX,
        ));
        self.instance_buffer.reallocate_on_next_write();
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

    /// Uploads this frame's camera, body poses and lines.
    pub fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        world: &World,
        camera: &CameraMatrices,
        options: &DrawOptions,
    ) {
        let light = Vec3::new(0.45, 0.8, 0.35).normalize();
        let globals = Globals {
            view_proj: camera.view_proj.to_cols_array_2d(),
            light: [
                light.x,
                light.y,
                light.z,
                if options.flat { 1.0 } else { 0.0 },
            ],
            eye: [camera.eye.x, camera.eye.y, camera.eye.z, 1.0],
        };
        queue.write_buffer(&self.pipelines.globals, 0, bytemuck::bytes_of(&globals));
        self.build_instances(world, options.selected);
        self.instance_buffer.write(device, queue, &self.instances);
        self.build_lines(world, camera, options);
        self.line_buffer.write(device, queue, &self.lines);
        self.draw_grid = options.grid;
    }

    /// One instance per body in draw order: pose in f32, palette colour (or the quarantine
    /// colour), and the highlight flag of the selected body.
    fn build_instances(&mut self, world: &World, selected: Option<usize>) {
        self.instances.clear();
        for &index in &self.order {
            let body = &world.bodies[index as usize];
            let q = body.orientation.as_quat();
            let p = body.position.as_vec3();
            let color = if body.quarantined {
                palette::linear(palette::QUARANTINED_SRGB)
            } else {
                self.base_colors[index as usize]
            };
            let highlight = if selected == Some(index as usize) {
                1.0
            } else {
                0.0
            };
            self.instances.push(InstanceData {
                rotation: q.to_array(),
                com: [p.x, p.y, p.z, 0.0],
                color: with_alpha(color, highlight),
            });
        }
    }

    /// This frame's lines: the depth-tested ones (constraints, selection outline), then from
    /// `overlay_start` those drawn over everything (contact markers).
    fn build_lines(&mut self, world: &World, camera: &CameraMatrices, options: &DrawOptions) {
        self.lines.clear();
        if options.constraints {
            overlay::constraint_segments(&mut self.lines, world, &self.constraint_groups);
        }
        if let Some(index) = options.selected.filter(|&i| i < world.bodies.len()) {
            overlay::selection_outline(&mut self.lines, world, index, camera.eye.as_dvec3());
        }
        self.overlay_start = self.lines.len() as u32;
        if options.contacts {
            overlay::contact_markers(&mut self.lines, world, self.scene_scale);
        }
    }

    /// Clears `target` and draws the scene into it, within `viewport` (x, y, width, height in
    /// pixels) when given. [`Self::resize`] must have been called with `target`'s size.
    pub fn draw(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        viewport: Option<[f32; 4]>,
    ) {
        let mut pass = self.begin_scene_pass(encoder, target);
        if let Some([x, y, w, h]) = viewport {
            if w < 1.0 || h < 1.0 {
                return;
            }
            pass.set_viewport(x, y, w, h, 0.0, 1.0);
        }
        pass.set_bind_group(0, &self.pipelines.globals_bind_group, &[]);
        if self.draw_grid
            && let Some(ground) = &self.ground_buffer
        {
            pass.set_vertex_buffer(0, ground.slice(..));
            pass.set_pipeline(&self.pipelines.ground);
            pass.draw(self.ground_plane.clone(), 0..1);
            pass.set_pipeline(&self.pipelines.lines);
            pass.draw(self.ground_grid.clone(), 0..1);
        }
        if !self.instances.is_empty() {
            pass.set_pipeline(&self.pipelines.bodies);
            pass.set_vertex_buffer(1, self.instance_buffer.buffer.slice(..));
            for (mesh, range) in self.meshes.iter().zip(&self.shape_ranges) {
                if range.is_empty() || mesh.vertex_count == 0 {
                    continue;
                }
                pass.set_vertex_buffer(0, mesh.buffer.slice(..));
                pass.draw(0..mesh.vertex_count, range.clone());
            }
        }
        let line_count = self.lines.len() as u32;
        if line_count > 0 {
            pass.set_vertex_buffer(0, self.line_buffer.buffer.slice(..));
            if self.overlay_start > 0 {
                pass.set_pipeline(&self.pipelines.lines);
                pass.draw(0..self.overlay_start, 0..1);
            }
            if line_count > self.overlay_start {
                pass.set_pipeline(&self.pipelines.overlay);
                pass.draw(self.overlay_start..line_count, 0..1);
            }
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

    /// Number of draw calls [`Self::draw`] issues for the bodies (one per shape in use).
    pub fn body_draw_calls(&self) -> usize {
        self.meshes
            .iter()
            .zip(&self.shape_ranges)
            .filter(|(m, r)| !r.is_empty() && m.vertex_count > 0)
            .count()
    }

    /// The instance data of the last [`Self::prepare`], in body order.
    pub fn instance_of(&self, body: usize) -> Option<InstanceData> {
        self.order
            .iter()
            .position(|&b| b as usize == body)
            .map(|k| self.instances[k])
    }
}

/// The renderer with its own device and an offscreen colour target: what `tumble record` and
/// the tests use.
pub struct OffscreenRenderer {
    pub gpu: Gpu,
    pub renderer: Renderer,
    pub target: Offscreen,
}

impl OffscreenRenderer {
    pub fn new(world: &World, width: u32, height: u32) -> Result<OffscreenRenderer, NoGpu> {
        let gpu = Gpu::headless()?;
        let format = wgpu::TextureFormat::Rgba8UnormSrgb;
        let mut renderer = Renderer::new(&gpu, format);
        renderer.set_world(&gpu.device, world);
        renderer.resize(&gpu.device, width, height);
        let target = Offscreen::new(&gpu.device, width, height, format);
        Ok(OffscreenRenderer {
            gpu,
            renderer,
            target,
        })
    }

    /// Renders the world as seen by `camera` and reads the picture back.
    pub fn render(
        &mut self,
        world: &World,
        camera: &OrbitCamera,
        options: &DrawOptions,
    ) -> anyhow::Result<Image> {
        let aspect = self.target.width as f64 / self.target.height as f64;
        self.renderer.prepare(
            &self.gpu.device,
            &self.gpu.queue,
            world,
            &camera.matrices(aspect),
            options,
        );
        let mut encoder = self.gpu.device.create_command_encoder(&Default::default());
        self.renderer.draw(&mut encoder, &self.target.view, None);
        self.target.copy_to_buffer(&mut encoder);
        self.gpu.queue.submit([encoder.finish()]);
        self.target.read(&self.gpu.device)
    }
}
