//! Rendered images as the arrays `volcast.render` returns: one per pass (per eye
//! of a stereo `pair`), frames first, `(frames, height, width)` for grey and
//! `(frames, height, width, channels)` for colour; `uint8` for `png`, `uint16` for
//! `png16`, `float32` for `nrrd`: the samples the files hold.

use std::path::Path;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyByteArray;
use volcast::output::encode::{sample16, sample8};
use volcast::pipeline::StoredImage;
use volcast::plan::Plan;
use volcast::scene::{Format, Layout, Scene};
use volcast::views::Eye;

use crate::Output;

/// The eyes a frame's files are named by: left and right for a stereo `pair`, one
/// image otherwise.
pub fn eyes(plan: &Plan) -> Vec<Eye> {
    match plan.output.stereo.map(|s| s.layout) {
        Some(Layout::Pair) => vec![Eye::Left, Eye::Right],
        _ => vec![Eye::Mono],
    }
}

/// The key of a pass's (and eye's) array: the pass name, with the files' `_left`
/// and `_right` for the eyes of a pair.
fn key(pass: &str, eye: Eye) -> String {
    match eye {
        Eye::Mono => pass.to_string(),
        Eye::Left => format!("{pass}_left"),
        Eye::Right => format!("{pass}_right"),
    }
}

/// The NumPy dtype of a format's samples.
fn dtype(format: Format) -> &'static str {
    match format {
        Format::Png => "uint8",
        Format::Png16 => "uint16",
        Format::Nrrd => "float32",
    }
}

/// One array of `frames` images of `(height, width, channels)` from their samples'
/// bytes (native byte order).
fn output(
    py: Python<'_>,
    key: String,
    dtype: &'static str,
    frames: usize,
    (height, width, channels): (usize, usize, usize),
    bytes: &[u8],
) -> Output {
    let mut shape = vec![frames, height, width];
    if channels > 1 {
        shape.push(channels);
    }
    (
        key,
        dtype,
        shape,
        PyByteArray::new(py, bytes).into_any().unbind(),
    )
}

/// The arrays of images kept in memory ([`volcast::pipeline::render_images`]), in
/// pass order.
pub fn of_stored(
    py: Python<'_>,
    scene: &Scene,
    format: Format,
    stored: &[StoredImage],
) -> PyResult<Vec<Output>> {
    let mut outputs = Vec::new();
    for (p, pass) in scene.passes.iter().enumerate() {
        for eye in [Eye::Mono, Eye::Left, Eye::Right] {
            let images: Vec<&StoredImage> = stored
                .iter()
                .filter(|s| s.pass == p && s.eye == eye)
                .collect();
            let Some(first) = images.first() else {
                continue;
            };
            let f = &first.film;
            let dims = (f.height, f.width, f.channels);
            let mut bytes: Vec<u8> = Vec::new();
            for s in &images {
                let film = &s.film;
                if (film.height, film.width, film.channels) != dims {
                    return Err(PyValueError::new_err(
                        "the frames of a pass differ in size (a bug: please report it)",
                    ));
                }
                match format {
                    Format::Png => bytes.extend(film.data.iter().map(|&v| sample8(v))),
                    Format::Png16 => {
                        bytes.extend(film.data.iter().flat_map(|&v| sample16(v).to_ne_bytes()))
                    }
                    Format::Nrrd => bytes.extend(film.data.iter().flat_map(|v| v.to_ne_bytes())),
                }
            }
            outputs.push(output(
                py,
                key(&pass.name, eye),
                dtype(format),
                images.len(),
                dims,
                &bytes,
            ));
        }
    }
    Ok(outputs)
}

/// The arrays of the files a run wrote into `out` for `plan`, read back.
pub fn read_back(py: Python<'_>, plan: &Plan, out: &Path) -> PyResult<Vec<Output>> {
    let format = plan.output.format;
    let mut outputs = Vec::new();
    for pass in &plan.output.passes {
        for eye in eyes(plan) {
            let mut bytes = Vec::new();
            let mut dims = None;
            for &k in &plan.frame_list {
                let path = volcast::output::frame_path(out, &pass.name, k, eye, format.extension());
                let (d, b) = match format {
                    Format::Nrrd => read_nrrd(&path)?,
                    _ => read_png(&path)?,
                };
                if dims.is_some_and(|x| x != d) {
                    return Err(PyValueError::new_err(format!(
                        "{}: not the size of the pass's other frames",
                        path.display()
                    )));
                }
                dims = Some(d);
                bytes.extend(b);
            }
            if let Some(d) = dims {
                outputs.push(output(
                    py,
                    key(&pass.name, eye),
                    dtype(format),
                    plan.frame_list.len(),
                    d,
                    &bytes,
                ));
            }
        }
    }
    Ok(outputs)
}

fn bad(path: &Path, e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("reading {}: {e}", path.display()))
}

/// A PNG's (height, width, channels) and samples (16-bit ones in native order).
fn read_png(path: &Path) -> PyResult<((usize, usize, usize), Vec<u8>)> {
    let file = std::fs::File::open(path).map_err(|e| bad(path, e))?;
    let mut reader = png::Decoder::new(std::io::BufReader::new(file))
        .read_info()
        .map_err(|e| bad(path, e))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| bad(path, "too large"))?;
    let mut buf = vec![0; size];
    let info = reader.next_frame(&mut buf).map_err(|e| bad(path, e))?;
    buf.truncate(info.buffer_size());
    let channels = info.color_type.samples();
    if info.bit_depth == png::BitDepth::Sixteen {
        for c in buf.chunks_exact_mut(2) {
            let v = u16::from_be_bytes([c[0], c[1]]);
            c.copy_from_slice(&v.to_ne_bytes());
        }
    }
    Ok(((info.height as usize, info.width as usize, channels), buf))
}

/// A float NRRD image's (height, width, channels) and values (native order).
fn read_nrrd(path: &Path) -> PyResult<((usize, usize, usize), Vec<u8>)> {
    let (header, data) = nrrd::read(path).map_err(|e| bad(path, e))?;
    let (c, w, h) = match header.sizes.as_slice() {
        &[w, h] => (1, w, h),
        &[c, w, h] => (c, w, h),
        other => return Err(bad(path, format!("sizes {other:?}: not an image"))),
    };
    let data = volcast::volume::VolumeData::from(data);
    let values = data
        .voxels::<f32>()
        .ok_or_else(|| bad(path, "not float values"))?;
    let bytes = values.iter().flat_map(f32::to_ne_bytes).collect();
    Ok(((h, w, c), bytes))
}
