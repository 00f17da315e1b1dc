//! Procedural demo scene.
