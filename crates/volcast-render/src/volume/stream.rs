//! Voxels read from one region of one file, shared by the NIfTI and MetaImage readers:
//! mapped in place (uncompressed, in the machine's byte order), or decoded from a
//! stream (compressed, or in the other byte order) into a buffer checked against the
//! memory limit first, hashing the bytes as stored either way.

use crate::volume::errors::data_err;
use std::io::{self, Read};
use std::path::Path;

use super::mapped::{self, open_for_mapping};
use super::{Limits, ScalarType, VolumeData, VolumeError};
use nrrd::{ElementSink, ReadError};

fn io_err(path: &Path) -> impl Fn(io::Error) -> VolumeError + '_ {
    move |source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Maps `bytes` bytes of `path` from byte `offset` as elements of `ty` (the file is
/// opened without blocking, must be regular and long enough), with the XXH3-128 of
/// the mapped bytes when `hash`.
pub(crate) fn map_region(
    path: &Path,
    ty: ScalarType,
    offset: u64,
    bytes: u64,
    hash: bool,
) -> Result<(VolumeData, Option<u128>), VolumeError> {
    let file = open_for_mapping(path).map_err(io_err(path))?;
    let m = mapped::map(&file, path, ty, offset, bytes)?;
    let digest = hash.then(|| xxhash_rust::xxh3::xxh3_128(m.bytes()));
    Ok((VolumeData::Mapped(m), digest))
}

/// A stream's elements: what is being decoded, for messages.
pub(crate) struct Decode<'a> {
    /// The file the stream comes from.
    pub path: &'a Path,
    /// Element type.
    pub ty: ScalarType,
    /// Byte order of the stored elements.
    pub little_endian: bool,
    /// Number of elements.
    pub count: usize,
    /// "gzip data", "zlib data", "raw data".
    pub what: &'a str,
}

impl Decode<'_> {
    fn bytes(&self) -> u64 {
        (self.count as u64).saturating_mul(self.ty.size() as u64)
    }

    /// Reads exactly the elements from `r`, after checking `limits` (no allocation
    /// beyond what arrives), with the XXH3-128 of their bytes as stored when `hash`.
    pub fn read(
        &self,
        r: &mut impl Read,
        limits: &Limits,
        hash: bool,
    ) -> Result<(VolumeData, Option<u128>), VolumeError> {
        limits
            .check(&[self.count], self.ty.size())
            .map_err(|e| match e {
                VolumeError::TooLarge { bytes, limit, .. } => VolumeError::TooLarge {
                    what: format!(
                        "{} ({} {} voxels)",
                        self.path.display(),
                        self.count,
                        self.ty
                    ),
                    bytes,
                    limit,
                },
                other => other,
            })?;
        let mut sink = ElementSink::new(self.ty, self.count, self.little_endian);
        if hash {
            sink = sink.hashing();
        }
        sink.read(r, self.count).map_err(|e| match e {
            ReadError::Short { bytes } => data_err(
                self.path,
                format!(
                    "data shorter than declared: expected {} bytes of {} ({} {} voxels), got {bytes}",
                    self.bytes(),
                    self.what,
                    self.count,
                    self.ty
                ),
            ),
            ReadError::Io(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::InvalidData | io::ErrorKind::InvalidInput | io::ErrorKind::UnexpectedEof
                ) =>
            {
                data_err(self.path, format!("{} is corrupt: {e}", self.what))
            }
            ReadError::Io(e) => io_err(self.path)(e),
            ReadError::Memory { bytes } => VolumeError::OutOfMemory {
                path: self.path.to_path_buf(),
                bytes,
            },
        })?;
        let digest = sink.hash();
        Ok((sink.finish().into(), digest))
    }

    /// An error if `r` holds one more byte after the elements.
    pub fn probe_end(&self, r: &mut impl Read) -> Result<(), VolumeError> {
        let mut one = [0u8; 1];
        loop {
            match r.read(&mut one) {
                Ok(0) => return Ok(()),
                Ok(_) => {
                    return Err(data_err(
                        self.path,
                        format!(
                            "{} continues past the {} bytes that the header declares",
                            self.what,
                            self.bytes()
                        ),
                    ))
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => {
                    return Err(data_err(
                        self.path,
                        format!(
                            "{} is corrupt after the {} declared bytes: {e}",
                            self.what,
                            self.bytes()
                        ),
                    ))
                }
            }
        }
    }
}

/// Reads and discards `n` bytes of `r` (`what` it is, for the message).
pub(crate) fn skip(path: &Path, r: &mut impl Read, n: u64, what: &str) -> Result<(), VolumeError> {
    let got = io::copy(&mut r.take(n), &mut io::sink())
        .map_err(|e| data_err(path, format!("{what} is corrupt: {e}")))?;
    if got < n {
        return Err(data_err(
            path,
            format!("{what} ends after {got} bytes, before the data starts at byte {n}"),
        ));
    }
    Ok(())
}
