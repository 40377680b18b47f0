//! NRRD reader and writer (format: <http://teem.sourceforge.net/nrrd/format.html>).
//!
//! Call tree of a load (teem's `nrrdLoad` order):
//!
//! ```text
//! read(path, limits)
//!  ├─ header::read_raw_header      magic, lines, `#` comments, `key:=value`, LIST names,
//!  │                               offset of attached data (blank line)
//!  ├─ fields::parse_fields         one parser per field (table FIELDS), in dependency order
//!  ├─ check::check_header          required fields, endian, skips, data file pieces, space
//!  └─ data::read_data
//!      ├─ raw encoding, native byte order, one file (attached or `data file: x.raw`):
//!      │   └─ locate_raw           open without blocking, refuse non-regular files,
//!      │                           line skip, byte skip (-1 = last bytes), length
//!      │                           check; then mapped::map: no copy, no Limits
//!      └─ anything else: Limits::check (count × type size) before any allocation, then
//!         for each data file (attached, single, %d pattern, LIST):
//!          ├─ skip_lines           `line skip` on the file as stored
//!          ├─ byte skip            raw/ascii/hex: on the file; gzip/bzip2: on the
//!          │                       decompressed stream; -1: data = last bytes (raw only)
//!          └─ codec::ElementSink   decode (raw | gzip | bzip2 | ascii | hex) into the
//!                                  native-typed buffer, honouring `endian`, growing
//!                                  only as bytes arrive
//! volume_header (view.rs)          N-D header → 3D sizes + Geometry for the renderer
//! encode / encode_voxels / write_detached (write.rs)
//! ```
//!
//! Headers are untrusted: every count is checked before it sizes anything, and every
//! error names the file (and for header problems the 1-based line and the field).

mod check;
mod codec;
mod data;
mod fields;
mod header;
mod view;
mod write;

use std::path::Path;

use super::{Limits, ScalarType, Storage, VolumeData, VolumeError, VolumeHeader};

pub(crate) use codec::{ElementSink, ReadError};
pub use write::{encode, encode_voxels, write_detached};

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

impl Encoding {
    /// Parses an encoding name with the spec's aliases (`gz`, `bz2`, `text`, `txt`),
    /// case-insensitively.
    pub fn parse(name: &str) -> Option<Encoding> {
        Some(match name.trim().to_ascii_lowercase().as_str() {
            "raw" => Encoding::Raw,
            "gzip" | "gz" => Encoding::Gzip,
            "bzip2" | "bz2" => Encoding::Bzip2,
            "ascii" | "text" | "txt" => Encoding::Ascii,
            "hex" => Encoding::Hex,
            _ => return None,
        })
    }

    /// The canonical name written in headers.
    pub fn name(self) -> &'static str {
        match self {
            Encoding::Raw => "raw",
            Encoding::Gzip => "gzip",
            Encoding::Bzip2 => "bzip2",
            Encoding::Ascii => "ascii",
            Encoding::Hex => "hex",
        }
    }

    /// True when the byte order of multi-byte elements is visible in the stored data.
    pub fn endian_matters(self) -> bool {
        !matches!(self, Encoding::Ascii)
    }

    /// True for gzip and bzip2.
    pub fn is_compression(self) -> bool {
        matches!(self, Encoding::Gzip | Encoding::Bzip2)
    }
}

/// Byte order of multi-byte elements in the stored data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Endian {
    /// least significant byte first
    Little,
    /// most significant byte first
    Big,
}

impl Endian {
    /// The name written in headers (`little`, `big`).
    pub fn name(self) -> &'static str {
        match self {
            Endian::Little => "little",
            Endian::Big => "big",
        }
    }
}

/// The named spaces of the `space` field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Space {
    /// `right-anterior-superior` (`RAS`)
    RightAnteriorSuperior,
    /// `left-anterior-superior` (`LAS`)
    LeftAnteriorSuperior,
    /// `left-posterior-superior` (`LPS`)
    LeftPosteriorSuperior,
    /// `right-anterior-superior-time` (`RAST`)
    RightAnteriorSuperiorTime,
    /// `left-anterior-superior-time` (`LAST`)
    LeftAnteriorSuperiorTime,
    /// `left-posterior-superior-time` (`LPST`)
    LeftPosteriorSuperiorTime,
    /// `scanner-xyz`
    ScannerXyz,
    /// `scanner-xyz-time`
    ScannerXyzTime,
    /// `3D-right-handed`
    RightHanded3D,
    /// `3D-left-handed`
    LeftHanded3D,
    /// `3D-right-handed-time`
    RightHanded3DTime,
    /// `3D-left-handed-time`
    LeftHanded3DTime,
}

impl Space {
    /// Every named space, with its canonical name, abbreviation (if any) and dimension.
    const TABLE: [(Space, &'static str, &'static str, usize); 12] = [
        (
            Space::RightAnteriorSuperior,
            "right-anterior-superior",
            "RAS",
            3,
        ),
        (
            Space::LeftAnteriorSuperior,
            "left-anterior-superior",
            "LAS",
            3,
        ),
        (
            Space::LeftPosteriorSuperior,
            "left-posterior-superior",
            "LPS",
            3,
        ),
        (
            Space::RightAnteriorSuperiorTime,
            "right-anterior-superior-time",
            "RAST",
            4,
        ),
        (
            Space::LeftAnteriorSuperiorTime,
            "left-anterior-superior-time",
            "LAST",
            4,
        ),
        (
            Space::LeftPosteriorSuperiorTime,
            "left-posterior-superior-time",
            "LPST",
            4,
        ),
        (Space::ScannerXyz, "scanner-xyz", "", 3),
        (Space::ScannerXyzTime, "scanner-xyz-time", "", 4),
        (Space::RightHanded3D, "3D-right-handed", "", 3),
        (Space::LeftHanded3D, "3D-left-handed", "", 3),
        (Space::RightHanded3DTime, "3D-right-handed-time", "", 4),
        (Space::LeftHanded3DTime, "3D-left-handed-time", "", 4),
    ];

    /// Parses a space name or abbreviation, case-insensitively.
    pub fn parse(name: &str) -> Option<Space> {
        let name = name.trim();
        Space::TABLE
            .iter()
            .find(|(_, long, short, _)| {
                long.eq_ignore_ascii_case(name)
                    || (!short.is_empty() && short.eq_ignore_ascii_case(name))
            })
            .map(|row| row.0)
    }

    fn row(self) -> &'static (Space, &'static str, &'static str, usize) {
        // Every variant is in TABLE, in declaration order.
        &Space::TABLE[self as usize]
    }

    /// The canonical name written in headers.
    pub fn name(self) -> &'static str {
        self.row().1
    }

    /// Number of world coordinates (3, or 4 for the `-time` spaces).
    pub fn dimension(self) -> usize {
        self.row().3
    }
}

/// Where the data of a header lives (`data file` field).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DataFile {
    /// After the header's blank line, in the same file.
    Attached,
    /// One file, relative to the header's folder unless absolute.
    Single(String),
    /// `data file: <format> <min> <max> <step> [<subdim>]`: numbered files made with a
    /// printf-style `%d` format (`slice%03d.raw 1 93 1 2`).
    Pattern {
        /// The file name format, with one `%d`-style conversion.
        format: String,
        /// First number.
        min: i64,
        /// Last number (inclusive).
        max: i64,
        /// Step (non-zero, towards `max`).
        step: i64,
        /// Dimension of the piece in each file (default: dimension − 1).
        subdim: Option<usize>,
    },
    /// `data file: LIST [<subdim>]` followed by one file name per line.
    List {
        /// The file names, in order.
        names: Vec<String>,
        /// Dimension of the piece in each file (default: dimension − 1).
        subdim: Option<usize>,
    },
}

/// A parsed NRRD header. Optional fields are `None` when absent; per-axis lists have
/// one entry per axis (fastest axis first).
#[derive(Clone, Debug, PartialEq)]
pub struct NrrdHeader {
    /// Format version from the magic (`NRRD0004` → 4); the writer uses at least this.
    pub version: u8,
    /// Element type.
    pub scalar_type: ScalarType,
    /// Axis sizes, fastest first (`dimension` is their number).
    pub sizes: Vec<usize>,
    /// Data encoding.
    pub encoding: Encoding,
    /// Byte order of the stored data (little when the header has no `endian` line).
    pub endian: Endian,
    /// `content`: a short description.
    pub content: Option<String>,
    /// `space`: a named world space.
    pub space: Option<Space>,
    /// Dimension of the world space (from `space` or `space dimension`).
    pub space_dimension: Option<usize>,
    /// `space directions`: per axis a world vector, or `None` for `none` (non-spatial axis).
    pub space_directions: Option<Vec<Option<Vec<f64>>>>,
    /// `space origin`: world position of the first sample.
    pub space_origin: Option<Vec<f64>>,
    /// `space units`: one per world coordinate.
    pub space_units: Option<Vec<String>>,
    /// `measurement frame` (parsed and kept, not used by the renderer).
    pub measurement_frame: Option<Vec<Vec<f64>>>,
    /// `spacings` (`NaN` for non-spatial axes).
    pub spacings: Option<Vec<f64>>,
    /// `thicknesses`.
    pub thicknesses: Option<Vec<f64>>,
    /// `axis mins`.
    pub axis_mins: Option<Vec<f64>>,
    /// `axis maxs`.
    pub axis_maxs: Option<Vec<f64>>,
    /// `centers` (`cell`, `node`, `???`).
    pub centers: Option<Vec<String>>,
    /// `kinds` (`domain`, `space`, `RGBA-color`, ...).
    pub kinds: Option<Vec<String>>,
    /// `labels`.
    pub labels: Option<Vec<String>>,
    /// `units`: per-axis units of the spacings.
    pub units: Option<Vec<String>>,
    /// `sample units`: units of the values.
    pub sample_units: Option<String>,
    /// `min`.
    pub min: Option<f64>,
    /// `max`.
    pub max: Option<f64>,
    /// `old min`.
    pub old_min: Option<f64>,
    /// `old max`.
    pub old_max: Option<f64>,
    /// Where the data is (not used by [`encode`], which always attaches it).
    pub data_file: DataFile,
    /// `line skip`: lines to skip in each data file before the data.
    pub line_skip: usize,
    /// `byte skip`: bytes to skip after the lines; -1 = the data is the last bytes (raw).
    pub byte_skip: i64,
    /// `#` comments, without the `#` and the spaces after it.
    pub comments: Vec<String>,
    /// `key:=value` pairs, in file order (unescaped).
    pub key_values: Vec<(String, String)>,
}

impl NrrdHeader {
    /// A header for writing `sizes` elements of `scalar_type`, raw, little-endian,
    /// attached, with no optional fields.
    pub fn new(scalar_type: ScalarType, sizes: Vec<usize>) -> NrrdHeader {
        NrrdHeader {
            version: 4,
            scalar_type,
            sizes,
            encoding: Encoding::Raw,
            endian: Endian::Little,
            content: None,
            space: None,
            space_dimension: None,
            space_directions: None,
            space_origin: None,
            space_units: None,
            measurement_frame: None,
            spacings: None,
            thicknesses: None,
            axis_mins: None,
            axis_maxs: None,
            centers: None,
            kinds: None,
            labels: None,
            units: None,
            sample_units: None,
            min: None,
            max: None,
            old_min: None,
            old_max: None,
            data_file: DataFile::Attached,
            line_skip: 0,
            byte_skip: 0,
            comments: Vec::new(),
            key_values: Vec::new(),
        }
    }

    /// Sets the per-axis `kinds` (e.g. `["RGBA-color", "space", "space"]`).
    pub fn with_kinds<S: Into<String>>(mut self, kinds: impl IntoIterator<Item = S>) -> Self {
        self.kinds = Some(kinds.into_iter().map(Into::into).collect());
        self
    }

    /// Sets the per-axis `spacings` (`NaN` for non-spatial axes).
    pub fn with_spacings(mut self, spacings: impl IntoIterator<Item = f64>) -> Self {
        self.spacings = Some(spacings.into_iter().collect());
        self
    }

    /// Sets the data encoding.
    pub fn with_encoding(mut self, encoding: Encoding) -> Self {
        self.encoding = encoding;
        self
    }

    /// Number of axes.
    pub fn dimension(&self) -> usize {
        self.sizes.len()
    }

    /// Number of elements (`None` if the product overflows).
    pub fn element_count(&self) -> Option<usize> {
        self.sizes.iter().try_fold(1usize, |a, &s| a.checked_mul(s))
    }

    /// The 3D view of this header used by the renderer: sizes (2D data → one slice,
    /// extra size-1 axes dropped), geometry from `space directions`/`space origin` or
    /// `spacings`, and the descriptive fields.
    pub fn volume_header(&self, path: &Path) -> Result<VolumeHeader, VolumeError> {
        view::volume_header(self, path)
    }
}

/// Reads and checks the header only (no data file is opened).
pub fn read_header(path: &Path) -> Result<NrrdHeader, VolumeError> {
    Ok(header::load_header(path)?.0)
}

/// Whether [`read`] will map the data (raw encoding in native byte order, attached or
/// in one `data file`) or read it, and how many bytes. For mapped data the data file is
/// opened to apply `line skip` and `byte skip` and to check its type and length.
pub fn storage(path: &Path) -> Result<Storage, VolumeError> {
    let (header, data_offset) = header::load_header(path)?;
    data::storage(path, &header, data_offset)
}

/// Reads header and data; `limits` is checked before any voxel memory is allocated.
/// Raw data in native byte order in one file is mapped instead (see
/// [`crate::volume::mapped`]) and does not count against `limits`.
pub fn read(path: &Path, limits: &Limits) -> Result<(NrrdHeader, VolumeData), VolumeError> {
    let (header, data_offset) = header::load_header(path)?;
    let (data, _) = data::read_data(path, &header, data_offset, limits, false)?;
    Ok((header, data))
}

/// [`read`], also returning the XXH3-128 of the data's bytes as stored (after
/// decompression, before byte swapping), computed while they are decoded (mapped
/// data: over the mapped bytes).
pub fn read_hashed(
    path: &Path,
    limits: &Limits,
) -> Result<(NrrdHeader, VolumeData, u128), VolumeError> {
    let (header, data_offset) = header::load_header(path)?;
    let (data, hash) = data::read_data(path, &header, data_offset, limits, true)?;
    Ok((header, data, hash.unwrap_or_default()))
}

/// Every file the volume at `path` is read from: the header, and each data file.
pub fn input_files(path: &Path) -> Result<Vec<std::path::PathBuf>, VolumeError> {
    let (header, data_offset) = header::load_header(path)?;
    let mut files = vec![path.to_path_buf()];
    if header.data_file != DataFile::Attached {
        files.extend(data::data_files(path, &header, data_offset));
    }
    Ok(files)
}
