//! One Python function per system, each calling the CLI subcommand's in-memory entry point with
//! the CLI's parameters and defaults (keyword arguments named as the flags, `-` as `_`).

use std::path::PathBuf;

use meshmatch::cli;
use meshmatch::correspondence::{Correspondence, CorrespondenceFile};
use meshmatch::mesh::TriMesh;
use meshmatch::meshmatch::TransferParams;
use meshmatch::synthesis::{quilting, weathering};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

use crate::job::{self, CancelToken};
use crate::mesh::{Mesh, usable_in};
use crate::{OrPy, refuse};

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(transfer, m)?)?;
    m.add_function(wrap_pyfunction!(complete, m)?)?;
    m.add_function(wrap_pyfunction!(update, m)?)?;
    m.add_function(wrap_pyfunction!(detail, m)?)?;
    m.add_function(wrap_pyfunction!(synthesize, m)?)?;
    m.add_function(wrap_pyfunction!(weather, m)?)?;
    m.add_function(wrap_pyfunction!(quilt, m)?)?;
    m.add_function(wrap_pyfunction!(curves, m)?)?;
    m.add_function(wrap_pyfunction!(features, m)?)?;
    m.add_function(wrap_pyfunction!(feature_maps, m)?)?;
    m.add_function(wrap_pyfunction!(bake, m)?)?;
    Ok(())
}

/// A result mesh for Python: no file of its own.
fn result(mut m: TriMesh) -> Mesh {
    m.path = None;
    Mesh::wrap(m)
}

/// The extension whose delivery a textured or untextured result is (`deliver`'s `ext`):
/// `textured` None = when the mesh has UVs.
fn ext_for(textured: Option<bool>, mesh: &TriMesh) -> &'static str {
    if textured.unwrap_or(mesh.uvs.is_some()) {
        "obj"
    } else {
        "ply"
    }
}

/// Solver settings shared by `transfer`, `complete`, `update` and `detail`, checked as the CLI
/// checks its flags.
#[allow(clippy::too_many_arguments)]
fn solve_params(
    vertices: usize,
    levels: Option<usize>,
    iterations: usize,
    tolerance: f32,
    seed: u64,
    shape_weight: f32,
    sharpen: bool,
) -> PyResult<TransferParams> {
    cli::common::VERTICES
        .check("--vertices", vertices)
        .or_py()?;
    if let Some(l) = levels {
        cli::common::LEVELS.check("--levels", l).or_py()?;
    }
    cli::common::ITERATIONS
        .check("--iterations", iterations)
        .or_py()?;
    let p = TransferParams {
        vertices,
        levels,
        iterations,
        tolerance,
        seed,
        shape_weight,
        sharpen,
        ..TransferParams::default()
    };
    p.validate().or_py()?;
    Ok(p)
}

/// Per-vertex flags from a mask argument: booleans, one per vertex, or vertex indices.
fn mask(a: &Bound<'_, PyAny>, n: usize, what: &str) -> PyResult<Vec<bool>> {
    if let Ok(flags) = a.extract::<Vec<bool>>() {
        if flags.len() != n {
            return refuse(format!(
                "{what}: {} flags for {n} vertices (give one boolean per vertex, or vertex \
                 indices)",
                flags.len()
            ));
        }
        return Ok(flags);
    }
    let np = a.py().import("numpy")?;
    let arr = np.call_method1("asarray", (a,))?;
    let kind: String = arr.getattr("dtype")?.getattr("kind")?.extract()?;
    if kind == "b" {
        let flags: Vec<bool> = arr.call_method0("tolist")?.extract()?;
        if flags.len() != n {
            return refuse(format!("{what}: {} flags for {n} vertices", flags.len()));
        }
        return Ok(flags);
    }
    let idx: Vec<i64> = arr
        .call_method1("reshape", (-1,))?
        .call_method0("tolist")?
        .extract()
        .map_err(|_| {
            crate::MeshMatchError::new_err(format!(
                "{what}: expected one boolean per vertex or a list of vertex indices"
            ))
        })?;
    let mut m = vec![false; n];
    for v in idx {
        if v < 0 || v as usize >= n {
            return refuse(format!(
                "{what}: vertex {v} out of range (the mesh has {n})"
            ));
        }
        m[v as usize] = true;
    }
    Ok(m)
}

/// Correspondences from a JSON file path, or pairs `(source_vertex, target_vertex)` /
/// `(source_vertex, [target_vertices])`, or an (n, 2) integer array.
fn correspondences(
    a: &Bound<'_, PyAny>,
    source: &TriMesh,
    target: &TriMesh,
) -> PyResult<Vec<Correspondence>> {
    if let Ok(p) = a.extract::<PathBuf>() {
        return a
            .py()
            .detach(|| CorrespondenceFile::load_for(&p, Some(source), Some(target)))
            .or_py();
    }
    let items: Vec<Bound<'_, PyAny>> = if a.hasattr("ndim")? {
        a.call_method0("tolist")?.extract()?
    } else {
        a.try_iter()?.collect::<PyResult<_>>()?
    };
    let mut out = Vec::with_capacity(items.len());
    for (i, it) in items.iter().enumerate() {
        let bad = || {
            crate::MeshMatchError::new_err(format!(
                "correspondences: pair {i} is not (source_vertex, target_vertex) or \
                 (source_vertex, [target_vertices])"
            ))
        };
        let (s, ts): (i64, Vec<i64>) = if let Ok((s, t)) = it.extract::<(i64, i64)>() {
            (s, vec![t])
        } else if let Ok((s, t)) = it.extract::<(i64, Vec<i64>)>() {
            (s, t)
        } else if let Ok(v) = it.extract::<Vec<i64>>() {
            if v.len() != 2 {
                return Err(bad());
            }
            (v[0], vec![v[1]])
        } else {
            return Err(bad());
        };
        if s < 0 || s as usize >= source.file_vertex_count {
            return refuse(format!(
                "correspondences: pair {i}: source vertex {s} out of range (the source has {} \
                 vertices)",
                source.file_vertex_count
            ));
        }
        if ts.is_empty() {
            return refuse(format!("correspondences: pair {i} has no target vertex"));
        }
        for &t in &ts {
            if t < 0 || t as usize >= target.file_vertex_count {
                return refuse(format!(
                    "correspondences: pair {i}: target vertex {t} out of range (the target has \
                     {} vertices)",
                    target.file_vertex_count
                ));
            }
        }
        out.push(Correspondence {
            source_vertex: s as u32,
            target_vertices: ts.into_iter().map(|t| t as u32).collect(),
        });
    }
    meshmatch::correspondence::check_limits(&out).or_py()?;
    Ok(out)
}

/// `--structure`: "auto" or a number from 0 to 1.
fn structure(a: &Bound<'_, PyAny>) -> PyResult<Option<f32>> {
    let text = if let Ok(x) = a.extract::<f64>() {
        x.to_string()
    } else {
        a.extract::<String>()?
    };
    cli::transfer::parse_structure(&text)
        .map(|s| s.0)
        .map_err(|e| crate::MeshMatchError::new_err(format!("--structure {text}: {e}")))
}

/// MeshMatch texture transfer (`meshmatch transfer`): the target with the source's look, as
/// per-vertex colours and, when the target has UVs (or `textured=True`), a texture baked into its
/// UVs (or a generated atlas) with the source read at full resolution.
#[pyfunction]
#[pyo3(signature = (source, target, correspondences=None, *,
    vertices=TransferParams::default().vertices, levels=None,
    iterations=TransferParams::default().iterations,
    tolerance=TransferParams::default().tolerance, seed=0,
    shape_weight=TransferParams::default().shape_weight,
    fine_shape_scale=TransferParams::default().fine_shape_scale, sharpen=true,
    structure=None, texture_size=None, textured=None, working_resolution=false,
    progress=None, cancel=None))]
#[allow(clippy::too_many_arguments)]
fn transfer(
    py: Python<'_>,
    source: &Mesh,
    target: &Mesh,
    correspondences: Option<&Bound<'_, PyAny>>,
    vertices: usize,
    levels: Option<usize>,
    iterations: usize,
    tolerance: f32,
    seed: u64,
    shape_weight: f32,
    fine_shape_scale: f32,
    sharpen: bool,
    structure: Option<&Bound<'_, PyAny>>,
    texture_size: Option<u32>,
    textured: Option<bool>,
    working_resolution: bool,
    progress: Option<&Bound<'_, PyAny>>,
    cancel: Option<&Bound<'_, CancelToken>>,
) -> PyResult<Mesh> {
    let mut params = solve_params(
        vertices,
        levels,
        iterations,
        tolerance,
        seed,
        shape_weight,
        sharpen,
    )?;
    params.fine_shape_scale = fine_shape_scale;
    params.structure = match structure {
        Some(s) => self::structure(s)?,
        None => None,
    };
    params.validate().or_py()?;
    let mut units = cli::common::WorkingUnits::new();
    let src = usable_in(py, source, "source", &mut units)?;
    if src.vertex_signal().is_none() {
        return refuse("source: carries no texture or vertex colours to transfer");
    }
    let tgt = usable_in(py, target, "target", &mut units)?;
    let corr = match correspondences {
        Some(c) => self::correspondences(c, &src, &tgt)?,
        None => Vec::new(),
    };
    let size = cli::common::texture_side(texture_size, &tgt);
    let ext = ext_for(textured, &tgt);
    let t = job::run(py, progress, cancel, |ctx| {
        cli::transfer::transfer_meshes(
            &src,
            &tgt,
            &corr,
            &params,
            &cli::transfer::Delivery {
                ext,
                texture_size: size,
                full_resolution: !working_resolution,
                dense: false,
            },
            &|e| ctx.event(e),
            &ctx.cancel,
        )
    })?;
    Ok(result(units.to_file(&t.delivered.mesh).into_owned()))
}

/// Completion by example (`meshmatch complete`): the vertices flagged by `mask` (booleans per
/// vertex, or vertex indices) are synthesised from the rest of the mesh's colours or texture;
/// or, with `painted` (a copy of the mesh whose colours were painted), its vertices of the
/// `clay` colour (R, G, B 0-255; default the most frequent colour) are synthesised from its
/// painted ones. Painted vertices keep their colours exactly.
#[pyfunction]
#[pyo3(signature = (mesh, mask=None, *, painted=None, clay=None,
    vertices=TransferParams::default().vertices, levels=None,
    iterations=TransferParams::default().iterations,
    tolerance=TransferParams::default().tolerance, seed=0,
    shape_weight=TransferParams::default().shape_weight, sharpen=true,
    texture_size=None, textured=None, progress=None, cancel=None))]
#[allow(clippy::too_many_arguments)]
fn complete(
    py: Python<'_>,
    mesh: &Mesh,
    mask: Option<&Bound<'_, PyAny>>,
    painted: Option<&Mesh>,
    clay: Option<(u8, u8, u8)>,
    vertices: usize,
    levels: Option<usize>,
    iterations: usize,
    tolerance: f32,
    seed: u64,
    shape_weight: f32,
    sharpen: bool,
    texture_size: Option<u32>,
    textured: Option<bool>,
    progress: Option<&Bound<'_, PyAny>>,
    cancel: Option<&Bound<'_, CancelToken>>,
) -> PyResult<Mesh> {
    let params = solve_params(
        vertices,
        levels,
        iterations,
        tolerance,
        seed,
        shape_weight,
        sharpen,
    )?;
    let mut units = cli::common::WorkingUnits::new();
    let m = usable_in(py, mesh, "mesh", &mut units)?;
    let painted = painted
        .map(|p| usable_in(py, p, "painted", &mut units))
        .transpose()?;
    let clay = clay.map(|(r, g, b)| [r as f32 / 255.0, g as f32 / 255.0, b as f32 / 255.0]);
    let example = match (&painted, mask) {
        (Some(_), Some(_)) => return refuse("complete: give mask or painted, not both"),
        (Some(p), None) => cli::complete::Example::Painted(p, clay),
        (None, Some(k)) => {
            cli::complete::Example::Mask(self::mask(k, m.file_vertex_count, "mask")?)
        }
        (None, None) => return refuse("complete needs mask= or painted="),
    };
    let ext = ext_for(textured, &m);
    let c = job::run(py, progress, cancel, |ctx| {
        cli::complete::complete_mesh(
            m,
            example,
            &params,
            ext,
            texture_size,
            &|e| ctx.event(e),
            &ctx.cancel,
        )
    })?;
    Ok(result(units.to_file(&c.mesh).into_owned()))
}

/// Texture update after a geometry edit (`meshmatch update`): `new` with `old`'s colours or
/// texture, copied where the surfaces coincide and synthesised where they changed.
#[pyfunction]
#[pyo3(signature = (old, new, *, vertices=TransferParams::default().vertices, levels=None,
    iterations=TransferParams::default().iterations,
    tolerance=TransferParams::default().tolerance, seed=0,
    shape_weight=TransferParams::default().shape_weight, sharpen=true,
    texture_size=None, textured=None, progress=None, cancel=None))]
#[allow(clippy::too_many_arguments)]
fn update(
    py: Python<'_>,
    old: &Mesh,
    new: &Mesh,
    vertices: usize,
    levels: Option<usize>,
    iterations: usize,
    tolerance: f32,
    seed: u64,
    shape_weight: f32,
    sharpen: bool,
    texture_size: Option<u32>,
    textured: Option<bool>,
    progress: Option<&Bound<'_, PyAny>>,
    cancel: Option<&Bound<'_, CancelToken>>,
) -> PyResult<Mesh> {
    let params = solve_params(
        vertices,
        levels,
        iterations,
        tolerance,
        seed,
        shape_weight,
        sharpen,
    )?;
    let mut units = cli::common::WorkingUnits::new();
    let o = usable_in(py, old, "old", &mut units)?;
    let n = usable_in(py, new, "new", &mut units)?;
    let ext = ext_for(textured, &n);
    let (out, _) = job::run(py, progress, cancel, |ctx| {
        cli::update::update_mesh(
            &o,
            &n,
            &params,
            ext,
            texture_size,
            &|e| ctx.event(e),
            &ctx.cancel,
        )
    })?;
    Ok(result(units.to_file(&out).into_owned()))
}

/// Detail transfer (`meshmatch detail`): the target at the working resolution, displaced along
/// its normals by the source's geometric detail (`strength` scales it).
#[pyfunction]
#[pyo3(signature = (source, target, *, strength=1.0,
    vertices=TransferParams::default().vertices, levels=None,
    iterations=TransferParams::default().iterations,
    tolerance=TransferParams::default().tolerance, seed=0,
    shape_weight=meshmatch::applications::DETAIL_SHAPE_WEIGHT, sharpen=true,
    progress=None, cancel=None))]
#[allow(clippy::too_many_arguments)]
fn detail(
    py: Python<'_>,
    source: &Mesh,
    target: &Mesh,
    strength: f32,
    vertices: usize,
    levels: Option<usize>,
    iterations: usize,
    tolerance: f32,
    seed: u64,
    shape_weight: f32,
    sharpen: bool,
    progress: Option<&Bound<'_, PyAny>>,
    cancel: Option<&Bound<'_, CancelToken>>,
) -> PyResult<Mesh> {
    let params = solve_params(
        vertices,
        levels,
        iterations,
        tolerance,
        seed,
        shape_weight,
        sharpen,
    )?;
    let mut units = cli::common::WorkingUnits::new();
    let s = usable_in(py, source, "source", &mut units)?;
    let t = usable_in(py, target, "target", &mut units)?;
    let r = job::run(py, progress, cancel, |ctx| {
        cli::detail::detail_mesh(&s, &t, strength, &params, &|e| ctx.event(e), &ctx.cancel)
    })?;
    Ok(result(units.to_file(&r.mesh).into_owned()))
}

/// Texture synthesis over a mesh from an exemplar image (`meshmatch synth`, Wei and Levoy
/// 2001): `exemplar` is an (H, W, 3 or 4) array (alpha: transparent pixels are never used) or an
/// image path. `output="texture"`: the target with the result baked into a texture of
/// `texture_size` (through its UVs or a generated atlas); `output="dense"`: the uniform-density
/// synthesized mesh with vertex colours (or displaced, with `displace=True`).
#[pyfunction]
#[pyo3(signature = (exemplar, target, *, texture_size=2048, scale=None, exemplar_width=None,
    vertex_budget=meshmatch::synthesis::exemplar::DEFAULT_VERTEX_BUDGET,
    orientation="auto".to_string(), levels=4, mask=None,
    search=meshmatch::synthesis::Search::default().as_str().to_string(), seed=0,
    displace=false, method="auto".to_string(),
    align_features=false, feature_mask=None, space="auto".to_string(),
    texel_budget=meshmatch::synthesis::exemplar::DEFAULT_TEXEL_BUDGET,
    output="texture".to_string(), progress=None, cancel=None))]
#[allow(clippy::too_many_arguments)]
fn synthesize(
    py: Python<'_>,
    exemplar: &Bound<'_, PyAny>,
    target: &Mesh,
    texture_size: u32,
    scale: Option<f32>,
    exemplar_width: Option<u32>,
    vertex_budget: usize,
    orientation: String,
    levels: usize,
    mask: Option<&Bound<'_, PyAny>>,
    search: String,
    seed: u64,
    displace: bool,
    method: String,
    align_features: bool,
    feature_mask: Option<&Bound<'_, PyAny>>,
    space: String,
    texel_budget: usize,
    output: String,
    progress: Option<&Bound<'_, PyAny>>,
    cancel: Option<&Bound<'_, CancelToken>>,
) -> PyResult<Mesh> {
    let out = match output.as_str() {
        "texture" => "result.glb",
        "dense" => "result.ply",
        o => return refuse(format!("output {o}: use texture or dense")),
    };
    let given = PathBuf::from("(array)");
    let args = cli::exemplar::SynthArgs {
        exemplar: PathBuf::from("exemplar"),
        target: PathBuf::from("target"),
        out: PathBuf::from(out),
        out_dense: None,
        texture_size,
        scale,
        exemplar_width,
        vertex_budget,
        orientation,
        levels,
        mask: mask.map(|_| given.clone()),
        search,
        seed,
        displace,
        method,
        align_features,
        feature_mask: feature_mask.map(|_| given.clone()),
        space,
        texel_budget,
    };
    let plan = cli::exemplar::check(&args).or_py()?;
    let (rgb, alpha, name) = match exemplar.extract::<PathBuf>() {
        Ok(p) if !exemplar.hasattr("shape")? => {
            let (tex, alpha) = py
                .detach(|| meshmatch::mesh::io::load_texture_with_alpha(&p))
                .or_py()?;
            (tex.image, alpha, p)
        }
        _ => {
            let (rgb, alpha) = crate::mesh::image(exemplar, "exemplar")?;
            (rgb, alpha, PathBuf::from("exemplar"))
        }
    };
    let (rgb, alpha) = cli::exemplar::prepare_exemplar(&args, rgb, alpha, &name).or_py()?;
    let mut units = cli::common::WorkingUnits::new();
    let t = usable_in(py, target, "target", &mut units)?;
    // scale is a length in the target's units, as `meshmatch synth --scale`
    let args = cli::exemplar::SynthArgs {
        scale: args.scale.map(|s| units.length(s)),
        ..args
    };
    let file_mask = mask
        .map(|m| self::mask(m, t.file_vertex_count, "mask"))
        .transpose()?;
    let feature_mask = match feature_mask {
        Some(f) => {
            let (rgb, _) = crate::mesh::image(f, "feature_mask")?;
            Some(image::DynamicImage::ImageRgb8(rgb).to_luma8())
        }
        None => None,
    };
    let s = job::run(py, progress, cancel, |ctx| {
        cli::exemplar::synthesize(
            &args,
            &plan,
            &rgb,
            alpha.as_ref(),
            &t,
            file_mask.as_deref(),
            feature_mask.as_ref(),
            &|e| ctx.event(e),
            &ctx.cancel,
        )
    })?;
    Ok(result(units.to_file(&s.mesh).into_owned()))
}

/// Geometry-correlated transfer (`meshmatch weather`, Mertens et al. 2006): weathering, dirt or
/// moss learned from the source's look and geometry, applied to the target by its geometry;
/// colours per target vertex and, when the target has UVs (or `textured=True`), a texture.
/// `mask` leaves source vertices out of training.
#[pyfunction]
#[pyo3(signature = (source, target, *, mask=None, method="parametric".to_string(),
    up="y".to_string(), vertices=weathering::Params::default().working_vertices,
    rays=weathering::Params::default().rays, clusters=weathering::Params::default().clusters,
    seed=0, components=None, mean="neighbours".to_string(), texture_size=1024, textured=None,
    progress=None, cancel=None))]
#[allow(clippy::too_many_arguments)]
fn weather(
    py: Python<'_>,
    source: &Mesh,
    target: &Mesh,
    mask: Option<&Bound<'_, PyAny>>,
    method: String,
    up: String,
    vertices: usize,
    rays: usize,
    clusters: usize,
    seed: u64,
    components: Option<Vec<usize>>,
    mean: String,
    texture_size: u32,
    textured: Option<bool>,
    progress: Option<&Bound<'_, PyAny>>,
    cancel: Option<&Bound<'_, CancelToken>>,
) -> PyResult<Mesh> {
    let method: weathering::Method = method.parse().or_py()?;
    let mean: weathering::Mean = mean.parse().or_py()?;
    let up: weathering::Up = up.parse().or_py()?;
    cli::weathering::check_weather(vertices, rays, clusters, texture_size).or_py()?;
    if let Some(c) = &components {
        weathering::check_components(c, weathering::Params::default().cca_dims).or_py()?;
    }
    let mut units = cli::common::WorkingUnits::new();
    let s = usable_in(py, source, "source", &mut units)?;
    let t = usable_in(py, target, "target", &mut units)?;
    let mask = mask
        .map(|m| self::mask(m, s.file_vertex_count, "mask"))
        .transpose()?;
    let params = weathering::Params {
        working_vertices: vertices,
        up,
        rays,
        clusters,
        method,
        mean,
        seed,
        components,
        ..weathering::Params::default()
    };
    let ext = ext_for(textured, &t);
    let w = job::run(py, progress, cancel, |ctx| {
        cli::weathering::weather_meshes(
            &s,
            &t,
            mask.as_deref(),
            &params,
            ext,
            texture_size,
            &|e| ctx.event(e),
            &ctx.cancel,
        )
    })?;
    Ok(result(units.to_file(&w.delivered.mesh).into_owned()))
}

/// `quilt`'s swatch: a `Mesh`, or a built-in name or a file path.
#[derive(FromPyObject)]
enum SwatchArg {
    Mesh(Mesh),
    Spec(PathBuf),
}

/// Mesh quilting (`meshmatch quilt`, Zhou et al. 2006): the base covered with 3D elements of a
/// swatch, a built-in one by name (chain, weave, nuts, studs, scales), a swatch mesh file, or a
/// `Mesh` whose elements (connected components) lie over the plane normal to `swatch_up`.
/// Returns `(elements, element_ids)`: the elements as one mesh and, per vertex, its element.
#[pyfunction]
#[pyo3(signature = (base, swatch=SwatchArg::Spec(PathBuf::from("chain")), *, swatch_size=None, thickness=None,
    swatch_up="z".to_string(), seed=quilting::Params::default().seed, merge=false, nudge=true,
    fill=true, trim=true, relink=true, lattice=true, progress=None, cancel=None))]
#[allow(clippy::too_many_arguments)]
fn quilt<'py>(
    py: Python<'py>,
    base: &Mesh,
    swatch: SwatchArg,
    swatch_size: Option<f32>,
    thickness: Option<f32>,
    swatch_up: String,
    seed: u64,
    merge: bool,
    nudge: bool,
    fill: bool,
    trim: bool,
    relink: bool,
    lattice: bool,
    progress: Option<&Bound<'py, PyAny>>,
    cancel: Option<&Bound<'py, CancelToken>>,
) -> PyResult<(Mesh, Bound<'py, PyAny>)> {
    cli::quilting::positive("swatch-size", swatch_size).or_py()?;
    cli::quilting::positive("thickness", thickness).or_py()?;
    let sw = match swatch {
        SwatchArg::Mesh(m) => {
            let axis = match swatch_up.to_ascii_lowercase().as_str() {
                "x" => quilting::Axis::X,
                "y" => quilting::Axis::Y,
                "z" => quilting::Axis::Z,
                _ => return refuse(format!("--swatch-up {swatch_up}: use x, y or z")),
            };
            quilting::load_swatch((*m.inner).clone(), axis).or_py()?
        }
        SwatchArg::Spec(p) => {
            let spec = p.to_string_lossy().into_owned();
            py.detach(|| cli::quilting::load_any_swatch(&spec, &swatch_up, seed))
                .or_py()?
        }
    };
    let mut units = cli::common::WorkingUnits::new();
    let b = usable_in(py, base, "base", &mut units)?;
    let params = quilting::Params {
        swatch_size: swatch_size.map(|x| units.length(x)),
        thickness: thickness.map(|x| units.length(x)),
        seed,
        merge_elements: merge,
        nudge,
        fill,
        trim,
        relink,
        lattice,
        ..quilting::Params::default()
    };
    let out = job::run(py, progress, cancel, |ctx| {
        let input = quilting::Input {
            base: &b,
            swatch: &sw,
            field: None,
        };
        quilting::run(&input, &params, &|e| ctx.event(e), &ctx.cancel)
    })?;
    let ids: Vec<i64> = out.element_id.iter().map(|&e| e as i64).collect();
    let mut elements = out.elements;
    for p in &mut elements.positions {
        *p = units.file_point(*p);
    }
    Ok((result(elements), PyArray1::from_vec(py, ids).into_any()))
}

/// Salient curves (`meshmatch curves`: crest lines and sharp creases, Xu et al. 2009 §4.1) as a
/// list of dicts: `points` (K, 3) float32 on the surface, `vertices` the snapped vertex path,
/// `kind` ("ridge", "ravine" or "crease"), `strength`, `length` and `closed`.
#[pyfunction]
#[pyo3(signature = (mesh, *,
    threshold=meshmatch::geometry::CurveParams::default().threshold, min_length=None,
    crease_angle=meshmatch::geometry::CurveParams::default().crease_angle_deg,
    creases_only=false, progress=None, cancel=None))]
#[allow(clippy::too_many_arguments)]
fn curves<'py>(
    py: Python<'py>,
    mesh: &Mesh,
    threshold: f32,
    min_length: Option<f32>,
    crease_angle: f32,
    creases_only: bool,
    progress: Option<&Bound<'py, PyAny>>,
    cancel: Option<&Bound<'py, CancelToken>>,
) -> PyResult<Bound<'py, PyList>> {
    use meshmatch::geometry::{CurveKind, CurveParams, salient_curves};
    cli::feature_aligned::check_curves(threshold, min_length, crease_angle).or_py()?;
    let mut units = cli::common::WorkingUnits::new();
    let m = usable_in(py, mesh, "mesh", &mut units)?;
    let params = CurveParams {
        threshold,
        min_length: min_length.map(|l| units.length(l)),
        crease_angle_deg: crease_angle,
        crest_lines: !creases_only,
        ..CurveParams::default()
    };
    let cs = job::run(py, progress, cancel, |_| {
        salient_curves(&m.positions, &m.faces, &params)
    })?;
    let list = PyList::empty(py);
    for c in &cs {
        let d = PyDict::new(py);
        let flat: Vec<f32> = c
            .points
            .iter()
            .flat_map(|&p| units.file_position(p))
            .collect();
        d.set_item(
            "points",
            PyArray1::from_vec(py, flat).reshape([c.points.len(), 3])?,
        )?;
        let vs: Vec<i64> = c
            .vertices
            .iter()
            .map(|&v| m.file_index.get(v as usize).copied().unwrap_or(v) as i64)
            .collect();
        d.set_item("vertices", PyArray1::from_vec(py, vs))?;
        d.set_item(
            "kind",
            match c.kind {
                CurveKind::Ridge => "ridge",
                CurveKind::Ravine => "ravine",
                CurveKind::Crease => "crease",
            },
        )?;
        d.set_item("strength", c.strength)?;
        d.set_item("length", units.file_length(c.length()))?;
        d.set_item("closed", c.closed)?;
        list.append(d)?;
    }
    Ok(list)
}

/// One geometric feature per vertex (`meshmatch features`): `ao`, `height`, `curvature[:i]`,
/// `normal-x|y|z`, `occlusion-x|y|z`, as the system computes it (not stretched to grey), (N,)
/// float32.
#[pyfunction]
#[pyo3(signature = (mesh, feature="ao".to_string(), *, up="y".to_string(),
    rays=weathering::Params::default().rays, seed=0, progress=None, cancel=None))]
#[allow(clippy::too_many_arguments)]
fn features<'py>(
    py: Python<'py>,
    mesh: &Mesh,
    feature: String,
    up: String,
    rays: usize,
    seed: u64,
    progress: Option<&Bound<'py, PyAny>>,
    cancel: Option<&Bound<'py, CancelToken>>,
) -> PyResult<Bound<'py, PyAny>> {
    let up: weathering::Up = up.parse().or_py()?;
    let mut units = cli::common::WorkingUnits::new();
    let m = usable_in(py, mesh, "mesh", &mut units)?;
    let params = weathering::Params {
        up,
        rays,
        seed,
        ..weathering::Params::default()
    };
    let v = job::run(py, progress, cancel, |ctx| {
        cli::features::feature_values(&m, &feature, &params, &ctx.cancel)
    })?;
    Ok(PyArray1::from_vec(py, v).into_any())
}

/// The feature maps artists bake (`meshmatch features --out X.png`): `feature` is `all`, one of
/// ao, curvature, cavity, thickness, normal, height, or a comma-separated list; baked in the
/// mesh's UVs (a generated atlas when it has none, or with `new_atlas`), gutters filled. Returns
/// a dict name -> float32 array in [0, 1], (size, size) grey or (size, size, 3) for the normal,
/// row 0 at the top, before the PNG's quantisation.
#[pyfunction]
#[pyo3(signature = (mesh, feature="all".to_string(), *, texture_size=2048,
    radius=weathering::feature_maps::MapParams::default().radius,
    cavity_radius=weathering::feature_maps::MapParams::default().cavity_radius,
    up="y".to_string(), rays=weathering::Params::default().rays, seed=0, new_atlas=false,
    progress=None, cancel=None))]
#[allow(clippy::too_many_arguments)]
fn feature_maps<'py>(
    py: Python<'py>,
    mesh: &Mesh,
    feature: String,
    texture_size: u32,
    radius: f32,
    cavity_radius: f32,
    up: String,
    rays: usize,
    seed: u64,
    new_atlas: bool,
    progress: Option<&Bound<'py, PyAny>>,
    cancel: Option<&Bound<'py, CancelToken>>,
) -> PyResult<Bound<'py, PyDict>> {
    use weathering::feature_maps as fm;
    let up: weathering::Up = up.parse().or_py()?;
    let names = fm::parse_map_names(&feature).or_py()?;
    cli::common::check_texture_size(texture_size).or_py()?;
    let params = fm::MapParams {
        texture_size,
        radius,
        cavity_radius,
        rays,
        seed,
        up,
        new_atlas,
    };
    fm::check_map_params(&params).or_py()?;
    let mut units = cli::common::WorkingUnits::new();
    let m = usable_in(py, mesh, "mesh", &mut units)?;
    let maps = job::run(py, progress, cancel, |ctx| {
        fm::bake_feature_maps(
            &m,
            &names,
            &params,
            &|f| {
                ctx.event(meshmatch::work::Event::Progress(
                    meshmatch::work::Progress {
                        stage: "feature maps",
                        fraction: f,
                        ..Default::default()
                    },
                ))
            },
            &ctx.cancel,
        )
    })?;
    let out = PyDict::new(py);
    for map in &maps.maps {
        let (w, h) = (map.image.width, map.image.height);
        let arr = if map.channels == 1 {
            let v: Vec<f32> = map.image.pixels.iter().map(|p| p[0]).collect();
            PyArray1::from_vec(py, v).reshape([h, w])?.into_any()
        } else {
            let v: Vec<f32> = map.image.pixels.iter().flatten().copied().collect();
            PyArray1::from_vec(py, v).reshape([h, w, 3])?.into_any()
        };
        out.set_item(map.name, arr)?;
    }
    Ok(out)
}

/// Bake (`meshmatch bake`): `source`'s colours or texture baked into a texture of `texture_size`
/// on `target` (same shape), through its UVs or a generated atlas (always with `new_atlas`).
#[pyfunction]
#[pyo3(signature = (source, target, *, texture_size=2048, new_atlas=false, progress=None,
    cancel=None))]
fn bake(
    py: Python<'_>,
    source: &Mesh,
    target: &Mesh,
    texture_size: u32,
    new_atlas: bool,
    progress: Option<&Bound<'_, PyAny>>,
    cancel: Option<&Bound<'_, CancelToken>>,
) -> PyResult<Mesh> {
    cli::common::check_texture_size(texture_size).or_py()?;
    let mut units = cli::common::WorkingUnits::new();
    let s = usable_in(py, source, "source", &mut units)?;
    let t = usable_in(py, target, "target", &mut units)?;
    let (out, _) = job::run(py, progress, cancel, |ctx| {
        cli::bake::bake_mesh(
            &t,
            &s,
            texture_size,
            new_atlas,
            &|f| ctx.fraction(f, "bake"),
            &ctx.cancel,
        )
    })?;
    Ok(result(units.to_file(&out).into_owned()))
}
