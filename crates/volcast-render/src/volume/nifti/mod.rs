//! NIfTI-1 and NIfTI-2 reader (formats: <https://nifti.nimh.nih.gov/nifti-1>,
//! `nifti1.h`, `nifti2.h`): one `.nii` file (magic `n+1` or `n+2`), or the same gzip-compressed (`.nii.gz`, told by its first
//! bytes, not its name), in either byte order.
//!
//! ```text
//! NiftiSpec::header    header::read_header  348 or 540 bytes, sizeof_hdr -> version and
//!                                           byte order, each
//!                                           field checked (dim, datatype, bitpix,
//!                                           vox_offset, magic); the sform, qform or
//!                                           pixdim geometry; scl_slope/scl_inter
//!                      the volume chosen    `[volume] index` of a 4D file, in bounds
//! NiftiSpec::load      .nii, native order:  lengths checked, the chosen volume mapped
//!                      otherwise:           Limits::check, then decoded (gzip, byte
//!                                           swap) growing only as data arrives
//! ```
//!
//! Lengths: an uncompressed file must hold exactly `vox_offset` and every volume; a
//! `.nii.gz` is decompressed only up to the chosen volume, so it must reach that far,
//! and is checked for data past the end only when the chosen volume is the last.
//!
//! Voxels keep their stored type; `scl_slope`/`scl_inter` become the header's
//! [`Rescale`](crate::volume::Rescale), folded into the value window. World
//! coordinates are NIfTI's (RAS+), not converted.

mod header;

use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

pub use header::NiftiHeader;

use super::mapped::{is_native_order, open_regular};
use super::stream::{self, Decode};
use super::{Limits, ReadReason, Storage, Volume, VolumeError, VolumeHeader};

/// A NIfTI-1 or NIfTI-2 file and the 3D volume of it to render.
#[derive(Clone, Debug, PartialEq)]
pub struct NiftiSpec {
    /// The `.nii` or `.nii.gz` file.
    pub path: PathBuf,
    /// Which volume of a 4D file (`[volume] index`); `None` for a 3D file.
    pub index: Option<usize>,
}

/// True when the file starts with the gzip magic bytes.
fn is_gzip(r: &mut impl BufRead) -> std::io::Result<bool> {
    Ok(r.fill_buf()?.starts_with(&[0x1f, 0x8b]))
}

/// Reads and checks the header of a `.nii` or `.nii.gz` file; also tells whether the
/// file is gzip-compressed.
pub fn read_header(path: &Path) -> Result<(NiftiHeader, bool), VolumeError> {
    let (file, _) = open_regular(path, "a NIfTI file")?;
    let mut r = BufReader::new(file);
    let gzip = is_gzip(&mut r).map_err(|source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let h = if gzip {
        header::read_header(path, &mut flate2::bufread::MultiGzDecoder::new(r))?
    } else {
        header::read_header(path, &mut r)?
    };
    Ok((h, gzip))
}

/// Where the chosen volume lies in the (uncompressed) data stream.
struct Layout {
    /// Bytes of one 3D volume.
    volume: u64,
    /// Bytes of all volumes.
    total: u64,
    /// Byte of the stream (from the start of the header) where the chosen volume starts.
    start: u64,
    /// Voxels of one volume.
    count: usize,
    /// True when the chosen volume is the last one of the file.
    last: bool,
}

impl NiftiSpec {
    fn data_err(&self, message: String) -> VolumeError {
        VolumeError::Data {
            path: self.path.clone(),
            message,
        }
    }

    /// The volume to render: `index`, which a 4D file needs and which must be in bounds.
    fn chosen(&self, h: &NiftiHeader) -> Result<usize, VolumeError> {
        let n = h.volumes();
        match self.index {
            None if n > 1 => Err(VolumeError::Invalid(format!(
                "{}: a 4D NIfTI file of {n} volumes (dim[4] = {n}): choose one with `[volume] index = 0` to {}",
                self.path.display(),
                n - 1
            ))),
            None => Ok(0),
            Some(i) if i < n => Ok(i),
            Some(i) => Err(VolumeError::Invalid(format!(
                "{}: [volume] index = {i} is out of bounds: the file holds {n} volume{} (dim[4] = {n}), index 0 to {}",
                self.path.display(),
                if n == 1 { "" } else { "s" },
                n - 1
            ))),
        }
    }

    fn layout(&self, h: &NiftiHeader) -> Result<Layout, VolumeError> {
        let index = self.chosen(h)?;
        let unlimited = Limits {
            max_bytes: u64::MAX,
        };
        let (count, volume) = unlimited.check(&h.sizes(), h.scalar_type.size())?;
        let (_, total) = unlimited.check(&[volume, h.volumes()], 1)?;
        let start = (volume as u64)
            .checked_mul(index as u64)
            .and_then(|o| o.checked_add(h.vox_offset))
            .ok_or_else(|| self.data_err("the chosen volume's offset overflows".into()))?;
        Ok(Layout {
            volume: volume as u64,
            total: total as u64,
            start,
            count,
            last: index + 1 == h.volumes(),
        })
    }

    /// Sizes, type, geometry and rescale of the chosen volume (reads the header only).
    pub fn header(&self) -> Result<VolumeHeader, VolumeError> {
        let (h, _) = read_header(&self.path)?;
        self.volume_header(&h)
    }

    fn volume_header(&self, h: &NiftiHeader) -> Result<VolumeHeader, VolumeError> {
        let index = self.chosen(h)?;
        let mut fields = h.fields();
        if h.volumes() > 1 {
            fields.push(("index".into(), format!("{index} of 0..{}", h.volumes() - 1)));
        }
        Ok(VolumeHeader {
            sizes: h.sizes(),
            scalar_type: h.scalar_type,
            geometry: h.geometry(&self.path)?,
            source: self.path.display().to_string(),
            fields,
            rescale: h.rescale(),
        })
    }

    /// An uncompressed file must hold exactly `vox_offset` + every volume's bytes.
    fn check_length(&self, h: &NiftiHeader, layout: &Layout) -> Result<(), VolumeError> {
        let len = std::fs::metadata(&self.path)
            .map_err(|source| VolumeError::Io {
                path: self.path.clone(),
                source,
            })?
            .len();
        let need = h.vox_offset.saturating_add(layout.total);
        let what = format!(
            "vox_offset {} + dim {:?} x {} ({} bytes)",
            h.vox_offset,
            &h.dims[..h.ndim],
            h.scalar_type,
            layout.total
        );
        if len < need {
            return Err(self.data_err(format!(
                "data shorter than declared: the file is {len} bytes, but {what} needs {need}"
            )));
        }
        if len > need {
            return Err(self.data_err(format!(
                "the file is {len} bytes, longer than the {need} that {what} declares"
            )));
        }
        Ok(())
    }

    /// Whether [`NiftiSpec::load`] maps the voxels (an uncompressed file in the
    /// machine's byte order) or reads them, and how many bytes; checks the header, the
    /// index and (uncompressed) the file's length.
    pub fn storage(&self) -> Result<Storage, VolumeError> {
        let (h, gzip) = read_header(&self.path)?;
        self.volume_header(&h)?;
        let layout = self.layout(&h)?;
        if gzip {
            return Ok(Storage::Read {
                bytes: layout.volume,
                reason: ReadReason::Compressed("a gzip-compressed file (.nii.gz)"),
            });
        }
        self.check_length(&h, &layout)?;
        Ok(Storage::uncompressed(
            h.scalar_type,
            h.little_endian,
            &self.path,
            layout.start,
            layout.volume,
        ))
    }

    /// Loads the chosen volume: mapped, or read with `limits` checked first.
    pub fn load(&self, limits: &Limits) -> Result<Volume, VolumeError> {
        self.load_hashed(limits, false).map(|(v, _)| v)
    }

    /// [`NiftiSpec::load`], also returning (when `hash`) the XXH3-128 of the chosen
    /// volume's bytes as stored.
    pub fn load_hashed(
        &self,
        limits: &Limits,
        hash: bool,
    ) -> Result<(Volume, Option<u128>), VolumeError> {
        let (h, gzip) = read_header(&self.path)?;
        let header = self.volume_header(&h)?;
        let layout = self.layout(&h)?;
        let decode = Decode {
            path: &self.path,
            ty: h.scalar_type,
            little_endian: h.little_endian,
            count: layout.count,
            what: if gzip { "gzip data" } else { "raw data" },
        };
        let (data, digest) = if gzip {
            let (file, meta) = open_regular(&self.path, "a NIfTI file")?;
            // DEFLATE expands by at most 1032:1: a skip beyond that cannot be data
            if layout.start > meta.len().saturating_mul(1032) {
                return Err(self.data_err(format!(
                    "the chosen volume starts at byte {} of the decompressed data, beyond what {} compressed bytes can hold (dim {:?}, vox_offset {})",
                    layout.start,
                    meta.len(),
                    &h.dims[..h.ndim],
                    h.vox_offset
                )));
            }
            let mut r = flate2::bufread::MultiGzDecoder::new(BufReader::new(file));
            stream::skip(&self.path, &mut r, layout.start, "gzip data")?;
            let out = decode.read(&mut r, limits, hash)?;
            if layout.last {
                decode.probe_end(&mut r)?;
            }
            out
        } else {
            self.check_length(&h, &layout)?;
            if is_native_order(h.scalar_type, h.little_endian) {
                stream::map_region(&self.path, h.scalar_type, layout.start, layout.volume, hash)?
            } else {
                let (file, _) = open_regular(&self.path, "a NIfTI file")?;
                let mut r = BufReader::new(file);
                r.seek(SeekFrom::Start(layout.start))
                    .map_err(|source| VolumeError::Io {
                        path: self.path.clone(),
                        source,
                    })?;
                decode.read(&mut (&mut r).take(layout.volume), limits, hash)?
            }
        };
        Ok((Volume { header, data }, digest))
    }
}
