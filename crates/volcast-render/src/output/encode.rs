//! Encoders: 8- and 16-bit PNG from display films, float32 NRRD from raw films.

use crate::render::Film;
use crate::volume::nrrd::{self, NrrdHeader};
use crate::volume::{ScalarType, TypedVoxels, VolumeError, Voxels};

/// Why an image could not be encoded.
#[derive(Debug, thiserror::Error)]
pub enum EncodeError {
    /// The encoder failed.
    #[error("PNG encoder: {0}")]
    Png(#[from] png::EncodingError),
    /// A buffer could not be allocated.
    #[error(transparent)]
    Memory(#[from] super::AllocError),
    /// A display film of a channel count PNG does not take.
    #[error("display films have 1 or 3 channels, not {0}")]
    Channels(usize),
}

/// The film's samples quantised by `q` to `N` bytes each, in a fallibly allocated
/// buffer.
fn quantised<const N: usize>(
    film: &Film,
    q: impl Fn(&f32) -> [u8; N],
) -> Result<Vec<u8>, super::AllocError> {
    let bytes = film.data.len().saturating_mul(N);
    let mut v = Vec::new();
    v.try_reserve_exact(bytes).map_err(|_| super::AllocError {
        bytes: bytes as u64,
    })?;
    v.extend(film.data.iter().flat_map(q));
    Ok(v)
}

/// The 8-bit PNG sample of a display value: `round(clamp(v, 0, 1) * 255)`.
#[inline]
pub fn sample8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// The 16-bit PNG sample of a display value: `round(clamp(v, 0, 1) * 65535)`.
#[inline]
pub fn sample16(v: f32) -> u16 {
    (v.clamp(0.0, 1.0) * 65535.0).round() as u16
}

/// PNG bytes of a display film (1 or 3 channels, values in [0, 1]) at 8 or 16 bits.
pub fn png(film: &Film, sixteen: bool) -> Result<Vec<u8>, EncodeError> {
    let color = match film.channels {
        1 => png::ColorType::Grayscale,
        3 => png::ColorType::Rgb,
        c => return Err(EncodeError::Channels(c)),
    };
    // the samples, 16-bit ones big-endian as PNG stores them
    let samples = if sixteen {
        quantised(film, |v| sample16(*v).to_be_bytes())?
    } else {
        quantised(film, |v| [sample8(*v)])?
    };
    encode_png(
        film.width as u32,
        film.height as u32,
        color,
        if sixteen {
            png::BitDepth::Sixteen
        } else {
            png::BitDepth::Eight
        },
        &samples,
    )
}

/// The PNG file of `width x height` pixels of `samples` (row by row, in PNG's
/// sample order).
pub(crate) fn encode_png(
    width: u32,
    height: u32,
    color: png::ColorType,
    depth: png::BitDepth,
    samples: &[u8],
) -> Result<Vec<u8>, EncodeError> {
    let mut bytes = Vec::new();
    // room for the file, about the size of the samples at worst
    let guess = samples.len() / 2 + 1024;
    bytes.try_reserve(guess).map_err(|_| super::AllocError {
        bytes: guess as u64,
    })?;
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(color);
    encoder.set_depth(depth);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(samples)?;
    writer.finish()?;
    Ok(bytes)
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
    nrrd::encode_voxels(&header, TypedVoxels::F32(Voxels::from_slice(&film.data)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PNG's header fields and its samples (16-bit ones as numbers), decoded.
    fn decode(bytes: &[u8]) -> (png::ColorType, png::BitDepth, u32, u32, Vec<u32>) {
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let mut buf = vec![0; reader.output_buffer_size().unwrap()];
        let info = reader.next_frame(&mut buf).unwrap();
        let samples = match info.bit_depth {
            png::BitDepth::Sixteen => buf[..info.buffer_size()]
                .chunks(2)
                .map(|b| u32::from(u16::from_be_bytes([b[0], b[1]])))
                .collect(),
            _ => buf[..info.buffer_size()]
                .iter()
                .map(|&b| u32::from(b))
                .collect(),
        };
        (
            info.color_type,
            info.bit_depth,
            info.width,
            info.height,
            samples,
        )
    }

    /// Grey and RGB films at 8 and 16 bits decode to their values quantised by
    /// `round(clamp(v) * max)` (in f32), in row order, with out-of-range values
    /// clamped; 16-bit samples come out in PNG's big-endian order.
    #[test]
    fn png_samples_are_the_quantised_film() {
        let values = [
            0.0, 0.25, 0.5, 1.0, -0.5, 1.5, 0.001, 0.999, 0.7, 0.3, 0.6, 0.1,
        ];
        for (channels, color) in [(1, png::ColorType::Grayscale), (3, png::ColorType::Rgb)] {
            let (width, height) = (12 / channels / 2, 2);
            let film = Film {
                width,
                height,
                channels,
                data: values.to_vec(),
            };
            for (sixteen, max, depth) in [
                (false, 255.0f32, png::BitDepth::Eight),
                (true, 65535.0, png::BitDepth::Sixteen),
            ] {
                let (c, d, w, h, samples) = decode(&png(&film, sixteen).unwrap());
                assert_eq!((c, d, w, h), (color, depth, width as u32, height as u32));
                let expect: Vec<u32> = values
                    .iter()
                    .map(|v: &f32| (v.clamp(0.0, 1.0) * max).round() as u32)
                    .collect();
                assert_eq!(samples, expect, "{channels} channels, 16-bit {sixteen}");
            }
        }
        let two = Film {
            width: 1,
            height: 1,
            channels: 2,
            data: vec![0.0; 2],
        };
        assert!(matches!(png(&two, false), Err(EncodeError::Channels(2))));
    }
}
