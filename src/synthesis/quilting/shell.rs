//! The base and its shell (§3.2): vertex and face normals, areas, adjacency, the orientation
//! field, and the offset surface bounding the shell, guarded in concave regions and relaxed to
//! lower its L2 stretch (eq. 8-9). [`Base::shell_point`] is the shell map.

use glam::Vec3;

use super::Params;
use crate::geometry::{
    face_areas, face_normals, minimize_shell_stretch, offset_surface, shell_point,
    shell_point_ruled, shell_stretch, tangent_direction, vertex_normals,
};
use crate::mesh::{Csr, TriMesh, boundary_faces, vertex_adjacency, vertex_faces};

/// The base surface with what the shell map needs.
pub(super) struct Base<'a> {
    pub(super) p: &'a [[f32; 3]],
    pub(super) faces: &'a [[u32; 3]],
    pub(super) vn: Vec<[f32; 3]>,
    pub(super) fnrm: Vec<[f32; 3]>,
    pub(super) area: Vec<f64>,
    pub(super) adj: Csr,
    pub(super) vf: Csr,
    /// Per face: it has an edge on the base's boundary.
    pub(super) on_boundary: Vec<bool>,
    /// The offset surface bounding the shell.
    pub(super) top: Vec<[f32; 3]>,
    /// Shell thickness `H` (height fraction 1).
    pub(super) thickness: f32,
    /// Map through the shell's tetrahedra instead of the ruled prism interpolation.
    pub(super) tetrahedra: bool,
    pub(super) field: Vec<Vec3>,
}

impl Base<'_> {
    /// The shell map: base point at barycentric `b` of face `f`, at height `h` (base units,
    /// `H` at the offset surface), through the shell's tetrahedra.
    pub(super) fn shell_point(&self, f: u32, b: [f32; 3], h: f32) -> Vec3 {
        let w = if self.thickness > 0.0 {
            h / self.thickness
        } else {
            0.0
        };
        if self.tetrahedra {
            shell_point(self.p, &self.top, self.faces, f, b, w)
        } else {
            shell_point_ruled(self.p, &self.top, self.faces, f, b, w)
        }
    }
}

/// The shell's stretch (eq. 9) before and after its minimisation, and its tetrahedra left
/// inverted.
pub(super) struct ShellStretch {
    pub(super) before: f64,
    pub(super) after: f64,
    pub(super) inverted: usize,
}

/// The base `mesh` with its orientation field (`given`, else the base x axis projected) and
/// its shell of thickness `h`.
pub(super) fn build<'a>(
    mesh: &'a TriMesh,
    given: Option<&[[f32; 3]]>,
    params: &Params,
    h: f32,
) -> (Base<'a>, ShellStretch) {
    let n = mesh.num_vertices();
    let faces = &mesh.faces;
    let vn = vertex_normals(&mesh.positions, faces);
    let fnrm = face_normals(&mesh.positions, faces);
    let area = face_areas(&mesh.positions, faces);
    let adj = vertex_adjacency(n, faces);
    let vf = vertex_faces(n, faces);
    let guard: Vec<f32> = (0..n)
        .map(|i| {
            if !params.concave_guard || h <= 0.0 {
                return 1.0;
            }
            let (pi, ni) = (Vec3::from(mesh.positions[i]), Vec3::from(vn[i]));
            let mut kappa = 0.0f32;
            for &j in adj.row(i) {
                let (pj, nj) = (
                    Vec3::from(mesh.positions[j as usize]),
                    Vec3::from(vn[j as usize]),
                );
                let (dp, dn) = (pj - pi, nj - ni);
                if dp.dot(dn) < 0.0 && dp.length() > 0.0 {
                    kappa = kappa.max(dn.length() / dp.length());
                }
            }
            if kappa > 0.0 {
                (0.9 / (kappa * h)).min(1.0)
            } else {
                1.0
            }
        })
        .collect();
    let field: Vec<Vec3> = (0..n)
        .map(|i| {
            let nv = Vec3::from(vn[i]);
            match given {
                Some(f) => tangent_direction(nv, Vec3::from(f[i])),
                None => {
                    let t = Vec3::X - nv * nv.x;
                    if t.length() > 0.3 {
                        t.normalize()
                    } else {
                        tangent_direction(nv, Vec3::Y)
                    }
                }
            }
        })
        .collect();
    let (mut top, _) = offset_surface(
        &mesh.positions,
        faces,
        &vn,
        h,
        Some(&guard),
        params.concave_guard,
    );
    let (stretch_before, stretch_after, shell_inverted) = if params.shell_sweeps > 0 && h > 0.0 {
        let rep = minimize_shell_stretch(
            &mesh.positions,
            faces,
            &vn,
            &mut top,
            h,
            params.shell_sweeps,
            params.seed,
        );
        (rep.before, rep.after, rep.inverted)
    } else {
        let plain = shell_stretch(&mesh.positions, &top, faces, h);
        (plain.l2, plain.l2, plain.inverted)
    };
    let base = Base {
        p: &mesh.positions,
        faces,
        vn,
        fnrm,
        area,
        adj,
        on_boundary: boundary_faces(faces),
        vf,
        top,
        thickness: h,
        tetrahedra: params.shell_tetrahedra,
        field,
    };
    (
        base,
        ShellStretch {
            before: stretch_before,
            after: stretch_after,
            inverted: shell_inverted,
        },
    )
}
