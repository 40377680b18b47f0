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
    let n = march.len();
    let mut sum = 0.0f64;
    let mut t_prev = march.t(0);
    let mut f_prev = value(t_prev) as f64;
    for i in 1..n {
        let t = march.t(i);
        let f = value(t) as f64;
        sum += (t - t_prev) * (f_prev + f) * 0.5;
        t_prev = t;
        f_prev = f;
    }
    ([finish(sum, output, mu), 0.0, 0.0, 0.0], n as u64)
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
