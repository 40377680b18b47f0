//! DICOM series (a folder of single-frame slices, `format = "dicom"`), read with the
//! `dicom` crate family (`dicom-object`).
//!
//! ```text
//! DicomSpec::slices   every regular file of the folder (no subfolders), in name order:
//!                     scan::scan (DICM magic; every declared length against the
//!                     file's, before the crate allocates it; the transfer syntax:
//!                     uncompressed little-endian only, others refused by name), then
//!                     the crate reads the elements up to the pixel data
//!                     series: the one there is, or `series = "UID"`
//!                     ImageOrientationPatient: two unit vectors at right angles
//!                     sorted by ImagePositionPatient along the slice normal; equal
//!                     spacing; gantry tilt refused; one slice: the z spacing is its
//!                     SliceThickness, else 1 (a "spacing z" field says so)
//! DicomSpec::load     Limits::check (columns x rows x slices), then each slice's pixel
//!                     data appended in order, each value taken from bits
//!                     HighBit+1-BitsStored ..= HighBit of its cell (PS3.5 8, sign
//!                     extended when signed); rescale slope/intercept: the same for
//!                     every slice -> the header's Rescale (voxels keep their type);
//!                     different -> float32 values slope * x + intercept
//! ```
//!
//! Voxel `(i, j, k)` (column, row, slice) sits at `IPP_0 + i dc X + j dr Y + k s`:
//! `X`, `Y` the row and column directions of ImageOrientationPatient, `dr, dc` the
//! PixelSpacing, `s` the step between sorted slice positions. World coordinates are the
//! patient's LPS, kept as they are.

mod scan;

use crate::volume::errors::header_err;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dicom_dictionary_std::tags;
use dicom_object::file::ReadPreamble;
use dicom_object::{DefaultDicomObject, OpenFileOptions};
use glam::DVec3;

use super::mapped::open_regular;
use super::{
    Geometry, Limits, ReadReason, Rescale, ScalarType, Storage, Volume, VolumeData, VolumeError,
    VolumeHeader,
};
use nrrd::{ElementSink, ReadError};

/// Most files a series folder may hold.
const MAX_FILES: usize = 100_000;

/// How far from 1 the length of either direction of ImageOrientationPatient may be:
/// GDCM's bound (1e-3 on the squared length), which cosines rounded to 4 digits stay
/// inside; the spacing is scaled by that length, so it is also the spacing's error.
const UNIT_TOLERANCE: f64 = 5e-4;

/// How far from 0 the dot product of the two directions may be (GDCM's bound).
const ORTHOGONAL_TOLERANCE: f64 = 1e-3;

/// The transfer syntaxes read: uncompressed, little-endian.
const READABLE: [(&str, &str); 2] = [
    ("1.2.840.10008.1.2", "Implicit VR Little Endian"),
    ("1.2.840.10008.1.2.1", "Explicit VR Little Endian"),
];

/// A folder of DICOM slices and the series to render.
#[derive(Clone, Debug, PartialEq)]
pub struct DicomSpec {
    /// The folder.
    pub dir: PathBuf,
    /// `series = "UID"`: the SeriesInstanceUID to render (needed when the folder holds
    /// several series).
    pub series: Option<String>,
}

/// What one slice says about itself.
#[derive(Clone, Debug)]
struct Slice {
    path: PathBuf,
    series: String,
    description: String,
    modality: String,
    transfer_syntax: String,
    rows: usize,
    columns: usize,
    bits_allocated: u16,
    bits_stored: u16,
    /// The most significant bit of a value in its cell (PS3.5 8): the value is bits
    /// `high_bit + 1 - bits_stored ..= high_bit`.
    high_bit: u16,
    signed: bool,
    orientation: [f64; 6],
    position: DVec3,
    spacing: [f64; 2],
    /// SliceThickness (0018,0050), the z spacing of a series of one slice: `Ok(None)`
    /// when missing or empty, `Err(text)` when it is not a positive number.
    thickness: Result<Option<f64>, String>,
    rescale: Rescale,
}

/// A sorted, checked series.
#[derive(Debug)]
struct Series {
    slices: Vec<Slice>,
    scalar_type: ScalarType,
    geometry: Geometry,
    /// The common rescale, or `None` when slices differ (voxels become float32).
    rescale: Option<Rescale>,
    /// How the z spacing was chosen when it could not be measured (one slice).
    assumed_z: Option<String>,
}

fn invalid(dir: &Path, message: String) -> VolumeError {
    VolumeError::Invalid(format!("{}: {message}", dir.display()))
}

/// Opens a DICOM file through the crate (after [`scan::scan`] checked its lengths),
/// reading up to the pixel data (`header_only`) or all of it.
fn open(path: &Path, header_only: bool) -> Result<DefaultDicomObject, VolumeError> {
    let (file, _) = open_regular(path, "a DICOM file")?;
    let mut options = OpenFileOptions::new().read_preamble(ReadPreamble::Always);
    if header_only {
        options = options.read_until(tags::PIXEL_DATA);
    }
    options
        .from_reader(std::io::BufReader::new(file))
        .map_err(|e| VolumeError::Data {
            path: path.to_path_buf(),
            message: format!("not a readable DICOM file: {e}"),
        })
}

/// The name of a transfer syntax UID.
fn syntax_name(uid: &str) -> String {
    use dicom_encoding::transfer_syntax::TransferSyntaxIndex;
    use dicom_transfer_syntax_registry::TransferSyntaxRegistry;
    TransferSyntaxRegistry.get(uid).map_or_else(
        || format!("{uid} (unknown)"),
        |ts| format!("{uid} ({})", ts.name()),
    )
}

/// `x` to 6 decimals, without trailing zeros.
fn short(x: f64) -> String {
    let s = format!("{x:.6}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

fn read_slice(path: &Path, transfer_syntax: String) -> Result<Slice, VolumeError> {
    let obj = open(path, true)?;
    let missing = |what: &str| {
        header_err(
            path,
            format!("missing {what}: a slice of a volume needs it"),
        )
    };
    let bad = |what: &str, e: &dyn std::fmt::Display| header_err(path, format!("{what}: {e}"));
    let text = |tag, what: &str| -> Result<String, VolumeError> {
        match obj.element_opt(tag) {
            Ok(Some(e)) => Ok(e
                .to_str()
                .map_err(|e| bad(what, &e))?
                .trim_end_matches(['\0', ' '])
                .to_string()),
            _ => Ok(String::new()),
        }
    };
    let int = |tag, what: &str| -> Result<Option<i64>, VolumeError> {
        match obj.element_opt(tag) {
            Ok(Some(e)) => e.to_int::<i64>().map(Some).map_err(|e| bad(what, &e)),
            _ => Ok(None),
        }
    };
    let floats = |tag, what: &str, n: usize| -> Result<Option<Vec<f64>>, VolumeError> {
        match obj.element_opt(tag) {
            Ok(Some(e)) => {
                let v = e.to_multi_float64().map_err(|e| bad(what, &e))?;
                if v.len() != n || !v.iter().all(|x| x.is_finite()) {
                    return Err(header_err(
                        path,
                        format!(
                            "{what} has {} values {v:?}, expected {n} finite numbers",
                            v.len()
                        ),
                    ));
                }
                Ok(Some(v))
            }
            _ => Ok(None),
        }
    };
    if let Some(frames) = int(tags::NUMBER_OF_FRAMES, "NumberOfFrames (0028,0008)")? {
        if frames > 1 {
            return Err(VolumeError::Unsupported {
                path: path.to_path_buf(),
                message: format!("NumberOfFrames (0028,0008) is {frames}: multi-frame files are not supported (one slice per file)"),
            });
        }
    }
    let samples = int(tags::SAMPLES_PER_PIXEL, "SamplesPerPixel")?.unwrap_or(1);
    let photometric = text(
        tags::PHOTOMETRIC_INTERPRETATION,
        "PhotometricInterpretation",
    )?;
    if samples != 1 || !(photometric.is_empty() || photometric.starts_with("MONOCHROME")) {
        return Err(VolumeError::Unsupported {
            path: path.to_path_buf(),
            message: format!("SamplesPerPixel {samples}, PhotometricInterpretation {photometric:?}: volcast renders greyscale (MONOCHROME1/2) slices"),
        });
    }
    let positive = |v: Option<i64>, what: &str| -> Result<usize, VolumeError> {
        match v {
            Some(n) if (1..=65535).contains(&n) => Ok(n as usize),
            Some(n) => Err(header_err(
                path,
                format!("{what} is {n}, expected 1 to 65535"),
            )),
            None => Err(missing(what)),
        }
    };
    let rows = positive(int(tags::ROWS, "Rows (0028,0010)")?, "Rows (0028,0010)")?;
    let columns = positive(
        int(tags::COLUMNS, "Columns (0028,0011)")?,
        "Columns (0028,0011)",
    )?;
    let bits_allocated = match int(tags::BITS_ALLOCATED, "BitsAllocated (0028,0100)")? {
        Some(b @ (8 | 16 | 32)) => b as u16,
        Some(b) => {
            return Err(VolumeError::Unsupported {
                path: path.to_path_buf(),
                message: format!("BitsAllocated (0028,0100) is {b}: volcast reads 8, 16 or 32"),
            })
        }
        None => return Err(missing("BitsAllocated (0028,0100)")),
    };
    let bits_stored = match int(tags::BITS_STORED, "BitsStored (0028,0101)")? {
        None => bits_allocated,
        Some(b) if (1..=i64::from(bits_allocated)).contains(&b) => b as u16,
        Some(b) => {
            return Err(header_err(
                path,
                format!(
                    "BitsStored (0028,0101) is {b}, expected 1 to BitsAllocated ({bits_allocated})"
                ),
            ))
        }
    };
    let high_bit = match int(tags::HIGH_BIT, "HighBit (0028,0102)")? {
        None => bits_stored - 1,
        Some(h) if (i64::from(bits_stored) - 1..i64::from(bits_allocated)).contains(&h) => h as u16,
        Some(h) => {
            return Err(header_err(
                path,
                format!(
                    "HighBit (0028,0102) is {h}, expected BitsStored-1 .. BitsAllocated-1 ({} to {}): the top bit of a {bits_stored}-bit value in a {bits_allocated}-bit cell",
                    bits_stored - 1,
                    bits_allocated - 1
                ),
            ))
        }
    };
    let signed = int(
        tags::PIXEL_REPRESENTATION,
        "PixelRepresentation (0028,0103)",
    )? == Some(1);
    let orientation = floats(
        tags::IMAGE_ORIENTATION_PATIENT,
        "ImageOrientationPatient (0020,0037)",
        6,
    )?
    .ok_or_else(|| missing("ImageOrientationPatient (0020,0037)"))?;
    let [x, y] = [0, 3].map(|i| DVec3::from_slice(&orientation[i..i + 3]));
    let (lx, ly, dot) = (x.length(), y.length(), x.dot(y));
    if (lx - 1.0).abs() > UNIT_TOLERANCE
        || (ly - 1.0).abs() > UNIT_TOLERANCE
        || dot.abs() > ORTHOGONAL_TOLERANCE
    {
        return Err(header_err(
            path,
            format!(
                "ImageOrientationPatient (0020,0037) is {orientation:?}: its row and column directions have lengths {} and {} and dot product {}, expected unit vectors (lengths within {UNIT_TOLERANCE} of 1) at right angles (dot product within {ORTHOGONAL_TOLERANCE} of 0)",
                short(lx),
                short(ly),
                short(dot)
            ),
        ));
    }
    let position = floats(
        tags::IMAGE_POSITION_PATIENT,
        "ImagePositionPatient (0020,0032)",
        3,
    )?
    .ok_or_else(|| missing("ImagePositionPatient (0020,0032)"))?;
    let spacing = floats(tags::PIXEL_SPACING, "PixelSpacing (0028,0030)", 2)?
        .ok_or_else(|| missing("PixelSpacing (0028,0030)"))?;
    if !spacing.iter().all(|&s| s > 0.0) {
        return Err(header_err(
            path,
            format!("PixelSpacing (0028,0030) is {spacing:?}, expected two positive numbers"),
        ));
    }
    let slope = floats(tags::RESCALE_SLOPE, "RescaleSlope (0028,1053)", 1)?.map_or(1.0, |v| v[0]);
    let intercept =
        floats(tags::RESCALE_INTERCEPT, "RescaleIntercept (0028,1052)", 1)?.map_or(0.0, |v| v[0]);
    if slope == 0.0 {
        return Err(header_err(path, "RescaleSlope (0028,1053) is 0".into()));
    }
    // read leniently: only a series of one slice uses it, so a bad value elsewhere
    // must not refuse a readable series
    let thickness = match obj.element_opt(tags::SLICE_THICKNESS) {
        Ok(Some(e)) => {
            let text = e.to_str().map_or_else(
                |_| String::new(),
                |t| t.trim_matches(['\0', ' ']).to_string(),
            );
            match e.to_float64() {
                Ok(t) if t.is_finite() && t > 0.0 => Ok(Some(t)),
                _ if text.is_empty() => Ok(None),
                _ => Err(text),
            }
        }
        _ => Ok(None),
    };
    Ok(Slice {
        path: path.to_path_buf(),
        series: text(tags::SERIES_INSTANCE_UID, "SeriesInstanceUID")?,
        description: text(tags::SERIES_DESCRIPTION, "SeriesDescription")?,
        modality: text(tags::MODALITY, "Modality")?,
        transfer_syntax,
        rows,
        columns,
        bits_allocated,
        bits_stored,
        high_bit,
        signed,
        orientation: std::array::from_fn(|i| orientation[i]),
        position: DVec3::new(position[0], position[1], position[2]),
        spacing: [spacing[0], spacing[1]],
        thickness,
        rescale: Rescale { slope, intercept },
    })
}

impl DicomSpec {
    /// The DICOM files of the folder (regular files holding `DICM` at byte 128), in
    /// name order; every declared length checked.
    fn files(&self) -> Result<Vec<(PathBuf, String)>, VolumeError> {
        let io = |source| VolumeError::Io {
            path: self.dir.clone(),
            source,
        };
        if !self.dir.is_dir() {
            return Err(invalid(
                &self.dir,
                "format = \"dicom\" reads a folder of slices: `path` must name the folder".into(),
            ));
        }
        let mut names = Vec::new();
        for e in std::fs::read_dir(&self.dir).map_err(io)? {
            let p = e.map_err(io)?.path();
            // regular files, or links to them (a link leading outside --confine is
            // refused when it is checked and opened)
            if std::fs::metadata(&p).is_ok_and(|m| m.is_file()) {
                names.push(p);
            }
            if names.len() > MAX_FILES {
                return Err(invalid(&self.dir, format!("more than {MAX_FILES} files")));
            }
        }
        names.sort();
        let mut out = Vec::new();
        for p in names {
            if let Some(s) = scan::scan(&p)? {
                // a DICOMDIR (media storage directory) is not a slice
                if s.sop_class.as_deref() != Some("1.2.840.10008.1.3.10") {
                    out.push((p, s.transfer_syntax));
                }
            }
        }
        if out.is_empty() {
            return Err(invalid(
                &self.dir,
                "no DICOM files (none has `DICM` at byte 128)".into(),
            ));
        }
        Ok(out)
    }

    /// Every file the series is read from.
    pub fn input_files(&self) -> Result<Vec<PathBuf>, VolumeError> {
        Ok(self.series()?.slices.into_iter().map(|s| s.path).collect())
    }

    fn series(&self) -> Result<Series, VolumeError> {
        let mut by_series: BTreeMap<String, Vec<Slice>> = BTreeMap::new();
        for (path, ts) in self.files()? {
            if !READABLE.iter().any(|(uid, _)| *uid == ts) {
                return Err(VolumeError::Unsupported {
                    path,
                    message: format!(
                        "transfer syntax {} is not supported: volcast reads uncompressed little-endian data ({}); decompress the series first (e.g. gdcmconv --raw, or dcmdjpeg)",
                        syntax_name(&ts),
                        READABLE.map(|(_, n)| n).join(", ")
                    ),
                });
            }
            let s = read_slice(&path, ts)?;
            by_series.entry(s.series.clone()).or_default().push(s);
        }
        let list = || {
            by_series
                .iter()
                .map(|(uid, s)| {
                    format!(
                        "\"{uid}\" ({} slices{}{})",
                        s.len(),
                        if s[0].modality.is_empty() {
                            String::new()
                        } else {
                            format!(", {}", s[0].modality)
                        },
                        if s[0].description.is_empty() {
                            String::new()
                        } else {
                            format!(", {}", s[0].description)
                        }
                    )
                })
                .collect::<Vec<_>>()
                .join(", ")
        };
        let list = list();
        let slices = match &self.series {
            Some(uid) => match by_series.remove(uid) {
                Some(s) => s,
                None => return Err(invalid(&self.dir, format!("series = \"{uid}\" is not in the folder; it holds {list}"))),
            },
            None if by_series.len() > 1 => {
                return Err(invalid(&self.dir, format!("the folder holds {} series: choose one with `series = \"UID\"` in [volume]: {list}", by_series.len())))
            }
            None => by_series.into_values().next().unwrap_or_default(),
        };
        self.checked(slices)
    }

    /// Sorts the slices of one series and checks that they make a volume.
    fn checked(&self, mut slices: Vec<Slice>) -> Result<Series, VolumeError> {
        let first = slices[0].clone();
        for s in &slices[1..] {
            let same = s.rows == first.rows
                && s.columns == first.columns
                && s.bits_allocated == first.bits_allocated
                && s.bits_stored == first.bits_stored
                && s.high_bit == first.high_bit
                && s.signed == first.signed
                && s.spacing == first.spacing
                && s.orientation
                    .iter()
                    .zip(&first.orientation)
                    .all(|(a, b)| (a - b).abs() < 1e-4);
            if !same {
                return Err(VolumeError::Unsupported {
                    path: s.path.clone(),
                    message: format!(
                        "its Rows, Columns, BitsAllocated, BitsStored, HighBit, PixelRepresentation, PixelSpacing or ImageOrientationPatient differ from those of {}: the slices of a volume share them",
                        first.path.display()
                    ),
                });
            }
        }
        let o = first.orientation;
        let x = DVec3::new(o[0], o[1], o[2]);
        let y = DVec3::new(o[3], o[4], o[5]);
        // every slice's directions were checked to be unit and orthogonal on reading
        let normal = x.cross(y).normalize();
        slices.sort_by(|a, b| a.position.dot(normal).total_cmp(&b.position.dot(normal)));
        let n = slices.len();
        let mut assumed_z = None;
        let step = if n > 1 {
            (slices[n - 1].position - slices[0].position) / (n - 1) as f64
        } else {
            let (z, from) = match &first.thickness {
                Ok(Some(t)) => (*t, "from SliceThickness (0018,0050)".to_string()),
                Ok(None) => (1.0, "no SliceThickness (0018,0050)".to_string()),
                Err(text) => (
                    1.0,
                    format!("SliceThickness (0018,0050) {text:?} is not a positive number"),
                ),
            };
            assumed_z = Some(format!(
                "assumed {z} (one slice: no second ImagePositionPatient to measure it; {from})"
            ));
            normal * z
        };
        for w in slices.windows(2) {
            let d = w[1].position - w[0].position;
            if d.length() < 1e-6 {
                return Err(VolumeError::Unsupported {
                    path: w[1].path.clone(),
                    message: format!(
                        "two slices at the same position {:?} (also {})",
                        w[0].position.to_array(),
                        w[0].path.display()
                    ),
                });
            }
            if (d - step).length() > 1e-3 * step.length().max(1.0) {
                return Err(VolumeError::Unsupported {
                    path: w[1].path.clone(),
                    message: format!(
                        "uneven slice spacing: {:.4} from the previous slice ({}), {:.4} on average: missing or extra slices?",
                        d.length(),
                        w[0].path.display(),
                        step.length()
                    ),
                });
            }
        }
        let tilt = step.normalize().cross(normal).length();
        if tilt > 1e-3 {
            return Err(VolumeError::Unsupported {
                path: self.dir.clone(),
                message: format!(
                    "gantry tilt: the slices are stacked {:.2} degrees away from their normal (ImagePositionPatient against ImageOrientationPatient); tilted series are not supported: resample them first",
                    tilt.asin().to_degrees()
                ),
            });
        }
        let scalar_type = match (first.bits_allocated, first.signed) {
            (8, false) => ScalarType::Uint8,
            (8, true) => ScalarType::Int8,
            (16, false) => ScalarType::Uint16,
            (16, true) => ScalarType::Int16,
            (32, false) => ScalarType::Uint32,
            _ => ScalarType::Int32,
        };
        let rescale = slices
            .iter()
            .all(|s| s.rescale == first.rescale)
            .then_some(first.rescale);
        let geometry = Geometry {
            origin: slices[0].position,
            axes: [x * first.spacing[1], y * first.spacing[0], step],
        };
        if !geometry.is_valid() {
            return Err(header_err(&first.path, "degenerate geometry".into()));
        }
        Ok(Series {
            slices,
            scalar_type,
            geometry,
            rescale,
            assumed_z,
        })
    }

    fn volume_header(&self, s: &Series) -> VolumeHeader {
        let first = &s.slices[0];
        let mut fields = vec![
            ("format".to_string(), "DICOM series".to_string()),
            (
                "space".to_string(),
                "LPS (DICOM patient coordinates, kept as they are)".to_string(),
            ),
            ("series".to_string(), first.series.clone()),
            ("slices".to_string(), s.slices.len().to_string()),
            (
                "transfer syntax".to_string(),
                syntax_name(&first.transfer_syntax),
            ),
        ];
        if !first.modality.is_empty() {
            fields.push(("modality".into(), first.modality.clone()));
        }
        if !first.description.is_empty() {
            fields.push(("description".into(), first.description.clone()));
        }
        if let Some(z) = &s.assumed_z {
            fields.push(("spacing z".into(), z.clone()));
        }
        if s.rescale.is_none() {
            fields.push((
                "rescale".into(),
                "differs between slices: voxels converted to float32 values".into(),
            ));
        }
        let [nx, ny] = [first.columns, first.rows];
        VolumeHeader {
            sizes: [nx, ny, s.slices.len()],
            scalar_type: if s.rescale.is_some() {
                s.scalar_type
            } else {
                ScalarType::Float32
            },
            geometry: s.geometry,
            source: self.dir.display().to_string(),
            fields,
            rescale: s.rescale.unwrap_or_default(),
        }
    }

    /// Sizes, type, geometry and rescale (reads every slice up to its pixel data).
    pub fn header(&self) -> Result<VolumeHeader, VolumeError> {
        Ok(self.volume_header(&self.series()?))
    }

    /// The voxels are always read (one file per slice).
    pub fn storage(&self) -> Result<Storage, VolumeError> {
        let h = self.header()?;
        Ok(Storage::Read {
            bytes: h.data_bytes(),
            reason: ReadReason::DataFiles(h.sizes[2] as u64),
        })
    }

    /// Reads the series: `limits` checked before allocating; the XXH3-128 of the pixel
    /// values (unpacked from their cells), slice by slice in order, when `hash`.
    pub fn load_hashed(
        &self,
        limits: &Limits,
        hash: bool,
    ) -> Result<(Volume, Option<u128>), VolumeError> {
        let series = self.series()?;
        let header = self.volume_header(&series);
        let (count, _) = limits.check(&header.sizes, header.scalar_type.size())?;
        let per_slice = header.sizes[0] * header.sizes[1];
        let stored = series.scalar_type;
        let mut sink = ElementSink::new(stored, count, true);
        let mut floats: Vec<f32> = Vec::new();
        if series.rescale.is_none() {
            floats
                .try_reserve_exact(count)
                .map_err(|_| VolumeError::OutOfMemory {
                    path: self.dir.clone(),
                    bytes: count as u64 * 4,
                })?;
        }
        let mut hasher = hash.then(xxhash_rust::xxh3::Xxh3::new);
        for s in &series.slices {
            let obj = open(&s.path, false)?;
            let pixels = obj
                .element(tags::PIXEL_DATA)
                .map_err(|_| header_err(&s.path, "no PixelData (7FE0,0010)".into()))?;
            let bytes = pixels.to_bytes().map_err(|e| VolumeError::Data {
                path: s.path.clone(),
                message: format!("PixelData (7FE0,0010): {e}"),
            })?;
            let need = per_slice * stored.size();
            if bytes.len() < need || bytes.len() > need + 1 {
                return Err(VolumeError::Data {
                    path: s.path.clone(),
                    message: format!(
                        "PixelData (7FE0,0010) has {} bytes, but Columns x Rows x BitsAllocated/8 = {} x {} x {} = {need}",
                        bytes.len(), s.columns, s.rows, stored.size()
                    ),
                });
            }
            let bytes = unpacked(&bytes[..need], s, stored);
            if let Some(h) = &mut hasher {
                h.update(&bytes);
            }
            if series.rescale.is_none() {
                let values = VolumeData::from_bytes(stored, &bytes, true);
                floats.extend((0..per_slice).map(|i| s.rescale.apply(values.get_f64(i)) as f32));
            } else {
                sink.read(&mut &bytes[..], per_slice).map_err(|e| match e {
                    ReadError::Memory { bytes } => VolumeError::OutOfMemory {
                        path: s.path.clone(),
                        bytes,
                    },
                    other => VolumeError::Data {
                        path: s.path.clone(),
                        message: format!("{other:?}"),
                    },
                })?;
            }
        }
        let data = if series.rescale.is_none() {
            VolumeData::F32(floats)
        } else {
            sink.finish().into()
        };
        Ok((Volume { header, data }, hasher.map(|h| h.digest128())))
    }
}

/// The values of the pixel cells: bits `HighBit + 1 - BitsStored ..= HighBit` of each
/// cell moved down to bit 0, the bits above cleared (unsigned) or filled with the sign
/// (signed), as PS3.5 8 lays a value out in its cell.
fn unpacked(bytes: &[u8], s: &Slice, ty: ScalarType) -> Vec<u8> {
    let bits = u32::from(s.bits_stored);
    let size = ty.size();
    // a value filling its cell (HighBit is then BitsStored - 1, checked on reading)
    if bits as usize == size * 8 {
        return bytes.to_vec();
    }
    // HighBit to bit 63 drops the bits above the value; shifting back down by
    // 64 - BitsStored drops those below it and extends the sign
    let up = 63 - u32::from(s.high_bit);
    let down = 64 - bits;
    bytes
        .chunks_exact(size)
        .flat_map(|c| {
            let mut v = [0u8; 8];
            v[..size].copy_from_slice(c);
            let x = u64::from_le_bytes(v) << up;
            let y = if s.signed {
                ((x as i64) >> down) as u64
            } else {
                x >> down
            };
            y.to_le_bytes()[..size].to_vec()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slice(bits_allocated: u16, bits_stored: u16, high_bit: u16, signed: bool) -> Slice {
        Slice {
            path: PathBuf::from("s.dcm"),
            series: String::new(),
            description: String::new(),
            modality: String::new(),
            transfer_syntax: String::new(),
            rows: 1,
            columns: 1,
            bits_allocated,
            bits_stored,
            high_bit,
            signed,
            orientation: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            position: DVec3::ZERO,
            spacing: [1.0, 1.0],
            thickness: Ok(None),
            rescale: Rescale::default(),
        }
    }

    #[test]
    fn unpacked_takes_the_bits_high_bit_ends() {
        // 8-bit cells, 7 bits ending at bit 7: the low bit is not part of the value
        let s = slice(8, 7, 7, false);
        assert_eq!(unpacked(&[0xFF, 0x81], &s, ScalarType::Uint8), [0x7F, 0x40]);
        // signed 32-bit cells, 24 bits ending at bit 27: bits 4..=27, bit 27 the sign
        let s = slice(32, 24, 27, true);
        let cells: Vec<u8> = [0xF800_000Fu32, 0x07FF_FFF0, 0x0000_0010]
            .iter()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let values: Vec<i32> = unpacked(&cells, &s, ScalarType::Int32)
            .chunks_exact(4)
            .map(|c| i32::from_le_bytes(c.try_into().unwrap()))
            .collect();
        assert_eq!(values, [-(1 << 23), (1 << 23) - 1, 1]);
        // a value filling its cell is kept as it is
        let s = slice(16, 16, 15, true);
        assert_eq!(unpacked(&[1, 0x80], &s, ScalarType::Int16), [1, 0x80]);
    }
}
