//! Per-ray integrators: one function per render mode, each a pure function of the
//! field and the ray (no I/O, no locks, no allocation).
//!
//! A ray inside the box is sampled at `t_enter`, every `dt` after it, and at
//! `t_exit` (the last step is shorter), so the entry and exit points are always
//! sampled and the samples cover the whole segment. With jitter, the samples
//! after the entry are shifted by a per-pixel fraction of `dt` (the entry and exit
//! are still sampled). Exact passes ([`Exact`], `exact.rs`) walk the cells instead
//! of sampling. Formulas: REFERENCE.md "Render modes" and "Emission-absorption and
//! compositing".

mod composite;
mod crossing;
mod exact;
mod projection;
mod root;
mod xray;

use std::sync::Arc;

use glam::DVec3;

pub use exact::Exact;

use crate::sample::Field;
use crate::scene::XrayOutput;
use crate::shade::Shader;
use crate::transfer::{Preintegrated, Table1D, Table2D};

use super::ray::IndexRay;

/// A transfer-function table.
#[derive(Clone, Copy, Debug)]
pub enum TransferTable<'a> {
    /// Over the normalised value.
    OneD(&'a Table1D),
    /// Over (value, gradient magnitude per voxel of the smallest spacing).
    TwoD(&'a Table2D),
}

/// What a pass computes per ray and how it samples the ray.
#[derive(Clone, Debug)]
pub struct Kernel<'a> {
    /// The quantity computed per ray, with everything precomputed it needs.
    pub integrand: Integrand<'a>,
    /// Per-pass seed of the jittered first sample; `None` = no jitter.
    pub jitter: Option<u64>,
}

impl<'a> From<Integrand<'a>> for Kernel<'a> {
    fn from(integrand: Integrand<'a>) -> Self {
        Kernel {
            integrand,
            jitter: None,
        }
    }
}

/// What a pass computes per ray, with everything precomputed it needs.
#[derive(Clone, Debug)]
pub enum Integrand<'a> {
    /// Line integral (trapezoid rule, accumulated in f64).
    Xray {
        /// Stored quantity.
        output: XrayOutput,
        /// Attenuation scale.
        mu: f64,
    },
    /// Maximum along the ray.
    Mip,
    /// Minimum along the ray.
    Minip,
    /// Length-weighted mean along the ray.
    Average,
    /// First local maximum at or above `threshold` (else the maximum).
    Lmip {
        /// Normalised value.
        threshold: f32,
    },
    /// Distance from the depth reference to the first crossing of `threshold`.
    Depth {
        /// Normalised value.
        threshold: f32,
    },
    /// Shaded first crossing of `iso`.
    Surface {
        /// Normalised value.
        iso: f32,
        /// Reflection model, material and light.
        shader: Shader,
    },
    /// Front-to-back emission-absorption.
    Composite {
        /// Transfer function table.
        table: TransferTable<'a>,
        /// Optional shading of each sample.
        shader: Option<Shader>,
        /// Reference step of the transfer function's alpha, world units.
        reference_step: f64,
        /// Stop once the accumulated opacity reaches this.
        early_stop: f32,
        /// World length of one voxel of the smallest spacing (to express gradient
        /// magnitudes per voxel for 2D transfer functions).
        voxel_length: f64,
        /// Pre-integrated segment table (1D transfer functions only).
        preintegrated: Option<Arc<Preintegrated>>,
    },
    /// Exact integration of the trilinear interpolant, cell by cell.
    Exact(Exact),
}

impl Kernel<'_> {
    /// Channels per pixel (1 for intensity modes, 4 for RGBA).
    pub fn channels(&self) -> usize {
        match &self.integrand {
            Integrand::Surface { .. }
            | Integrand::Composite { .. }
            | Integrand::Exact(Exact::Surface { .. }) => 4,
            _ => 1,
        }
    }

    /// The pixel value where a ray misses the volume.
    pub fn miss(&self) -> [f32; 4] {
        match &self.integrand {
            // the line integral of nothing is zero
            Integrand::Xray { output, .. } | Integrand::Exact(Exact::Xray { output, .. }) => {
                [xray::finish(0.0, *output, 1.0), 0.0, 0.0, 0.0]
            }
            _ if self.channels() == 4 => [0.0; 4],
            _ => [f32::NAN, 0.0, 0.0, 0.0],
        }
    }
}

/// Everything about one pixel's ray an integrator needs.
#[derive(Clone, Copy, Debug)]
pub struct PixelRay {
    /// World origin.
    pub origin: DVec3,
    /// World unit direction.
    pub dir: DVec3,
    /// Index-space form.
    pub index: IndexRay,
    /// Entry into the box (world-unit parameter).
    pub t_enter: f64,
    /// Exit from the box.
    pub t_exit: f64,
    /// Where depth is measured from.
    pub t_depth_ref: f64,
}

impl PixelRay {
    /// World position at `t`.
    #[inline(always)]
    pub fn world(&self, t: f64) -> DVec3 {
        self.origin + self.dir * t
    }
}

/// Sample positions along `[t0, t1]`: `t0`, every `dt` (shifted back by a
/// fraction of `dt` when jittered), and `t1`.
#[derive(Clone, Copy, Debug)]
pub struct March {
    t0: f64,
    t1: f64,
    dt: f64,
    /// Sample `i >= 1` sits at `t0 + (i + shift) dt`; `shift` is in `(-1, 0]`.
    shift: f64,
    full_steps: usize,
    tail: bool,
}

impl March {
    /// The march for one ray segment.
    pub fn new(t0: f64, t1: f64, dt: f64) -> March {
        March::jittered(t0, t1, dt, 0.0)
    }

    /// The march with every sample after the entry moved back by `jitter * dt`,
    /// `jitter` in `[0, 1)` (0 = the plain march, bit for bit): the samples are
    /// `t0`, `t0 + (1 - jitter) dt`, `t0 + (2 - jitter) dt`, ..., `t1`.
    pub fn jittered(t0: f64, t1: f64, dt: f64, jitter: f64) -> March {
        let shift = -jitter.clamp(0.0, 1.0 - f64::EPSILON);
        let len = (t1 - t0).max(0.0);
        let full_steps = (len / dt - shift).floor() as usize;
        // a tail shorter than a millionth of a step is merged into the last sample
        let tail = len - (full_steps as f64 + shift) * dt > 1e-6 * dt;
        March {
            t0,
            t1,
            dt,
            shift,
            full_steps,
            tail,
        }
    }

    /// Number of sample positions.
    pub fn len(&self) -> usize {
        self.full_steps + 1 + usize::from(self.tail)
    }

    /// Always false: a march has at least its entry point.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Position `i` (`0 <= i < len()`): computed from the index, never accumulated,
    /// so long rays do not drift.
    #[inline(always)]
    pub fn t(&self, i: usize) -> f64 {
        if i > self.full_steps {
            self.t1
        } else {
            // `i + 0.0` is exact, so the plain march is unchanged by the shift
            (self.t0 + (i as f64 + self.shift) * self.dt)
                .max(self.t0)
                .min(self.t1)
        }
    }
}

/// The jitter of one pixel's first sample, in `[0, 1)` of a step: a hash of the
/// pass's seed, the view's pose (which identifies the frame and the eye) and the
/// pixel, so it is the same whatever thread renders the pixel (REFERENCE.md
/// "Emission-absorption and compositing": a fixed per-pixel seed keeps frames
/// reproducible).
pub fn jitter_fraction(seed: u64, pose: [f64; 6], i: usize, j: usize) -> f64 {
    let mut h = splitmix64(seed);
    for x in pose {
        h = splitmix64(h ^ x.to_bits());
    }
    h = splitmix64(h ^ i as u64);
    h = splitmix64(h ^ ((j as u64) << 32 | 0x5bd1));
    // the top 53 bits as a fraction in [0, 1)
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// SplitMix64's finaliser (Steele, Lea and Flood 2014): a bijective 64-bit mix.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Integrates one ray; `jitter` (in `[0, 1)`) moves the samples after the entry
/// back by that fraction of `dt`. Returns the pixel value and the number of field
/// samples taken (cells visited, for exact passes).
pub fn trace<F: Field>(
    kernel: &Kernel,
    field: &F,
    ray: &PixelRay,
    dt: f64,
    jitter: f64,
) -> ([f32; 4], u64) {
    let march = March::jittered(ray.t_enter, ray.t_exit, dt, jitter);
    let value = |t: f64| field.value(ray.index.at(t));
    match &kernel.integrand {
        Integrand::Xray { output, mu } => xray::trace(&march, value, *output, *mu),
        Integrand::Mip => projection::extremum(&march, value, f32::max),
        Integrand::Minip => projection::extremum(&march, value, f32::min),
        Integrand::Average => projection::average(&march, value),
        Integrand::Lmip { threshold } => projection::lmip(&march, value, *threshold),
        Integrand::Depth { threshold } => crossing::depth(&march, value, *threshold, ray),
        Integrand::Surface { iso, shader } => crossing::surface(&march, field, *iso, shader, ray),
        Integrand::Composite {
            table,
            shader,
            reference_step,
            early_stop,
            voxel_length,
            preintegrated,
        } => composite::trace(
            &march,
            field,
            ray,
            composite::Params {
                table: *table,
                shader: shader.as_ref(),
                reference_step: *reference_step,
                early_stop: *early_stop,
                voxel_length: *voxel_length,
                preintegrated: preintegrated.as_deref(),
            },
        ),
        Integrand::Exact(e) => exact::trace(e, field, ray),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn march_covers_the_segment() {
        let m = March::new(1.0, 3.5, 1.0);
        let ts: Vec<f64> = (0..m.len()).map(|i| m.t(i)).collect();
        assert_eq!(ts, vec![1.0, 2.0, 3.0, 3.5]);
        let m = March::new(1.0, 3.0, 1.0);
        assert_eq!(
            (0..m.len()).map(|i| m.t(i)).collect::<Vec<_>>(),
            vec![1.0, 2.0, 3.0]
        );
        let m = March::new(2.0, 2.0, 0.5);
        assert_eq!(m.len(), 1);
        assert_eq!(m.t(0), 2.0);
    }

    #[test]
    fn jittered_march_keeps_entry_and_exit() {
        let m = March::jittered(1.0, 3.5, 1.0, 0.25);
        let ts: Vec<f64> = (0..m.len()).map(|i| m.t(i)).collect();
        assert_eq!(ts, vec![1.0, 1.75, 2.75, 3.5]);
        let m = March::jittered(1.0, 3.0, 1.0, 0.5);
        let ts: Vec<f64> = (0..m.len()).map(|i| m.t(i)).collect();
        assert_eq!(ts, vec![1.0, 1.5, 2.5, 3.0]);
        // zero jitter is the plain march, bit for bit
        let (a, b) = (
            March::new(0.1, 7.3, 0.37),
            March::jittered(0.1, 7.3, 0.37, 0.0),
        );
        assert_eq!(a.len(), b.len());
        for i in 0..a.len() {
            assert_eq!(a.t(i).to_bits(), b.t(i).to_bits());
        }
    }

    #[test]
    fn jitter_is_a_deterministic_uniform_fraction() {
        let pose = [0.0, -3.0, 0.0, 0.0, 1.0, 0.0];
        let f = |i, j| jitter_fraction(7, pose, i, j);
        assert_eq!(f(3, 4), f(3, 4));
        assert_ne!(f(3, 4), f(4, 3));
        assert_ne!(f(3, 4), jitter_fraction(8, pose, 3, 4));
        // the mean of many pixels is near 1/2 (standard error 1/sqrt(12 n) = 0.003)
        let n = 10_000;
        let mean: f64 = (0..n).map(|k| f(k % 100, k / 100)).sum::<f64>() / n as f64;
        assert!((mean - 0.5).abs() < 0.015, "{mean}");
        assert!((0..n).all(|k| (0.0..1.0).contains(&f(k % 100, k / 100))));
    }

    #[test]
    fn long_march_does_not_drift() {
        let m = March::new(0.0, 1.0, 1e-6);
        assert_eq!(m.t(m.len() - 1), 1.0);
        assert!((m.t(500_000) - 0.5).abs() < 1e-15);
    }
}
