//! volcast: declarative TOML scene files in, rendered images of 3D scalar volumes out.
//!
//! One run, top to bottom ([`pipeline::render`]):
//!
//! ```text
//! scene file --scene::load-------------> Scene (parsed, validated, paths absolute)
//!            --VolumeSource::header----> VolumeHeader (sizes, type, geometry; no voxels)
//!            --plan::Plan::build-------> Plan (views x passes, precomputations, memory;
//!                                        each pass's mode::Mode plans its RayMode; the
//!                                        outputs and the scene's record: the Scene is
//!                                        not read after this)
//!            --VolumeSource::load------> Volume (native type, limits checked first)
//!            --pipeline (fit)----------> Plan with the zoom of `zoom = "fit"`
//!            --RenderPass::prepare-----> a RenderView per pass (tables, grids, gradients)
//!            --RenderView::render------> Film (f32 channels per view)
//!            --output (encode, write)--> numbered files, written atomically, and the
//!                                        manifest, the animations and the viewer page
//! ```
//!
//! The layers, from the bottom: [`label`], [`transfer`], [`shade`], [`batch`] and
//! [`volume`] (readers, no rendering); [`sample`] (reconstruction of the field);
//! [`render`] (cameras, rays, passes and integrators); [`mode`] (the render modes,
//! one module per family); [`scene`] (the file format);
//! [`views`] and [`output`]; [`plan`]; [`histogram`]; [`pipeline`]; [`mod@bench`]. A
//! module imports only from the layers below it. The scene-file reference and the
//! formulas are in the user guide (`docs/`).
#![warn(missing_docs)]

pub mod batch;
pub mod bench;
pub mod error;
pub mod histogram;
pub mod label;
pub mod mode;
pub mod number;
pub mod output;
mod parallel;
pub mod plan;
pub mod render;
pub mod sample;
pub mod scene;
pub mod shade;
pub mod transfer;
pub mod views;
pub mod volume;

pub use error::Error;
pub mod pipeline;
