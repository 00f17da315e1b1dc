//! Step 2, patch growing (§3.1) and flattening: the seed face's frame, then the placement disc
//! flattened by the global lattice where it is regular and little distorted, else by the
//! discrete exponential map, shrunk while distorted.

use glam::{Vec2, Vec3};

use super::QuiltStats;
use super::flat::Flat;
use super::lattice::{LATTICE_BAD_AREA, LATTICE_NEAR, Lattice, LatticeChart};
use super::setup::Setup;
use super::shell::Base;
use crate::geometry::{DiscSeed, ExpMap, StripePattern, exp_map, tangent_direction};

/// A flattened patch.
pub(super) struct Patch {
    /// Its seed face.
    pub(super) seed: usize,
    pub(super) flat: Flat,
    /// Area distortion `max(rho, 1/rho)` per face of `flat`.
    pub(super) rho: Vec<f32>,
    /// Radius of the placement disc, base units.
    pub(super) rp: f32,
    /// The lattice's translation (swatch units) when the lattice flattens this patch.
    pub(super) lattice_t: Option<Vec2>,
}

/// The patch seeded on face `seed` with a placement disc of radius `rp`: flattened by the
/// lattice's chart when it serves, else by the exponential map, shrinking while distorted.
pub(super) fn flatten(
    setup: &Setup,
    base: &Base,
    lattice: &mut Lattice,
    seed: usize,
    rp: f32,
    stats: &mut QuiltStats,
) -> Patch {
    let disc = disc_of(setup, base, seed);
    // the lattice's try computes the disc at the full radius; the fallback starts from it
    let mut first_disc = None;
    if let Some(lat) = lattice
        .patterns
        .as_ref()
        .filter(|_| !lattice.near_singular[seed])
    {
        let em = first_disc.insert(disc(rp));
        let chart = &mut lattice.chart;
        if let Some((flat, rho, t)) = by_lattice(
            setup,
            base,
            lat,
            &lattice.singular,
            chart,
            em,
            seed,
            rp,
            stats,
        ) {
            return Patch {
                seed,
                flat,
                rho,
                rp,
                lattice_t: Some(t),
            };
        }
    }
    matched(setup, base, seed, first_disc, disc, rp, stats)
}

/// The patch seeded on face `seed` flattened by the exponential map alone (shrunk while
/// distorted, as a matched patch is), whatever the lattice.
pub(super) fn by_exp_map_at(
    setup: &Setup,
    base: &Base,
    seed: usize,
    rp: f32,
    stats: &mut QuiltStats,
) -> Patch {
    matched(
        setup,
        base,
        seed,
        None,
        disc_of(setup, base, seed),
        rp,
        stats,
    )
}

/// The patch on `disc` (starting from `first_disc` when computed already) flattened by the
/// exponential map, shrunk while distorted: a patch for the paper's matching.
fn matched(
    setup: &Setup,
    base: &Base,
    seed: usize,
    first_disc: Option<ExpMap>,
    disc: impl Fn(f32) -> ExpMap,
    rp: f32,
    stats: &mut QuiltStats,
) -> Patch {
    let (flat, rho, rp) = by_exp_map(setup, base, first_disc, disc, rp, stats);
    Patch {
        seed,
        flat,
        rho,
        rp,
        lattice_t: None,
    }
}

/// The disc around face `seed` of placement radius `rp` flattened by the exponential map, out
/// to where elements centred within `rp` still land on flattened triangles.
fn disc_of<'a>(setup: &'a Setup, base: &'a Base, seed: usize) -> impl Fn(f32) -> ExpMap + 'a {
    let (r_elem, mean_edge, tau) = (setup.r_elem, setup.mean_edge, setup.tau);
    let disc_seed = seed_frame(base, seed);
    move |rp: f32| {
        exp_map(
            base.p,
            &base.vn,
            &base.adj,
            &disc_seed,
            rp + 2.0 * r_elem + 2.0 * mean_edge + tau,
        )
    }
}

/// The exponential map's seed on face `seed`: its centroid, its normal and the orientation
/// field there.
fn seed_frame(base: &Base, seed: usize) -> DiscSeed {
    let (faces, mesh_positions) = (base.faces, base.p);
    let sc = faces[seed];
    let centroid = sc
        .iter()
        .map(|&v| Vec3::from(mesh_positions[v as usize]))
        .sum::<Vec3>()
        / 3.0;
    let n0 = Vec3::from(base.fnrm[seed]).normalize_or(Vec3::from(base.vn[sc[0] as usize]));
    let e1 = tangent_direction(n0, sc.iter().map(|&v| base.field[v as usize]).sum::<Vec3>());
    DiscSeed {
        face: sc,
        point: centroid.to_array(),
        normal: n0.to_array(),
        e1: e1.to_array(),
    }
}

/// The disc `em` flattened by the lattice's two phases, unwrapped outwards from the seed, with
/// its distortion and the translation that puts the swatch's lattice on the phases'; `None`
/// when the chart is distorted or folded over more than [`LATTICE_BAD_AREA`] of the disc or its
/// mean scale is off by more than `lattice_scale`.
#[allow(clippy::too_many_arguments)]
fn by_lattice(
    setup: &Setup,
    base: &Base,
    lat: &[StripePattern; 2],
    singular: &[bool],
    chart: &mut LatticeChart,
    em: &ExpMap,
    seed: usize,
    rp: f32,
    stats: &mut QuiltStats,
) -> Option<(Flat, Vec<f32>, Vec2)> {
    let (params, s, period) = (setup.params, setup.s, setup.period);
    let g = chart.unwrap(
        lat,
        singular,
        base.p,
        base,
        &em.vertices,
        &em.dist,
        seed as u32,
    )?;
    // swatch coordinates: one phase cycle per period; the seed point (the
    // seed face's centroid) at the origin of the patch
    let k = [
        period[0] as f64 / std::f64::consts::TAU,
        period[1] as f64 / std::f64::consts::TAU,
    ];
    let c0 = g[0].1;
    let g0 = [
        (c0[0][0] + c0[1][0] + c0[2][0]) * k[0] / 3.0,
        (c0[0][1] + c0[1][1] + c0[2][1]) * k[1] / 3.0,
    ];
    let to_uv = |q: [f64; 2]| {
        Vec2::new(
            ((q[0] * k[0] - g0[0]) * s as f64) as f32,
            ((q[1] * k[1] - g0[1]) * s as f64) as f32,
        )
    };
    let flat = Flat::from_faces(
        base,
        g.into_iter().map(|(f, c)| (f, c.map(to_uv))).collect(),
        true,
    );
    let near = |f: u32| chart.within(base, f, LATTICE_NEAR * rp);
    let (_, rho, scale) = flat.distortion_and_scale(base, rp, near);
    // the share of the disc's area distorted beyond the limit (folded faces
    // included): elements on those faces are dropped one by one below, so a
    // few slivers need not cost the patch its lattice
    let (mut bad, mut all, mut worst) = (0.0f64, 0.0f64, 1.0f32);
    for ((f, t), &q) in flat.faces.iter().zip(&rho) {
        if t.iter().all(|p| p.length() <= rp) && near(*f) {
            let a = base.area[*f as usize];
            all += a;
            if q > params.max_distortion {
                bad += a;
            } else {
                worst = worst.max(q);
            }
        }
    }
    let win = params.lattice_scale.max(1.0) as f64;
    if all > 0.0 && bad <= LATTICE_BAD_AREA * all && (1.0 / win..=win).contains(&scale) {
        stats.max_distortion = stats.max_distortion.max(worst);
        stats.lattice_patches += 1;
        let t = Vec2::new(
            -(g0[0].rem_euclid(period[0] as f64)) as f32,
            -(g0[1].rem_euclid(period[1] as f64)) as f32,
        );
        return Some((flat, rho, t));
    }
    None
}

/// The disc flattened by the exponential map (`first_disc` when computed already, else
/// `disc`), its radius shrunk by 0.75 while its distortion exceeds `max_distortion`, down to
/// `rp_min`. Returns the flattening, its distortion and the radius.
fn by_exp_map(
    setup: &Setup,
    base: &Base,
    mut first_disc: Option<ExpMap>,
    disc: impl Fn(f32) -> ExpMap,
    mut rp: f32,
    stats: &mut QuiltStats,
) -> (Flat, Vec<f32>, f32) {
    let (params, rp_min) = (setup.params, setup.rp_min);
    loop {
        let em = first_disc.take().unwrap_or_else(|| disc(rp));
        let flat = Flat::new(base, &em.vertices, &em.uv);
        let (d, rho) = flat.distortion(base, rp);
        if d <= params.max_distortion || rp <= rp_min * 1.0001 {
            if d.is_finite() {
                stats.max_distortion = stats.max_distortion.max(d);
            }
            return (flat, rho, rp);
        }
        stats.shrunk_patches += 1;
        rp = (rp * 0.75).max(rp_min);
    }
}
