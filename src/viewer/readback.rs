//! Test-only GPU readback: runs the vertex shader's body transform as a compute pass over the
//! renderer's own buffers, so the tests can compare what the GPU draws with the core's vertices.
//! Kept out of `renderer.rs` because nothing draws with it.

use super::gpu::{Gpu, buffer, buffer_init, read_mapped};
use super::renderer::{Renderer, ShapeMesh};
use std::ops::Range;

/// For each body, the world position of each of its rest vertices (None when not on the
/// surface).
type BodyPoints = Vec<Vec<Option<[f32; 3]>>>;

impl Renderer {
    /// Runs the vertex shader's body transform (`body_point` in scene.wgsl) over every body's
    /// mesh vertex buffer and the instance buffer of the last [`Self::prepare`], on the GPU, and
    /// reads the results back: for each body, the world position of each rest vertex that lies
    /// on the surface (None for interior vertices, which are never drawn).
    pub fn gpu_body_points(&self, gpu: &Gpu) -> anyhow::Result<BodyPoints> {
        anyhow::ensure!(self.storage, "this adapter has no compute shaders");
        let pass = BodyPointsPass::new(&gpu.device, &self.pipelines.module);
        let scene = &self.scene;
        let instances = &self.layers[0].instance_buffer.buffer;
        let mut out: BodyPoints = vec![Vec::new(); scene.order.len()];
        for (mesh, range) in scene.meshes.iter().zip(&scene.shape_ranges) {
            if range.is_empty() || mesh.vertex_count == 0 {
                continue;
            }
            let values = pass.run(gpu, mesh, instances, range)?;
            let rest_count = mesh
                .source_vertex
                .iter()
                .copied()
                .max()
                .map_or(0, |m| m as usize + 1);
            let bodies = &scene.order[range.start as usize..range.end as usize];
            for (k, &body) in bodies.iter().enumerate() {
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

/// The `cs_body_points` compute pipeline: mesh (1) and instances (2) in, points (3) out,
/// parameters (4) as a uniform.
struct BodyPointsPass {
    layout: wgpu::BindGroupLayout,
    pipeline: wgpu::ComputePipeline,
}

impl BodyPointsPass {
    fn new(device: &wgpu::Device, module: &wgpu::ShaderModule) -> BodyPointsPass {
        let entry = |binding: u32, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let storage = |read_only| wgpu::BufferBindingType::Storage { read_only };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("body points"),
            entries: &[
                entry(1, storage(true)),
                entry(2, storage(true)),
                entry(3, storage(false)),
                entry(4, wgpu::BufferBindingType::Uniform),
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
            module,
            entry_point: Some("cs_body_points"),
            compilation_options: Default::default(),
            cache: None,
        });
        BodyPointsPass { layout, pipeline }
    }

    /// The world positions (x, y, z per mesh vertex, body after body) of the bodies in
    /// `range` of the draw order, which all have `mesh`'s shape.
    fn run(
        &self,
        gpu: &Gpu,
        mesh: &ShapeMesh,
        instances: &wgpu::Buffer,
        range: &Range<u32>,
    ) -> anyhow::Result<Vec<f32>> {
        let device = &gpu.device;
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
        let resources = [&mesh.buffer, instances, &result, &params];
        let entries: Vec<wgpu::BindGroupEntry> = (1..)
            .zip(resources)
            .map(|(binding, buffer)| wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            })
            .collect();
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("body points"),
            layout: &self.layout,
            entries: &entries,
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups(count.div_ceil(64) as u32, 1, 1);
        }
        encoder.copy_buffer_to_buffer(&result, 0, &readback, 0, size);
        gpu.queue.submit([encoder.finish()]);
        read_mapped(device, readback.slice(..size), |data| {
            bytemuck::cast_slice::<u8, f32>(data).to_vec()
        })
    }
}
