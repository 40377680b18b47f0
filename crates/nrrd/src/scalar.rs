//! Element types, the decoded data, and borrowed element bytes for writing.

use std::fmt;

use crate::file::Mapped;

/// The element type of the data (the `type` field), with the names the NRRD format uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ScalarType {
    /// signed 8-bit integer
    Int8,
    /// unsigned 8-bit integer
    Uint8,
    /// signed 16-bit integer
    Int16,
    /// unsigned 16-bit integer
    Uint16,
    /// signed 32-bit integer
    Int32,
    /// unsigned 32-bit integer
    Uint32,
    /// signed 64-bit integer
    Int64,
    /// unsigned 64-bit integer
    Uint64,
    /// IEEE 754 single precision
    Float32,
    /// IEEE 754 double precision
    Float64,
}

impl ScalarType {
    /// Every type, in NRRD's order.
    pub const ALL: [ScalarType; 10] = [
        ScalarType::Int8,
        ScalarType::Uint8,
        ScalarType::Int16,
        ScalarType::Uint16,
        ScalarType::Int32,
        ScalarType::Uint32,
        ScalarType::Int64,
        ScalarType::Uint64,
        ScalarType::Float32,
        ScalarType::Float64,
    ];

    /// Size of one element in bytes.
    pub fn size(self) -> usize {
        match self {
            ScalarType::Int8 | ScalarType::Uint8 => 1,
            ScalarType::Int16 | ScalarType::Uint16 => 2,
            ScalarType::Int32 | ScalarType::Uint32 | ScalarType::Float32 => 4,
            ScalarType::Int64 | ScalarType::Uint64 | ScalarType::Float64 => 8,
        }
    }

    /// The canonical NRRD name (`uint8`, `int16`, `float`, `double`, ...).
    pub fn nrrd_name(self) -> &'static str {
        match self {
            ScalarType::Int8 => "int8",
            ScalarType::Uint8 => "uint8",
            ScalarType::Int16 => "int16",
            ScalarType::Uint16 => "uint16",
            ScalarType::Int32 => "int32",
            ScalarType::Uint32 => "uint32",
            ScalarType::Int64 => "int64",
            ScalarType::Uint64 => "uint64",
            ScalarType::Float32 => "float",
            ScalarType::Float64 => "double",
        }
    }

    /// Parses a type name: the short names used in scene files (`uint8`, `int16`,
    /// `float32`, `float64`) and every alias the NRRD format defines (`uchar`,
    /// `unsigned short int`, `longlong`, `float`, `double`, ...). Case-insensitive,
    /// runs of whitespace count as one space.
    pub fn parse(name: &str) -> Option<ScalarType> {
        let norm: String = name
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
            .to_ascii_lowercase();
        Some(match norm.as_str() {
            "signed char" | "int8" | "int8_t" | "i8" => ScalarType::Int8,
            "uchar" | "unsigned char" | "uint8" | "uint8_t" | "u8" => ScalarType::Uint8,
            "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t"
            | "i16" => ScalarType::Int16,
            "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" | "u16" => {
                ScalarType::Uint16
            }
            "int" | "signed int" | "int32" | "int32_t" | "i32" => ScalarType::Int32,
            "uint" | "unsigned int" | "uint32" | "uint32_t" | "u32" => ScalarType::Uint32,
            "longlong"
            | "long long"
            | "long long int"
            | "signed long long"
            | "signed long long int"
            | "int64"
            | "int64_t"
            | "i64" => ScalarType::Int64,
            "ulonglong"
            | "unsigned long long"
            | "unsigned long long int"
            | "uint64"
            | "uint64_t"
            | "u64" => ScalarType::Uint64,
            "float" | "float32" | "f32" => ScalarType::Float32,
            "double" | "float64" | "f64" => ScalarType::Float64,
            _ => return None,
        })
    }

    /// Number of distinct values of the 8- and 16-bit integer types (256, 65536): the
    /// size of a lookup table indexed by value; 0 for the wider types.
    pub fn lut_size(self) -> usize {
        match self {
            ScalarType::Int8 | ScalarType::Uint8 => 256,
            ScalarType::Int16 | ScalarType::Uint16 => 65536,
            _ => 0,
        }
    }

    /// True for the two floating-point types.
    pub fn is_float(self) -> bool {
        matches!(self, ScalarType::Float32 | ScalarType::Float64)
    }
}

impl fmt::Display for ScalarType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.nrrd_name())
    }
}

/// The Rust number types NRRD elements are decoded into (`i8` ... `u64`, `f32`, `f64`).
pub trait Element: sealed::Sealed + Copy + Send + Sync + 'static {
    /// The NRRD type of this element.
    const TYPE: ScalarType;
    /// Decodes one element from its `size` bytes in the given byte order.
    fn from_bytes(bytes: &[u8], little_endian: bool) -> Self;
    /// Wraps a vector of these elements as [`Data`].
    fn into_data(values: Vec<Self>) -> Data;
}

mod sealed {
    pub trait Sealed {}
}

macro_rules! impl_element {
    ($($t:ty => $st:ident, $var:ident);*) => {$(
        impl sealed::Sealed for $t {}
        impl Element for $t {
            const TYPE: ScalarType = ScalarType::$st;
            fn from_bytes(bytes: &[u8], little_endian: bool) -> Self {
                let mut a = [0u8; std::mem::size_of::<$t>()];
                a.copy_from_slice(&bytes[..std::mem::size_of::<$t>()]);
                if little_endian {
                    <$t>::from_le_bytes(a)
                } else {
                    <$t>::from_be_bytes(a)
                }
            }
            fn into_data(values: Vec<Self>) -> Data {
                Data::$var(values)
            }
        }
    )*};
}

impl_element!(
    i8 => Int8, I8; u8 => Uint8, U8; i16 => Int16, I16; u16 => Uint16, U16;
    i32 => Int32, I32; u32 => Uint32, U32; i64 => Int64, I64; u64 => Uint64, U64;
    f32 => Float32, F32; f64 => Float64, F64
);

/// The data of a NRRD file in its element type, in file order (fastest axis first):
/// decoded into memory, or mapped read-only from the file (raw data in the machine's
/// byte order, see [`Mapped`]).
///
/// Equality compares the element type and the native bytes.
#[derive(Clone, Debug)]
pub enum Data {
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
    Mapped(Mapped),
}

fn slice_bytes<T: Element>(v: &[T]) -> &[u8] {
    // SAFETY: `T` is one of the plain number types (sealed), which have no padding
    // and no invalid bit patterns; the byte slice covers exactly the elements.
    unsafe { std::slice::from_raw_parts(v.as_ptr().cast::<u8>(), std::mem::size_of_val(v)) }
}

impl Data {
    /// The element type.
    pub fn scalar_type(&self) -> ScalarType {
        match self {
            Data::I8(_) => ScalarType::Int8,
            Data::U8(_) => ScalarType::Uint8,
            Data::I16(_) => ScalarType::Int16,
            Data::U16(_) => ScalarType::Uint16,
            Data::I32(_) => ScalarType::Int32,
            Data::U32(_) => ScalarType::Uint32,
            Data::I64(_) => ScalarType::Int64,
            Data::U64(_) => ScalarType::Uint64,
            Data::F32(_) => ScalarType::Float32,
            Data::F64(_) => ScalarType::Float64,
            Data::Mapped(m) => m.scalar_type(),
        }
    }

    /// The elements' bytes in the machine's byte order (mapped bytes may sit at any
    /// alignment).
    pub fn as_bytes(&self) -> &[u8] {
        match self {
            Data::I8(v) => slice_bytes(v),
            Data::U8(v) => v,
            Data::I16(v) => slice_bytes(v),
            Data::U16(v) => slice_bytes(v),
            Data::I32(v) => slice_bytes(v),
            Data::U32(v) => slice_bytes(v),
            Data::I64(v) => slice_bytes(v),
            Data::U64(v) => slice_bytes(v),
            Data::F32(v) => slice_bytes(v),
            Data::F64(v) => slice_bytes(v),
            Data::Mapped(m) => m.bytes(),
        }
    }

    /// A borrowed view of the elements, for [`encode_elements`](crate::encode_elements).
    pub fn elements(&self) -> Elements<'_> {
        Elements {
            scalar_type: self.scalar_type(),
            bytes: self.as_bytes(),
        }
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.as_bytes().len() / self.scalar_type().size()
    }

    /// True when there are no elements.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// True when the data is mapped from a file rather than held in memory.
    pub fn is_mapped(&self) -> bool {
        matches!(self, Data::Mapped(_))
    }

    /// Decodes the elements of type `ty` in `bytes` stored in the given byte order (a
    /// trailing partial element is ignored).
    pub fn from_bytes(ty: ScalarType, bytes: &[u8], little_endian: bool) -> Data {
        fn dec<T: Element>(bytes: &[u8], le: bool) -> Data {
            let n = T::TYPE.size();
            T::into_data(
                bytes
                    .chunks_exact(n)
                    .map(|c| T::from_bytes(c, le))
                    .collect(),
            )
        }
        match ty {
            ScalarType::Int8 => dec::<i8>(bytes, little_endian),
            ScalarType::Uint8 => Data::U8(bytes.to_vec()),
            ScalarType::Int16 => dec::<i16>(bytes, little_endian),
            ScalarType::Uint16 => dec::<u16>(bytes, little_endian),
            ScalarType::Int32 => dec::<i32>(bytes, little_endian),
            ScalarType::Uint32 => dec::<u32>(bytes, little_endian),
            ScalarType::Int64 => dec::<i64>(bytes, little_endian),
            ScalarType::Uint64 => dec::<u64>(bytes, little_endian),
            ScalarType::Float32 => dec::<f32>(bytes, little_endian),
            ScalarType::Float64 => dec::<f64>(bytes, little_endian),
        }
    }
}

impl PartialEq for Data {
    fn eq(&self, other: &Data) -> bool {
        self.scalar_type() == other.scalar_type() && self.as_bytes() == other.as_bytes()
    }
}

/// Elements to write, borrowed: their type and their bytes in the machine's byte
/// order, at any alignment (an image's samples, a mapped file's bytes).
#[derive(Clone, Copy, Debug)]
pub struct Elements<'a> {
    scalar_type: ScalarType,
    bytes: &'a [u8],
}

impl<'a> Elements<'a> {
    /// `bytes` as elements of `ty` in the machine's byte order; `None` unless the
    /// length is a multiple of the type's size.
    pub fn new(ty: ScalarType, bytes: &'a [u8]) -> Option<Elements<'a>> {
        bytes.len().is_multiple_of(ty.size()).then_some(Elements {
            scalar_type: ty,
            bytes,
        })
    }

    /// The elements of a slice.
    pub fn from_slice<T: Element>(values: &'a [T]) -> Elements<'a> {
        Elements {
            scalar_type: T::TYPE,
            bytes: slice_bytes(values),
        }
    }

    /// The element type.
    pub fn scalar_type(&self) -> ScalarType {
        self.scalar_type
    }

    /// The elements' bytes, in the machine's byte order.
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.bytes.len() / self.scalar_type.size()
    }

    /// True when there are no elements.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }
}
