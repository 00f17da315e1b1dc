//! `meshmatch features`: one geometric feature of a mesh as vertex colours (the ambient
//! occlusion, curvature and height bakes texturing tools offer), from the features of the
//! geometry-correlated transfer.

use std::path::PathBuf;

use super::common::*;
use crate::error::{Error, Result};
use crate::mesh::io;
use crate::synthesis::mertens::{self, Params, Up};
use crate::work::CancelToken;

/// Arguments of `meshmatch features`.
#[derive(clap::Args, Debug)]
pub struct FeaturesArgs {
    /// The mesh.
    pub mesh: PathBuf,
    /// Output mesh with the feature as grey vertex colours (.ply, .glb, .gltf, .obj), on the mesh's own
    /// vertices.
    #[arg(long)]
    pub out: PathBuf,
    /// ao, height, curvature[:i] (i = 0..3, radius index, small to large), normal-x|y|z,
    /// occlusion-x|y|z.
    #[arg(long, default_value = "ao")]
    pub feature: String,
    /// The object's up axis, for height: y or z.
    #[arg(long, default_value = "y")]
    pub up: String,
    /// Occlusion rays per vertex, 1 to 4096.
    #[arg(long, default_value_t = Params::default().rays, allow_negative_numbers = true, value_parser = RAYS)]
    pub rays: usize,
    /// Random seed (ray directions).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true, value_parser = SEED)]
    pub seed: u64,
}

impl FeaturesArgs {
    /// Run the subcommand; returns the exit code.
    pub fn run(&self) -> Result<i32> {
        let up: Up = self.up.parse()?;
        check_rays(self.rays)?;
        check_outputs(&[&self.mesh], &[("--out", &self.out, OutKind::Mesh)])?;
        let mesh = load_usable(&self.mesh)?;
        let params = Params {
            up,
            rays: self.rays,
            seed: self.seed,
            ..Params::default()
        };
        mertens::check_feature_name(&self.feature, params.curvature_radii.len())?;
        let t = std::time::Instant::now();
        let field = feature_values(&mesh, &self.feature, &params, &CancelToken::new())?;
        let (lo, hi) = field
            .iter()
            .filter(|x| x.is_finite())
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "feature '{}' has no finite value on this mesh",
                self.feature
            )));
        }
        // Occlusion and height have natural [0, 1] ranges; others are stretched to [0, 1].
        let natural = matches!(self.feature.as_str(), "ao" | "height") && lo >= 0.0 && hi <= 1.0;
        let (lo, hi) = if natural { (0.0, 1.0) } else { (lo, hi) };
        let span = (hi - lo).max(1e-12);
        let grey: Vec<[f32; 3]> = field
            .iter()
            .map(|&x| {
                let g = ((x - lo) / span).clamp(0.0, 1.0);
                [g, g, g]
            })
            .collect();
        let mut out = mesh.clone();
        out.colors = Some(grey);
        out.texture = None;
        io::save(&out, &self.out)?;
        eprintln!(
            "feature {} in {:.2} s: range {lo:.4} .. {hi:.4}{}",
            self.feature,
            t.elapsed().as_secs_f64(),
            if natural {
                ""
            } else {
                " (stretched to black .. white)"
            }
        );
        eprintln!("wrote {}", self.out.display());
        Ok(0)
    }
}

/// One feature of `meshmatch features` (`ao`, `height`, `curvature[:i]`, `normal-x|y|z`,
/// `occlusion-x|y|z`) per vertex of a mesh in memory, as the system computes it (not stretched
/// to grey). The CLI and the Python package call it.
pub fn feature_values(
    mesh: &crate::mesh::TriMesh,
    feature: &str,
    params: &Params,
    cancel: &CancelToken,
) -> Result<Vec<f32>> {
    check_rays(params.rays)?;
    mertens::check_feature_name(feature, params.curvature_radii.len())?;
    let fs = mertens::features(&mesh.positions, &mesh.faces, params, cancel)?;
    mertens::feature_field(&fs, feature)
}
