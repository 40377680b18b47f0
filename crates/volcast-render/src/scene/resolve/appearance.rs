//! `[material.NAME]` and `[transfer.NAME]` tables, and the built-in transfer functions.

use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::Arc;

use glam::Vec3;
use toml::Spanned;

use super::Resolver;
use crate::scene::schema::{MaterialTable, Sp, TransferTable, WidgetTable};
use crate::scene::{Transfer, Units};
use crate::shade::Material;
use crate::transfer::{self, Transfer1D, Transfer2D, Widget, WidgetShape};

impl Resolver<'_> {
    pub(super) fn materials(
        &mut self,
        m: &BTreeMap<String, Spanned<MaterialTable>>,
    ) -> BTreeMap<String, Material> {
        let mut out = BTreeMap::new();
        for (name, t) in m {
            let v = t.get_ref();
            let base = Material::neutral();
            let color = |r: &mut Self, key: &str, s: &Sp<[f64; 3]>, d: Vec3| {
                s.as_ref().map_or(d, |s| {
                    Vec3::from_array(r.unit_color(key, s).map(|x| x as f32))
                })
            };
            let ambient = color(self, "ambient", &v.ambient, base.ambient);
            let diffuse = color(self, "diffuse", &v.diffuse, base.diffuse);
            let specular = color(self, "specular", &v.specular, base.specular);
            let exponent = match (&v.shininess, &v.exponent) {
                (Some(_), Some(e)) => {
                    self.err(e.span(), "give either `shininess` (exponent = 32 * shininess) or `exponent`, not both");
                    base.exponent
                }
                (Some(_), None) => {
                    32.0 * self.number(
                        "shininess",
                        &v.shininess,
                        1.0,
                        |x| x >= 0.0,
                        "a number >= 0",
                    ) as f32
                }
                (None, Some(_)) => {
                    self.number("exponent", &v.exponent, 32.0, |x| x >= 0.0, "a number >= 0") as f32
                }
                (None, None) => base.exponent,
            };
            out.insert(
                name.clone(),
                Material {
                    ambient,
                    diffuse,
                    specular,
                    exponent,
                },
            );
        }
        out
    }

    pub(super) fn transfers(
        &mut self,
        m: &BTreeMap<String, Spanned<TransferTable>>,
    ) -> BTreeMap<String, Transfer> {
        let mut out = builtin_transfers();
        for (name, t) in m {
            if let Some(tf) = self.transfer(name, t) {
                out.insert(name.clone(), tf);
            }
        }
        out
    }

    pub(super) fn transfer(&mut self, name: &str, t: &Spanned<TransferTable>) -> Option<Transfer> {
        let v = t.get_ref();
        let two_d = self.choice(
            "kind",
            &v.kind,
            &[("1d", false), ("2d", true)],
            v.widget.is_some(),
        );
        let here = format!("[transfer.{name}]");
        if two_d {
            self.not_for(&format!("by the 2D transfer function {here} (it is built from [[transfer.{name}.widget]])"), &[
                ("color", v.color.as_ref().map(|s| s.span())),
                ("alpha", v.alpha.as_ref().map(|s| s.span())),
                ("interpolation", v.interpolation.as_ref().map(|s| s.span())),
            ]);
            let gradient_max = self.number(
                "gradient_max",
                &v.gradient_max,
                1.0,
                |x| x > 0.0,
                "a positive gradient magnitude",
            );
            let mut widgets = Vec::new();
            for w in v.widget.iter().flatten() {
                widgets.push(self.widget(w)?);
            }
            if widgets.is_empty() {
                self.err(
                    t.span(),
                    format!("{here} is 2D but has no [[transfer.{name}.widget]]"),
                );
                return None;
            }
            match Transfer2D::new(widgets, gradient_max as f32) {
                Ok(tf) => Some(Transfer::TwoD(Arc::new(tf))),
                Err(e) => {
                    self.err(t.span(), format!("{here}: {e}"));
                    None
                }
            }
        } else {
            self.not_for(
                &format!("by the 1D transfer function {here}"),
                &[("gradient_max", v.gradient_max.as_ref().map(|s| s.span()))],
            );
            let interpolation = self.choice(
                "interpolation",
                &v.interpolation,
                &[
                    ("linear", transfer::Interpolation::Linear),
                    ("cubic", transfer::Interpolation::Cubic),
                ],
                transfer::Interpolation::Linear,
            );
            let color: Vec<(f32, [f32; 3])> = match &v.color {
                Some(c) => c
                    .get_ref()
                    .iter()
                    .map(|(p, k)| (self.knot("color", *p, c.span()), k.map(|x| x as f32)))
                    .collect(),
                None => vec![(0.0, [1.0; 3])],
            };
            let Some(alpha) = &v.alpha else {
                self.err(
                    t.span(),
                    format!("{here} needs `alpha = [[position, alpha], ...]` knots"),
                );
                return None;
            };
            let alpha: Vec<(f32, f32)> = alpha
                .get_ref()
                .iter()
                .map(|(p, a)| (self.knot("alpha", *p, alpha.span()), *a as f32))
                .collect();
            match Transfer1D::new(color, alpha, interpolation) {
                Ok(tf) => Some(Transfer::OneD(Arc::new(tf))),
                Err(e) => {
                    let span = if e.to_string().starts_with("color") {
                        v.color.as_ref().map_or(t.span(), |s| s.span())
                    } else {
                        v.alpha.as_ref().map_or(t.span(), |s| s.span())
                    };
                    self.err(span, format!("{here}: {e}"));
                    None
                }
            }
        }
    }

    /// A position on a transfer function's value axis as written: normalised as it
    /// is, or a data value under `units = "data"` (converted, and checked to lie in
    /// the volume window).
    fn knot(&mut self, key: &str, x: f64, span: Range<usize>) -> f32 {
        match self.units {
            Units::Normalised => x as f32,
            Units::Data { .. } => self
                .value_at(&format!("{key} knot"), x, span)
                .unwrap_or(0.0) as f32,
        }
    }

    pub(super) fn widget(&mut self, w: &Spanned<WidgetTable>) -> Option<Widget> {
        let v = w.get_ref();
        let shape = self.choice(
            "shape",
            &v.shape,
            &[
                ("rectangle", WidgetShape::Rectangle),
                ("gaussian", WidgetShape::Gaussian),
            ],
            WidgetShape::Rectangle,
        );
        let range = |r: &mut Self, key: &str, s: &Sp<[f64; 2]>, d: [f32; 2]| -> [f32; 2] {
            match s {
                None => d,
                Some(s) => {
                    let [a, b] = *s.get_ref();
                    if a.is_finite() && b.is_finite() && a <= b {
                        [a as f32, b as f32]
                    } else {
                        r.err(
                            s.span(),
                            format!("{key} = [{a}, {b}]: expected [low, high] with low <= high"),
                        );
                        d
                    }
                }
            }
        };
        let mut value = range(self, "value", &v.value, [0.0, 1.0]);
        if let (Some(s), Units::Data { .. }) = (&v.value, self.units) {
            let [a, b] = *s.get_ref();
            value = [
                self.knot("value", a, s.span()),
                self.knot("value", b, s.span()),
            ];
        }
        let gradient = range(self, "gradient", &v.gradient, [0.0, f32::MAX]);
        let color = v
            .color
            .as_ref()
            .map_or([1.0; 3], |c| self.unit_color("color", c).map(|x| x as f32));
        let alpha = self.number(
            "alpha",
            &v.alpha,
            1.0,
            |x| (0.0..=1.0).contains(&x),
            "a number in [0, 1]",
        ) as f32;
        if v.value.is_none() {
            self.err(
                w.span(),
                "a widget needs `value = [low, high]` (normalised values, or data values under units = \"data\")",
            );
            return None;
        }
        Some(Widget {
            shape,
            value,
            gradient,
            color,
            alpha,
        })
    }
}

/// Transfer functions every scene can name without defining them.
fn builtin_transfers() -> BTreeMap<String, Transfer> {
    let mut m = BTreeMap::new();
    let grey = Transfer1D::new(
        vec![(0.0, [1.0; 3]), (1.0, [1.0; 3])],
        vec![(0.0, 0.0), (1.0, 1.0)],
        transfer::Interpolation::Linear,
    )
    .expect("built-in transfer function is valid");
    m.insert("grey".to_string(), Transfer::OneD(Arc::new(grey)));
    // The example of docs/scene-reference.md.
    let bone = Transfer1D::new(
        vec![
            (0.0, [0.91, 0.70, 0.61]),
            (0.32, [1.0, 1.0, 0.85]),
            (1.0, [1.0, 1.0, 0.85]),
        ],
        vec![(0.0, 0.0), (0.30, 0.0), (0.32, 0.9), (1.0, 1.0)],
        transfer::Interpolation::Linear,
    )
    .expect("built-in transfer function is valid");
    m.insert("bone".to_string(), Transfer::OneD(Arc::new(bone)));
    m
}
