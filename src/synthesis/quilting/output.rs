//! The output: the shell guard (an element mapped through a strongly distorted or extrapolated
//! patch is dropped when it leaves the shell), the kept elements in one mesh, and the
//! arrangement measured against the swatch's ([`super::measure`]).

use super::elements::{Placed, Placement};
use super::measure::{self, SwatchMeasures};
use super::periodicity::Periodicity;
use super::swatch::Swatch;
use super::{QuiltOutput, QuiltStats};
use crate::geometry::TriangleBvh;
use crate::mesh::TriMesh;

/// The shell guard: an element mapped through a strongly distorted or extrapolated patch
/// (thin parts such as ears, legs and a giraffe's horns) can be flung away from the surface; an
/// element is kept only when every vertex lies within the shell, at most 1.5 H (plus a
/// twentieth of the swatch width for the base's chordal error) from the base.
pub(super) struct ShellGuard {
    bvh: TriangleBvh,
    limit: f32,
}

impl ShellGuard {
    /// The guard over the base `positions`/`faces`, with `stats`' thickness and swatch size.
    pub(super) fn new(positions: &[[f32; 3]], faces: &[[u32; 3]], stats: &QuiltStats) -> Self {
        ShellGuard {
            bvh: TriangleBvh::new(positions, faces),
            limit: 1.5 * stats.thickness + 0.05 * stats.swatch_size,
        }
    }

    /// Whether every point lies within the shell.
    pub(super) fn inside(&self, ps: &[[f32; 3]]) -> bool {
        ps.iter().all(|q| {
            self.bvh
                .closest_point(*q)
                .is_some_and(|(_, _, d)| d <= self.limit)
        })
    }
}

/// The alive elements within the shell over `base_positions`/`faces`, merged in one mesh,
/// their sources named in the given swatch (`found`: its detected tile's).
pub(super) fn assemble(
    elements: &Placement,
    elem_faces: &[Vec<[u32; 3]>],
    base_positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    mut stats: QuiltStats,
    found: Option<&Periodicity>,
) -> QuiltOutput {
    let placed = &elements.placed;
    let mut positions = Vec::new();
    let mut out_f = Vec::new();
    let mut element_id = Vec::new();
    let mut element_source = Vec::new();
    let mut element_pieces = Vec::new();
    let mut element_share = Vec::new();
    let guard = ShellGuard::new(base_positions, faces, &stats);
    let inside = |pe: &&Placed| guard.inside(&pe.positions);
    let before = placed.iter().filter(|p| p.alive).count();
    let kept: Vec<&Placed> = placed.iter().filter(|p| p.alive).filter(inside).collect();
    stats.dropped_outside_shell = before - kept.len();
    for pe in kept {
        let id = element_source.len() as u32;
        let v0 = positions.len() as u32;
        positions.extend_from_slice(&pe.positions);
        element_id.extend(std::iter::repeat_n(id, pe.positions.len()));
        out_f.extend(pe.faces(elem_faces).iter().map(|f| f.map(|v| v + v0)));
        element_source.push(pe.source);
        element_pieces.push(pe.pieces.len() as u32);
        element_share.push(pe.share);
    }
    stats.elements = element_source.len();
    let mut out = QuiltOutput {
        elements: TriMesh::new(positions, out_f),
        element_id,
        element_source,
        element_pieces,
        element_share,
        stats,
    };
    if let Some(p) = found {
        for src in &mut out.element_source {
            *src = p.source[*src as usize];
        }
    }
    out
}

/// The arrangement of `out` over `mesh` measured against the tile `sw`'s (`found`: detected),
/// into its stats.
pub(super) fn measure(
    out: &mut QuiltOutput,
    mesh: &TriMesh,
    sw: &Swatch,
    found: Option<&Periodicity>,
    swatch_measures: &SwatchMeasures,
    (s, l): (f32, f32),
) {
    let m = measure::quilt_measures(out, mesh, swatch_measures, s, l);
    let st = &mut out.stats;
    st.periodicity = found
        .map_or(if sw.periodic { "periodic" } else { "box" }, |p| p.kind)
        .to_string();
    st.lattice_vectors = found.and_then(|p| p.lattice);
    st.tile_elements = sw.num_elements();
    st.density_ratio = m.density_ratio;
    st.density_ratio_convex = m.density_ratio_convex;
    st.density_ratio_saddle = m.density_ratio_saddle;
    st.link_share = m.link_share;
    st.swatch_links_per_element = swatch_measures.links_per_element;
    st.links_per_element = m.links_per_element;
    st.coverage = m.coverage;
}
