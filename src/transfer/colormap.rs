//! Colour maps: a normalised number in [0, 1] to a colour. The perceptual maps of
//! matplotlib (viridis, magma, inferno, plasma, cividis) and Google's turbo come from
//! the `colorous` crate (d3-scale-chromatic's fits of the published tables); `grey`
//! is the identity ramp.

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
            Colormap::Cividis => colorous::CIVIDIS,
            Colormap::Turbo => colorous::TURBO,
            Colormap::Grey => return [t as f32; 3],
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
