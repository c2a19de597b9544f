//! The attachments the scene pass needs besides its colour target: the depth buffer and, with
//! MSAA, the multisampled colour buffer resolved into the target. A module of its own so that
//! device setup ([`super::gpu`]) and the pipelines can share [`DEPTH_FORMAT`] without depending on
//! the renderer.

/// Depth format of the scene pass; also what MSAA support is checked against.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Depth and MSAA attachments sized for one colour target.
pub struct SceneAttachments {
    pub width: u32,
    pub height: u32,
    /// Multisampled colour, resolved into the target (None without MSAA).
    pub msaa: Option<wgpu::TextureView>,
    pub depth: wgpu::TextureView,
}

impl SceneAttachments {
    pub fn new(
        device: &wgpu::Device,
        width: u32,
        height: u32,
        sample_count: u32,
        color_format: wgpu::TextureFormat,
    ) -> SceneAttachments {
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
                    sample_count,
                    dimension: wgpu::TextureDimension::D2,
                    format,
                    usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                    view_formats: &[],
                })
                .create_view(&wgpu::TextureViewDescriptor::default())
        };
        let msaa = (sample_count > 1).then(|| texture("msaa colour", color_format));
        let depth = texture("depth", DEPTH_FORMAT);
        SceneAttachments {
            width,
            height,
            msaa,
            depth,
        }
    }

    pub fn fits(&self, width: u32, height: u32) -> bool {
        self.width == width && self.height == height
    }
}
