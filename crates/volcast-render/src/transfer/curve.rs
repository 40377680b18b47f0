//! Curves through knots: piecewise linear, or monotone piecewise cubic Hermite (PCHIP).
//!
//! docs/formulas.md "Transfer functions" warns that a cubic spline through the knots may overshoot
//! them and must be clamped. The cubic here is the shape-preserving PCHIP instead (Fritsch and
//! Carlson 1980, with the Fritsch-Butland weighted harmonic mean for interior slopes and the
//! three-point end slopes of MATLAB's `pchip` and SciPy's `PchipInterpolator`): it passes through
//! every knot, is monotone wherever the knots are, and on each segment stays between the
//! segment's two knot values, so it never leaves [0, 1] either. The evaluation is clamped to
//! those two values as well, so that f32 rounding cannot overshoot by an ulp.
//!
//! Knots at equal positions make a step: the curve takes the value of the last knot at that
//! position from there on (right-continuous), and the pieces on either side of a step are
//! interpolated independently, as if each were a curve of its own.

use super::Interpolation;

/// A curve of `N` channels through validated knots (positions finite and non-decreasing).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Curve<const N: usize> {
    positions: Vec<f32>,
    values: Vec<[f32; N]>,
    /// Cubic only: per segment (knot `i` to `i + 1`), the end tangents scaled by the segment's
    /// width, `h m_i` and `h m_{i+1}`, per channel. Scaled tangents are bounded by three times
    /// the segment's rise, whatever its width, so a very narrow segment cannot overflow.
    tangents: Vec<[[f32; N]; 2]>,
}

impl<const N: usize> Curve<N> {
    /// A curve through `knots`, which must be non-empty with finite, non-decreasing positions.
    pub(crate) fn new(knots: &[(f32, [f32; N])], interpolation: Interpolation) -> Self {
        let positions: Vec<f32> = knots.iter().map(|k| k.0).collect();
        let values: Vec<[f32; N]> = knots.iter().map(|k| k.1).collect();
        let tangents = match interpolation {
            Interpolation::Linear => Vec::new(),
            Interpolation::Cubic => scaled_tangents(&positions, &values),
        };
        Curve {
            positions,
            values,
            tangents,
        }
    }

    /// The largest value of channel `c` over the whole curve (the largest knot value: neither
    /// interpolation exceeds its knots).
    pub(crate) fn max_value(&self, c: usize) -> f32 {
        self.values.iter().map(|v| v[c]).fold(f32::MIN, f32::max)
    }

    /// The curve at `x`; constant before the first and after the last knot. `x` must not be NaN.
    pub(crate) fn eval(&self, x: f32) -> [f32; N] {
        // First knot strictly after x: the segment is (i - 1, i), which has positive width.
        let i = self.positions.partition_point(|&p| p <= x);
        if i == 0 {
            return self.values[0];
        }
        if i == self.positions.len() {
            return self.values[i - 1];
        }
        let (x0, x1) = (self.positions[i - 1], self.positions[i]);
        let t = ((x - x0) / (x1 - x0)).clamp(0.0, 1.0);
        let (y0, y1) = (self.values[i - 1], self.values[i]);
        match self.tangents.get(i - 1) {
            None => std::array::from_fn(|c| y0[c] + t * (y1[c] - y0[c])),
            Some([a, b]) => std::array::from_fn(|c| hermite(y0[c], y1[c], a[c], b[c], t)),
        }
    }
}

/// Cubic Hermite on [0, 1] from `y0` to `y1` with scaled end tangents `a`, `b`, clamped to the
/// range of its end values.
fn hermite(y0: f32, y1: f32, a: f32, b: f32, t: f32) -> f32 {
    let rise = y1 - y0;
    let c2 = 3.0 * rise - 2.0 * a - b;
    let c3 = a + b - 2.0 * rise;
    let y = y0 + t * (a + t * (c2 + t * c3));
    y.clamp(y0.min(y1), y0.max(y1))
}

/// PCHIP tangents, scaled per segment, for every channel; each run of strictly increasing
/// positions (between steps) is handled on its own. Computed in f64.
fn scaled_tangents<const N: usize>(positions: &[f32], values: &[[f32; N]]) -> Vec<[[f32; N]; 2]> {
    let segments = positions.len().saturating_sub(1);
    let mut tangents = vec![[[0.0; N]; 2]; segments];
    let mut start = 0;
    while start < positions.len() {
        let mut end = start + 1;
        while end < positions.len() && positions[end] > positions[end - 1] {
            end += 1;
        }
        // Knots start..end are strictly increasing; a step (or the end) follows.
        let xs: Vec<f64> = positions[start..end]
            .iter()
            .map(|&x| f64::from(x))
            .collect();
        for c in 0..N {
            let ys: Vec<f64> = values[start..end].iter().map(|v| f64::from(v[c])).collect();
            let slopes = pchip_slopes(&xs, &ys);
            for k in 0..xs.len().saturating_sub(1) {
                let h = xs[k + 1] - xs[k];
                tangents[start + k][0][c] = (h * slopes[k]) as f32;
                tangents[start + k][1][c] = (h * slopes[k + 1]) as f32;
            }
        }
        start = end;
    }
    tangents
}

/// PCHIP derivatives at strictly increasing `xs` (Fritsch-Carlson shape preservation).
fn pchip_slopes(xs: &[f64], ys: &[f64]) -> Vec<f64> {
    let n = xs.len();
    if n < 2 {
        return vec![0.0; n];
    }
    let h: Vec<f64> = xs.windows(2).map(|w| w[1] - w[0]).collect();
    let secant: Vec<f64> = (0..n - 1).map(|k| (ys[k + 1] - ys[k]) / h[k]).collect();
    if n == 2 {
        return vec![secant[0]; 2];
    }
    let mut slopes = vec![0.0; n];
    for k in 1..n - 1 {
        slopes[k] = interior_slope(h[k - 1], h[k], secant[k - 1], secant[k]);
    }
    slopes[0] = end_slope(h[0], h[1], secant[0], secant[1]);
    slopes[n - 1] = end_slope(h[n - 2], h[n - 3], secant[n - 2], secant[n - 3]);
    slopes
}

/// Fritsch-Butland weighted harmonic mean of the neighbouring secants; 0 at a local extremum
/// or next to a flat segment. Never more than 3 times either secant, which keeps each segment
/// monotone (Fritsch and Carlson's sufficient condition).
fn interior_slope(h_before: f64, h_after: f64, s_before: f64, s_after: f64) -> f64 {
    if s_before == 0.0 || s_after == 0.0 || s_before.signum() != s_after.signum() {
        return 0.0;
    }
    let w1 = 2.0 * h_after + h_before;
    let w2 = h_after + 2.0 * h_before;
    (w1 + w2) / (w1 / s_before + w2 / s_after)
}

/// Three-point end slope, limited to keep the end segment monotone (as MATLAB's `pchip`).
/// `h0`, `s0`: the end segment's width and secant; `h1`, `s1`: its neighbour's.
fn end_slope(h0: f64, h1: f64, s0: f64, s1: f64) -> f64 {
    let d = ((2.0 * h0 + h1) * s0 - h0 * s1) / (h0 + h1);
    if sign(d) != sign(s0) {
        0.0
    } else if sign(s0) != sign(s1) && d.abs() > 3.0 * s0.abs() {
        3.0 * s0
    } else {
        d
    }
}

/// -1, 0 or 1 (unlike `f64::signum`, 0 for zero).
fn sign(x: f64) -> i8 {
    if x > 0.0 {
        1
    } else if x < 0.0 {
        -1
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn curve(knots: &[(f32, f32)], interpolation: Interpolation) -> Curve<1> {
        let knots: Vec<(f32, [f32; 1])> = knots.iter().map(|&(x, y)| (x, [y])).collect();
        Curve::new(&knots, interpolation)
    }

    #[test]
    fn pchip_of_a_line_is_the_line() {
        let xs = [0.0, 0.1, 0.4, 1.0];
        let ys: Vec<f64> = xs.iter().map(|x| 0.2 + 0.5 * x).collect();
        for s in pchip_slopes(&xs, &ys) {
            assert!((s - 0.5).abs() < 1e-12, "slope {s}");
        }
    }

    #[test]
    fn pchip_slope_is_zero_at_an_extremum_and_next_to_a_plateau() {
        let xs = [0.0, 0.25, 0.5, 0.75, 1.0];
        let ys = [0.0, 1.0, 0.5, 0.5, 0.8];
        let s = pchip_slopes(&xs, &ys);
        assert_eq!(s[1], 0.0, "peak");
        assert_eq!(s[2], 0.0, "start of a plateau");
        assert_eq!(s[3], 0.0, "end of a plateau");
    }

    #[test]
    fn hermite_reaches_its_end_values() {
        assert_eq!(hermite(0.2, 0.7, 0.9, -0.3, 0.0), 0.2);
        assert_eq!(hermite(0.2, 0.7, 0.9, 0.3, 1.0), 0.7);
    }

    #[test]
    fn a_single_knot_is_constant() {
        for interpolation in [Interpolation::Linear, Interpolation::Cubic] {
            let c = curve(&[(0.4, 0.7)], interpolation);
            for x in [0.0, 0.4, 0.5, 1.0] {
                assert_eq!(c.eval(x), [0.7]);
            }
        }
    }

    #[test]
    fn runs_between_steps_are_interpolated_independently() {
        // The cubic on [0, 0.5] must not see the jump at 0.5: it is the line through its knots.
        let c = curve(
            &[(0.0, 0.0), (0.25, 0.25), (0.5, 0.5), (0.5, 0.0), (1.0, 0.0)],
            Interpolation::Cubic,
        );
        for x in [0.1f32, 0.2, 0.3, 0.45] {
            assert!((c.eval(x)[0] - x).abs() < 1e-6, "x {x}: {}", c.eval(x)[0]);
        }
        assert_eq!(c.eval(0.5), [0.0]);
        assert_eq!(c.eval(0.75), [0.0]);
    }

    #[test]
    fn narrow_segments_stay_finite() {
        let c = curve(
            &[
                (0.0, 0.0),
                (1e-45, 1.0),
                (2e-45, 0.0),
                (0.5, 1.0),
                (1.0, 0.0),
            ],
            Interpolation::Cubic,
        );
        for x in [0.0, 1e-45, 1.5e-45, 0.25, 0.5, 0.9] {
            let y = c.eval(x)[0];
            assert!((0.0..=1.0).contains(&y), "x {x}: {y}");
        }
    }
}
