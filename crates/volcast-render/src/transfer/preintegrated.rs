//! Pre-integrated 1D transfer functions (Engel, Kraus and Ertl 2001, "High-quality
//! pre-integrated volume rendering using hardware-accelerated pixel shading";
//! docs/formulas.md "Emission-absorption and compositing").
//!
//! A ray segment of length `L` from a sample of value `f` (front) to one of value
//! `b` (back) is integrated as if the value varied linearly between them, so thin
//! peaks of the transfer function between two samples are not missed.
//!
//! - **Opacity, exact for any step.** With the extinction per reference step
//!   `sigma(v) = -ln(1 - alpha(v))` (the transfer function's alpha is defined for
//!   the reference step `dt0`), the segment's optical depth is
//!   `(L / dt0) * (K(b) - K(f)) / (b - f)` with `K(v) = integral_0^v sigma`. `K` is
//!   tabulated once ([`INTEGRAL_ENTRIES`] intervals), so the opacity
//!   `1 - exp(-depth)` is exact for whatever length the segment has (full steps,
//!   the shorter last step, jittered first steps).
//! - **Colour.** The segment's colour, with self-attenuation inside the segment,
//!   depends on its length: it is tabulated over (front, back) on a
//!   [`COLOR_ENTRIES`]^2 grid for the pass's step, as the colour per unit opacity
//!   (`C / A`), and multiplied by the exact opacity of each segment. Segments of
//!   another length (the last one) keep that mean colour, exact when the colour is
//!   constant across the segment's values.
//!
//! Opaque samples (`alpha = 1`) have infinite extinction; they are given
//! [`MAX_EXTINCTION`] per reference step, which is opaque to f32 precision for any
//! step longer than 2e-5 reference steps.

use rayon::prelude::*;

use super::one_d::clamp_unit;
use super::Transfer1D;

/// Intervals of the tabulated extinction integral `K` over [0, 1].
pub const INTEGRAL_ENTRIES: usize = 4096;
/// Entries per axis of the (front, back) colour table.
pub const COLOR_ENTRIES: usize = 256;
/// Extinction per reference step given to fully opaque values.
pub const MAX_EXTINCTION: f64 = 1e6;
/// Most sub-segments used to integrate one entry of the colour table: one per
/// 1/128 of the value range the segment spans (at least one), so each sub-segment
/// sees at most 1/128 of the transfer function.
const SUBSTEPS: usize = 64;

/// The pre-integration tables of one 1D transfer function for one step.
#[derive(Clone, Debug, PartialEq)]
pub struct Preintegrated {
    /// `K(i / INTEGRAL_ENTRIES)` for `i` in `0..=INTEGRAL_ENTRIES`.
    integral: Vec<f64>,
    /// Colour per unit opacity of a segment of the table's step, `[front][back]`.
    color: Vec<[f32; 3]>,
}

/// Extinction per reference step of opacity `a` (docs/formulas.md opacity correction:
/// `1 - a = exp(-sigma)`), capped at [`MAX_EXTINCTION`].
fn extinction(a: f32) -> f64 {
    let a = f64::from(clamp_unit(a));
    (-(-a).ln_1p()).min(MAX_EXTINCTION)
}

impl Preintegrated {
    /// Tables for `tf` and segments of `ratio` reference steps (the pass's step
    /// divided by the transfer function's reference step).
    pub fn build(tf: &Transfer1D, ratio: f64) -> Preintegrated {
        let m = INTEGRAL_ENTRIES;
        // K by Simpson's rule on each interval, split in two halves
        let mut integral = Vec::with_capacity(m + 1);
        integral.push(0.0);
        let h = 1.0 / m as f64;
        let sigma = |v: f64| extinction(tf.eval(v as f32)[3]);
        let mut k = 0.0f64;
        for i in 0..m {
            let v0 = i as f64 * h;
            let s = [0.0, 0.25, 0.5, 0.75, 1.0].map(|x| sigma(v0 + x * h));
            k += h / 12.0 * (s[0] + 4.0 * s[1] + 2.0 * s[2] + 4.0 * s[3] + s[4]);
            integral.push(k);
        }
        let colors = tf.table(INTEGRAL_ENTRIES);
        let n = COLOR_ENTRIES;
        let mut table = Preintegrated {
            integral,
            color: Vec::new(),
        };
        let color: Vec<[f32; 3]> = (0..n * n)
            .into_par_iter()
            .map(|idx| {
                let front = (idx / n) as f64 / (n - 1) as f64;
                let back = (idx % n) as f64 / (n - 1) as f64;
                table.integrate_color(front, back, ratio, |v| colors.lookup(v as f32))
            })
            .collect();
        table.color = color;
        table
    }

    /// The colour per unit opacity of a segment from `front` to `back` of `ratio`
    /// reference steps: front-to-back compositing of up to [`SUBSTEPS`] sub-segments,
    /// each with its exact opacity and the colour at its middle value.
    fn integrate_color(
        &self,
        front: f64,
        back: f64,
        ratio: f64,
        rgba: impl Fn(f64) -> [f32; 4],
    ) -> [f32; 3] {
        let mut c = [0.0f64; 3];
        let mut transparency = 1.0f64;
        let substeps = ((back - front).abs() * 128.0)
            .ceil()
            .clamp(1.0, SUBSTEPS as f64) as usize;
        let dv = (back - front) / substeps as f64;
        for s in 0..substeps {
            let (v0, v1) = (front + s as f64 * dv, front + (s + 1) as f64 * dv);
            let depth = self.mean_extinction(v0, v1) * ratio / substeps as f64;
            let a = -(-depth).exp_m1();
            let col = rgba(0.5 * (v0 + v1));
            for ch in 0..3 {
                c[ch] += transparency * a * f64::from(col[ch]);
            }
            transparency *= 1.0 - a;
        }
        let opacity = 1.0 - transparency;
        if opacity > 1e-12 {
            c.map(|x| (x / opacity) as f32)
        } else {
            // too transparent to weigh the colours: the colour at the middle value
            let col = rgba(0.5 * (front + back));
            [col[0], col[1], col[2]]
        }
    }

    /// `K(v)`, linear between the tabulated points.
    #[inline]
    fn k(&self, v: f64) -> f64 {
        let m = INTEGRAL_ENTRIES;
        let x = v.clamp(0.0, 1.0) * m as f64;
        let i = (x as usize).min(m - 1);
        let t = x - i as f64;
        self.integral[i] + t * (self.integral[i + 1] - self.integral[i])
    }

    /// The mean extinction per reference step over the values between `a` and `b`
    /// (over an interval one table entry wide around their middle when they are
    /// closer than that, where the difference quotient would cancel).
    #[inline]
    pub fn mean_extinction(&self, a: f64, b: f64) -> f64 {
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        let (lo, hi) = (lo.clamp(0.0, 1.0), hi.clamp(0.0, 1.0));
        let w = 1.0 / INTEGRAL_ENTRIES as f64;
        let (lo, hi) = if hi - lo >= w {
            (lo, hi)
        } else {
            let mid = 0.5 * (lo + hi);
            let lo = (mid - 0.5 * w).clamp(0.0, 1.0 - w);
            (lo, lo + w)
        };
        (self.k(hi) - self.k(lo)) / (hi - lo)
    }

    /// True when every segment whose two end values lie in `[lo, hi]` is fully
    /// transparent: the tabulated extinction integral is flat over the range and
    /// the one table entry around it that narrow segments are widened to (see
    /// [`Preintegrated::mean_extinction`]), so their opacity is exactly zero.
    pub fn transparent(&self, lo: f64, hi: f64) -> bool {
        let m = INTEGRAL_ENTRIES;
        let w = 1.0 / m as f64;
        let index = |v: f64| (v.clamp(0.0, 1.0) * m as f64) as usize;
        let (a, b) = (index(lo - 2.0 * w), (index(hi + 2.0 * w) + 1).min(m));
        // K never decreases (the extinction is not negative): equal ends, flat between
        self.integral[a] == self.integral[b]
    }

    /// RGB (not premultiplied) and opacity of a segment from a sample of value
    /// `front` to one of value `back`, `ratio` reference steps long.
    #[inline]
    pub fn segment(&self, front: f32, back: f32, ratio: f64) -> ([f32; 3], f32) {
        let (f, b) = (f64::from(clamp_unit(front)), f64::from(clamp_unit(back)));
        let depth = self.mean_extinction(f, b) * ratio.max(0.0);
        let alpha = -(-depth).exp_m1();
        // bilinear in (front, back)
        let n = COLOR_ENTRIES;
        let last = (n - 1) as f64;
        let (x, y) = (f * last, b * last);
        let (i, j) = ((x as usize).min(n - 2), (y as usize).min(n - 2));
        let (tx, ty) = ((x - i as f64) as f32, (y - j as f64) as f32);
        let at = |a: usize, b: usize| self.color[a * n + b];
        let (c00, c01, c10, c11) = (at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
        let rgb = std::array::from_fn(|ch| {
            let lo = c00[ch] + (c01[ch] - c00[ch]) * ty;
            let hi = c10[ch] + (c11[ch] - c10[ch]) * ty;
            lo + (hi - lo) * tx
        });
        (rgb, alpha as f32)
    }

    /// Memory held by the tables, in bytes.
    pub fn byte_size(&self) -> usize {
        std::mem::size_of_val(self.integral.as_slice())
            + std::mem::size_of_val(self.color.as_slice())
    }

    /// Memory the tables take, in bytes, before building them (for the plan).
    pub fn planned_bytes() -> u64 {
        ((INTEGRAL_ENTRIES + 1) * 8 + COLOR_ENTRIES * COLOR_ENTRIES * 12) as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transfer::Interpolation;

    fn tf(alpha: Vec<(f32, f32)>) -> Transfer1D {
        Transfer1D::new(
            vec![(0.0, [1.0, 0.5, 0.25]), (1.0, [1.0, 0.5, 0.25])],
            alpha,
            Interpolation::Linear,
        )
        .unwrap()
    }

    #[test]
    fn constant_alpha_gives_the_corrected_opacity() {
        // alpha a per reference step: a segment of r steps has 1 - (1 - a)^r
        let a = 0.3f32;
        let p = Preintegrated::build(&tf(vec![(0.0, a), (1.0, a)]), 0.5);
        for (f, b, r) in [(0.1, 0.9, 0.5), (0.5, 0.5, 2.0), (1.0, 0.0, 1e-3)] {
            let (c, alpha) = p.segment(f, b, r);
            let want = 1.0 - (1.0 - f64::from(a)).powf(r);
            assert!(
                (f64::from(alpha) - want).abs() < 1e-6 * want.max(1e-3),
                "{alpha} vs {want}"
            );
            assert!((c[1] - 0.5).abs() < 1e-6);
        }
    }

    #[test]
    fn a_peak_between_samples_is_not_missed() {
        // alpha is a narrow tent at 0.5; a segment from 0.2 to 0.8 crosses it.
        let peak = tf(vec![
            (0.0, 0.0),
            (0.49, 0.0),
            (0.5, 0.9),
            (0.51, 0.0),
            (1.0, 0.0),
        ]);
        let p = Preintegrated::build(&peak, 1.0);
        let (_, alpha) = p.segment(0.2, 0.8, 1.0);
        // Independent value: the mean of sigma over [0.2, 0.8] is the tent's integral
        // of -ln(1 - alpha) over 0.6; the tent's integral by a fine midpoint sum.
        let n = 200_000;
        let mut integral = 0.0f64;
        for k in 0..n {
            let v = 0.49 + 0.02 * (k as f64 + 0.5) / n as f64;
            let a = 0.9 * (1.0 - (v - 0.5).abs() / 0.01);
            integral += -(1.0 - a).ln() * 0.02 / n as f64;
        }
        let want = 1.0 - (-integral / 0.6).exp();
        assert!((f64::from(alpha) - want).abs() < 1e-4, "{alpha} vs {want}");
        // the midpoint sample (0.5 exactly) would see alpha 0.9, the end samples 0
        assert!(alpha > 0.01 && alpha < 0.1);
        // and the other direction (back to front values) is the same segment
        assert_eq!(p.segment(0.8, 0.2, 1.0).1, alpha);
    }

    #[test]
    fn opaque_values_stay_opaque() {
        let p = Preintegrated::build(&tf(vec![(0.0, 1.0), (1.0, 1.0)]), 1.0);
        assert_eq!(p.segment(0.3, 0.7, 1.0).1, 1.0);
        assert_eq!(p.segment(0.3, 0.3, 1e-3).1, 1.0);
        assert!(p.byte_size() as u64 == Preintegrated::planned_bytes());
    }
}
