//! Scalar element types and the native-typed voxel storage.
//!
//! A volume keeps its data in the type it was stored in (an 8-bit volume costs one
//! byte per voxel); samplers convert single voxels to `f32` when they read them.

use super::mapped::MappedVoxels;

/// The element type of a volume or image, with the names the NRRD format uses.
pub use nrrd::ScalarType;

mod sealed {
    /// Only this module's primitive types are voxels: samplers rely on their
    /// contract (every bit pattern valid, [`super::Voxel::lut_index`] in range).
    pub trait Sealed {}
}

/// A voxel element type: converts to `f64` exactly where the type allows, and
/// decodes itself from bytes of either endianness. Implemented for the ten
/// primitive number types of NRRD only (sealed).
pub trait Voxel: sealed::Sealed + Copy + Send + Sync + 'static {
    /// The matching [`ScalarType`].
    const TYPE: ScalarType;
    /// The value as `f64` (exact for every type but 64-bit integers beyond 2^53).
    fn to_f64(self) -> f64;
    /// Decodes one element from `Self::TYPE.size()` bytes.
    fn from_bytes(bytes: &[u8], little_endian: bool) -> Self;
    /// Converts from `f64` by rounding and saturating (integers) or rounding (floats).
    fn from_f64(v: f64) -> Self;
    /// Entries of a lookup table indexed by [`Voxel::lut_index`]: 256 or 65536 for
    /// 8- and 16-bit types (so a normalisation can be one table load), 0 otherwise.
    const LUT_SIZE: usize = 0;
    /// The value's position in a table of `LUT_SIZE` entries, in increasing order
    /// of value (only called when `LUT_SIZE > 0`); always below `LUT_SIZE`.
    #[inline(always)]
    fn lut_index(self) -> usize {
        0
    }
    /// The value at table position `i` (inverse of `lut_index`).
    fn lut_value(_i: usize) -> f64 {
        0.0
    }
}

/// Implements [`Voxel`] for a primitive: `$round` converts an `f64` (rounding for
/// integers, where `as` also saturates and maps NaN to 0); `$($lut)*` adds the
/// lookup-table methods for 8- and 16-bit types, indexing through the wider `$wide`.
macro_rules! impl_voxel {
    ($t:ty, $st:expr, $round:expr $(, lut $wide:ty)?) => {
        impl sealed::Sealed for $t {}
        impl Voxel for $t {
            const TYPE: ScalarType = $st;
            // `$wide` is twice as wide as `$t`: 2^(bits of $t) entries
            $(const LUT_SIZE: usize = 1 << (4 * std::mem::size_of::<$wide>());)?
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn from_bytes(bytes: &[u8], little_endian: bool) -> Self {
                let arr: [u8; std::mem::size_of::<$t>()] = bytes[..std::mem::size_of::<$t>()]
                    .try_into()
                    .expect("caller passes at least size_of::<T>() bytes");
                if little_endian {
                    <$t>::from_le_bytes(arr)
                } else {
                    <$t>::from_be_bytes(arr)
                }
            }
            #[inline]
            fn from_f64(v: f64) -> Self {
                let round: fn(f64) -> f64 = $round;
                round(v) as $t
            }
            $(
                #[inline(always)]
                fn lut_index(self) -> usize {
                    (self as $wide - <$t>::MIN as $wide) as usize
                }
                fn lut_value(i: usize) -> f64 {
                    (i as $wide + <$t>::MIN as $wide) as f64
                }
            )?
        }
    };
}

impl_voxel!(i8, ScalarType::Int8, f64::round, lut i16);
impl_voxel!(u8, ScalarType::Uint8, f64::round, lut i16);
impl_voxel!(i16, ScalarType::Int16, f64::round, lut i32);
impl_voxel!(u16, ScalarType::Uint16, f64::round, lut i32);
impl_voxel!(i32, ScalarType::Int32, f64::round);
impl_voxel!(u32, ScalarType::Uint32, f64::round);
impl_voxel!(i64, ScalarType::Int64, f64::round);
impl_voxel!(u64, ScalarType::Uint64, f64::round);
impl_voxel!(f32, ScalarType::Float32, |v| v);
impl_voxel!(f64, ScalarType::Float64, |v| v);

impl Voxels<'_, f32> {
    /// Whether every voxel lies in [0, 1] (NaN does not): read in parallel, once
    /// per run for a float32 volume whose window is [0, 1], so that sampling can
    /// skip the clamp of each voxel ([`Grid::with_unit_voxels`](crate::sample::Grid::with_unit_voxels)).
    pub fn all_in_unit_interval(&self) -> bool {
        use rayon::prelude::*;
        // whole voxels per chunk: a multiple of 4 bytes
        self.bytes.par_chunks(1 << 20).all(|chunk| {
            chunk.chunks_exact(4).all(|b| {
                let v = f32::from_ne_bytes([b[0], b[1], b[2], b[3]]);
                (0.0..=1.0).contains(&v)
            })
        })
    }
}

impl Voxels<'_, u8> {
    /// The smallest and the largest voxel (`[255, 0]` for no voxels), read in
    /// parallel: once per run for an 8-bit volume whose own window does not cover
    /// every byte value, to learn whether it covers the data
    /// ([`Grid::with_raw_bytes`](crate::sample::Grid::with_raw_bytes)).
    pub fn byte_range(&self) -> [u8; 2] {
        use rayon::prelude::*;
        self.bytes
            .par_chunks(1 << 20)
            .map(|chunk| {
                chunk
                    .iter()
                    .fold([u8::MAX, 0], |[lo, hi], &b| [lo.min(b), hi.max(b)])
            })
            .reduce(|| [u8::MAX, 0], |a, b| [a[0].min(b[0]), a[1].max(b[1])])
    }
}

/// A read-only view of voxels of type `T` in native byte order, x fastest: the
/// storage the renderer samples. The bytes may sit at any address (a memory-mapped
/// file's data starts wherever its header ends), so elements are read with
/// unaligned loads, which cost the same as aligned ones on the CPUs volcast targets.
#[derive(Clone, Copy, Debug)]
pub struct Voxels<'a, T> {
    bytes: &'a [u8],
    len: usize,
    _type: std::marker::PhantomData<T>,
}

impl<'a, T: Voxel> From<&'a [T]> for Voxels<'a, T> {
    fn from(values: &'a [T]) -> Self {
        Voxels::from_slice(values)
    }
}

impl<'a, T: Voxel> From<&'a Vec<T>> for Voxels<'a, T> {
    fn from(values: &'a Vec<T>) -> Self {
        Voxels::from_slice(values)
    }
}

impl<'a, T: Voxel> Voxels<'a, T> {
    /// The voxels in `bytes` (native byte order; `bytes.len()` a multiple of the
    /// element size, any alignment).
    pub fn from_bytes(bytes: &'a [u8]) -> Voxels<'a, T> {
        let size = std::mem::size_of::<T>();
        assert_eq!(bytes.len() % size, 0, "whole elements");
        Voxels {
            bytes,
            len: bytes.len() / size,
            _type: std::marker::PhantomData,
        }
    }

    /// The voxels of a typed slice.
    pub fn from_slice(values: &'a [T]) -> Voxels<'a, T> {
        // SAFETY: `T` is a primitive number (the `Voxel` implementations), without
        // padding, so its values' memory is `size_of_val` initialised bytes.
        let bytes = unsafe {
            std::slice::from_raw_parts(values.as_ptr().cast::<u8>(), std::mem::size_of_val(values))
        };
        Voxels::from_bytes(bytes)
    }

    /// Number of voxels.
    #[inline(always)]
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when there are no voxels.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Voxel `i` (panics when `i >= len()`).
    #[inline(always)]
    pub fn get(&self, i: usize) -> T {
        assert!(i < self.len, "voxel index {i} out of {}", self.len);
        // SAFETY: `i < len` and `len * size_of::<T>() <= bytes.len()`, so the element
        // lies inside `bytes`; every bit pattern is a valid `T` (primitive numbers);
        // `read_unaligned` has no alignment requirement.
        unsafe {
            self.bytes
                .as_ptr()
                .add(i * std::mem::size_of::<T>())
                .cast::<T>()
                .read_unaligned()
        }
    }

    /// The eight corners of a trilinear cell, with one bounds check: voxels `base`,
    /// `+ dx`, `+ dy`, `+ dx + dy`, `+ dz`, `+ dz + dx`, `+ dz + dy`, `+ dz + dy + dx`
    /// (corner `(a, b, c)` at index `a + 2 b + 4 c`).
    #[inline(always)]
    pub fn corners(&self, base: usize, dx: usize, dy: usize, dz: usize) -> [T; 8] {
        let last = base + dx + dy + dz;
        assert!(last < self.len, "voxel index {last} out of {}", self.len);
        // SAFETY: the largest index, `last`, was checked just above.
        unsafe { self.corners_unchecked(base, dx, dy, dz) }
    }

    /// [`Voxels::corners`] without the bounds check, for callers that derive the
    /// indices from positions clamped to the grid.
    ///
    /// # Safety
    /// `base + dx + dy + dz < self.len()` (the largest of the eight indices).
    #[inline(always)]
    pub unsafe fn corners_unchecked(&self, base: usize, dx: usize, dy: usize, dz: usize) -> [T; 8] {
        let last = base + dx + dy + dz;
        debug_assert!(last < self.len, "voxel index {last} out of {}", self.len);
        let p = self.bytes.as_ptr();
        let size = std::mem::size_of::<T>();
        // SAFETY: every index is at most `last < len` (the caller's promise).
        let at = |i: usize| unsafe { p.add(i * size).cast::<T>().read_unaligned() };
        [
            at(base),
            at(base + dx),
            at(base + dy),
            at(base + dy + dx),
            at(base + dz),
            at(base + dz + dx),
            at(base + dz + dy),
            at(last),
        ]
    }

    /// The address of voxel 0 (for vector loads; see [`Voxels::corners_unchecked`]
    /// for the bounds the caller must keep).
    #[inline(always)]
    pub fn as_ptr(&self) -> *const u8 {
        self.bytes.as_ptr()
    }

    /// The same bytes read as another type of the same size (the raw bits of
    /// signed 8- and 16-bit voxels as unsigned ones, for tables indexed by bits).
    pub fn reinterpret<U: Voxel>(self) -> Voxels<'a, U> {
        assert_eq!(
            std::mem::size_of::<T>(),
            std::mem::size_of::<U>(),
            "same element size"
        );
        Voxels {
            bytes: self.bytes,
            len: self.len,
            _type: std::marker::PhantomData,
        }
    }

    /// Every voxel, in order.
    pub fn iter(&self) -> impl Iterator<Item = T> + 'a {
        let size = std::mem::size_of::<T>();
        self.bytes.chunks_exact(size).map(|c| {
            // SAFETY: `c` holds `size_of::<T>()` bytes; every bit pattern is a
            // valid `T`; `read_unaligned` has no alignment requirement.
            unsafe { c.as_ptr().cast::<T>().read_unaligned() }
        })
    }

    /// The voxels with indices in `range` (panics when it is not inside `0..len()`).
    pub fn slice(&self, range: std::ops::Range<usize>) -> Voxels<'a, T> {
        assert!(
            range.start <= range.end && range.end <= self.len,
            "voxel range {range:?} out of {}",
            self.len
        );
        let size = std::mem::size_of::<T>();
        Voxels::from_bytes(&self.bytes[range.start * size..range.end * size])
    }

    /// The voxels' bytes, in native byte order.
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// The voxels as a `&[T]`, when their address is aligned for `T`: always for
    /// owned data; for mapped data when the data's offset in the file is a multiple of
    /// the element's alignment.
    pub fn as_slice(&self) -> Option<&'a [T]> {
        if self.bytes.as_ptr().align_offset(std::mem::align_of::<T>()) != 0 {
            return None;
        }
        // SAFETY: the pointer is aligned for `T` (checked), `len * size_of::<T>()`
        // bytes are readable for `'a`, and every bit pattern is a valid `T` (primitive
        // numbers). An empty view has a dangling-but-aligned or real pointer: fine too.
        Some(unsafe { std::slice::from_raw_parts(self.bytes.as_ptr().cast::<T>(), self.len) })
    }

    /// The voxels as a typed slice, for code that needs `&[T]` (the render core
    /// before it reads [`Voxels`]): borrowed when aligned ([`Voxels::as_slice`]: owned
    /// data, or mapped data at an offset that is a multiple of the alignment),
    /// otherwise copied into a new buffer of `len()` elements, which is memory volcast
    /// allocates and therefore checked against `limits` first. Only unaligned mapped
    /// data (e.g. 16-bit voxels after an attached NRRD header of odd length) is copied.
    pub fn to_aligned(
        &self,
        limits: &super::Limits,
    ) -> Result<std::borrow::Cow<'a, [T]>, super::VolumeError> {
        if let Some(s) = self.as_slice() {
            return Ok(std::borrow::Cow::Borrowed(s));
        }
        let bytes = self.bytes.len() as u64;
        if bytes > limits.max_bytes {
            return Err(super::VolumeError::TooLarge {
                what: format!(
                    "an aligned copy of the {} mapped {} voxels (they start at an offset of \
                     the file that is not a multiple of {} bytes)",
                    self.len,
                    T::TYPE,
                    std::mem::align_of::<T>()
                ),
                bytes: Some(bytes),
                limit: limits.max_bytes,
            });
        }
        Ok(std::borrow::Cow::Owned(self.iter().collect()))
    }
}

/// Voxel values in their native type, x fastest: owned (read, decoded or computed
/// into memory volcast allocated) or mapped from a file ([`MappedVoxels`]). Read them
/// through [`VolumeData::voxels`] or [`with_voxels!`](crate::with_voxels), which work
/// for both.
///
/// Equality compares the element type and the values (like `Vec` equality: NaN is
/// unequal to itself), whatever the storage.
#[derive(Clone, Debug)]
pub enum VolumeData {
    /// `int8`
    I8(Vec<i8>),
    /// `uint8`
    U8(Vec<u8>),
    /// `int16`
    I16(Vec<i16>),
    /// `uint16`
    U16(Vec<u16>),
    /// `int32`
    I32(Vec<i32>),
    /// `uint32`
    U32(Vec<u32>),
    /// `int64`
    I64(Vec<i64>),
    /// `uint64`
    U64(Vec<u64>),
    /// `float`
    F32(Vec<f32>),
    /// `double`
    F64(Vec<f64>),
    /// Any type, mapped read-only from a file.
    Mapped(MappedVoxels),
    /// Any type, in a buffer the caller owns (a NumPy array), used in place.
    Shared(super::shared::SharedVoxels),
}

/// A [`Voxels`] view tagged with its element type: what [`VolumeData::typed`] returns,
/// for dispatching generic code on the element type (see [`with_voxels!`](crate::with_voxels)).
#[derive(Clone, Copy, Debug)]
pub enum TypedVoxels<'a> {
    /// `int8`
    I8(Voxels<'a, i8>),
    /// `uint8`
    U8(Voxels<'a, u8>),
    /// `int16`
    I16(Voxels<'a, i16>),
    /// `uint16`
    U16(Voxels<'a, u16>),
    /// `int32`
    I32(Voxels<'a, i32>),
    /// `uint32`
    U32(Voxels<'a, u32>),
    /// `int64`
    I64(Voxels<'a, i64>),
    /// `uint64`
    U64(Voxels<'a, u64>),
    /// `float`
    F32(Voxels<'a, f32>),
    /// `double`
    F64(Voxels<'a, f64>),
}

impl<'a> TypedVoxels<'a> {
    /// The element type.
    pub fn scalar_type(self) -> ScalarType {
        fn of<T: Voxel>(_: Voxels<'_, T>) -> ScalarType {
            T::TYPE
        }
        crate::with_voxels!(self, v => of(v))
    }

    /// The number of elements.
    pub fn len(self) -> usize {
        crate::with_voxels!(self, v => v.len())
    }

    /// Whether there are no elements.
    pub fn is_empty(self) -> bool {
        self.len() == 0
    }
}

impl<'a> From<&'a VolumeData> for TypedVoxels<'a> {
    fn from(data: &'a VolumeData) -> TypedVoxels<'a> {
        data.typed()
    }
}

/// Calls `$body` with `$v` bound to the [`Voxels`] view of a [`VolumeData`] (owned or
/// mapped) or of a [`TypedVoxels`], typed with its element type:
/// `with_voxels!(&volume.data, v => f(v))` calls `f::<u16>(v: Voxels<u16>)` for 16-bit
/// data, and so on.
#[macro_export]
macro_rules! with_voxels {
    ($data:expr, $v:ident => $body:expr) => {
        match $crate::volume::TypedVoxels::from($data) {
            $crate::volume::TypedVoxels::I8($v) => $body,
            $crate::volume::TypedVoxels::U8($v) => $body,
            $crate::volume::TypedVoxels::I16($v) => $body,
            $crate::volume::TypedVoxels::U16($v) => $body,
            $crate::volume::TypedVoxels::I32($v) => $body,
            $crate::volume::TypedVoxels::U32($v) => $body,
            $crate::volume::TypedVoxels::I64($v) => $body,
            $crate::volume::TypedVoxels::U64($v) => $body,
            $crate::volume::TypedVoxels::F32($v) => $body,
            $crate::volume::TypedVoxels::F64($v) => $body,
        }
    };
}

impl VolumeData {
    /// The element type.
    pub fn scalar_type(&self) -> ScalarType {
        match self {
            VolumeData::I8(_) => ScalarType::Int8,
            VolumeData::U8(_) => ScalarType::Uint8,
            VolumeData::I16(_) => ScalarType::Int16,
            VolumeData::U16(_) => ScalarType::Uint16,
            VolumeData::I32(_) => ScalarType::Int32,
            VolumeData::U32(_) => ScalarType::Uint32,
            VolumeData::I64(_) => ScalarType::Int64,
            VolumeData::U64(_) => ScalarType::Uint64,
            VolumeData::F32(_) => ScalarType::Float32,
            VolumeData::F64(_) => ScalarType::Float64,
            VolumeData::Mapped(m) => m.scalar_type(),
            VolumeData::Shared(s) => s.scalar_type(),
        }
    }

    /// The voxels' bytes in native byte order (owned or mapped).
    fn native_bytes(&self) -> &[u8] {
        fn of<T: Voxel>(v: &[T]) -> &[u8] {
            Voxels::from_slice(v).bytes
        }
        match self {
            VolumeData::I8(v) => of(v),
            VolumeData::U8(v) => v,
            VolumeData::I16(v) => of(v),
            VolumeData::U16(v) => of(v),
            VolumeData::I32(v) => of(v),
            VolumeData::U32(v) => of(v),
            VolumeData::I64(v) => of(v),
            VolumeData::U64(v) => of(v),
            VolumeData::F32(v) => of(v),
            VolumeData::F64(v) => of(v),
            VolumeData::Mapped(m) => m.bytes(),
            VolumeData::Shared(s) => s.bytes(),
        }
    }

    /// The voxels as a typed view, when they are of type `T` (owned or mapped alike).
    pub fn voxels<T: Voxel>(&self) -> Option<Voxels<'_, T>> {
        (self.scalar_type() == T::TYPE).then(|| Voxels::from_bytes(self.native_bytes()))
    }

    /// The voxels as a view tagged with their type.
    pub fn typed(&self) -> TypedVoxels<'_> {
        let b = self.native_bytes();
        match self.scalar_type() {
            ScalarType::Int8 => TypedVoxels::I8(Voxels::from_bytes(b)),
            ScalarType::Uint8 => TypedVoxels::U8(Voxels::from_bytes(b)),
            ScalarType::Int16 => TypedVoxels::I16(Voxels::from_bytes(b)),
            ScalarType::Uint16 => TypedVoxels::U16(Voxels::from_bytes(b)),
            ScalarType::Int32 => TypedVoxels::I32(Voxels::from_bytes(b)),
            ScalarType::Uint32 => TypedVoxels::U32(Voxels::from_bytes(b)),
            ScalarType::Int64 => TypedVoxels::I64(Voxels::from_bytes(b)),
            ScalarType::Uint64 => TypedVoxels::U64(Voxels::from_bytes(b)),
            ScalarType::Float32 => TypedVoxels::F32(Voxels::from_bytes(b)),
            ScalarType::Float64 => TypedVoxels::F64(Voxels::from_bytes(b)),
        }
    }

    /// The mapping, when the voxels are mapped from a file.
    pub fn mapped(&self) -> Option<&MappedVoxels> {
        match self {
            VolumeData::Mapped(m) => Some(m),
            _ => None,
        }
    }

    /// True when the voxels are mapped from a file rather than held in memory.
    pub fn is_mapped(&self) -> bool {
        self.mapped().is_some()
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.native_bytes().len() / self.scalar_type().size()
    }

    /// True when there are no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes of voxel data, owned or mapped (see [`VolumeData::allocated_bytes`]).
    pub fn byte_len(&self) -> usize {
        self.native_bytes().len()
    }

    /// Bytes of voxel data held in memory volcast allocated (0 when mapped or
    /// shared).
    pub fn allocated_bytes(&self) -> usize {
        if self.is_mapped() || matches!(self, VolumeData::Shared(_)) {
            0
        } else {
            self.byte_len()
        }
    }

    /// Element `i` as `f64` (panics when `i >= len()`).
    pub fn get_f64(&self, i: usize) -> f64 {
        with_voxels!(self, v => v.get(i).to_f64())
    }

    /// Decodes `count` elements of type `ty` from `bytes` (exactly `count * ty.size()`
    /// bytes are read).
    pub fn from_bytes(ty: ScalarType, bytes: &[u8], little_endian: bool) -> VolumeData {
        fn dec<T: Voxel>(bytes: &[u8], le: bool) -> Vec<T> {
            let n = T::TYPE.size();
            bytes
                .chunks_exact(n)
                .map(|c| T::from_bytes(c, le))
                .collect()
        }
        match ty {
            ScalarType::Int8 => VolumeData::I8(dec(bytes, little_endian)),
            ScalarType::Uint8 => VolumeData::U8(bytes.to_vec()),
            ScalarType::Int16 => VolumeData::I16(dec(bytes, little_endian)),
            ScalarType::Uint16 => VolumeData::U16(dec(bytes, little_endian)),
            ScalarType::Int32 => VolumeData::I32(dec(bytes, little_endian)),
            ScalarType::Uint32 => VolumeData::U32(dec(bytes, little_endian)),
            ScalarType::Int64 => VolumeData::I64(dec(bytes, little_endian)),
            ScalarType::Uint64 => VolumeData::U64(dec(bytes, little_endian)),
            ScalarType::Float32 => VolumeData::F32(dec(bytes, little_endian)),
            ScalarType::Float64 => VolumeData::F64(dec(bytes, little_endian)),
        }
    }

    /// Builds data of type `ty` from `f64` values (used by the ASCII encoding and tests).
    pub fn from_f64s(ty: ScalarType, values: &[f64]) -> VolumeData {
        fn conv<T: Voxel>(values: &[f64]) -> Vec<T> {
            values.iter().map(|&v| T::from_f64(v)).collect()
        }
        match ty {
            ScalarType::Int8 => VolumeData::I8(conv(values)),
            ScalarType::Uint8 => VolumeData::U8(conv(values)),
            ScalarType::Int16 => VolumeData::I16(conv(values)),
            ScalarType::Uint16 => VolumeData::U16(conv(values)),
            ScalarType::Int32 => VolumeData::I32(conv(values)),
            ScalarType::Uint32 => VolumeData::U32(conv(values)),
            ScalarType::Int64 => VolumeData::I64(conv(values)),
            ScalarType::Uint64 => VolumeData::U64(conv(values)),
            ScalarType::Float32 => VolumeData::F32(conv(values)),
            ScalarType::Float64 => VolumeData::F64(conv(values)),
        }
    }
}

impl From<nrrd::Data> for VolumeData {
    fn from(d: nrrd::Data) -> VolumeData {
        match d {
            nrrd::Data::I8(v) => VolumeData::I8(v),
            nrrd::Data::U8(v) => VolumeData::U8(v),
            nrrd::Data::I16(v) => VolumeData::I16(v),
            nrrd::Data::U16(v) => VolumeData::U16(v),
            nrrd::Data::I32(v) => VolumeData::I32(v),
            nrrd::Data::U32(v) => VolumeData::U32(v),
            nrrd::Data::I64(v) => VolumeData::I64(v),
            nrrd::Data::U64(v) => VolumeData::U64(v),
            nrrd::Data::F32(v) => VolumeData::F32(v),
            nrrd::Data::F64(v) => VolumeData::F64(v),
            nrrd::Data::Mapped(m) => VolumeData::Mapped(m),
        }
    }
}

impl PartialEq for VolumeData {
    fn eq(&self, other: &VolumeData) -> bool {
        fn same<T: Voxel + PartialEq>(a: Voxels<'_, T>, other: &VolumeData) -> bool {
            other
                .voxels::<T>()
                .is_some_and(|b| a.len() == b.len() && a.iter().eq(b.iter()))
        }
        with_voxels!(self, v => same(v, other))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_range_spans_every_chunk() {
        // several chunks, the extremes in different ones
        let mut v = vec![100u8; 3 << 20];
        assert_eq!(Voxels::from_slice(&v).byte_range(), [100, 100]);
        v[5] = 7;
        v[(2 << 20) + 3] = 201;
        assert_eq!(Voxels::from_slice(&v).byte_range(), [7, 201]);
        assert_eq!(Voxels::<u8>::from_slice(&[]).byte_range(), [255, 0]);
    }

    #[test]
    fn unit_interval_check_takes_both_zeros_and_ends_and_refuses_the_rest() {
        // long enough for several chunks, the odd voxel last
        let mut v = vec![0.5f32; 700_000];
        v[1] = -0.0;
        v[2] = 1.0;
        v[3] = 0.0;
        assert!(Voxels::from_slice(&v).all_in_unit_interval());
        for bad in [
            f32::NAN,
            -f32::from_bits(1),
            1.0 + f32::EPSILON,
            f32::INFINITY,
            -1.0,
        ] {
            let last = v.len() - 1;
            v[last] = bad;
            assert!(!Voxels::from_slice(&v).all_in_unit_interval(), "{bad}");
        }
        // at an address that is not a multiple of 4
        let bytes: Vec<u8> = std::iter::once(0u8)
            .chain([0.25f32, 1.0, 0.0].iter().flat_map(|x| x.to_ne_bytes()))
            .collect();
        assert!(Voxels::<f32>::from_bytes(&bytes[1..]).all_in_unit_interval());
    }

    #[test]
    fn aliases_parse() {
        assert_eq!(
            ScalarType::parse("unsigned  short INT"),
            Some(ScalarType::Uint16)
        );
        assert_eq!(ScalarType::parse("uchar"), Some(ScalarType::Uint8));
        assert_eq!(ScalarType::parse("longlong"), Some(ScalarType::Int64));
        assert_eq!(ScalarType::parse("double"), Some(ScalarType::Float64));
        assert_eq!(ScalarType::parse("block"), None);
        for t in ScalarType::ALL {
            assert_eq!(ScalarType::parse(t.nrrd_name()), Some(t));
        }
    }

    #[test]
    fn lookup_tables_cover_the_type_in_order() {
        fn check<T: Voxel + PartialOrd>(lo: T, hi: T) {
            assert_eq!(lo.lut_index(), 0);
            assert_eq!(hi.lut_index(), T::LUT_SIZE - 1);
            assert_eq!(T::lut_value(0), lo.to_f64());
            assert_eq!(T::lut_value(T::LUT_SIZE - 1), hi.to_f64());
        }
        check(i8::MIN, i8::MAX);
        check(u8::MIN, u8::MAX);
        check(i16::MIN, i16::MAX);
        check(u16::MIN, u16::MAX);
        assert_eq!(<f32 as Voxel>::LUT_SIZE, 0);
        assert_eq!((-3i16).lut_index(), 32765);
    }

    #[test]
    fn views_at_any_alignment() {
        let values = [1u16, 0xfffe, 300, 7];
        let mut bytes = vec![0u8];
        for v in values {
            bytes.extend(v.to_ne_bytes());
        }
        // the same bytes at an odd and at an even address
        let aligned = VolumeData::U16(values.to_vec());
        let owned = aligned.voxels::<u16>().unwrap();
        let odd = if bytes[1..].as_ptr().align_offset(2) == 0 {
            bytes.push(0);
            bytes.copy_within(1..9, 2);
            Voxels::<u16>::from_bytes(&bytes[2..10])
        } else {
            Voxels::<u16>::from_bytes(&bytes[1..9])
        };
        assert!(owned.as_slice().is_some());
        assert!(odd.as_slice().is_none());
        let limits = super::super::Limits { max_bytes: 8 };
        let copy = odd.to_aligned(&limits).unwrap();
        assert!(matches!(copy, std::borrow::Cow::Owned(_)));
        assert_eq!(&*copy, &values[..]);
        let tight = super::super::Limits { max_bytes: 7 };
        assert!(odd.to_aligned(&tight).is_err());
        let borrowed = owned.to_aligned(&tight).unwrap();
        assert!(matches!(borrowed, std::borrow::Cow::Borrowed(_)));
        assert_eq!(odd.iter().collect::<Vec<_>>(), values);
        assert_eq!(odd.slice(1..3).iter().collect::<Vec<_>>(), [0xfffe, 300]);
        assert!(odd.slice(4..4).is_empty());
        assert!(aligned.voxels::<i16>().is_none());
        assert_eq!(aligned.get_f64(1), 65534.0);
        assert_eq!((aligned.len(), aligned.byte_len()), (4, 8));
        assert!(!aligned.is_mapped());
        assert_ne!(aligned, VolumeData::I16(vec![1, -2, 300, 7]));
        assert_ne!(
            VolumeData::F32(vec![f32::NAN]),
            VolumeData::F32(vec![f32::NAN])
        );
    }

    #[test]
    fn decode_endianness() {
        let d = VolumeData::from_bytes(ScalarType::Int16, &[0x01, 0x02, 0xff, 0xff], false);
        assert_eq!(d, VolumeData::I16(vec![0x0102, -1]));
        let d = VolumeData::from_bytes(ScalarType::Uint16, &[0x01, 0x02], true);
        assert_eq!(d, VolumeData::U16(vec![0x0201]));
    }
}
