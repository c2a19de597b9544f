//! Adapter and device creation, and offscreen render targets with CPU readback.

use std::fmt;

/// An adapter with its device and queue.
pub struct Gpu {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
}

/// Why no GPU device could be had.
#[derive(Debug)]
pub struct NoGpu(pub String);

impl fmt::Display for NoGpu {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "no usable GPU adapter: {} (a software Vulkan driver works: on Debian/Ubuntu `apt-get install mesa-vulkan-drivers`)",
            self.0
        )
    }
}

impl std::error::Error for NoGpu {}

impl Gpu {
    /// A device for offscreen rendering (no window). Honours `WGPU_BACKEND` and the other wgpu
    /// environment variables.
    pub fn headless() -> Result<Gpu, NoGpu> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        Self::with_instance(instance, None)
    }

    /// A device on `instance` able to present to `surface` when given.
    pub fn with_instance(
        instance: wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Gpu, NoGpu> {
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: surface,
            ..Default::default()
        };
        let adapter = pollster::block_on(instance.request_adapter(&options))
            .map_err(|e| NoGpu(e.to_string()))?;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("tumble"),
            required_features: wgpu::Features::empty(),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| {
            NoGpu(format!(
                "cannot open a device on {}: {e}",
                adapter.get_info().name
            ))
        })?;
        Ok(Gpu {
            instance,
            adapter,
            device,
            queue,
        })
    }

    /// "llvmpipe (LLVM 15.0.6, 256 bits) / Vulkan", for display.
    pub fn description(&self) -> String {
        let info = self.adapter.get_info();
        format!("{} / {:?}", info.name, info.backend)
    }

    /// 4 when both the colour format and the depth format support 4x MSAA, else 1.
    /// `TUMBLE_MSAA=1` (or 2, 4, 8) overrides it where supported.
    pub fn sample_count(&self, color_format: wgpu::TextureFormat) -> u32 {
        let ok = |format: wgpu::TextureFormat, n: u32| {
            self.adapter
                .get_texture_format_features(format)
                .flags
                .sample_count_supported(n)
        };
        let wanted = std::env::var("TUMBLE_MSAA")
            .ok()
            .and_then(|v| v.trim().parse::<u32>().ok())
            .unwrap_or(4);
        if wanted > 1 && ok(color_format, wanted) && ok(super::renderer::DEPTH_FORMAT, wanted) {
            wanted
        } else {
            1
        }
    }

    /// Whether compute shaders with storage buffers are available (not on old GL).
    pub fn has_compute(&self) -> bool {
        self.adapter
            .get_downlevel_capabilities()
            .flags
            .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS)
            && self.device.limits().max_storage_buffers_per_shader_stage >= 3
    }
}

/// An RGBA8 image, rows top to bottom, no padding.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

impl Image {
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = 4 * (y as usize * self.width as usize + x as usize);
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// The rectangle `[x, x+w) x [y, y+h)`, clamped to the image.
    pub fn crop(&self, x: u32, y: u32, w: u32, h: u32) -> Image {
        let x = x.min(self.width);
        let y = y.min(self.height);
        let w = w.min(self.width - x);
        let h = h.min(self.height - y);
        let mut rgba = Vec::with_capacity(4 * (w * h) as usize);
        for row in y..y + h {
            let start = 4 * (row as usize * self.width as usize + x as usize);
            rgba.extend_from_slice(&self.rgba[start..start + 4 * w as usize]);
        }
        Image {
            width: w,
            height: h,
            rgba,
        }
    }

    /// Writes a PNG.
    pub fn write_png(&self, writer: impl std::io::Write) -> std::io::Result<()> {
        let mut encoder = png::Encoder::new(writer, self.width, self.height);
        encoder.set_color(png::ColorType::Rgba);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_compression(png::Compression::Fast);
        let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
        writer
            .write_image_data(&self.rgba)
            .map_err(std::io::Error::other)?;
        writer.finish().map_err(std::io::Error::other)
    }

    /// Writes a PNG through a temporary file renamed into place.
    pub fn save_png(&self, path: &std::path::Path) -> anyhow::Result<()> {
        super::record::write_file_atomically(path, |w| self.write_png(w))
    }
}

/// A colour texture that can be rendered to and read back.
pub struct Offscreen {
    pub texture: wgpu::Texture,
    pub view: wgpu::TextureView,
    /// The same texels seen as the sRGB variant of `format` (what the scene renderer draws
    /// into); equal to `view` when `format` is already sRGB.
    pub srgb_view: wgpu::TextureView,
    pub width: u32,
    pub height: u32,
    pub format: wgpu::TextureFormat,
    readback: wgpu::Buffer,
    padded_row: u32,
}

impl Offscreen {
    pub fn new(
        device: &wgpu::Device,
        width: u32,
        height: u32,
        format: wgpu::TextureFormat,
    ) -> Offscreen {
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("offscreen colour"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::COPY_DST,
            view_formats: &[format.add_srgb_suffix()],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        let srgb_view = texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(format.add_srgb_suffix()),
            ..Default::default()
        });
        let padded_row = (4 * width).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("offscreen readback"),
            size: padded_row as u64 * height as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Offscreen {
            texture,
            view,
            srgb_view,
            width,
            height,
            format,
            readback,
            padded_row,
        }
    }

    /// Records the copy of the texture into the readback buffer.
    pub fn copy_to_buffer(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.copy_texture_to_buffer(
            self.texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Maps the readback buffer (after a submitted [`Self::copy_to_buffer`]) and returns RGBA.
    pub fn read(&self, device: &wgpu::Device) -> anyhow::Result<Image> {
        let slice = self.readback.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow::anyhow!("GPU readback failed: {e}"))?;
        rx.recv()?
            .map_err(|e| anyhow::anyhow!("GPU readback failed: {e}"))?;
        let mut rgba = Vec::with_capacity(4 * (self.width * self.height) as usize);
        {
            let data = slice
                .get_mapped_range()
                .map_err(|e| anyhow::anyhow!("GPU readback failed: {e:?}"))?;
            for row in 0..self.height as usize {
                let start = row * self.padded_row as usize;
                rgba.extend_from_slice(&data[start..start + 4 * self.width as usize]);
            }
        }
        self.readback.unmap();
        if matches!(
            self.format,
            wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
        ) {
            for px in rgba.chunks_exact_mut(4) {
                px.swap(0, 2);
            }
        }
        Ok(Image {
            width: self.width,
            height: self.height,
            rgba,
        })
    }
}
