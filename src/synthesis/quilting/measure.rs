//! How well a quilt keeps its swatch's arrangement: element density, links and gaps, measured
//! on the swatch's tile and on the output the same way.
//!
//! - **Density**: elements per unit of area. The swatch's is its tile's count over the tile's
//!   area ([`super::periodicity`]); the output's is its element count over the base's area,
//!   in swatch units (divided by `s^2`), a thread cut short ([`super::trim`]) counting for the
//!   share of its faces it kept. Also split by the sign of the base's Gaussian curvature
//!   (angle defects summed over a ball half a swatch wide around each face): convex and saddle.
//!   An element counts for the base faces nearest its vertices, each for an equal part of it
//!   (a strand lies over several regions).
//! - **Links per element**: twice the number of linked pairs ([`super::links`]) over the
//!   element count. On a lattice tile the swatch's count includes its copies around it (links
//!   across the tile's border are the swatch's own); on a tile from spacing only the swatch's
//!   own links count. The *share of links reproduced* is the output's rate over the swatch's.
//! - **Largest gap**: the largest distance from a point on the ground (`z = 0`) of the swatch to
//!   the nearest element vertex (sampled on a 48 x 48 grid over the tile, copies around it
//!   included; over the centre box for a tile from spacing). **Coverage** is the share of the
//!   base's area (face centroids) within that distance, scaled, of an output vertex: where the
//!   quilt leaves no gap larger than the swatch's largest.

use std::collections::HashMap;

use glam::{IVec3, Vec3};
use rayon::prelude::*;

use super::links::{centre_curve, linked_pairs};
use super::swatch::Swatch;
use crate::geometry::TriangleBvh;
use crate::mesh::TriMesh;

/// The swatch's own numbers, in swatch units.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SwatchMeasures {
    /// Elements per unit area.
    pub density: f32,
    /// Links per element (0 when no element threads through another).
    pub links_per_element: f32,
    /// Largest distance from the ground to the nearest element vertex.
    pub largest_gap: f32,
}

/// The output's numbers against the swatch's.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct QuiltMeasures {
    /// Output density over the swatch's (1 = the swatch's own).
    pub density_ratio: f32,
    /// The same over convex regions of the base (`None`: no such region).
    pub density_ratio_convex: Option<f32>,
    /// The same over saddle-shaped regions (`None`: no such region).
    pub density_ratio_saddle: Option<f32>,
    /// Output links per element over the swatch's (`None`: the swatch has no links).
    pub link_share: Option<f32>,
    /// Output links per element.
    pub links_per_element: f32,
    /// Share of base area with no gap larger than the swatch's largest.
    pub coverage: f32,
}

/// Measure the tile; `with_copies`: count links and gaps with the tile's copies around it.
pub fn swatch_measures(tile: &Swatch, with_copies: bool) -> SwatchMeasures {
    let ne = tile.num_elements();
    let images: Vec<[f32; 2]> = if with_copies {
        tile.images()
    } else {
        vec![[0.0, 0.0]]
    };
    let density = if with_copies {
        ne as f32 / (tile.extent[0] * tile.extent[1])
    } else {
        super::periodicity::spacing_density(&unperiodic(tile))
    };
    let mut curves = Vec::new();
    let mut owner = Vec::new();
    for im in &images {
        for e in 0..ne {
            let ps = tile.element_positions(e);
            let c = centre_curve(ps, &tile.element_faces(e)).map(|c| {
                c.iter()
                    .map(|p| *p + Vec3::new(im[0], im[1], 0.0))
                    .collect()
            });
            curves.push(c);
            owner.push((e, *im == [0.0, 0.0]));
        }
    }
    let ordered: usize = linked_pairs(&curves)
        .iter()
        .map(|&(i, j)| owner[i as usize].1 as usize + owner[j as usize].1 as usize)
        .sum();
    let links_per_element = ordered as f32 / ne.max(1) as f32;
    // gap samples
    let (lo, hi) = if with_copies {
        ([0.0, 0.0], tile.extent)
    } else {
        let mut lo = [f32::INFINITY; 2];
        let mut hi = [f32::NEG_INFINITY; 2];
        for e in &tile.elements {
            for k in 0..2 {
                lo[k] = lo[k].min(e.centre[k]);
                hi[k] = hi[k].max(e.centre[k]);
            }
        }
        (lo, hi)
    };
    let verts: Vec<Vec3> = images
        .iter()
        .flat_map(|im| {
            tile.mesh
                .positions
                .iter()
                .map(move |p| Vec3::new(p[0] + im[0], p[1] + im[1], p[2]))
        })
        .collect();
    const G: usize = 48;
    let largest_gap = (0..G * G)
        .into_par_iter()
        .map(|k| {
            let (i, j) = (k % G, k / G);
            let p = Vec3::new(
                lo[0] + (hi[0] - lo[0]) * (i as f32 + 0.5) / G as f32,
                lo[1] + (hi[1] - lo[1]) * (j as f32 + 0.5) / G as f32,
                0.0,
            );
            verts
                .iter()
                .map(|q| q.distance_squared(p))
                .fold(f32::INFINITY, f32::min)
                .sqrt()
        })
        .reduce(|| 0.0f32, f32::max);
    SwatchMeasures {
        density,
        links_per_element,
        largest_gap,
    }
}

fn unperiodic(tile: &Swatch) -> Swatch {
    let mut t = tile.clone();
    t.periodic = false;
    t
}

/// Angle defect per vertex (interior vertices; boundary vertices get 0).
fn angle_defects(mesh: &TriMesh) -> Vec<f32> {
    let n = mesh.num_vertices();
    let mut sum = vec![0.0f32; n];
    let mut edge_count: HashMap<(u32, u32), u32> = HashMap::new();
    for f in &mesh.faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            *edge_count.entry((a.min(b), a.max(b))).or_default() += 1;
            let p = Vec3::from(mesh.positions[f[k] as usize]);
            let u = Vec3::from(mesh.positions[f[(k + 1) % 3] as usize]) - p;
            let v = Vec3::from(mesh.positions[f[(k + 2) % 3] as usize]) - p;
            sum[f[k] as usize] += u.angle_between(v);
        }
    }
    let mut boundary = vec![false; n];
    for (&(a, b), &c) in &edge_count {
        if c == 1 {
            boundary[a as usize] = true;
            boundary[b as usize] = true;
        }
    }
    (0..n)
        .map(|v| {
            if boundary[v] || sum[v] == 0.0 {
                0.0
            } else {
                std::f32::consts::TAU - sum[v]
            }
        })
        .collect()
}

/// Measure an output against its swatch. `s`: swatch-to-base scale; `l`: swatch width in base
/// units (the curvature ball is `l / 2`).
/// Links per element among the swatch's own elements as modelled (no copies around them: a
/// finite patch's border elements have fewer partners than its interior's).
pub fn modelled_links_per_element(sw: &Swatch) -> f32 {
    let ne = sw.num_elements();
    let curves: Vec<Option<Vec<Vec3>>> = (0..ne)
        .into_par_iter()
        .map(|e| centre_curve(sw.element_positions(e), &sw.element_faces(e)))
        .collect();
    2.0 * linked_pairs(&curves).len() as f32 / ne.max(1) as f32
}

pub fn quilt_measures(
    out: &super::QuiltOutput,
    base: &TriMesh,
    sw: &SwatchMeasures,
    s: f32,
    l: f32,
) -> QuiltMeasures {
    let nf = base.num_faces();
    let area = crate::geometry::face_areas(&base.positions, &base.faces);
    let total: f64 = area.iter().sum();
    let ne = out.num_elements();
    let expected = sw.density as f64 / (s as f64 * s as f64);
    // a thread cut short counts for the share of its element it holds
    let share = |e: usize| out.element_share.get(e).map_or(1.0, |&x| x as f64);
    let counted: f64 = (0..ne).map(share).sum();
    let density_ratio = if total > 0.0 && expected > 0.0 {
        (counted / total / expected) as f32
    } else {
        0.0
    };
    let ranges = element_ranges(out);
    let links = element_links(out, &ranges);
    let links_per_element = 2.0 * links as f32 / ne.max(1) as f32;
    let link_share = (sw.links_per_element > 0.0).then(|| links_per_element / sw.links_per_element);
    let sign = curvature_signs(base, l);
    let home = element_homes(out, base, &ranges);
    let by_sign = |want: i8| -> Option<f32> {
        let a: f64 = (0..nf).filter(|&f| sign[f] == want).map(|f| area[f]).sum();
        if a < 0.02 * total || expected <= 0.0 {
            return None;
        }
        let n: f64 = home
            .iter()
            .enumerate()
            .map(|(e, at)| {
                let part: f32 = at
                    .iter()
                    .filter(|(f, _)| sign[*f as usize] == want)
                    .map(|x| x.1)
                    .sum();
                share(e) * part as f64
            })
            .sum();
        Some((n / a / expected) as f32)
    };
    // coverage: face centroids within the swatch's largest gap of an output vertex
    let covered = covered_area(out, base, &area, (sw.largest_gap * s).max(1e-9));
    QuiltMeasures {
        density_ratio,
        density_ratio_convex: by_sign(1),
        density_ratio_saddle: by_sign(-1),
        link_share,
        links_per_element,
        coverage: if total > 0.0 {
            (covered / total) as f32
        } else {
            0.0
        },
    }
}

/// Per element, its vertex range and its face range in the output (`(u32::MAX, 0)` if empty).
struct ElementRanges {
    vertices: Vec<(u32, u32)>,
    faces: Vec<(u32, u32)>,
}

/// The vertex and face ranges of every output element.
fn element_ranges(out: &super::QuiltOutput) -> ElementRanges {
    let ne = out.num_elements();
    let mut ranges = vec![(u32::MAX, 0u32); ne];
    for (v, &e) in out.element_id.iter().enumerate() {
        let r = &mut ranges[e as usize];
        r.0 = r.0.min(v as u32);
        r.1 = r.1.max(v as u32 + 1);
    }
    let mut face_ranges = vec![(u32::MAX, 0u32); ne];
    for (f, tri) in out.elements.faces.iter().enumerate() {
        let e = out.element_id[tri[0] as usize] as usize;
        let r = &mut face_ranges[e];
        r.0 = r.0.min(f as u32);
        r.1 = r.1.max(f as u32 + 1);
    }
    ElementRanges {
        vertices: ranges,
        faces: face_ranges,
    }
}

/// The number of linked pairs of output elements (by the linking number of their centre curves).
fn element_links(out: &super::QuiltOutput, ranges: &ElementRanges) -> usize {
    let curves: Vec<Option<Vec<Vec3>>> = (0..out.num_elements())
        .into_par_iter()
        .map(|e| {
            let (v0, v1) = ranges.vertices[e];
            let (f0, f1) = ranges.faces[e];
            if v0 >= v1 || f0 >= f1 {
                return None;
            }
            let ps = &out.elements.positions[v0 as usize..v1 as usize];
            let fs: Vec<[u32; 3]> = out.elements.faces[f0 as usize..f1 as usize]
                .iter()
                .map(|f| f.map(|v| v - v0))
                .collect();
            centre_curve(ps, &fs)
        })
        .collect();
    linked_pairs(&curves).len()
}

/// The centroid of face `f`.
fn face_centroid(base: &TriMesh, f: usize) -> Vec3 {
    base.faces[f]
        .iter()
        .map(|&v| Vec3::from(base.positions[v as usize]))
        .sum::<Vec3>()
        / 3.0
}

/// Curvature class of every base face: angle defects summed over a ball of `l / 2` around its
/// centroid; 1 convex, -1 saddle, 0 neither (below a twentieth of a flat disc's turning).
fn curvature_signs(base: &TriMesh, l: f32) -> Vec<i8> {
    let defect = angle_defects(base);
    let radius = 0.5 * l;
    let key = |p: Vec3| (p / radius).floor().as_ivec3();
    let mut grid: HashMap<IVec3, Vec<u32>> = HashMap::new();
    for (v, p) in base.positions.iter().enumerate() {
        grid.entry(key(Vec3::from(*p))).or_default().push(v as u32);
    }
    (0..base.num_faces())
        .into_par_iter()
        .map(|f| {
            let c = face_centroid(base, f);
            let k = key(c);
            let mut k_sum = 0.0f32;
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        if let Some(list) = grid.get(&(k + IVec3::new(dx, dy, dz))) {
                            for &v in list {
                                if Vec3::from(base.positions[v as usize]).distance(c) <= radius {
                                    k_sum += defect[v as usize];
                                }
                            }
                        }
                    }
                }
            }
            // below a twentieth of a flat disc's worth of turning: neither
            if k_sum > 0.05 {
                1
            } else if k_sum < -0.05 {
                -1
            } else {
                0
            }
        })
        .collect()
}

/// Where each element lies over the base: the base faces nearest [`HOME_SAMPLES`] of its
/// vertices at most (evenly strided over them), each sample with an equal part of the element.
/// A strand as long as a swatch is wide lies over several curvature regions, and its vertex
/// centroid, a chord's midpoint, sits off the surface (inside an ear it wraps round); its
/// vertices lie on it.
fn element_homes(
    out: &super::QuiltOutput,
    base: &TriMesh,
    ranges: &ElementRanges,
) -> Vec<Vec<(u32, f32)>> {
    let bvh = TriangleBvh::new(&base.positions, &base.faces);
    (0..out.num_elements())
        .into_par_iter()
        .map(|e| {
            let (v0, v1) = ranges.vertices[e];
            if v0 >= v1 {
                return Vec::new();
            }
            let ps = &out.elements.positions[v0 as usize..v1 as usize];
            let stride = ps.len().div_ceil(HOME_SAMPLES);
            let mut at: Vec<(u32, f32)> = ps
                .iter()
                .step_by(stride)
                .filter_map(|p| bvh.closest_point(*p).map(|x| (x.0, 0.0)))
                .collect();
            let w = 1.0 / at.len().max(1) as f32;
            at.iter_mut().for_each(|x| x.1 = w);
            at
        })
        .collect()
}

/// Most vertices of an element [`element_homes`] places it by.
const HOME_SAMPLES: usize = 16;

/// The area of the base faces whose centroid lies within `reach` of an output vertex.
fn covered_area(out: &super::QuiltOutput, base: &TriMesh, area: &[f64], reach: f32) -> f64 {
    let vkey = |p: Vec3| (p / reach).floor().as_ivec3();
    let mut vgrid: HashMap<IVec3, Vec<u32>> = HashMap::new();
    for (v, p) in out.elements.positions.iter().enumerate() {
        vgrid
            .entry(vkey(Vec3::from(*p)))
            .or_default()
            .push(v as u32);
    }
    (0..base.num_faces())
        .into_par_iter()
        .filter(|&f| {
            let c = face_centroid(base, f);
            let k = vkey(c);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        if let Some(list) = vgrid.get(&(k + IVec3::new(dx, dy, dz)))
                            && list.iter().any(|&v| {
                                Vec3::from(out.elements.positions[v as usize]).distance(c) <= reach
                            })
                        {
                            return true;
                        }
                    }
                }
            }
            false
        })
        .map(|f| area[f])
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strand lying over both halves of a flat strip counts half for each, not wholly for the
    /// face nearest its vertex centroid.
    #[test]
    fn a_strand_counts_over_the_faces_it_lies_on() {
        let base = TriMesh::new(
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1.0, 0.0],
                [2.0, 1.0, 0.0],
            ],
            vec![[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]],
        );
        // 40 vertices from x = 0.05 to 1.95 along y = 0.5, in pairs forming a thin ribbon
        let n = 20;
        let mut positions = Vec::new();
        for i in 0..n {
            let x = 0.05 + 1.9 * i as f32 / (n - 1) as f32;
            positions.push([x, 0.45, 0.01]);
            positions.push([x, 0.55, 0.01]);
        }
        let faces: Vec<[u32; 3]> = (0..n as u32 - 1)
            .flat_map(|i| [[2 * i, 2 * i + 2, 2 * i + 3], [2 * i, 2 * i + 3, 2 * i + 1]])
            .collect();
        let out = super::super::QuiltOutput {
            element_id: vec![0; positions.len()],
            elements: TriMesh::new(positions, faces),
            element_source: vec![0],
            element_pieces: vec![1],
            element_share: vec![1.0],
            stats: Default::default(),
        };
        let homes = element_homes(&out, &base, &element_ranges(&out));
        let left: f32 = homes[0].iter().filter(|(f, _)| *f < 2).map(|x| x.1).sum();
        let right: f32 = homes[0].iter().filter(|(f, _)| *f >= 2).map(|x| x.1).sum();
        assert!((left + right - 1.0).abs() < 1e-5, "{left} + {right}");
        assert!(
            (left - 0.5).abs() <= 0.1 && (right - 0.5).abs() <= 0.1,
            "{left} / {right}"
        );
    }
}
