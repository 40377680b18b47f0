//! volcast: declarative TOML scene files in, rendered images of 3D scalar volumes out.
//!
//! ```text
//! scene file --scene::load--> Scene (resolved, validated, paths absolute)
//!            --VolumeSource::header--> VolumeHeader (no voxel memory yet)
//!            --plan::Plan::build--> Plan (views x passes; precomputations; memory)
//!            --VolumeSource::load--> Volume (native type, limits checked first)
//!            --render::render_view--> Film (f32 channels per view)
//!            --output::write--> numbered files (written atomically)
//! ```
//! The scene-file contract is `SCENES.md`; the formulas are those of `REFERENCE.md`
//! (both in the project's shared folder); the README documents the whole format.
#![warn(missing_docs)]

pub mod batch;
pub mod bench;
pub mod error;
pub mod histogram;
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
