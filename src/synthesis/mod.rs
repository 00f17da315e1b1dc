//! The synthesis systems, one folder each, all of one shape:
//!
//! - a module doc naming the paper and the equations it implements;
//! - `Params` (serde; `Default` = the paper's defaults);
//! - `Input` (what it works on) and `Output` (what it returns);
//! - one front door `run(&Input, &Params, sink, cancel) -> Result<Output>` that reports
//!   [`crate::work::Event`]s (progress, partial results) and stops on the cancel token.
//!
//! They reuse `geometry`, `hierarchy` and `features`; the CLI reaches each through one file in
//! `cli/` and the app through one entry in `app/systems.rs`.
//!
//! - [`feature_aligned`]: feature-aligned shape texturing (Xu et al. 2009): salient curves, a
//!   curve-guided field, field-driven synthesis.
//! - [`weathering`]: geometry-correlated texture transfer (Mertens et al. 2006).
//! - [`quilting`]: geometric texture synthesis by mesh quilting (Zhou et al. 2006).
//! - [`texture_optimization`]: surface texture optimisation (Kwatra et al. 2005) with the
//!   feature-to-feature constraint (Xu et al. 2009 §5), a stage `synth` and feature-aligned
//!   texturing run after the Wei-Levoy synthesis.
//! - [`exemplar`]: image-exemplar texture synthesis over arbitrary surfaces (Wei & Levoy 2001).

pub mod curve_field;
pub mod exemplar;
pub mod feature_aligned;
pub mod quilting;
pub mod texture_optimization;
pub mod weathering;

pub use exemplar::{
    Orientation, Search, SynthParams, SynthResult, SynthTimings, synthesize, synthesize_with_alpha,
    synthesize_with_field,
};
pub use texture_optimization::Method;
