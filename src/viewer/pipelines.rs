//! The scene shader's interface and its render pipelines: the uniform block, the vertex formats
//! (mesh vertices, per-body instances, coloured line vertices) and one pipeline per kind of
//! geometry, all sharing `scene.wgsl`, the globals bind group (group 0) and a shadow map
//! (group 1).

use super::gpu::buffer;
use super::shadow;
use super::targets::DEPTH_FORMAT;
use bytemuck::{Pod, Zeroable};

const SHADER: &str = include_str!("../../shaders/scene.wgsl");

/// Vertex inputs of `vs_body`: the mesh vertex, and the body's instance at locations 2 to 4.
pub(super) const BODY_BUFFERS: [Option<wgpu::VertexBufferLayout<'static>>; 2] = [
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

/// Vertex inputs of `vs_line`.
const LINE_BUFFERS: [Option<wgpu::VertexBufferLayout<'static>>; 1] =
    [Some(wgpu::VertexBufferLayout {
        array_stride: std::mem::size_of::<LineVertex>() as u64,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x4],
    })];

/// The uniform block (`Globals` in scene.wgsl), written once per frame.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub struct Globals {
    pub view_proj: [[f32; 4]; 4],
    /// World to the shadow map's clip space.
    pub light_view_proj: [[f32; 4]; 4],
    /// Direction towards the light (x, y, z) and 1 for unlit drawing (w).
    pub light: [f32; 4],
    pub eye: [f32; 4],
    /// 1 with shadows (x), one shadow-map texel in texture coordinates (y), how far receivers
    /// look up the map along their normal, in world units (z).
    pub shadow: [f32; 4],
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

/// A vertex of the ground, the grid and the overlay lines, in world space.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct LineVertex {
    pub position: [f32; 3],
    pub color: [f32; 4],
}

/// The shader module, the globals uniform and the pipelines drawn from them.
pub struct ScenePipelines {
    /// Kept for the compute entry point of the GPU readback.
    pub module: wgpu::ShaderModule,
    pub globals: wgpu::Buffer,
    pub globals_bind_group: wgpu::BindGroup,
    /// Layout of the shadow map's bind group (group 1).
    pub shadow_layout: wgpu::BindGroupLayout,
    /// Bodies into a shadow map, from the light.
    pub shadow: wgpu::RenderPipeline,
    /// The pipelines of lit surfaces that sample the shadow map, and the same without shadows
    /// (the lookup compiled out: software rasterisers pay for it even when skipped).
    pub shadowed: SurfacePipelines,
    pub unshadowed: SurfacePipelines,
    /// Depth-tested lines: constraint segments, selection outline.
    pub lines: wgpu::RenderPipeline,
    /// Lines over everything: contact markers lie inside the overlapping bodies.
    pub overlay: wgpu::RenderPipeline,
}

/// The pipelines of lit surfaces, which receive shadows.
pub struct SurfacePipelines {
    /// Instanced, depth-tested, back-face culled triangles.
    pub bodies: wgpu::RenderPipeline,
    /// A compared world's bodies over the first one's: blended, writing no depth.
    pub ghosts: wgpu::RenderPipeline,
    /// The ground plane, painted first and writing no depth: everything is drawn over it,
    /// including the parts of bodies that sink below y = 0.
    pub ground: wgpu::RenderPipeline,
    /// The ground grid's lines, depth-tested, shaded like the plane.
    pub grid: wgpu::RenderPipeline,
}

impl SurfacePipelines {
    /// With the shader's `SHADOWS` constant set to `shadows`.
    fn new(base: &PipelineBase<'_>, shadows: bool) -> SurfacePipelines {
        use wgpu::CompareFunction::{Always, Less, LessEqual};
        use wgpu::PrimitiveTopology::{LineList, TriangleList};
        let constants: &[(&str, f64)] = if shadows {
            &[("SHADOWS", 1.0)]
        } else {
            &[("SHADOWS", 0.0)]
        };
        let body = |label, fragment_entry, depth_write, blend| PipelineSpec {
            label,
            vertex_entry: "vs_body",
            fragment_entry,
            buffers: &BODY_BUFFERS,
            topology: TriangleList,
            cull_mode: Some(wgpu::Face::Back),
            depth_write,
            depth_compare: Less,
            blend,
            constants,
        };
        let ground = |label, topology, depth_write, depth_compare| PipelineSpec {
            label,
            vertex_entry: "vs_line",
            fragment_entry: "fs_ground",
            buffers: &LINE_BUFFERS,
            topology,
            cull_mode: None,
            depth_write,
            depth_compare,
            blend: None,
            constants,
        };
        let ghost_blend = Some(wgpu::BlendState::ALPHA_BLENDING);
        SurfacePipelines {
            bodies: base.build(body("bodies", "fs_body", true, None)),
            ghosts: base.build(body("ghost bodies", "fs_ghost", false, ghost_blend)),
            ground: base.build(ground("ground", TriangleList, false, Always)),
            grid: base.build(ground("grid", LineList, true, LessEqual)),
        }
    }
}

/// What differs between the scene's pipelines.
struct PipelineSpec<'a> {
    label: &'a str,
    vertex_entry: &'a str,
    fragment_entry: &'a str,
    buffers: &'a [Option<wgpu::VertexBufferLayout<'a>>],
    topology: wgpu::PrimitiveTopology,
    cull_mode: Option<wgpu::Face>,
    depth_write: bool,
    depth_compare: wgpu::CompareFunction,
    blend: Option<wgpu::BlendState>,
    /// Values of the shader's pipeline-overridable constants.
    constants: &'a [(&'a str, f64)],
}

/// What all the scene's pipelines share.
struct PipelineBase<'a> {
    device: &'a wgpu::Device,
    layout: &'a wgpu::PipelineLayout,
    module: &'a wgpu::ShaderModule,
    color_format: wgpu::TextureFormat,
    sample_count: u32,
}

impl PipelineBase<'_> {
    fn build(&self, spec: PipelineSpec<'_>) -> wgpu::RenderPipeline {
        self.device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(spec.label),
                layout: Some(self.layout),
                vertex: wgpu::VertexState {
                    module: self.module,
                    entry_point: Some(spec.vertex_entry),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: spec.constants,
                        ..Default::default()
                    },
                    buffers: spec.buffers,
                },
                primitive: wgpu::PrimitiveState {
                    topology: spec.topology,
                    cull_mode: spec.cull_mode,
                    front_face: wgpu::FrontFace::Ccw,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(spec.depth_write),
                    depth_compare: Some(spec.depth_compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: wgpu::MultisampleState {
                    count: self.sample_count,
                    ..Default::default()
                },
                fragment: Some(wgpu::FragmentState {
                    module: self.module,
                    entry_point: Some(spec.fragment_entry),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants: spec.constants,
                        ..Default::default()
                    },
                    targets: &[Some(wgpu::ColorTargetState {
                        format: self.color_format,
                        blend: spec.blend,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                }),
                multiview_mask: None,
                cache: None,
            })
    }
}

impl ScenePipelines {
    /// Everything needed to draw into `color_format` with `sample_count` samples per pixel.
    pub fn new(
        device: &wgpu::Device,
        color_format: wgpu::TextureFormat,
        sample_count: u32,
    ) -> ScenePipelines {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("scene.wgsl"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let (layout, globals, globals_bind_group) = globals_binding(device);
        let shadow_layout = shadow::bind_group_layout(device);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("scene"),
            bind_group_layouts: &[Some(&layout), Some(&shadow_layout)],
            immediate_size: 0,
        });
        let base = PipelineBase {
            device,
            layout: &pipeline_layout,
            module: &module,
            color_format,
            sample_count,
        };
        let line = |label, depth_write, depth_compare| PipelineSpec {
            label,
            vertex_entry: "vs_line",
            fragment_entry: "fs_line",
            buffers: &LINE_BUFFERS,
            topology: wgpu::PrimitiveTopology::LineList,
            cull_mode: None,
            depth_write,
            depth_compare,
            blend: None,
            constants: &[],
        };
        ScenePipelines {
            shadow: shadow::pipeline(device, &module, &layout),
            shadowed: SurfacePipelines::new(&base, true),
            unshadowed: SurfacePipelines::new(&base, false),
            lines: base.build(line("lines", true, wgpu::CompareFunction::LessEqual)),
            overlay: base.build(line("overlay lines", false, wgpu::CompareFunction::Always)),
            module,
            globals,
            globals_bind_group,
            shadow_layout,
        }
    }
}

/// The globals uniform buffer at binding 0, seen by both shader stages: its layout, the buffer
/// and the bind group.
fn globals_binding(
    device: &wgpu::Device,
) -> (wgpu::BindGroupLayout, wgpu::Buffer, wgpu::BindGroup) {
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
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("globals"),
        layout: &layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: globals.as_entire_binding(),
        }],
    });
    (layout, globals, bind_group)
}
