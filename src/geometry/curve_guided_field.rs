//! Curve-guided tangent vector field (Xu et al. 2009, "Feature-aligned shape texturing", §4):
//! greedy curve orientation (eq. 1) and constrained harmonic vector diffusion (eq. 2).
//!
//! The field is three independent scalar functions (x, y, z). Each solves `(L + P) x = P b`
//! (L: cotan stiffness, `P_ii = α = 1e8` at constrained curve vertices, b: that component of the
//! oriented curve tangents), plus `ε M` (ε = 1e-10 tr L / tr M, M: Voronoi mass) so components
//! without a curve stay definite (they get a zero field, reported as singular). The result is
//! projected on the tangent planes and normalised.
//!
//! Greedy orientation: orient the longest curve (arc length) as stored, solve, score every other
//! curve with `g(c, u) = max{ Σ (π - θ_p)/(π + θ_p), Σ θ_p/(2π - θ_p) }` (θ_p: angle between the
//! curve tangent and the projected `u(p)`; θ = π/2 where `|u| < 1e-8`), orient the best one by the
//! winning term, add its constraints, repeat.
//!
//! Factorisation reuse: the sparsity pattern of `L + P` never changes (P is diagonal), so one
//! symbolic Cholesky analysis is made up front and each greedy step is a numeric
//! refactorisation on it plus three triangular solves (the guide's proposal 6; a true rank-k
//! update à la Davis & Hager is not available in faer).
//!
//! Curve tangents: `p_{i+1} - p_{i-1}` (one-sided at open ends, wrapped on closed curves),
//! projected and normalised. Vertices shared by several oriented curves get the mean of their
//! tangents, released when the mean is shorter than `junction_release` (corners).

use std::f64::consts::PI;

use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::{MatMut, Side};
use glam::{DVec3, Vec3};

use super::basic::{d3, vertex_normals};
use super::curvature::onb;
use super::laplacian::{LaplacePattern, check_faces, mass_matrix_voronoi};
use crate::error::{Error, Result};
use crate::work::{CancelToken, Stopwatch};

/// Parameters of the curve-guided field.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct FieldParams {
    /// Penalty weight α of the constraints (paper: 1e8).
    pub alpha: f64,
    /// Release a junction vertex when the mean of its oriented unit tangents is shorter.
    pub junction_release: f64,
    /// Curves oriented per greedy step, as a fraction of those still unoriented (at least one):
    /// 0 is the paper's one curve per step, one numeric factorisation each; the default 1/8
    /// takes, besides the best, those of the best eighth whose direction the field has already
    /// decided (its two scores differ by half their sum). Measured (`examples/field_batch`): the demo giraffe's 235
    /// curves on 46K vertices take 49 s in 235 steps one by one, 7.9 s in 37 steps batched,
    /// every curve oriented the same way; Spot's 35 curves end with a field 0.8% rougher.
    pub batch: f64,
}

impl Default for FieldParams {
    fn default() -> Self {
        FieldParams {
            alpha: 1e8,
            junction_release: 0.3,
            batch: 0.125,
        }
    }
}

/// A curve joins a batch of [`FieldParams::batch`] only when its two orientation scores differ
/// by at least this fraction of their sum.
const DECIDED_MARGIN: f64 = 0.5;

/// The constrained harmonic solver of one mesh: cotan Laplacian and one symbolic Cholesky
/// analysis; [`HarmonicFieldSolver::solve`] refactorises numerically for each constraint set.
pub struct HarmonicFieldSolver {
    n: usize,
    pat: LaplacePattern,
    base: Vec<f64>,
    sym: SymbolicLlt<usize>,
    normals: Vec<[f32; 3]>,
    alpha: f64,
}

impl HarmonicFieldSolver {
    /// Build `L + εM` and its symbolic analysis.
    pub fn new(positions: &[[f32; 3]], faces: &[[u32; 3]], alpha: f64) -> Result<Self> {
        let n = positions.len();
        check_faces(n, faces)?;
        if faces.is_empty() {
            return Err(Error::InvalidMesh(
                "a curve-guided field needs faces".into(),
            ));
        }
        let pat = LaplacePattern::new(n, faces);
        let mut base = pat.cotan_values(positions, faces);
        let mass = mass_matrix_voronoi(positions, faces);
        let trace_l: f64 = pat.diag.iter().map(|&d| base[d]).sum();
        let trace_m: f64 = mass.iter().sum::<f64>().max(1e-300);
        let eps = 1e-10 * trace_l / trace_m;
        for (i, &m) in mass.iter().enumerate() {
            base[pat.diag[i]] += if m > 0.0 { m * eps } else { 1.0 };
        }
        let mat = pat.matrix(base.clone());
        let sym = SymbolicLlt::try_new(mat.symbolic(), Side::Lower)
            .map_err(|e| Error::InvalidMesh(format!("symbolic Cholesky failed: {e:?}")))?;
        Ok(HarmonicFieldSolver {
            n,
            pat,
            base,
            sym,
            normals: vertex_normals(positions, faces),
            alpha,
        })
    }

    /// Number of vertices.
    pub fn num_vertices(&self) -> usize {
        self.n
    }

    /// The unit vertex normals.
    pub fn normals(&self) -> &[[f32; 3]] {
        &self.normals
    }

    /// Solve `(L + εM + P) x = P b` for the three components, constraints `(vertex, b)`; returns
    /// the raw (unprojected) field.
    pub fn solve(&self, constraints: &[(u32, DVec3)]) -> Result<Vec<DVec3>> {
        let n = self.n;
        let mut val = self.base.clone();
        let mut rhs = vec![0.0f64; 3 * n];
        for &(v, b) in constraints {
            let v = v as usize;
            val[self.pat.diag[v]] += self.alpha;
            rhs[v] += self.alpha * b.x;
            rhs[n + v] += self.alpha * b.y;
            rhs[2 * n + v] += self.alpha * b.z;
        }
        let mat = self.pat.matrix(val);
        let llt = Llt::try_new_with_symbolic(self.sym.clone(), mat.as_ref(), Side::Lower)
            .map_err(|e| Error::InvalidMesh(format!("Cholesky of L + P failed: {e:?}")))?;
        llt.solve_in_place(MatMut::from_column_major_slice_mut(&mut rhs, n, 3));
        Ok((0..n)
            .map(|i| DVec3::new(rhs[i], rhs[n + i], rhs[2 * n + i]))
            .collect())
    }
}

/// Unit tangents of a vertex polyline: `p_{i+1} - p_{i-1}` projected on the tangent plane.
pub fn curve_tangents(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    vertices: &[u32],
    closed: bool,
) -> Vec<DVec3> {
    let m = vertices.len();
    let p = |i: usize| d3(positions[vertices[i] as usize]);
    (0..m)
        .map(|i| {
            let (a, b) = if closed && m > 2 {
                ((i + m - 1) % m, (i + 1) % m)
            } else {
                (i.saturating_sub(1), (i + 1).min(m - 1))
            };
            let d = p(b) - p(a);
            let nv = d3(normals[vertices[i] as usize]);
            (d - d.dot(nv) * nv).normalize_or_zero()
        })
        .collect()
}

/// The two terms of eq. (1) for one curve: `(Σ (π-θ)/(π+θ), Σ θ/(2π-θ))`; the first favours the
/// stored orientation, the second the reversed one.
pub fn score_terms(tangents: &[DVec3], field: &[DVec3]) -> (f64, f64) {
    let mut g = (0.0, 0.0);
    for (t, u) in tangents.iter().zip(field) {
        let th = if u.length() < 1e-8 || t.length() < 1e-12 {
            PI / 2.0
        } else {
            t.normalize().dot(u.normalize()).clamp(-1.0, 1.0).acos()
        };
        g.0 += (PI - th) / (PI + th);
        g.1 += th / (2.0 * PI - th);
    }
    g
}

/// The two terms of eq. (1) for a curve against a raw (unprojected) field: the field is
/// projected on the tangent planes at the curve's vertices first.
fn curve_scores(
    raw: &[DVec3],
    normals: &[[f32; 3]],
    tangents: &[DVec3],
    vertices: &[u32],
) -> (f64, f64) {
    let f: Vec<DVec3> = vertices
        .iter()
        .map(|&v| {
            let nv = d3(normals[v as usize]);
            let u = raw[v as usize];
            u - u.dot(nv) * nv
        })
        .collect();
    score_terms(tangents, &f)
}

/// Roughness of a unit tangent field: the mean of `|f_a - f_b|²` over the faces' edges (each
/// interior edge counted twice). Lower is smoother; a field whose curves disagree in
/// orientation is rougher.
pub fn field_roughness(faces: &[[u32; 3]], field: &[[f32; 3]]) -> f64 {
    let mut e = 0.0f64;
    for t in faces {
        for k in 0..3 {
            let (a, b) = (field[t[k] as usize], field[t[(k + 1) % 3] as usize]);
            e += (0..3).map(|d| ((a[d] - b[d]) as f64).powi(2)).sum::<f64>();
        }
    }
    e / (3 * faces.len()).max(1) as f64
}

/// An oriented curve-guided field.
#[derive(Clone, Debug, Default)]
pub struct CurveField {
    /// Unit tangent per vertex.
    pub field: Vec<[f32; 3]>,
    /// Per curve: true = kept as given, false = reversed.
    pub forward: Vec<bool>,
    /// Curves in the order the greedy algorithm oriented them.
    pub order: Vec<usize>,
    /// Vertices where the projected field vanished (singularities, curve-free components).
    pub singular: Vec<u32>,
    /// Vertices constrained in the final solve.
    pub constrained: Vec<u32>,
    /// Seconds per greedy step (one numeric factorisation, three solves, scoring).
    pub step_secs: Vec<f64>,
    /// Seconds for the symbolic analysis.
    pub setup_secs: f64,
    /// Seconds of the full-resolution solves after a coarse greedy (0 when the greedy ran at
    /// full resolution: its last step is the final solve).
    pub final_solve_secs: f64,
}

/// One curve as the field sees it: its snapped vertex path and whether it closes.
#[derive(Clone, Debug)]
pub struct FieldCurve {
    /// Mesh vertices along the curve.
    pub vertices: Vec<u32>,
    /// Closed loop.
    pub closed: bool,
}

impl From<&super::crest_lines::Curve> for FieldCurve {
    /// A salient curve's snapped vertex path.
    fn from(c: &super::crest_lines::Curve) -> Self {
        FieldCurve {
            vertices: c.vertices.clone(),
            closed: c.closed,
        }
    }
}

/// Gather the constraints of the oriented curves (junctions averaged or released).
fn constraints(
    tangents: &[Vec<DVec3>],
    curves: &[FieldCurve],
    oriented: &[(usize, bool)],
    release: f64,
    n: usize,
) -> Vec<(u32, DVec3)> {
    let mut sum = vec![DVec3::ZERO; n];
    let mut cnt = vec![0u32; n];
    let mut list = Vec::new();
    for &(c, fwd) in oriented {
        let s = if fwd { 1.0 } else { -1.0 };
        for (&v, &t) in curves[c].vertices.iter().zip(&tangents[c]) {
            if t.length_squared() == 0.0 {
                continue;
            }
            if cnt[v as usize] == 0 {
                list.push(v);
            }
            sum[v as usize] += s * t;
            cnt[v as usize] += 1;
        }
    }
    list.sort_unstable();
    list.into_iter()
        .filter_map(|v| {
            let m = sum[v as usize] / cnt[v as usize] as f64;
            if cnt[v as usize] > 1 && m.length() < release {
                None
            } else {
                Some((v, m.normalize()))
            }
        })
        .collect()
}

/// What the field's front doors share: the solver, its normals, the curves' tangents.
struct Prepared {
    solver: HarmonicFieldSolver,
    normals: Vec<[f32; 3]>,
    tangents: Vec<Vec<DVec3>>,
    /// Seconds for the symbolic analysis.
    setup_secs: f64,
}

/// Build the solver and the curves' tangents; refuses curves that name missing vertices.
fn prepare(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    curves: &[FieldCurve],
    params: &FieldParams,
) -> Result<Prepared> {
    let n = positions.len();
    if curves
        .iter()
        .flat_map(|c| &c.vertices)
        .any(|&v| v as usize >= n)
    {
        return Err(Error::InvalidInput(
            "a curve refers to a missing vertex".into(),
        ));
    }
    let clock = Stopwatch::start();
    let solver = HarmonicFieldSolver::new(positions, faces, params.alpha)?;
    let setup_secs = clock.secs();
    let normals = solver.normals().to_vec();
    let tangents: Vec<Vec<DVec3>> = curves
        .iter()
        .map(|c| curve_tangents(positions, &normals, &c.vertices, c.closed))
        .collect();
    Ok(Prepared {
        solver,
        normals,
        tangents,
        setup_secs,
    })
}

/// Greedy orientation of `curves` (Xu et al. §4.1) and the final projected, normalised field.
pub fn oriented_curve_field(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    curves: &[FieldCurve],
    params: &FieldParams,
    cancel: &CancelToken,
) -> Result<CurveField> {
    let n = positions.len();
    let Prepared {
        solver,
        normals,
        tangents,
        setup_secs,
    } = prepare(positions, faces, curves, params)?;
    let lengths: Vec<f64> = curves
        .iter()
        .map(|c| {
            c.vertices
                .windows(2)
                .map(|w| d3(positions[w[0] as usize]).distance(d3(positions[w[1] as usize])))
                .sum()
        })
        .collect();
    let mut forward = vec![true; curves.len()];
    let mut oriented: Vec<(usize, bool)> = Vec::new();
    let mut remaining: Vec<usize> = (0..curves.len())
        .filter(|&c| !curves[c].vertices.is_empty())
        .collect();
    let mut step_secs = Vec::new();
    let mut raw: Vec<DVec3> = vec![DVec3::ZERO; n];
    if let Some(first) = remaining
        .iter()
        .copied()
        .max_by(|&a, &b| lengths[a].total_cmp(&lengths[b]).then(b.cmp(&a)))
    {
        remaining.retain(|&c| c != first);
        oriented.push((first, true));
        loop {
            cancel.check()?;
            let clock = Stopwatch::start();
            let cons = constraints(&tangents, curves, &oriented, params.junction_release, n);
            raw = solver.solve(&cons)?;
            if remaining.is_empty() {
                step_secs.push(clock.secs());
                break;
            }
            // Score every remaining curve against the field; orient the best one (or the best
            // batch), best first.
            let mut scored: Vec<(f64, usize, bool, f64)> = remaining
                .iter()
                .map(|&c| {
                    let (g0, g1) = curve_scores(&raw, &normals, &tangents[c], &curves[c].vertices);
                    // how decided the field already is about this curve's direction
                    let margin = (g0 - g1).abs() / (g0 + g1).max(1e-300);
                    if g0 >= g1 {
                        (g0, c, true, margin)
                    } else {
                        (g1, c, false, margin)
                    }
                })
                .collect();
            scored.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            let room = ((remaining.len() as f64 * params.batch.clamp(0.0, 1.0)).ceil() as usize)
                .clamp(1, remaining.len());
            // The best curve always; more of the best only where the field has decided them
            // (an undecided curve waits for a solve that includes its neighbours).
            let take = 1 + scored[1..room]
                .iter()
                .filter(|x| x.3 >= DECIDED_MARGIN)
                .count();
            let chosen: Vec<(f64, usize, bool, f64)> = std::iter::once(scored[0])
                .chain(
                    scored[1..room]
                        .iter()
                        .copied()
                        .filter(|x| x.3 >= DECIDED_MARGIN),
                )
                .collect();
            debug_assert_eq!(chosen.len(), take);
            for &(_, c, fwd, _) in &chosen {
                forward[c] = fwd;
                oriented.push((c, fwd));
            }
            let done: Vec<usize> = chosen.iter().map(|x| x.1).collect();
            remaining.retain(|r| !done.contains(r));
            step_secs.push(clock.secs());
        }
    }
    let constrained: Vec<u32> =
        constraints(&tangents, curves, &oriented, params.junction_release, n)
            .into_iter()
            .map(|(v, _)| v)
            .collect();
    Ok(finish(
        &raw,
        &normals,
        forward,
        oriented.iter().map(|o| o.0).collect(),
        constrained,
        step_secs,
        setup_secs,
    ))
}

/// Project the raw field to the tangent planes and normalise it (a fixed tangent where it
/// vanishes, listed as singular).
fn finish(
    raw: &[DVec3],
    normals: &[[f32; 3]],
    forward: Vec<bool>,
    order: Vec<usize>,
    constrained: Vec<u32>,
    step_secs: Vec<f64>,
    setup_secs: f64,
) -> CurveField {
    let mut singular = Vec::new();
    let field: Vec<[f32; 3]> = (0..raw.len())
        .map(|i| {
            let nv = d3(normals[i]);
            let u = raw[i] - raw[i].dot(nv) * nv;
            let l = u.length();
            if l > 1e-8 && l.is_finite() {
                (u / l).as_vec3().to_array()
            } else {
                singular.push(i as u32);
                if nv.length_squared() > 0.5 {
                    onb(nv).0.as_vec3().to_array()
                } else {
                    Vec3::X.to_array()
                }
            }
        })
        .collect();
    CurveField {
        field,
        forward,
        order,
        singular,
        constrained,
        step_secs,
        setup_secs,
        final_solve_secs: 0.0,
    }
}

/// The field of curves whose orientations are given (`forward[c]`: kept as given; `order`: the
/// greedy order, kept in the result), of which only some are decided (`decided[c]`; all of
/// them: one constrained harmonic solve). With [`oriented_curve_field`] run on a coarser mesh of
/// the same shape, this gives the greedy's decisions at the coarse cost and the field at full
/// resolution. Undecided curves: one solve with the decided ones, every undecided curve oriented at once by
/// the winning term of eq. (1) against that field, then the solve with all of them (two solves
/// on one factorisation's symbolic analysis). A coarse greedy leaves a curve undecided when it
/// shrank to fewer than three coarse vertices (its tangent, hence its score, is lost there).
pub fn curve_field_completing_orientations(
    positions: &[[f32; 3]],
    faces: &[[u32; 3]],
    curves: &[FieldCurve],
    forward: &[bool],
    decided: &[bool],
    order: Vec<usize>,
    params: &FieldParams,
) -> Result<CurveField> {
    let n = positions.len();
    if forward.len() != curves.len() || decided.len() != curves.len() {
        return Err(Error::InvalidInput(
            "one orientation per curve is needed".into(),
        ));
    }
    let Prepared {
        solver,
        normals,
        tangents,
        setup_secs,
    } = prepare(positions, faces, curves, params)?;
    let mut forward = forward.to_vec();
    let usable = |c: usize| !curves[c].vertices.is_empty();
    let pending: Vec<usize> = (0..curves.len())
        .filter(|&c| usable(c) && !decided[c])
        .collect();
    let mut steps = Vec::new();
    let solve = |oriented: &[(usize, bool)]| -> Result<(Vec<DVec3>, Vec<u32>)> {
        let cons = constraints(&tangents, curves, oriented, params.junction_release, n);
        let raw = if cons.is_empty() {
            vec![DVec3::ZERO; n]
        } else {
            solver.solve(&cons)?
        };
        Ok((raw, cons.into_iter().map(|(v, _)| v).collect()))
    };
    let decided_set: Vec<(usize, bool)> = (0..curves.len())
        .filter(|&c| usable(c) && decided[c])
        .map(|c| (c, forward[c]))
        .collect();
    if !pending.is_empty() && !decided_set.is_empty() {
        let clock = Stopwatch::start();
        let (raw, _) = solve(&decided_set)?;
        for &c in &pending {
            let (g0, g1) = curve_scores(&raw, &normals, &tangents[c], &curves[c].vertices);
            forward[c] = g0 >= g1;
        }
        steps.push(clock.secs());
    }
    let oriented: Vec<(usize, bool)> = (0..curves.len())
        .filter(|&c| usable(c))
        .map(|c| (c, forward[c]))
        .collect();
    let clock = Stopwatch::start();
    let (raw, constrained) = solve(&oriented)?;
    steps.push(clock.secs());
    Ok(finish(
        &raw,
        &normals,
        forward,
        order,
        constrained,
        steps,
        setup_secs,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(m: u32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        crate::testdata::grid(m as usize)
    }

    #[test]
    fn score_terms_match_the_guide() {
        let t = [DVec3::X];
        let (a, b) = score_terms(&t, &[DVec3::X]);
        assert!((a - 1.0).abs() < 1e-12 && b.abs() < 1e-12);
        let (a, b) = score_terms(&t, &[DVec3::Y]);
        assert!((a - 1.0 / 3.0).abs() < 1e-12 && (b - 1.0 / 3.0).abs() < 1e-12);
        let (a, b) = score_terms(&t, &[-DVec3::X]);
        assert!(a.abs() < 1e-12 && (b - 1.0).abs() < 1e-12);
    }

    #[test]
    fn parallel_lines_end_co_oriented_and_field_is_constant() {
        let m = 21u32;
        let (pos, faces) = grid(m);
        // three horizontal lines, the middle one stored reversed
        let line = |y: u32, rev: bool| {
            let mut v: Vec<u32> = (2..m - 2).map(|x| y * m + x).collect();
            if rev {
                v.reverse();
            }
            FieldCurve {
                vertices: v,
                closed: false,
            }
        };
        let curves = vec![line(3, false), line(10, true), line(17, false)];
        let f = oriented_curve_field(
            &pos,
            &faces,
            &curves,
            &FieldParams::default(),
            &CancelToken::new(),
        )
        .unwrap();
        // all end up pointing the same way
        let dir =
            |c: usize| if f.forward[c] { 1.0 } else { -1.0 } * if c == 1 { -1.0 } else { 1.0 };
        assert_eq!(dir(0), dir(1));
        assert_eq!(dir(1), dir(2));
        // between the lines the field is (nearly) constant ±x
        for y in 4..17 {
            for x in 1..m - 1 {
                let u = f.field[(y * m + x) as usize];
                assert!(u[0].abs() > 0.99, "{x},{y}: {u:?}");
            }
        }
        assert!(f.singular.is_empty());
        // constraint fidelity
        for &v in &curves[0].vertices {
            assert!(f.field[v as usize][0].abs() > 0.99999);
        }
    }
}
