//! `meshmatch quilt` and `meshmatch swatch`: mesh quilting (Zhou et al. 2006), geometric
//! textures (chain mail, weaves, nuts, studs, scales) stitched over a base surface, and the
//! procedural swatches it ships with.

use std::path::{Path, PathBuf};

use super::common::*;
use crate::error::{Error, Result};
use crate::mesh::{TriMesh, io};
use crate::synthesis::quilting::{self, Axis, Params, Swatch, SwatchKind};
use crate::work::CancelToken;

/// Arguments of `meshmatch quilt`.
#[derive(clap::Args, Debug)]
pub struct QuiltArgs {
    /// The swatch: a mesh file whose elements (connected components) lie over z = 0 with z up
    /// and whose x-y extent is the swatch, or a built-in kind: chain, weave, nuts, studs, scales.
    #[arg(long)]
    pub swatch: String,
    /// The base surface to cover.
    #[arg(long)]
    pub base: PathBuf,
    /// Output: .obj (one object per element, `element_N`, and `base`), .ply (the elements with a
    /// per-vertex `element` id), .glb or .gltf (elements and base as one mesh).
    #[arg(long)]
    pub out: PathBuf,
    /// Swatch width (its x extent) in base units; default a tenth of the base's bounding-box
    /// diagonal.
    #[arg(long, allow_negative_numbers = true)]
    pub swatch_size: Option<f32>,
    /// Shell thickness in base units; default the swatch height scaled like its width.
    #[arg(long, allow_negative_numbers = true)]
    pub thickness: Option<f32>,
    /// Which axis of a swatch file points away from the surface: x, y or z.
    #[arg(long, default_value = "z")]
    pub swatch_up: String,
    /// Write only the elements, not the base.
    #[arg(long)]
    pub elements_only: bool,
    /// Random seed.
    #[arg(long, default_value_t = Params::default().seed, allow_negative_numbers = true, value_parser = super::common::SEED)]
    pub seed: u64,
    /// Merge threads (elongated elements) that continue each other across patch seams:
    /// deform both half-way and stitch them into one instead of dropping one copy. Slower;
    /// compact elements are never merged.
    #[arg(long)]
    pub merge: bool,
    /// Do not try threads (elongated elements) dropped at patch seams again, moved by part of
    /// their spacing into the gap (on by default: fills the gaps they leave on curved bases).
    #[arg(long)]
    pub no_nudge: bool,
    /// Do not fill the gaps left between patches once the base is covered (on by default:
    /// each gap wider than the swatch's own largest gets the first copy of a swatch element
    /// that clears every other element).
    #[arg(long)]
    pub no_fill: bool,
    /// Do not cut threads short: a thread (elongated element) that no whole copy fits (dropped
    /// at a seam, torn off a patch, or too long for a gap) is otherwise kept in part, its
    /// longest clear run cut across and capped (on by default; compact elements are never
    /// cut).
    #[arg(long)]
    pub no_trim: bool,
    /// Do not relink chains broken at seams: an element with fewer links than in the swatch
    /// (a ring ending a chain where two patches meet) otherwise gets its missing partner
    /// where that adds links, replacing at most one element (on by default).
    #[arg(long)]
    pub no_relink: bool,
    /// Match every patch to its neighbours as the paper does instead of placing patches on one
    /// global lattice (two stripe patterns along the orientation field and across it). The
    /// lattice, on by default, lines up threads and crossings across seams.
    #[arg(long)]
    pub no_lattice: bool,
}

/// Refuse a length flag (`--swatch-size`, `--thickness`) that is given but not positive and finite.
pub fn positive(name: &str, v: Option<f32>) -> Result<()> {
    match v {
        Some(x) if !(x.is_finite() && x > 0.0) => Err(Error::InvalidInput(format!(
            "--{name} {x}: use a positive length in base units"
        ))),
        _ => Ok(()),
    }
}

/// A built-in swatch by name, or a swatch mesh file with `up` as its up axis (the Python package
/// takes swatches the same way).
pub fn load_any_swatch(spec: &str, up: &str, seed: u64) -> Result<Swatch> {
    let up = match up.to_ascii_lowercase().as_str() {
        "x" => Axis::X,
        "y" => Axis::Y,
        "z" => Axis::Z,
        _ => {
            return Err(Error::InvalidInput(format!(
                "--swatch-up {up}: use x, y or z"
            )));
        }
    };
    if let Ok(kind) = SwatchKind::parse(spec) {
        return Ok(quilting::swatch(kind, seed));
    }
    let path = Path::new(spec);
    if !path.exists() {
        return Err(Error::InvalidInput(format!(
            "--swatch {spec}: no such file, and not a built-in swatch (chain, weave, nuts, studs, scales)"
        )));
    }
    // in its own units (its bounding-box diagonal), so that a swatch modelled in millimetres
    // and the same in metres are the same swatch; quilting sizes it by the base
    let (mesh, warnings, exact) = io::load_with_warnings_exact(path)?;
    io::print_warnings(&warnings);
    let mesh = crate::cli::common::WorkingUnits::new().adopt(mesh, Some(&exact));
    quilting::load_swatch(mesh, up)
}

impl QuiltArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        let a = self;
        let swatch_file = Path::new(&a.swatch);
        let mut inputs = vec![a.base.as_path()];
        if swatch_file.exists() {
            inputs.push(swatch_file);
        }
        check_outputs(&inputs, &[("--out", a.out.as_path(), OutKind::Mesh)])?;
        positive("swatch-size", a.swatch_size)?;
        positive("thickness", a.thickness)?;
        let swatch = load_any_swatch(&a.swatch, &a.swatch_up, a.seed)?;
        let mut units = WorkingUnits::new();
        let base = units.load(&a.base)?;
        let params = Params {
            swatch_size: a.swatch_size.map(|x| units.length(x)),
            thickness: a.thickness.map(|x| units.length(x)),
            seed: a.seed,
            merge_elements: a.merge,
            nudge: !a.no_nudge,
            fill: !a.no_fill,
            trim: !a.no_trim,
            relink: !a.no_relink,
            lattice: !a.no_lattice,
            ..Params::default()
        };
        let bar = progress_bar();
        let sink = |e| bar_sink(&bar, e);
        let input = quilting::Input {
            base: &base,
            swatch: &swatch,
            field: None,
        };
        let mut out = quilting::run(&input, &params, &sink, &CancelToken::new())?;
        bar.finish_and_clear();
        let s = &out.stats;
        eprintln!(
            "quilted {} elements ({} faces; {} copies merged into others, {} moved into gaps, {} \
             placed in gaps after the patches, {} threads cut short, {} partners relinked) in \
             {:.2} s: {} patches ({} on the global lattice), \
             {:.1}% of the base covered, swatch {:.4} wide, shell {:.4} thick, shell stretch L2 \
             {:.3} -> {:.3}",
            s.elements,
            out.elements.num_faces(),
            s.merged,
            s.nudged,
            s.filled,
            s.trimmed,
            s.relinked,
            s.seconds,
            s.patches,
            s.lattice_patches,
            100.0 * s.covered_fraction,
            units.file_length(s.swatch_size),
            units.file_length(s.thickness),
            s.shell_stretch_before,
            s.shell_stretch
        );
        eprintln!("{}", s.arrangement_summary());
        if s.shell_inverted > 0 {
            eprintln!(
                "note: {} of the shell's {} tetrahedra stay inverted (base vertices whose normal \
                 points away from a neighbouring face); elements over them may fold",
                s.shell_inverted,
                3 * base.num_faces()
            );
        }
        let ext = a
            .out
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        // back in the base's file units
        for p in &mut out.elements.positions {
            *p = units.file_point(*p);
        }
        let base = units.to_file(&base);
        let with_base = (!a.elements_only).then_some(base.as_ref());
        match ext.as_str() {
            "obj" => quilting::save_quilt_obj(&out, with_base, &a.out)?,
            "ply" => {
                if !a.elements_only {
                    eprintln!(
                        "note: PLY carries the elements with a per-vertex element id, not the \
                         base (use .obj or .glb for both)"
                    );
                }
                quilting::save_quilt_ply(&out, &a.out)?
            }
            _ => io::save(&merged(&out.elements, with_base), &a.out)?,
        }
        crate::cli::common::announce_written(&a.out);
        Ok(0)
    }
}

/// The elements and, when given, the base as one mesh (for formats without objects).
fn merged(elements: &TriMesh, base: Option<&TriMesh>) -> TriMesh {
    let mut positions = elements.positions.clone();
    let mut faces = elements.faces.clone();
    if let Some(b) = base {
        let o = positions.len() as u32;
        positions.extend_from_slice(&b.positions);
        faces.extend(b.faces.iter().map(|f| [f[0] + o, f[1] + o, f[2] + o]));
    }
    TriMesh::new(positions, faces)
}

/// Arguments of `meshmatch swatch`.
#[derive(clap::Args, Debug)]
pub struct SwatchArgs {
    /// chain, weave, nuts, studs or scales (periodic), or a finite patch as an artist models
    /// one: rings-patch (3 rows of 4 interlinked tilted rings), weave-patch, pebbles.
    #[arg(long)]
    pub kind: String,
    /// Output mesh (.obj, .ply, .glb, .gltf): elements over z = 0, z up.
    #[arg(long)]
    pub out: PathBuf,
    /// Random seed (jitter of nuts and scales).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true, value_parser = super::common::SEED)]
    pub seed: u64,
}

impl SwatchArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        check_outputs(&[], &[("--out", self.out.as_path(), OutKind::Mesh)])?;
        if let Ok(kind) = quilting::PatchKind::parse(&self.kind) {
            let mesh = quilting::finite_patch(kind, self.seed);
            let s = quilting::load_swatch(mesh.clone(), Axis::Z)?;
            io::save(&mesh, &self.out)?;
            eprintln!(
                "{} (finite patch): {} elements, {} faces, {:.3} x {:.3}, height {:.3}",
                self.kind,
                s.elements.len(),
                s.mesh.num_faces(),
                s.extent[0],
                s.extent[1],
                s.height
            );
            crate::cli::common::announce_written(&self.out);
            return Ok(0);
        }
        let kind = SwatchKind::parse(&self.kind).map_err(|_| {
            crate::error::Error::InvalidInput(format!(
                "--kind {}: not a built-in swatch (chain, weave, nuts, studs, scales, or the \
                 finite patches rings-patch, weave-patch, pebbles)",
                self.kind
            ))
        })?;
        let s = quilting::swatch(kind, self.seed);
        io::save(&s.mesh, &self.out)?;
        eprintln!(
            "{} swatch: {} elements, {} faces, {:.3} x {:.3}, height {:.3}",
            self.kind,
            s.elements.len(),
            s.mesh.num_faces(),
            s.extent[0],
            s.extent[1],
            s.height
        );
        crate::cli::common::announce_written(&self.out);
        Ok(0)
    }
}
