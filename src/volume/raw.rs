//! Headerless raw volumes (STUB: to be implemented; the signatures are the contract).

use std::path::PathBuf;

use super::{Geometry, Limits, ScalarType, Volume, VolumeError, VolumeHeader};

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
    /// Sizes, type and geometry (checks the file's length, reads no voxels).
    pub fn header(&self) -> Result<VolumeHeader, VolumeError> {
        Ok(VolumeHeader {
            sizes: self.sizes,
            scalar_type: self.scalar_type,
            geometry: Geometry::from_spacing(self.spacing),
            source: self.path.display().to_string(),
            fields: Vec::new(),
        })
    }

    /// Reads the voxels.
    pub fn load(&self, _limits: &Limits) -> Result<Volume, VolumeError> {
        Err(VolumeError::Invalid("raw reading is not implemented yet".into()))
    }
}
