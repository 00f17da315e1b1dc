//! GPU side of the renderer: pipelines, per-mesh buffers and offscreen targets (wgpu via eframe).

use eframe::wgpu;
use eframe::wgpu::util::DeviceExt;

use super::camera::{Camera, Frame};
use crate::mesh::TriMesh;

/// Colour format of every render target's texture: gamma-encoded RGBA8, which egui samples as-is.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// Format the pipelines draw in: the same bytes seen as sRGB, so the shaders work in linear light
/// and the store encodes (no per-fragment `pow`: cheap on software rasterisers).
pub const DRAW_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Depth format of every render target.
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Colour of vertices that have no colour (light grey, sRGB).
pub const DEFAULT_VERTEX_COLOR: [f32; 3] = [0.75, 0.75, 0.75];

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Uniforms {
    view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    wire: [f32; 4],
    layers: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    uv: [f32; 2],
}

/// One correspondence marker, drawn as a shaded sphere that the mesh can hide.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MarkerInstance {
    /// Sphere centre (world space).
    pub center: [f32; 3],
    /// Sphere radius (world units).
    pub radius: f32,
    /// Fill colour (sRGB).
    pub color: [f32; 3],
    /// Rim: 0 none, 1 selected (white), 2 waiting for its partner (yellow).
    pub rim: f32,
}

/// How to draw one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrawStyle {
    /// Draw the triangle edges over the shaded surface.
    pub wireframe: bool,
    /// Background colour (sRGB, straight alpha).
    pub background: [f32; 4],
    /// Ambient fraction of the headlight shading in [0, 1].
    pub ambient: f32,
}

impl Default for DrawStyle {
    fn default() -> Self {
        DrawStyle {
            wireframe: false,
            background: [0.16, 0.17, 0.19, 1.0],
            ambient: 0.25,
        }
    }
}

/// The mesh pipelines for one device (shaded triangles, wireframe lines, marker spheres).
pub struct MeshRenderer {
    fill: wgpu::RenderPipeline,
    wire: wgpu::RenderPipeline,
    /// Marker spheres where they are in front of the mesh (depth-tested).
    marker: wgpu::RenderPipeline,
    /// Faint marker spheres where the mesh hides them (depth test reversed, blended).
    marker_ghost: wgpu::RenderPipeline,
    sphere_vertices: wgpu::Buffer,
    sphere_indices: wgpu::Buffer,
    sphere_index_count: u32,
    layout: wgpu::BindGroupLayout,
    texture_layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    /// MSAA sample count used by targets made for this renderer.
    pub samples: u32,
}

impl MeshRenderer {
    /// Build the pipelines; `samples` is the MSAA count (1 or 4; falls back to 1 if unsupported).
    ///
    /// The parts: [`supported_samples`], the shader, [`uniform_layout`], [`texture_layout`],
    /// [`base_sampler`], the four pipelines through [`PipelineParts::pipeline`] (shaded
    /// triangles, blended wireframe, markers in front and hidden), and [`marker_sphere`].
    pub fn new(device: &wgpu::Device, adapter: Option<&wgpu::Adapter>, samples: u32) -> Self {
        let samples = supported_samples(adapter, samples);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("meshmatch mesh shader"),
            source: wgpu::ShaderSource::Wgsl(include_str!("../../shaders/mesh.wgsl").into()),
        });
        let layout = uniform_layout(device);
        let texture_layout = texture_layout(device);
        let sampler = base_sampler(device);
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("meshmatch pipeline layout"),
            bind_group_layouts: &[Some(&layout), Some(&texture_layout)],
            immediate_size: 0,
        });
        let parts = PipelineParts {
            device,
            module: &module,
            layout: &pipeline_layout,
            samples,
        };
        let buffers = mesh_buffers();
        let marker_buffers = marker_buffers();
        let opaque = (true, wgpu::CompareFunction::LessEqual, None);
        let tri = wgpu::PrimitiveTopology::TriangleList;
        let fill = parts.pipeline("vs_main", "fs_main", tri, &buffers, opaque);
        // Blended, so a dense mesh's wireframe darkens its surface instead of hiding it.
        let wire = parts.pipeline(
            "vs_wire",
            "fs_wire",
            wgpu::PrimitiveTopology::LineList,
            &buffers,
            (
                true,
                wgpu::CompareFunction::LessEqual,
                Some(wgpu::BlendState::ALPHA_BLENDING),
            ),
        );
        let marker = parts.pipeline("vs_marker", "fs_marker", tri, &marker_buffers, opaque);
        let marker_ghost = parts.pipeline(
            "vs_marker",
            "fs_marker_ghost",
            tri,
            &marker_buffers,
            (
                false,
                wgpu::CompareFunction::Greater,
                Some(wgpu::BlendState::ALPHA_BLENDING),
            ),
        );
        let (sphere_vertices, sphere_indices, sphere_index_count) = marker_sphere(device);
        MeshRenderer {
            fill,
            wire,
            marker,
            marker_ghost,
            sphere_vertices,
            sphere_indices,
            sphere_index_count,
            layout,
            texture_layout,
            sampler,
            samples,
        }
    }

    /// Encode a frame: clear `target`, draw `mesh` seen by `camera`.
    pub fn draw(
        &self,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        target: &RenderTarget,
        mesh: Option<&GpuMesh>,
        camera: &Camera,
        style: &DrawStyle,
    ) {
        if let Some(mesh) = mesh {
            let aspect = target.width as f32 / target.height.max(1) as f32;
            let vp = camera.view_proj(&mesh.frame, aspect);
            let (eye, _) = camera.eye_target(&mesh.frame);
            let u = Uniforms {
                view_proj: vp.to_cols_array_2d(),
                eye: [eye.x, eye.y, eye.z, 2e-4],
                wire: [0.05, 0.05, 0.05, style.ambient],
                layers: mesh.layers,
            };
            queue.write_buffer(&mesh.uniforms, 0, bytemuck::bytes_of(&u));
        }
        let bg = style.background;
        let (view, resolve) = match &target.msaa {
            Some(m) => (m, Some(&target.draw_view)),
            None => (&target.draw_view, None),
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("meshmatch pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target: resolve,
                ops: wgpu::Operations {
                    // The view is sRGB: clear with the background's linear value.
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: crate::color::srgb_to_linear(bg[0]) as f64,
                        g: crate::color::srgb_to_linear(bg[1]) as f64,
                        b: crate::color::srgb_to_linear(bg[2]) as f64,
                        a: bg[3] as f64,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &target.depth,
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
        let Some(mesh) = mesh else { return };
        pass.set_bind_group(0, &mesh.bind_group, &[]);
        let tex = match (&mesh.texture_group, mesh.textured) {
            (Some(t), true) => t,
            _ => &mesh.white_group,
        };
        pass.set_bind_group(1, tex, &[]);
        pass.set_vertex_buffer(0, mesh.vertices.slice(..));
        pass.set_vertex_buffer(1, mesh.colors.slice(..));
        pass.set_pipeline(&self.fill);
        pass.set_index_buffer(mesh.indices.slice(..), wgpu::IndexFormat::Uint32);
        pass.draw_indexed(0..mesh.index_count, 0, 0..1);
        if style.wireframe && mesh.edge_count > 0 {
            pass.set_pipeline(&self.wire);
            pass.set_index_buffer(mesh.edges.slice(..), wgpu::IndexFormat::Uint32);
            pass.draw_indexed(0..mesh.edge_count, 0, 0..1);
        }
        if mesh.marker_count > 0
            && let Some(instances) = &mesh.markers
        {
            // Hidden parts first, faint; then the visible spheres over them.
            pass.set_vertex_buffer(0, self.sphere_vertices.slice(..));
            pass.set_vertex_buffer(1, instances.slice(..));
            pass.set_index_buffer(self.sphere_indices.slice(..), wgpu::IndexFormat::Uint32);
            for pipeline in [&self.marker_ghost, &self.marker] {
                pass.set_pipeline(pipeline);
                pass.draw_indexed(0..self.sphere_index_count, 0, 0..mesh.marker_count);
            }
        }
    }
}

/// `samples` where the adapter supports it for both the colour and the depth format, else 1.
fn supported_samples(adapter: Option<&wgpu::Adapter>, samples: u32) -> u32 {
    match adapter {
        Some(a) => {
            let c = a.get_texture_format_features(DRAW_FORMAT).flags;
            let d = a.get_texture_format_features(DEPTH_FORMAT).flags;
            if samples > 1 && c.sample_count_supported(samples) && d.sample_count_supported(samples)
            {
                samples
            } else {
                1
            }
        }
        None => 1,
    }
}

/// Bind group 0: the frame's uniforms.
fn uniform_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("meshmatch uniforms"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }],
    })
}

/// Bind group 1: the base texture and its sampler, the paint and the mask over it.
fn texture_layout(device: &wgpu::Device) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("meshmatch base texture"),
        entries: &[
            fragment_texture(0),
            wgpu::BindGroupLayoutEntry {
                binding: 1,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                count: None,
            },
            // Paint over the base, through the same UVs (read texel by texel).
            fragment_texture(2),
            // The mask over the paint, the same way.
            fragment_texture(3),
        ],
    })
}

/// The base texture's sampler: trilinear, repeating (UVs outside [0, 1] tile, as OBJ and glTF
/// expect).
fn base_sampler(device: &wgpu::Device) -> wgpu::Sampler {
    device.create_sampler(&wgpu::SamplerDescriptor {
        label: Some("meshmatch base sampler"),
        address_mode_u: wgpu::AddressMode::Repeat,
        address_mode_v: wgpu::AddressMode::Repeat,
        mag_filter: wgpu::FilterMode::Linear,
        min_filter: wgpu::FilterMode::Linear,
        mipmap_filter: wgpu::MipmapFilterMode::Linear,
        ..Default::default()
    })
}

/// Mesh vertex attributes: position, normal, UV.
const MESH_ATTRIBUTES: [wgpu::VertexAttribute; 3] =
    wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3, 3 => Float32x2];
/// Per-vertex colour attribute (its own buffer).
const COLOR_ATTRIBUTES: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![2 => Float32x3];
/// Marker sphere vertex attribute: position.
const SPHERE_ATTRIBUTES: [wgpu::VertexAttribute; 1] = wgpu::vertex_attr_array![0 => Float32x3];
/// Marker instance attributes: centre and radius, colour and rim.
const MARKER_ATTRIBUTES: [wgpu::VertexAttribute; 2] =
    wgpu::vertex_attr_array![1 => Float32x4, 2 => Float32x4];

/// Vertex buffers of a mesh: vertices, and colours in a buffer of their own.
fn mesh_buffers() -> [Option<wgpu::VertexBufferLayout<'static>>; 2] {
    [
        Some(wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<Vertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &MESH_ATTRIBUTES,
        }),
        Some(wgpu::VertexBufferLayout {
            array_stride: 12,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &COLOR_ATTRIBUTES,
        }),
    ]
}

/// Vertex buffers of the markers: the unit sphere's vertices and one instance per marker.
fn marker_buffers() -> [Option<wgpu::VertexBufferLayout<'static>>; 2] {
    [
        Some(wgpu::VertexBufferLayout {
            array_stride: 12,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &SPHERE_ATTRIBUTES,
        }),
        Some(wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<MarkerInstance>() as u64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &MARKER_ATTRIBUTES,
        }),
    ]
}

/// What every pipeline of the renderer shares.
struct PipelineParts<'a> {
    device: &'a wgpu::Device,
    module: &'a wgpu::ShaderModule,
    layout: &'a wgpu::PipelineLayout,
    samples: u32,
}

impl PipelineParts<'_> {
    /// A pipeline from entry points `vs` and `fs` (its label), drawing `topology` from `buffers`
    /// with depth writes, depth comparison and blending as given.
    fn pipeline(
        &self,
        vs: &str,
        fs: &str,
        topology: wgpu::PrimitiveTopology,
        buffers: &[Option<wgpu::VertexBufferLayout>],
        (depth_write, compare, blend): (bool, wgpu::CompareFunction, Option<wgpu::BlendState>),
    ) -> wgpu::RenderPipeline {
        self.device
            .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(fs),
                layout: Some(self.layout),
                vertex: wgpu::VertexState {
                    module: self.module,
                    entry_point: Some(vs),
                    buffers,
                    compilation_options: Default::default(),
                },
                primitive: wgpu::PrimitiveState {
                    topology,
                    cull_mode: None,
                    ..Default::default()
                },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(depth_write),
                    depth_compare: Some(compare),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: wgpu::MultisampleState {
                    count: self.samples,
                    mask: !0,
                    alpha_to_coverage_enabled: false,
                },
                fragment: Some(wgpu::FragmentState {
                    module: self.module,
                    entry_point: Some(fs),
                    targets: &[Some(wgpu::ColorTargetState {
                        format: DRAW_FORMAT,
                        blend,
                        write_mask: wgpu::ColorWrites::ALL,
                    })],
                    compilation_options: Default::default(),
                }),
                multiview_mask: None,
                cache: None,
            })
    }
}

/// The marker sphere's vertex and index buffers and its index count.
fn marker_sphere(device: &wgpu::Device) -> (wgpu::Buffer, wgpu::Buffer, u32) {
    let (sphere_positions, sphere_tris) = unit_sphere(12, 20);
    let vertices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("marker sphere vertices"),
        contents: bytemuck::cast_slice(&sphere_positions),
        usage: wgpu::BufferUsages::VERTEX,
    });
    let indices = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("marker sphere triangles"),
        contents: bytemuck::cast_slice(&sphere_tris),
        usage: wgpu::BufferUsages::INDEX,
    });
    (vertices, indices, sphere_tris.len() as u32)
}

/// A unit UV sphere with `rings` latitude bands and `segments` longitude segments: positions
/// (which are also the normals) and triangles.
fn unit_sphere(rings: u32, segments: u32) -> (Vec<[f32; 3]>, Vec<u32>) {
    let mut positions = Vec::with_capacity(((rings + 1) * (segments + 1)) as usize);
    for r in 0..=rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..=segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            positions.push([
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ]);
        }
    }
    let row = segments + 1;
    let mut tris = Vec::with_capacity((rings * segments * 6) as usize);
    for r in 0..rings {
        for s in 0..segments {
            let a = r * row + s;
            let b = a + row;
            tris.extend_from_slice(&[a, b, a + 1, a + 1, b, b + 1]);
        }
    }
    (positions, tris)
}

/// Smooth per-vertex normals (area-weighted sum of face normals).
pub fn vertex_normals(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let mut n = vec![glam::Vec3::ZERO; positions.len()];
    for f in faces {
        let idx = [f[0] as usize, f[1] as usize, f[2] as usize];
        if idx.iter().any(|&i| i >= positions.len()) {
            continue;
        }
        let a = glam::Vec3::from(positions[idx[0]]);
        let b = glam::Vec3::from(positions[idx[1]]);
        let c = glam::Vec3::from(positions[idx[2]]);
        let fnrm = (b - a).cross(c - a);
        if fnrm.is_finite() {
            for &i in &idx {
                n[i] += fnrm;
            }
        }
    }
    n.into_iter()
        .map(|v| v.normalize_or_zero().to_array())
        .collect()
}

/// The colours to draw for a mesh: explicit colours, else the mesh's own signal, else grey.
pub fn display_colors(mesh: &TriMesh, colors: Option<&[[f32; 3]]>) -> Vec<[f32; 3]> {
    let n = mesh.positions.len();
    let src = match colors {
        Some(c) => Some(c.to_vec()),
        None => mesh.vertex_signal(),
    };
    let mut out = src.unwrap_or_default();
    out.resize(n, DEFAULT_VERTEX_COLOR);
    for c in &mut out {
        for x in c.iter_mut() {
            *x = if x.is_finite() {
                x.clamp(0.0, 1.0)
            } else {
                0.0
            };
        }
    }
    out
}

/// A mesh uploaded to the GPU: drawn vertices (split at sharp edges and UV seams, see
/// [`super::draw_mesh`]), colours (rewritable), triangles, edges and, for a textured mesh, its
/// texture with mipmaps.
pub struct GpuMesh {
    vertices: wgpu::Buffer,
    colors: wgpu::Buffer,
    indices: wgpu::Buffer,
    edges: wgpu::Buffer,
    uniforms: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// A 1x1 white texture: vertex colours alone.
    white_group: wgpu::BindGroup,
    /// The mesh's own texture, if it has one with UVs.
    texture_group: Option<wgpu::BindGroup>,
    /// Views the groups are made of: white, the mesh's texture, and the paint and mask layers
    /// (a 1x1 transparent texture where there is none).
    white_view: wgpu::TextureView,
    base_view: Option<wgpu::TextureView>,
    paint: [Option<PaintTexture>; 2],
    no_paint_view: wgpu::TextureView,
    /// Weights of the result, the paint layer and the mask layer (see [`Self::set_layers`]).
    layers: [f32; 4],
    /// Whether the texture is drawn (else the vertex colours).
    textured: bool,
    /// Mesh vertex of every drawn vertex.
    draw_vertex: Vec<u32>,
    index_count: u32,
    edge_count: u32,
    vertex_count: usize,
    /// Marker instances (grown on demand) and how many to draw.
    markers: Option<wgpu::Buffer>,
    marker_count: u32,
    /// Bounding sphere of the mesh (the camera frames it).
    pub frame: Frame,
}

/// A texel layer on the GPU: its texture, a view of it and its size.
struct PaintTexture {
    texture: wgpu::Texture,
    view: wgpu::TextureView,
    width: u32,
    height: u32,
}

/// Which texel layer [`GpuMesh::write_paint`] and its kin address.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PaintSlot {
    /// The paint layer.
    Paint = 0,
    /// The mask layer, drawn over the paint.
    Mask = 1,
}

/// Whether `mesh` can be drawn through its texture (a texture and per-corner UVs).
pub fn has_texture(mesh: &TriMesh) -> bool {
    mesh.texture.is_some()
        && mesh
            .uvs
            .as_ref()
            .is_some_and(|u| u.len() == 3 * mesh.faces.len())
}

/// Upload an sRGB image with its mip chain as a sampleable texture.
fn upload_texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    image: &image::RgbaImage,
) -> wgpu::TextureView {
    let max = device.limits().max_texture_dimension_2d.max(1);
    let mut img = image.clone();
    if img.width() > max || img.height() > max {
        let s = max as f32 / img.width().max(img.height()) as f32;
        img = image::imageops::resize(
            &img,
            ((img.width() as f32 * s) as u32).max(1),
            ((img.height() as f32 * s) as u32).max(1),
            image::imageops::FilterType::Triangle,
        );
    }
    let mips = crate::geometry::mip_chain(&img);
    let texture = device.create_texture(&wgpu::TextureDescriptor {
        label: Some("mesh base texture"),
        size: wgpu::Extent3d {
            width: img.width(),
            height: img.height(),
            depth_or_array_layers: 1,
        },
        mip_level_count: mips.len() as u32,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8UnormSrgb,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (level, m) in mips.iter().enumerate() {
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &texture,
                mip_level: level as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            m.as_raw(),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * m.width()),
                rows_per_image: Some(m.height()),
            },
            wgpu::Extent3d {
                width: m.width(),
                height: m.height(),
                depth_or_array_layers: 1,
            },
        );
    }
    texture.create_view(&Default::default())
}

/// A texture of `width`×`height` RGBA8 sRGB texels (one level), written tile by tile.
fn paint_texture(device: &wgpu::Device, width: u32, height: u32) -> wgpu::Texture {
    device.create_texture(&wgpu::TextureDescriptor {
        label: Some("mesh paint layer"),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8UnormSrgb,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    })
}

/// The group of the base texture `base` with the paint texture `paint`.
fn texture_group(
    device: &wgpu::Device,
    renderer: &MeshRenderer,
    base: &wgpu::TextureView,
    paint: &wgpu::TextureView,
    mask: &wgpu::TextureView,
) -> wgpu::BindGroup {
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("mesh texture group"),
        layout: &renderer.texture_layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(base),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: wgpu::BindingResource::Sampler(&renderer.sampler),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: wgpu::BindingResource::TextureView(paint),
            },
            wgpu::BindGroupEntry {
                binding: 3,
                resource: wgpu::BindingResource::TextureView(mask),
            },
        ],
    })
}

impl GpuMesh {
    /// Upload `mesh` with per-vertex sRGB `colors` (see [`display_colors`]); with `textured` and
    /// a texture on the mesh, its texture is drawn per pixel instead of the colours.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        renderer: &MeshRenderer,
        mesh: &TriMesh,
        colors: &[[f32; 3]],
        textured: bool,
    ) -> Self {
        let can_texture = has_texture(mesh);
        // UVs whenever the mesh has them: a paint layer is drawn through them too.
        let with_uvs = mesh
            .uvs
            .as_ref()
            .is_some_and(|u| u.len() == 3 * mesh.faces.len());
        let d = super::draw_mesh::draw_mesh(mesh, with_uvs);
        let mut verts: Vec<Vertex> = (0..d.positions.len())
            .map(|i| Vertex {
                position: d.positions[i],
                normal: d.normals[i],
                uv: d.uvs[i],
            })
            .collect();
        if verts.is_empty() {
            verts.push(Vertex {
                position: [0.0; 3],
                normal: [0.0; 3],
                uv: [0.0; 2],
            });
        }
        let textured = textured && can_texture;
        let cols = expand_colors(&d.vertex, colors, textured, verts.len());
        let nv = mesh.positions.len() as u32;
        // Each edge once, ordered by (lower end, higher end): bucketed by the lower end.
        let mut edge_pairs: Vec<(u32, u32)> = mesh
            .faces
            .iter()
            .filter(|f| f.iter().all(|&i| i < nv))
            .flat_map(|f| [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])])
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        let edge_rows = crate::mesh::Csr::from_pairs(nv as usize, &mut edge_pairs);
        let edges: Vec<u32> = (0..nv as usize)
            .flat_map(|a| edge_rows.row(a).iter().map(move |&b| (a, b as usize)))
            .flat_map(|(a, b)| [d.first[a], d.first[b]])
            .collect();
        let tris = d.triangles;
        let init = |label: &str, bytes: &[u8], usage: wgpu::BufferUsages| {
            // wgpu rejects zero-sized bindings; keep at least 4 bytes.
            let pad = [0u8; 16];
            let contents = if bytes.is_empty() { &pad[..] } else { bytes };
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let vertices = init(
            "mesh vertices",
            bytemuck::cast_slice(&verts),
            wgpu::BufferUsages::VERTEX,
        );
        let colors = init(
            "mesh colours",
            bytemuck::cast_slice(&cols),
            wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
        );
        let indices = init(
            "mesh triangles",
            bytemuck::cast_slice(&tris),
            wgpu::BufferUsages::INDEX,
        );
        let edges_buf = init(
            "mesh edges",
            bytemuck::cast_slice(&edges),
            wgpu::BufferUsages::INDEX,
        );
        let uniforms = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("mesh uniforms"),
            size: std::mem::size_of::<Uniforms>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("mesh bind group"),
            layout: &renderer.layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: uniforms.as_entire_binding(),
            }],
        });
        let white = image::RgbaImage::from_pixel(1, 1, image::Rgba([255; 4]));
        let white_view = upload_texture(device, queue, &white);
        let clear = image::RgbaImage::from_pixel(1, 1, image::Rgba([0; 4]));
        let no_paint_view = upload_texture(device, queue, &clear);
        let white_group = texture_group(
            device,
            renderer,
            &white_view,
            &no_paint_view,
            &no_paint_view,
        );
        let base_view = mesh.texture.as_ref().filter(|_| can_texture).map(|t| {
            let rgba = image::DynamicImage::ImageRgb8(t.image.clone()).to_rgba8();
            upload_texture(device, queue, &rgba)
        });
        let texture_group = base_view
            .as_ref()
            .map(|v| texture_group(device, renderer, v, &no_paint_view, &no_paint_view));
        GpuMesh {
            vertices,
            colors,
            indices,
            edges: edges_buf,
            uniforms,
            bind_group,
            white_group,
            texture_group,
            white_view,
            base_view,
            paint: [None, None],
            no_paint_view,
            layers: [1.0; 4],
            textured,
            draw_vertex: d.vertex,
            index_count: tris.len() as u32,
            edge_count: edges.len() as u32,
            vertex_count: mesh.positions.len(),
            markers: None,
            marker_count: 0,
            frame: Frame::of_points(&mesh.positions),
        }
    }

    /// Replace the marker spheres drawn with this mesh (an empty slice draws none).
    pub fn set_markers(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        markers: &[MarkerInstance],
    ) {
        self.marker_count = markers.len() as u32;
        if markers.is_empty() {
            return;
        }
        let bytes = bytemuck::cast_slice::<MarkerInstance, u8>(markers);
        let fits = self
            .markers
            .as_ref()
            .is_some_and(|b| b.size() >= bytes.len() as u64);
        if !fits {
            // Room for twice as many, so dragging in more markers rarely reallocates.
            self.markers = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("marker instances"),
                size: (bytes.len() as u64 * 2).max(256),
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        if let Some(b) = &self.markers {
            queue.write_buffer(b, 0, bytes);
        }
    }

    /// Replace the per-vertex colours (writes the colour buffer only); with `textured`, a mesh
    /// that has a texture draws it instead. Extra entries are ignored; missing ones are grey.
    pub fn update_colors(&mut self, queue: &wgpu::Queue, colors: &[[f32; 3]], textured: bool) {
        self.textured = textured && self.texture_group.is_some();
        let cols = expand_colors(&self.draw_vertex, colors, self.textured, 0);
        if !cols.is_empty() {
            queue.write_buffer(&self.colors, 0, bytemuck::cast_slice(&cols));
        }
    }

    /// Weights the view composites with (see the shader): the result over grey, the paint
    /// layer and the mask layer.
    pub fn set_layers(&mut self, weights: [f32; 3]) -> bool {
        let l = [weights[0], weights[1], weights[2], 0.0];
        let changed = l != self.layers;
        self.layers = l;
        changed
    }

    fn rebind(&mut self, device: &wgpu::Device, renderer: &MeshRenderer) {
        let view = |p: &Option<PaintTexture>| p.as_ref().map(|p| p.view.clone());
        let paint = view(&self.paint[0]).unwrap_or_else(|| self.no_paint_view.clone());
        let mask = view(&self.paint[1]).unwrap_or_else(|| self.no_paint_view.clone());
        self.white_group = texture_group(device, renderer, &self.white_view, &paint, &mask);
        self.texture_group = self
            .base_view
            .as_ref()
            .map(|b| texture_group(device, renderer, b, &paint, &mask));
    }

    /// Draw a texel layer of `width`×`height` texels over the mesh through its UVs (a new,
    /// transparent one when there was none of that size; write it with [`Self::write_paint`]).
    /// True when a new texture was made.
    pub fn set_paint_layer(
        &mut self,
        device: &wgpu::Device,
        renderer: &MeshRenderer,
        slot: PaintSlot,
        width: u32,
        height: u32,
    ) -> bool {
        let i = slot as usize;
        if self.paint[i]
            .as_ref()
            .is_some_and(|p| (p.width, p.height) == (width, height))
        {
            return false;
        }
        let texture = paint_texture(device, width, height);
        let view = texture.create_view(&Default::default());
        self.paint[i] = Some(PaintTexture {
            texture,
            view,
            width,
            height,
        });
        self.rebind(device, renderer);
        true
    }

    /// Stop drawing a texel layer.
    pub fn clear_paint_layer(
        &mut self,
        device: &wgpu::Device,
        renderer: &MeshRenderer,
        slot: PaintSlot,
    ) {
        if self.paint[slot as usize].take().is_some() {
            self.rebind(device, renderer);
        }
    }

    /// Size of a texel layer drawn, if any.
    pub fn paint_layer_size(&self, slot: PaintSlot) -> Option<(u32, u32)> {
        self.paint[slot as usize]
            .as_ref()
            .map(|p| (p.width, p.height))
    }

    /// Write the texels `rect` = (x, y, width, height) of a texel layer from RGBA8 rows of
    /// `bytes_per_row` bytes.
    pub fn write_paint(
        &self,
        queue: &wgpu::Queue,
        slot: PaintSlot,
        rect: [u32; 4],
        bytes: &[u8],
        bytes_per_row: u32,
    ) {
        let Some(p) = &self.paint[slot as usize] else {
            return;
        };
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &p.texture,
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: rect[0],
                    y: rect[1],
                    z: 0,
                },
                aspect: wgpu::TextureAspect::All,
            },
            bytes,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(bytes_per_row),
                rows_per_image: Some(rect[3]),
            },
            wgpu::Extent3d {
                width: rect[2],
                height: rect[3],
                depth_or_array_layers: 1,
            },
        );
    }

    /// Whether the mesh's texture is drawn.
    pub fn is_textured(&self) -> bool {
        self.textured
    }

    /// Number of vertices uploaded.
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }
}

/// Colours of the drawn vertices: white under a texture, else each one's mesh vertex colour;
/// at least `min_len` entries.
fn expand_colors(
    draw_vertex: &[u32],
    colors: &[[f32; 3]],
    textured: bool,
    min_len: usize,
) -> Vec<[f32; 3]> {
    let mut out: Vec<[f32; 3]> = draw_vertex
        .iter()
        .map(|&v| {
            if textured {
                [1.0; 3]
            } else {
                colors
                    .get(v as usize)
                    .copied()
                    .unwrap_or(DEFAULT_VERTEX_COLOR)
            }
        })
        .collect();
    if out.len() < min_len {
        out.resize(min_len, DEFAULT_VERTEX_COLOR);
    }
    out
}

/// An offscreen colour+depth target (with optional MSAA) that can be shown by egui or read back.
pub struct RenderTarget {
    /// The resolved colour texture (Rgba8Unorm, sampleable, copyable).
    pub texture: wgpu::Texture,
    /// View of [`Self::texture`] (what egui samples).
    pub view: wgpu::TextureView,
    /// The same texture seen as sRGB: what the pipelines draw into.
    draw_view: wgpu::TextureView,
    msaa: Option<wgpu::TextureView>,
    depth: wgpu::TextureView,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl RenderTarget {
    /// Create a `width`×`height` target for `renderer`'s sample count.
    pub fn new(device: &wgpu::Device, renderer: &MeshRenderer, width: u32, height: u32) -> Self {
        let width = width.clamp(1, 8192);
        let height = height.clamp(1, 8192);
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let tex = |label, format, samples, usage, view_formats: &[wgpu::TextureFormat]| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats,
            })
        };
        let texture = tex(
            "target colour",
            COLOR_FORMAT,
            1,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            &[DRAW_FORMAT],
        );
        let msaa = (renderer.samples > 1).then(|| {
            tex(
                "target msaa",
                DRAW_FORMAT,
                renderer.samples,
                wgpu::TextureUsages::RENDER_ATTACHMENT,
                &[],
            )
            .create_view(&Default::default())
        });
        let depth = tex(
            "target depth",
            DEPTH_FORMAT,
            renderer.samples,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
            &[],
        )
        .create_view(&Default::default());
        let view = texture.create_view(&Default::default());
        let draw_view = texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(DRAW_FORMAT),
            ..Default::default()
        });
        RenderTarget {
            texture,
            view,
            draw_view,
            msaa,
            depth,
            width,
            height,
        }
    }

    /// Copy the colour texture to the CPU as tightly packed RGBA8 rows (blocks until done).
    pub fn read_rgba(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
    ) -> crate::error::Result<Vec<u8>> {
        let bpr = (self.width * 4).div_ceil(256) * 256;
        let buf = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: bpr as u64 * self.height as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut enc = device.create_command_encoder(&Default::default());
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &buf,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(bpr),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
        queue.submit([enc.finish()]);
        let slice = buf.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| crate::error::Error::InvalidInput(format!("GPU readback failed: {e}")))?;
        rx.recv()
            .map_err(|_| crate::error::Error::InvalidInput("GPU readback was dropped".into()))?
            .map_err(|e| crate::error::Error::InvalidInput(format!("GPU readback failed: {e}")))?;
        let data = slice
            .get_mapped_range()
            .map_err(|e| crate::error::Error::InvalidInput(format!("GPU readback failed: {e}")))?;
        let mut out = Vec::with_capacity((self.width * self.height * 4) as usize);
        for row in 0..self.height as usize {
            let start = row * bpr as usize;
            out.extend_from_slice(&data[start..start + self.width as usize * 4]);
        }
        drop(data);
        buf.unmap();
        Ok(out)
    }
}

/// A filterable 2-D texture read by the fragment shader, at `binding`.
fn fragment_texture(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::FRAGMENT,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: true },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}
