//! `meshmatch.Mesh`: a triangle mesh with optional colours, UVs and texture, as numpy arrays;
//! `meshmatch.load` and `Mesh.save` through the library's loaders and writers.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use meshmatch::mesh::{Texture, TriMesh, io};
use numpy::{
    AllowTypeChange, PyArray1, PyArrayLike2, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3,
};
use pyo3::prelude::*;

use crate::{OrPy, refuse};

/// A triangle mesh: `vertices` (N, 3), `faces` (F, 3), and optionally `colors` (N, 3) sRGB in
/// [0, 1], `uvs` (3F, 2) per face corner (V up), `texture` (H, W, 3) uint8 sRGB, row 0 at the
/// top. Arrays read back are copies; results of meshmatch calls are new meshes.
#[pyclass(module = "meshmatch", name = "Mesh", frozen, from_py_object)]
#[derive(Clone)]
pub struct Mesh {
    pub(crate) inner: Arc<TriMesh>,
    /// The coordinates as its file gives them, at the file's precision (a mesh from `load`), so
    /// that a system's working units are the command line's.
    pub(crate) exact: Option<Arc<Vec<[f64; 3]>>>,
}

impl Mesh {
    pub fn wrap(m: TriMesh) -> Self {
        Mesh {
            inner: Arc::new(m),
            exact: None,
        }
    }
}

/// Flat `[f32; K]` rows from any (n, K) array-like (lists, float64, ints).
fn rows<const K: usize>(a: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f32; K]>> {
    let arr: PyArrayLike2<f32, AllowTypeChange> = a.extract().map_err(|_| {
        crate::MeshMatchError::new_err(format!(
            "{what}: expected an array of shape (n, {K}) of numbers"
        ))
    })?;
    let v = arr.as_array();
    if v.ncols() != K {
        return refuse(format!(
            "{what}: expected shape (n, {K}), got ({}, {})",
            v.nrows(),
            v.ncols()
        ));
    }
    let mut out = Vec::with_capacity(v.nrows());
    for r in v.rows() {
        let mut x = [0.0f32; K];
        for (k, xk) in x.iter_mut().enumerate() {
            *xk = r[k];
        }
        out.push(x);
    }
    Ok(out)
}

/// Per-vertex colours from (n, 3) or (n, 4) floats in [0, 1], or uint8 0-255; alpha dropped.
fn colors(a: &Bound<'_, PyAny>, n: usize) -> PyResult<Vec<[f32; 3]>> {
    let (vals, scale): (Vec<Vec<f32>>, f32) = if let Ok(u) = a.extract::<PyReadonlyArray2<u8>>() {
        let v = u.as_array();
        (
            v.rows()
                .into_iter()
                .map(|r| r.iter().map(|&x| x as f32).collect())
                .collect(),
            1.0 / 255.0,
        )
    } else {
        let arr: PyArrayLike2<f32, AllowTypeChange> = a.extract().map_err(|_| {
            crate::MeshMatchError::new_err(
                "colors: expected an array of shape (n, 3) or (n, 4) of numbers",
            )
        })?;
        let v = arr.as_array();
        (
            v.rows()
                .into_iter()
                .map(|r| r.iter().copied().collect())
                .collect(),
            1.0,
        )
    };
    if vals.len() != n {
        return refuse(format!(
            "colors: {} rows for {n} vertices (one colour per vertex)",
            vals.len()
        ));
    }
    let mut out = Vec::with_capacity(n);
    for (i, r) in vals.iter().enumerate() {
        if r.len() != 3 && r.len() != 4 {
            return refuse(format!(
                "colors: expected 3 (RGB) or 4 (RGBA) columns, got {}",
                r.len()
            ));
        }
        let c = [r[0] * scale, r[1] * scale, r[2] * scale];
        if !c.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)) {
            return refuse(format!(
                "colors: vertex {i} has {c:?}; use sRGB values from 0 to 1 (or uint8)"
            ));
        }
        out.push(c);
    }
    Ok(out)
}

/// Per-corner UVs (3F, 2) from (3F, 2), (F, 3, 2) or per-vertex (N, 2) arrays.
fn uvs(a: &Bound<'_, PyAny>, faces: &[[u32; 3]], n: usize) -> PyResult<Vec<[f32; 2]>> {
    let np = a.py().import("numpy")?;
    let arr = np.call_method1("asarray", (a, "float32"))?;
    let shape: Vec<usize> = arr.getattr("shape")?.extract()?;
    let flat = match shape.as_slice() {
        [f, 3, 2] if *f == faces.len() => arr.call_method1("reshape", ((3 * f, 2),))?,
        [_, 2] => arr,
        _ => {
            return refuse(format!(
                "uvs: expected shape (3F, 2) per face corner, (F, 3, 2) or (N, 2) per vertex; got \
                 {shape:?} for {} faces and {n} vertices",
                faces.len()
            ));
        }
    };
    let v: Vec<[f32; 2]> = rows::<2>(&flat, "uvs")?;
    if v.len() == 3 * faces.len() {
        Ok(v)
    } else if v.len() == n {
        Ok(faces
            .iter()
            .flat_map(|f| f.map(|i| v[i as usize]))
            .collect())
    } else {
        refuse(format!(
            "uvs: {} rows: give one per face corner (3 x {} faces) or one per vertex ({n})",
            v.len(),
            faces.len()
        ))
    }
}

/// An sRGB image from (H, W, 3) or (H, W, 4) uint8 (or floats in [0, 1]); the alpha, if any.
pub fn image(
    a: &Bound<'_, PyAny>,
    what: &str,
) -> PyResult<(image::RgbImage, Option<image::GrayImage>)> {
    let arr: PyReadonlyArray3<u8> = match a.extract::<PyReadonlyArray3<u8>>() {
        Ok(u) => u,
        Err(_) => {
            let np = a.py().import("numpy")?;
            let f = np.call_method1("asarray", (a, "float32"))?;
            let ndim: usize = f.getattr("ndim")?.extract()?;
            if ndim != 3 {
                return refuse(format!(
                    "{what}: expected an image array of shape (height, width, 3 or 4)"
                ));
            }
            let ok: bool = np
                .call_method1("all", (np.call_method1("isfinite", (&f,))?,))?
                .extract()?;
            if !ok {
                return refuse(format!("{what}: has values that are not finite numbers"));
            }
            let scaled = np.call_method1(
                "rint",
                (np.call_method1("clip", (f.call_method1("__mul__", (255.0,))?, 0, 255))?,),
            )?;
            scaled.call_method1("astype", ("uint8",))?.extract()?
        }
    };
    let v = arr.as_array();
    let (h, w, c) = v.dim();
    if h == 0 || w == 0 || !(c == 3 || c == 4) {
        return refuse(format!(
            "{what}: expected shape (height, width, 3 or 4) with height and width at least 1, got \
             ({h}, {w}, {c})"
        ));
    }
    let mut rgb = image::RgbImage::new(w as u32, h as u32);
    let mut alpha = (c == 4).then(|| image::GrayImage::new(w as u32, h as u32));
    for y in 0..h {
        for x in 0..w {
            rgb.put_pixel(
                x as u32,
                y as u32,
                image::Rgb([v[[y, x, 0]], v[[y, x, 1]], v[[y, x, 2]]]),
            );
            if let Some(al) = alpha.as_mut() {
                al.put_pixel(x as u32, y as u32, image::Luma([v[[y, x, 3]]]));
            }
        }
    }
    Ok((rgb, alpha))
}

/// (n, K) float32 array from rows.
fn array2<'py, const K: usize>(py: Python<'py>, rows: &[[f32; K]]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f32> = rows.iter().flatten().copied().collect();
    Ok(PyArray1::from_vec(py, flat)
        .reshape([rows.len(), K])?
        .into_any())
}

#[pymethods]
impl Mesh {
    #[new]
    #[pyo3(signature = (vertices, faces, colors=None, uvs=None, texture=None))]
    fn new(
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        colors: Option<&Bound<'_, PyAny>>,
        uvs: Option<&Bound<'_, PyAny>>,
        texture: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let positions = rows::<3>(vertices, "vertices")?;
        let n = positions.len();
        let f: PyArrayLike2<i64, AllowTypeChange> = faces.extract().map_err(|_| {
            crate::MeshMatchError::new_err("faces: expected an integer array of shape (F, 3)")
        })?;
        let fv = f.as_array();
        if fv.ncols() != 3 {
            return refuse(format!(
                "faces: expected shape (F, 3) (triangles), got ({}, {})",
                fv.nrows(),
                fv.ncols()
            ));
        }
        let mut tris = Vec::with_capacity(fv.nrows());
        for (i, r) in fv.rows().into_iter().enumerate() {
            let mut t = [0u32; 3];
            for k in 0..3 {
                let x = r[k];
                if x < 0 || x as usize >= n {
                    return refuse(format!(
                        "faces: face {i} names vertex {x}, but there are {n} vertices (0 to {})",
                        n.saturating_sub(1)
                    ));
                }
                t[k] = x as u32;
            }
            tris.push(t);
        }
        let mut m = TriMesh::new(positions, tris);
        if let Some(c) = colors {
            m.colors = Some(self::colors(c, n)?);
        }
        if let Some(u) = uvs {
            m.uvs = Some(self::uvs(u, &m.faces, n)?);
        }
        if let Some(t) = texture {
            if m.uvs.is_none() {
                return refuse("texture: a texture needs uvs");
            }
            let (rgb, _) = image(t, "texture")?;
            m.texture = Some(Arc::new(Texture {
                image: rgb,
                path: None,
            }));
        }
        Ok(Mesh::wrap(m))
    }

    /// Vertex positions, (N, 3) float32.
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        array2(py, &self.inner.positions)
    }

    /// Triangles as vertex indices, (F, 3) int32.
    #[getter]
    fn faces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let flat: Vec<i32> = self
            .inner
            .faces
            .iter()
            .flatten()
            .map(|&i| i as i32)
            .collect();
        Ok(PyArray1::from_vec(py, flat)
            .reshape([self.inner.faces.len(), 3])?
            .into_any())
    }

    /// Per-vertex sRGB colours in [0, 1], (N, 3) float32, or None.
    #[getter]
    fn colors<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner
            .colors
            .as_ref()
            .map(|c| array2(py, c))
            .transpose()
    }

    /// Per face corner texture coordinates (V up), (3F, 2) float32: corner k of face f is row
    /// 3f + k. None without UVs.
    #[getter]
    fn uvs<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner.uvs.as_ref().map(|u| array2(py, u)).transpose()
    }

    /// Per-vertex normals from the file, (N, 3) float32, or None.
    #[getter]
    fn normals<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.inner
            .normals
            .as_ref()
            .map(|n| array2(py, n))
            .transpose()
    }

    /// The texture, (H, W, 3) uint8 sRGB, row 0 at the top; None without one.
    #[getter]
    fn texture<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        match &self.inner.texture {
            None => Ok(None),
            Some(t) => {
                let (w, h) = t.image.dimensions();
                Ok(Some(
                    PyArray1::from_vec(py, t.image.as_raw().clone())
                        .reshape([h as usize, w as usize, 3])?
                        .into_any(),
                ))
            }
        }
    }

    /// For each vertex, its index in the file it was loaded from (the identity for meshes made
    /// from arrays; loading drops vertices no face uses), (N,) int64.
    #[getter]
    fn file_index<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        let v: Vec<i64> = self.inner.file_index.iter().map(|&i| i as i64).collect();
        PyArray1::from_vec(py, v).into_any()
    }

    /// Number of vertices.
    #[getter]
    fn num_vertices(&self) -> usize {
        self.inner.num_vertices()
    }

    /// Number of triangles.
    #[getter]
    fn num_faces(&self) -> usize {
        self.inner.num_faces()
    }

    /// A copy with other colours, (N, 3) or (N, 4) in [0, 1] or uint8 (None removes them).
    #[pyo3(signature = (colors))]
    fn with_colors(&self, colors: Option<&Bound<'_, PyAny>>) -> PyResult<Self> {
        let mut m = (*self.inner).clone();
        m.colors = colors
            .map(|c| self::colors(c, m.num_vertices()))
            .transpose()?;
        Ok(Mesh::wrap(m))
    }

    /// Write the mesh by extension: .ply (vertex colours), .glb or .gltf (COLOR_0 and/or the
    /// texture as baseColorTexture), .obj (+ .mtl + PNG texture).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let m = self.inner.clone();
        py.detach(move || io::save(&m, &path)).or_py()
    }

    fn __repr__(&self) -> String {
        let m = &self.inner;
        let mut extra = String::new();
        if m.colors.is_some() {
            extra.push_str(", colors");
        }
        if m.uvs.is_some() {
            extra.push_str(", uvs");
        }
        if let Some(t) = &m.texture {
            extra.push_str(&format!(
                ", texture {}x{}",
                t.image.width(),
                t.image.height()
            ));
        }
        format!(
            "Mesh({} vertices, {} faces{extra})",
            m.num_vertices(),
            m.num_faces()
        )
    }
}

/// Load a mesh file (.obj with its .mtl and texture, .ply, .glb, .gltf) as the CLI does: checked
/// for use (finite coordinates, faces with area, size) and repaired (vertices no face uses,
/// degenerate and duplicate faces dropped; `Mesh.file_index` maps back). Warnings go through
/// Python's `warnings` module.
#[pyfunction]
pub fn load(py: Python<'_>, path: PathBuf) -> PyResult<Mesh> {
    let (m, warnings, exact) = py
        .detach(|| {
            let (m, mut w, exact) = io::load_with_warnings_exact(&path)?;
            let (m, more) = meshmatch::cli::common::make_usable(m, &path)?;
            w.extend(more);
            Ok::<_, meshmatch::Error>((m, w, exact))
        })
        .or_py()?;
    warn(py, &warnings)?;
    Ok(Mesh {
        inner: Arc::new(m),
        exact: Some(Arc::new(exact)),
    })
}

/// Pass warning lines to Python's `warnings.warn`.
pub fn warn(py: Python<'_>, lines: &[String]) -> PyResult<()> {
    if lines.is_empty() {
        return Ok(());
    }
    let w = py.import("warnings")?;
    for l in lines {
        w.call_method1("warn", (l.as_str(),))?;
    }
    Ok(())
}

/// The mesh behind a `Mesh` argument, made ready for the engine as the CLI makes a loaded file
/// (`name` names it in messages: "source", "target").
pub fn usable(py: Python<'_>, m: &Mesh, name: &str) -> PyResult<TriMesh> {
    let mut t = (*m.inner).clone();
    if t.path.is_none() {
        t.path = Some(PathBuf::from(name));
    }
    let (t, warnings) = meshmatch::cli::common::make_usable(t, Path::new(name)).or_py()?;
    warn(py, &warnings)?;
    Ok(t)
}

/// [`usable`], in a system's working units (as the command line takes its files).
pub fn usable_in(
    py: Python<'_>,
    m: &Mesh,
    name: &str,
    units: &mut meshmatch::cli::common::WorkingUnits,
) -> PyResult<TriMesh> {
    let t = usable(py, m, name)?;
    Ok(units.adopt(t, m.exact.as_ref().map(|e| e.as_slice())))
}
