//! Renderer: meshes drawn through their texture (per pixel, mipmapped, sRGB-correct) or their
//! vertex colours, with hard edges where the surface is sharp, headlight Lambert shading and
//! optional wireframe, drawn with wgpu into offscreen targets. The app shows those targets in its viewports; the CLI's
//! `render` command reads them back to PNG through the same code ([`render_image`]).

pub mod camera;
pub mod draw_mesh;
pub mod gpu;

use std::path::Path;
use std::sync::{Arc, OnceLock};

use eframe::wgpu;

pub use camera::{Camera, FOV_Y_DEG, Frame, Hit, fov_y, pick};
pub use draw_mesh::{DrawMesh, SHARP_ANGLE_DEG, draw_mesh};
pub use gpu::{
    DrawStyle, GpuMesh, MarkerInstance, MeshRenderer, PaintSlot, RenderTarget, display_colors,
    has_texture,
};

use crate::error::{Error, Result};
use crate::mesh::TriMesh;

/// Options of an offscreen render.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderOptions {
    /// Camera rotation about the vertical axis, degrees (0 = seen from +Z).
    pub azimuth_deg: f32,
    /// Camera elevation above the horizontal plane, degrees.
    pub elevation_deg: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Draw triangle edges.
    pub wireframe: bool,
    /// Marker spheres to draw with the mesh (hidden ones faint).
    pub markers: Vec<MarkerInstance>,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            azimuth_deg: 30.0,
            elevation_deg: 15.0,
            width: 800,
            height: 600,
            wireframe: false,
            markers: Vec::new(),
        }
    }
}

/// A wgpu device for rendering without a window (any backend, software fallback allowed).
pub struct Headless {
    /// The adapter in use.
    pub adapter: wgpu::Adapter,
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The mesh pipelines for this device.
    pub renderer: MeshRenderer,
}

impl Headless {
    /// Open a device: a hardware adapter if there is one, else a fallback (e.g. lavapipe).
    pub fn new() -> Result<Self> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::all();
        let instance = wgpu::Instance::new(desc);
        let mut last_err = String::from("no adapter");
        let mut adapter = None;
        for fallback in [false, true] {
            match pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: fallback,
                compatible_surface: None,
                apply_limit_buckets: false,
            })) {
                Ok(a) => {
                    adapter = Some(a);
                    break;
                }
                Err(e) => last_err = e.to_string(),
            }
        }
        let adapter = adapter.ok_or_else(|| {
            Error::InvalidInput(format!(
                "no GPU adapter for offscreen rendering: {last_err}"
            ))
        })?;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("meshmatch headless"),
            required_limits: wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()),
            ..Default::default()
        }))
        .map_err(|e| Error::InvalidInput(format!("cannot open GPU device: {e}")))?;
        let renderer = MeshRenderer::new(&device, Some(&adapter), 4);
        Ok(Headless {
            adapter,
            device,
            queue,
            renderer,
        })
    }

    /// The process-wide headless device, opened on first use.
    pub fn shared() -> Result<Arc<Headless>> {
        static SHARED: OnceLock<std::result::Result<Arc<Headless>, String>> = OnceLock::new();
        SHARED
            .get_or_init(|| Headless::new().map(Arc::new).map_err(|e| e.to_string()))
            .clone()
            .map_err(Error::InvalidInput)
    }

    /// Render `mesh` with `colors` (or its own signal) and read the pixels back.
    pub fn render(
        &self,
        mesh: &TriMesh,
        colors: Option<&[[f32; 3]]>,
        opts: &RenderOptions,
    ) -> Result<image::RgbaImage> {
        if opts.width == 0 || opts.height == 0 || opts.width > 8192 || opts.height > 8192 {
            return Err(Error::InvalidInput(format!(
                "image size {}x{} must be within 1..=8192",
                opts.width, opts.height
            )));
        }
        if let Some(c) = colors
            && c.len() != mesh.positions.len()
        {
            return Err(Error::InvalidInput(format!(
                "{} colours for {} vertices",
                c.len(),
                mesh.positions.len()
            )));
        }
        let cols = display_colors(mesh, colors);
        // The mesh's own signal: its texture per pixel when it has one.
        let textured = colors.is_none() && has_texture(mesh);
        let mut gpu_mesh = GpuMesh::new(
            &self.device,
            &self.queue,
            &self.renderer,
            mesh,
            &cols,
            textured,
        );
        gpu_mesh.set_markers(&self.device, &self.queue, &opts.markers);
        let target = RenderTarget::new(&self.device, &self.renderer, opts.width, opts.height);
        let camera = Camera {
            azimuth_deg: opts.azimuth_deg,
            elevation_deg: opts.elevation_deg,
            zoom: 1.0,
            pan: [0.0, 0.0],
        };
        let style = DrawStyle {
            wireframe: opts.wireframe,
            ..DrawStyle::default()
        };
        let mut enc = self.device.create_command_encoder(&Default::default());
        self.renderer.draw(
            &self.queue,
            &mut enc,
            &target,
            Some(&gpu_mesh),
            &camera,
            &style,
        );
        self.queue.submit([enc.finish()]);
        let rgba = target.read_rgba(&self.device, &self.queue)?;
        image::RgbaImage::from_raw(target.width, target.height, rgba)
            .ok_or_else(|| Error::InvalidInput("readback size mismatch".into()))
    }
}

/// Render `mesh` offscreen (colours: `colors`, else the mesh's own colours/texture, else grey)
/// and return the image. Works without a display (software adapters such as lavapipe).
pub fn render_image(
    mesh: &TriMesh,
    colors: Option<&[[f32; 3]]>,
    opts: &RenderOptions,
) -> Result<image::RgbaImage> {
    if mesh.positions.is_empty() || mesh.faces.is_empty() {
        return Err(Error::InvalidMesh(
            "nothing to render: mesh has no faces".into(),
        ));
    }
    Headless::shared()?.render(mesh, colors, opts)
}

/// Render `mesh` offscreen like [`render_image`] and write the image as PNG to `out`.
pub fn render_to_png(
    mesh: &TriMesh,
    colors: Option<&[[f32; 3]]>,
    opts: &RenderOptions,
    out: &Path,
) -> Result<()> {
    let img = render_image(mesh, colors, opts)?;
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::format(out, format!("PNG encoding failed: {e}")))?;
    crate::mesh::io::write_atomic(out, &bytes)
}

/// Distinct marker colour for correspondence `i` (golden-angle hues), the same in the app and in `render`.
pub fn marker_color(i: usize) -> [u8; 3] {
    let h = (i as f32 * 0.618_034).fract();
    let s = 0.75f32;
    let v = 0.95f32;
    let k = |n: f32| {
        let k = (n + h * 6.0) % 6.0;
        v - v * s * k.min(4.0 - k).clamp(0.0, 1.0)
    };
    [k(5.0), k(3.0), k(1.0)].map(|x| (x * 255.0).round() as u8)
}
