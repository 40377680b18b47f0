//! Colour maps: a normalised number in [0, 1] to a colour. The perceptual maps of
//! matplotlib (viridis, magma, inferno, plasma) come from the `colorous` crate
//! (d3-scale-chromatic's fits of the published tables, within 1/255 of them); cividis
//! and Google's turbo are their published 256-entry tables, linear between entries
//! ([`super::colormap_tables`]: colorous's fits of these two are up to 18/255 and
//! 32/255 away from the tables); `hot` and
//! `bone` are matplotlib's piecewise-linear definitions (its `_cm.py` segment data,
//! which reproduce MATLAB's maps of the same names), written here from those numbers;
//! `grey` is the identity ramp. Every map is tested against matplotlib's own 256-entry
//! tables (`tests/fixtures/colormaps/`).

use super::colormap_tables as tables;

/// A colour map, by its scene-file name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Colormap {
    /// matplotlib's viridis.
    Viridis,
    /// matplotlib's magma.
    Magma,
    /// matplotlib's inferno.
    Inferno,
    /// matplotlib's plasma.
    Plasma,
    /// cividis (Nuñez et al. 2018).
    Cividis,
    /// Google's turbo (Mikhailov 2019), a rainbow that runs through the hues.
    Turbo,
    /// Black to white.
    Grey,
    /// matplotlib's hot: black, red, yellow, white.
    Hot,
    /// matplotlib's bone: grey with a blue tinge.
    Bone,
}

/// One channel of a segmented map: `(x, value)` breakpoints, linear between them, `x`
/// from 0 to 1 in increasing order (matplotlib's `(x, y0, y1)` rows with `y0 = y1`:
/// neither map has a jump).
type Segments = &'static [(f64, f64)];

/// matplotlib's `_hot_data` (`lib/matplotlib/_cm.py`): red, green, blue.
const HOT: [Segments; 3] = [
    &[(0.0, 0.0416), (0.365079, 1.0), (1.0, 1.0)],
    &[(0.0, 0.0), (0.365079, 0.0), (0.746032, 1.0), (1.0, 1.0)],
    &[(0.0, 0.0), (0.746032, 0.0), (1.0, 1.0)],
];

/// matplotlib's `_bone_data` (`lib/matplotlib/_cm.py`): red, green, blue.
const BONE: [Segments; 3] = [
    &[(0.0, 0.0), (0.746032, 0.652778), (1.0, 1.0)],
    &[
        (0.0, 0.0),
        (0.365079, 0.319444),
        (0.746032, 0.777778),
        (1.0, 1.0),
    ],
    &[(0.0, 0.0), (0.365079, 0.444444), (1.0, 1.0)],
];

/// A 256-entry table at `t` in [0, 1], entry `i` at `i / 255`, linear between entries.
fn tabulated(table: &[[f32; 3]; 256], t: f64) -> [f32; 3] {
    let x = t * 255.0;
    let i = (x.floor() as usize).min(254);
    let f = (x - i as f64) as f32;
    let (a, b) = (table[i], table[i + 1]);
    [0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * f)
}

/// The value of one segmented channel at `t` in [0, 1].
fn segmented(channel: Segments, t: f64) -> f64 {
    for w in channel.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if t <= x1 {
            return y0 + (y1 - y0) * (t - x0) / (x1 - x0);
        }
    }
    channel.last().map_or(0.0, |k| k.1)
}

impl Colormap {
    /// Every map with its scene-file name.
    pub const ALL: &'static [(&'static str, Colormap)] = &[
        ("viridis", Colormap::Viridis),
        ("magma", Colormap::Magma),
        ("inferno", Colormap::Inferno),
        ("plasma", Colormap::Plasma),
        ("cividis", Colormap::Cividis),
        ("turbo", Colormap::Turbo),
        ("grey", Colormap::Grey),
        ("hot", Colormap::Hot),
        ("bone", Colormap::Bone),
    ];

    /// The scene-file name.
    pub fn name(self) -> &'static str {
        Colormap::ALL
            .iter()
            .find(|(_, m)| *m == self)
            .map_or("?", |(n, _)| n)
    }

    /// The colour at `t` (clamped to [0, 1]; NaN reads as 0), RGB in [0, 1].
    pub fn at(self, t: f64) -> [f32; 3] {
        let t = if t >= 1.0 {
            1.0
        } else if t > 0.0 {
            t
        } else {
            0.0
        };
        let gradient = match self {
            Colormap::Viridis => colorous::VIRIDIS,
            Colormap::Magma => colorous::MAGMA,
            Colormap::Inferno => colorous::INFERNO,
            Colormap::Plasma => colorous::PLASMA,
            Colormap::Cividis => return tabulated(&tables::CIVIDIS, t),
            Colormap::Turbo => return tabulated(&tables::TURBO, t),
            Colormap::Grey => return [t as f32; 3],
            Colormap::Hot => return HOT.map(|c| segmented(c, t) as f32),
            Colormap::Bone => return BONE.map(|c| segmented(c, t) as f32),
        };
        let c = gradient.eval_continuous(t);
        [c.r, c.g, c.b].map(|x| f32::from(x) / 255.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_of_the_maps() {
        // matplotlib's viridis runs from #440154 to #fde725
        let v0 = Colormap::Viridis.at(0.0);
        let v1 = Colormap::Viridis.at(1.0);
        let close = |a: [f32; 3], b: [u8; 3]| {
            a.iter()
                .zip(b)
                .all(|(x, y)| (x * 255.0 - f32::from(y)).abs() <= 2.0)
        };
        assert!(close(v0, [0x44, 0x01, 0x54]), "{v0:?}");
        assert!(close(v1, [0xfd, 0xe7, 0x25]), "{v1:?}");
        assert_eq!(Colormap::Grey.at(0.25), [0.25; 3]);
        assert_eq!(Colormap::Grey.at(f64::NAN), [0.0; 3]);
        assert_eq!(Colormap::Turbo.at(7.0), Colormap::Turbo.at(1.0));
        for (name, m) in Colormap::ALL {
            assert_eq!(m.name(), *name);
        }
    }
}
