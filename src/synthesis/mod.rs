//! Texture synthesis systems that reuse the shared geometry and hierarchy modules.
//!
//! - [`quilting`]: geometric texture synthesis by mesh quilting (Zhou et al. 2006).
//! - [`wei_levoy`]: image-exemplar texture synthesis over arbitrary surfaces (Wei & Levoy 2001).

pub mod quilting;
pub mod wei_levoy;

pub use wei_levoy::{Orientation, Search, SynthParams, SynthResult, SynthTimings, synthesize};
