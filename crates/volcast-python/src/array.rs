//! A NumPy array as a volume, used in place: the Python side (python/volcast)
//! checks its shape and dtype and makes it Fortran-ordered (i fastest, volcast's
//! x fastest: no copy for Fortran arrays, one for C-ordered or strided ones); this
//! side borrows its buffer for as long as the volume lives.

use std::sync::Arc;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use volcast::volume::{
    Geometry, Rescale, ScalarType, SharedVoxels, Volume, VolumeData, VolumeHeader, VolumeSource,
    VoxelBytes,
};

/// The bytes of a NumPy array, kept alive by a reference to it.
struct ArrayBytes {
    /// The array: its buffer stays where it is while referenced (NumPy refuses to
    /// resize an array that others reference).
    _array: Py<PyAny>,
    ptr: usize,
    len: usize,
}

impl VoxelBytes for ArrayBytes {
    fn bytes(&self) -> &[u8] {
        if self.len == 0 {
            return &[];
        }
        // SAFETY: `ptr` is the address of the array's buffer of `len` bytes (from
        // `ndarray.ctypes.data` and `ndarray.nbytes`), which lives, unmoved, as long
        // as `_array` holds a reference to the array.
        unsafe { std::slice::from_raw_parts(self.ptr as *const u8, self.len) }
    }
}

/// The scalar type of a NumPy dtype name (`int8` ... `float64`).
fn scalar_type(name: &str) -> Option<ScalarType> {
    Some(match name {
        "int8" => ScalarType::Int8,
        "uint8" => ScalarType::Uint8,
        "int16" => ScalarType::Int16,
        "uint16" => ScalarType::Uint16,
        "int32" => ScalarType::Int32,
        "uint32" => ScalarType::Uint32,
        "int64" => ScalarType::Int64,
        "uint64" => ScalarType::Uint64,
        "float32" => ScalarType::Float32,
        "float64" => ScalarType::Float64,
        _ => return None,
    })
}

/// The in-memory source of a Fortran-contiguous array of native byte order with
/// `shape` and NumPy dtype `dtype`, whose buffer starts at `ptr` and holds `nbytes`.
#[allow(clippy::too_many_arguments)]
pub fn source(
    array: Py<PyAny>,
    ptr: usize,
    nbytes: usize,
    dtype: &str,
    shape: [usize; 3],
    spacing: [f64; 3],
    origin: [f64; 3],
) -> PyResult<VolumeSource> {
    let ty = scalar_type(dtype)
        .ok_or_else(|| PyValueError::new_err(format!("volume: dtype {dtype} is not supported")))?;
    let count = shape.iter().product::<usize>();
    if count.checked_mul(ty.size()) != Some(nbytes) {
        return Err(PyValueError::new_err(format!(
            "volume: {nbytes} bytes do not hold {} x {} x {} {dtype} voxels",
            shape[0], shape[1], shape[2]
        )));
    }
    let owner = Arc::new(ArrayBytes {
        _array: array,
        ptr,
        len: nbytes,
    });
    let shared = SharedVoxels::new(ty, owner).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let mut geometry = Geometry::from_spacing(spacing);
    geometry.origin = origin.into();
    if !geometry.is_valid() {
        return Err(PyValueError::new_err(format!(
            "volume: spacing {spacing:?} and origin {origin:?} must be finite, the spacings non-zero"
        )));
    }
    let header = VolumeHeader {
        sizes: shape,
        scalar_type: ty,
        geometry,
        source: format!("a {} x {} x {} {dtype} array", shape[0], shape[1], shape[2]),
        fields: Vec::new(),
        rescale: Rescale::default(),
    };
    Ok(VolumeSource::Memory(Arc::new(Volume {
        header,
        data: VolumeData::Shared(shared),
    })))
}
