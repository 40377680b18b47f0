//! Per-ray integrators: one function per render mode, each a pure function of the
//! field and the ray (no I/O, no locks, no allocation).
//!
//! A ray inside the box is sampled at `t_enter`, every `dt` after it, and at
//! `t_exit` (the last step is shorter), so the entry and exit points are always
//! sampled and the samples cover the whole segment. Formulas: REFERENCE.md
//! "Render modes" and "Emission-absorption and compositing".

mod composite;
mod crossing;
mod projection;
mod xray;

use glam::DVec3;

use crate::sample::Field;
use crate::scene::XrayOutput;
use crate::shade::Shader;
use crate::transfer::{Table1D, Table2D};

use super::ray::IndexRay;

/// A transfer-function table.
#[derive(Clone, Copy, Debug)]
pub enum TransferTable<'a> {
    /// Over the normalised value.
    OneD(&'a Table1D),
    /// Over (value, gradient magnitude per voxel of the smallest spacing).
    TwoD(&'a Table2D),
}

/// What a pass computes per ray, with everything precomputed it needs.
#[derive(Clone, Debug)]
pub enum Kernel<'a> {
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
    },
}

impl Kernel<'_> {
    /// Channels per pixel (1 for intensity modes, 4 for RGBA).
    pub fn channels(&self) -> usize {
        match self {
            Kernel::Surface { .. } | Kernel::Composite { .. } => 4,
            _ => 1,
        }
    }

    /// The pixel value where a ray misses the volume.
    pub fn miss(&self) -> [f32; 4] {
        match self {
            // the line integral of nothing is zero
            Kernel::Xray { output, .. } => [xray::finish(0.0, *output, 1.0), 0.0, 0.0, 0.0],
            Kernel::Surface { .. } | Kernel::Composite { .. } => [0.0; 4],
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

/// Sample positions along `[t0, t1]`: `t0`, every `dt`, and `t1`.
#[derive(Clone, Copy, Debug)]
pub struct March {
    t0: f64,
    t1: f64,
    dt: f64,
    full_steps: usize,
    tail: bool,
}

impl March {
    /// The march for one ray segment.
    pub fn new(t0: f64, t1: f64, dt: f64) -> March {
        let len = (t1 - t0).max(0.0);
        let full_steps = (len / dt).floor() as usize;
        // a tail shorter than a millionth of a step is merged into the last sample
        let tail = len - full_steps as f64 * dt > 1e-6 * dt;
        March {
            t0,
            t1,
            dt,
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
            (self.t0 + i as f64 * self.dt).min(self.t1)
        }
    }
}

/// Integrates one ray; returns the pixel value and the number of field samples taken.
pub fn trace<F: Field>(kernel: &Kernel, field: &F, ray: &PixelRay, dt: f64) -> ([f32; 4], u64) {
    let march = March::new(ray.t_enter, ray.t_exit, dt);
    let value = |t: f64| field.value(ray.index.at(t));
    match kernel {
        Kernel::Xray { output, mu } => xray::trace(&march, value, *output, *mu),
        Kernel::Mip => projection::extremum(&march, value, f32::max),
        Kernel::Minip => projection::extremum(&march, value, f32::min),
        Kernel::Average => projection::average(&march, value),
        Kernel::Lmip { threshold } => projection::lmip(&march, value, *threshold),
        Kernel::Depth { threshold } => crossing::depth(&march, value, *threshold, ray),
        Kernel::Surface { iso, shader } => crossing::surface(&march, field, *iso, shader, ray),
        Kernel::Composite {
            table,
            shader,
            reference_step,
            early_stop,
            voxel_length,
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
            },
        ),
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
    fn long_march_does_not_drift() {
        let m = March::new(0.0, 1.0, 1e-6);
        assert_eq!(m.t(m.len() - 1), 1.0);
        assert!((m.t(500_000) - 0.5).abs() < 1e-15);
    }
}
