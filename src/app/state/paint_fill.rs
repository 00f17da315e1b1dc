//! Fill: a connected region of similar colour, or a whole UV island, in one undo step.
//!
//! On a mesh with UVs the fill works on the texel layer. A region fill floods from the texel
//! under the pointer over the texels the mesh covers (4-neighbours, and across UV seams through
//! links between the texels on either side of a seam edge) while the colour the view shows
//! there (the base with the paint over it) stays within the tolerance of the seed's colour; an
//! island fill paints every texel of the UV chart under the pointer (the faces joined by edges
//! whose two sides have the same UVs). Without UVs the same two fills act on the vertices: over
//! the mesh's edges while the displayed colour stays close, or the whole connected part.
//! Each fill is one stroke at full weight, so the tile undo keeps only the tiles it touched.

use std::collections::HashMap;

use glam::Vec3;

use super::layers::PaintTarget;
use super::paint_layer::{TexelLayer, barycentric, for_texels, has_uvs, new_layer_for};
use super::*;

/// What a fill click fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FillKind {
    /// The connected region of similar colour under the pointer.
    Region,
    /// The whole UV island (chart) under the pointer; without UVs, the connected part.
    Island,
}

/// Whether two sRGB colours (0..=255) differ by at most `tol` (0..=1) in every channel.
#[inline]
fn close(a: [u8; 3], b: [u8; 3], tol: f32) -> bool {
    let t = (tol.clamp(0.0, 1.0) * 255.0).round() as i32;
    (0..3).all(|k| (a[k] as i32 - b[k] as i32).abs() <= t)
}

/// A canonical id per distinct position (meshes split at seams repeat positions).
fn position_ids(mesh: &TriMesh) -> Vec<u32> {
    let mut map: HashMap<[u32; 3], u32> = HashMap::with_capacity(mesh.positions.len());
    mesh.positions
        .iter()
        .map(|p| {
            let n = map.len() as u32;
            *map.entry(p.map(f32::to_bits)).or_insert(n)
        })
        .collect()
}

/// One face's use of an undirected edge: the edge (canonical position ids, smaller first),
/// the face and the corner numbers of the edge's two ends in it.
type EdgeUse = ((u32, u32), usize, usize, usize);

/// Every face's use of every edge, sorted by edge (the uses of one edge are adjacent).
fn edge_uses(mesh: &TriMesh, ids: &[u32]) -> Vec<EdgeUse> {
    let mut edges = Vec::with_capacity(mesh.faces.len() * 3);
    for (f, face) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (ids[face[k] as usize], ids[face[(k + 1) % 3] as usize]);
            if a == b {
                continue;
            }
            edges.push(if a < b {
                ((a, b), f, k, (k + 1) % 3)
            } else {
                ((b, a), f, (k + 1) % 3, k)
            });
        }
    }
    edges.sort_unstable();
    edges
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        parent[x as usize] = parent[parent[x as usize] as usize];
        x = parent[x as usize];
    }
    x
}

/// The UV chart of every face: faces sharing an edge whose two ends have the same UVs on both
/// sides are in one chart. Chart ids are the smallest face of each chart.
pub fn uv_charts(mesh: &TriMesh) -> Vec<u32> {
    let n = mesh.faces.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let Some(uvs) = mesh.uvs.as_ref().filter(|u| u.len() == 3 * n) else {
        return parent;
    };
    let ids = position_ids(mesh);
    for uses in edge_uses(mesh, &ids).chunk_by(|x, y| x.0 == y.0) {
        for (i, &(_, f, a, b)) in uses.iter().enumerate() {
            for &(_, g, c, d) in &uses[i + 1..] {
                if uvs[3 * f + a] == uvs[3 * g + c] && uvs[3 * f + b] == uvs[3 * g + d] {
                    let (x, y) = (find(&mut parent, f as u32), find(&mut parent, g as u32));
                    let (lo, hi) = (x.min(y), x.max(y));
                    parent[hi as usize] = lo;
                }
            }
        }
    }
    (0..n as u32).map(|f| find(&mut parent, f)).collect()
}

/// Links between the texels on either side of every UV seam: for each mesh edge whose sides
/// have different UVs, the texels under points a texel apart along it, side by side. Sorted.
fn seam_links(mesh: &TriMesh, w: u32, h: u32) -> Vec<(u32, u32)> {
    let Some(uvs) = mesh
        .uvs
        .as_ref()
        .filter(|u| u.len() == 3 * mesh.faces.len())
    else {
        return Vec::new();
    };
    let texel = |uv: [f32; 2]| -> Option<u32> {
        let x = (uv[0] * w as f32).floor();
        let y = ((1.0 - uv[1]) * h as f32).floor();
        (x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32).then(|| y as u32 * w + x as u32)
    };
    let ids = position_ids(mesh);
    let mut links = Vec::new();
    for uses in edge_uses(mesh, &ids).chunk_by(|x, y| x.0 == y.0) {
        for (i, &(_, f, a, b)) in uses.iter().enumerate() {
            for &(_, g, c, d) in &uses[i + 1..] {
                let (p0, p1) = (uvs[3 * f + a], uvs[3 * f + b]);
                let (q0, q1) = (uvs[3 * g + c], uvs[3 * g + d]);
                if p0 == q0 && p1 == q1 {
                    continue;
                }
                let len = |s: [f32; 2], e: [f32; 2]| {
                    ((e[0] - s[0]) * w as f32).hypot((e[1] - s[1]) * h as f32)
                };
                let steps = (len(p0, p1).max(len(q0, q1)).ceil() as usize).clamp(1, 1 << 16);
                for s in 0..=steps {
                    let t = s as f32 / steps as f32;
                    let lerp = |u: [f32; 2], v: [f32; 2]| {
                        [u[0] + (v[0] - u[0]) * t, u[1] + (v[1] - u[1]) * t]
                    };
                    if let (Some(x), Some(y)) = (texel(lerp(p0, p1)), texel(lerp(q0, q1)))
                        && x != y
                    {
                        links.push((x, y));
                        links.push((y, x));
                    }
                }
            }
        }
    }
    links.sort_unstable();
    links.dedup();
    links
}

/// The colour a fill judges per texel of a `w`×`h` layer (the slot's result with `paint` over
/// it, sRGB) and whether the mesh covers the texel (within one texel of a face's UV triangle).
fn shown_texels(
    slot: &MeshSlot,
    paint: Option<&TexelLayer>,
    w: u32,
    h: u32,
) -> (Vec<[u8; 3]>, Vec<bool>) {
    let m = slot.displayed();
    let mut covered = vec![false; (w * h) as usize];
    let mut colors = vec![[0u8; 3]; (w * h) as usize];
    let texture = m
        .texture
        .as_ref()
        .filter(|_| slot.shows_texture())
        .map(|t| {
            if t.image.dimensions() == (w, h) {
                t.image.clone()
            } else {
                image::imageops::resize(&t.image, w, h, image::imageops::FilterType::Triangle)
            }
        });
    let cols = slot.display_colors();
    for_texels(m, w, h, 0..m.faces.len(), &|_| true, &mut |x, y, f, b| {
        let i = (y * w + x) as usize;
        covered[i] = true;
        if texture.is_none() {
            let face = m.faces[f];
            colors[i] = [0, 1, 2].map(|k| {
                let v: f32 = (0..3).map(|j| b[j] * cols[face[j] as usize][k]).sum();
                (v * 255.0).round().clamp(0.0, 255.0) as u8
            });
        }
    });
    if let Some(img) = texture {
        for (x, y, p) in img.enumerate_pixels() {
            colors[(y * w + x) as usize] = p.0;
        }
    }
    let Some(layer) = paint.filter(|l| (l.width, l.height) == (w, h)) else {
        return (colors, covered);
    };
    for y in 0..h {
        for x in 0..w {
            let p = layer.get(x, y);
            if p[3] > 0 {
                let a = p[3] as f32 / 255.0;
                let c = &mut colors[(y * w + x) as usize];
                for k in 0..3 {
                    c[k] = (c[k] as f32 * (1.0 - a) + p[k] as f32 * a).round() as u8;
                }
            }
        }
    }
    (colors, covered)
}

/// The texels of the region of similar colour around `seed` (see the module doc).
pub fn flood_texels(
    mesh: &TriMesh,
    layer_colors: &[[u8; 3]],
    covered: &[bool],
    w: u32,
    h: u32,
    seed: u32,
    tolerance: f32,
) -> Vec<u32> {
    let n = (w * h) as usize;
    if seed as usize >= n || !covered[seed as usize] {
        return Vec::new();
    }
    let links = seam_links(mesh, w, h);
    let target = layer_colors[seed as usize];
    let mut seen = vec![false; n];
    let mut queue = vec![seed];
    seen[seed as usize] = true;
    let mut out = Vec::new();
    let push = |t: u32, seen: &mut [bool], queue: &mut Vec<u32>| {
        let i = t as usize;
        if !seen[i] && covered[i] && close(layer_colors[i], target, tolerance) {
            seen[i] = true;
            queue.push(t);
        }
    };
    while let Some(t) = queue.pop() {
        out.push(t);
        let (x, y) = (t % w, t / w);
        if x > 0 {
            push(t - 1, &mut seen, &mut queue);
        }
        if x + 1 < w {
            push(t + 1, &mut seen, &mut queue);
        }
        if y > 0 {
            push(t - w, &mut seen, &mut queue);
        }
        if y + 1 < h {
            push(t + w, &mut seen, &mut queue);
        }
        let from = links.partition_point(|l| l.0 < t);
        for &(_, o) in links[from..].iter().take_while(|l| l.0 == t) {
            push(o, &mut seen, &mut queue);
        }
    }
    out
}

/// The vertices of the region of similar colour around `seed` over the mesh's edges.
pub fn flood_vertices(mesh: &TriMesh, colors: &[[f32; 3]], seed: u32, tolerance: f32) -> Vec<u32> {
    let n = mesh.positions.len();
    if seed as usize >= n || colors.len() < n {
        return Vec::new();
    }
    let adj = vertex_neighbours(mesh);
    let q = |c: [f32; 3]| c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
    let target = q(colors[seed as usize]);
    let mut seen = vec![false; n];
    seen[seed as usize] = true;
    let mut queue = vec![seed];
    let mut out = Vec::new();
    while let Some(v) = queue.pop() {
        out.push(v);
        for &u in &adj.1[adj.0[v as usize] as usize..adj.0[v as usize + 1] as usize] {
            if !seen[u as usize] && close(q(colors[u as usize]), target, tolerance) {
                seen[u as usize] = true;
                queue.push(u);
            }
        }
    }
    out
}

/// Vertex neighbours over the faces' edges, CSR (offsets, neighbours).
fn vertex_neighbours(mesh: &TriMesh) -> (Vec<u32>, Vec<u32>) {
    let n = mesh.positions.len();
    let mut deg = vec![0u32; n + 1];
    for f in &mesh.faces {
        for k in 0..3 {
            deg[f[k] as usize + 1] += 2;
        }
    }
    for i in 0..n {
        deg[i + 1] += deg[i];
    }
    let mut fill = deg.clone();
    let mut nb = vec![0u32; deg[n] as usize];
    for f in &mesh.faces {
        for k in 0..3 {
            let v = f[k] as usize;
            for j in [(k + 1) % 3, (k + 2) % 3] {
                nb[fill[v] as usize] = f[j];
                fill[v] += 1;
            }
        }
    }
    (deg, nb)
}

/// The faces connected to `face` through shared vertices (a connected part of the mesh).
fn connected_faces(mesh: &TriMesh, face: usize) -> Vec<usize> {
    let n = mesh.positions.len();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for f in &mesh.faces {
        for k in 1..3 {
            let (x, y) = (find(&mut parent, f[0]), find(&mut parent, f[k]));
            parent[x.max(y) as usize] = x.min(y);
        }
    }
    let root = find(&mut parent, mesh.faces[face][0]);
    (0..mesh.faces.len())
        .filter(|&f| find(&mut parent, mesh.faces[f][0]) == root)
        .collect()
}

impl<P: AppParams> AppState<P> {
    /// Fill from a surface point (`point` on face `face` of one side's displayed mesh) with the
    /// brush's colour (or erase, with the eraser): the region of similar colour within
    /// [`Brush::fill_tolerance`], or the whole UV island. One undo step. Returns the number of
    /// texels (or vertices) filled.
    pub fn fill_at(&mut self, side: Side, face: usize, point: [f32; 3], kind: FillKind) -> usize {
        let brush = self.brush;
        let Some(slot) = self.slot(side) else {
            return 0;
        };
        let mesh: Arc<TriMesh> = slot.working.clone().unwrap_or_else(|| slot.file.clone());
        let Some(f) = mesh.faces.get(face).copied() else {
            return 0;
        };
        let corners = f.map(|v| Vec3::from(mesh.positions[v as usize]));
        let bary = barycentric(Vec3::from(point), corners);
        self.push_undo();
        if !brush.eraser {
            paint_layer::remember_color(&mut self.color_history, brush.color);
        }
        let Some(slot) = self.slot_mut(side) else {
            return 0;
        };
        let count = if has_uvs(&mesh) {
            let mut layer = slot
                .target_layers(brush.target)
                .1
                .take()
                .unwrap_or_else(|| new_layer_for(&mesh));
            let (w, h) = (layer.width, layer.height);
            let texels: Vec<u32> = match kind {
                FillKind::Region => {
                    let uvs = mesh.uvs.as_ref().expect("has UVs");
                    let uv = (0..3).fold([0.0f32; 2], |acc, k| {
                        let t = uvs[3 * face + k];
                        [acc[0] + bary[k] * t[0], acc[1] + bary[k] * t[1]]
                    });
                    let x = ((uv[0].rem_euclid(1.0) * w as f32) as u32).min(w - 1);
                    let y = (((1.0 - uv[1].rem_euclid(1.0)) * h as f32) as u32).min(h - 1);
                    let paint = match brush.target {
                        PaintTarget::Paint => Some(&layer),
                        PaintTarget::Mask => slot.texels.as_ref(),
                    };
                    let (colors, covered) = shown_texels(slot, paint, w, h);
                    flood_texels(
                        &mesh,
                        &colors,
                        &covered,
                        w,
                        h,
                        y * w + x,
                        brush.fill_tolerance,
                    )
                }
                FillKind::Island => {
                    let charts = uv_charts(&mesh);
                    let chart = charts[face];
                    let faces = (0..mesh.faces.len()).filter(|&g| charts[g] == chart);
                    let mut out = Vec::new();
                    for_texels(&mesh, w, h, faces, &|_| true, &mut |x, y, _, _| {
                        out.push(y * w + x)
                    });
                    out
                }
            };
            layer.begin_stroke(brush.color, brush.eraser);
            let mut n = 0;
            for t in texels {
                if layer.stamp(t % w, t / w, 1.0) {
                    n += 1;
                }
            }
            *slot.target_layers(brush.target).1 = Some(layer);
            n
        } else {
            let verts: Vec<u32> = match kind {
                FillKind::Region => {
                    let k = (0..3)
                        .max_by(|&a, &b| bary[a].total_cmp(&bary[b]))
                        .unwrap_or(0);
                    flood_vertices(&mesh, &slot.display_colors(), f[k], brush.fill_tolerance)
                }
                FillKind::Island => {
                    let mut on = vec![false; mesh.positions.len()];
                    for g in connected_faces(&mesh, face) {
                        for v in mesh.faces[g] {
                            on[v as usize] = true;
                        }
                    }
                    (0..on.len() as u32).filter(|&v| on[v as usize]).collect()
                }
            };
            let n = mesh.positions.len();
            let paint = slot
                .target_layers(brush.target)
                .0
                .get_or_insert_with(|| vec![[0.0; 4]; n]);
            for &v in &verts {
                let c = brush.color;
                paint[v as usize] = if brush.eraser {
                    [0.0; 4]
                } else {
                    [c[0], c[1], c[2], 1.0]
                };
            }
            slot.colors_dirty = true;
            verts.len()
        };
        self.message = format!(
            "filled {count} {}",
            if has_uvs(&mesh) { "texels" } else { "vertices" }
        );
        count
    }
}
