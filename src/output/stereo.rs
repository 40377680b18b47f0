//! Stereo layouts (REFERENCE.md "Rotation sequences and stereo"): side by side for
//! parallel viewing, swapped for cross-eyed viewing, or an anaglyph.

use crate::render::Film;
use crate::scene::Anaglyph;

/// `first | gap | second`, the gap filled with `fill` (one value per channel).
pub fn side_by_side(first: &Film, second: &Film, gap: usize, fill: &[f32]) -> Film {
    assert_eq!(
        (first.width, first.height, first.channels),
        (second.width, second.height, second.channels)
    );
    let c = first.channels;
    let w = first.width * 2 + gap;
    let mut out = Film::new(w, first.height, c);
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
    out
}

/// Rec. 709 luma of a display pixel (grey pixels are their own luma).
fn luma(px: &[f32]) -> f32 {
    if px.len() >= 3 {
        0.2126 * px[0] + 0.7152 * px[1] + 0.0722 * px[2]
    } else {
        px[0]
    }
}

/// An anaglyph of two display images: red from the left eye's luminance; green and
/// blue (red-cyan) or green only (red-green) from the right eye's.
pub fn anaglyph(left: &Film, right: &Film, glasses: Anaglyph) -> Film {
    assert_eq!((left.width, left.height), (right.width, right.height));
    let mut out = Film::new(left.width, left.height, 3);
    let l = left.data.chunks_exact(left.channels);
    let r = right.data.chunks_exact(right.channels);
    for ((dst, lp), rp) in out.data.chunks_exact_mut(3).zip(l).zip(r) {
        let (yl, yr) = (luma(lp), luma(rp));
        dst[0] = yl;
        dst[1] = yr;
        dst[2] = match glasses {
            Anaglyph::RedCyan => yr,
            Anaglyph::RedGreen => 0.0,
        };
    }
    out
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
        let s = side_by_side(&film(2, 0.25), &film(2, 0.75), 1, &[0.5]);
        assert_eq!(s.width, 5);
        assert_eq!(&s.data[..5], &[0.25, 0.25, 0.5, 0.75, 0.75]);
    }

    #[test]
    fn anaglyph_channels_come_from_the_right_eyes() {
        let a = anaglyph(&film(1, 0.2), &film(1, 0.9), Anaglyph::RedCyan);
        assert_eq!(&a.data[..3], &[0.2, 0.9, 0.9]);
        let a = anaglyph(&film(1, 0.2), &film(1, 0.9), Anaglyph::RedGreen);
        assert_eq!(&a.data[..3], &[0.2, 0.9, 0.0]);
    }
}
