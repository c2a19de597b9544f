//! Adapter and device creation, buffer helpers, and offscreen render targets with CPU readback.

use super::targets::DEPTH_FORMAT;
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
        // Running out of memory (a frame of 16384 x 16384 with its multisampled and depth
        // buffers) follows from what was asked, not from a bug: said, and the run ends, where
        // wgpu's default handler panicked. Other errors are bugs and still panic.
        device.on_uncaptured_error(std::sync::Arc::new(|error| match error {
            wgpu::Error::OutOfMemory { .. } => {
                eprintln!(
                    "error: the GPU ran out of memory ({error}); a smaller --size needs less"
                );
                // The exit skips destructors: a recording's partial file is removed here.
                crate::io::atomic_file::remove_unfinished_files();
                std::process::exit(1);
            }
            other => panic!("wgpu error: {other}"),
        }));
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
        if wanted > 1 && ok(color_format, wanted) && ok(DEPTH_FORMAT, wanted) {
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
        crate::io::write_file_atomically(path, |w| self.write_png(w))
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
        let row_bytes = 4 * self.width as usize;
        let mut rgba = read_mapped(device, self.readback.slice(..), |data| {
            // Rows are padded to the copy alignment in the buffer.
            let mut rgba = Vec::with_capacity(row_bytes * self.height as usize);
            for row in 0..self.height as usize {
                let start = row * self.padded_row as usize;
                rgba.extend_from_slice(&data[start..start + row_bytes]);
            }
            rgba
        })?;
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

/// Maps `slice` for reading once the copy into it has been submitted, waits for the GPU, hands
/// the bytes to `read` and unmaps the buffer again (so it can take the next copy).
pub(super) fn read_mapped<R>(
    device: &wgpu::Device,
    slice: wgpu::BufferSlice<'_>,
    read: impl FnOnce(&[u8]) -> R,
) -> anyhow::Result<R> {
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| anyhow::anyhow!("GPU readback failed: {e}"))?;
    rx.recv()?
        .map_err(|e| anyhow::anyhow!("GPU readback failed: {e}"))?;
    let result = {
        let data = slice
            .get_mapped_range()
            .map_err(|e| anyhow::anyhow!("GPU readback failed: {e:?}"))?;
        read(&data)
    };
    slice.buffer().unmap();
    Ok(result)
}

/// A buffer of at least 16 bytes (wgpu rejects empty bindings), not mapped.
pub(super) fn buffer(
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

/// A buffer created with its contents.
pub(super) fn buffer_init(
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

/// A buffer rewritten every frame (instances, lines). It is reallocated only when the data
/// outgrows it, then for the next power of two of the element count, so a growing scene costs
/// few allocations.
pub(super) struct StreamingBuffer {
    pub buffer: wgpu::Buffer,
    label: &'static str,
    usage: wgpu::BufferUsages,
    /// Elements that fit.
    capacity: usize,
}

impl StreamingBuffer {
    pub fn new(device: &wgpu::Device, label: &'static str, usage: wgpu::BufferUsages) -> Self {
        StreamingBuffer {
            buffer: buffer(device, label, 16, usage),
            label,
            usage,
            capacity: 0,
        }
    }

    /// Uploads `items` from the start of the buffer, reallocating it first when they do not fit.
    pub fn write<T: bytemuck::Pod>(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        items: &[T],
    ) {
        if items.len() > self.capacity {
            self.capacity = items.len().next_power_of_two();
            self.buffer = buffer(
                device,
                self.label,
                (self.capacity * std::mem::size_of::<T>()) as u64,
                self.usage,
            );
        }
        if !items.is_empty() {
            queue.write_buffer(&self.buffer, 0, bytemuck::cast_slice(items));
        }
    }

    /// Makes the next non-empty write allocate afresh, sized for its data: a new scene does not
    /// keep the previous one's allocation.
    pub fn reallocate_on_next_write(&mut self) {
        self.capacity = 0;
    }
}

/// A render pass drawing over what `target` already holds (egui, labels).
pub(super) fn overlay_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    target: &wgpu::TextureView,
    label: &str,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Load,
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
