//! Named transfer-function presets with knots in data units: colour and scalar opacity
//! of 3D Slicer's volume-rendering presets (`Modules/Loadable/VolumeRendering/Resources/
//! presets.xml` in Slicer/Slicer, read at commit 583e9b37, 2026-08-21; the numbers are
//! data, copied from its `colorTransfer` and `scalarOpacity` attributes). Slicer's
//! gradient opacity, shading coefficients and interpolation flag are not used: the
//! scene's `shading`, `material` and `interpolation` apply instead. Slicer's curves are
//! piecewise linear (VTK's defaults: RGB colour interpolation, midpoint 0.5, sharpness 0).
//!
//! A preset is placed on the normalised scale with the volume's window `[lo, hi]`
//! ([`Preset::transfer`]): each curve is cut to the window exactly (its value at `lo`
//! and `hi`, the knots between), then `t = (x - lo) / (hi - lo)`.

use super::{Interpolation, Transfer1D, TransferError};

/// A transfer-function preset: knots in data units (Hounsfield units for CT).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Preset {
    /// The scene-file name (`transfer = "ct-bone"`).
    pub name: &'static str,
    /// The Slicer preset it comes from.
    pub slicer: &'static str,
    /// Colour knots `(data value, [r, g, b])`.
    pub color: &'static [(f64, [f64; 3])],
    /// Opacity knots `(data value, alpha)`.
    pub alpha: &'static [(f64, f64)],
}

/// Every preset, by scene-file name.
pub const PRESETS: &[Preset] = &[
    Preset {
        name: "ct-bone",
        slicer: "CT-Bone",
        color: &[
            (-3024.0, [0.0, 0.0, 0.0]),
            (-16.4458, [0.729412, 0.254902, 0.301961]),
            (641.385, [0.905882, 0.815686, 0.552941]),
            (3071.0, [1.0, 1.0, 1.0]),
        ],
        alpha: &[
            (-3024.0, 0.0),
            (-16.4458, 0.0),
            (641.385, 0.715686),
            (3071.0, 0.705882),
        ],
    },
    Preset {
        name: "ct-soft-tissue",
        slicer: "CT-Soft-Tissue",
        color: &[
            (-2048.0, [0.0, 0.0, 0.0]),
            (-167.01, [0.0, 0.0, 0.0]),
            (-160.0, [0.0556356, 0.0556356, 0.0556356]),
            (240.0, [1.0, 1.0, 1.0]),
            (3661.0, [1.0, 1.0, 1.0]),
        ],
        alpha: &[
            (-2048.0, 0.0),
            (-167.01, 0.0),
            (-160.0, 1.0),
            (240.0, 1.0),
            (3661.0, 1.0),
        ],
    },
    // Slicer has no preset named "CT-Angio": its CT-AAA (abdominal aortic aneurysm,
    // contrast-enhanced CT angiography) shows contrast-filled vessels and bone.
    Preset {
        name: "ct-angio",
        slicer: "CT-AAA",
        color: &[
            (-3024.0, [0.0, 0.0, 0.0]),
            (143.556, [0.615686, 0.356863, 0.184314]),
            (166.222, [0.882353, 0.603922, 0.290196]),
            (214.389, [1.0, 1.0, 1.0]),
            (419.736, [1.0, 0.937033, 0.954531]),
            (3071.0, [0.827451, 0.658824, 1.0]),
        ],
        alpha: &[
            (-3024.0, 0.0),
            (143.556, 0.0),
            (166.222, 0.686275),
            (214.389, 0.696078),
            (419.736, 0.833333),
            (3071.0, 0.803922),
        ],
    },
    Preset {
        name: "mr-default",
        slicer: "MR-Default",
        color: &[
            (0.0, [0.0, 0.0, 0.0]),
            (20.0, [0.168627, 0.0, 0.0]),
            (40.0, [0.403922, 0.145098, 0.0784314]),
            (120.0, [0.780392, 0.607843, 0.380392]),
            (220.0, [0.847059, 0.835294, 0.788235]),
            (1024.0, [1.0, 1.0, 1.0]),
        ],
        alpha: &[
            (0.0, 0.0),
            (20.0, 0.0),
            (40.0, 0.15),
            (120.0, 0.3),
            (220.0, 0.375),
            (1024.0, 0.5),
        ],
    },
];

impl Preset {
    /// The preset called `name`.
    pub fn find(name: &str) -> Option<&'static Preset> {
        PRESETS.iter().find(|p| p.name == name)
    }

    /// The scene-file names of every preset.
    pub fn names() -> impl Iterator<Item = &'static str> {
        PRESETS.iter().map(|p| p.name)
    }

    /// The preset on the normalised scale of the window `[lo, hi]` (data values,
    /// `lo < hi`, both finite): piecewise linear, cut exactly to the window.
    pub fn transfer(&self, lo: f64, hi: f64) -> Result<Transfer1D, TransferError> {
        let color = window_knots(self.color, lo, hi);
        let alpha = window_knots(
            &self
                .alpha
                .iter()
                .map(|&(x, a)| (x, [a]))
                .collect::<Vec<_>>(),
            lo,
            hi,
        )
        .into_iter()
        .map(|(t, [a])| (t, a))
        .collect();
        Transfer1D::new(color, alpha, Interpolation::Linear)
    }
}

/// The piecewise-linear curve through `knots` (data values, increasing), constant
/// beyond its ends, cut to `[lo, hi]` and placed at `t = (x - lo) / (hi - lo)`: its
/// value at `lo`, the knots strictly inside, its value at `hi`.
fn window_knots<const N: usize>(
    knots: &[(f64, [f64; N])],
    lo: f64,
    hi: f64,
) -> Vec<(f32, [f32; N])> {
    let at = |x: f64| -> [f64; N] {
        let (first, last) = (knots[0], knots[knots.len() - 1]);
        if x <= first.0 {
            return first.1;
        }
        if x >= last.0 {
            return last.1;
        }
        let k = knots
            .windows(2)
            .find(|w| x <= w[1].0)
            .expect("x is inside the knots");
        let f = (x - k[0].0) / (k[1].0 - k[0].0);
        std::array::from_fn(|c| k[0].1[c] + (k[1].1[c] - k[0].1[c]) * f)
    };
    let t = |x: f64| ((x - lo) / (hi - lo)).clamp(0.0, 1.0) as f32;
    let narrow = |v: [f64; N]| v.map(|y| y as f32);
    std::iter::once((0.0, narrow(at(lo))))
        .chain(
            knots
                .iter()
                .filter(|k| lo < k.0 && k.0 < hi)
                .map(|k| (t(k.0), narrow(k.1))),
        )
        .chain(std::iter::once((1.0, narrow(at(hi)))))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_placed_on_the_window() {
        // CT-Bone at 300 HU, by hand from Slicer's knots (-16.4458, 0) and
        // (641.385, 0.715686): alpha = 0.715686 (300 + 16.4458) / 657.8308
        let bone = Preset::find("ct-bone").unwrap();
        let tf = bone.transfer(-1000.0, 2000.0).unwrap();
        let t = (300.0 + 1000.0) / 3000.0;
        let [r, g, b, a] = tf.eval(t as f32);
        let f = (300.0 + 16.4458) / (641.385 + 16.4458);
        let want_a = 0.715686 * f;
        let want_r = 0.729412 + (0.905882 - 0.729412) * f;
        let want_g = 0.254902 + (0.815686 - 0.254902) * f;
        let want_b = 0.301961 + (0.552941 - 0.301961) * f;
        for (got, want) in [(r, want_r), (g, want_g), (b, want_b), (a, want_a)] {
            assert!((f64::from(got) - want).abs() < 1e-5, "{got} vs {want}");
        }
        // the window's low end, inside Slicer's first segment: alpha 0, colour a
        // fraction of the way from black to the knot at -16.4458
        let f = (3024.0 - 1000.0) / (3024.0 - 16.4458);
        let low = tf.eval(0.0);
        assert!((f64::from(low[0]) - 0.729412 * f).abs() < 1e-6, "{low:?}");
        assert_eq!(low[3], 0.0);
        // beyond Slicer's last knot, the curve stays at its last value
        let wide = bone.transfer(-4000.0, 4000.0).unwrap();
        let top = wide.eval(1.0);
        assert!((top[3] - 0.705882).abs() < 1e-6 && top[0] == 1.0, "{top:?}");
        // a window inside one segment: the two cut ends only
        let soft = Preset::find("ct-soft-tissue")
            .unwrap()
            .transfer(0.0, 100.0)
            .unwrap();
        let mid = soft.eval(0.5);
        let g = 0.0556356 + (1.0 - 0.0556356) * (50.0 + 160.0) / 400.0;
        assert!(
            (f64::from(mid[0]) - g).abs() < 1e-6 && mid[3] == 1.0,
            "{mid:?}"
        );
    }

    #[test]
    fn every_preset_is_valid_on_common_windows() {
        for p in PRESETS {
            for (lo, hi) in [(-1024.0, 3071.0), (0.0, 255.0), (-3e4, 3e4), (100.0, 100.5)] {
                p.transfer(lo, hi)
                    .unwrap_or_else(|e| panic!("{} on [{lo}, {hi}]: {e}", p.name));
            }
            assert!(p.color.windows(2).all(|w| w[0].0 < w[1].0), "{}", p.name);
            assert!(p.alpha.windows(2).all(|w| w[0].0 < w[1].0), "{}", p.name);
        }
        assert!(Preset::find("bone").is_none(), "distinct from the built-in");
    }
}
