//! Encoders: 8- and 16-bit PNG from display films, float32 NRRD from raw films.

use std::io::Cursor;

use image::{ImageBuffer, ImageFormat, Luma, Rgb};

use crate::render::Film;
use crate::volume::nrrd::{self, NrrdHeader};
use crate::volume::{ScalarType, VolumeData, VolumeError};

/// Why an image could not be encoded.
#[derive(Debug, thiserror::Error)]
pub enum EncodeError {
    /// The encoder failed.
    #[error(transparent)]
    Image(#[from] image::ImageError),
    /// A buffer could not be allocated.
    #[error(transparent)]
    Memory(#[from] super::AllocError),
    /// A display film of a channel count PNG does not take.
    #[error("display films have 1 or 3 channels, not {0}")]
    Channels(usize),
}

/// The film's samples quantised by `q`, in a fallibly allocated buffer.
fn quantised<T>(film: &Film, q: impl Fn(&f32) -> T) -> Result<Vec<T>, super::AllocError> {
    let mut v = Vec::new();
    v.try_reserve_exact(film.data.len())
        .map_err(|_| super::AllocError {
            bytes: (film.data.len() as u64).saturating_mul(std::mem::size_of::<T>() as u64),
        })?;
    v.extend(film.data.iter().map(q));
    Ok(v)
}

/// PNG bytes of a display film (1 or 3 channels, values in [0, 1]) at 8 or 16 bits.
pub fn png(film: &Film, sixteen: bool) -> Result<Vec<u8>, EncodeError> {
    let (w, h) = (film.width as u32, film.height as u32);
    let mut bytes = Vec::new();
    // room for the file, about the size of the samples at worst
    let guess = film.data.len().saturating_mul(if sixteen { 2 } else { 1 }) / 2 + 1024;
    bytes.try_reserve(guess).map_err(|_| super::AllocError {
        bytes: guess as u64,
    })?;
    let mut out = Cursor::new(&mut bytes);
    let q8 = |v: &f32| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    let q16 = |v: &f32| (v.clamp(0.0, 1.0) * 65535.0).round() as u16;
    let bad = || unreachable_size();
    match (film.channels, sixteen) {
        (1, false) => ImageBuffer::<Luma<u8>, _>::from_raw(w, h, quantised(film, q8)?)
            .ok_or_else(bad)?
            .write_to(&mut out, ImageFormat::Png)?,
        (1, true) => ImageBuffer::<Luma<u16>, _>::from_raw(w, h, quantised(film, q16)?)
            .ok_or_else(bad)?
            .write_to(&mut out, ImageFormat::Png)?,
        (3, false) => ImageBuffer::<Rgb<u8>, _>::from_raw(w, h, quantised(film, q8)?)
            .ok_or_else(bad)?
            .write_to(&mut out, ImageFormat::Png)?,
        (3, true) => ImageBuffer::<Rgb<u16>, _>::from_raw(w, h, quantised(film, q16)?)
            .ok_or_else(bad)?
            .write_to(&mut out, ImageFormat::Png)?,
        (c, _) => return Err(EncodeError::Channels(c)),
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
