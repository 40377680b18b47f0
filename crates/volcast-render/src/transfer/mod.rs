//! Transfer functions: from a normalised value (and gradient magnitude) to colour and opacity.
//!
//! In: knots ([`Transfer1D`]) or widgets ([`Transfer2D`]) as resolved from the scene's
//! `[transfer.NAME]` tables. Out: RGBA in [0, 1], evaluated directly or tabulated
//! ([`Table1D`], [`Table2D`]) once per pass for the `composite` integrator, which also applies
//! [`correct_opacity`] for its step size. Colour is not premultiplied; alpha is defined for the
//! pass's reference step. Formulas: docs/formulas.md "Transfer functions" and "Emission-absorption
//! and compositing".

mod colormap;
mod colormap_tables;
mod curve;
mod one_d;
mod preintegrated;
mod presets;
mod two_d;

use std::fmt;

pub use colormap::Colormap;
#[cfg(test)]
pub(crate) use one_d::split_position;
pub(crate) use one_d::{clamp_unit, table_position};
pub use one_d::{Table1D, Transfer1D};
pub use preintegrated::{Preintegrated, COLOR_ENTRIES, INTEGRAL_ENTRIES, MAX_EXTINCTION};
pub use presets::{Preset, PRESETS};
pub use two_d::{Table2D, Transfer2D, Widget, WidgetShape};

/// A transfer function over the normalised value, or over (value, gradient
/// magnitude).
#[derive(Clone, Debug)]
pub enum Transfer {
    /// Over the normalised value.
    OneD(std::sync::Arc<Transfer1D>),
    /// Over (value, gradient magnitude).
    TwoD(std::sync::Arc<Transfer2D>),
}

impl Transfer {
    /// The smallest normalised value with a non-zero opacity.
    pub fn first_opaque(&self) -> Option<f64> {
        match self {
            Transfer::OneD(tf) => tf.first_opaque(),
            Transfer::TwoD(tf) => tf.first_opaque(),
        }
    }
}

/// How a 1D transfer function interpolates between its knots.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// Piecewise linear.
    Linear,
    /// Monotone piecewise cubic Hermite (PCHIP, Fritsch and Carlson 1980): smooth (C1), passes
    /// through the knots and never overshoots them, so it needs no clamping to [0, 1]
    /// (docs/formulas.md warns that an ordinary cubic spline does).
    Cubic,
}

/// Which list of knots of a 1D transfer function an error is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KnotCurve {
    /// The colour knots `(position, [r, g, b])`.
    Color,
    /// The opacity knots `(position, alpha)`.
    Alpha,
}

impl fmt::Display for KnotCurve {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            KnotCurve::Color => "color",
            KnotCurve::Alpha => "alpha",
        })
    }
}

/// An invalid transfer function: what is wrong and what was expected. Messages start with the
/// part concerned (`color`, `alpha`, `widget`, `gradient_max`) and count items from 1.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TransferError {
    /// A list of knots is empty.
    #[error("{curve}: no knots (at least one [position, value] knot is required)")]
    NoKnots {
        /// The empty list.
        curve: KnotCurve,
    },
    /// A knot's position or value is invalid.
    #[error("{curve} knot {} of {count}: {problem}", index + 1)]
    Knot {
        /// The list holding the knot.
        curve: KnotCurve,
        /// 0-based index of the knot (the message counts from 1).
        index: usize,
        /// Number of knots in the list.
        count: usize,
        /// What is wrong and what was expected.
        problem: String,
    },
    /// A 2D widget is invalid.
    #[error("widget {} of {count}: {problem}", index + 1)]
    Widget {
        /// 0-based index of the widget (the message counts from 1).
        index: usize,
        /// Number of widgets.
        count: usize,
        /// What is wrong and what was expected.
        problem: String,
    },
    /// The gradient magnitude range of a 2D transfer function is empty or not finite.
    #[error("gradient_max {0} must be a finite number greater than 0")]
    GradientMax(f32),
}

/// A value that must lie in [0, 1]: `name` says what it is in the message.
fn check_unit(name: &str, x: f32) -> Result<(), String> {
    if !x.is_finite() {
        Err(format!("{name} {x} is not a finite number"))
    } else if !(0.0..=1.0).contains(&x) {
        Err(format!("{name} {x} is outside [0, 1]"))
    } else {
        Ok(())
    }
}

/// Opacity correction (docs/formulas.md "Emission-absorption and compositing"): the opacity for a
/// step `ratio = dt / dt0` times the reference step, for which the opacity is `a`:
/// `a' = 1 - (1 - a)^ratio`, so that images converge as `dt -> 0` instead of turning opaque.
///
/// Computed in f64 as `-expm1(log1p(-a) * ratio)`, which keeps its relative accuracy for small
/// `a` and small steps, where `1 - (1 - a).powf(ratio)` cancels to nothing (in f32,
/// `a = 1e-7, ratio = 1e-3` gives exactly 0 instead of 1e-10). `a` is clamped to [0, 1] and
/// `ratio` to `>= 0` (NaN counts as 0); `a = 0` stays 0 and `a = 1` stays 1 for any ratio (an
/// opaque sample stays opaque). The result is in [0, 1].
pub fn correct_opacity(a: f32, ratio: f32) -> f32 {
    let a = f64::from(if a.is_nan() { 0.0 } else { a.clamp(0.0, 1.0) });
    let ratio = f64::from(ratio.max(0.0));
    if a == 0.0 || a == 1.0 {
        return a as f32;
    }
    let corrected = -((-a).ln_1p() * ratio).exp_m1();
    (corrected as f32).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ratio_one_keeps_the_opacity() {
        for a in [0.0f32, 1e-7, 0.01, 0.3, 0.5, 0.9, 0.999_999, 1.0] {
            let c = correct_opacity(a, 1.0);
            assert!((c - a).abs() <= f32::EPSILON * a, "{a} -> {c}");
        }
    }

    #[test]
    fn two_steps_compose_into_one() {
        // Transparencies multiply: (1 - c(a, r1)) (1 - c(a, r2)) = 1 - c(a, r1 + r2).
        for a in [1e-6f32, 0.01, 0.2, 0.5, 0.8, 0.99, 0.999_9] {
            for (r1, r2) in [
                (0.5f32, 0.5f32),
                (0.1, 0.9),
                (0.25, 2.0),
                (1.0, 3.0),
                (1e-3, 0.01),
            ] {
                let (c1, c2) = (correct_opacity(a, r1), correct_opacity(a, r2));
                let composed = 1.0 - (1.0 - c1) * (1.0 - c2);
                let direct = correct_opacity(a, r1 + r2);
                assert!(
                    (composed - direct).abs() < 1e-6,
                    "a {a}, {r1} + {r2}: {composed} vs {direct}"
                );
            }
        }
    }

    #[test]
    fn opaque_stays_opaque_and_transparent_stays_transparent() {
        for ratio in [0.0f32, 1e-6, 0.5, 1.0, 10.0, f32::INFINITY] {
            assert_eq!(correct_opacity(1.0, ratio), 1.0, "ratio {ratio}");
            assert_eq!(correct_opacity(0.0, ratio), 0.0, "ratio {ratio}");
        }
    }

    #[test]
    fn out_of_range_inputs_are_clamped() {
        assert_eq!(correct_opacity(f32::NAN, 1.0), 0.0);
        assert_eq!(correct_opacity(1.5, 0.5), 1.0);
        assert_eq!(correct_opacity(-0.5, 0.5), 0.0);
        assert_eq!(correct_opacity(0.5, -1.0), 0.0);
        assert_eq!(correct_opacity(0.5, f32::NAN), 0.0);
        assert_eq!(correct_opacity(0.5, f32::INFINITY), 1.0);
    }

    #[test]
    fn small_opacity_and_small_step_keep_their_relative_accuracy() {
        let (a, ratio) = (1e-7f32, 1e-3f32);
        // Reference from series, independent of expm1/log1p: with x = ratio * ln(1 - a)
        // = -ratio (a + a^2/2 + a^3/3 + ...), a' = 1 - e^x = -x - x^2/2 - x^3/6 - ...;
        // the terms left out are below 1e-20 relative.
        let (a64, r64) = (f64::from(a), f64::from(ratio));
        let x = -r64 * (a64 + a64 * a64 / 2.0 + a64.powi(3) / 3.0);
        let expected = -x - x * x / 2.0 - x.powi(3) / 6.0;
        let got = f64::from(correct_opacity(a, ratio));
        assert!(
            ((got - expected) / expected).abs() < 1e-6,
            "{got} vs {expected}"
        );
        // The naive formula cancels: 1 - a rounds to 1 - 2^-23 in f32, whose 1e-3 power
        // rounds to 1, leaving 0 (and even in f64 it keeps only ~6 digits).
        let naive = 1.0 - (1.0 - a).powf(ratio);
        assert_eq!(naive, 0.0);
    }
}
