//! Turning film values into displayable colours in [0, 1].
//!
//! Intensity modes use one grey window `[lo, hi]` for a whole sequence (so a
//! turntable does not flicker); depth shows near as bright; a colour map, when the
//! pass has one, turns that grey level into a colour; pixels without a value (NaN:
//! the ray missed, or never crossed the threshold) show the background; RGBA films
//! are composited over the background.

use crate::render::Film;
use crate::transfer::Colormap;

/// How film values become grey or colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DisplayKind {
    /// Grey = `(v - lo) / (hi - lo)`, through the colour map when there is one.
    Intensity(Window, Option<Colormap>),
    /// Grey = `(hi - v) / (hi - lo)`: near is bright; through the colour map when
    /// there is one.
    Depth(Window, Option<Colormap>),
    /// RGBA (not premultiplied) over the background.
    Rgba,
}

/// A grey window `[lo, hi]`, `lo < hi`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    /// Value shown black.
    pub lo: f64,
    /// Value shown white.
    pub hi: f64,
}

impl Window {
    /// The window spanning films' [`Window::finite_range`]s. A constant image `v`
    /// gets the window from 0 to `v` (so zero shows black and anything else white);
    /// no finite value gives `[0, 1]`.
    pub fn of_ranges(ranges: impl IntoIterator<Item = (f64, f64)>) -> Window {
        let (lo, hi) = ranges
            .into_iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), (a, b)| {
                (lo.min(a), hi.max(b))
            });
        Window::from_range(lo, hi)
    }

    /// The smallest and largest finite value of `film` (channel 0); `(inf, -inf)`
    /// when none is finite. Ranges combine by min and max, in any order.
    pub fn finite_range(film: &Film) -> (f64, f64) {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for px in film.data.chunks_exact(film.channels) {
            let v = px[0] as f64;
            if v.is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        (lo, hi)
    }

    /// A window from a value range, made valid as in [`Window::of_ranges`].
    pub fn from_range(lo: f64, hi: f64) -> Window {
        if !(lo.is_finite() && hi.is_finite()) {
            Window { lo: 0.0, hi: 1.0 }
        } else if lo < hi {
            Window { lo, hi }
        } else if lo > 0.0 {
            Window { lo: 0.0, hi: lo }
        } else if lo < 0.0 {
            Window { lo, hi: 0.0 }
        } else {
            Window { lo: 0.0, hi: 1.0 }
        }
    }

    /// `v` on the window's scale, clamped to [0, 1].
    pub fn unit(&self, v: f64) -> f64 {
        ((v - self.lo) / (self.hi - self.lo)).clamp(0.0, 1.0)
    }
}

/// Converts a film to display values: 1 channel (grey) where the film is an
/// intensity film without a colour map (`grey` counts as none) and the background
/// is grey, else 3 (RGB). The new film is allocated fallibly.
pub fn to_display(
    film: &Film,
    kind: DisplayKind,
    background: [f32; 3],
) -> Result<Film, super::AllocError> {
    let grey_bg = background[0] == background[1] && background[1] == background[2];
    let map = match kind {
        DisplayKind::Intensity(_, m) | DisplayKind::Depth(_, m) => {
            m.filter(|m| *m != Colormap::Grey)
        }
        DisplayKind::Rgba => None,
    };
    let channels = match kind {
        DisplayKind::Rgba => 3,
        _ if grey_bg && map.is_none() => 1,
        _ => 3,
    };
    let mut out = super::try_film(film.width, film.height, channels)?;
    for (src, dst) in film
        .data
        .chunks_exact(film.channels)
        .zip(out.data.chunks_exact_mut(channels))
    {
        match kind {
            DisplayKind::Rgba => {
                let a = src[3].clamp(0.0, 1.0);
                for c in 0..3 {
                    let v = src[c].clamp(0.0, 1.0) * a + background[c] * (1.0 - a);
                    dst[c] = if v.is_finite() { v } else { background[c] };
                }
            }
            DisplayKind::Intensity(w, _) | DisplayKind::Depth(w, _) => {
                let v = src[0] as f64;
                if v.is_nan() {
                    dst.copy_from_slice(&background[..channels]);
                } else {
                    let g = match kind {
                        DisplayKind::Depth(..) => 1.0 - w.unit(v),
                        _ => w.unit(v),
                    };
                    match map {
                        Some(m) => dst.copy_from_slice(&m.at(g)),
                        None => dst.fill(g as f32),
                    }
                }
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_and_background() {
        let f = Film {
            width: 3,
            height: 1,
            channels: 1,
            data: vec![1.0, 3.0, f32::NAN],
        };
        let w = Window::of_ranges([Window::finite_range(&f)]);
        assert_eq!((w.lo, w.hi), (1.0, 3.0));
        let d = to_display(&f, DisplayKind::Intensity(w, None), [0.25; 3]).unwrap();
        assert_eq!(d.data, vec![0.0, 1.0, 0.25]);
        let grey = to_display(
            &f,
            DisplayKind::Intensity(w, Some(Colormap::Grey)),
            [0.25; 3],
        );
        assert_eq!(grey.unwrap().data, d.data);
        let d = to_display(&f, DisplayKind::Depth(w, None), [0.0, 0.0, 1.0]).unwrap();
        assert_eq!(d.channels, 3);
        assert_eq!(d.data, vec![1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
    }

    #[test]
    fn colour_maps_turn_the_grey_level_into_a_colour() {
        let f = Film {
            width: 3,
            height: 1,
            channels: 1,
            data: vec![1.0, 3.0, f32::NAN],
        };
        let w = Window { lo: 1.0, hi: 3.0 };
        let hot = Some(Colormap::Hot);
        let d = to_display(&f, DisplayKind::Intensity(w, hot), [0.25; 3]).unwrap();
        assert_eq!(d.channels, 3);
        // matplotlib's hot: #0b0000 at 0, white at 1; a miss keeps the background
        let want = [0.0416, 0.0, 0.0, 1.0, 1.0, 1.0, 0.25, 0.25, 0.25];
        for (g, w) in d.data.iter().zip(want) {
            assert!((g - w).abs() < 1e-6, "{:?}", d.data);
        }
        // depth: near (low values) bright
        let d = to_display(&f, DisplayKind::Depth(w, hot), [0.0; 3]).unwrap();
        assert_eq!(&d.data[..3], &[1.0; 3]);
    }

    #[test]
    fn rgba_over_background() {
        let f = Film {
            width: 1,
            height: 1,
            channels: 4,
            data: vec![1.0, 0.0, 0.0, 0.5],
        };
        let d = to_display(&f, DisplayKind::Rgba, [0.0, 0.0, 1.0]).unwrap();
        assert_eq!(d.data, vec![0.5, 0.0, 0.5]);
    }

    #[test]
    fn degenerate_windows() {
        assert_eq!(Window::from_range(2.0, 2.0), Window { lo: 0.0, hi: 2.0 });
        assert_eq!(Window::from_range(-2.0, -2.0), Window { lo: -2.0, hi: 0.0 });
        assert_eq!(Window::from_range(0.0, 0.0), Window { lo: 0.0, hi: 1.0 });
        assert_eq!(
            Window::from_range(f64::INFINITY, f64::NEG_INFINITY),
            Window { lo: 0.0, hi: 1.0 }
        );
    }
}
