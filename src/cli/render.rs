//! `meshmatch render`: a mesh to a PNG, offscreen, with the app's renderer.

use std::path::PathBuf;

use crate::correspondence::CorrespondenceFile;
use crate::error::{Error, Result};

/// Arguments of `meshmatch render`.
#[derive(clap::Args, Debug)]
pub struct RenderArgs {
    /// The mesh to render.
    pub mesh: PathBuf,
    /// Output PNG (must end in .png; never one of the inputs).
    #[arg(long)]
    pub out: PathBuf,
    /// Camera azimuth around the up axis, degrees.
    #[arg(long, default_value_t = 30.0, allow_hyphen_values = true)]
    pub azimuth: f32,
    /// Camera elevation, degrees.
    #[arg(long, default_value_t = 20.0, allow_hyphen_values = true)]
    pub elevation: f32,
    /// Image size as WxH, each 1 to 8192.
    #[arg(long, default_value = "800x600", allow_negative_numbers = true)]
    pub size: String,
    /// Draw the wireframe over the shading.
    #[arg(long)]
    pub wireframe: bool,
    /// Correspondences JSON whose markers to draw: spheres in the app's marker colours
    /// (hidden ones faint).
    #[arg(long)]
    pub correspondences: Option<PathBuf>,
    /// Which side of the correspondences this mesh is.
    #[arg(long, value_enum, default_value = "target")]
    pub side: MarkerSide,
}

/// Which side of a correspondence file a rendered mesh is.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MarkerSide {
    /// The source mesh (`source_vertex`).
    Source,
    /// The target mesh (`target_vertices`).
    Target,
}

impl RenderArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        let (width, height) = parse_size(&self.size)?;
        for (flag, v) in [("--azimuth", self.azimuth), ("--elevation", self.elevation)] {
            if !v.is_finite() {
                return Err(Error::InvalidInput(format!(
                    "{flag} {v}: must be a finite number of degrees"
                )));
            }
        }
        let inputs = super::common::input_paths(&[Some(&self.mesh), self.correspondences.as_ref()]);
        super::common::check_outputs(
            &inputs,
            &[("--out", &self.out, super::common::OutKind::Png)],
        )?;
        let m = super::common::load_usable(&self.mesh)?;
        let markers = match &self.correspondences {
            Some(p) => {
                let (s, t) = match self.side {
                    MarkerSide::Source => (Some(&m), None),
                    MarkerSide::Target => (None, Some(&m)),
                };
                render_markers(&m, &CorrespondenceFile::load_for(p, s, t)?, self.side)?
            }
            None => Vec::new(),
        };
        let opts = crate::render::RenderOptions {
            azimuth_deg: self.azimuth,
            elevation_deg: self.elevation,
            width,
            height,
            wireframe: self.wireframe,
            markers,
        };
        crate::render::render_to_png(&m, None, &opts, &self.out)?;
        crate::cli::common::announce_written(&self.out);
        Ok(0)
    }
}

/// Marker spheres for `side` of `corr` on `mesh`: the app's colours, a radius of 2% of the
/// mesh's bounding radius.
fn render_markers(
    mesh: &crate::mesh::TriMesh,
    corr: &[crate::correspondence::Correspondence],
    side: MarkerSide,
) -> Result<Vec<crate::render::MarkerInstance>> {
    let radius = crate::render::Frame::of_points(&mesh.positions).radius * 0.02;
    let mut out = Vec::new();
    for (pair, c) in corr.iter().enumerate() {
        let side = match side {
            MarkerSide::Source => crate::correspondence::Side::Source,
            MarkerSide::Target => crate::correspondence::Side::Target,
        };
        for &v in c.vertices(side) {
            let p = mesh.positions.get(v as usize).ok_or_else(|| {
                Error::InvalidInput(format!(
                    "correspondence {}: vertex {v} is out of range ({} vertices)",
                    pair + 1,
                    mesh.positions.len()
                ))
            })?;
            out.push(crate::render::MarkerInstance {
                center: *p,
                radius,
                color: crate::render::marker_color(pair).map(|x| x as f32 / 255.0),
                rim: 0.0,
            });
        }
    }
    Ok(out)
}

fn parse_size(s: &str) -> Result<(u32, u32)> {
    let bad = || {
        Error::InvalidInput(format!(
            "--size {s}: expected WxH, each 1 to 8192 pixels, e.g. 800x600"
        ))
    };
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h): (u32, u32) = (
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    );
    if w == 0 || h == 0 || w > 8192 || h > 8192 {
        return Err(bad());
    }
    Ok((w, h))
}
