//! MetaImage reader (ITK's MetaIO: <https://itk.org/Wiki/ITK/MetaIO/Documentation>): a
//! `.mha` file (text header, then the data: `ElementDataFile = LOCAL`) or a `.mhd`
//! header naming its data file, raw or zlib-compressed (`CompressedData = True`).
//!
//! ```text
//! read_header      `Key = Value` lines up to `ElementDataFile` (the last key), each
//!                  checked: NDims, DimSize, ElementType, ElementNumberOfChannels,
//!                  ElementSpacing, Offset, TransformMatrix (and their synonyms,
//!                  chosen as ITK's MetaIO does), byte order, compression,
//!                  HeaderSize; LIST and numbered data files refused by name; keys
//!                  matched case-sensitively, as ITK does
//! MetaSpec::load   uncompressed, native order: lengths checked, mapped
//!                  otherwise: Limits::check, then decoded (zlib, byte swap)
//! ```
//!
//! Voxel `(i, j, k)` sits at `Offset + i s0 d0 + j s1 d1 + k s2 d2`, with `s` the
//! `ElementSpacing` and `d0, d1, d2` the consecutive triples of `TransformMatrix`
//! (ITK's direction columns). World coordinates are the file's (ITK's LPS), not
//! converted.

use crate::volume::errors::unsupported;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use glam::DVec3;

use super::mapped::{is_native_order, open_regular};
use super::stream::{self, Decode};
use super::{Geometry, Limits, ReadReason, ScalarType, Storage, Volume, VolumeError, VolumeHeader};

/// Longest header accepted.
const MAX_HEADER: u64 = 1 << 20;

/// Where the data is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum DataFile {
    /// After the header, in the same file (`LOCAL`); at this byte.
    Local(u64),
    /// A file, relative to the header's folder unless absolute.
    File(PathBuf),
}

/// A parsed and checked MetaImage header.
#[derive(Clone, Debug, PartialEq)]
pub struct MetaHeader {
    /// `DimSize`, reduced to x, y, z.
    pub sizes: [usize; 3],
    /// `NDims`.
    pub ndims: usize,
    /// `ElementType`.
    pub scalar_type: ScalarType,
    /// Index-to-world map from `ElementSpacing`, `Offset` and `TransformMatrix`.
    pub geometry: Geometry,
    /// False when `BinaryDataByteOrderMSB` (or `ElementByteOrderMSB`) is true.
    pub little_endian: bool,
    /// `CompressedData`.
    pub compressed: bool,
    /// `CompressedDataSize`.
    pub compressed_size: Option<u64>,
    /// `HeaderSize` (detached data only; -1 = the data is the last bytes).
    pub header_size: i64,
    /// `ElementDataFile`.
    pub data_file: DataFile,
    /// Descriptive fields for display.
    pub fields: Vec<(String, String)>,
}

fn header_err(path: &Path, line: usize, message: String) -> VolumeError {
    VolumeError::Header {
        path: path.to_path_buf(),
        line,
        message,
    }
}

/// The scalar type of an `ElementType`, or why it cannot be rendered.
fn element_type(name: &str) -> Result<ScalarType, String> {
    Ok(match name {
        "MET_UCHAR" => ScalarType::Uint8,
        "MET_CHAR" => ScalarType::Int8,
        "MET_USHORT" => ScalarType::Uint16,
        "MET_SHORT" => ScalarType::Int16,
        "MET_UINT" | "MET_ULONG" => ScalarType::Uint32,
        "MET_INT" | "MET_LONG" => ScalarType::Int32,
        "MET_ULONG_LONG" => ScalarType::Uint64,
        "MET_LONG_LONG" => ScalarType::Int64,
        "MET_FLOAT" => ScalarType::Float32,
        "MET_DOUBLE" => ScalarType::Float64,
        other if other.ends_with("_ARRAY") || other == "MET_STRING" => {
            return Err(format!("{other} is not a scalar element type"))
        }
        other => return Err(format!("{other:?} is not a MetaImage element type")),
    })
}

/// One `Key = Value` line.
struct Entry {
    line: usize,
    value: String,
}

/// The raw entries of a header, by key.
struct Entries {
    path: PathBuf,
    list: Vec<(String, Entry)>,
}

/// The keys volcast reads, spelt as ITK's MetaIO matches them (case-sensitively).
const KEYS: &[&str] = &[
    "ObjectType",
    "NDims",
    "DimSize",
    "ElementType",
    "ElementNumberOfChannels",
    "BinaryData",
    "ElementSpacing",
    "ElementSize",
    "Offset",
    "Position",
    "Origin",
    "TransformMatrix",
    "Rotation",
    "Orientation",
    "BinaryDataByteOrderMSB",
    "ElementByteOrderMSB",
    "CompressedData",
    "CompressedDataSize",
    "HeaderSize",
    "ElementDataFile",
    "FileFormatVersion",
    "AnatomicalOrientation",
    "Modality",
    "Comment",
];

/// A geometry key found in a header: its name, its line and its numbers.
type Synonym<'a> = (&'a str, usize, Vec<f64>);

impl Entries {
    /// The entry of the first of `names` present.
    fn get(&self, names: &[&str]) -> Option<(&str, &Entry)> {
        names.iter().find_map(|n| {
            self.list
                .iter()
                .find(|(k, _)| k == n)
                .map(|(k, e)| (k.as_str(), e))
        })
    }

    /// Every one of `synonyms` present, parsed and checked (`count` finite numbers),
    /// with its key and line; the one ITK uses first.
    fn synonyms<'a>(
        &self,
        synonyms: &[&'a str],
        count: usize,
    ) -> Result<Vec<Synonym<'a>>, VolumeError> {
        let mut found = Vec::new();
        for &name in synonyms {
            if let Some(v) = self.numbers(&[name], count)? {
                let line = self.get(&[name]).map_or(0, |(_, e)| e.line);
                found.push((name, line, v));
            }
        }
        Ok(found)
    }

    fn numbers(&self, names: &[&str], count: usize) -> Result<Option<Vec<f64>>, VolumeError> {
        let Some((key, e)) = self.get(names) else {
            return Ok(None);
        };
        let values: Option<Vec<f64>> = e
            .value
            .split_whitespace()
            .map(|t| t.parse::<f64>().ok().filter(|x| x.is_finite()))
            .collect();
        match values {
            Some(v) if v.len() == count => Ok(Some(v)),
            _ => Err(header_err(
                &self.path,
                e.line,
                format!("`{key} = {}`: expected {count} finite numbers", e.value),
            )),
        }
    }

    fn boolean(&self, names: &[&str]) -> Result<Option<bool>, VolumeError> {
        let Some((key, e)) = self.get(names) else {
            return Ok(None);
        };
        match e.value.to_ascii_lowercase().as_str() {
            "true" | "1" => Ok(Some(true)),
            "false" | "0" => Ok(Some(false)),
            _ => Err(header_err(
                &self.path,
                e.line,
                format!("`{key} = {}`: expected True or False", e.value),
            )),
        }
    }

    fn integer(&self, name: &str) -> Result<Option<i64>, VolumeError> {
        let Some((key, e)) = self.get(&[name]) else {
            return Ok(None);
        };
        e.value.parse::<i64>().map(Some).map_err(|_| {
            header_err(
                &self.path,
                e.line,
                format!("`{key} = {}`: expected a whole number", e.value),
            )
        })
    }
}

/// Reads the header lines, up to and including `ElementDataFile`; returns them and the
/// byte after that line (where LOCAL data starts).
fn read_entries(path: &Path, r: &mut impl BufRead) -> Result<(Entries, u64), VolumeError> {
    let mut list: Vec<(String, Entry)> = Vec::new();
    let mut consumed = 0u64;
    let mut buf = Vec::new();
    for line in 1.. {
        buf.clear();
        let n = r
            .take(MAX_HEADER + 1 - consumed)
            .read_until(b'\n', &mut buf)
            .map_err(|source| VolumeError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        consumed += n as u64;
        if consumed > MAX_HEADER {
            return Err(header_err(
                path,
                line,
                format!("header is longer than {MAX_HEADER} bytes without `ElementDataFile`, the key that ends it"),
            ));
        }
        if n == 0 {
            return Err(header_err(
                path,
                line,
                if list.is_empty() {
                    "empty file: not a MetaImage header (expected `Key = Value` lines ending with `ElementDataFile`)".into()
                } else {
                    "the header ends without `ElementDataFile = LOCAL` or `= <data file>`, which every MetaImage header ends with".into()
                },
            ));
        }
        let text = std::str::from_utf8(&buf).map_err(|_| {
            header_err(
                path,
                line,
                "line is not text: not a MetaImage header, or data before `ElementDataFile`".into(),
            )
        })?;
        let text = text.trim_end_matches(['\n', '\r']);
        if text.trim().is_empty() {
            continue;
        }
        let Some((key, value)) = text.split_once('=') else {
            return Err(header_err(
                path,
                line,
                format!("expected `Key = Value`, got {text:?}"),
            ));
        };
        let (key, value) = (key.trim().to_string(), value.trim().to_string());
        if let Some(known) = KEYS
            .iter()
            .find(|k| k.eq_ignore_ascii_case(&key) && **k != key)
        {
            // ITK matches keys case-sensitively and would ignore this one
            return Err(header_err(
                path,
                line,
                format!("`{key}`: MetaImage keys are case-sensitive; ITK reads `{known}`, and ignores `{key}`"),
            ));
        }
        if let Some((_, e)) = list.iter().find(|(k, _)| k.eq_ignore_ascii_case(&key)) {
            return Err(header_err(
                path,
                line,
                format!("`{key}` is given twice (first on line {})", e.line),
            ));
        }
        let last = key == "ElementDataFile";
        list.push((key, Entry { line, value }));
        if last {
            break;
        }
    }
    Ok((
        Entries {
            path: path.to_path_buf(),
            list,
        },
        consumed,
    ))
}

/// Reads and checks the header of a `.mha` or `.mhd` file.
pub fn read_header(path: &Path) -> Result<MetaHeader, VolumeError> {
    let (file, _) = open_regular(path, "a MetaImage header")?;
    let (e, data_start) = read_entries(path, &mut BufReader::new(file))?;
    parse(path, &e, data_start)
}

fn parse(path: &Path, e: &Entries, data_start: u64) -> Result<MetaHeader, VolumeError> {
    let required = |name: &str| {
        e.get(&[name]).ok_or_else(|| {
            header_err(
                path,
                0,
                format!("missing `{name}`: a MetaImage header needs it"),
            )
        })
    };
    if let Some((key, t)) = e.get(&["ObjectType"]) {
        if !t.value.eq_ignore_ascii_case("Image") {
            return Err(unsupported(
                path,
                format!(
                    "line {}: `{key} = {}`: only images are read",
                    t.line, t.value
                ),
            ));
        }
    }
    let (_, nd) = required("NDims")?;
    let ndims = match nd.value.parse::<usize>() {
        Ok(n @ 2..=4) => n,
        _ => {
            return Err(unsupported(
                path,
                format!(
                    "line {}: `NDims = {}`: volcast reads 2-, 3- and 4-dimensional images (a 4th axis of size 1)",
                    nd.line, nd.value
                ),
            ))
        }
    };
    let (_, ds) = required("DimSize")?;
    let dims: Vec<usize> = ds
        .value
        .split_whitespace()
        .map(|t| t.parse::<usize>().ok().filter(|&n| n >= 1))
        .collect::<Option<Vec<_>>>()
        .filter(|v| v.len() == ndims)
        .ok_or_else(|| {
            header_err(
                path,
                ds.line,
                format!(
                    "`DimSize = {}`: expected {ndims} sizes of at least 1 (NDims = {ndims})",
                    ds.value
                ),
            )
        })?;
    if ndims == 4 && dims[3] > 1 {
        return Err(unsupported(
            path,
            format!(
                "line {}: `DimSize = {}`: a 4D image with {} volumes; volcast renders one 3D volume (a 4th axis of size 1 only)",
                ds.line, ds.value, dims[3]
            ),
        ));
    }
    let (_, et) = required("ElementType")?;
    let scalar_type = element_type(&et.value).map_err(|why| {
        unsupported(
            path,
            format!(
                "line {}: `ElementType`: {why}: volcast reads MET_UCHAR, MET_CHAR, MET_USHORT, MET_SHORT, MET_UINT, MET_INT, MET_ULONG, MET_LONG, MET_ULONG_LONG, MET_LONG_LONG, MET_FLOAT, MET_DOUBLE",
                et.line
            ),
        )
    })?;
    if let Some(c) = e.integer("ElementNumberOfChannels")? {
        if c != 1 {
            return Err(unsupported(
                path,
                format!(
                    "`ElementNumberOfChannels = {c}`: volcast renders scalar images (1 channel)"
                ),
            ));
        }
    }
    if e.boolean(&["BinaryData"])? == Some(false) {
        return Err(unsupported(
            path,
            "`BinaryData = False` (text data) is not supported: write the image with binary data"
                .into(),
        ));
    }
    // Synonyms as ITK's MetaIO reads them, whatever their order in the file: each is
    // checked, and the first of each list below wins.
    let spacings = e.synonyms(&["ElementSpacing", "ElementSize"], ndims)?;
    let origins = e.synonyms(&["Origin", "Offset", "Position"], ndims)?;
    let matrices = e.synonyms(
        &["TransformMatrix", "Rotation", "Orientation"],
        ndims * ndims,
    )?;
    let find = |name: &str| origins.iter().find(|o| o.0 == name);
    if let (None, Some((_, l1, a)), Some((_, l2, b))) =
        (find("Origin"), find("Offset"), find("Position"))
    {
        // MetaIO versions differ on whether Offset or Position comes last
        if a != b {
            return Err(header_err(
                path,
                (*l1).max(*l2),
                format!(
                    "`Offset` (line {l1}) and `Position` (line {l2}) give different origins {a:?} and {b:?}: versions of ITK differ on which one wins; give one of them, or `Origin`"
                ),
            ));
        }
    }
    if let Some(v) = e.integer("FileFormatVersion")? {
        // MetaIO reads Position, Origin, Rotation and Orientation only in version 0
        let legacy = ["Position", "Origin", "Rotation", "Orientation"]
            .into_iter()
            .find(|k| e.get(&[k]).is_some());
        if let (true, Some(k)) = (v != 0, legacy) {
            return Err(header_err(
                path,
                e.get(&[k]).map_or(0, |(_, x)| x.line),
                format!("`{k}` with `FileFormatVersion = {v}`: versions of ITK differ on whether they read it; use `Offset` and `TransformMatrix`"),
            ));
        }
    }
    let spacing = spacings
        .into_iter()
        .next()
        .map_or_else(|| vec![1.0; ndims], |s| s.2);
    let offset = origins
        .into_iter()
        .next()
        .map_or_else(|| vec![0.0; ndims], |s| s.2);
    let matrix = matrices.into_iter().next().map_or_else(
        || {
            (0..ndims * ndims)
                .map(|i| if i / ndims == i % ndims { 1.0 } else { 0.0 })
                .collect()
        },
        |s| s.2,
    );
    let n3 = ndims.min(3);
    let component = |v: &[f64], i: usize| if i < n3 { v[i] } else { 0.0 };
    let mut axes = [DVec3::Z; 3];
    for (i, axis) in axes.iter_mut().enumerate().take(n3) {
        let d = &matrix[i * ndims..(i + 1) * ndims];
        *axis = DVec3::new(component(d, 0), component(d, 1), component(d, 2)) * spacing[i];
    }
    let geometry = Geometry {
        origin: DVec3::new(
            component(&offset, 0),
            component(&offset, 1),
            component(&offset, 2),
        ),
        axes,
    };
    if !geometry.is_valid() {
        return Err(header_err(
            path,
            0,
            format!(
                "ElementSpacing {spacing:?}, TransformMatrix {matrix:?} and Offset {offset:?} give degenerate axes: they must be finite, non-zero and independent"
            ),
        ));
    }
    let msb = e.boolean(&["BinaryDataByteOrderMSB", "ElementByteOrderMSB"])?;
    let compressed = e.boolean(&["CompressedData"])?.unwrap_or(false);
    let compressed_size = match e.integer("CompressedDataSize")? {
        None => None,
        Some(n) if n > 0 => Some(n as u64),
        Some(n) => {
            return Err(header_err(
                path,
                0,
                format!("`CompressedDataSize = {n}`: expected a positive byte count"),
            ))
        }
    };
    let header_size = e.integer("HeaderSize")?.unwrap_or(0);
    if header_size < -1 || (header_size == -1 && compressed) {
        return Err(header_err(
            path,
            0,
            format!("`HeaderSize = {header_size}`: expected a byte count >= 0, or -1 (uncompressed data at the end of the file)"),
        ));
    }
    let (_, df) = required("ElementDataFile")?;
    let name = df.value.as_str();
    let data_file = if name.eq_ignore_ascii_case("LOCAL") {
        DataFile::Local(data_start)
    } else if name.split_whitespace().next() == Some("LIST") {
        return Err(unsupported(
            path,
            format!("line {}: `ElementDataFile = LIST`: data in a list of files is not supported (write one data file)", df.line),
        ));
    } else if name.contains('%') && name.split_whitespace().count() > 1 {
        return Err(unsupported(
            path,
            format!("line {}: `ElementDataFile = {name}`: numbered data files are not supported (write one data file)", df.line),
        ));
    } else if name.is_empty() {
        return Err(header_err(
            path,
            df.line,
            "`ElementDataFile` is empty: expected LOCAL or a file name".into(),
        ));
    } else {
        let p = Path::new(name);
        DataFile::File(if p.is_absolute() {
            p.to_path_buf()
        } else {
            path.parent().unwrap_or(Path::new(".")).join(p)
        })
    };
    let mut fields = vec![
        ("format".to_string(), "MetaImage".to_string()),
        (
            "space".to_string(),
            "LPS (MetaImage world coordinates, kept as they are)".to_string(),
        ),
    ];
    for key in [
        "AnatomicalOrientation",
        "Modality",
        "Comment",
        "ElementDataFile",
    ] {
        if let Some((k, v)) = e.get(&[key]) {
            fields.push((k.to_string(), v.value.clone()));
        }
    }
    let mut sizes = [1usize; 3];
    sizes[..n3].copy_from_slice(&dims[..n3]);
    Ok(MetaHeader {
        sizes,
        ndims,
        scalar_type,
        geometry,
        little_endian: msb != Some(true),
        compressed,
        compressed_size,
        header_size,
        data_file,
        fields,
    })
}

impl MetaHeader {
    /// The file holding the data and where it starts in it (before `HeaderSize -1`
    /// is resolved against the file's length).
    fn data_path(&self, header_path: &Path) -> PathBuf {
        match &self.data_file {
            DataFile::Local(_) => header_path.to_path_buf(),
            DataFile::File(p) => p.clone(),
        }
    }

    /// The 3D header the renderer uses.
    pub fn volume_header(&self, path: &Path) -> VolumeHeader {
        VolumeHeader {
            sizes: self.sizes,
            scalar_type: self.scalar_type,
            geometry: self.geometry,
            source: path.display().to_string(),
            fields: self.fields.clone(),
            rescale: Default::default(),
        }
    }
}

/// Every file a MetaImage is read from: the header, and a detached data file.
pub fn input_files(path: &Path) -> Result<Vec<PathBuf>, VolumeError> {
    let h = read_header(path)?;
    let mut files = vec![path.to_path_buf()];
    if let DataFile::File(p) = &h.data_file {
        files.push(p.clone());
    }
    Ok(files)
}

/// Where the data is, once checked against the data file's length.
struct Located {
    file: PathBuf,
    /// First byte of the data (compressed or not).
    start: u64,
    /// Bytes of voxels (decompressed).
    bytes: u64,
    /// Voxels.
    count: usize,
    /// Compressed bytes available (compressed data only).
    compressed: u64,
}

fn locate(path: &Path, h: &MetaHeader) -> Result<Located, VolumeError> {
    let (count, bytes) = Limits {
        max_bytes: u64::MAX,
    }
    .check(&h.sizes, h.scalar_type.size())?;
    let bytes = bytes as u64;
    let file = h.data_path(path);
    let (_, meta) = open_regular(&file, "MetaImage data")?;
    let len = meta.len();
    let data_err = |message: String| VolumeError::Data {
        path: file.clone(),
        message,
    };
    let what = format!("DimSize {:?} x {} ({bytes} bytes)", &h.sizes, h.scalar_type);
    let start = match (&h.data_file, h.header_size) {
        (DataFile::Local(at), _) => *at,
        (DataFile::File(_), -1) => len.checked_sub(bytes).ok_or_else(|| {
            data_err(format!(
                "data shorter than declared: `HeaderSize = -1` takes the last {bytes} bytes ({what}), but the file has {len}"
            ))
        })?,
        (DataFile::File(_), n) => n as u64,
    };
    let available = len.checked_sub(start).ok_or_else(|| {
        data_err(format!(
            "the data starts at byte {start} (HeaderSize, or the end of the header), beyond the end of the {len}-byte file"
        ))
    })?;
    if h.compressed {
        let compressed = match h.compressed_size {
            Some(n) if n > available => {
                return Err(data_err(format!(
                    "`CompressedDataSize = {n}`, but only {available} bytes follow the header"
                )))
            }
            Some(n) => n,
            None => available,
        };
        // DEFLATE expands by at most 1032:1
        if bytes > compressed.saturating_mul(1032) {
            return Err(data_err(format!(
                "{what} cannot come from {compressed} compressed bytes (zlib expands at most 1032 times)"
            )));
        }
        return Ok(Located {
            file,
            start,
            bytes,
            count,
            compressed,
        });
    }
    if available != bytes {
        return Err(data_err(format!(
            "{} {available} bytes of data after byte {start}, but {what} needs exactly {bytes}",
            if available < bytes {
                "data shorter than declared:"
            } else {
                "data longer than declared:"
            }
        )));
    }
    Ok(Located {
        file,
        start,
        bytes,
        count,
        compressed: 0,
    })
}

/// A MetaImage file as a volume source.
pub struct MetaSpec<'a> {
    /// The `.mha` or `.mhd` file.
    pub path: &'a Path,
}

impl MetaSpec<'_> {
    /// Sizes, type and geometry (reads the header only).
    pub fn header(&self) -> Result<VolumeHeader, VolumeError> {
        Ok(read_header(self.path)?.volume_header(self.path))
    }

    /// Whether the voxels are mapped (uncompressed, native byte order) or read.
    pub fn storage(&self) -> Result<Storage, VolumeError> {
        let h = read_header(self.path)?;
        let at = locate(self.path, &h)?;
        Ok(if h.compressed {
            Storage::Read {
                bytes: at.bytes,
                reason: ReadReason::Compressed("zlib-compressed data (CompressedData = True)"),
            }
        } else {
            Storage::uncompressed(h.scalar_type, h.little_endian, &at.file, at.start, at.bytes)
        })
    }

    /// Loads the voxels (mapped, or read with `limits` checked first), with the
    /// XXH3-128 of their bytes as stored when `hash`.
    pub fn load_hashed(
        &self,
        limits: &Limits,
        hash: bool,
    ) -> Result<(Volume, Option<u128>), VolumeError> {
        let h = read_header(self.path)?;
        let at = locate(self.path, &h)?;
        let header = h.volume_header(self.path);
        if !h.compressed && is_native_order(h.scalar_type, h.little_endian) {
            let (data, digest) =
                stream::map_region(&at.file, h.scalar_type, at.start, at.bytes, hash)?;
            return Ok((Volume { header, data }, digest));
        }
        let (file, _) = open_regular(&at.file, "MetaImage data")?;
        let mut r = BufReader::new(file);
        r.seek(SeekFrom::Start(at.start))
            .map_err(|source| VolumeError::Io {
                path: at.file.clone(),
                source,
            })?;
        let decode = Decode {
            path: &at.file,
            ty: h.scalar_type,
            little_endian: h.little_endian,
            count: at.count,
            what: if h.compressed {
                "zlib data"
            } else {
                "raw data"
            },
        };
        let (data, digest) = if h.compressed {
            let mut limited = r.take(at.compressed);
            let gzip = limited
                .fill_buf()
                .map_err(|source| VolumeError::Io {
                    path: at.file.clone(),
                    source,
                })?
                .starts_with(&[0x1f, 0x8b]);
            if gzip {
                let mut d = flate2::bufread::MultiGzDecoder::new(limited);
                let out = decode.read(&mut d, limits, hash)?;
                decode.probe_end(&mut d)?;
                out
            } else {
                let mut d = flate2::bufread::ZlibDecoder::new(limited);
                let out = decode.read(&mut d, limits, hash)?;
                decode.probe_end(&mut d)?;
                out
            }
        } else {
            decode.read(&mut r.take(at.bytes), limits, hash)?
        };
        Ok((Volume { header, data }, digest))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_text(text: &str) -> Result<MetaHeader, VolumeError> {
        let p = Path::new("t.mhd");
        let (e, start) = read_entries(p, &mut text.as_bytes())?;
        parse(p, &e, start)
    }

    const BASE: &str = "ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementType = MET_SHORT\nElementSpacing = 0.5 2 3\nOffset = 1 2 3\nTransformMatrix = 0 1 0 -1 0 0 0 0 1\nElementDataFile = v.raw\n";

    #[test]
    fn geometry_from_spacing_offset_and_matrix() {
        let h = parse_text(BASE).unwrap();
        assert_eq!(h.sizes, [4, 3, 2]);
        assert_eq!(h.scalar_type, ScalarType::Int16);
        assert_eq!(h.geometry.origin, DVec3::new(1.0, 2.0, 3.0));
        assert_eq!(h.geometry.axes[0], DVec3::new(0.0, 0.5, 0.0));
        assert_eq!(h.geometry.axes[1], DVec3::new(-2.0, 0.0, 0.0));
        assert_eq!(h.geometry.axes[2], DVec3::new(0.0, 0.0, 3.0));
        assert_eq!(h.data_file, DataFile::File(PathBuf::from("v.raw")));
        let local = parse_text(
            "NDims = 2\nDimSize = 4 3\nElementType = MET_UCHAR\nElementDataFile = LOCAL\nXX",
        )
        .unwrap();
        assert_eq!(local.sizes, [4, 3, 1]);
        assert_eq!(local.data_file, DataFile::Local(72));
    }

    #[test]
    fn bad_headers_are_named() {
        let e = |text: &str| parse_text(text).unwrap_err().to_string();
        assert!(e(&BASE.replace("4 3 2", "4 3")).contains("`DimSize = 4 3`"));
        assert!(e(&BASE.replace("MET_SHORT", "MET_SHORT_ARRAY")).contains("not a scalar"));
        assert!(e(&BASE.replace("0.5 2 3", "0.5 nan 3")).contains("ElementSpacing"));
        assert!(e(&BASE.replace("0 0 1\n", "0 0 0\n")).contains("degenerate"));
        assert!(e(&BASE.replace("v.raw", "LIST")).contains("LIST"));
        assert!(e(&BASE.replace("v.raw", "s%03d.raw 1 5 1")).contains("numbered"));
        assert!(e(&BASE.replace("NDims = 3", "NDims = 7")).contains("NDims = 7"));
        assert!(e(&BASE.replace("ElementDataFile = v.raw\n", "")).contains("ends without"));
        assert!(e(&format!("NDims = 3\n{BASE}")).contains("given twice"));
        assert!(e(&BASE.replace("ObjectType = Image\n", "garbage\n"))
            .contains("expected `Key = Value`"));
        assert!(e(&format!(
            "{}CompressedData = True\nHeaderSize = -1\nElementDataFile = x\n",
            &BASE[..BASE.len() - 24]
        ))
        .contains("HeaderSize"));
        assert!(e("").contains("empty file"));
    }
}
