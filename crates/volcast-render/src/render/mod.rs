//! Rendering: views, rays, render passes and their integrators, and the one
//! parallel loop that runs them. Opens no files; produces [`Film`]s of `f32`
//! channels.
//!
//! ```text
//! pass.rs        RenderPass (planned) --prepare--> dyn RenderView (generic inside);
//!                RayMode, a mode as the renderer runs it (implemented in crate::mode)
//! frame.rs       the loop over a view's pixels, in tiles
//! footprint.rs   per tile, the part of its rays a macrocell walk must cover
//! integrator/    what a ray computes, one type per mode (compositing's is in
//!                crate::mode::composite); `drive`, the one sampling loop
//! march.rs       where a ray is sampled
//! skip.rs        the macrocell grid and its walk (empty-space skipping)
//! camera.rs, ray.rs   views, rays and their clipping to the volume's box
//! clip.rs        clipping planes, cut from each ray's interval
//! ```

pub mod camera;
pub mod clip;
pub mod footprint;
pub mod frame;
pub mod integrator;
pub mod march;
pub mod pass;
pub mod ray;
pub mod skip;

pub use camera::{Ray, View};
pub use clip::{ClipPlane, Cut};
pub use frame::{Film, Kernel, RenderView};
pub use integrator::Counts;
pub use pass::{ImageKind, Needs, RenderPass, Resources};
pub use ray::IndexFrame;
