//! The histograms as PNG plots: the value histogram (bars on a log axis of voxel
//! counts) and the 2D histogram (value x gradient magnitude, log counts through
//! viridis, with a colour bar), with a scene's [`Overlays`] drawn over them.
//!
//! plotters draws the frame, the ticks and the axis labels (the embedded font, no
//! system font library); the bars, the cells and the overlays are then drawn by
//! pixel through [`PlotArea`], the map from data to pixels each plot returns, so a
//! caller (a test) can tell where a value lies in the image.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::{Curve1D, Histograms, Overlays, WidgetBox};
use crate::label::short_number;
use crate::output::plotting;
use crate::transfer::{Colormap, WidgetShape};

/// Width of both plots, in pixels.
pub const WIDTH: u32 = 1000;
/// Height of the value histogram.
pub const HEIGHT_1D: u32 = 560;
/// Height of the 2D histogram.
pub const HEIGHT_2D: u32 = 720;

/// The colour of the value histogram's bars.
const BAR: [u8; 3] = [96, 112, 140];
/// Colours of the scene's passes, in order (matplotlib's tab10).
const PASS_COLORS: [RGBColor; 8] = [
    RGBColor(214, 39, 40),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];
/// The window's lines.
const WINDOW: RGBColor = RGBColor(60, 60, 60);

/// A plot could not be drawn or encoded.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("drawing the histogram plot: {0}")]
pub struct PlotError(pub String);

fn plot_err(e: impl std::fmt::Display) -> PlotError {
    PlotError(e.to_string())
}

/// The map from data to pixels of a plot's data area.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlotArea {
    /// The leftmost and rightmost pixel columns of the data area.
    pub columns: [i32; 2],
    /// The top and bottom pixel rows.
    pub rows: [i32; 2],
    /// The value axis `[low, high]` (data units), at the left and right columns.
    pub value: [f64; 2],
    /// The vertical axis `[bottom, top]`: voxel counts (log) on the value
    /// histogram, gradient magnitudes on the 2D histogram.
    pub vertical: [f64; 2],
    /// Whether the vertical axis is logarithmic.
    pub log: bool,
}

impl PlotArea {
    /// The pixel column of data value `v` (outside the area if `v` is off the axis).
    pub fn column(&self, v: f64) -> i32 {
        self.x_of(v).round() as i32
    }

    /// The pixel row of vertical coordinate `y`.
    pub fn row(&self, y: f64) -> i32 {
        self.y_of(y).round() as i32
    }

    fn x_of(&self, v: f64) -> f64 {
        let ([a, b], [lo, hi]) = (self.columns, self.value);
        f64::from(a) + (v - lo) / (hi - lo) * f64::from(b - a)
    }

    fn y_of(&self, y: f64) -> f64 {
        let ([top, bottom], [lo, hi]) = (self.rows, self.vertical);
        let f = if self.log {
            (y / lo).ln() / (hi / lo).ln()
        } else {
            (y - lo) / (hi - lo)
        };
        f64::from(bottom) - f * f64::from(bottom - top)
    }

    /// The data value at the centre of pixel column `x`.
    fn value_at(&self, x: i32) -> f64 {
        let ([a, b], [lo, hi]) = (self.columns, self.value);
        lo + f64::from(x - a) / f64::from((b - a).max(1)) * (hi - lo)
    }

    /// The vertical coordinate at the centre of pixel row `y`.
    fn vertical_at(&self, y: i32) -> f64 {
        let ([top, bottom], [lo, hi]) = (self.rows, self.vertical);
        let f = f64::from(bottom - y) / f64::from((bottom - top).max(1));
        if self.log {
            lo * (hi / lo).powf(f)
        } else {
            lo + f * (hi - lo)
        }
    }

    fn inside_columns(&self, x: i32) -> bool {
        (self.columns[0]..=self.columns[1]).contains(&x)
    }
}

/// A drawn plot.
#[derive(Clone, Debug)]
pub struct Plot {
    /// The PNG file.
    pub png: Vec<u8>,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Where the data lies in the image.
    pub area: PlotArea,
}

/// An RGB buffer and its size.
struct Canvas {
    rgb: Vec<u8>,
    width: u32,
    height: u32,
}

impl Canvas {
    fn new(width: u32, height: u32) -> Canvas {
        Canvas {
            rgb: vec![255; (width * height * 3) as usize],
            width,
            height,
        }
    }

    fn set(&mut self, x: i32, y: i32, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as u32) < self.width && (y as u32) < self.height {
            let i = 3 * (y as usize * self.width as usize + x as usize);
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    /// Draws with plotters over what the buffer holds.
    fn draw<R>(
        &mut self,
        f: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Result<R, PlotError>,
    ) -> Result<R, PlotError> {
        let root = BitMapBackend::with_buffer(&mut self.rgb, (self.width, self.height))
            .into_drawing_area();
        let r = f(&root)?;
        root.present().map_err(plot_err)?;
        Ok(r)
    }

    fn finish(self, area: PlotArea) -> Result<Plot, PlotError> {
        let (width, height) = (self.width, self.height);
        Ok(Plot {
            png: plotting::encode_rgb_png(width, height, self.rgb).map_err(PlotError)?,
            width,
            height,
            area,
        })
    }
}

/// A number as the plots and messages show it: up to 4 decimals, or scientific
/// notation (4 significant digits) for tiny and huge numbers.
pub fn number(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || (1e-3..1e6).contains(&a) {
        short_number(x, 4)
    } else {
        format!("{x:.3e}")
    }
}

/// A tick label.
fn tick(x: &f64) -> String {
    number(*x)
}

/// A count label on a log axis.
fn count_tick(y: &f64) -> String {
    if *y >= 1.0 {
        format!("{y:.0}")
    } else {
        short_number(*y, 2)
    }
}

/// An error unless both axes of `h` are finite, non-empty ranges (plotters cannot
/// place ticks on others).
fn check_axes(h: &Histograms) -> Result<(), PlotError> {
    for (name, [lo, hi]) in [("value", h.value_range), ("gradient", h.gradient_range)] {
        if !((hi - lo).is_finite() && hi > lo) {
            return Err(PlotError(format!(
                "the {name} axis [{lo}, {hi}] is not a finite, non-empty range"
            )));
        }
    }
    Ok(())
}

/// The value histogram of `h`, with the window, iso values, thresholds and 1D
/// transfer functions of `overlays`, under `title`.
pub fn value_plot(h: &Histograms, overlays: &Overlays, title: &str) -> Result<Plot, PlotError> {
    check_axes(h)?;
    plotting::register_font().map_err(PlotError)?;
    let mut canvas = Canvas::new(WIDTH, HEIGHT_1D);
    let most = h.counts.iter().copied().max().unwrap_or(0).max(1);
    let vertical = [0.5, most as f64 * 2.0];
    let curves = !overlays.curves.is_empty();
    let area = canvas.draw(|root| {
        let mut chart = ChartBuilder::on(root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .margin_right(if curves { 64 } else { 24 })
            .x_label_area_size(48)
            .y_label_area_size(76)
            .build_cartesian_2d(
                h.value_range[0]..h.value_range[1],
                (vertical[0]..vertical[1]).log_scale(),
            )
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("value (data units)")
            .y_desc("voxels per bin (log scale)")
            .label_style(("sans-serif", 13))
            .axis_desc_style(("sans-serif", 15))
            .x_labels(10)
            .x_label_formatter(&tick)
            .y_label_formatter(&count_tick)
            .draw()
            .map_err(plot_err)?;
        Ok(area_of(&chart, h.value_range, vertical, true))
    })?;
    for x in area.columns[0]..=area.columns[1] {
        let c = h.counts[h.value_bin(area.value_at(x))];
        if c > 0 {
            let top = area.row(c as f64).max(area.rows[0]);
            for y in top..=area.rows[1] {
                canvas.set(x, y, BAR);
            }
        }
    }
    let mut colors = PASS_COLORS.iter().copied().cycle();
    canvas.draw(|root| {
        draw_window_and_markers(root, &area, overlays, &mut colors)?;
        if curves {
            draw_opacity_axis(root, &area)?;
        }
        for (k, c) in overlays.curves.iter().enumerate() {
            let color = colors.next().unwrap_or(BLACK);
            draw_curve(root, &area, c, color, k)?;
        }
        Ok(())
    })?;
    canvas.finish(area)
}

/// The 2D histogram of `h`, with the window, iso values, thresholds, 2D
/// transfer-function widgets and their `gradient_max` of `overlays`, under `title`.
pub fn gradient_plot(h: &Histograms, overlays: &Overlays, title: &str) -> Result<Plot, PlotError> {
    check_axes(h)?;
    plotting::register_font().map_err(PlotError)?;
    let mut canvas = Canvas::new(WIDTH, HEIGHT_2D);
    let most = h.counts_2d.iter().copied().max().unwrap_or(0).max(1);
    let scale = [1.0, (most as f64).max(2.0)];
    let (area, bar) = canvas.draw(|root| {
        let root = root.titled(title, ("sans-serif", 18)).map_err(plot_err)?;
        let (main, side) = root.split_horizontally(WIDTH - 150);
        let mut chart = ChartBuilder::on(&main)
            .margin(12)
            .x_label_area_size(48)
            .y_label_area_size(76)
            .build_cartesian_2d(
                h.value_range[0]..h.value_range[1],
                h.gradient_range[0]..h.gradient_range[1],
            )
            .map_err(plot_err)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("value (data units)")
            .y_desc("gradient magnitude (normalised value per voxel)")
            .label_style(("sans-serif", 13))
            .axis_desc_style(("sans-serif", 15))
            .x_labels(10)
            .x_label_formatter(&tick)
            .y_label_formatter(&tick)
            .draw()
            .map_err(plot_err)?;
        let area = area_of(&chart, h.value_range, h.gradient_range, false);
        let mut colorbar = ChartBuilder::on(&side)
            .margin(12)
            .margin_left(8)
            .x_label_area_size(48)
            .y_label_area_size(0)
            .right_y_label_area_size(70)
            .build_cartesian_2d(0.0..1.0, (scale[0]..scale[1]).log_scale())
            .map_err(plot_err)?;
        colorbar
            .configure_mesh()
            .disable_mesh()
            .disable_x_axis()
            .y_desc("voxels per cell (log scale)")
            .label_style(("sans-serif", 13))
            .axis_desc_style(("sans-serif", 15))
            .y_label_formatter(&count_tick)
            .draw()
            .map_err(plot_err)?;
        let bar = area_of(&colorbar, [0.0, 1.0], scale, true);
        Ok((area, bar))
    })?;
    let shade = |c: f64| -> [u8; 3] {
        let t = c.ln() / scale[1].ln();
        Colormap::Viridis.at(t).map(|x| (x * 255.0).round() as u8)
    };
    for y in area.rows[0]..=area.rows[1] {
        let j = h.gradient_bin(area.vertical_at(y));
        for x in area.columns[0]..=area.columns[1] {
            let c = h.count_2d(h.value_bin(area.value_at(x)), j);
            if c > 0 {
                canvas.set(x, y, shade(c as f64));
            }
        }
    }
    for y in bar.rows[0]..=bar.rows[1] {
        let color = shade(bar.vertical_at(y));
        for x in bar.columns[0]..=bar.columns[1] {
            canvas.set(x, y, color);
        }
    }
    let mut colors = PASS_COLORS.iter().copied().cycle();
    canvas.draw(|root| {
        draw_window_and_markers(root, &area, overlays, &mut colors)?;
        for m in &overlays.gradient_max {
            let y = area.y_of(m.at);
            if y >= f64::from(area.rows[0]) && y <= f64::from(area.rows[1]) {
                let (a, b) = (f64::from(area.columns[0]), f64::from(area.columns[1]));
                draw_segment(root, &area, (a, y), (b, y), WHITE, 2, true)?;
                label(
                    root,
                    &m.label,
                    (area.columns[1] - 4, y.round() as i32 - 3),
                    Pos::new(HPos::Right, VPos::Bottom),
                    BLACK,
                )?;
            }
        }
        for w in &overlays.widgets {
            draw_widget(root, &area, w)?;
        }
        Ok(())
    })?;
    canvas.finish(area)
}

/// The data area of a chart and its axes.
fn area_of<X: plotters::coord::ranged1d::Ranged, Y: plotters::coord::ranged1d::Ranged>(
    chart: &ChartContext<'_, BitMapBackend<'_>, Cartesian2d<X, Y>>,
    value: [f64; 2],
    vertical: [f64; 2],
    log: bool,
) -> PlotArea {
    let (xs, ys) = chart.plotting_area().get_pixel_range();
    PlotArea {
        columns: [xs.start, xs.end - 1],
        rows: [ys.start, ys.end - 1],
        value,
        vertical,
        log,
    }
}

type Root<'a, 'b> = DrawingArea<BitMapBackend<'b>, Shift>;

/// Text on a white box, anchored at `at`.
fn label(
    root: &Root,
    text: &str,
    at: (i32, i32),
    pos: Pos,
    color: RGBColor,
) -> Result<(), PlotError> {
    let style = TextStyle::from(("sans-serif", 13).into_font())
        .color(&color)
        .pos(pos);
    let (w, h) = root.estimate_text_size(text, &style).map_err(plot_err)?;
    let (w, h) = (w as i32, h as i32);
    let x0 = match pos.h_pos {
        HPos::Left => at.0,
        HPos::Center => at.0 - w / 2,
        HPos::Right => at.0 - w,
    };
    let y0 = match pos.v_pos {
        VPos::Top => at.1,
        VPos::Center => at.1 - h / 2,
        VPos::Bottom => at.1 - h,
    };
    root.draw(&Rectangle::new(
        [(x0 - 2, y0 - 1), (x0 + w + 2, y0 + h + 1)],
        WHITE.mix(0.8).filled(),
    ))
    .map_err(plot_err)?;
    root.draw(&Text::new(text.to_string(), at, style))
        .map_err(plot_err)
}

/// The segment from `a` to `b` (pixel coordinates) clipped to the data area
/// (Liang-Barsky), if any of it is inside.
fn clip(area: &PlotArea, a: (f64, f64), b: (f64, f64)) -> Option<((i32, i32), (i32, i32))> {
    if ![a.0, a.1, b.0, b.1].iter().all(|v| v.is_finite()) {
        return None;
    }
    let (x0, x1) = (f64::from(area.columns[0]), f64::from(area.columns[1]));
    let (y0, y1) = (f64::from(area.rows[0]), f64::from(area.rows[1]));
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-dx, a.0 - x0),
        (dx, x1 - a.0),
        (-dy, a.1 - y0),
        (dy, y1 - a.1),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                t0 = t0.max(r);
            } else {
                t1 = t1.min(r);
            }
        }
    }
    if t0 > t1 {
        return None;
    }
    let at = |t: f64| ((a.0 + t * dx).round() as i32, (a.1 + t * dy).round() as i32);
    Some((at(t0), at(t1)))
}

/// A line from `a` to `b` (pixel coordinates, clipped to the area), over a black
/// halo when `halo`, dashed when `dashed`.
fn draw_segment(
    root: &Root,
    area: &PlotArea,
    a: (f64, f64),
    b: (f64, f64),
    color: RGBColor,
    width: u32,
    dashed: bool,
) -> Result<(), PlotError> {
    let Some((p, q)) = clip(area, a, b) else {
        return Ok(());
    };
    let pieces: Vec<((i32, i32), (i32, i32))> = if dashed {
        let (dx, dy) = (f64::from(q.0 - p.0), f64::from(q.1 - p.1));
        let len = dx.hypot(dy);
        let (on, period) = (8.0, 13.0);
        let at = |s: f64| {
            let t = (s / len.max(1e-9)).min(1.0);
            (p.0 + (t * dx).round() as i32, p.1 + (t * dy).round() as i32)
        };
        (0..)
            .map(|k| f64::from(k) * period)
            .take_while(|s| *s < len)
            .map(|s| (at(s), at(s + on)))
            .collect()
    } else {
        vec![(p, q)]
    };
    for (p, q) in pieces {
        root.draw(&PathElement::new(vec![p, q], color.stroke_width(width)))
            .map_err(plot_err)?;
    }
    Ok(())
}

/// The window: the values outside it shaded, its ends dashed and labelled.
fn draw_window(root: &Root, area: &PlotArea, overlays: &Overlays) -> Result<(), PlotError> {
    let Some([lo, hi]) = overlays.window else {
        return Ok(());
    };
    let [top, bottom] = area.rows;
    let [left, right] = area.columns;
    let (a, b) = (
        area.column(lo).clamp(left, right),
        area.column(hi).clamp(left, right),
    );
    for (x0, x1) in [(left, a), (b, right)] {
        if x1 > x0 {
            root.draw(&Rectangle::new(
                [(x0, top), (x1, bottom)],
                BLACK.mix(0.12).filled(),
            ))
            .map_err(plot_err)?;
        }
    }
    for (v, name, h, dx) in [
        (lo, "window low", HPos::Left, 4),
        (hi, "window high", HPos::Right, -4),
    ] {
        let x = area.column(v);
        if area.inside_columns(x) {
            let (xf, t, bt) = (f64::from(x), f64::from(top), f64::from(bottom));
            draw_segment(root, area, (xf, t), (xf, bt), WINDOW, 2, true)?;
            label(
                root,
                &format!("{name} {}", tick(&v)),
                (x + dx, bottom - 4 - 10 * overlays.curves.len() as i32),
                Pos::new(h, VPos::Bottom),
                WINDOW,
            )?;
        }
    }
    Ok(())
}

/// The window and the markers (iso values and thresholds), each marker in the
/// next of `colors`.
fn draw_window_and_markers(
    root: &Root,
    area: &PlotArea,
    overlays: &Overlays,
    colors: &mut impl Iterator<Item = RGBColor>,
) -> Result<(), PlotError> {
    draw_window(root, area, overlays)?;
    let mut stagger = 0;
    for m in &overlays.markers {
        let color = colors.next().unwrap_or(BLACK);
        draw_marker(root, area, &m.label, m.at, color, &mut stagger)?;
    }
    Ok(())
}

/// An iso value or threshold: a vertical line with its label near the top
/// (successive labels are staggered so they do not overlap).
fn draw_marker(
    root: &Root,
    area: &PlotArea,
    text: &str,
    at: f64,
    color: RGBColor,
    stagger: &mut i32,
) -> Result<(), PlotError> {
    let x = area.column(at);
    if !area.inside_columns(x) {
        return Ok(());
    }
    let [top, bottom] = area.rows;
    root.draw(&PathElement::new(
        vec![(x, top), (x, bottom)],
        color.stroke_width(2),
    ))
    .map_err(plot_err)?;
    let right_half = x > (area.columns[0] + area.columns[1]) / 2;
    let (h, dx) = if right_half {
        (HPos::Right, -4)
    } else {
        (HPos::Left, 4)
    };
    let y = top + 4 + 18 * (*stagger % 5);
    *stagger += 1;
    label(root, text, (x + dx, y), Pos::new(h, VPos::Top), color)
}

/// The opacity axis of the 1D transfer functions, on the right of the data area.
fn draw_opacity_axis(root: &Root, area: &PlotArea) -> Result<(), PlotError> {
    let [top, bottom] = area.rows;
    let x = area.columns[1] + 1;
    root.draw(&PathElement::new(vec![(x, top), (x, bottom)], BLACK))
        .map_err(plot_err)?;
    let opacity_row = |a: f64| bottom - (a * f64::from(bottom - top)).round() as i32;
    for a in [0.0, 0.25, 0.5, 0.75, 1.0] {
        let y = opacity_row(a);
        root.draw(&PathElement::new(vec![(x, y), (x + 5, y)], BLACK))
            .map_err(plot_err)?;
        let style =
            TextStyle::from(("sans-serif", 13).into_font()).pos(Pos::new(HPos::Left, VPos::Center));
        root.draw(&Text::new(short_number(a, 2), (x + 8, y), style))
            .map_err(plot_err)?;
    }
    let style = TextStyle::from(
        ("sans-serif", 15)
            .into_font()
            .transform(FontTransform::Rotate90),
    )
    .pos(Pos::new(HPos::Center, VPos::Center));
    root.draw(&Text::new(
        "transfer-function opacity",
        (x + 46, (top + bottom) / 2),
        style,
    ))
    .map_err(plot_err)
}

/// A 1D transfer function: its opacity as a curve against the opacity axis (0 at
/// the bottom, 1 at the top), its colour as a strip along the bottom (the `k`-th
/// function's strip above the others'), and its label at the top right.
fn draw_curve(
    root: &Root,
    area: &PlotArea,
    c: &Curve1D,
    color: RGBColor,
    k: usize,
) -> Result<(), PlotError> {
    let [top, bottom] = area.rows;
    let strip = 10;
    let (s1, s0) = (
        bottom - strip * k as i32,
        bottom - strip * (k as i32 + 1) + 1,
    );
    let mut line = Vec::new();
    for x in area.columns[0]..=area.columns[1] {
        let (rgb, a) = c.at(area.value_at(x));
        let rgb = RGBColor(
            (rgb[0] * 255.0).round() as u8,
            (rgb[1] * 255.0).round() as u8,
            (rgb[2] * 255.0).round() as u8,
        );
        root.draw(&PathElement::new(vec![(x, s0), (x, s1)], rgb))
            .map_err(plot_err)?;
        line.push((
            x,
            bottom - (f64::from(a) * f64::from(bottom - top)).round() as i32,
        ));
    }
    root.draw(&PathElement::new(line, color.stroke_width(2)))
        .map_err(plot_err)?;
    let y = top + 4 + 18 * k as i32;
    let x = area.columns[1] - 4;
    label(
        root,
        &format!("{} (opacity, colour strip)", c.label),
        (x, y),
        Pos::new(HPos::Right, VPos::Top),
        color,
    )
}

/// A 2D transfer-function widget: a rectangle's outline; a Gaussian's box dashed
/// and its `alpha / e` contour (the ellipse inscribed in the box) solid; over a
/// black halo, in the widget's colour, labelled at its top left corner.
fn draw_widget(root: &Root, area: &PlotArea, w: &WidgetBox) -> Result<(), PlotError> {
    let (x0, x1) = (area.x_of(w.value[0]), area.x_of(w.value[1]));
    // the renderer clamps gradients to its range: cap the box at the axis
    let top_g = w.gradient[1].min(area.vertical[1] * 4.0);
    let (y0, y1) = (area.y_of(w.gradient[0]), area.y_of(top_g));
    let color = RGBColor(
        (w.color[0] * 255.0).round() as u8,
        (w.color[1] * 255.0).round() as u8,
        (w.color[2] * 255.0).round() as u8,
    );
    let corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)];
    let dashed = w.shape == WidgetShape::Gaussian;
    for (c, width) in [(BLACK, 4), (color, 2)] {
        for e in 0..4 {
            draw_segment(
                root,
                area,
                corners[e],
                corners[(e + 1) % 4],
                c,
                width,
                dashed,
            )?;
        }
        if dashed {
            let (cx, cy, rx, ry) = (
                (x0 + x1) / 2.0,
                (y0 + y1) / 2.0,
                (x1 - x0) / 2.0,
                (y1 - y0) / 2.0,
            );
            let n = 96;
            let p = |i: usize| {
                let t = std::f64::consts::TAU * i as f64 / n as f64;
                (cx + rx * t.cos(), cy + ry * t.sin())
            };
            for i in 0..n {
                draw_segment(root, area, p(i), p(i + 1), c, width, false)?;
            }
        }
    }
    let lx = x0.max(f64::from(area.columns[0])).round() as i32 + 3;
    let ly = y1.max(f64::from(area.rows[0])).round() as i32 + 3;
    if area.inside_columns(lx) && ly < area.rows[1] {
        let text = format!(
            "{} (alpha {})",
            w.label,
            short_number(f64::from(w.alpha), 2)
        );
        label(
            root,
            &text,
            (lx, ly),
            Pos::new(HPos::Left, VPos::Top),
            BLACK,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area() -> PlotArea {
        PlotArea {
            columns: [100, 900],
            rows: [50, 450],
            value: [0.0, 8.0],
            vertical: [0.0, 4.0],
            log: false,
        }
    }

    #[test]
    fn the_pixel_map_and_its_inverse_agree() {
        let a = area();
        assert_eq!(a.column(0.0), 100);
        assert_eq!(a.column(8.0), 900);
        assert_eq!(a.column(2.0), 300);
        assert_eq!(a.row(0.0), 450);
        assert_eq!(a.row(4.0), 50);
        assert_eq!(a.row(1.0), 350);
        for x in [100, 317, 900] {
            assert_eq!(a.column(a.value_at(x)), x);
        }
        for y in [50, 123, 450] {
            assert_eq!(a.row(a.vertical_at(y)), y);
        }
        let log = PlotArea {
            vertical: [1.0, 1000.0],
            log: true,
            ..a
        };
        assert_eq!(log.row(10.0), 450 - 133);
        assert_eq!(log.row(log.vertical_at(200)), 200);
    }

    #[test]
    fn segments_are_clipped_to_the_area() {
        let a = area();
        // inside: unchanged
        assert_eq!(
            clip(&a, (200.0, 100.0), (300.0, 200.0)),
            Some(((200, 100), (300, 200)))
        );
        // a horizontal line far beyond both sides: cut at the columns
        assert_eq!(
            clip(&a, (-1e9, 200.0), (1e9, 200.0)),
            Some(((100, 200), (900, 200)))
        );
        // entirely outside
        assert_eq!(clip(&a, (0.0, 0.0), (50.0, 40.0)), None);
        assert_eq!(clip(&a, (f64::NAN, 0.0), (50.0, 40.0)), None);
    }
}
