//! Voxels in memory that volcast did not allocate and does not own: a caller's buffer
//! (the NumPy array given to the Python module), used in place and kept alive by a
//! reference-counted owner. Like mapped voxels, they are read through [`Voxels`]
//! views (x fastest, native byte order, any alignment).
//!
//! [`Voxels`]: super::Voxels

use std::fmt;
use std::sync::Arc;

use super::{ScalarType, VolumeError};

/// Something that holds voxel bytes and keeps them alive and unchanged while it
/// exists (a Python array and a reference to it, a `Vec<u8>`, ...).
pub trait VoxelBytes: Send + Sync {
    /// The voxels' bytes, in native byte order, x fastest.
    fn bytes(&self) -> &[u8];
}

impl VoxelBytes for Vec<u8> {
    fn bytes(&self) -> &[u8] {
        self
    }
}

/// Voxels of one type in a buffer someone else owns: cloning shares the buffer.
#[derive(Clone)]
pub struct SharedVoxels {
    scalar_type: ScalarType,
    owner: Arc<dyn VoxelBytes>,
}

impl SharedVoxels {
    /// The voxels of type `scalar_type` that `owner` holds; an error unless its
    /// length is a whole number of elements.
    pub fn new(
        scalar_type: ScalarType,
        owner: Arc<dyn VoxelBytes>,
    ) -> Result<SharedVoxels, VolumeError> {
        let n = owner.bytes().len();
        if !n.is_multiple_of(scalar_type.size()) {
            return Err(VolumeError::Invalid(format!(
                "{n} bytes are not a whole number of {scalar_type} voxels ({} bytes each)",
                scalar_type.size()
            )));
        }
        Ok(SharedVoxels { scalar_type, owner })
    }

    /// The element type.
    pub fn scalar_type(&self) -> ScalarType {
        self.scalar_type
    }

    /// The voxels' bytes, in native byte order.
    pub fn bytes(&self) -> &[u8] {
        self.owner.bytes()
    }
}

impl fmt::Debug for SharedVoxels {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SharedVoxels")
            .field("scalar_type", &self.scalar_type)
            .field("bytes", &self.bytes().len())
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::VolumeData;

    /// Shared bytes read as the voxels they hold, and only whole elements are taken.
    #[test]
    fn shared_bytes_are_read_in_place() {
        let values: Vec<u16> = vec![1, 2, 300, 65535];
        let bytes: Vec<u8> = values.iter().flat_map(|v| v.to_ne_bytes()).collect();
        let shared = SharedVoxels::new(ScalarType::Uint16, Arc::new(bytes)).unwrap();
        let data = VolumeData::Shared(shared);
        assert_eq!(data.scalar_type(), ScalarType::Uint16);
        assert_eq!(data, VolumeData::U16(values));
        assert_eq!(data.allocated_bytes(), 0);
        assert!(SharedVoxels::new(ScalarType::Int32, Arc::new(vec![0u8; 6])).is_err());
    }
}
