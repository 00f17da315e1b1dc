//! Feature-aligned shape texturing, after Xu, Cohen-Or, Ju, Liu, Zhang, Zhou & Xu 2009,
//! "Feature-aligned shape texturing" (SIGGRAPH Asia 2009).
//!
//! Pipeline: salient curves of the target (§4.1: crest lines after Yoshizawa et al. 2005 and sharp
//! creases, grouped and broken; [`crate::geometry::salient_curves`]) -> greedy curve orientation
//! with the score of eq. (1) -> constrained harmonic vector diffusion `(L + P) x = P b`, eq. (2),
//! projected on the tangent planes ([`crate::geometry::oriented_curve_field`]) -> texture
//! synthesis driven by that field: the Wei-Levoy system
//! ([`super::exemplar::synthesize_with_field`]) with the field as texture "right" direction (the
//! exemplar's x axis runs along the curves), then with [`Method::Optimize`] the surface texture
//! optimisation of §5.1 (eq. 3; [`super::texture_optimization`]) and, with
//! [`Params::align_features`], the feature-to-feature constraint of §5.2 (eq. 4): the exemplar's
//! principal line (detected, or from a mask) is placed on the curves. An exemplar whose lines are
//! vertical is turned a quarter turn first so that they run along the curves.

use crate::error::{Error, Result};
use crate::geometry::{Curve, CurveField, CurveParams, FieldParams};
use crate::mesh::TriMesh;
use crate::work::{CancelToken, Event, Progress, Stopwatch};

use super::curve_field::FieldStage;
pub use super::curve_field::{COARSE_GREEDY, GREEDY_VERTICES};
use super::exemplar::{self, Orientation, SynthParams, SynthResult};
use super::texture_optimization::{self as opt, ExemplarLines, Method};

/// Parameters (paper defaults: α = 1e8; curve thresholds are the guide's proposals).
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Params {
    /// Salient curve extraction and preparation.
    pub curves: CurveParams,
    /// Field: penalty weight, junction release.
    pub field: FieldParams,
    /// The synthesis driven by the field (its `orientation` is ignored: the field is used).
    pub synth: SynthParams,
    /// Neighbourhood synthesis only, or followed by the texture optimisation.
    pub method: Method,
    /// Place the exemplar's principal line on the salient curves (§5.2; implies the optimisation).
    pub align_features: bool,
    /// The texture optimisation's parameters.
    pub optimization: opt::Params,
    /// Above this many target vertices the greedy orientation runs on a coarse level of the
    /// mesh ([`Params::greedy_vertices`]), then at full resolution; `None`: the default,
    /// [`COARSE_GREEDY`].
    pub coarse_greedy_above: Option<usize>,
    /// Vertices of the coarse level the greedy orientation runs on (at most; 0: the default,
    /// [`GREEDY_VERTICES`]).
    pub greedy_vertices: usize,
}

/// What the system works on.
#[derive(Clone, Copy, Debug)]
pub struct Input<'a> {
    /// The mesh to texture.
    pub target: &'a TriMesh,
    /// The exemplar image (its x axis follows the curves).
    pub exemplar: &'a image::RgbImage,
    /// Curves to use instead of extracting them (e.g. edited or loaded).
    pub curves: Option<&'a [Curve]>,
    /// The exemplar's alpha, if it has transparent pixels (never synthesized).
    pub alpha: Option<&'a image::GrayImage>,
    /// The exemplar's line features (white on black, the exemplar's size) for
    /// [`Params::align_features`]; detected when `None`.
    pub feature_mask: Option<&'a image::GrayImage>,
}

/// Seconds per stage.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct Timings {
    /// Salient curves.
    pub curves: f64,
    /// Greedy orientation and field.
    pub field: f64,
    /// Synthesis.
    pub synthesis: f64,
    /// Texture optimisation.
    pub optimization: f64,
}

/// The system's output.
#[derive(Clone, Debug)]
pub struct Output {
    /// The salient curves used.
    pub curves: Vec<Curve>,
    /// Their orientations and the field on the target's vertices.
    pub field: CurveField,
    /// The synthesis (mesh with colours, colours on the target's vertices, ...).
    pub synth: SynthResult,
    /// Stage timings.
    pub timings: Timings,
    /// The texture optimisation's report, when it ran.
    pub optimization: Option<opt::Report>,
    /// The exemplar's principal lines (in the exemplar as used), with the constraint.
    pub lines: Option<ExemplarLines>,
    /// Whether the exemplar was turned a quarter turn (its lines were vertical).
    pub exemplar_turned: bool,
    /// Rows the exemplar (as turned) was rolled down by, wrapping, to bring its principal lines
    /// away from its top and bottom borders (0: not rolled).
    pub exemplar_rolled: usize,
}

/// The salient curves and the oriented field of a mesh (the first two stages of [`run`];
/// [`super::curve_field::curves_and_field`] with this system's parameters).
pub fn curves_and_field(
    target: &TriMesh,
    curves: Option<&[Curve]>,
    params: &Params,
    cancel: &CancelToken,
) -> Result<(Vec<Curve>, CurveField, Timings)> {
    let stage = FieldStage {
        curves: &params.curves,
        field: &params.field,
        coarse_greedy_above: params.coarse_greedy_above,
        greedy_vertices: params.greedy_vertices,
    };
    let (curves, field, (curves_secs, field_secs)) =
        super::curve_field::curves_and_field(target, curves, &stage, cancel)?;
    let t = Timings {
        curves: curves_secs,
        field: field_secs,
        ..Timings::default()
    };
    Ok((curves, field, t))
}

/// The system's front door: curves -> oriented field -> field-driven synthesis.
pub fn run(
    input: &Input,
    params: &Params,
    sink: &dyn Fn(Event),
    cancel: &CancelToken,
) -> Result<Output> {
    let total = Stopwatch::start();
    if input.target.faces.is_empty() {
        return Err(Error::InvalidMesh("target mesh has no faces".into()));
    }
    sink(Event::Progress(Progress {
        stage: "curves",
        elapsed: total.secs(),
        ..Default::default()
    }));
    let (curves, field, mut timings) =
        curves_and_field(input.target, input.curves, params, cancel)?;
    sink(Event::StageTime("curves", timings.curves));
    sink(Event::StageTime("field", timings.field));
    if curves.is_empty() {
        return Err(Error::InvalidInput(
            "no salient curve on the target: lower the threshold or the crease angle".into(),
        ));
    }
    let optimise = params.align_features || params.method == Method::Optimize;
    if optimise && params.synth.displace {
        return Err(Error::InvalidInput(
            "the texture optimisation makes colours: it does not combine with displacement".into(),
        ));
    }
    // The exemplar's principal lines, turned to run along x if they are vertical, and rolled
    // away from the top and bottom borders so that whole patches can be centred on them.
    let (mut lines, mut turned) = (None, false);
    let (mut ex_own, mut alpha_own) = (None, None);
    let mut rolled = 0usize;
    if params.align_features {
        let (l, t) = opt::find_principal_lines(input.exemplar, input.alpha, input.feature_mask)?;
        turned = t;
        let turn = |i: &image::RgbImage| image::imageops::rotate90(i);
        let turn_g = |i: &image::GrayImage| image::imageops::rotate90(i);
        let (ex_t, alpha_t, mask_t) = if t {
            (
                Some(turn(input.exemplar)),
                input.alpha.map(turn_g),
                input.feature_mask.map(turn_g),
            )
        } else {
            (None, None, None)
        };
        let ex_ref = ex_t.as_ref().unwrap_or(input.exemplar);
        let alpha_ref = alpha_t.as_ref().or(input.alpha);
        let mask_ref = mask_t.as_ref().or(input.feature_mask);
        let margin = params.optimization.patch.max(8);
        match opt::exemplar_lines::border_roll(&l, margin) {
            Some(dy) => {
                let ex_r = opt::exemplar_lines::roll_rows(ex_ref, dy);
                let alpha_r = alpha_ref.map(|a| opt::exemplar_lines::roll_rows(a, dy));
                let mask_r = mask_ref.map(|m| opt::exemplar_lines::roll_rows(m, dy));
                let (l2, t2) = opt::find_principal_lines(&ex_r, alpha_r.as_ref(), mask_r.as_ref())?;
                if t2 {
                    // the roll changed the reading: keep the unrolled lines
                    lines = Some(l);
                    ex_own = ex_t;
                    alpha_own = alpha_t;
                } else {
                    rolled = dy;
                    lines = Some(l2);
                    ex_own = Some(ex_r);
                    alpha_own = alpha_r;
                }
            }
            None => {
                lines = Some(l);
                ex_own = ex_t;
                alpha_own = alpha_t;
            }
        }
    }
    let exemplar = ex_own.as_ref().unwrap_or(input.exemplar);
    let alpha = alpha_own.as_ref().or(input.alpha);
    let clock = Stopwatch::start();
    let sp = SynthParams {
        orientation: Orientation::Features,
        ..params.synth.clone()
    };
    let mut synth = exemplar::synthesize_with_alpha(
        exemplar,
        alpha,
        input.target,
        None,
        Some(&field.field),
        &sp,
        sink,
        cancel,
    )?;
    timings.synthesis = clock.secs();
    let mut optimization = None;
    if optimise {
        let clock = Stopwatch::start();
        let report = opt::optimize_result(
            &mut synth,
            input.target,
            exemplar,
            alpha,
            lines.as_ref().map(|l| (&curves[..], l)),
            &params.optimization,
            sink,
            cancel,
        )?;
        timings.optimization = clock.secs();
        optimization = Some(report);
    }
    Ok(Output {
        curves,
        field,
        synth,
        timings,
        optimization,
        lines,
        exemplar_turned: turned,
        exemplar_rolled: rolled,
    })
}
