//! Reader and writer of NRRD files, the format of teem's "nearly raw raster data"
//! (<http://teem.sourceforge.net/nrrd/format.html>): every encoding (raw, gzip, bzip2,
//! ascii, hex), attached and detached headers (one data file, a `%d` pattern, a
//! `LIST`), `line skip` and `byte skip`, the space fields, and every element type.
//!
//! ```no_run
//! let (header, data) = nrrd::read(std::path::Path::new("head.nrrd"))?;
//! println!("{:?} {} {:?}", header.sizes, header.scalar_type, header.space_directions);
//! let bytes = nrrd::encode(&header.with_encoding(nrrd::Encoding::Gzip), &data)?;
//! # Ok::<(), nrrd::Error>(())
//! ```
//!
//! Call tree of a load (teem's `nrrdLoad` order):
//!
//! ```text
//! Reader::read(path)
//!  ├─ header::read_raw_header      magic, lines, `#` comments, `key:=value`, LIST names,
//!  │                               offset of attached data (blank line)
//!  ├─ fields::parse_fields         one parser per field (table FIELDS), in dependency order
//!  ├─ check::check_header          required fields, endian, skips, data file pieces, space
//!  └─ data::read_data
//!      ├─ raw encoding, native byte order, one file (attached or `data file: x.raw`):
//!      │   └─ locate_raw           open without blocking, refuse non-regular files,
//!      │                           line skip, byte skip (-1 = last bytes), length
//!      │                           check; then file::map: no copy, no byte limit
//!      └─ anything else: the byte limit (count × type size) before any allocation,
//!         then for each data file (attached, single, %d pattern, LIST):
//!          ├─ skip_lines           `line skip` on the file as stored
//!          ├─ byte skip            raw/ascii/hex: on the file; gzip/bzip2: on the
//!          │                       decompressed stream; -1: data = last bytes (raw only)
//!          └─ codec::ElementSink   decode (raw | gzip | bzip2 | ascii | hex) into the
//!                                  native-typed buffer, honouring `endian`, growing
//!                                  only as bytes arrive
//! encode / encode_elements / write_detached (write.rs)
//! ```
//!
//! Headers are untrusted: every count is checked before it sizes anything, and every
//! error names the file (and for header problems the 1-based line and the field).

#![warn(missing_docs)]

mod check;
mod codec;
mod data;
mod error;
mod fields;
pub mod file;
mod header;
mod scalar;
mod write;

use std::fmt;
use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use codec::{ElementSink, ReadError};
pub use error::{human_bytes, Error};
pub use file::Mapped;
pub use scalar::{Data, Element, Elements, ScalarType};
pub use write::{encode, encode_elements, write_detached, write_detached_elements};

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
}

/// The check run on every file the reader opens (see [`Reader::on_open`]).
pub type OpenHook = dyn Fn(&Path, &File) -> io::Result<()> + Send + Sync;

/// Reading options: a limit on the memory the data may take, and a check of every
/// opened file. `Reader::default()` has no limit and no check.
#[derive(Clone)]
pub struct Reader {
    max_bytes: u64,
    on_open: Option<Arc<OpenHook>>,
}

impl Default for Reader {
    fn default() -> Self {
        Reader {
            max_bytes: u64::MAX,
            on_open: None,
        }
    }
}

impl fmt::Debug for Reader {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Reader")
            .field("max_bytes", &self.max_bytes)
            .field("on_open", &self.on_open.is_some())
            .finish()
    }
}

impl Reader {
    /// A reader with no byte limit and no open check.
    pub fn new() -> Reader {
        Reader::default()
    }

    /// The largest data buffer, in bytes, that reading may allocate; it is checked
    /// against the header's sizes before any allocation ([`Error::TooLarge`]). Mapped
    /// data (see [`Storage::Mapped`]) allocates nothing and is not limited.
    pub fn max_bytes(mut self, max_bytes: u64) -> Reader {
        self.max_bytes = max_bytes;
        self
    }

    /// A check run on every file right after it is opened (header and data files),
    /// before anything is read from it; an error refuses the file
    /// ([`Error::Io`] naming it). Use it to confine reads to a folder, judged from the
    /// opened file rather than its path.
    pub fn on_open(
        mut self,
        check: impl Fn(&Path, &File) -> io::Result<()> + Send + Sync + 'static,
    ) -> Reader {
        self.on_open = Some(Arc::new(check));
        self
    }

    /// Opens `path` without blocking and runs the open check.
    pub(crate) fn open(&self, path: &Path) -> io::Result<File> {
        let file = file::open_nonblocking(path)?;
        if let Some(check) = &self.on_open {
            check(path, &file)?;
        }
        Ok(file)
    }

    /// Reads and checks the header only (no data file is opened).
    pub fn read_header(&self, path: &Path) -> Result<NrrdHeader, Error> {
        Ok(header::load_header(self, path)?.0)
    }

    /// Whether [`Reader::read`] will map the data (raw encoding in native byte order,
    /// attached or in one `data file`) or read it, and how many bytes. For mapped data
    /// the data file is opened to apply `line skip` and `byte skip` and to check its
    /// type and length.
    pub fn storage(&self, path: &Path) -> Result<Storage, Error> {
        let (header, data_offset) = header::load_header(self, path)?;
        data::storage(self, path, &header, data_offset)
    }

    /// Reads header and data; the byte limit is checked before any data memory is
    /// allocated. Raw data in native byte order in one file is mapped instead
    /// ([`Data::Mapped`]) and does not count against the limit.
    pub fn read(&self, path: &Path) -> Result<(NrrdHeader, Data), Error> {
        let (header, data_offset) = header::load_header(self, path)?;
        let (data, _) = data::read_data(self, path, &header, data_offset, false)?;
        Ok((header, data))
    }

    /// [`Reader::read`], also returning the XXH3-128 of the data's bytes as stored
    /// (after decompression, before byte swapping), computed while they are decoded
    /// (mapped data: over the mapped bytes).
    pub fn read_hashed(&self, path: &Path) -> Result<(NrrdHeader, Data, u128), Error> {
        let (header, data_offset) = header::load_header(self, path)?;
        let (data, hash) = data::read_data(self, path, &header, data_offset, true)?;
        Ok((header, data, hash.unwrap_or_default()))
    }

    /// Every file the data at `path` is read from: the header, and each data file.
    pub fn input_files(&self, path: &Path) -> Result<Vec<PathBuf>, Error> {
        let (header, data_offset) = header::load_header(self, path)?;
        let mut files = vec![path.to_path_buf()];
        if header.data_file != DataFile::Attached {
            files.extend(data::data_files(path, &header, data_offset));
        }
        Ok(files)
    }
}

/// Reads and checks the header of `path` only ([`Reader::read_header`] with no limit).
pub fn read_header(path: &Path) -> Result<NrrdHeader, Error> {
    Reader::new().read_header(path)
}

/// Reads header and data of `path` ([`Reader::read`] with no byte limit).
pub fn read(path: &Path) -> Result<(NrrdHeader, Data), Error> {
    Reader::new().read(path)
}

/// How [`Reader::read`] will hold the data, known from the header (and, for mapped
/// data, the data file's length) before reading.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Storage {
    /// Mapped read-only from `path`: `bytes` bytes starting at byte `offset` of the
    /// file. Costs address space and page cache, not allocated memory.
    Mapped {
        /// The file that holds the data (the data file of a detached header).
        path: PathBuf,
        /// Where the data starts in that file, after every header and skip.
        offset: u64,
        /// Bytes mapped (elements × type size).
        bytes: u64,
    },
    /// Read (decoded, decompressed or byte-swapped) into `bytes` bytes of memory.
    Read {
        /// Bytes allocated for the elements (elements × type size).
        bytes: u64,
        /// Why the data cannot be mapped.
        reason: ReadReason,
    },
}

/// Why data is read into memory rather than mapped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadReason {
    /// Multi-byte elements in the other byte order: swapped while reading.
    ByteOrder,
    /// An encoding other than raw (gzip, bzip2, ascii, hex): decoded while reading.
    Encoding(Encoding),
    /// The data is split over this many files (`data file` pattern or `LIST`).
    DataFiles(u64),
}

// The README's example compiles as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeDoctests;
