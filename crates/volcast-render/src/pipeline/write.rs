//! Laying out, encoding and writing the images of one (pass, frame).

use std::path::PathBuf;

use super::FrameViews;
use crate::error::Error;
use crate::label::FrameInfo;
use crate::output::display::{to_display, DisplayKind};
use crate::output::manifest::{self, FileRecord};
use crate::output::overlay::{self, Colorbar, Overlay, ScaleBar};
use crate::output::{encode, frame_path, stereo};
use crate::plan::Plan;
use crate::render::{Film, ImageKind, View};
use crate::scene::{AnaglyphColors, Format, Layout, Projection};
use crate::views::Eye;

/// The images of one (pass, frame) as its files store them, in file order: one per
/// eye of a `pair` (or mono) frame, else the eyes laid out in one; display colours
/// in [0, 1] with the overlays drawn for PNG formats ([`encode::sample8`] and
/// [`encode::sample16`] quantise them), the raw values for NRRD.
pub(super) fn frame_images<'a>(
    plan: &Plan,
    fv: &FrameViews<'a>,
) -> Result<Vec<(Eye, std::borrow::Cow<'a, Film>)>, Error> {
    let (p, k, window) = (fv.pass, fv.frame, fv.window);
    let outputs = &plan.output;
    let pass = &outputs.passes[p];
    let format = outputs.format;
    let bg = outputs.background;
    let display_kind = match (plan.passes[p].kind(), window) {
        (ImageKind::Depth, Some(w)) => DisplayKind::Depth(w, pass.colormap),
        (_, Some(w)) => DisplayKind::Intensity(w, pass.colormap),
        _ => DisplayKind::Rgba,
    };
    // Films in the form the format stores: raw values for NRRD, display colours for PNG
    // (with the overlays drawn over them).
    let stored: Vec<(Eye, std::borrow::Cow<Film>)> = fv
        .eyes
        .iter()
        .map(|e| match format {
            Format::Nrrd => Ok((e.eye, std::borrow::Cow::Borrowed(e.film))),
            _ => to_display(e.film, display_kind, bg)
                .and_then(|f| {
                    let o = frame_overlay(plan, p, k, &e.view, display_kind);
                    if o.is_empty() {
                        Ok(f)
                    } else {
                        overlay::draw(f, &o, bg)
                    }
                })
                .map(|f| (e.eye, std::borrow::Cow::Owned(f)))
                .map_err(|a| Error::Encode {
                    path: frame_path(&plan.out, &pass.name, k, e.eye, format.extension()),
                    message: a.to_string(),
                }),
        })
        .collect::<Result<_, Error>>()?;
    let layout = outputs.stereo.map(|s| s.layout);
    let images: Vec<(Eye, std::borrow::Cow<Film>)> = match (layout, stored.as_slice()) {
        (None, _) | (Some(Layout::Pair), _) => stored,
        (Some(l), [(_, left), (_, right)]) => {
            let st = outputs.stereo.expect("layout implies stereo");
            let fill: Vec<f32> = match format {
                Format::Nrrd if left.channels == 1 => vec![f32::NAN],
                Format::Nrrd => vec![0.0; left.channels],
                _ => bg[..left.channels.min(3)].to_vec(),
            };
            // grey passes always combine luminance; shaded ones as the scene says
            let colors = if plan.passes[p].kind() != ImageKind::Rgba {
                AnaglyphColors::Gray
            } else {
                st.anaglyph_colors
            };
            let combined = match l {
                Layout::SideBySide => stereo::side_by_side(left, right, st.gap, &fill),
                Layout::CrossEyed => stereo::side_by_side(right, left, st.gap, &fill),
                Layout::Anaglyph => stereo::anaglyph(left, right, st.anaglyph, colors),
                Layout::Pair => unreachable!("handled above"),
            }
            .map_err(|a| Error::Encode {
                path: frame_path(&plan.out, &pass.name, k, Eye::Mono, format.extension()),
                message: a.to_string(),
            })?;
            vec![(Eye::Mono, std::borrow::Cow::Owned(combined))]
        }
        _ => unreachable!("stereo frames have two eyes"),
    };
    Ok(images)
}

/// Lays out, encodes and writes the images of one (pass, frame); returns each file
/// with its manifest entry.
pub(super) fn write_frame(
    plan: &Plan,
    fv: &FrameViews,
) -> Result<Vec<(PathBuf, FileRecord)>, Error> {
    let (p, k) = (fv.pass, fv.frame);
    let outputs = &plan.output;
    let pass = &outputs.passes[p];
    let format = outputs.format;
    let images = frame_images(plan, fv)?;
    let mut files = Vec::new();
    for (eye, img) in images {
        let path = frame_path(&plan.out, &pass.name, k, eye, format.extension());
        let bytes = match format {
            Format::Png | Format::Png16 => {
                encode::png(&img, format == Format::Png16).map_err(|e| Error::Encode {
                    path: path.clone(),
                    message: e.to_string(),
                })?
            }
            Format::Nrrd => {
                let (azimuth, _) = plan.views.frame_angles_deg(k);
                let mut kv = vec![
                    ("volcast_pass".to_string(), pass.name.clone()),
                    ("volcast_mode".to_string(), pass.mode.to_string()),
                    ("volcast_frame".to_string(), k.to_string()),
                    ("volcast_azimuth_deg".to_string(), format!("{azimuth}")),
                ];
                if eye != Eye::Mono {
                    let e = fv.eyes.iter().find(|e| e.eye == eye);
                    if let Some(e) = e {
                        kv.push((
                            "volcast_eye_azimuth_deg".to_string(),
                            format!("{}", plan.views.angles_deg(e.key).0),
                        ));
                    }
                }
                encode::nrrd(&img, &kv).map_err(|e| Error::Encode {
                    path: path.clone(),
                    message: e.to_string(),
                })?
            }
        };
        let record = manifest::write_recorded(&path, &bytes).map_err(|source| Error::Output {
            path: path.clone(),
            source,
        })?;
        files.push((path, record));
    }
    Ok(files)
}

/// What is drawn over one eye's picture of pass `p`, frame `k`: the scene's labels
/// (placeholders from the frame's centre view, so both eyes of a stereo frame agree),
/// the scale bar of an orthographic view, and the colour bar of an intensity pass.
fn frame_overlay(plan: &Plan, p: usize, k: usize, view: &View, kind: DisplayKind) -> Overlay {
    let outputs = &plan.output;
    let pass = &outputs.passes[p];
    // the frame's camera on any path (keyframes, rock, elevation, circle)
    let (azimuth, elevation) = plan.views.frame_angles_deg(k);
    let info = FrameInfo {
        scene: &outputs.title,
        pass: &pass.name,
        frame: k,
        azimuth,
        elevation,
    };
    let labels = outputs
        .labels
        .iter()
        .map(|l| (l.text_for(&info), l.clone()))
        .collect();
    let scale_bar =
        (outputs.scale_bar && view.projection == Projection::Orthographic).then(|| ScaleBar {
            pixel_size: 2.0 * view.half_height / plan.height as f64,
            unit: plan.length_unit.clone(),
        });
    // values of the volume under units = "data" for the passes whose window is on
    // the value axis
    let value_based = pass.window_in_values;
    let shown = |x: f64| {
        if value_based {
            outputs.units.show(x)
        } else {
            x
        }
    };
    let colorbar = match (outputs.colorbar, kind) {
        (true, DisplayKind::Intensity(w, map)) => Some(Colorbar {
            map,
            top: shown(w.hi),
            bottom: shown(w.lo),
        }),
        // near (the window's low end) is bright
        (true, DisplayKind::Depth(w, map)) => Some(Colorbar {
            map,
            top: w.lo,
            bottom: w.hi,
        }),
        _ => None,
    };
    Overlay {
        labels,
        scale_bar,
        colorbar,
    }
}
