//! Emission-absorption compositing, front to back (REFERENCE.md
//! "Emission-absorption and compositing"). Each segment between two sample
//! positions is represented by the field at its midpoint; its opacity is corrected
//! from the transfer function's reference step to the segment's own length, so the
//! image converges as the step shrinks. Colour and opacity accumulate in f64: with
//! tiny opacities and tiny steps (1e-7 per voxel at 1e-3 voxel) each sample adds
//! hundreds of f32 ulps' worth, and f32 rounding would drift as the step shrinks.
//!
//! Pre-integrated passes (`preintegrated = true`) instead sample the field at the
//! march positions and take each segment's colour and opacity from the table of
//! segment integrals over (front value, back value) ([`Preintegrated`]; Engel et al.
//! 2001), so a thin peak of the transfer function between two samples still counts.

use glam::{DVec3, Vec3};

use super::crossing::normal_from_gradient;
use super::{March, PixelRay, TransferTable};
use crate::sample::Field;
use crate::shade::Shader;
use crate::transfer::{correct_opacity, Preintegrated};

pub struct Params<'a> {
    pub table: TransferTable<'a>,
    pub shader: Option<&'a Shader>,
    pub reference_step: f64,
    pub early_stop: f32,
    pub voxel_length: f64,
    pub preintegrated: Option<&'a Preintegrated>,
}

pub fn trace<F: Field>(march: &March, field: &F, ray: &PixelRay, p: Params) -> ([f32; 4], u64) {
    if let Some(pre) = p.preintegrated {
        return trace_preintegrated(march, field, ray, &p, pre);
    }
    let n = march.len();
    let mut acc = FrontToBack::new(p.early_stop);
    let mut samples = 0;
    let to_eye = (-ray.dir).as_vec3();
    for i in 1..n {
        let (ta, tb) = (march.t(i - 1), march.t(i));
        let length = tb - ta;
        if length <= 0.0 {
            continue;
        }
        let t = 0.5 * (ta + tb);
        let pos = ray.index.at(t);
        let v = field.value(pos);
        samples += 1;
        let mut grad = None;
        let rgba = match p.table {
            TransferTable::OneD(tab) => tab.lookup(v),
            TransferTable::TwoD(tab) => {
                let g = field.gradient(pos);
                grad = Some(g);
                tab.lookup(v, (g.length() * p.voxel_length) as f32)
            }
        };
        let a = correct_opacity(rgba[3], (length / p.reference_step) as f32);
        if a <= 0.0 {
            continue;
        }
        let base = Vec3::new(rgba[0], rgba[1], rgba[2]);
        let c = shade(p.shader, field, ray, t, grad, base, to_eye);
        if acc.add(c, a) {
            break;
        }
    }
    (acc.finish(), samples)
}

/// Front-to-back compositing of pre-integrated segments between consecutive samples.
fn trace_preintegrated<F: Field>(
    march: &March,
    field: &F,
    ray: &PixelRay,
    p: &Params,
    pre: &Preintegrated,
) -> ([f32; 4], u64) {
    let n = march.len();
    let mut acc = FrontToBack::new(p.early_stop);
    let to_eye = (-ray.dir).as_vec3();
    let mut t_prev = march.t(0);
    let mut v_prev = field.value(ray.index.at(t_prev));
    let mut samples = 1;
    for i in 1..n {
        let t = march.t(i);
        let length = t - t_prev;
        if length <= 0.0 {
            continue;
        }
        let v = field.value(ray.index.at(t));
        samples += 1;
        let (rgb, a) = pre.segment(v_prev, v, length / p.reference_step);
        let t_mid = 0.5 * (t_prev + t);
        t_prev = t;
        v_prev = v;
        if a <= 0.0 {
            continue;
        }
        let base = Vec3::from_array(rgb);
        let c = shade(p.shader, field, ray, t_mid, None, base, to_eye);
        if acc.add(c, a) {
            break;
        }
    }
    (acc.finish(), samples)
}

/// The colour of a sample: the transfer function's colour `base`, shaded where the
/// pass shades (with the gradient already computed for a 2D transfer function, if any).
fn shade<F: Field>(
    shader: Option<&Shader>,
    field: &F,
    ray: &PixelRay,
    t: f64,
    gradient: Option<DVec3>,
    base: Vec3,
    to_eye: Vec3,
) -> Vec3 {
    let Some(shader) = shader else { return base };
    let g = gradient.unwrap_or_else(|| field.gradient(ray.index.at(t)));
    let normal = normal_from_gradient(g, ray.dir);
    shader.shade(
        ray.world(t).as_vec3(),
        normal.map(|n| n.as_vec3()),
        to_eye,
        base,
    )
}

/// Front-to-back accumulation (REFERENCE.md: `C' += (1 - A') C_i`, `A' += (1 - A') A_i`)
/// in f64, with early ray termination.
struct FrontToBack {
    color: DVec3,
    alpha: f64,
    early_stop: f64,
}

impl FrontToBack {
    fn new(early_stop: f32) -> FrontToBack {
        FrontToBack {
            color: DVec3::ZERO,
            alpha: 0.0,
            early_stop: f64::from(early_stop),
        }
    }

    /// Adds a sample of colour `c` and opacity `a`; true once the ray may stop.
    #[inline]
    fn add(&mut self, c: Vec3, a: f32) -> bool {
        let w = (1.0 - self.alpha) * f64::from(a);
        self.color += c.as_dvec3() * w;
        self.alpha += w;
        self.alpha >= self.early_stop
    }

    /// RGBA, not premultiplied.
    fn finish(self) -> [f32; 4] {
        if self.alpha > 0.0 {
            let c = (self.color / self.alpha).as_vec3();
            [c.x, c.y, c.z, self.alpha as f32]
        } else {
            [0.0; 4]
        }
    }
}
