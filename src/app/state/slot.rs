//! Loaded meshes and what is displayed for them; paint carried between meshes.

use std::path::PathBuf;
use std::sync::Arc;

use crate::mesh::TriMesh;

/// One loaded mesh and what is displayed for it.
#[derive(Clone)]
pub struct MeshSlot {
    /// The mesh as loaded (file vertex numbering).
    pub file: Arc<TriMesh>,
    /// Identity of this load (changes whenever the mesh is replaced).
    pub id: u64,
    /// The working-resolution mesh once the worker prepared it.
    pub working: Option<Arc<TriMesh>>,
    /// File vertex of each working vertex.
    pub working_to_file: Option<Arc<[u32]>>,
    /// A working vertex for each file vertex (the first one that maps to it), `u32::MAX` if none.
    pub file_to_working: Option<Vec<u32>>,
    /// Base colours of the displayed mesh (before paint).
    pub base_colors: Vec<[f32; 3]>,
    /// The base colours are the displayed mesh's own signal (not a result): a textured mesh is
    /// then drawn through its texture.
    pub own_signal: bool,
    /// Vertex normals of the displayed mesh (for marker visibility).
    pub normals: Vec<[f32; 3]>,
    /// Paint layer on the displayed mesh: RGB + coverage per vertex.
    pub paint: Option<Vec<[f32; 4]>>,
    /// Paint at the texture's resolution, through the displayed mesh's UVs (over `paint`).
    pub texels: Option<super::paint_layer::TexelLayer>,
    /// Mask layer on the displayed mesh's vertices (meshes without UVs): RGB + coverage.
    pub mask: Option<Vec<[f32; 4]>>,
    /// Mask at the texture's resolution, through the displayed mesh's UVs.
    pub mask_texels: Option<super::paint_layer::TexelLayer>,
    /// Geometry changed since the renderer last uploaded it.
    pub geometry_dirty: bool,
    /// Colours changed since the renderer last uploaded them.
    pub colors_dirty: bool,
    /// Name of the built-in scene this mesh came from (it has no file), if any.
    pub scene: Option<String>,
    /// Texture image applied with File > Open texture (or a dropped image), if any.
    pub texture_file: Option<PathBuf>,
    /// Paint restored from a session, kept with the positions it was painted on so that the
    /// working mesh, once prepared, gets it from the original rather than from the file mesh;
    /// with it, the layer applied at load (to tell whether strokes were made since).
    pub(super) restored_paint: Option<(PaintSample, Vec<[f32; 4]>)>,
}

impl MeshSlot {
    pub(super) fn new(mesh: Arc<TriMesh>, id: u64) -> Self {
        let base_colors = crate::render::display_colors(&mesh, None);
        let normals = crate::render::gpu::vertex_normals(&mesh.positions, &mesh.faces);
        MeshSlot {
            normals,
            file: mesh,
            id,
            working: None,
            working_to_file: None,
            file_to_working: None,
            base_colors,
            own_signal: true,
            paint: None,
            texels: None,
            mask: None,
            mask_texels: None,
            geometry_dirty: true,
            colors_dirty: true,
            scene: None,
            texture_file: None,
            restored_paint: None,
        }
    }

    /// The mesh shown in the view: the working mesh when prepared, else the file mesh.
    pub fn displayed(&self) -> &TriMesh {
        self.working.as_deref().unwrap_or(&self.file)
    }

    /// File vertex of a displayed vertex.
    pub fn to_file(&self, v: u32) -> u32 {
        match &self.working_to_file {
            Some(map) => map.get(v as usize).copied().unwrap_or(v),
            None => v,
        }
    }

    /// Displayed vertex of a file vertex, if it is shown.
    pub fn to_displayed(&self, f: u32) -> Option<u32> {
        match &self.file_to_working {
            Some(map) => map.get(f as usize).copied().filter(|&w| w != u32::MAX),
            None => ((f as usize) < self.file.positions.len()).then_some(f),
        }
    }

    /// Position of a file vertex on the displayed mesh.
    pub fn file_vertex_position(&self, f: u32) -> Option<[f32; 3]> {
        let d = self.to_displayed(f)?;
        self.displayed().positions.get(d as usize).copied()
    }

    /// Whether the view draws the displayed mesh's texture per pixel: it has one, shows its own
    /// signal and carries no paint.
    pub fn shows_texture(&self) -> bool {
        self.own_signal && self.paint.is_none() && crate::render::has_texture(self.displayed())
    }

    /// Colours to draw: base colours with the paint layer composited.
    pub fn display_colors(&self) -> Vec<[f32; 3]> {
        match &self.paint {
            None => self.base_colors.clone(),
            Some(p) => self
                .base_colors
                .iter()
                .zip(p)
                .map(|(b, p)| {
                    let a = p[3];
                    [0, 1, 2].map(|k| b[k] * (1.0 - a) + p[k] * a)
                })
                .collect(),
        }
    }
}

/// A paint layer with the vertex positions it was painted on.
#[derive(Clone, Debug)]
pub(super) struct PaintSample {
    pub(super) positions: Vec<[f32; 3]>,
    pub(super) rgba: Vec<[f32; 4]>,
}

/// For each point of `to`, the index of the nearest point of `from` (identity when both lists
/// are the same points); empty when `from` is empty.
pub fn nearest_map(from: &[[f32; 3]], to: &[[f32; 3]]) -> Vec<u32> {
    if from.is_empty() {
        return Vec::new();
    }
    if from == to {
        return (0..to.len() as u32).collect();
    }
    let grid = PointGrid::new(from);
    to.iter().map(|&p| grid.nearest(from, p)).collect()
}

/// Carry a per-vertex paint layer painted on `from` onto the vertices `to` (nearest vertex).
pub fn remap_paint(from: &[[f32; 3]], paint: &[[f32; 4]], to: &[[f32; 3]]) -> Vec<[f32; 4]> {
    if paint.len() != from.len() {
        return vec![[0.0; 4]; to.len()];
    }
    let map = nearest_map(from, to);
    if map.is_empty() {
        return vec![[0.0; 4]; to.len()];
    }
    map.iter().map(|&i| paint[i as usize]).collect()
}

/// A uniform grid over points for nearest-point queries (about two points per cell).
pub(super) struct PointGrid {
    pub(super) min: glam::Vec3,
    pub(super) cell: f32,
    pub(super) dims: [i32; 3],
    pub(super) start: Vec<u32>,
    pub(super) items: Vec<u32>,
}

impl PointGrid {
    pub(super) fn new(points: &[[f32; 3]]) -> Self {
        let mut min = glam::Vec3::splat(f32::INFINITY);
        let mut max = glam::Vec3::splat(f32::NEG_INFINITY);
        for p in points {
            let v = glam::Vec3::from(*p);
            min = min.min(v);
            max = max.max(v);
        }
        let ext = (max - min).max(glam::Vec3::splat(1e-6));
        let cells = (points.len() as f32 / 2.0).max(1.0);
        let cell = ((ext.x * ext.y * ext.z) / cells)
            .cbrt()
            .max(ext.max_element() / 256.0);
        let dims = [0, 1, 2].map(|k| ((ext[k] / cell).floor() as i32 + 1).clamp(1, 1024));
        let n = (dims[0] * dims[1] * dims[2]) as usize;
        let mut grid = PointGrid {
            min,
            cell,
            dims,
            start: vec![0; n + 1],
            items: vec![0; points.len()],
        };
        let ids: Vec<usize> = points.iter().map(|p| grid.index(grid.coord(*p))).collect();
        for &c in &ids {
            grid.start[c + 1] += 1;
        }
        for c in 0..n {
            grid.start[c + 1] += grid.start[c];
        }
        let mut fill = grid.start.clone();
        for (i, &c) in ids.iter().enumerate() {
            grid.items[fill[c] as usize] = i as u32;
            fill[c] += 1;
        }
        grid
    }

    pub(super) fn coord(&self, p: [f32; 3]) -> [i32; 3] {
        [0, 1, 2]
            .map(|k| (((p[k] - self.min[k]) / self.cell).floor() as i32).clamp(0, self.dims[k] - 1))
    }

    pub(super) fn index(&self, c: [i32; 3]) -> usize {
        ((c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]) as usize
    }

    /// Index of the point nearest to `p` (rings of cells until no nearer one can exist).
    pub(super) fn nearest(&self, points: &[[f32; 3]], p: [f32; 3]) -> u32 {
        let q = glam::Vec3::from(p);
        let c = self.coord(p);
        let mut best = (f32::INFINITY, 0u32);
        let max_r = self.dims.into_iter().max().unwrap_or(1);
        for r in 0..=max_r {
            for z in (c[2] - r).max(0)..=(c[2] + r).min(self.dims[2] - 1) {
                for y in (c[1] - r).max(0)..=(c[1] + r).min(self.dims[1] - 1) {
                    for x in (c[0] - r).max(0)..=(c[0] + r).min(self.dims[0] - 1) {
                        let ring = (x - c[0]).abs().max((y - c[1]).abs()).max((z - c[2]).abs());
                        if ring != r {
                            continue;
                        }
                        let cell = self.index([x, y, z]);
                        for &i in
                            &self.items[self.start[cell] as usize..self.start[cell + 1] as usize]
                        {
                            let d = q.distance_squared(glam::Vec3::from(points[i as usize]));
                            if d < best.0 || (d == best.0 && i < best.1) {
                                best = (d, i);
                            }
                        }
                    }
                }
            }
            // Points in ring r + 1 are at least r cells away from `p`.
            let reach = r as f32 * self.cell;
            if best.0.is_finite() && best.0 <= reach * reach {
                break;
            }
        }
        best.1
    }
}
