//! Overlays drawn into written PNG frames (never into NRRD output): `[[label]]` text
//! with placeholders, `[image] scale_bar` (a bar of a round length in world units,
//! orthographic views only) and `[image] colorbar` (the colours of an intensity pass's
//! window, with its values). Drawn on the display film, after the grey window and the
//! colour map, with the font the accuracy plot uses (DejaVu Sans, embedded), so the
//! same scene gives the same bytes on every machine.

use ab_glyph::{point, Font, FontRef, PxScale, ScaleFont};

use crate::label::{short_number, Label};
use crate::render::Film;
use crate::transfer::Colormap;

/// DejaVu Sans (Bitstream Vera licence, `assets/fonts/DejaVuSans.LICENSE`).
pub(crate) static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// The scale bar of one view: world units per pixel and the unit's name.
#[derive(Clone, Debug, PartialEq)]
pub struct ScaleBar {
    /// World units per pixel (orthographic: the view's height over the image's).
    pub pixel_size: f64,
    /// The volume's length unit (`mm`), when its file names one.
    pub unit: Option<String>,
}

impl ScaleBar {
    /// The bar's length in world units: 1, 2 or 5 times a power of ten, the longest
    /// at most a quarter of the image's width; and in whole pixels.
    pub fn length(&self, width: usize) -> (f64, usize) {
        let target = 0.25 * width as f64 * self.pixel_size;
        let p = 10f64.powf(target.log10().floor());
        let l = [5.0, 2.0, 1.0]
            .into_iter()
            .map(|m| m * p)
            .find(|l| *l <= target * (1.0 + 1e-12))
            .unwrap_or(p);
        (l, (l / self.pixel_size).round().max(1.0) as usize)
    }
}

/// The colour bar of an intensity pass: its colours from the top (map at 1) to the
/// bottom (map at 0), with the values shown there.
#[derive(Clone, Debug, PartialEq)]
pub struct Colorbar {
    /// The pass's colour map (`None`: grey).
    pub map: Option<Colormap>,
    /// The value shown at the top of the bar (the map's 1 end).
    pub top: f64,
    /// The value shown at the bottom (the map's 0 end).
    pub bottom: f64,
}

/// Everything drawn over one picture.
#[derive(Clone, Debug, Default)]
pub struct Overlay {
    /// Label texts (placeholders filled in) with their labels.
    pub labels: Vec<(String, Label)>,
    /// The scale bar, if any.
    pub scale_bar: Option<ScaleBar>,
    /// The colour bar, if any.
    pub colorbar: Option<Colorbar>,
}

impl Overlay {
    /// True when nothing is drawn.
    pub fn is_empty(&self) -> bool {
        self.labels.is_empty() && self.scale_bar.is_none() && self.colorbar.is_none()
    }
}

/// The margin between overlays and the picture's edges, in pixels.
pub fn margin(width: usize, height: usize) -> usize {
    ((width.min(height) as f64 * 0.02).round() as usize).max(3)
}

/// The font size of the scale bar's and colour bar's numbers, in pixels.
pub fn small_size(height: usize) -> f32 {
    (height as f32 / 24.0).round().max(10.0)
}

/// The colour bar's rectangle: left, top, width, height in pixels.
pub fn colorbar_rect(width: usize, height: usize) -> (usize, usize, usize, usize) {
    let w = ((width as f64 / 40.0).round() as usize).max(6);
    let h = (height / 2).max(1);
    (
        width.saturating_sub(margin(width, height) + w),
        (height - h) / 2,
        w,
        h,
    )
}

fn is_grey(c: [f32; 3]) -> bool {
    c[0] == c[1] && c[1] == c[2]
}

/// Draws `overlay` on a display film (1 or 3 channels); a grey film becomes RGB when
/// something on it has colour. Text drawn in `ink` (the scale bar, the colour bar's
/// numbers) contrasts with the background.
pub fn draw(
    film: Film,
    overlay: &Overlay,
    background: [f32; 3],
) -> Result<Film, super::AllocError> {
    let coloured = overlay.labels.iter().any(|(_, l)| !is_grey(l.color))
        || overlay
            .colorbar
            .as_ref()
            .is_some_and(|c| c.map.is_some_and(|m| m != Colormap::Grey));
    let mut film = if film.channels == 1 && coloured {
        let mut rgb = super::try_film(film.width, film.height, 3)?;
        for (d, s) in rgb.data.chunks_exact_mut(3).zip(&film.data) {
            d.fill(*s);
        }
        rgb
    } else {
        film
    };
    let font = FontRef::try_from_slice(FONT).expect("the embedded font is a valid TrueType file");
    let (w, h) = (film.width, film.height);
    let m = margin(w, h) as f32;
    let luminance = 0.2126 * background[0] + 0.7152 * background[1] + 0.0722 * background[2];
    let ink = if luminance > 0.5 { [0.0; 3] } else { [1.0; 3] };
    let small = small_size(h);
    // the height the scale bar takes at the bottom left
    let mut bottom_left = 0.0;
    if let Some(sb) = &overlay.scale_bar {
        let (l, px) = sb.length(w);
        let thick = ((h as f64 / 100.0).round() as usize).max(2);
        let (x0, y1) = (m as usize, h.saturating_sub(m as usize));
        fill_rect(&mut film, x0, y1.saturating_sub(thick), px, thick, ink);
        let text = match &sb.unit {
            Some(u) => format!("{} {u}", short_number(l, 6)),
            None => short_number(l, 6),
        };
        let line = line_height(small);
        let top = y1 as f32 - thick as f32 - 2.0 - line;
        draw_text(&mut film, &font, small, &text, m, top, ink);
        bottom_left = thick as f32 + 2.0 + line + m / 2.0;
    }
    if let Some(cb) = &overlay.colorbar {
        let (x0, y0, bw, bh) = colorbar_rect(w, h);
        for r in 0..bh {
            let t = 1.0 - (r as f64 + 0.5) / bh as f64;
            let c = match cb.map {
                Some(map) => map.at(t),
                None => [t as f32; 3],
            };
            fill_rect(&mut film, x0, y0 + r, bw, 1, c);
        }
        let mid = 0.5 * (cb.top + cb.bottom);
        for (v, y) in [(cb.top, y0), (mid, y0 + bh / 2), (cb.bottom, y0 + bh)] {
            let text = value_text(v, (cb.top - cb.bottom).abs());
            let tw = text_width(&font, small, &text);
            let x = x0 as f32 - 4.0 - tw;
            draw_text(
                &mut film,
                &font,
                small,
                &text,
                x,
                y as f32 - small / 2.0,
                ink,
            );
        }
    }
    // labels: stacked per position, in file order
    for (col, row) in (0..3).flat_map(|r| (0..3).map(move |c| (c, r))) {
        let here: Vec<&(String, Label)> = overlay
            .labels
            .iter()
            .filter(|(_, l)| l.position.cell() == (col, row))
            .collect();
        let lines: Vec<(&str, &Label)> = here
            .iter()
            .flat_map(|(t, l)| t.lines().map(move |s| (s, l)))
            .collect();
        let total: f32 = lines.iter().map(|(_, l)| line_height(l.size)).sum();
        let mut y = match row {
            0 => m,
            1 => (h as f32 - total) / 2.0,
            _ if col == 0 => h as f32 - m - total - bottom_left,
            _ => h as f32 - m - total,
        };
        for (text, l) in lines {
            let tw = text_width(&font, l.size, text);
            let x = match col {
                0 => m,
                1 => (w as f32 - tw) / 2.0,
                _ => w as f32 - m - tw,
            };
            draw_text(&mut film, &font, l.size, text, x, y, l.color);
            y += line_height(l.size);
        }
    }
    Ok(film)
}

/// A colour-bar value with about four significant digits of its range.
fn value_text(v: f64, range: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e6 || v.abs() < 1e-3) {
        return format!("{v:.2e}");
    }
    let decimals = if range > 0.0 {
        (3 - range.log10().floor() as i32).clamp(0, 6) as usize
    } else {
        3
    };
    short_number(v, decimals)
}

fn line_height(size: f32) -> f32 {
    (size * 1.2).ceil()
}

/// Sets the pixels of a rectangle (clipped to the film) to `c`.
fn fill_rect(film: &mut Film, x0: usize, y0: usize, w: usize, h: usize, c: [f32; 3]) {
    let ch = film.channels;
    for y in y0..(y0 + h).min(film.height) {
        for x in x0..(x0 + w).min(film.width) {
            let k = (y * film.width + x) * ch;
            film.data[k..k + ch].copy_from_slice(&c[..ch]);
        }
    }
}

/// The advance width of `text` at `size` pixels.
pub fn text_width(font: &FontRef, size: f32, text: &str) -> f32 {
    let sf = font.as_scaled(PxScale::from(size));
    let mut width = 0.0;
    let mut prev = None;
    for c in text.chars() {
        let id = sf.glyph_id(c);
        if let Some(p) = prev {
            width += sf.kern(p, id);
        }
        width += sf.h_advance(id);
        prev = Some(id);
    }
    width
}

/// Draws one line of text with its top-left corner at `(x, y)`, blending `color` by
/// each pixel's coverage.
fn draw_text(
    film: &mut Film,
    font: &FontRef,
    size: f32,
    text: &str,
    x: f32,
    y: f32,
    color: [f32; 3],
) {
    let scale = PxScale::from(size);
    let sf = font.as_scaled(scale);
    let baseline = y + sf.ascent();
    let mut caret = x;
    let mut prev = None;
    let (fw, fh, ch) = (film.width as i64, film.height as i64, film.channels);
    for c in text.chars() {
        let id = sf.glyph_id(c);
        if let Some(p) = prev {
            caret += sf.kern(p, id);
        }
        let glyph = id.with_scale_and_position(scale, point(caret, baseline));
        caret += sf.h_advance(id);
        prev = Some(id);
        let Some(outline) = font.outline_glyph(glyph) else {
            continue;
        };
        let b = outline.px_bounds();
        outline.draw(|gx, gy, cov| {
            let (px, py) = (b.min.x as i64 + gx as i64, b.min.y as i64 + gy as i64);
            if px < 0 || py < 0 || px >= fw || py >= fh || cov <= 0.0 {
                return;
            }
            let k = (py as usize * film.width + px as usize) * ch;
            let a = cov.min(1.0);
            for (d, c) in film.data[k..k + ch].iter_mut().zip(color) {
                *d = *d * (1.0 - a) + c * a;
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scale_bar_lengths_are_round() {
        let sb = ScaleBar {
            pixel_size: 0.8,
            unit: None,
        };
        // a quarter of 256 px is 51.2 world units: 50, 62.5 px
        assert_eq!(sb.length(256), (50.0, 63));
        let sb = ScaleBar {
            pixel_size: 2.0 * 3f64.sqrt() / 200.0,
            unit: None,
        };
        // a quarter of 200 px is 0.866: 0.5
        assert_eq!(sb.length(200).0, 0.5);
    }

    #[test]
    fn numbers_are_short() {
        assert_eq!(value_text(0.25, 1.0), "0.25");
        assert_eq!(value_text(1150.0, 3000.0), "1150");
    }
}
