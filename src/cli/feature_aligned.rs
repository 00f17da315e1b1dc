//! `meshmatch curves`: the salient curves of a mesh (crest lines after Yoshizawa et al. 2005 and
//! sharp creases, grouped and broken as Xu et al. 2009 §4.1) as OBJ polylines.

use std::path::PathBuf;

use super::common::*;
use crate::error::{Error, Result};
use crate::geometry::{CurveKind, CurveParams, salient_curves};

/// Arguments of `meshmatch curves`.
#[derive(clap::Args, Debug)]
pub struct CurvesArgs {
    /// The mesh.
    pub mesh: PathBuf,
    /// Output OBJ with the curves as polylines (`v` and `l` lines, one object per curve) in the
    /// mesh's own coordinates.
    #[arg(long)]
    pub out: PathBuf,
    /// Minimum strength of a curve, `∫ |k| ds` (dimensionless).
    #[arg(long, default_value_t = CurveParams::default().threshold, allow_negative_numbers = true)]
    pub threshold: f32,
    /// Minimum curve length in mesh units (default: 5 mean edge lengths).
    #[arg(long, allow_negative_numbers = true)]
    pub min_length: Option<f32>,
    /// Dihedral angle (degrees) above which an edge is a sharp crease (180 = none).
    #[arg(long, default_value_t = CurveParams::default().crease_angle_deg, allow_negative_numbers = true)]
    pub crease_angle: f32,
    /// Creases only (no ridges or ravines).
    #[arg(long)]
    pub creases_only: bool,
    /// Write the snapped vertex paths instead of the crest polylines.
    #[arg(long)]
    pub snapped: bool,
}

impl CurvesArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        check_curves(self.threshold, self.min_length, self.crease_angle)?;
        check_outputs(
            &[self.mesh.as_path()],
            &[("--out", self.out.as_path(), OutKind::File)],
        )?;
        let mut units = WorkingUnits::new();
        let mesh = units.load(&self.mesh)?;
        let params = CurveParams {
            threshold: self.threshold,
            min_length: self.min_length.map(|l| units.length(l)),
            crease_angle_deg: self.crease_angle,
            crest_lines: !self.creases_only,
            ..CurveParams::default()
        };
        let t = std::time::Instant::now();
        let curves = salient_curves(&mesh.positions, &mesh.faces, &params)?;
        let secs = t.elapsed().as_secs_f64();
        let mut s = String::new();
        s.push_str(&format!(
            "# meshmatch curves: {} curves of {}\n",
            curves.len(),
            self.mesh.display()
        ));
        let mut base = 1usize;
        for (i, c) in curves.iter().enumerate() {
            let kind = match c.kind {
                CurveKind::Ridge => "ridge",
                CurveKind::Ravine => "ravine",
                CurveKind::Crease => "crease",
            };
            s.push_str(&format!(
                "o curve{i}_{kind}\n# strength {:.4} length {:.6}\n",
                c.strength,
                units.file_length(c.length())
            ));
            let pts: Vec<[f32; 3]> = if self.snapped {
                c.vertices
                    .iter()
                    .map(|&v| mesh.positions[v as usize])
                    .collect()
            } else {
                c.points.clone()
            };
            for p in pts.iter().map(|&p| units.file_position(p)) {
                s.push_str(&format!("v {} {} {}\n", p[0], p[1], p[2]));
            }
            s.push('l');
            for k in 0..pts.len() {
                s.push_str(&format!(" {}", base + k));
            }
            if c.closed && pts.len() > 2 {
                s.push_str(&format!(" {base}"));
            }
            s.push('\n');
            base += pts.len();
        }
        crate::mesh::io::write_atomic(&self.out, s.as_bytes())?;
        let (nr, nv, nc) = curves.iter().fold((0, 0, 0), |(r, v, c), x| match x.kind {
            CurveKind::Ridge => (r + 1, v, c),
            CurveKind::Ravine => (r, v + 1, c),
            CurveKind::Crease => (r, v, c + 1),
        });
        crate::cli::common::announce(format!(
            "{} curves ({nr} ridges, {nv} ravines, {nc} creases) in {secs:.2} s; wrote {}",
            curves.len(),
            self.out.display()
        ));
        Ok(0)
    }
}

/// Refuse `curves` settings outside their ranges, in the CLI's words.
pub fn check_curves(threshold: f32, min_length: Option<f32>, crease_angle: f32) -> Result<()> {
    if !(threshold.is_finite() && threshold >= 0.0) {
        return Err(Error::InvalidInput(format!(
            "--threshold {threshold}: use a finite number, 0 or more"
        )));
    }
    if let Some(l) = min_length
        && !(l.is_finite() && l > 0.0)
    {
        return Err(Error::InvalidInput(format!(
            "--min-length {l}: use a positive length in mesh units"
        )));
    }
    if !(0.0..=180.0).contains(&crease_angle) {
        return Err(Error::InvalidInput(format!(
            "--crease-angle {crease_angle}: use 0 to 180 degrees"
        )));
    }
    Ok(())
}
