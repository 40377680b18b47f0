//! MIP, MinIP, average and local MIP (REFERENCE.md "Render modes").

use super::xray::trapezoid;
use super::March;

/// The extremum (`pick` = max or min) of the samples.
pub fn extremum(
    march: &March,
    value: impl Fn(f64) -> f32,
    pick: fn(f32, f32) -> f32,
) -> ([f32; 4], u64) {
    let n = march.len();
    let mut best = value(march.t(0));
    for i in 1..n {
        best = pick(best, value(march.t(i)));
    }
    ([best, 0.0, 0.0, 0.0], n as u64)
}

/// The length-weighted mean (the trapezoid integral over the length); a ray of zero
/// length (grazing a corner) gets its one sample.
pub fn average(march: &March, value: impl Fn(f64) -> f32) -> ([f32; 4], u64) {
    let n = march.len();
    let (t0, t1) = (march.t(0), march.t(n - 1));
    let (integral, first) = trapezoid(march, value);
    let mean = if n == 1 || t1 <= t0 {
        first
    } else {
        integral / (t1 - t0)
    };
    ([mean as f32, 0.0, 0.0, 0.0], n as u64)
}

/// The first local maximum among samples at or above `threshold`: the last sample
/// of the first non-decreasing run that starts at or above it. Where no sample
/// reaches the threshold the result is the ray's maximum (as in Sato et al. 1998),
/// so the image has no holes.
pub fn lmip(march: &March, value: impl Fn(f64) -> f32, threshold: f32) -> ([f32; 4], u64) {
    let n = march.len();
    let mut max = f32::NEG_INFINITY;
    let mut climbing: Option<f32> = None;
    for i in 0..n {
        let f = value(march.t(i));
        match climbing {
            Some(prev) if f < prev => return ([prev, 0.0, 0.0, 0.0], i as u64 + 1),
            Some(_) => climbing = Some(f),
            None if f >= threshold => climbing = Some(f),
            None => max = max.max(f),
        }
    }
    ([climbing.unwrap_or(max), 0.0, 0.0, 0.0], n as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(v: &'static [f32]) -> (March, impl Fn(f64) -> f32) {
        let m = March::new(0.0, (v.len() - 1) as f64, 1.0);
        (m, move |t: f64| v[t.round() as usize])
    }

    #[test]
    fn lmip_picks_first_peak_above_threshold() {
        let (m, f) = samples(&[0.1, 0.6, 0.7, 0.65, 0.9, 0.2]);
        assert_eq!(lmip(&m, f, 0.5).0[0], 0.7);
        let (m, f) = samples(&[0.1, 0.3, 0.2]);
        assert_eq!(lmip(&m, f, 0.5).0[0], 0.3, "falls back to the maximum");
        let (m, f) = samples(&[0.1, 0.6, 0.8]);
        assert_eq!(lmip(&m, f, 0.5).0[0], 0.8, "still climbing at the exit");
    }

    #[test]
    fn average_is_length_weighted() {
        let m = March::new(0.0, 1.5, 1.0); // samples at 0, 1, 1.5
        let r = average(&m, |t| t as f32);
        assert!((r.0[0] - 0.75).abs() < 1e-7);
    }
}
