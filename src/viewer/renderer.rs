//! The wgpu scene renderer shared by the window, the recorder and the tests.
//!
//! Static data is uploaded once per scene: one flat-shaded vertex buffer per distinct shape
//! (vertices duplicated per face, carrying the face normal), the ground plane and grid. Each frame
//! uploads only the bodies' poses as instance data (quaternion, centre of mass, colour) plus a few
//! lines (constraints, contacts). The vertex shader computes `R(q) v + COM` in f32, the core's
//! formula, and each shape is one instanced draw.

use super::camera::CameraMatrices;
use super::gpu::Gpu;
use super::palette;
use crate::World;
use bytemuck::{Pod, Zeroable};
use glam::{DVec3, Vec3};
use std::ops::Range;

pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

const SHADER: &str = include_str!("../../shaders/scene.wgsl");

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Globals {
    view_proj: [[f32; 4]; 4],
    light: [f32; 4],
    eye: [f32; 4],
}

/// One vertex of a shape's flat-shaded mesh, in body space.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct MeshVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
}

/// Per-body data uploaded every frame.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq)]
pub struct InstanceData {
    /// Quaternion (x, y, z, w).
    pub rotation: [f32; 4],
    /// Centre of mass (x, y, z, unused).
    pub com: [f32; 4],
    /// Linear colour (r, g, b) and highlight (a).
    pub color: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct LineVertex {
    position: [f32; 3],
    color: [f32; 4],
}

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

struct ShapeMesh {
    buffer: wgpu::Buffer,
    vertex_count: u32,
    /// Rest-vertex index of each buffer vertex.
    source_vertex: Vec<u32>,
}

struct Targets {
    width: u32,
    height: u32,
    msaa: Option<wgpu::TextureView>,
    depth: wgpu::TextureView,
}

pub struct Renderer {
    pub color_format: wgpu::TextureFormat,
    pub sample_count: u32,
    storage: bool,
    module: wgpu::ShaderModule,
    globals: wgpu::Buffer,
    globals_bind_group: wgpu::BindGroup,
    body_pipeline: wgpu::RenderPipeline,
    line_pipeline: wgpu::RenderPipeline,
    ground_pipeline: wgpu::RenderPipeline,
    overlay_pipeline: wgpu::RenderPipeline,
    meshes: Vec<ShapeMesh>,
    /// Body indices grouped by shape; `shape_ranges[s]` is shape `s`'s slice of it.
    order: Vec<u32>,
    shape_ranges: Vec<Range<u32>>,
    base_colors: Vec<[f32; 3]>,
    /// Constraint indices drawn as one segment (a file record's lower and upper bound).
    constraint_groups: Vec<Vec<usize>>,
    instances: Vec<InstanceData>,
    instance_buffer: wgpu::Buffer,
    instance_capacity: usize,
    ground_buffer: Option<wgpu::Buffer>,
    ground_plane: Range<u32>,
    ground_grid: Range<u32>,
    lines: Vec<LineVertex>,
    line_buffer: wgpu::Buffer,
    line_capacity: usize,
    line_count: u32,
    /// Lines from this index on are drawn without depth test.
    overlay_start: u32,
    draw_grid: bool,
    /// Size of the scene, for the length of contact normals.
    scene_scale: f64,
    targets: Option<Targets>,
}

fn buffer(
    device: &wgpu::Device,
    label: &str,
    size: u64,
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size.max(16),
        usage,
        mapped_at_creation: false,
    })
}

fn buffer_init(
    device: &wgpu::Device,
    label: &str,
    contents: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    use wgpu::util::DeviceExt;
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage,
    })
}

fn push_line(lines: &mut Vec<LineVertex>, a: DVec3, b: DVec3, color: [f32; 4]) {
    lines.push(LineVertex {
        position: a.as_vec3().to_array(),
        color,
    });
    lines.push(LineVertex {
        position: b.as_vec3().to_array(),
        color,
    });
}

fn with_alpha(c: [f32; 3], a: f32) -> [f32; 4] {
    [c[0], c[1], c[2], a]
}

/// 1, 2 or 5 times a power of ten, at least `x`.
fn nice_step(x: f64) -> f64 {
    let p = 10f64.powf(x.max(1e-9).log10().floor());
    for m in [1.0, 2.0, 5.0, 10.0] {
        if m * p >= x {
            return m * p;
        }
    }
    10.0 * p
}

impl Renderer {
    /// Pipelines for rendering into `color_format` (MSAA 4x when the adapter supports it).
    pub fn new(gpu: &Gpu, color_format: wgpu::TextureFormat) -> Renderer {
        let device = &gpu.device;
        let sample_count = gpu.sample_count(color_format);
        let storage = gpu.has_compute();
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("scene.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let globals = buffer(
            device,
            "globals",
            std::mem::size_of::<Globals>() as u64,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("globals"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                ty: wgpu::BindingType::Buffer {
                    ty: wgpu::BufferBindingType::Uniform,
                    has_dynamic_offset: false,
                    min_binding_size: None,
                },
                count: None,
            }],
        });
        let globals_bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("globals"),
            layout: &layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: globals.as_entire_binding(),
            }],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("scene"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });

        let body_vertex_layouts = [
            Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<MeshVertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
            }),
            Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<InstanceData>() as u64,
                step_mode: wgpu::VertexStepMode::Instance,
                attributes: &wgpu::vertex_attr_array![2 => Float32x4, 3 => Float32x4, 4 => Float32x4],
            }),
        ];
        let line_vertex_layouts = [Some(wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<LineVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x4],
        })];
        let make = |label: &str,
                    vs: &str,
                    fs: &str,
                    buffers: &[Option<wgpu::VertexBufferLayout>],
                    topology: wgpu::PrimitiveTopology,
                    cull: Option<wgpu::Face>,
                    depth_write: bool,
                    depth_compare: wgpu::CompareFunction| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(vs),
                    compilation_options: Default::default(),
                    buffers,
                },
                primitive: wgpu::PrimitiveState {
                    topology,
                    cull_mode: cull,
                    front_face: wgpu::FrontFace::Ccw,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(depth_write),
                    depth_compare: Some(depth_compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: wgpu::MultisampleState {
                    count: sample_count,
                    ..Default::default()
                },
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fs),
                    compilation_options: Default::default(),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: color_format,
                        blend: None,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        use wgpu::CompareFunction::{Always, Less, LessEqual};
        use wgpu::PrimitiveTopology::{LineList, TriangleList};
        let body_pipeline = make(
            "bodies",
            "vs_body",
            "fs_body",
            &body_vertex_layouts,
            TriangleList,
            Some(wgpu::Face::Back),
            true,
            Less,
        );
        let line_pipeline = make(
            "lines",
            "vs_line",
            "fs_line",
            &line_vertex_layouts,
            LineList,
            None,
            true,
            LessEqual,
        );
        // Contact markers lie inside the overlapping bodies: drawn over everything.
        let overlay_pipeline = make(
            "overlay lines",
            "vs_line",
            "fs_line",
            &line_vertex_layouts,
            LineList,
            None,
            false,
            Always,
        );
        // The ground plane is painted first and writes no depth: everything is drawn over it,
        // including the parts of bodies that sink below y = 0.
        let ground_pipeline = make(
            "ground",
            "vs_line",
            "fs_line",
            &line_vertex_layouts,
            TriangleList,
            None,
            false,
            Always,
        );

        let vertex_usage = wgpu::BufferUsages::VERTEX
            | wgpu::BufferUsages::COPY_DST
            | if storage {
                wgpu::BufferUsages::STORAGE
            } else {
                wgpu::BufferUsages::empty()
            };
        Renderer {
            color_format,
            sample_count,
            storage,
            module,
            globals,
            globals_bind_group,
            body_pipeline,
            line_pipeline,
            ground_pipeline,
            overlay_pipeline,
            meshes: Vec::new(),
            order: Vec::new(),
            shape_ranges: Vec::new(),
            base_colors: Vec::new(),
            constraint_groups: Vec::new(),
            instances: Vec::new(),
            instance_buffer: buffer(device, "instances", 16, vertex_usage),
            instance_capacity: 0,
            ground_buffer: None,
            ground_plane: 0..0,
            ground_grid: 0..0,
            lines: Vec::new(),
            line_buffer: buffer(
                device,
                "lines",
                16,
                wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            ),
            line_capacity: 0,
            line_count: 0,
            overlay_start: 0,
            draw_grid: true,
            scene_scale: 1.0,
            targets: None,
        }
    }

    fn vertex_usage(&self) -> wgpu::BufferUsages {
        wgpu::BufferUsages::VERTEX
            | wgpu::BufferUsages::COPY_DST
            | if self.storage {
                wgpu::BufferUsages::STORAGE
            } else {
                wgpu::BufferUsages::empty()
            }
    }

    /// Uploads the static data of a (new) scene: shape meshes, colours, ground grid.
    pub fn set_world(&mut self, device: &wgpu::Device, world: &World) {
        self.meshes = world
            .shapes
            .iter()
            .map(|shape| {
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
                    buffer: buffer_init(
                        device,
                        "shape mesh",
                        bytemuck::cast_slice(&vertices),
                        self.vertex_usage(),
                    ),
                    vertex_count: vertices.len() as u32,
                    source_vertex,
                }
            })
            .collect();

        let mut order: Vec<u32> = (0..world.bodies.len() as u32).collect();
        order.sort_by_key(|&i| world.bodies[i as usize].shape);
        self.shape_ranges = vec![0..0; world.shapes.len()];
        let mut start = 0;
        while start < order.len() {
            let shape = world.bodies[order[start] as usize].shape;
            let mut end = start;
            while end < order.len() && world.bodies[order[end] as usize].shape == shape {
                end += 1;
            }
            self.shape_ranges[shape] = start as u32..end as u32;
            start = end;
        }
        self.order = order;
        self.base_colors = world
            .bodies
            .iter()
            .enumerate()
            .map(|(i, b)| palette::linear(palette::body_srgb(i, b.fixed)))
            .collect();

        self.constraint_groups.clear();
        for (index, c) in world.constraints.iter().enumerate() {
            let same = self.constraint_groups.last().map(|g| {
                let p = &world.constraints[g[0]];
                (p.body1, p.body2, p.vertex1, p.vertex2) == (c.body1, c.body2, c.vertex1, c.vertex2)
            });
            match same {
                Some(true) => self
                    .constraint_groups
                    .last_mut()
                    .expect("nonempty")
                    .push(index),
                _ => self.constraint_groups.push(vec![index]),
            }
        }

        let (lo, hi) = super::camera::scene_bounds(world);
        self.scene_scale = (hi - lo).length().max(1e-3);
        self.build_ground(device, lo, hi);
        self.instance_capacity = 0;
    }

    fn build_ground(&mut self, device: &wgpu::Device, lo: DVec3, hi: DVec3) {
        // Around the origin, past the bodies, and at least as wide as the scene is tall (a
        // tower stands on a floor, not on a tile).
        let half = [lo.x, hi.x, lo.z, hi.z]
            .iter()
            .map(|v| v.abs())
            .fold(0.5 * (hi.y - lo.y), f64::max)
            .max(1.0)
            * 1.15;
        let step = nice_step(half / 12.0);
        let n = (half / step).ceil() as i64;
        let extent = n as f64 * step;
        let ground = with_alpha(palette::linear(palette::GROUND_SRGB), 1.0);
        let grid = with_alpha(palette::linear(palette::GRID_SRGB), 1.0);
        let x_axis = with_alpha(palette::linear(palette::GRID_X_AXIS_SRGB), 1.0);
        let z_axis = with_alpha(palette::linear(palette::GRID_Z_AXIS_SRGB), 1.0);
        let v = |x: f64, z: f64, color: [f32; 4]| LineVertex {
            position: [x as f32, 0.0, z as f32],
            color,
        };
        let e = extent;
        let mut vertices = vec![
            v(-e, -e, ground),
            v(e, -e, ground),
            v(e, e, ground),
            v(-e, -e, ground),
            v(e, e, ground),
            v(-e, e, ground),
        ];
        for k in -n..=n {
            let t = k as f64 * step;
            // Lines along x (constant z) and along z (constant x); the axes themselves in colour.
            let (cx, cz) = if k == 0 {
                (x_axis, z_axis)
            } else {
                (grid, grid)
            };
            vertices.extend([v(-e, t, cx), v(e, t, cx), v(t, -e, cz), v(t, e, cz)]);
        }
        self.ground_plane = 0..6;
        self.ground_grid = 6..vertices.len() as u32;
        self.ground_buffer = Some(buffer_init(
            device,
            "ground",
            bytemuck::cast_slice(&vertices),
            wgpu::BufferUsages::VERTEX,
        ));
    }

    /// (Re)creates the depth and MSAA targets for a `width` x `height` colour target.
    pub fn resize(&mut self, device: &wgpu::Device, width: u32, height: u32) {
        let (width, height) = (width.max(1), height.max(1));
        if self
            .targets
            .as_ref()
            .is_some_and(|t| t.width == width && t.height == height)
        {
            return;
        }
        let texture = |label: &str, format: wgpu::TextureFormat| {
            device
                .create_texture(&wgpu::TextureDescriptor {
                    label: Some(label),
                    size: wgpu::Extent3d {
                        width,
                        height,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: self.sample_count,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                    view_formats: &[],
                })
                .create_view(&wgpu::TextureViewDescriptor::default())
        };
        let msaa = (self.sample_count > 1).then(|| texture("msaa colour", self.color_format));
        let depth = texture("depth", DEPTH_FORMAT);
        self.targets = Some(Targets {
            width,
            height,
            msaa,
            depth,
        });
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
        queue.write_buffer(&self.globals, 0, bytemuck::bytes_of(&globals));

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
            let highlight = if options.selected == Some(index as usize) {
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
        if self.instances.len() > self.instance_capacity {
            self.instance_capacity = self.instances.len().next_power_of_two();
            self.instance_buffer = buffer(
                device,
                "instances",
                (self.instance_capacity * std::mem::size_of::<InstanceData>()) as u64,
                self.vertex_usage(),
            );
        }
        if !self.instances.is_empty() {
            queue.write_buffer(
                &self.instance_buffer,
                0,
                bytemuck::cast_slice(&self.instances),
            );
        }

        self.lines.clear();
        if options.constraints {
            for group in &self.constraint_groups {
                let first = &world.constraints[group[0]];
                let (p1, p2) = first.points(&world.bodies);
                let violation = group
                    .iter()
                    .map(|&k| world.constraints[k].violation(&world.bodies))
                    .fold(0.0, f64::max);
                // Red at 10% of the rest length outside the bounds.
                let t = violation / (0.1 * first.rest_length).max(1e-9);
                let color = with_alpha(palette::linear(palette::violation_srgb(t)), 1.0);
                push_line(&mut self.lines, p1, p2, color);
            }
        }
        if let Some(index) = options.selected.filter(|&i| i < world.bodies.len()) {
            // Outline of the picked body, pulled slightly towards the eye so it wins the depth
            // test against the body's own faces.
            let eye = camera.eye.as_dvec3();
            let color = with_alpha(palette::linear([1.0, 0.85, 0.25]), 1.0);
            let vertices: Vec<DVec3> = world
                .current_vertices(index)
                .into_iter()
                .map(|p| p + (eye - p) * 0.003)
                .collect();
            let shape = &world.shapes[world.bodies[index].shape];
            for tri in &shape.triangles {
                for k in 0..3 {
                    let (a, b) = (tri[k] as usize, tri[(k + 1) % 3] as usize);
                    push_line(&mut self.lines, vertices[a], vertices[b], color);
                }
            }
        }
        self.overlay_start = self.lines.len() as u32;
        if options.contacts {
            let point_color = with_alpha(palette::linear([1.0, 0.95, 0.2]), 1.0);
            let normal_color = with_alpha(palette::linear([1.0, 0.45, 0.1]), 1.0);
            let s = 0.015 * self.scene_scale;
            for (_, _, contact) in world.current_contacts() {
                let p = contact.point2;
                for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
                    push_line(&mut self.lines, p - s * axis, p + s * axis, point_color);
                }
                push_line(
                    &mut self.lines,
                    p,
                    p + contact.normal * (5.0 * s),
                    normal_color,
                );
            }
        }
        self.line_count = self.lines.len() as u32;
        if self.lines.len() > self.line_capacity {
            self.line_capacity = self.lines.len().next_power_of_two();
            self.line_buffer = buffer(
                device,
                "lines",
                (self.line_capacity * std::mem::size_of::<LineVertex>()) as u64,
                wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            );
        }
        if !self.lines.is_empty() {
            queue.write_buffer(&self.line_buffer, 0, bytemuck::cast_slice(&self.lines));
        }
        self.draw_grid = options.grid;
    }

    /// Clears `target` and draws the scene into it, within `viewport` (x, y, width, height in
    /// pixels) when given. [`Self::resize`] must have been called with `target`'s size.
    pub fn draw(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        viewport: Option<[f32; 4]>,
    ) {
        let targets = self
            .targets
            .as_ref()
            .expect("Renderer::resize before Renderer::draw");
        let background = palette::linear(palette::BACKGROUND_SRGB);
        let clear = wgpu::Color {
            r: background[0] as f64,
            g: background[1] as f64,
            b: background[2] as f64,
            a: 1.0,
        };
        let (view, resolve_target, store) = match &targets.msaa {
            Some(msaa) => (msaa, Some(target), wgpu::StoreOp::Discard),
            None => (target, None, wgpu::StoreOp::Store),
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
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
                view: &targets.depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if let Some([x, y, w, h]) = viewport {
            if w < 1.0 || h < 1.0 {
                return;
            }
            pass.set_viewport(x, y, w, h, 0.0, 1.0);
        }
        pass.set_bind_group(0, &self.globals_bind_group, &[]);
        if self.draw_grid
            && let Some(ground) = &self.ground_buffer
        {
            pass.set_vertex_buffer(0, ground.slice(..));
            pass.set_pipeline(&self.ground_pipeline);
            pass.draw(self.ground_plane.clone(), 0..1);
            pass.set_pipeline(&self.line_pipeline);
            pass.draw(self.ground_grid.clone(), 0..1);
        }
        if !self.instances.is_empty() {
            pass.set_pipeline(&self.body_pipeline);
            pass.set_vertex_buffer(1, self.instance_buffer.slice(..));
            for (mesh, range) in self.meshes.iter().zip(&self.shape_ranges) {
                if range.is_empty() || mesh.vertex_count == 0 {
                    continue;
                }
                pass.set_vertex_buffer(0, mesh.buffer.slice(..));
                pass.draw(0..mesh.vertex_count, range.clone());
            }
        }
        if self.line_count > 0 {
            pass.set_vertex_buffer(0, self.line_buffer.slice(..));
            if self.overlay_start > 0 {
                pass.set_pipeline(&self.line_pipeline);
                pass.draw(0..self.overlay_start, 0..1);
            }
            if self.line_count > self.overlay_start {
                pass.set_pipeline(&self.overlay_pipeline);
                pass.draw(self.overlay_start..self.line_count, 0..1);
            }
        }
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

    /// Runs the vertex shader's body transform (`body_point` in scene.wgsl) over every body's
    /// mesh vertex buffer and the instance buffer of the last [`Self::prepare`], on the GPU, and
    /// reads the results back: for each body, the world position of each rest vertex that lies
    /// on the surface (None for interior vertices, which are never drawn).
    pub fn gpu_body_points(&self, gpu: &Gpu) -> anyhow::Result<Vec<Vec<Option<[f32; 3]>>>> {
        anyhow::ensure!(self.storage, "this adapter has no compute shaders");
        let device = &gpu.device;
        let storage = |binding: u32, read_only: bool| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("body points"),
            entries: &[
                storage(1, true),
                storage(2, true),
                storage(3, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 4,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("body points"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("body points"),
            layout: Some(&pipeline_layout),
            module: &self.module,
            entry_point: Some("cs_body_points"),
            compilation_options: Default::default(),
            cache: None,
        });

        let mut out: Vec<Vec<Option<[f32; 3]>>> = vec![Vec::new(); self.order.len()];
        for (mesh, range) in self.meshes.iter().zip(&self.shape_ranges) {
            if range.is_empty() || mesh.vertex_count == 0 {
                continue;
            }
            let count = mesh.vertex_count as u64 * range.len() as u64;
            let size = 12 * count;
            let result = buffer(
                device,
                "body points",
                size,
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            );
            let readback = buffer(
                device,
                "body points readback",
                size,
                wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            );
            let params: [u32; 4] = [mesh.vertex_count, range.start, range.len() as u32, 0];
            let params = buffer_init(
                device,
                "body points params",
                bytemuck::cast_slice(&params),
                wgpu::BufferUsages::UNIFORM,
            );
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("body points"),
                layout: &layout,
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: mesh.buffer.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: self.instance_buffer.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: result.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: params.as_entire_binding(),
                    },
                ],
            });
            let mut encoder = device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(0, &bind_group, &[]);
                pass.dispatch_workgroups(count.div_ceil(64) as u32, 1, 1);
            }
            encoder.copy_buffer_to_buffer(&result, 0, &readback, 0, size);
            gpu.queue.submit([encoder.finish()]);
            let slice = readback.slice(..size);
            let (tx, rx) = std::sync::mpsc::channel();
            slice.map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send(r);
            });
            device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            rx.recv()?.map_err(|e| anyhow::anyhow!("{e}"))?;
            let values: Vec<f32> = bytemuck::cast_slice(
                &slice
                    .get_mapped_range()
                    .map_err(|e| anyhow::anyhow!("{e:?}"))?,
            )
            .to_vec();
            readback.unmap();

            let rest_count = mesh
                .source_vertex
                .iter()
                .copied()
                .max()
                .map_or(0, |m| m as usize + 1);
            for (k, &body) in self.order[range.start as usize..range.end as usize]
                .iter()
                .enumerate()
            {
                let mut points = vec![None; rest_count];
                for (v, &source) in mesh.source_vertex.iter().enumerate() {
                    let i = 3 * (k * mesh.vertex_count as usize + v);
                    points[source as usize] = Some([values[i], values[i + 1], values[i + 2]]);
                }
                out[body as usize] = points;
            }
        }
        Ok(out)
    }
}

/// The renderer with its own device and an offscreen colour target: what `tumble record` and
/// the tests use.
pub struct OffscreenRenderer {
    pub gpu: Gpu,
    pub renderer: Renderer,
    pub target: super::gpu::Offscreen,
}

impl OffscreenRenderer {
    pub fn new(
        world: &World,
        width: u32,
        height: u32,
    ) -> Result<OffscreenRenderer, super::gpu::NoGpu> {
        let gpu = Gpu::headless()?;
        let format = wgpu::TextureFormat::Rgba8UnormSrgb;
        let mut renderer = Renderer::new(&gpu, format);
        renderer.set_world(&gpu.device, world);
        renderer.resize(&gpu.device, width, height);
        let target = super::gpu::Offscreen::new(&gpu.device, width, height, format);
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
        camera: &super::camera::OrbitCamera,
        options: &DrawOptions,
    ) -> anyhow::Result<super::gpu::Image> {
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
