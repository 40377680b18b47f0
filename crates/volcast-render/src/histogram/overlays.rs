//! What a scene draws over its histograms, in the plots' units: the volume's window,
//! every pass's iso value or threshold, the 1D transfer functions' colour and opacity
//! curves and the 2D transfer functions' widgets, their values converted from the
//! resolved scene's normalised values to data values.

use crate::sample::Normalize;
use crate::scene::Scene;
use crate::transfer::Transfer;
use crate::transfer::WidgetShape;
use crate::volume::Rescale;

use super::data_value;

/// A value marked by a line, with its label.
#[derive(Clone, Debug, PartialEq)]
pub struct Marker {
    /// What it is (`"iso: iso 0.35"`).
    pub label: String,
    /// Data value (a vertical line), or gradient magnitude (a horizontal line).
    pub at: f64,
}

/// A 1D transfer function sampled along the value axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Curve1D {
    /// The pass and the transfer function's name.
    pub label: String,
    /// `(data value, colour, opacity)`, in increasing order of value, spanning the
    /// window (the function is constant beyond it).
    pub points: Vec<(f64, [f32; 3], f32)>,
}

impl Curve1D {
    /// The colour and opacity at data value `x`: linear between the points,
    /// constant beyond the first and the last.
    pub fn at(&self, x: f64) -> ([f32; 3], f32) {
        let p = &self.points;
        let Some(first) = p.first() else {
            return ([0.0; 3], 0.0);
        };
        let k = p.partition_point(|q| q.0 <= x);
        if k == 0 || x.is_nan() {
            return (first.1, first.2);
        }
        if k == p.len() {
            let last = p[k - 1];
            return (last.1, last.2);
        }
        let (a, b) = (p[k - 1], p[k]);
        let f = ((x - a.0) / (b.0 - a.0)) as f32;
        let f = if f.is_finite() { f } else { 0.0 };
        let lerp = |u: f32, v: f32| u + (v - u) * f;
        ([0, 1, 2].map(|c| lerp(a.1[c], b.1[c])), lerp(a.2, b.2))
    }
}

/// A widget of a 2D transfer function over (value, gradient magnitude).
#[derive(Clone, Debug, PartialEq)]
pub struct WidgetBox {
    /// The pass, the transfer function's name and the widget's number.
    pub label: String,
    /// Rectangle or Gaussian.
    pub shape: WidgetShape,
    /// Data values `[low, high]`.
    pub value: [f64; 2],
    /// Gradient magnitudes `[low, high]` (normalised value per voxel).
    pub gradient: [f64; 2],
    /// Linear RGB.
    pub color: [f32; 3],
    /// Peak opacity.
    pub alpha: f32,
}

/// Everything drawn over the plots (nothing for a volume without a scene).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overlays {
    /// The value window `[low, high]` in data values (normalised 0 and 1).
    pub window: Option<[f64; 2]>,
    /// Iso values and thresholds (vertical lines on both plots).
    pub markers: Vec<Marker>,
    /// 1D transfer functions (over the value histogram).
    pub curves: Vec<Curve1D>,
    /// 2D transfer-function widgets (over the 2D histogram).
    pub widgets: Vec<WidgetBox>,
    /// The 2D transfer functions' `gradient_max` (horizontal lines on the 2D
    /// histogram: larger magnitudes are looked up there).
    pub gradient_max: Vec<Marker>,
}

/// Points along a 1D transfer function (about one per pixel column of the plot).
const CURVE_POINTS: usize = 1025;

impl Overlays {
    /// Nothing to draw.
    pub fn is_empty(&self) -> bool {
        *self == Overlays::default()
    }

    /// The overlays of `scene`, whose normalised values map to data values by the
    /// run's normalisation `norm` of stored values and the volume's `rescale`.
    pub fn of_scene(scene: &Scene, norm: Normalize, rescale: Rescale) -> Overlays {
        let data = |t: f64| data_value(norm, rescale, t);
        let mut o = Overlays {
            window: Some([data(0.0), data(1.0)]),
            ..Overlays::default()
        };
        for pass in &scene.passes {
            let name = &pass.name;
            let mut mark = |what: &str, t: f64| {
                o.markers.push(Marker {
                    label: format!("{name}: {what} {}", super::plot::number(data(t))),
                    at: data(t),
                })
            };
            if let Some(l) = pass.mode.level() {
                mark(l.key, l.value);
            }
            match pass.mode.transfer() {
                Some((transfer_name, Transfer::OneD(tf))) => o.curves.push(Curve1D {
                    label: format!("{name}: {transfer_name}"),
                    points: (0..CURVE_POINTS)
                        .map(|i| {
                            let t = i as f64 / (CURVE_POINTS - 1) as f64;
                            let [r, g, b, a] = tf.eval(t as f32);
                            (data(t), [r, g, b], a)
                        })
                        .collect(),
                }),
                Some((transfer_name, Transfer::TwoD(tf))) => {
                    for (k, w) in tf.widgets().iter().enumerate() {
                        o.widgets.push(WidgetBox {
                            label: format!("{name}: {transfer_name} {}", k + 1),
                            shape: w.shape,
                            value: w.value.map(|v| data(f64::from(v))),
                            gradient: w.gradient.map(f64::from),
                            color: w.color,
                            alpha: w.alpha,
                        });
                    }
                    o.gradient_max.push(Marker {
                        label: format!("{name}: gradient_max"),
                        at: f64::from(tf.gradient_max()),
                    });
                }
                None => {}
            }
        }
        o
    }
}
