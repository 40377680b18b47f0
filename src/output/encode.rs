//! Encoders: 8- and 16-bit PNG from display films, float32 NRRD from raw films.

use std::io::Cursor;

use image::{ImageBuffer, ImageFormat, Luma, Rgb};

use crate::render::Film;
use crate::volume::nrrd::{self, NrrdHeader};
use crate::volume::{ScalarType, VolumeData, VolumeError};

/// PNG bytes of a display film (1 or 3 channels, values in [0, 1]) at 8 or 16 bits.
pub fn png(film: &Film, sixteen: bool) -> Result<Vec<u8>, image::ImageError> {
    let (w, h) = (film.width as u32, film.height as u32);
    let mut bytes = Vec::new();
    let mut out = Cursor::new(&mut bytes);
    let q8 = |v: &f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    let q16 = |v: &f32| (v.clamp(0.0, 1.0) * 65535.0).round() as u16;
    let bad = || unreachable_size();
    match (film.channels, sixteen) {
        (1, false) => ImageBuffer::<Luma<u8>, _>::from_raw(
            w,
            h,
            film.data.iter().map(q8).collect::<Vec<u8>>(),
        )
        .ok_or_else(bad)?
        .write_to(&mut out, ImageFormat::Png)?,
        (1, true) => ImageBuffer::<Luma<u16>, _>::from_raw(
            w,
            h,
            film.data.iter().map(q16).collect::<Vec<u16>>(),
        )
        .ok_or_else(bad)?
        .write_to(&mut out, ImageFormat::Png)?,
        (3, false) => {
            ImageBuffer::<Rgb<u8>, _>::from_raw(w, h, film.data.iter().map(q8).collect::<Vec<u8>>())
                .ok_or_else(bad)?
                .write_to(&mut out, ImageFormat::Png)?
        }
        (3, true) => ImageBuffer::<Rgb<u16>, _>::from_raw(
            w,
            h,
            film.data.iter().map(q16).collect::<Vec<u16>>(),
        )
        .ok_or_else(bad)?
        .write_to(&mut out, ImageFormat::Png)?,
        (c, _) => panic!("display films have 1 or 3 channels, not {c}"),
    }
    Ok(bytes)
}

fn unreachable_size() -> image::ImageError {
    image::ImageError::Parameter(image::error::ParameterError::from_kind(
        image::error::ParameterErrorKind::DimensionMismatch,
    ))
}

/// NRRD bytes of a raw film: float32, sizes `W H` (scalar) or `C W H` (components
/// fastest), row 0 at the top, with the given `key:=value` pairs.
pub fn nrrd(film: &Film, key_values: &[(String, String)]) -> Result<Vec<u8>, VolumeError> {
    let header = if film.channels == 1 {
        NrrdHeader::new(ScalarType::Float32, vec![film.width, film.height])
            .with_kinds(["space", "space"])
    } else {
        NrrdHeader::new(
            ScalarType::Float32,
            vec![film.channels, film.width, film.height],
        )
        .with_kinds(["RGBA-color", "space", "space"])
    };
    let mut header = header;
    header.key_values.extend(key_values.iter().cloned());
    nrrd::encode(&header, &VolumeData::F32(film.data.clone()))
}
