//! One drawn world's data for a frame: its bodies' poses as instances, its lines (constraints,
//! selection outline, grab, contacts), and its shadow map. The renderer keeps one layer per
//! world it shows, so compared worlds share the scene's meshes but not their poses or shadows.

use super::gpu::StreamingBuffer;
use super::overlay::{self, with_alpha};
use super::palette;
use super::pipelines::{InstanceData, LineVertex, ScenePipelines};
use super::renderer::{DrawOptions, SceneData};
use super::shadow::ShadowMap;
use crate::World;
use glam::DVec3;

pub(super) struct Layer {
    pub(super) instances: Vec<InstanceData>,
    pub(super) instance_buffer: StreamingBuffer,
    lines: Vec<LineVertex>,
    line_buffer: StreamingBuffer,
    /// Lines from this index on are drawn without depth test.
    overlay_start: u32,
    pub(super) shadow: ShadowMap,
}

impl Layer {
    pub(super) fn new(device: &wgpu::Device, pipelines: &ScenePipelines, storage: bool) -> Layer {
        Layer {
            instances: Vec::new(),
            instance_buffer: StreamingBuffer::new(device, "instances", vertex_usage(storage)),
            lines: Vec::new(),
            line_buffer: StreamingBuffer::new(
                device,
                "lines",
                wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            ),
            overlay_start: 0,
            shadow: ShadowMap::new(device, &pipelines.shadow_layout),
        }
    }

    /// Builds and uploads the instances and lines of `world` seen from `eye`.
    pub(super) fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        world: &World,
        scene: &SceneData,
        eye: DVec3,
        options: &DrawOptions,
    ) {
        self.build_instances(world, scene, options);
        self.instance_buffer.write(device, queue, &self.instances);
        self.build_lines(world, scene, eye, options);
        self.line_buffer.write(device, queue, &self.lines);
    }

    /// A new scene: the next upload allocates afresh for its size.
    pub(super) fn forget_sizes(&mut self) {
        self.instance_buffer.reallocate_on_next_write();
    }

    /// One instance per body in draw order: pose in f32, palette colour (the quarantine colour,
    /// dimmed when asleep), and the highlight flag of the selected body. A hidden fixed body
    /// keeps its instance (the shapes' instance ranges stay as they are) with a zero rotation,
    /// which the shaders' `rotate` turns into no area at all: drawn nowhere, casting no shadow,
    /// never picked.
    fn build_instances(&mut self, world: &World, scene: &SceneData, options: &DrawOptions) {
        self.instances.clear();
        for &index in &scene.order {
            let body = &world.bodies[index as usize];
            let hidden = body.fixed && !options.fixed_bodies;
            let q = match hidden {
                true => glam::Quat::from_xyzw(0.0, 0.0, 0.0, 0.0),
                false => body.orientation.as_quat(),
            };
            let p = body.position.as_vec3();
            let color = if body.quarantined {
                palette::linear(palette::QUARANTINED_SRGB)
            } else if body.asleep {
                palette::asleep(scene.base_colors[index as usize])
            } else {
                scene.base_colors[index as usize]
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
    }

    /// This frame's lines: the depth-tested ones (constraints, selection outline), then from
    /// `overlay_start` those drawn over everything (the grab, contact markers).
    fn build_lines(&mut self, world: &World, scene: &SceneData, eye: DVec3, options: &DrawOptions) {
        self.lines.clear();
        if options.constraints {
            overlay::constraint_segments(&mut self.lines, world, &scene.constraint_groups);
        }
        let shown = |i: usize| options.fixed_bodies || !world.bodies[i].fixed;
        if let Some(index) = (options.selected).filter(|&i| i < world.bodies.len() && shown(i)) {
            overlay::selection_outline(&mut self.lines, world, index, eye);
        }
        self.overlay_start = self.lines.len() as u32;
        overlay::grab_line(&mut self.lines, world, scene.scale);
        if options.contacts {
            overlay::contact_markers(&mut self.lines, world, scene.scale);
        }
    }

    /// The bodies, one instanced draw per shape, with the pipeline already set.
    pub(super) fn draw_bodies(&self, pass: &mut wgpu::RenderPass<'_>, scene: &SceneData) {
        if self.instances.is_empty() {
            return;
        }
        pass.set_vertex_buffer(1, self.instance_buffer.buffer.slice(..));
        for (mesh, range) in scene.meshes.iter().zip(&scene.shape_ranges) {
            if range.is_empty() || mesh.vertex_count == 0 {
                continue;
            }
            pass.set_vertex_buffer(0, mesh.buffer.slice(..));
            pass.draw(0..mesh.vertex_count, range.clone());
        }
    }

    /// The depth-tested lines, then the overlay lines.
    pub(super) fn draw_lines(&self, pass: &mut wgpu::RenderPass<'_>, pipelines: &ScenePipelines) {
        let line_count = self.lines.len() as u32;
        if line_count == 0 {
            return;
        }
        pass.set_vertex_buffer(0, self.line_buffer.buffer.slice(..));
        if self.overlay_start > 0 {
            pass.set_pipeline(&pipelines.lines);
            pass.draw(0..self.overlay_start, 0..1);
        }
        if line_count > self.overlay_start {
            pass.set_pipeline(&pipelines.overlay);
            pass.draw(self.overlay_start..line_count, 0..1);
        }
    }

    /// Renders the bodies' depth from the light into the layer's shadow map.
    pub(super) fn draw_shadow(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        pipelines: &ScenePipelines,
        scene: &SceneData,
    ) {
        let mut pass = self.shadow.begin_pass(encoder);
        pass.set_pipeline(&pipelines.shadow);
        pass.set_bind_group(0, &pipelines.globals_bind_group, &[]);
        self.draw_bodies(&mut pass, scene);
    }
}

/// Usage of the mesh and instance buffers: storage too where the readback can bind them.
pub(super) fn vertex_usage(storage: bool) -> wgpu::BufferUsages {
    wgpu::BufferUsages::VERTEX
        | wgpu::BufferUsages::COPY_DST
        | if storage {
            wgpu::BufferUsages::STORAGE
        } else {
            wgpu::BufferUsages::empty()
        }
}
