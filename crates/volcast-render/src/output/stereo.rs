//! Stereo layouts (docs/formulas.md "Rotation sequences and stereo"): side by side for
//! parallel viewing, swapped for cross-eyed viewing, or an anaglyph.

use crate::render::Film;
use crate::scene::{Anaglyph, AnaglyphColors};

/// `first | gap | second`, the gap filled with `fill` (one value per channel).
pub fn side_by_side(
    first: &Film,
    second: &Film,
    gap: usize,
    fill: &[f32],
) -> Result<Film, super::AllocError> {
    assert_eq!(
        (first.width, first.height, first.channels),
        (second.width, second.height, second.channels)
    );
    let c = first.channels;
    let w = first.width * 2 + gap;
    let mut out = super::try_film(w, first.height, c)?;
    for (j, row) in out.data.chunks_exact_mut(w * c).enumerate() {
        fn src(f: &Film, j: usize) -> &[f32] {
            let n = f.width * f.channels;
            &f.data[j * n..(j + 1) * n]
        }
        let (left, rest) = row.split_at_mut(first.width * c);
        let (mid, right) = rest.split_at_mut(gap * c);
        left.copy_from_slice(src(first, j));
        for px in mid.chunks_exact_mut(c) {
            px.copy_from_slice(fill);
        }
        right.copy_from_slice(src(second, j));
    }
    Ok(out)
}

/// Rec. 709 luma of a display pixel (grey pixels are their own luma).
fn luma(px: &[f32]) -> f32 {
    if px.len() >= 3 {
        0.2126 * px[0] + 0.7152 * px[1] + 0.0722 * px[2]
    } else {
        px[0]
    }
}

/// The RGB of a display pixel (grey pixels repeated).
fn rgb(px: &[f32]) -> [f32; 3] {
    if px.len() >= 3 {
        [px[0], px[1], px[2]]
    } else {
        [px[0]; 3]
    }
}

/// An anaglyph of two display images: the red channel from the left view, green
/// and blue (red-cyan) or green only (red-green, blue 0) from the right view.
/// `colors` says what is taken: `Color` the views' own channels (a full-colour
/// anaglyph: left red, right green and blue), `HalfColor` the left view's luminance
/// for red and the right view's channels for the rest, `Gray` luminance for all
/// (Rec. 709 luma). For grey images all three are the same.
pub fn anaglyph(
    left: &Film,
    right: &Film,
    glasses: Anaglyph,
    colors: AnaglyphColors,
) -> Result<Film, super::AllocError> {
    assert_eq!((left.width, left.height), (right.width, right.height));
    let mut out = super::try_film(left.width, left.height, 3)?;
    let l = left.data.chunks_exact(left.channels);
    let r = right.data.chunks_exact(right.channels);
    for ((dst, lp), rp) in out.data.chunks_exact_mut(3).zip(l).zip(r) {
        let (lc, rc) = match colors {
            AnaglyphColors::Color => (rgb(lp), rgb(rp)),
            AnaglyphColors::HalfColor => ([luma(lp); 3], rgb(rp)),
            AnaglyphColors::Gray => ([luma(lp); 3], [luma(rp); 3]),
        };
        dst[0] = lc[0];
        dst[1] = rc[1];
        dst[2] = match glasses {
            Anaglyph::RedCyan => rc[2],
            Anaglyph::RedGreen => 0.0,
        };
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn film(w: usize, v: f32) -> Film {
        Film {
            width: w,
            height: 2,
            channels: 1,
            data: vec![v; w * 2],
        }
    }

    #[test]
    fn halves_and_gap() {
        let s = side_by_side(&film(2, 0.25), &film(2, 0.75), 1, &[0.5]).unwrap();
        assert_eq!(s.width, 5);
        assert_eq!(&s.data[..5], &[0.25, 0.25, 0.5, 0.75, 0.75]);
    }

    #[test]
    fn anaglyph_channels_come_from_the_right_eyes() {
        for colors in [
            AnaglyphColors::Color,
            AnaglyphColors::HalfColor,
            AnaglyphColors::Gray,
        ] {
            let a = anaglyph(&film(1, 0.2), &film(1, 0.9), Anaglyph::RedCyan, colors).unwrap();
            assert_eq!(&a.data[..3], &[0.2, 0.9, 0.9]);
            let a = anaglyph(&film(1, 0.2), &film(1, 0.9), Anaglyph::RedGreen, colors).unwrap();
            assert_eq!(&a.data[..3], &[0.2, 0.9, 0.0]);
        }
    }

    #[test]
    fn colour_anaglyphs() {
        let px = |r: f32, g: f32, b: f32| Film {
            width: 1,
            height: 1,
            channels: 3,
            data: vec![r, g, b],
        };
        let (l, r) = (px(0.8, 0.1, 0.2), px(0.3, 0.6, 0.4));
        let a = anaglyph(&l, &r, Anaglyph::RedCyan, AnaglyphColors::Color).unwrap();
        assert_eq!(a.data, vec![0.8, 0.6, 0.4]);
        let a = anaglyph(&l, &r, Anaglyph::RedCyan, AnaglyphColors::HalfColor).unwrap();
        assert_eq!(a.data, vec![luma(&l.data), 0.6, 0.4]);
        let a = anaglyph(&l, &r, Anaglyph::RedGreen, AnaglyphColors::Gray).unwrap();
        assert_eq!(a.data, vec![luma(&l.data), luma(&r.data), 0.0]);
    }
}
