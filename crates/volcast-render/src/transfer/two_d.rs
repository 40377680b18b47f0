//! 2D transfer functions `RGBA(f, |grad f|)` built from widgets, and their lookup tables
//! (docs/formulas.md "Transfer functions": boundaries between materials show up as arcs in the
//! value / gradient-magnitude histogram, Levoy 1988, Kindlmann and Durkin 1998).

use super::one_d::{clamp_unit, lerp4, table_position};
use super::{check_unit, TransferError};

/// The shape of a widget's opacity over the (value, gradient magnitude) plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WidgetShape {
    /// Constant `alpha` inside the box `value x gradient` (edges included), 0 outside.
    Rectangle,
    /// A Gaussian bump filling the box, unbounded (Kniss et al. 2003); see [`Widget::opacity`].
    Gaussian,
}

/// One region of a 2D transfer function: a shape over a box of (value, gradient magnitude),
/// with a colour and a peak opacity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Widget {
    /// Opacity profile.
    pub shape: WidgetShape,
    /// Normalised value range `[low, high]`.
    pub value: [f32; 2],
    /// Gradient magnitude range `[low, high]`, in the units of [`Transfer2D::eval`]'s `g`.
    pub gradient: [f32; 2],
    /// Linear RGB colour, each in [0, 1].
    pub color: [f32; 3],
    /// Peak opacity, in [0, 1].
    pub alpha: f32,
}

impl Widget {
    /// The widget's opacity at value `v` and gradient magnitude `g`.
    ///
    /// - Rectangle: `alpha` where `value[0] <= v <= value[1]` and `gradient[0] <= g <=
    ///   gradient[1]`, else 0.
    /// - Gaussian: `alpha * exp(-(((v - cv) / hv)^2 + ((g - cg) / hg)^2))` with centres
    ///   `cv`, `cg` the midpoints of the two ranges and `hv`, `hg` half their lengths: Kniss et
    ///   al.'s `exp(-(x - c)^T K^T K (x - c))` with `K = diag(1/hv, 1/hg)`. It is `alpha` at the
    ///   centre and `alpha / e` at a half-width from it along either axis (on the box's edge).
    ///   A zero-length range is the limit `h -> 0`: that axis' term is 0 at the centre and
    ///   infinite (opacity 0) elsewhere.
    pub fn opacity(&self, v: f32, g: f32) -> f32 {
        match self.shape {
            WidgetShape::Rectangle => {
                let inside = |x: f32, [lo, hi]: [f32; 2]| lo <= x && x <= hi;
                if inside(v, self.value) && inside(g, self.gradient) {
                    self.alpha
                } else {
                    0.0
                }
            }
            WidgetShape::Gaussian => {
                let exponent = gaussian_term(v, self.value) + gaussian_term(g, self.gradient);
                self.alpha * (-exponent).exp()
            }
        }
    }
}

/// `((x - c) / h)^2` for the range `[lo, hi]` with centre `c` and half-width `h` (computed as
/// halves first, so that even `[-f32::MAX, f32::MAX]` does not overflow); for `h = 0`, 0 at the
/// centre and infinity elsewhere.
fn gaussian_term(x: f32, [lo, hi]: [f32; 2]) -> f32 {
    let centre = lo / 2.0 + hi / 2.0;
    let half = hi / 2.0 - lo / 2.0;
    let offset = x - centre;
    if half > 0.0 {
        (offset / half).powi(2)
    } else if offset == 0.0 {
        0.0
    } else {
        f32::INFINITY
    }
}

/// RGBA over (normalised value, gradient magnitude), the combination of widgets.
#[derive(Clone, Debug, PartialEq)]
pub struct Transfer2D {
    widgets: Vec<Widget>,
    gradient_max: f32,
}

impl Transfer2D {
    /// The smallest value any widget with a non-zero alpha starts at.
    pub fn first_opaque(&self) -> Option<f64> {
        self.widgets
            .iter()
            .filter(|w| w.alpha > 0.0)
            .map(|w| f64::from(w.value[0]))
            .reduce(f64::min)
    }

    /// A 2D transfer function over values in [0, 1] and gradient magnitudes in
    /// `[0, gradient_max]`.
    ///
    /// Every widget needs finite ranges with `low <= high`, `alpha` and colour components in
    /// [0, 1]; `gradient_max` must be finite and positive. No widgets at all is allowed (and
    /// transparent everywhere).
    pub fn new(widgets: Vec<Widget>, gradient_max: f32) -> Result<Transfer2D, TransferError> {
        for (index, widget) in widgets.iter().enumerate() {
            check_widget(widget).map_err(|problem| TransferError::Widget {
                index,
                count: widgets.len(),
                problem,
            })?;
        }
        if !(gradient_max.is_finite() && gradient_max > 0.0) {
            return Err(TransferError::GradientMax(gradient_max));
        }
        Ok(Transfer2D {
            widgets,
            gradient_max,
        })
    }

    /// The widgets, in the order given.
    pub fn widgets(&self) -> &[Widget] {
        &self.widgets
    }

    /// The largest gradient magnitude covered; larger ones count as this.
    pub fn gradient_max(&self) -> f32 {
        self.gradient_max
    }

    /// `[r, g, b, alpha]` at normalised value `v` and gradient magnitude `g`.
    ///
    /// `v` is clamped to [0, 1] and `g` to `[0, gradient_max]` (NaN counts as 0), as in
    /// [`Table2D::lookup`]. With `a_i` the widgets' opacities there: `alpha = min(1, sum a_i)`
    /// and `colour = sum(a_i c_i) / sum(a_i)`, the opacity-weighted mean (0 where every
    /// `a_i = 0`).
    pub fn eval(&self, v: f32, g: f32) -> [f32; 4] {
        let v = clamp_unit(v);
        let g = if g.is_nan() {
            0.0
        } else {
            g.clamp(0.0, self.gradient_max)
        };
        let mut alpha = 0.0f32;
        let mut weighted = [0.0f32; 3];
        for widget in &self.widgets {
            let a = widget.opacity(v, g);
            alpha += a;
            for (sum, c) in weighted.iter_mut().zip(widget.color) {
                *sum += a * c;
            }
        }
        if alpha <= 0.0 {
            return [0.0; 4];
        }
        let [red, green, blue] = weighted.map(|s| (s / alpha).min(1.0));
        [red, green, blue, alpha.min(1.0)]
    }

    /// `nv x ng` evaluations on the regular grid over `v` in [0, 1] and `g` in
    /// `[0, gradient_max]`, corners included (each size is raised to 2 if smaller).
    pub fn table(&self, nv: usize, ng: usize) -> Table2D {
        let (nv, ng) = (nv.max(2), ng.max(2));
        let v_at = |i: usize| i as f32 / (nv - 1) as f32;
        let g_at = |j: usize| j as f32 / (ng - 1) as f32 * self.gradient_max;
        let entries = (0..ng)
            .flat_map(|j| (0..nv).map(move |i| (i, j)))
            .map(|(i, j)| self.eval(v_at(i), g_at(j)))
            .collect();
        Table2D {
            nv,
            ng,
            gradient_max: self.gradient_max,
            entries,
        }
    }
}

/// A tabulated 2D transfer function: RGBA on a regular `nv x ng` grid (value fastest) over
/// [0, 1] x `[0, gradient_max]`.
#[derive(Clone, Debug, PartialEq)]
pub struct Table2D {
    nv: usize,
    ng: usize,
    gradient_max: f32,
    entries: Vec<[f32; 4]>,
}

impl Table2D {
    /// RGBA at value `v` and gradient magnitude `g`, bilinear between the four nearest entries;
    /// `v` and `g` are clamped to the table's range and NaN counts as 0.
    #[inline(always)]
    pub fn lookup(&self, v: f32, g: f32) -> [f32; 4] {
        let (i, tv) = cell(v, self.nv);
        let (j, tg) = cell(g / self.gradient_max, self.ng);
        let at = |i: usize, j: usize| self.entries[j * self.nv + i];
        let low = lerp4(at(i, j), at(i + 1, j), tv);
        let high = lerp4(at(i, j + 1), at(i + 1, j + 1), tv);
        lerp4(low, high, tg)
    }

    /// Number of entries along the value and the gradient-magnitude axes (each at least 2).
    pub fn dims(&self) -> (usize, usize) {
        (self.nv, self.ng)
    }

    /// The largest opacity of each value entry over every gradient magnitude, in order
    /// of value.
    pub fn max_alpha_per_value(&self) -> Vec<f32> {
        (0..self.nv)
            .map(|i| {
                (0..self.ng)
                    .map(|j| self.entries[j * self.nv + i][3])
                    .fold(0.0, f32::max)
            })
            .collect()
    }

    /// The table with every entry's opacity replaced by `f(opacity)` (colours kept).
    pub fn map_alpha(&self, f: impl Fn(f32) -> f32) -> Table2D {
        Table2D {
            entries: self
                .entries
                .iter()
                .map(|&[r, g, b, a]| [r, g, b, f(a)])
                .collect(),
            ..*self
        }
    }

    /// Memory held by the entries, in bytes.
    pub fn byte_size(&self) -> usize {
        std::mem::size_of_val(self.entries.as_slice())
    }
}

/// For `u` (clamped to [0, 1], NaN to 0) on an axis of `n >= 2` entries: the lower entry's
/// index (at most `n - 2`) and the fraction towards the next one.
fn cell(u: f32, n: usize) -> (usize, f32) {
    let x = table_position(u, (n - 1) as f32);
    // `x` is in [0, n - 1]: one instruction through i32 (tables are far smaller)
    let i = (x as i32 as usize).min(n - 2);
    (i, x - i as f32)
}

/// Checks one widget's ranges, colour and alpha.
fn check_widget(widget: &Widget) -> Result<(), String> {
    check_range("value", widget.value)?;
    check_range("gradient", widget.gradient)?;
    check_unit("alpha", widget.alpha)?;
    for (name, c) in ["red", "green", "blue"].into_iter().zip(widget.color) {
        check_unit(&format!("color {name}"), c)?;
    }
    Ok(())
}

/// A range `[low, high]` is finite with `low <= high`.
fn check_range(name: &str, [lo, hi]: [f32; 2]) -> Result<(), String> {
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(format!("{name} range [{lo}, {hi}] is not finite"));
    }
    if lo > hi {
        return Err(format!(
            "{name} range [{lo}, {hi}] is reversed (expected [low, high] with low <= high)"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn widget(
        shape: WidgetShape,
        value: [f32; 2],
        gradient: [f32; 2],
        color: [f32; 3],
        alpha: f32,
    ) -> Widget {
        Widget {
            shape,
            value,
            gradient,
            color,
            alpha,
        }
    }

    fn single(w: Widget) -> Transfer2D {
        Transfer2D::new(vec![w], 10.0).expect("test widget is valid")
    }

    #[test]
    fn rectangle_is_alpha_inside_and_zero_outside() {
        let tf = single(widget(
            WidgetShape::Rectangle,
            [0.25, 0.5],
            [1.0, 3.0],
            [1.0, 0.5, 0.0],
            0.75,
        ));
        let inside = [1.0, 0.5, 0.0, 0.75];
        assert_eq!(tf.eval(0.375, 2.0), inside);
        assert_eq!(tf.eval(0.25, 1.0), inside, "edges are included");
        assert_eq!(tf.eval(0.5, 3.0), inside, "edges are included");
        assert_eq!(tf.eval(0.2, 2.0), [0.0; 4]);
        assert_eq!(tf.eval(0.6, 2.0), [0.0; 4]);
        assert_eq!(tf.eval(0.375, 0.5), [0.0; 4]);
        assert_eq!(tf.eval(0.375, 3.5), [0.0; 4]);
    }

    #[test]
    fn gaussian_peaks_at_the_centre_and_is_alpha_over_e_at_a_half_width() {
        let w = widget(
            WidgetShape::Gaussian,
            [0.2, 0.6],
            [2.0, 6.0],
            [0.0, 1.0, 0.0],
            0.8,
        );
        // Centre (0.4, 4); half-widths 0.2 and 2.
        assert_eq!(w.opacity(0.4, 4.0), 0.8);
        let e1 = 0.8 * (-1.0f32).exp();
        for (v, g) in [(0.6, 4.0), (0.2, 4.0), (0.4, 6.0), (0.4, 2.0)] {
            assert!(
                (w.opacity(v, g) - e1).abs() < 1e-6,
                "({v}, {g}): {}",
                w.opacity(v, g)
            );
        }
        let e2 = 0.8 * (-2.0f32).exp();
        assert!((w.opacity(0.6, 6.0) - e2).abs() < 1e-6);
        assert!(w.opacity(0.9, 4.0) > 0.0, "unbounded support");
        let tf = single(w);
        assert_eq!(tf.eval(0.4, 4.0), [0.0, 1.0, 0.0, 0.8]);
    }

    #[test]
    fn zero_width_ranges_do_not_divide_by_zero() {
        let w = widget(WidgetShape::Gaussian, [0.5, 0.5], [0.0, 2.0], [1.0; 3], 1.0);
        assert_eq!(w.opacity(0.5, 1.0), 1.0);
        assert_eq!(w.opacity(0.5001, 1.0), 0.0);
        let point = widget(WidgetShape::Gaussian, [0.5, 0.5], [1.0, 1.0], [1.0; 3], 1.0);
        assert_eq!(point.opacity(0.5, 1.0), 1.0);
        assert_eq!(point.opacity(0.0, 0.0), 0.0);
        let huge = widget(
            WidgetShape::Gaussian,
            [0.0, 1.0],
            [-f32::MAX, f32::MAX],
            [1.0; 3],
            1.0,
        );
        assert_eq!(huge.opacity(0.5, 0.0), 1.0);
    }

    #[test]
    fn widgets_combine_by_summed_alpha_and_weighted_colour() {
        let red = widget(
            WidgetShape::Rectangle,
            [0.0, 0.5],
            [0.0, 10.0],
            [1.0, 0.0, 0.0],
            0.25,
        );
        let blue = widget(
            WidgetShape::Rectangle,
            [0.25, 1.0],
            [0.0, 10.0],
            [0.0, 0.0, 1.0],
            0.5,
        );
        let tf = Transfer2D::new(vec![red, blue], 10.0).expect("valid");
        assert_eq!(tf.eval(0.1, 1.0), [1.0, 0.0, 0.0, 0.25]);
        assert_eq!(tf.eval(0.9, 1.0), [0.0, 0.0, 1.0, 0.5]);
        // Overlap: alpha 0.75; colour (0.25 red + 0.5 blue) / 0.75.
        let both = tf.eval(0.375, 1.0);
        let expected = [1.0 / 3.0, 0.0, 2.0 / 3.0, 0.75];
        for c in 0..4 {
            assert!(
                (both[c] - expected[c]).abs() < 1e-6,
                "{both:?} vs {expected:?}"
            );
        }
        // Alphas summing past 1 saturate.
        let opaque = Transfer2D::new(vec![red, blue, blue], 10.0).expect("valid");
        assert_eq!(opaque.eval(0.375, 1.0)[3], 1.0);
        assert!((opaque.eval(0.375, 1.0)[2] - 0.8).abs() < 1e-6);
    }

    #[test]
    fn no_widgets_is_transparent() {
        let tf = Transfer2D::new(vec![], 1.0).expect("valid");
        assert_eq!(tf.eval(0.5, 0.5), [0.0; 4]);
        assert_eq!(tf.table(4, 4).lookup(0.5, 0.5), [0.0; 4]);
    }

    #[test]
    fn inputs_are_clamped_and_nan_safe() {
        let tf = single(widget(
            WidgetShape::Gaussian,
            [0.0, 0.5],
            [0.0, 4.0],
            [1.0; 3],
            1.0,
        ));
        assert_eq!(tf.eval(f32::NAN, f32::NAN), tf.eval(0.0, 0.0));
        assert_eq!(tf.eval(-1.0, -5.0), tf.eval(0.0, 0.0));
        assert_eq!(tf.eval(2.0, 1e30), tf.eval(1.0, 10.0));
        let table = tf.table(8, 8);
        assert_eq!(table.lookup(f32::NAN, f32::NAN), table.lookup(0.0, 0.0));
        assert_eq!(
            table.lookup(f32::INFINITY, f32::INFINITY),
            table.lookup(1.0, 10.0)
        );
        assert!(table.lookup(f32::NAN, 3.0).iter().all(|c| c.is_finite()));
    }

    #[test]
    fn table_matches_eval_at_entries_and_within_the_bilinear_bound() {
        let (alpha, hv, hg) = (0.9f32, 0.15f32, 1.5f32);
        let w = widget(
            WidgetShape::Gaussian,
            [0.5 - hv, 0.5 + hv],
            [4.0 - hg, 4.0 + hg],
            [0.2, 0.4, 0.6],
            alpha,
        );
        let tf = single(w);
        let (nv, ng) = (64, 32);
        let table = tf.table(nv, ng);
        assert_eq!(table.dims(), (nv, ng));
        assert_eq!(table.byte_size(), nv * ng * 16);
        assert_eq!(table.lookup(0.0, 0.0), tf.eval(0.0, 0.0));
        assert_eq!(table.lookup(1.0, 10.0), tf.eval(1.0, 10.0));
        // |d/dx exp(-x^2)| <= sqrt(2/e), so the opacity is Lipschitz with K_v = alpha sqrt(2/e)/hv
        // along v and K_g = alpha sqrt(2/e)/hg along g. Bilinear interpolation is a convex
        // combination of the 4 corners, with sum w_i |v - v_i| = 2 t (1 - t) dv <= dv / 2: the
        // error is at most (K_v dv + K_g dg) / 2.
        let slope = alpha * (2.0f32 / std::f32::consts::E).sqrt();
        let (dv, dg) = (1.0 / (nv - 1) as f32, 10.0 / (ng - 1) as f32);
        let tolerance = (slope / hv * dv + slope / hg * dg) / 2.0 + 1e-6;
        let mut worst = 0.0f32;
        for i in 0..=197 {
            for j in 0..=101 {
                let (v, g) = (i as f32 / 197.0, j as f32 / 101.0 * 10.0);
                worst = worst.max((table.lookup(v, g)[3] - tf.eval(v, g)[3]).abs());
            }
        }
        assert!(worst <= tolerance, "{worst} > {tolerance}");
        assert!(
            worst > tolerance / 100.0,
            "the sweep exercises the bound ({worst})"
        );
    }

    fn error(widgets: Vec<Widget>, gradient_max: f32) -> String {
        match Transfer2D::new(widgets, gradient_max) {
            Ok(_) => panic!("expected an error"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn invalid_widgets_are_rejected_with_a_message() {
        let ok = widget(
            WidgetShape::Rectangle,
            [0.2, 0.4],
            [0.0, 1.0],
            [1.0; 3],
            0.5,
        );
        let reversed = Widget {
            value: [0.6, 0.4],
            ..ok
        };
        assert_eq!(
            error(vec![ok, reversed], 1.0),
            "widget 2 of 2: value range [0.6, 0.4] is reversed (expected [low, high] with low <= high)"
        );
        let infinite = Widget {
            gradient: [0.0, f32::INFINITY],
            ..ok
        };
        assert_eq!(
            error(vec![infinite], 1.0),
            "widget 1 of 1: gradient range [0, inf] is not finite"
        );
        let too_opaque = Widget { alpha: 1.5, ..ok };
        assert_eq!(
            error(vec![too_opaque], 1.0),
            "widget 1 of 1: alpha 1.5 is outside [0, 1]"
        );
        let bad_colour = Widget {
            color: [0.0, 0.0, -0.1],
            ..ok
        };
        assert_eq!(
            error(vec![bad_colour], 1.0),
            "widget 1 of 1: color blue -0.1 is outside [0, 1]"
        );
        for g in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            assert_eq!(
                error(vec![ok], g),
                format!("gradient_max {g} must be a finite number greater than 0")
            );
        }
    }
}
