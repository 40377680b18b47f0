//! Headerless raw volumes: the scene gives sizes, type, byte order, spacing and offset;
//! the file length must agree exactly (a headerless file of the wrong length almost
//! always means wrong sizes or type). Data in the machine's byte order is mapped
//! ([`super::mapped`]); the other byte order is read, with the decoder shared with the
//! NRRD raw encoding.

use std::io::{BufReader, Seek, SeekFrom};
use std::path::PathBuf;

use super::mapped::{self, check_regular_file, is_native_order, open_for_mapping};
use super::{Geometry, Limits, ScalarType, Storage, Volume, VolumeData, VolumeError, VolumeHeader};
use nrrd::{ElementSink, ReadError};

/// A raw file and the description the scene gives of it.
#[derive(Clone, Debug, PartialEq)]
pub struct RawSpec {
    /// The data file.
    pub path: PathBuf,
    /// Voxels along x, y, z.
    pub sizes: [usize; 3],
    /// Element type.
    pub scalar_type: ScalarType,
    /// Byte order of multi-byte elements.
    pub little_endian: bool,
    /// Voxel spacing along x, y, z.
    pub spacing: [f64; 3],
    /// Bytes to skip before the data; -1 = the data is the last bytes of the file.
    pub offset: i64,
}

impl RawSpec {
    /// Sizes, type and geometry (checks the parameters and the file's length, reads no
    /// voxels).
    pub fn header(&self) -> Result<VolumeHeader, VolumeError> {
        self.data_start()?;
        Ok(VolumeHeader {
            sizes: self.sizes,
            scalar_type: self.scalar_type,
            geometry: Geometry::from_spacing(self.spacing),
            source: self.path.display().to_string(),
            fields: Vec::new(),
            rescale: Default::default(),
        })
    }

    /// True when [`RawSpec::load`] maps the file (data in the machine's byte order).
    pub fn is_mappable(&self) -> bool {
        is_native_order(self.scalar_type, self.little_endian)
    }

    /// Whether [`RawSpec::load`] maps or reads the voxels (checks what
    /// [`RawSpec::header`] checks).
    pub fn storage(&self) -> Result<Storage, VolumeError> {
        let offset = self.data_start()?;
        let bytes = self.check_params()?;
        Ok(Storage::uncompressed(
            self.scalar_type,
            self.little_endian,
            &self.path,
            offset,
            bytes,
        ))
    }

    /// Maps the voxels (data in native byte order, not counted against `limits`), or
    /// reads them (limits checked before any allocation).
    pub fn load(&self, limits: &Limits) -> Result<Volume, VolumeError> {
        self.load_hashed(limits, false).map(|(v, _)| v)
    }

    /// [`RawSpec::load`], also returning (when `hash`) the XXH3-128 of the data's bytes
    /// as stored, computed while they are read (mapped data: over the mapped bytes).
    pub fn load_hashed(
        &self,
        limits: &Limits,
        hash: bool,
    ) -> Result<(Volume, Option<u128>), VolumeError> {
        let header = self.header()?;
        if self.is_mappable() {
            let v = self.load_mapped(header)?;
            let digest = match (&v.data, hash) {
                (VolumeData::Mapped(m), true) => Some(xxhash_rust::xxh3::xxh3_128(m.bytes())),
                _ => None,
            };
            return Ok((v, digest));
        }
        let (count, _) = limits.check(&self.sizes, self.scalar_type.size())?;
        let start = self.data_start()?;
        let io_err = |source| VolumeError::Io {
            path: self.path.clone(),
            source,
        };
        let (file, _) = mapped::open_regular(&self.path, "volume data")?;
        let mut r = BufReader::new(file);
        r.seek(SeekFrom::Start(start)).map_err(io_err)?;
        let mut sink = ElementSink::new(self.scalar_type, count, self.little_endian);
        if hash {
            sink = sink.hashing();
        }
        sink.read(&mut r, count).map_err(|e| match e {
            // The length was checked, so this means the file changed meanwhile.
            ReadError::Short { bytes } => VolumeError::Data {
                path: self.path.clone(),
                message: format!(
                    "file ended after {bytes} bytes of data (did it change while being read?)"
                ),
            },
            ReadError::Io(source) => VolumeError::Io {
                path: self.path.clone(),
                source,
            },
            ReadError::Memory { bytes } => VolumeError::OutOfMemory {
                path: self.path.clone(),
                bytes,
            },
        })?;
        let digest = sink.hash();
        Ok((
            Volume {
                header,
                data: sink.finish().into(),
            },
            digest,
        ))
    }

    /// Maps the data, checking type and length on the opened file.
    fn load_mapped(&self, header: VolumeHeader) -> Result<Volume, VolumeError> {
        let need = self.check_params()?;
        let io_err = |source| VolumeError::Io {
            path: self.path.clone(),
            source,
        };
        let file = open_for_mapping(&self.path).map_err(io_err)?;
        let meta = file.metadata().map_err(io_err)?;
        check_regular_file(&self.path, &meta)?;
        let start = self.start_in(meta.len(), need)?;
        let data = mapped::map(&file, &self.path, self.scalar_type, start, need)?;
        Ok(Volume {
            header,
            data: VolumeData::Mapped(data),
        })
    }

    /// Checks the parameters; returns the data's size in bytes.
    fn check_params(&self) -> Result<u64, VolumeError> {
        if self.sizes.contains(&0) {
            return Err(VolumeError::Invalid(format!(
                "raw volume {}: sizes {:?} must all be at least 1",
                self.path.display(),
                self.sizes
            )));
        }
        if !self.spacing.iter().all(|s| s.is_finite() && *s > 0.0) {
            return Err(VolumeError::Invalid(format!(
                "raw volume {}: spacing {:?} must be finite and positive",
                self.path.display(),
                self.spacing
            )));
        }
        if self.offset < -1 {
            return Err(VolumeError::Invalid(format!(
                "raw volume {}: offset {} must be 0 or more, or -1 for data at the end of the file",
                self.path.display(),
                self.offset
            )));
        }
        let (_, bytes) = Limits {
            max_bytes: u64::MAX,
        }
        .check(&self.sizes, self.scalar_type.size())?;
        Ok(bytes as u64)
    }

    /// Checks the parameters, the file's type and its length; returns where the data
    /// starts.
    fn data_start(&self) -> Result<u64, VolumeError> {
        let need = self.check_params()?;
        let meta = std::fs::metadata(&self.path).map_err(|source| VolumeError::Io {
            path: self.path.clone(),
            source,
        })?;
        check_regular_file(&self.path, &meta)?;
        self.start_in(meta.len(), need)
    }

    /// Where `need` bytes of data start in a file of `len` bytes, or why they do not fit.
    fn start_in(&self, len: u64, need: u64) -> Result<u64, VolumeError> {
        let data_err = |message: String| VolumeError::Data {
            path: self.path.clone(),
            message,
        };
        let what = format!(
            "{} × {} × {} {} = {need} bytes",
            self.sizes[0], self.sizes[1], self.sizes[2], self.scalar_type
        );
        if self.offset == -1 {
            return match len.checked_sub(need) {
                Some(start) => Ok(start),
                None => Err(data_err(format!(
                    "file is {len} bytes, shorter than the {what} of data (offset -1 = the last bytes)"
                ))),
            };
        }
        let offset = self.offset as u64;
        let expected = offset.saturating_add(need);
        if len < expected {
            return Err(data_err(format!(
                "file is {len} bytes, but offset {offset} + {what} needs {expected}"
            )));
        }
        if len > expected {
            return Err(data_err(format!(
                "file is {len} bytes, but offset {offset} + {what} is only {expected}: \
                 check sizes and type; if the data really is the last {need} bytes, use offset {} (or -1)",
                len - need
            )));
        }
        Ok(offset)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(
        dir: &tempfile::TempDir,
        bytes: &[u8],
        sizes: [usize; 3],
        ty: ScalarType,
        offset: i64,
    ) -> RawSpec {
        let path = dir.path().join("v.raw");
        std::fs::write(&path, bytes).unwrap();
        RawSpec {
            path,
            sizes,
            scalar_type: ty,
            little_endian: false,
            spacing: [1.0, 2.0, 0.5],
            offset,
        }
    }

    #[test]
    fn reads_big_endian_with_offset_and_tail() {
        let dir = tempfile::tempdir().unwrap();
        let bytes = [9, 9, 0, 1, 0, 2, 1, 0, 0xff, 0xff];
        let s = spec(&dir, &bytes, [2, 2, 1], ScalarType::Int16, 2);
        let v = s.load(&Limits::default()).unwrap();
        assert_eq!(v.data, VolumeData::I16(vec![1, 2, 256, -1]));
        assert_eq!(v.header.geometry, Geometry::from_spacing([1.0, 2.0, 0.5]));
        let s = RawSpec { offset: -1, ..s };
        assert_eq!(
            s.load(&Limits::default()).unwrap().data,
            VolumeData::I16(vec![1, 2, 256, -1])
        );
    }

    #[test]
    fn wrong_lengths_explain_themselves() {
        let dir = tempfile::tempdir().unwrap();
        let s = spec(&dir, &[0; 10], [2, 2, 1], ScalarType::Int16, 0);
        let e = s.header().unwrap_err().to_string();
        assert!(e.contains("use offset 2"), "{e}");
        let s = spec(&dir, &[0; 7], [2, 2, 1], ScalarType::Int16, 0);
        let e = s.header().unwrap_err().to_string();
        assert!(
            e.contains("file is 7 bytes") && e.contains("needs 8"),
            "{e}"
        );
        let s = RawSpec { offset: -1, ..s };
        assert!(s.header().is_err());
    }

    #[test]
    fn bad_parameters() {
        let dir = tempfile::tempdir().unwrap();
        let s = spec(&dir, &[0; 8], [2, 2, 1], ScalarType::Int16, 0);
        assert!(s.header().is_ok());
        assert!(RawSpec {
            sizes: [0, 2, 1],
            ..s.clone()
        }
        .header()
        .is_err());
        assert!(RawSpec {
            spacing: [1.0, f64::NAN, 1.0],
            ..s.clone()
        }
        .header()
        .is_err());
        assert!(RawSpec {
            spacing: [1.0, 0.0, 1.0],
            ..s.clone()
        }
        .header()
        .is_err());
        assert!(RawSpec {
            offset: -2,
            ..s.clone()
        }
        .header()
        .is_err());
        let missing = RawSpec {
            path: dir.path().join("nope.raw"),
            ..s.clone()
        };
        assert!(matches!(missing.header(), Err(VolumeError::Io { .. })));
        let huge = RawSpec {
            sizes: [usize::MAX, 2, 1],
            ..s
        };
        assert!(huge.header().is_err());
    }

    #[test]
    fn limits_checked_before_reading() {
        let dir = tempfile::tempdir().unwrap();
        let s = spec(&dir, &[0; 8], [2, 2, 1], ScalarType::Int16, 0);
        assert!(matches!(
            s.load(&Limits { max_bytes: 4 }),
            Err(VolumeError::TooLarge { .. })
        ));
    }
}
