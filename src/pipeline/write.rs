//! Laying out, encoding and writing the images of one (pass, frame).

use super::*;

/// Lays out, encodes and writes the images of one (pass, frame); returns each file
/// with its manifest entry.
pub(super) fn write_frame(
    scene: &Scene,
    plan: &Plan,
    fv: &FrameViews,
) -> Result<Vec<(PathBuf, FileRecord)>, Error> {
    let (p, k, window) = (fv.pass, fv.frame, fv.window);
    let pass = &scene.passes[p];
    let format = scene.image.format;
    let bg = scene.image.background;
    let display_kind = match (plan.passes[p].kind(), window) {
        (ImageKind::Depth, Some(w)) => DisplayKind::Depth(w, pass.colormap),
        (_, Some(w)) => DisplayKind::Intensity(w, pass.colormap),
        _ => DisplayKind::Rgba,
    };
    // Films in the form the format stores: raw values for NRRD, display colours for PNG.
    let stored: Vec<(Eye, std::borrow::Cow<Film>)> = fv
        .eyes
        .iter()
        .map(|e| match format {
            Format::Nrrd => Ok((e.eye, std::borrow::Cow::Borrowed(e.film))),
            _ => to_display(e.film, display_kind, bg)
                .map(|f| (e.eye, std::borrow::Cow::Owned(f)))
                .map_err(|a| Error::Encode {
                    path: frame_path(&plan.out, &pass.name, k, e.eye, format.extension()),
                    message: a.to_string(),
                }),
        })
        .collect::<Result<_, Error>>()?;
    let layout = scene.stereo.map(|s| s.layout);
    let images: Vec<(Eye, std::borrow::Cow<Film>)> = match (layout, stored.as_slice()) {
        (None, _) | (Some(Layout::Pair), _) => stored,
        (Some(l), [(_, left), (_, right)]) => {
            let st = scene.stereo.expect("layout implies stereo");
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
                let azimuth = scene.camera.azimuth_deg + scene.orbit.azimuth_offset_deg(k);
                let mut kv = vec![
                    ("volcast_pass".to_string(), pass.name.clone()),
                    ("volcast_mode".to_string(), pass.mode.name().to_string()),
                    ("volcast_frame".to_string(), k.to_string()),
                    ("volcast_azimuth_deg".to_string(), format!("{azimuth}")),
                ];
                if eye != Eye::Mono {
                    let e = fv.eyes.iter().find(|e| e.eye == eye);
                    if let Some(e) = e {
                        kv.push((
                            "volcast_eye_azimuth_deg".to_string(),
                            format!(
                                "{}",
                                scene.camera.azimuth_deg + plan.views.azimuth_offset_deg(e.key)
                            ),
                        ));
                    }
                }
                encode::nrrd(&img, &kv).map_err(|e| Error::Encode {
                    path: path.clone(),
                    message: e.to_string(),
                })?
            }
        };
        write_atomic(&path, &bytes).map_err(|source| Error::Output {
            path: path.clone(),
            source,
        })?;
        let record = manifest::file_record(&path, &bytes);
        files.push((path, record));
    }
    Ok(files)
}
