//! The speed-against-error plot of the accuracy bench: one panel per render mode,
//! time per view (log) against RMS error (log), one line per method and
//! reconstruction joining its steps. Drawn with plotters into a memory buffer (no
//! system font libraries: the label font is embedded, `assets/fonts/README.md`) and
//! encoded as PNG by the `image` crate.

use std::collections::BTreeMap;

use plotters::prelude::*;

use super::{BenchError, Report, Row};

use crate::output::plotting;

const WIDTH: u32 = 1600;
const HEIGHT: u32 = 900;
/// Errors below this are drawn at it (a log axis has no zero).
const ERROR_FLOOR: f64 = 1e-9;

fn plot_err(e: impl std::fmt::Display) -> BenchError {
    BenchError::Plot(e.to_string())
}

/// The field each panel shows: the Marschner-Lobb signal for every mode (the
/// standard hard case), and the sphere with the narrow transfer function for
/// compositing (where pre-integration matters); the first field of a quick run
/// otherwise.
fn panel_rows<'a>(r: &'a Report, mode: &str) -> (String, Vec<&'a Row>) {
    let has = |f: &str| r.rows.iter().any(|x| x.field == f && x.mode == mode);
    let (field, tf) = if mode == "composite" {
        (if has("sphere") { "sphere" } else { "" }, Some("narrow"))
    } else {
        (
            if has("marschner-lobb") {
                "marschner-lobb"
            } else {
                ""
            },
            None,
        )
    };
    let field = if field.is_empty() {
        r.rows
            .iter()
            .find(|x| x.mode == mode)
            .map_or(String::new(), |x| x.field.clone())
    } else {
        field.to_string()
    };
    let rows = r
        .rows
        .iter()
        .filter(|x| {
            x.mode == mode && x.field == field && (tf.is_none() || x.transfer.as_deref() == tf)
        })
        .collect();
    let title = match tf {
        Some(t) => format!("{mode}, {field}, transfer {t}"),
        None => format!("{mode}, {field}"),
    };
    (title, rows)
}

/// Tick values of a log axis over `[lo, hi]` (`0 < lo < hi`): the powers of ten
/// inside it, with 2 and 5 times them when that gives fewer than three, and every
/// integer multiple when still fewer (a panel whose errors span less than a decade
/// showed no tick label at all with plotters' own choice, powers of ten only).
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let inside = |mantissas: &[f64]| -> Vec<f64> {
        let (e0, e1) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
        (e0..=e1)
            .flat_map(|e| mantissas.iter().map(move |m| m * 10f64.powi(e)))
            .filter(|y| (lo..=hi).contains(y))
            .collect()
    };
    for mantissas in [
        &[1.0][..],
        &[1.0, 2.0, 5.0],
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
    ] {
        let ticks = inside(mantissas);
        if ticks.len() >= 3 || mantissas.len() == 9 {
            return ticks;
        }
    }
    unreachable!("the last set of mantissas returns")
}

/// The legend entry of a row: method, interpolation and gradient estimator.
fn series_label(r: &Row) -> String {
    match &r.gradient {
        Some(g) => format!("{} {} {}", r.method, r.interpolation, g),
        None => format!("{} {}", r.method, r.interpolation),
    }
}

/// Draws the plot and returns the PNG bytes.
pub fn speed_vs_error(report: &Report) -> Result<Vec<u8>, BenchError> {
    plotting::register_font().map_err(BenchError::Plot)?;
    let mut buf = vec![255u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let root = root
            .titled(
                "volcast: RMS error against time per view (lines join steps 2 .. 0.125 voxels)",
                ("sans-serif", 22),
            )
            .map_err(plot_err)?;
        let modes = crate::mode::names();
        let mut labels: Vec<String> = report.rows.iter().map(series_label).collect();
        labels.sort();
        labels.dedup();
        for (area, mode) in root.split_evenly((2, 4)).iter().zip(modes) {
            let (title, rows) = panel_rows(report, mode);
            if rows.is_empty() {
                continue;
            }
            // one series per (method, interpolation, gradient), ordered by step
            let mut series: BTreeMap<String, Vec<(f64, f64, f64)>> = BTreeMap::new();
            for r in &rows {
                let label = series_label(r);
                series.entry(label).or_default().push((
                    r.step_voxels.unwrap_or(0.0),
                    r.ms_per_frame.max(1e-6),
                    r.rms_error.max(ERROR_FLOOR),
                ));
            }
            let xs = rows.iter().map(|r| r.ms_per_frame.max(1e-6));
            let ys = rows.iter().map(|r| r.rms_error.max(ERROR_FLOOR));
            let (x0, x1) = xs.fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(x), b.max(x)));
            let (y0, y1) = ys.fold((f64::MAX, f64::MIN), |(a, b), y| (a.min(y), b.max(y)));
            let mut chart = ChartBuilder::on(area)
                .caption(title, ("sans-serif", 16))
                .margin(8)
                .x_label_area_size(34)
                .y_label_area_size(58)
                .build_cartesian_2d(
                    (x0 / 1.3..x1 * 1.3).log_scale(),
                    (y0 / 2.0..y1 * 2.0)
                        .log_scale()
                        .with_key_points(log_ticks(y0 / 2.0, y1 * 2.0)),
                )
                .map_err(plot_err)?;
            chart
                .configure_mesh()
                .x_desc("ms per view")
                .y_desc("RMS error")
                .label_style(("sans-serif", 11))
                .x_labels(5)
                .y_labels(6)
                .y_label_formatter(&|y| format!("{y:.1e}").replace(".0e", "e"))
                .x_label_formatter(&|x| format!("{x:.2}"))
                .draw()
                .map_err(plot_err)?;
            for (label, mut pts) in series {
                pts.sort_by(|a, b| b.0.total_cmp(&a.0));
                // the same colour for the same method in every panel
                let k = labels.iter().position(|l| *l == label).unwrap_or(0);
                let color = Palette99::pick(k).to_rgba();
                let line: Vec<(f64, f64)> = pts.iter().map(|p| (p.1, p.2)).collect();
                chart
                    .draw_series(LineSeries::new(line.clone(), color.stroke_width(2)))
                    .map_err(plot_err)?
                    .label(label)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 14, y)], color.stroke_width(2))
                    });
                chart
                    .draw_series(line.into_iter().map(|p| Circle::new(p, 3, color.filled())))
                    .map_err(plot_err)?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.3))
                .label_font(("sans-serif", 10))
                .position(SeriesLabelPosition::UpperRight)
                .draw()
                .map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    plotting::encode_rgb_png(WIDTH, HEIGHT, buf).map_err(BenchError::Plot)
}

#[cfg(test)]
mod tests {
    use super::log_ticks;

    #[test]
    fn every_log_axis_gets_tick_labels() {
        // wide: powers of ten only
        assert_eq!(log_ticks(5e-5, 2e-2), vec![1e-4, 1e-3, 1e-2]);
        // the panels that had none: less than a decade (lmip, depth, surface)
        let t = log_ticks(0.011, 0.045);
        assert!(t.len() >= 3, "{t:?}");
        assert!(t.iter().all(|y| (0.011..=0.045).contains(y)), "{t:?}");
        assert_eq!(log_ticks(0.0015, 0.012), vec![2e-3, 5e-3, 1e-2]);
        // a factor of 4 (2x either side of one value) still gets two labels
        assert!(log_ticks(0.0305, 0.122).len() >= 2);
    }
}
