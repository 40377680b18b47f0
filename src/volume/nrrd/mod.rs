//! NRRD reader and writer (STUB: to be implemented; the signatures are the contract).

use std::path::{Path, PathBuf};

use super::{Limits, ScalarType, VolumeData, VolumeError, VolumeHeader};

/// How the data bytes are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// raw bytes
    Raw,
    /// gzip-compressed raw bytes
    Gzip,
    /// bzip2-compressed raw bytes
    Bzip2,
    /// whitespace-separated decimal numbers
    Ascii,
    /// two hex digits per byte
    Hex,
}

/// A parsed NRRD header.
#[derive(Clone, Debug, PartialEq)]
pub struct NrrdHeader {
    /// Element type.
    pub scalar_type: ScalarType,
    /// Axis sizes, fastest first.
    pub sizes: Vec<usize>,
    /// Data encoding.
    pub encoding: Encoding,
    /// `key:=value` pairs, in file order.
    pub key_values: Vec<(String, String)>,
}

impl NrrdHeader {
    /// A header for writing `sizes` elements of `scalar_type`, raw, little-endian.
    pub fn new(scalar_type: ScalarType, sizes: Vec<usize>) -> NrrdHeader {
        NrrdHeader {
            scalar_type,
            sizes,
            encoding: Encoding::Raw,
            key_values: Vec::new(),
        }
    }

    /// The 3D view of this header used by the renderer.
    pub fn volume_header(&self, path: &Path) -> Result<VolumeHeader, VolumeError> {
        Err(VolumeError::Unsupported {
            path: path.to_path_buf(),
            message: "NRRD reading is not implemented yet".into(),
        })
    }
}

/// Reads and checks the header only.
pub fn read_header(path: &Path) -> Result<NrrdHeader, VolumeError> {
    Err(VolumeError::Unsupported {
        path: PathBuf::from(path),
        message: "NRRD reading is not implemented yet".into(),
    })
}

/// Reads header and data.
pub fn read(path: &Path, _limits: &Limits) -> Result<(NrrdHeader, VolumeData), VolumeError> {
    Err(VolumeError::Unsupported {
        path: PathBuf::from(path),
        message: "NRRD reading is not implemented yet".into(),
    })
}

/// Encodes a complete attached-header NRRD file in memory.
pub fn encode(_header: &NrrdHeader, _data: &VolumeData) -> Result<Vec<u8>, VolumeError> {
    Err(VolumeError::Invalid("NRRD writing is not implemented yet".into()))
}
