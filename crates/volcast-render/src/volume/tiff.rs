//! TIFF stacks (`.tif`, `.tiff`, `format = "tiff"`), decoded with the `tiff` crate: a
//! multi-page file (each page a z slice: tifffile's and Fiji's ImageJ hyperstacks,
//! OME-TIFF), or a folder or glob of single-page files in natural name order.
//!
//! ```text
//! TiffSpec::layout   every page's directory read (no pixels): one sample per pixel,
//!                    8/16/32/64-bit integers or 32/64-bit floats, uncompressed, LZW,
//!                    Deflate or PackBits (others refused by name); every page the
//!                    size and type of the first; the strips' bytes inside the file
//!                    and enough of them for the page (a hostile size costs nothing)
//!                    axes: the ImageJ description (images, channels, slices,
//!                    frames), the OME-XML (SizeZ/C/T, DimensionOrder) or tifffile's
//!                    shape; `channel = k` picks a channel, `index = t` a frame
//!                    spacing: ImageJ (1/XResolution, 1/YResolution, spacing, unit),
//!                    OME PhysicalSizeX/Y/Z (converted to X's unit), resolution in
//!                    centimetres; otherwise 1, and `info` says it is assumed
//! TiffSpec::load     Limits::check (columns x rows x pages), then the chosen pages
//!                    decoded one at a time into the volume, hashed as decoded
//! ```
//!
//! Voxel `(i, j, k)` (column, row, page) sits at `(i sx, j sy, k sz)`: origin 0, axes
//! along x, y, z, in the file's unit (µm for most microscopes; not converted to mm).

use crate::volume::errors::{data_err, header_err, unsupported};
use std::cmp::Ordering;
use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use ::tiff::decoder::{Decoder, DecodingResult, Limits as TiffLimits};
use ::tiff::tags::{CompressionMethod, PhotometricInterpretation, SampleFormat, Tag};
use ::tiff::TiffError;
use nrrd::{ElementSink, ReadError};

use super::mapped::open_regular;
use super::{Geometry, Limits, ReadReason, ScalarType, Storage, Volume, VolumeError, VolumeHeader};

/// Most pages (or files of a series) read: each costs a directory in the file.
const MAX_PAGES: usize = 1 << 20;

/// Largest tag value the crate may read (OME-XML descriptions of big files run to
/// megabytes; strip offsets of a tall page are 8 bytes a row).
const MAX_TAG_BYTES: usize = 16 << 20;

/// A TIFF file, folder or glob and the channel to render.
#[derive(Clone, Debug, PartialEq)]
pub struct TiffSpec {
    /// A file, a folder of single-page files, or a glob (`slices/*.tif`; `*` and `?`
    /// in the file name only).
    pub path: PathBuf,
    /// `channel = k`: the channel of a multi-channel file (0-based).
    pub channel: Option<usize>,
    /// `index = t`: the frame of a time series (ImageJ `frames`, OME `SizeT`; 0-based).
    pub index: Option<usize>,
}

/// What one page's directory says.
#[derive(Clone, Debug, PartialEq)]
struct Page {
    width: usize,
    height: usize,
    ty: ScalarType,
    compression: u16,
}

/// The pages of the volume, checked: where each z slice is, and its geometry.
#[derive(Debug)]
struct Layout {
    /// (file, page of that file) of each z slice, in order.
    slices: Vec<(PathBuf, usize)>,
    page: Page,
    spacing: [f64; 3],
    fields: Vec<(String, String)>,
}

/// The crate's error on `page` of `path`, sorted as volcast sorts errors.
fn tiff_err(path: &Path, page: usize, e: TiffError) -> VolumeError {
    match e {
        TiffError::IoError(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => data_err(
            path,
            format!("page {page}: the file ends inside the page's data or directory (truncated?)"),
        ),
        TiffError::IoError(source) => VolumeError::Io {
            path: path.to_path_buf(),
            source,
        },
        TiffError::UnsupportedError(e) => unsupported(path, format!("page {page}: {e}")),
        TiffError::LimitsExceeded => data_err(
            path,
            format!(
                "page {page}: a tag or the page is larger than the reader allows ({} per tag)",
                super::human_bytes(MAX_TAG_BYTES as u64)
            ),
        ),
        other => data_err(path, format!("page {page}: not a readable TIFF: {other}")),
    }
}

/// The name of a compression scheme, and whether it is read.
fn compression_name(c: u16) -> (String, bool) {
    match CompressionMethod::from_u16_exhaustive(c) {
        CompressionMethod::None => ("uncompressed".into(), true),
        CompressionMethod::LZW => ("LZW".into(), true),
        CompressionMethod::Deflate | CompressionMethod::OldDeflate => ("Deflate".into(), true),
        CompressionMethod::PackBits => ("PackBits".into(), true),
        CompressionMethod::JPEG | CompressionMethod::ModernJPEG => ("JPEG".into(), false),
        CompressionMethod::Huffman | CompressionMethod::Fax3 | CompressionMethod::Fax4 => {
            ("CCITT fax".into(), false)
        }
        CompressionMethod::ZSTD => ("Zstandard".into(), false),
        CompressionMethod::WebP => ("WebP".into(), false),
        _ => (format!("compression {c}"), false),
    }
}

/// Most bytes one byte of a compressed strip can decode to: bounds what a page's
/// strips can hold, so that a page declaring more than its bytes can make is refused
/// before its buffer is allocated (Deflate's ratio is at most 1032; an LZW code of
/// at least 9 bits emits at most 4096 bytes; a PackBits pair at most 128).
fn expansion(c: u16) -> u64 {
    match CompressionMethod::from_u16_exhaustive(c) {
        CompressionMethod::None => 1,
        CompressionMethod::PackBits => 64,
        CompressionMethod::Deflate | CompressionMethod::OldDeflate => 1032,
        _ => 4096,
    }
}

type TiffDecoder = Decoder<BufReader<File>>;

/// Opens `path` for the crate (a regular file, inside `--confine`); its length.
fn open(path: &Path) -> Result<(TiffDecoder, u64), VolumeError> {
    let (file, meta) = open_regular(path, "a TIFF file")?;
    let mut limits = TiffLimits::default();
    limits.ifd_value_size = MAX_TAG_BYTES;
    let d = Decoder::new(BufReader::new(file)).map_err(|e| match e {
        TiffError::FormatError(_) => data_err(
            path,
            format!("not a TIFF file (expected `II*` or `MM*` and a first directory): {e}"),
        ),
        other => tiff_err(path, 0, other),
    })?;
    Ok((d.with_limits(limits), meta.len()))
}

/// Reads and checks the current page's directory (`page` its number, for messages).
fn read_page(
    d: &mut TiffDecoder,
    path: &Path,
    page: usize,
    file_len: u64,
) -> Result<Page, VolumeError> {
    let err = |e| tiff_err(path, page, e);
    let uint = |d: &mut TiffDecoder, tag: Tag| d.find_tag_unsigned_vec::<u64>(tag).map_err(err);
    let (w, h) = d.dimensions().map_err(err)?;
    let samples = uint(d, Tag::SamplesPerPixel)?.map_or(1, |v| v.first().copied().unwrap_or(1));
    let photometric = uint(d, Tag::PhotometricInterpretation)?.and_then(|v| v.first().copied());
    if photometric == Some(0) {
        // the crate inverts WhiteIsZero samples for some layouts and not others
        return Err(unsupported(
            path,
            format!("page {page}: PhotometricInterpretation WhiteIsZero (0) is not supported: volcast reads BlackIsZero greyscale (invert the image first)"),
        ));
    }
    let grey = photometric.is_none_or(|p| {
        matches!(
            u16::try_from(p)
                .ok()
                .and_then(PhotometricInterpretation::from_u16),
            Some(PhotometricInterpretation::BlackIsZero)
        )
    });
    if !grey || samples != 1 {
        let name = match photometric {
            Some(2) => "RGB".to_string(),
            Some(3) => "palette colour".into(),
            Some(5) => "CMYK".into(),
            Some(6) => "YCbCr".into(),
            Some(p) => format!("PhotometricInterpretation {p}"),
            None => "greyscale".into(),
        };
        return Err(unsupported(
            path,
            format!("page {page}: a colour or multi-sample TIFF ({name}, {samples} samples per pixel): volcast reads greyscale pages of one sample (split the channels into pages, as ImageJ and tifffile do)"),
        ));
    }
    let bits = uint(d, Tag::BitsPerSample)?.map_or(1, |v| v.first().copied().unwrap_or(1));
    let format = uint(d, Tag::SampleFormat)?.map_or(1, |v| v.first().copied().unwrap_or(1));
    let ty = match (
        u16::try_from(format)
            .ok()
            .map(SampleFormat::from_u16_exhaustive),
        bits,
    ) {
        (Some(SampleFormat::Uint), 8) => ScalarType::Uint8,
        (Some(SampleFormat::Uint), 16) => ScalarType::Uint16,
        (Some(SampleFormat::Uint), 32) => ScalarType::Uint32,
        (Some(SampleFormat::Uint), 64) => ScalarType::Uint64,
        (Some(SampleFormat::Int), 8) => ScalarType::Int8,
        (Some(SampleFormat::Int), 16) => ScalarType::Int16,
        (Some(SampleFormat::Int), 32) => ScalarType::Int32,
        (Some(SampleFormat::Int), 64) => ScalarType::Int64,
        (Some(SampleFormat::IEEEFP), 32) => ScalarType::Float32,
        (Some(SampleFormat::IEEEFP), 64) => ScalarType::Float64,
        _ => {
            let kind = match format {
                1 => "unsigned integer",
                2 => "signed integer",
                3 => "float",
                _ => "other",
            };
            return Err(unsupported(
                path,
                format!("page {page}: {bits}-bit {kind} samples (SampleFormat {format}, BitsPerSample {bits}): volcast reads 8-, 16-, 32- and 64-bit integers and 32- and 64-bit floats"),
            ));
        }
    };
    let compression = uint(d, Tag::Compression)?.map_or(1, |v| v.first().copied().unwrap_or(1));
    let compression = u16::try_from(compression).unwrap_or(u16::MAX);
    let (name, readable) = compression_name(compression);
    if !readable {
        return Err(unsupported(
            path,
            format!("page {page}: {name} compression is not supported: volcast reads uncompressed, LZW, Deflate and PackBits TIFFs"),
        ));
    }
    // the strips (or tiles) must lie in the file and could hold the page: a page
    // declaring more than its bytes can decode to is refused before it is allocated
    let (offsets, counts) = if d.find_tag(Tag::TileOffsets).map_err(err)?.is_some() {
        (Tag::TileOffsets, Tag::TileByteCounts)
    } else {
        (Tag::StripOffsets, Tag::StripByteCounts)
    };
    let offsets = uint(d, offsets)?.unwrap_or_default();
    let counts = uint(d, counts)?.unwrap_or_default();
    if offsets.is_empty() || offsets.len() != counts.len() {
        return Err(data_err(
            path,
            format!("page {page}: {} strip or tile offsets for {} byte counts: expected one of each per strip", offsets.len(), counts.len()),
        ));
    }
    let mut stored = 0u64;
    for (&o, &c) in offsets.iter().zip(&counts) {
        if o.checked_add(c).is_none_or(|end| end > file_len) {
            return Err(data_err(
                path,
                format!("page {page}: a strip of {c} bytes at byte {o} ends past the end of the file ({file_len} bytes; truncated?)"),
            ));
        }
        stored = stored.saturating_add(c);
    }
    let need = (u64::from(w) * u64::from(h)).saturating_mul(ty.size() as u64);
    if stored.saturating_mul(expansion(compression)) < need {
        return Err(data_err(
            path,
            format!("page {page}: {w} x {h} {ty} samples ({need} bytes) cannot come from its {stored} bytes of {name} data (truncated or damaged?)"),
        ));
    }
    Ok(Page {
        width: w as usize,
        height: h as usize,
        ty,
        compression,
    })
}

/// Every page's directory of a file, each checked, with the first page's
/// ImageDescription, XResolution, YResolution and ResolutionUnit.
struct FileInfo {
    pages: Vec<Page>,
    description: Option<String>,
    resolution: Option<[f64; 2]>,
    resolution_unit: u64,
}

fn read_file(path: &Path) -> Result<FileInfo, VolumeError> {
    let (mut d, len) = open(path)?;
    let err = |e| tiff_err(path, 0, e);
    let description = match d.find_tag(Tag::ImageDescription).map_err(err)? {
        Some(v) => v.into_string().ok(),
        None => None,
    };
    let rational = |d: &mut TiffDecoder, tag| -> Result<Option<f64>, VolumeError> {
        Ok(match d.find_tag(tag).map_err(err)? {
            Some(::tiff::decoder::ifd::Value::Rational(n, m)) if n > 0 && m > 0 => {
                Some(f64::from(m) / f64::from(n))
            }
            Some(v) => v.into_f64().ok().filter(|r| *r > 0.0).map(|r| 1.0 / r),
            None => None,
        })
    };
    let x = rational(&mut d, Tag::XResolution)?;
    let y = rational(&mut d, Tag::YResolution)?;
    let resolution_unit = d
        .find_tag_unsigned::<u64>(Tag::ResolutionUnit)
        .map_err(err)?
        .unwrap_or(2);
    let mut pages = vec![read_page(&mut d, path, 0, len)?];
    while d.more_images() {
        let n = pages.len();
        if n >= MAX_PAGES {
            return Err(unsupported(path, format!("more than {MAX_PAGES} pages")));
        }
        d.next_image().map_err(|e| tiff_err(path, n, e))?;
        pages.push(read_page(&mut d, path, n, len)?);
    }
    Ok(FileInfo {
        pages,
        description,
        resolution: x.zip(y).map(|(x, y)| [x, y]),
        resolution_unit,
    })
}

/// `key=value` lines of an ImageJ description.
fn imagej(description: &str) -> Option<Vec<(String, String)>> {
    if !description.starts_with("ImageJ=") {
        return None;
    }
    Some(
        description
            .lines()
            .filter_map(|l| l.split_once('='))
            .map(|(k, v)| (k.trim().to_string(), v.trim().to_string()))
            .collect(),
    )
}

/// ImageJ's unit with its escapes undone (`\u00B5m` is µm).
fn imagej_unit(u: &str) -> String {
    let u = u.replace("\\u00B5", "µ").replace("\\u00b5", "µ");
    match u.as_str() {
        "micron" | "microns" | "um" => "µm".into(),
        _ => u,
    }
}

/// The attributes of the first `<Pixels>` element of an OME-XML text.
fn ome_pixels(xml: &str) -> Option<Vec<(String, String)>> {
    if !xml.contains("<OME") && !xml.contains(":OME") {
        return None;
    }
    let start = xml.find("<Pixels").or_else(|| xml.find(":Pixels "))?;
    let rest = &xml[start..];
    let tag = &rest[..rest.find('>')?];
    let mut attrs = Vec::new();
    let mut s = tag.split_once(char::is_whitespace)?.1;
    while let Some((name, after)) = s.split_once('=') {
        let after = after.trim_start();
        let quote = after.chars().next()?;
        let body = &after[1..];
        let end = body.find(quote)?;
        attrs.push((name.trim().to_string(), body[..end].to_string()));
        s = &body[end + 1..];
    }
    Some(attrs)
}

/// A length unit as a power of ten of metres (OME's UnitsLength names): powers, so
/// that converting 1500 nm to µm gives 1.5 exactly.
fn metres_exponent(unit: &str) -> Option<i32> {
    Some(match unit {
        "m" => 0,
        "cm" => -2,
        "mm" => -3,
        "µm" | "um" | "μm" => -6,
        "nm" => -9,
        "Å" => -10,
        "pm" => -12,
        _ => return None,
    })
}

/// Compares names as people count: runs of digits by their value (`img_9` before
/// `img_10`), the rest as text.
fn natural(a: &str, b: &str) -> Ordering {
    let (mut a, mut b) = (a, b);
    loop {
        match (a.chars().next(), b.chars().next()) {
            (None, None) => return Ordering::Equal,
            (None, _) => return Ordering::Less,
            (_, None) => return Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let da = a.find(|c: char| !c.is_ascii_digit()).unwrap_or(a.len());
                let db = b.find(|c: char| !c.is_ascii_digit()).unwrap_or(b.len());
                let (na, nb) = (
                    a[..da].trim_start_matches('0'),
                    b[..db].trim_start_matches('0'),
                );
                let o = na
                    .len()
                    .cmp(&nb.len())
                    .then_with(|| na.cmp(nb))
                    .then_with(|| da.cmp(&db));
                if o != Ordering::Equal {
                    return o;
                }
                a = &a[da..];
                b = &b[db..];
            }
            (Some(x), Some(y)) => {
                if x != y {
                    return x.cmp(&y);
                }
                a = &a[x.len_utf8()..];
                b = &b[y.len_utf8()..];
            }
        }
    }
}

/// Whether `name` matches `pattern` (`*` any run, `?` one character).
fn matches(pattern: &[char], name: &[char]) -> bool {
    match pattern.split_first() {
        None => name.is_empty(),
        Some(('*', rest)) => (0..=name.len()).any(|i| matches(rest, &name[i..])),
        Some(('?', rest)) => !name.is_empty() && matches(rest, &name[1..]),
        Some((c, rest)) => name.first() == Some(c) && matches(rest, &name[1..]),
    }
}

/// True when the file name of `path` holds a wildcard (`*` or `?`).
pub fn is_glob(path: &Path) -> bool {
    path.file_name()
        .is_some_and(|n| n.to_string_lossy().contains(['*', '?']))
}

/// True when the folder `dir` holds a `.tif` or `.tiff` file (`volcast info` on a
/// folder: a TIFF series rather than DICOM slices).
pub fn holds_tiffs(dir: &Path) -> bool {
    std::fs::read_dir(dir).is_ok_and(|entries| {
        entries.flatten().any(|e| {
            let name = e.file_name().to_string_lossy().to_ascii_lowercase();
            name.ends_with(".tif") || name.ends_with(".tiff")
        })
    })
}

impl TiffSpec {
    /// The files of a folder (`.tif`/`.tiff`) or glob, in natural name order; the
    /// file itself otherwise.
    fn files(&self) -> Result<Option<Vec<PathBuf>>, VolumeError> {
        let (dir, pattern): (&Path, Option<Vec<char>>) = if is_glob(&self.path) {
            let name = self.path.file_name().unwrap_or_default().to_string_lossy();
            (
                self.path.parent().unwrap_or(Path::new(".")),
                Some(name.chars().collect()),
            )
        } else if self.path.is_dir() {
            (&self.path, None)
        } else {
            return Ok(None);
        };
        let io = |source| VolumeError::Io {
            path: dir.to_path_buf(),
            source,
        };
        let mut names = Vec::new();
        for e in std::fs::read_dir(dir).map_err(io)? {
            let p = e.map_err(io)?.path();
            let name = p
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .to_string();
            let wanted = match &pattern {
                Some(pat) => matches(pat, &name.chars().collect::<Vec<_>>()),
                None => {
                    let lower = name.to_ascii_lowercase();
                    lower.ends_with(".tif") || lower.ends_with(".tiff")
                }
            };
            // regular files, or links to them (a link leading outside --confine is
            // refused when it is checked and opened)
            if wanted && std::fs::metadata(&p).is_ok_and(|m| m.is_file()) {
                names.push((name, p));
            }
            if names.len() > MAX_PAGES {
                return Err(VolumeError::Invalid(format!(
                    "{}: more than {MAX_PAGES} files",
                    self.path.display()
                )));
            }
        }
        if names.is_empty() {
            return Err(VolumeError::Invalid(format!(
                "{}: no TIFF files (expected .tif or .tiff files{})",
                self.path.display(),
                if pattern.is_some() {
                    " matching the pattern"
                } else {
                    " in the folder"
                }
            )));
        }
        names.sort_by(|a, b| natural(&a.0, &b.0));
        Ok(Some(names.into_iter().map(|(_, p)| p).collect()))
    }

    /// Every file a load reads.
    pub fn input_files(&self) -> Result<Vec<PathBuf>, VolumeError> {
        Ok(self.files()?.unwrap_or_else(|| vec![self.path.clone()]))
    }

    fn layout(&self) -> Result<Layout, VolumeError> {
        match self.files()? {
            Some(files) => self.series_layout(files),
            None => self.file_layout(),
        }
    }

    /// A folder or glob: one page per file, every file like the first.
    fn series_layout(&self, files: Vec<PathBuf>) -> Result<Layout, VolumeError> {
        if let Some(c) = self.channel.filter(|&c| c > 0) {
            return Err(VolumeError::Invalid(format!(
                "{}: channel = {c}, but a folder or glob of TIFFs is read one greyscale page per file (1 channel)",
                self.path.display()
            )));
        }
        if let Some(i) = self.index.filter(|&i| i > 0) {
            return Err(VolumeError::Invalid(format!(
                "{}: index = {i}, but a folder or glob of TIFFs is one volume (1 frame)",
                self.path.display()
            )));
        }
        let first = read_file(&files[0])?;
        let mut slices = Vec::with_capacity(files.len());
        for f in &files {
            let pages = if f == &files[0] {
                first.pages.clone()
            } else {
                read_file(f)?.pages
            };
            if pages.len() != 1 {
                return Err(unsupported(
                    f,
                    format!("{} pages: a folder or glob of TIFFs is read one page per file (name a multi-page file by itself)", pages.len()),
                ));
            }
            if pages[0] != first.pages[0] {
                let (a, b) = (&pages[0], &first.pages[0]);
                return Err(unsupported(
                    f,
                    format!(
                        "{} x {} {} pixels ({}), but {} has {} x {} {} ({}): the slices of a volume share size and type",
                        a.width, a.height, a.ty, compression_name(a.compression).0,
                        files[0].display(), b.width, b.height, b.ty, compression_name(b.compression).0
                    ),
                ));
            }
            slices.push((f.clone(), 0));
        }
        let mut fields = vec![
            (
                "format".to_string(),
                format!("TIFF series ({} files, one page each)", files.len()),
            ),
            (
                "compression".into(),
                compression_name(first.pages[0].compression).0,
            ),
        ];
        let spacing = spacing(&files[0], &first, None, &mut fields)?;
        Ok(Layout {
            slices,
            page: first.pages[0].clone(),
            spacing,
            fields,
        })
    }

    /// One file: its pages are z slices, or (ImageJ, OME) slices of channels.
    fn file_layout(&self) -> Result<Layout, VolumeError> {
        let path = &self.path;
        let info = read_file(path)?;
        let n = info.pages.len();
        let first = info.pages[0].clone();
        for (k, p) in info.pages.iter().enumerate().skip(1) {
            if *p != first {
                return Err(unsupported(
                    path,
                    format!(
                        "page {k} has {} x {} {} pixels, page 0 {} x {} {}: the pages of a volume share size and type",
                        p.width, p.height, p.ty, first.width, first.height, first.ty
                    ),
                ));
            }
        }
        let description = info.description.clone().unwrap_or_default();
        let mut fields = Vec::new();
        // slices, channels, frames, and the strides of each: slice z of channel c of
        // frame t is page `z * strides[0] + c * strides[1] + t * strides[2]`
        let (z_count, channels, frames, strides) = if let Some(ij) = imagej(&description) {
            let get = |k: &str| -> Result<Option<usize>, VolumeError> {
                match ij.iter().find(|(key, _)| key == k) {
                    None => Ok(None),
                    Some((_, v)) => v
                        .parse::<usize>()
                        .ok()
                        .filter(|&x| x >= 1)
                        .map(Some)
                        .ok_or_else(|| {
                            header_err(
                                path,
                                format!("ImageJ description: `{k}={v}`: expected a whole number of at least 1"),
                            )
                        }),
                }
            };
            let c = get("channels")?.unwrap_or(1);
            let t = get("frames")?.unwrap_or(1);
            let images = get("images")?.unwrap_or(n);
            let z = get("slices")?.unwrap_or(images / c.saturating_mul(t));
            if c.checked_mul(z).and_then(|cz| cz.checked_mul(t)) != Some(images) {
                return Err(header_err(
                    path,
                    format!("ImageJ description: channels={c} x slices={z} x frames={t} is not images={images}"),
                ));
            }
            if images != n {
                return Err(unsupported(
                    path,
                    format!("the ImageJ description declares images={images}, but the file has {n} pages (ImageJ's layout of a single directory for files over 4 GiB is not read)"),
                ));
            }
            let kind = match (c > 1, t > 1) {
                (false, false) => "TIFF (ImageJ)".to_string(),
                (true, false) => format!("TIFF (ImageJ hyperstack, {c} channels)"),
                (false, true) => format!("TIFF (ImageJ hyperstack, {t} frames)"),
                (true, true) => format!("TIFF (ImageJ hyperstack, {c} channels, {t} frames)"),
            };
            fields.push(("format".to_string(), kind));
            // ImageJ's page order: channel fastest, then slice, then frame
            (z, c, t, [c, 1, c * z])
        } else if let Some(px) = ome_pixels(&description) {
            let get = |k: &str| -> Result<usize, VolumeError> {
                match px.iter().find(|(key, _)| key == k) {
                    None => Ok(1),
                    Some((_, v)) => v.parse::<usize>().ok().filter(|&x| x >= 1).ok_or_else(|| {
                        header_err(
                            path,
                            format!("OME-XML: Pixels {k}=\"{v}\": expected a whole number of at least 1"),
                        )
                    }),
                }
            };
            let (z, c, t) = (get("SizeZ")?, get("SizeC")?, get("SizeT")?);
            let order = px
                .iter()
                .find(|(k, _)| k == "DimensionOrder")
                .map_or("XYZCT".to_string(), |(_, v)| v.clone());
            let planes = z.checked_mul(c).and_then(|zc| zc.checked_mul(t));
            if planes.is_none_or(|p| p > n) {
                return Err(header_err(
                    path,
                    format!("OME-XML: SizeZ={z} x SizeC={c} x SizeT={t} planes, but the file has {n} pages"),
                ));
            }
            let planes = planes.unwrap_or(n);
            // DimensionOrder is `XY` then Z, C and T, the fastest first: each axis's
            // stride is the product of the sizes of those before it
            let rest: Vec<char> = order.chars().skip(2).collect();
            let mut sorted = rest.clone();
            sorted.sort_unstable();
            if !order.starts_with("XY") || sorted != ['C', 'T', 'Z'] {
                return Err(header_err(
                    path,
                    format!("OME-XML: DimensionOrder=\"{order}\": expected XY followed by Z, C and T in some order"),
                ));
            }
            let size = |a: char| match a {
                'Z' => z,
                'C' => c,
                _ => t,
            };
            let stride = |a: char| {
                rest.iter()
                    .take_while(|&&b| b != a)
                    .map(|&b| size(b))
                    .product::<usize>()
            };
            let kind = match (c > 1, t > 1) {
                (false, false) => "OME-TIFF".to_string(),
                (true, false) => format!("OME-TIFF ({c} channels)"),
                (false, true) => format!("OME-TIFF ({t} frames)"),
                (true, true) => format!("OME-TIFF ({c} channels, {t} frames)"),
            };
            fields.push(("format".to_string(), kind));
            if planes < n {
                fields.push((
                    "pages".into(),
                    format!("{n}, of which the first image's {planes} are read"),
                ));
            }
            (z, c, t, [stride('Z'), stride('C'), stride('T')])
        } else {
            if let Some(shape) = tifffile_shape(&description) {
                // the axes beyond the page's rows and columns
                let outer: Vec<usize> = shape[..shape.len().saturating_sub(2)].to_vec();
                if outer.iter().filter(|&&s| s > 1).count() > 1 {
                    return Err(unsupported(
                        path,
                        format!("tifffile's shape {shape:?} has more than one axis beyond rows and columns, and the file does not name them: write it with imagej=True or as OME-TIFF, so that channels and slices are told apart"),
                    ));
                }
            }
            fields.push(("format".to_string(), "TIFF".into()));
            (n, 1, 1, [1, 0, 0])
        };
        let channel = choose(path, "channel", "channel", self.channel, channels)?;
        let frame = choose(path, "index", "frame", self.index, frames)?;
        if fields.iter().all(|(k, _)| k != "pages") {
            fields.push(("pages".into(), n.to_string()));
        }
        if channels > 1 {
            fields.push(("channel".into(), format!("{channel} of {channels}")));
        }
        if frames > 1 {
            fields.push(("frame".into(), format!("{frame} of {frames} (index)")));
        }
        fields.push(("compression".into(), compression_name(first.compression).0));
        let slices = (0..z_count)
            .map(|k| {
                let page = k * strides[0] + channel * strides[1] + frame * strides[2];
                (path.clone(), page)
            })
            .collect();
        let spacing = spacing(path, &info, Some(&description), &mut fields)?;
        Ok(Layout {
            slices,
            page: first,
            spacing,
            fields,
        })
    }

    fn volume_header(&self, l: &Layout) -> Result<VolumeHeader, VolumeError> {
        let geometry = Geometry::from_spacing(l.spacing);
        if !geometry.is_valid() {
            return Err(header_err(
                &self.path,
                format!("spacing {:?}: expected positive numbers", l.spacing),
            ));
        }
        Ok(VolumeHeader {
            sizes: [l.page.width, l.page.height, l.slices.len()],
            scalar_type: l.page.ty,
            geometry,
            source: self.path.display().to_string(),
            fields: l.fields.clone(),
            rescale: Default::default(),
        })
    }

    /// Sizes, type and spacing (reads every page's directory, no pixels).
    pub fn header(&self) -> Result<VolumeHeader, VolumeError> {
        self.volume_header(&self.layout()?)
    }

    /// The pages are always decoded into memory.
    pub fn storage(&self) -> Result<Storage, VolumeError> {
        let l = self.layout()?;
        let h = self.volume_header(&l)?;
        let files = self.files()?.map_or(1, |f| f.len());
        Ok(Storage::Read {
            bytes: h.data_bytes(),
            reason: if files > 1 {
                ReadReason::DataFiles(files as u64)
            } else {
                ReadReason::Compressed("TIFF pages, decoded one by one")
            },
        })
    }

    /// Reads the chosen pages: `limits` checked before anything is allocated; the
    /// XXH3-128 of the decoded samples (native byte order), page by page, when `hash`.
    pub fn load_hashed(
        &self,
        limits: &Limits,
        hash: bool,
    ) -> Result<(Volume, Option<u128>), VolumeError> {
        let l = self.layout()?;
        let header = self.volume_header(&l)?;
        let (count, _) = limits
            .check(&header.sizes, header.scalar_type.size())
            .map_err(|e| match e {
                VolumeError::TooLarge { bytes, limit, .. } => VolumeError::TooLarge {
                    what: format!(
                        "{} ({} x {} x {} {} voxels)",
                        self.path.display(),
                        header.sizes[0],
                        header.sizes[1],
                        header.sizes[2],
                        header.scalar_type
                    ),
                    bytes,
                    limit,
                },
                other => other,
            })?;
        let per_page = l.page.width * l.page.height;
        let page_bytes = per_page * l.page.ty.size();
        let mut sink = ElementSink::new(l.page.ty, count, cfg!(target_endian = "little"));
        if hash {
            sink = sink.hashing();
        }
        let mut open_file: Option<(PathBuf, TiffDecoder)> = None;
        for (file, page) in &l.slices {
            if open_file.as_ref().is_none_or(|(p, _)| p != file) {
                let (d, _) = open(file)?;
                let mut limits = TiffLimits::default();
                limits.ifd_value_size = MAX_TAG_BYTES;
                // the page's buffer was checked against the volume's limit above
                limits.decoding_buffer_size = page_bytes;
                limits.intermediate_buffer_size = limits.intermediate_buffer_size.max(page_bytes);
                open_file = Some((file.clone(), d.with_limits(limits)));
            }
            let Some((_, d)) = open_file.as_mut() else {
                continue;
            };
            d.seek_to_image(*page)
                .map_err(|e| tiff_err(file, *page, e))?;
            let mut decoded = d.read_image().map_err(|e| tiff_err(file, *page, e))?;
            let bytes = decoded_bytes(&mut decoded, l.page.ty).ok_or_else(|| {
                data_err(
                    file,
                    format!(
                        "page {page}: decoded as other samples than its directory's {}",
                        l.page.ty
                    ),
                )
            })?;
            if bytes.len() != page_bytes {
                return Err(data_err(
                    file,
                    format!(
                        "page {page}: decoded {} bytes, expected {} x {} x {} = {page_bytes}",
                        bytes.len(),
                        l.page.width,
                        l.page.height,
                        l.page.ty.size()
                    ),
                ));
            }
            sink.read(&mut &bytes[..], per_page).map_err(|e| match e {
                ReadError::Memory { bytes } => VolumeError::OutOfMemory {
                    path: file.clone(),
                    bytes,
                },
                other => data_err(file, format!("page {page}: {other:?}")),
            })?;
        }
        let digest = sink.hash();
        Ok((
            Volume {
                header,
                data: sink.finish().into(),
            },
            digest,
        ))
    }
}

/// The samples of a decoded page as bytes in the machine's order, if they are of `ty`.
fn decoded_bytes(d: &mut DecodingResult, ty: ScalarType) -> Option<&[u8]> {
    let same = matches!(
        (&*d, ty),
        (DecodingResult::U8(_), ScalarType::Uint8)
            | (DecodingResult::U16(_), ScalarType::Uint16)
            | (DecodingResult::U32(_), ScalarType::Uint32)
            | (DecodingResult::U64(_), ScalarType::Uint64)
            | (DecodingResult::I8(_), ScalarType::Int8)
            | (DecodingResult::I16(_), ScalarType::Int16)
            | (DecodingResult::I32(_), ScalarType::Int32)
            | (DecodingResult::I64(_), ScalarType::Int64)
            | (DecodingResult::F32(_), ScalarType::Float32)
            | (DecodingResult::F64(_), ScalarType::Float64)
    );
    same.then(|| match d {
        DecodingResult::U8(v) => v.as_slice(),
        DecodingResult::I8(v) => bytes_of(v),
        DecodingResult::U16(v) => bytes_of(v),
        DecodingResult::I16(v) => bytes_of(v),
        DecodingResult::U32(v) => bytes_of(v),
        DecodingResult::I32(v) => bytes_of(v),
        DecodingResult::U64(v) => bytes_of(v),
        DecodingResult::I64(v) => bytes_of(v),
        DecodingResult::F32(v) => bytes_of(v),
        DecodingResult::F64(v) => bytes_of(v),
        DecodingResult::F16(_) => &[],
    })
}

/// The bytes of a slice of primitive numbers.
fn bytes_of<T: super::Voxel>(v: &[T]) -> &[u8] {
    super::Voxels::from_slice(v).as_bytes()
}

/// The `key = k` of an axis of `count` entries (`what`: "channel", "frame"): the one
/// there is, or the one chosen, in range.
fn choose(
    path: &Path,
    key: &str,
    what: &str,
    chosen: Option<usize>,
    count: usize,
) -> Result<usize, VolumeError> {
    let plural = if count == 1 { "" } else { "s" };
    match chosen {
        None if count == 1 => Ok(0),
        None => Err(VolumeError::Invalid(format!(
            "{}: the file has {count} {what}s: choose one with `{key} = 0` to {} in [volume]",
            path.display(),
            count - 1
        ))),
        Some(k) if k >= count => Err(VolumeError::Invalid(format!(
            "{}: {key} = {k} is out of range: the file has {count} {what}{plural} ({key} = 0{})",
            path.display(),
            if count == 1 {
                String::new()
            } else {
                format!(" to {}", count - 1)
            }
        ))),
        Some(k) => Ok(k),
    }
}

/// tifffile's `{"shape": [...]}` description, if that is what it is.
fn tifffile_shape(description: &str) -> Option<Vec<usize>> {
    if !description.trim_start().starts_with('{') {
        return None;
    }
    let v: serde_json::Value = serde_json::from_str(description.trim_end_matches('\0')).ok()?;
    v.get("shape")?
        .as_array()?
        .iter()
        .map(|x| x.as_u64().map(|x| x as usize))
        .collect()
}

/// The voxel spacing a file declares, and fields saying where it came from.
fn spacing(
    path: &Path,
    info: &FileInfo,
    description: Option<&str>,
    fields: &mut Vec<(String, String)>,
) -> Result<[f64; 3], VolumeError> {
    let description = description.map_or_else(
        || info.description.clone().unwrap_or_default(),
        str::to_string,
    );
    let mut field = |k: &str, v: String| fields.push((k.to_string(), v));
    let positive = |what: &str, x: f64| -> Result<f64, VolumeError> {
        if x.is_finite() && x > 0.0 {
            Ok(x)
        } else {
            Err(header_err(
                path,
                format!("{what} is {x}: expected a positive number"),
            ))
        }
    };
    if let Some(ij) = imagej(&description) {
        let get = |k: &str| ij.iter().find(|(key, _)| key == k).map(|(_, v)| v.clone());
        let unit = get("unit").map(|u| imagej_unit(&u));
        let [x, y] = match info.resolution {
            Some([x, y]) => {
                field(
                    "spacing x, y",
                    "1 / XResolution, 1 / YResolution (ImageJ)".into(),
                );
                [
                    positive("1 / XResolution", x)?,
                    positive("1 / YResolution", y)?,
                ]
            }
            None => {
                field(
                    "spacing x, y",
                    "assumed 1 (no XResolution, YResolution)".into(),
                );
                [1.0, 1.0]
            }
        };
        let z = match get("spacing") {
            Some(s) => {
                let z = s.parse::<f64>().map_err(|_| {
                    header_err(
                        path,
                        format!("ImageJ description: `spacing={s}`: expected a number"),
                    )
                })?;
                field("spacing z", "spacing= (ImageJ)".into());
                positive("ImageJ spacing", z)?
            }
            None => {
                field(
                    "spacing z",
                    "assumed 1 (no spacing= in the ImageJ description)".into(),
                );
                1.0
            }
        };
        field(
            "unit",
            unit.unwrap_or_else(|| "none given (ImageJ: pixels)".into()),
        );
        return Ok([x, y, z]);
    }
    if let Some(px) = ome_pixels(&description) {
        let get = |k: &str| px.iter().find(|(key, _)| key == k).map(|(_, v)| v.clone());
        let mut sizes = [1.0; 3];
        let mut units = ["µm".to_string(), "µm".to_string(), "µm".to_string()];
        let mut given = [false; 3];
        for (i, a) in ["X", "Y", "Z"].iter().enumerate() {
            if let Some(v) = get(&format!("PhysicalSize{a}")) {
                let s = v.parse::<f64>().map_err(|_| {
                    header_err(
                        path,
                        format!("OME-XML: PhysicalSize{a}=\"{v}\": expected a number"),
                    )
                })?;
                sizes[i] = positive(&format!("OME PhysicalSize{a}"), s)?;
                given[i] = true;
            }
            if let Some(u) = get(&format!("PhysicalSize{a}Unit")) {
                units[i] = u;
            }
        }
        // every axis in the unit of the first given one
        let unit = units[given.iter().position(|&g| g).unwrap_or(0)].clone();
        let exponent = |u: &str| {
            metres_exponent(u).ok_or_else(|| {
                unsupported(path, format!("OME-XML: PhysicalSize unit {u:?} is not a length volcast knows (m, cm, mm, µm, nm, Å, pm)"))
            })
        };
        let to = exponent(&unit)?;
        for i in 0..3 {
            if given[i] {
                let d = exponent(&units[i])? - to;
                let scale = 10f64.powi(d.abs());
                sizes[i] = if d >= 0 {
                    sizes[i] * scale
                } else {
                    sizes[i] / scale
                };
            }
        }
        let said = |i: usize, a: &str| {
            if given[i] {
                format!("PhysicalSize{a} (OME-XML)")
            } else {
                format!("assumed 1 (no PhysicalSize{a} in the OME-XML)")
            }
        };
        field(
            "spacing x, y",
            format!("{}, {}", said(0, "X"), said(1, "Y")),
        );
        field("spacing z", said(2, "Z"));
        field("unit", unit);
        return Ok(sizes);
    }
    let z_note = "assumed 1 (no ImageJ or OME description)".to_string();
    match info.resolution {
        // pixels per centimetre measure the pixels; per inch (72 dpi by default) is
        // the size a page prints at
        Some([x, y]) if info.resolution_unit == 3 => {
            field(
                "spacing x, y",
                "1 / XResolution, 1 / YResolution (ResolutionUnit centimetre)".into(),
            );
            field("spacing z", z_note);
            field("unit", "cm".into());
            Ok([
                positive("1 / XResolution", x)?,
                positive("1 / YResolution", y)?,
                1.0,
            ])
        }
        Some(_) => {
            field("spacing", "assumed 1 (XResolution and YResolution are per inch or unitless: a print size, not a pixel size)".into());
            Ok([1.0; 3])
        }
        None => {
            field(
                "spacing",
                "assumed 1 (no ImageJ or OME description, no resolution)".into(),
            );
            Ok([1.0; 3])
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order_counts_numbers() {
        let mut v = vec![
            "img_10.tif",
            "img_9.tif",
            "img_8.tif",
            "a.tif",
            "img_010.tif",
        ];
        v.sort_by(|a, b| natural(a, b));
        assert_eq!(
            v,
            [
                "a.tif",
                "img_8.tif",
                "img_9.tif",
                "img_10.tif",
                "img_010.tif"
            ]
        );
    }

    #[test]
    fn glob_patterns() {
        let m = |p: &str, n: &str| {
            matches(
                &p.chars().collect::<Vec<_>>(),
                &n.chars().collect::<Vec<_>>(),
            )
        };
        assert!(m("*.tif", "s1.tif"));
        assert!(m("s?.tif", "s1.tif"));
        assert!(!m("s?.tif", "s10.tif"));
        assert!(!m("*.tif", "s1.tiff"));
    }

    #[test]
    fn ome_pixels_attributes() {
        let xml = r#"<?xml version="1.0"?><OME xmlns="x"><Image ID="Image:0"><Pixels DimensionOrder="XYCZT" ID='Pixels:0' PhysicalSizeX="0.5" SizeC="2"><TiffData/></Pixels></Image></OME>"#;
        let px = ome_pixels(xml).unwrap();
        assert!(px.contains(&("DimensionOrder".into(), "XYCZT".into())));
        assert!(px.contains(&("ID".into(), "Pixels:0".into())));
        assert!(px.contains(&("SizeC".into(), "2".into())));
        assert_eq!(imagej_unit("\\u00B5m"), "µm");
    }
}
