//! Feature-aligned shape texturing, after Xu, Cohen-Or, Ju, Liu, Zhang, Zhou & Xu 2009,
//! "Feature-aligned shape texturing" (SIGGRAPH Asia 2009).
//!
//! Pipeline: salient curves of the target (§4.1: crest lines after Yoshizawa et al. 2005 and sharp
//! creases, grouped and broken; [`crate::geometry::salient_curves`]) -> greedy curve orientation
//! with the score of eq. (1) -> constrained harmonic vector diffusion `(L + P) x = P b`, eq. (2),
//! projected on the tangent planes ([`crate::geometry::oriented_curve_field`]) -> texture
//! synthesis driven by that field. The synthesis here is the Wei-Levoy system
//! ([`super::wei_levoy::synthesize_with_field`]) with the field as texture "right" direction: the
//! exemplar's x axis runs along the curves, so put the exemplar's principal line horizontal.
//!
//! Not implemented: the surface texture optimisation of §5.1 (Kwatra et al.) and the
//! feature-to-feature constraint of §5.2 (eq. 3, 4: exemplar lines placed exactly on the curves).

use crate::error::{Error, Result};
use crate::geometry::{
    Curve, CurveField, CurveParams, FieldCurve, FieldParams, oriented_curve_field, salient_curves,
};
use crate::mesh::TriMesh;
use crate::work::{CancelToken, Event, Progress, Stopwatch};

use super::wei_levoy::{self, Orientation, SynthParams, SynthResult};

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
}

/// The salient curves and the oriented field of a mesh (the first two stages of [`run`]).
pub fn curves_and_field(
    target: &TriMesh,
    curves: Option<&[Curve]>,
    params: &Params,
    cancel: &CancelToken,
) -> Result<(Vec<Curve>, CurveField, Timings)> {
    let mut t = Timings::default();
    let sw = Stopwatch::start();
    let curves = match curves {
        Some(c) => c.to_vec(),
        None => salient_curves(&target.positions, &target.faces, &params.curves)?,
    };
    t.curves = sw.secs();
    cancel.check()?;
    let sw = Stopwatch::start();
    let fc: Vec<FieldCurve> = curves.iter().map(FieldCurve::from).collect();
    let field = oriented_curve_field(&target.positions, &target.faces, &fc, &params.field, cancel)?;
    t.field = sw.secs();
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
    let sw = Stopwatch::start();
    let sp = SynthParams {
        orientation: Orientation::Features,
        ..params.synth.clone()
    };
    let synth = wei_levoy::synthesize_with_alpha(
        input.exemplar,
        input.alpha,
        input.target,
        None,
        Some(&field.field),
        &sp,
        sink,
        cancel,
    )?;
    timings.synthesis = sw.secs();
    Ok(Output {
        curves,
        field,
        synth,
        timings,
    })
}
