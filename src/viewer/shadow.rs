//! Shadows from the key light: one directional shadow map per drawn world, the bodies' depth seen
//! from the light through an orthographic projection fitted to the scene (bodies and ground),
//! sampled by the scene shader with 3x3 percentage-closer filtering. Bodies render their back
//! faces into the map with a slope-scaled depth bias, and receivers look it up a texel and a half
//! along their normal, which together keep lit faces free of acne.

use super::pipelines::BODY_BUFFERS;
use glam::{DMat4, DVec3};

/// Side of the shadow map in texels.
pub const SHADOW_SIZE: u32 = 2048;
/// Depth format of the shadow map.
pub const SHADOW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Unit direction towards the key light (world space).
pub const LIGHT: DVec3 = DVec3::new(0.45, 0.8, 0.35);

pub fn light_direction() -> DVec3 {
    LIGHT.normalize()
}

/// The light's view-projection for a scene within `lo`..`hi`, and the size of one shadow-map
/// texel in world units.
pub fn light_view_proj(lo: DVec3, hi: DVec3) -> (DMat4, f64) {
    let light = light_direction();
    let centre = (lo + hi) / 2.0;
    let radius = ((hi - lo).length() / 2.0).max(1e-3);
    let view =
        glam::dcamera::rh::view::look_at_mat4(centre + light * 2.0 * radius, centre, DVec3::Y);
    let mut min = DVec3::splat(f64::INFINITY);
    let mut max = DVec3::splat(f64::NEG_INFINITY);
    for k in 0..8 {
        let corner = DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let p = view.transform_point3(corner);
        min = min.min(p);
        max = max.max(p);
    }
    // View space looks down -z: near and far are distances along it, with a margin.
    let margin = 0.01 * radius;
    let proj = glam::dcamera::rh::proj::directx::orthographic(
        min.x,
        max.x,
        min.y,
        max.y,
        (-max.z - margin).max(1e-4),
        -min.z + margin,
    );
    let texel = (max.x - min.x).max(max.y - min.y) / SHADOW_SIZE as f64;
    (proj * view, texel)
}

/// The bind group layout through which the scene's pipelines read a shadow map (group 1).
pub fn bind_group_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("shadow map"),
        entries: &[
            wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Depth,
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            },
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
                count: None,
            },
        ],
    })
}

/// One world's shadow map, its depth view to render into and its bind group to sample it.
pub struct ShadowMap {
    pub view: wgpu::TextureView,
    pub bind_group: wgpu::BindGroup,
}

impl ShadowMap {
    pub fn new(device: &wgpu::Device, layout: &wgpu::BindGroupLayout) -> ShadowMap {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("shadow map"),
            size: wgpu::Extent3d {
                width: SHADOW_SIZE,
                height: SHADOW_SIZE,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: SHADOW_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        // Bilinear comparison: each tap is itself a 2x2 filter.
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("shadow map"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("shadow map"),
            layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
            ],
        });
        ShadowMap { view, bind_group }
    }

    /// The depth pass into this map (cleared to the far plane).
    pub fn begin_pass<'e>(&self, encoder: &'e mut wgpu::CommandEncoder) -> wgpu::RenderPass<'e> {
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shadow map"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }
}

/// The depth-only pipeline drawing bodies from the light: back faces, slope-scaled bias.
pub fn pipeline(
    device: &wgpu::Device,
    module: &wgpu::ShaderModule,
    globals_layout: &wgpu::BindGroupLayout,
) -> wgpu::RenderPipeline {
    let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("shadow map"),
        bind_group_layouts: &[Some(globals_layout)],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("shadow map"),
        layout: Some(&layout),
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_shadow"),
            compilation_options: Default::default(),
            buffers: &BODY_BUFFERS,
        },
        primitive: wgpu::PrimitiveState {
            cull_mode: Some(wgpu::Face::Front),
            front_face: wgpu::FrontFace::Ccw,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: SHADOW_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: Default::default(),
            bias: wgpu::DepthBiasState {
                constant: 2,
                slope_scale: 2.0,
                clamp: 0.0,
            },
        }),
        multisample: Default::default(),
        fragment: None,
        multiview_mask: None,
        cache: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_light_frustum_holds_the_scene() {
        let (lo, hi) = (DVec3::new(-3.0, 0.0, -2.0), DVec3::new(4.0, 9.0, 5.0));
        let (m, texel) = light_view_proj(lo, hi);
        for k in 0..8 {
            let corner = DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            let p = m.project_point3(corner);
            assert!(p.x.abs() <= 1.0 + 1e-9 && p.y.abs() <= 1.0 + 1e-9, "{p}");
            assert!((0.0..=1.0).contains(&p.z), "{p}");
        }
        // Nearer the light is smaller depth.
        let near = m.project_point3(DVec3::new(0.5, 4.5, 1.5) + light_direction());
        let far = m.project_point3(DVec3::new(0.5, 4.5, 1.5));
        assert!(near.z < far.z);
        assert!(texel > 0.0 && texel < 20.0 / SHADOW_SIZE as f64);
    }
}
