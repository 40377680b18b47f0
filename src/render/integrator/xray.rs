//! X-ray / look-through (REFERENCE.md "Render modes"): the line integral of the
//! normalised value by the trapezoid rule, accumulated in f64; Beer-Lambert for the
//! absorbed and transmitted images.

use super::March;
use crate::scene::XrayOutput;

pub fn trace(
    march: &March,
    value: impl Fn(f64) -> f32,
    output: XrayOutput,
    mu: f64,
) -> ([f32; 4], u64) {
    let (integral, _) = trapezoid(march, value);
    (
        [finish(integral, output, mu), 0.0, 0.0, 0.0],
        march.len() as u64,
    )
}

/// The trapezoid-rule integral of `value` over the march, accumulated in f64, and
/// the value at its first sample.
pub fn trapezoid(march: &March, value: impl Fn(f64) -> f32) -> (f64, f64) {
    let mut sum = 0.0f64;
    let mut t_prev = march.t(0);
    let first = value(t_prev) as f64;
    let mut f_prev = first;
    for i in 1..march.len() {
        let t = march.t(i);
        let f = value(t) as f64;
        sum += (t - t_prev) * (f_prev + f) * 0.5;
        t_prev = t;
        f_prev = f;
    }
    (sum, first)
}

/// The stored quantity for a line integral `integral` of the normalised value.
pub fn finish(integral: f64, output: XrayOutput, mu: f64) -> f32 {
    let tau = mu * integral;
    (match output {
        XrayOutput::Integral => tau,
        XrayOutput::Absorbed => -(-tau).exp_m1(),
        XrayOutput::Transmitted => (-tau).exp(),
    }) as f32
}
