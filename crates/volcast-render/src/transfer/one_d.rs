//! 1D transfer functions: colour and opacity knots over the normalised value, and their
//! lookup tables (docs/formulas.md "Transfer functions").

use super::curve::Curve;
use super::{check_unit, Interpolation, KnotCurve, TransferError};

/// RGBA over the normalised value `v` in [0, 1], from colour and opacity knots.
///
/// Colour and opacity have knots of their own (at positions of their own); both use the same
/// [`Interpolation`]. Each is constant before its first and after its last knot, and two knots
/// at the same position make a step (see [`Transfer1D::new`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Transfer1D {
    color: Curve<3>,
    alpha: Curve<1>,
    interpolation: Interpolation,
}

impl Transfer1D {
    /// A transfer function through `color` knots `(position, [r, g, b])` and `alpha` knots
    /// `(position, alpha)`.
    ///
    /// Each list needs at least one knot; positions must be finite, within [0, 1] and
    /// non-decreasing; values must be in [0, 1]. Equal positions are allowed and make a step:
    /// from that position on, the curve starts from the last knot there.
    pub fn new(
        color: Vec<(f32, [f32; 3])>,
        alpha: Vec<(f32, f32)>,
        interpolation: Interpolation,
    ) -> Result<Transfer1D, TransferError> {
        let alpha: Vec<(f32, [f32; 1])> = alpha.into_iter().map(|(p, a)| (p, [a])).collect();
        check_knots(KnotCurve::Color, &color, &["red", "green", "blue"])?;
        check_knots(KnotCurve::Alpha, &alpha, &["alpha"])?;
        Ok(Transfer1D {
            color: Curve::new(&color, interpolation),
            alpha: Curve::new(&alpha, interpolation),
            interpolation,
        })
    }

    /// The interpolation between knots.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// The smallest value (to 1/4096) with a non-zero opacity, if any: where the
    /// transfer function starts to show something.
    pub fn first_opaque(&self) -> Option<f64> {
        (0..=4096u32)
            .map(|i| f64::from(i) / 4096.0)
            .find(|&v| self.alpha.eval(v as f32)[0] > 0.0)
    }

    /// The largest opacity anywhere (the largest alpha knot: neither interpolation exceeds its
    /// knots); 0 means the transfer function is entirely transparent.
    pub fn max_alpha(&self) -> f32 {
        self.alpha.max_value(0)
    }

    /// `[r, g, b, alpha]` at normalised value `v`, clamped to [0, 1] (NaN counts as 0, as in
    /// [`Table1D::lookup`]). Every component is in [0, 1].
    pub fn eval(&self, v: f32) -> [f32; 4] {
        let v = clamp_unit(v);
        let [r, g, b] = self.color.eval(v);
        let [a] = self.alpha.eval(v);
        [r, g, b, a]
    }

    /// `n` evenly spaced evaluations over [0, 1], the first at 0 and the last at 1 (`n` is
    /// raised to 2 if smaller).
    pub fn table(&self, n: usize) -> Table1D {
        let n = n.clamp(2, 1 << 24);
        let last = (n - 1) as f32;
        Table1D {
            entries: (0..n).map(|i| self.eval(i as f32 / last)).collect(),
        }
    }
}

/// A tabulated 1D transfer function: RGBA entries evenly spaced over [0, 1], for fast lookups
/// while rendering.
#[derive(Clone, Debug, PartialEq)]
pub struct Table1D {
    entries: Vec<[f32; 4]>,
}

impl Table1D {
    /// RGBA at `v`, linearly interpolated between the two nearest entries; `v` is clamped to
    /// [0, 1] and NaN gives entry 0.
    #[inline(always)]
    pub fn lookup(&self, v: f32) -> [f32; 4] {
        self.lookup_at(table_position(v, (self.entries.len() - 1) as f32))
    }

    /// RGBA at the table position `x`, which [`table_position`] gave for this table
    /// (`v` and the number of entries less one): [`Table1D::lookup`] for a caller
    /// that already has the position.
    #[inline(always)]
    pub(crate) fn lookup_at(&self, x: f32) -> [f32; 4] {
        let last = (self.entries.len() - 1) as f32;
        // `table_position` gives [0, last]; clamped again (NaN to 0, two comparisons
        // that compile to max and min) so that any `x` reads inside the table
        let x = if x > 0.0 { x } else { 0.0 };
        let x = if x < last { x } else { last };
        // SAFETY: x is in [0, last]
        unsafe { self.lookup_within(x) }
    }

    /// [`Table1D::lookup_at`] without clamping `x` again, for a caller whose `x`
    /// comes from [`table_position`] with this table's last index (the composite's
    /// samples: two instructions fewer per sample that is not clear).
    ///
    /// # Safety
    /// `x` is in `[0, len - 1]` (so not NaN).
    #[inline(always)]
    pub(crate) unsafe fn lookup_within(&self, x: f32) -> [f32; 4] {
        let last = self.entries.len() - 1;
        debug_assert!((0.0..=last as f32).contains(&x), "{x} outside [0, {last}]");
        // SAFETY (the caller's): x is in [0, last]
        let (i, t) = unsafe { split_position(x, last as u32) };
        // SAFETY: i + 1 <= last (`split_position`)
        unsafe { self.lerp_entries(i as usize, t) }
    }

    /// Entries `i` and `i + 1` interpolated at fraction `t` from `i` (the second
    /// half of [`Table1D::lookup_within`], for a caller that split the position
    /// itself with [`split_position`]).
    ///
    /// # Safety
    /// `i + 1 < len` (as every entry index [`split_position`] gives for this
    /// table's last index is).
    #[inline(always)]
    pub(crate) unsafe fn lerp_entries(&self, i: usize, t: f32) -> [f32; 4] {
        debug_assert!(
            i + 1 < self.entries.len(),
            "entry {i} of {}",
            self.entries.len()
        );
        // SAFETY (the caller's): i + 1 < len
        let (a, b) = unsafe {
            (
                *self.entries.get_unchecked(i),
                *self.entries.get_unchecked(i + 1),
            )
        };
        lerp4(a, b, t)
    }

    /// Number of entries (at least 2).
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// The entries' opacities, in order of value.
    pub fn alphas(&self) -> impl Iterator<Item = f32> + '_ {
        self.entries.iter().map(|e| e[3])
    }

    /// The table with every entry's opacity replaced by `f(opacity)` (colours kept).
    pub fn map_alpha(&self, f: impl Fn(f32) -> f32) -> Table1D {
        Table1D {
            entries: self
                .entries
                .iter()
                .map(|&[r, g, b, a]| [r, g, b, f(a)])
                .collect(),
        }
    }

    /// Always false: a table has at least 2 entries.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Memory held by the entries, in bytes.
    pub fn byte_size(&self) -> usize {
        std::mem::size_of_val(self.entries.as_slice())
    }
}

/// `(1 - t) a + t b` per component: exact at `t = 0` and `t = 1` (four lanes at once,
/// the same operations per lane as in scalar code).
#[inline(always)]
pub(crate) fn lerp4(a: [f32; 4], b: [f32; 4], t: f32) -> [f32; 4] {
    use glam::Vec4;
    (Vec4::splat(1.0 - t) * Vec4::from_array(a) + Vec4::splat(t) * Vec4::from_array(b)).to_array()
}

/// Where a table whose entries are evenly spaced over [0, 1], the last at index
/// `last`, looks `v` up: `v` clamped to [0, 1] (NaN to 0) times `last`. Every table
/// lookup computes its position here; the composite forms the same product from the
/// clamped value (after its test for values that look up a transparent entry, which
/// must agree with this position to the bit).
#[inline(always)]
pub(crate) fn table_position(v: f32, last: f32) -> f32 {
    clamp_unit(v) * last
}

/// Table position `x` of a table whose last index is `last` split into the entry
/// before it, `i` (at most `last - 1`, so that `i + 1` is an entry too), and the
/// fraction `x - i` towards the next: the one split every 1D lookup makes (the
/// composite's eight-lane lookups make it lane by lane, with the same operations).
///
/// # Safety
/// `x` is in `[0, last]` (so not NaN), `1 <= last < 2^31` (a table has at least two
/// and fewer than 2^31 entries: see [`Transfer1D::table`]).
#[inline(always)]
pub(crate) unsafe fn split_position(x: f32, last: u32) -> (u32, f32) {
    // truncation is floor for x >= 0; one instruction through i32
    // SAFETY (the caller's): x is in [0, last], which an i32 holds
    let i = (unsafe { x.to_int_unchecked::<i32>() } as u32).min(last - 1);
    // through u32 (i < 2^31): one conversion, where one from usize tests the sign
    (i, x - i as f32)
}

/// `x` clamped to [0, 1], NaN to 0 (two comparisons: `x > 0` is false for NaN).
#[inline(always)]
pub(crate) fn clamp_unit(x: f32) -> f32 {
    let x = if x > 0.0 { x } else { 0.0 };
    if x < 1.0 {
        x
    } else {
        1.0
    }
}

/// Checks the knot rules of [`Transfer1D::new`]; `channels` names the value's components.
fn check_knots<const N: usize>(
    curve: KnotCurve,
    knots: &[(f32, [f32; N])],
    channels: &[&str; N],
) -> Result<(), TransferError> {
    if knots.is_empty() {
        return Err(TransferError::NoKnots { curve });
    }
    let mut previous: Option<f32> = None;
    for (index, &(position, value)) in knots.iter().enumerate() {
        let fail = |problem: String| TransferError::Knot {
            curve,
            index,
            count: knots.len(),
            problem,
        };
        check_position(position, previous).map_err(fail)?;
        for (&name, &x) in channels.iter().zip(&value) {
            check_unit(name, x).map_err(fail)?;
        }
        previous = Some(position);
    }
    Ok(())
}

/// A knot position is finite, within [0, 1] and not below the previous knot's.
fn check_position(position: f32, previous: Option<f32>) -> Result<(), String> {
    if !position.is_finite() {
        return Err(format!("position {position} is not a finite number"));
    }
    if !(0.0..=1.0).contains(&position) {
        return Err(format!(
            "position {position} is outside [0, 1] (positions are normalised values)"
        ));
    }
    match previous {
        Some(p) if position < p => Err(format!(
            "position {position} is below the previous knot's {p} (knots must be in increasing order)"
        )),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LINEAR: Interpolation = Interpolation::Linear;
    const CUBIC: Interpolation = Interpolation::Cubic;

    fn alpha_only(alpha: &[(f32, f32)], interpolation: Interpolation) -> Transfer1D {
        Transfer1D::new(vec![(0.0, [1.0; 3])], alpha.to_vec(), interpolation)
            .expect("test knots are valid")
    }

    /// A deterministic "random-ish" knot set: a small linear congruential generator.
    fn random_knots(count: usize, seed: u32) -> Vec<(f32, f32)> {
        let mut state = seed;
        let mut next = move || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1u32 << 24) as f32
        };
        let mut positions: Vec<f32> = (0..count).map(|_| next()).collect();
        positions.sort_by(f32::total_cmp);
        positions.into_iter().map(|p| (p, next())).collect()
    }

    /// Evaluation points: the start of each segment and `per_segment - 1` points inside it
    /// (not its end, which rounding could push into the next segment), with the segment's index.
    fn sample_points(knots: &[(f32, f32)], per_segment: usize) -> Vec<(usize, f32)> {
        let mut points = Vec::new();
        for (k, w) in knots.windows(2).enumerate() {
            for j in 0..per_segment {
                points.push((
                    k,
                    w[0].0 + (w[1].0 - w[0].0) * j as f32 / per_segment as f32,
                ));
            }
        }
        points
    }

    #[test]
    fn linear_is_exact_at_knots_and_midpoints() {
        // Dyadic positions and values: every midpoint is exactly representable.
        let color = vec![
            (0.0, [0.0, 1.0, 0.5]),
            (0.5, [1.0, 0.0, 0.25]),
            (1.0, [0.5, 0.5, 0.75]),
        ];
        let alpha = vec![(0.25, 0.0), (0.5, 1.0), (0.75, 0.5)];
        let tf = Transfer1D::new(color, alpha, LINEAR).expect("valid");
        assert_eq!(tf.eval(0.0), [0.0, 1.0, 0.5, 0.0]);
        assert_eq!(tf.eval(0.5), [1.0, 0.0, 0.25, 1.0]);
        assert_eq!(tf.eval(1.0), [0.5, 0.5, 0.75, 0.5]);
        assert_eq!(tf.eval(0.25), [0.5, 0.5, 0.375, 0.0]);
        assert_eq!(tf.eval(0.375), [0.75, 0.25, 0.3125, 0.5]);
        assert_eq!(tf.eval(0.625)[3], 0.75);
        assert_eq!(tf.eval(0.75), [0.75, 0.25, 0.5, 0.5]);
    }

    #[test]
    fn constant_beyond_the_end_knots_and_clamped_outside_the_unit_range() {
        let tf = alpha_only(&[(0.25, 0.2), (0.75, 0.6)], LINEAR);
        assert_eq!(tf.eval(0.0)[3], 0.2);
        assert_eq!(tf.eval(0.1)[3], 0.2);
        assert_eq!(tf.eval(0.9)[3], 0.6);
        assert_eq!(tf.eval(-5.0)[3], 0.2);
        assert_eq!(tf.eval(7.0)[3], 0.6);
        assert_eq!(tf.eval(f32::NAN), tf.eval(0.0));
        assert_eq!(tf.eval(f32::INFINITY), tf.eval(1.0));
    }

    #[test]
    fn cubic_passes_through_the_knots() {
        let knots = random_knots(12, 7);
        let tf = alpha_only(&knots, CUBIC);
        for &(p, a) in &knots {
            assert_eq!(tf.eval(p)[3], a, "knot at {p}");
        }
    }

    #[test]
    fn cubic_never_overshoots_its_neighbouring_knots() {
        for seed in 1..20 {
            let knots = random_knots(10, seed);
            let tf = alpha_only(&knots, CUBIC);
            for (k, x) in sample_points(&knots, 50) {
                let (a0, a1) = (knots[k].1, knots[k + 1].1);
                let y = tf.eval(x)[3];
                assert!(
                    a0.min(a1) <= y && y <= a0.max(a1),
                    "seed {seed}, x {x}: {y} outside [{a0}, {a1}]"
                );
            }
        }
    }

    #[test]
    fn cubic_is_monotone_where_the_knots_are() {
        // Increasing, with a plateau and unequal spacing, then decreasing.
        let knots = [
            (0.0, 0.0),
            (0.1, 0.05),
            (0.15, 0.6),
            (0.4, 0.6),
            (0.5, 0.9),
            (0.55, 1.0),
            (1.0, 0.1),
        ];
        let tf = alpha_only(&knots, CUBIC);
        let mut previous = tf.eval(0.0)[3];
        for i in 1..=2000 {
            let x = i as f32 / 2000.0;
            let y = tf.eval(x)[3];
            // f32 rounding in the Hermite polynomial: a few ulps.
            if x <= 0.55 {
                assert!(y >= previous - 1e-6, "x {x}: {y} < {previous}");
            } else {
                assert!(y <= previous + 1e-6, "x {x}: {y} > {previous}");
            }
            if (0.15..=0.4).contains(&x) {
                assert_eq!(y, 0.6, "plateau at {x}");
            }
            previous = y;
        }
    }

    #[test]
    fn output_is_always_in_the_unit_range() {
        let knots = [
            (0.0, 0.0),
            (0.01, 1.0),
            (0.02, 0.0),
            (0.03, 1.0),
            (0.5, 1.0),
            (0.51, 0.0),
        ];
        let color: Vec<(f32, [f32; 3])> =
            knots.iter().map(|&(p, a)| (p, [a, 1.0 - a, a])).collect();
        for interpolation in [LINEAR, CUBIC] {
            let tf = Transfer1D::new(color.clone(), knots.to_vec(), interpolation).expect("valid");
            for i in 0..=10_000 {
                let rgba = tf.eval(i as f32 / 10_000.0);
                assert!(rgba.iter().all(|c| (0.0..=1.0).contains(c)), "{rgba:?}");
            }
        }
    }

    #[test]
    fn equal_positions_make_a_step() {
        for interpolation in [LINEAR, CUBIC] {
            let tf = alpha_only(
                &[(0.0, 0.0), (0.5, 0.2), (0.5, 0.9), (1.0, 1.0)],
                interpolation,
            );
            assert!((tf.eval(0.499_999)[3] - 0.2).abs() < 1e-5);
            assert_eq!(tf.eval(0.5)[3], 0.9, "the last knot at the step wins");
            assert!(tf.eval(0.75)[3] >= 0.9);
            // A step at the very start and end.
            let edges = alpha_only(
                &[(0.0, 0.3), (0.0, 0.6), (1.0, 0.1), (1.0, 0.8)],
                interpolation,
            );
            assert_eq!(edges.eval(0.0)[3], 0.6);
            assert_eq!(edges.eval(1.0)[3], 0.8);
        }
    }

    #[test]
    fn table_lookup_matches_eval_at_the_entries() {
        let tf = alpha_only(&random_knots(8, 3), CUBIC);
        let n = 256;
        let table = tf.table(n);
        assert_eq!(table.len(), n);
        assert_eq!(table.byte_size(), n * 16);
        for i in 0..n {
            let v = i as f32 / (n - 1) as f32;
            let (got, want) = (table.lookup(v), tf.eval(v));
            // Two roundings, in i / (n - 1) and back in v * (n - 1), leave x within
            // i * 2^-23 <= 255 * 2^-23 = 3.04e-5 of the entry, and neighbouring entries differ by
            // at most 1.
            for c in 0..4 {
                assert!(
                    (got[c] - want[c]).abs() < 3.1e-5,
                    "entry {i}: {got:?} vs {want:?}"
                );
            }
        }
        assert_eq!(table.lookup(0.0), tf.eval(0.0));
        assert_eq!(table.lookup(1.0), tf.eval(1.0));
    }

    #[test]
    fn table_lookup_matches_eval_between_entries() {
        // Tolerance from the table resolution: the curves are Lipschitz with constant K (the
        // steepest secant for linear; at most 3 times it for PCHIP, whose segment derivatives
        // never exceed 3 secants), and linear interpolation of a K-Lipschitz function between
        // entries h apart is off by at most 2 t (1 - t) K h <= K h / 2.
        let knots: [(f32, f32); 5] = [(0.0, 0.0), (0.2, 0.1), (0.3, 0.9), (0.7, 0.4), (1.0, 1.0)];
        let steepest = knots
            .windows(2)
            .map(|w| ((w[1].1 - w[0].1) / (w[1].0 - w[0].0)).abs())
            .fold(0.0, f32::max);
        for (interpolation, lipschitz) in [(LINEAR, steepest), (CUBIC, 3.0 * steepest)] {
            let tf = alpha_only(&knots, interpolation);
            for n in [16, 256, 4096] {
                let table = tf.table(n);
                let h = 1.0 / (n - 1) as f32;
                let tolerance = lipschitz * h / 2.0 + 1e-6;
                let mut worst = 0.0f32;
                for i in 0..=9973 {
                    let v = i as f32 / 9973.0;
                    worst = worst.max((table.lookup(v)[3] - tf.eval(v)[3]).abs());
                }
                assert!(
                    worst <= tolerance,
                    "{interpolation:?} n {n}: {worst} > {tolerance}"
                );
            }
        }
    }

    #[test]
    fn table_lookup_clamps_and_survives_nan() {
        let table = alpha_only(&[(0.0, 0.25), (1.0, 0.75)], LINEAR).table(2);
        assert_eq!(table.lookup(f32::NAN)[3], 0.25);
        assert_eq!(table.lookup(-1.0)[3], 0.25);
        assert_eq!(table.lookup(2.0)[3], 0.75);
        assert_eq!(table.lookup(0.5)[3], 0.5);
        assert_eq!(alpha_only(&[(0.0, 0.5)], LINEAR).table(0).len(), 2);
    }

    #[test]
    fn max_alpha_is_the_largest_alpha_knot() {
        assert_eq!(
            alpha_only(&[(0.0, 0.0), (1.0, 0.0)], CUBIC).max_alpha(),
            0.0
        );
        assert_eq!(
            alpha_only(&[(0.0, 0.3), (0.5, 0.8), (1.0, 0.1)], CUBIC).max_alpha(),
            0.8
        );
    }

    fn error(color: Vec<(f32, [f32; 3])>, alpha: Vec<(f32, f32)>) -> String {
        match Transfer1D::new(color, alpha, LINEAR) {
            Ok(_) => panic!("expected an error"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn invalid_knots_are_rejected_with_a_message() {
        let white = vec![(0.0, [1.0; 3])];
        assert_eq!(
            error(white.clone(), vec![(0.0, 0.0), (0.3, 0.5), (0.2, 1.0)]),
            "alpha knot 3 of 3: position 0.2 is below the previous knot's 0.3 (knots must be in increasing order)"
        );
        assert_eq!(
            error(vec![], vec![(0.0, 0.0)]),
            "color: no knots (at least one [position, value] knot is required)"
        );
        assert_eq!(
            error(white.clone(), vec![]),
            "alpha: no knots (at least one [position, value] knot is required)"
        );
        assert_eq!(
            error(
                vec![(0.0, [1.0; 3]), (0.5, [0.2, 1.5, 0.0])],
                vec![(0.0, 0.0)]
            ),
            "color knot 2 of 2: green 1.5 is outside [0, 1]"
        );
        assert_eq!(
            error(white.clone(), vec![(1.5, 0.0)]),
            "alpha knot 1 of 1: position 1.5 is outside [0, 1] (positions are normalised values)"
        );
        assert_eq!(
            error(white.clone(), vec![(f32::NAN, 0.0)]),
            "alpha knot 1 of 1: position NaN is not a finite number"
        );
        assert_eq!(
            error(white, vec![(0.0, f32::NAN)]),
            "alpha knot 1 of 1: alpha NaN is not a finite number"
        );
    }
}
