//! The parallel loop over the pixels of one view, shared by every render mode.
//!
//! Rows are rendered in parallel (rayon) into disjoint slices of the film; a
//! pixel's value depends only on the view and the pixel, so the image is the same
//! whatever the thread count or the order rows finish in.

use rayon::prelude::*;

use super::integrator::{jitter_fraction, trace, Kernel, PixelRay};
use super::{IndexFrame, View};
use crate::sample::Field;
use crate::scene::Projection;

/// An image of `f32` channels (1 = intensity, 4 = RGBA not premultiplied), row 0
/// at the top, channels fastest.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Channels per pixel.
    pub channels: usize,
    /// `width * height * channels` values.
    pub data: Vec<f32>,
}

impl Film {
    /// A film filled with zeros.
    pub fn new(width: usize, height: usize, channels: usize) -> Film {
        Film {
            width,
            height,
            channels,
            data: vec![0.0; width * height * channels],
        }
    }

    /// The channels of pixel `(i, j)`.
    pub fn pixel(&self, i: usize, j: usize) -> &[f32] {
        let s = (j * self.width + i) * self.channels;
        &self.data[s..s + self.channels]
    }
}

/// Renders `view` with `kernel` over `field`; `dt` is the sample spacing in world
/// units. Returns the film and the number of field samples taken.
pub fn render_view<F: Field>(
    view: &View,
    kernel: &Kernel,
    field: &F,
    frame: &IndexFrame,
    dt: f64,
) -> (Film, u64) {
    let channels = kernel.channels();
    let mut film = Film::new(view.width, view.height, channels);
    let miss = kernel.miss();
    let row_len = view.width * channels;
    let samples: u64 = film
        .data
        .par_chunks_mut(row_len)
        .enumerate()
        .map(|(j, row)| {
            let mut count = 0u64;
            for (i, px) in row.chunks_exact_mut(channels).enumerate() {
                let (value, n) =
                    render_pixel(view, kernel, field, frame, dt, i, j).unwrap_or((miss, 0));
                px.copy_from_slice(&value[..channels]);
                count += n;
            }
            count
        })
        .sum();
    (film, samples)
}

/// One pixel (also the way to debug a single pixel); `None` where the ray misses.
pub fn render_pixel<F: Field>(
    view: &View,
    kernel: &Kernel,
    field: &F,
    frame: &IndexFrame,
    dt: f64,
    i: usize,
    j: usize,
) -> Option<([f32; 4], u64)> {
    let ray = view.pixel_ray(i, j);
    let index = frame.to_index(ray.origin, ray.dir);
    let t_min = match view.projection {
        Projection::Perspective => 0.0,
        Projection::Orthographic => f64::NEG_INFINITY,
    };
    let (t_enter, t_exit) = frame.clip(&index, t_min)?;
    let pixel_ray = PixelRay {
        origin: ray.origin,
        dir: ray.dir,
        index,
        t_enter,
        t_exit,
        t_depth_ref: view.depth_reference(&ray).unwrap_or(t_enter),
    };
    let jitter = kernel.jitter.map_or(0.0, |seed| {
        let (e, f) = (view.eye, view.forward);
        jitter_fraction(seed, [e.x, e.y, e.z, f.x, f.y, f.z], i, j)
    });
    Some(trace(kernel, field, &pixel_ray, dt, jitter))
}
