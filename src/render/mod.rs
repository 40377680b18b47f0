//! Rendering: views, rays and integrators, and the one parallel loop that runs them.
//! Opens no files; produces [`Film`]s of `f32` channels.

pub mod camera;
pub mod frame;
pub mod integrator;
pub mod ray;

pub use camera::{Ray, View};
pub use frame::{render_view, Film};
pub use integrator::{Kernel, TransferTable};
pub use ray::IndexFrame;
