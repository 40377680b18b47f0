//! DICOM series (a folder of slices, `format = "dicom"`, or one file), read with the
//! `dicom` crate family (`dicom-object`; pixel data decoders of
//! `dicom-transfer-syntax-registry`, see `pixels.rs`).
//!
//! ```text
//! DicomSpec::files    every regular file of the folder (no subfolders), in name order,
//!                     or the one file: scan::scan (DICM magic; every declared length
//!                     against the file's (a deflated data set: against its inflated
//!                     length), before the crate allocates it; the transfer syntax:
//!                     pixels::READABLE, others refused by name), then the crate reads
//!                     the elements up to the pixel data
//! read_frames         a slice per frame: a single-frame file is one; an enhanced
//!                     multi-frame object's frames take ImagePositionPatient,
//!                     ImageOrientationPatient, PixelSpacing and the rescale from their
//!                     item of PerFrameFunctionalGroupsSequence, else the shared
//!                     groups, else the data set; an RT dose's frames sit at
//!                     GridFrameOffsetVector along the normal, DoseGridScaling their slope
//!                     series: the one there is, or `series = "UID"`
//!                     ImageOrientationPatient: two unit vectors at right angles
//!                     sorted by ImagePositionPatient along the slice normal; equal
//!                     spacing; gantry tilt refused; one slice: the z spacing is its
//!                     SliceThickness, else 1 (a "spacing z" field says so)
//! DicomSpec::load     Limits::check (columns x rows x slices), then each slice's pixel
//!                     data appended in order (a file opened once while its frames are
//!                     read; encapsulated frames decoded by pixels::decode), each
//!                     value taken from bits
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

mod pixels;
mod scan;

use crate::volume::errors::header_err;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dicom_core::Tag;
use dicom_dictionary_std::tags;
use dicom_object::file::ReadPreamble;
use dicom_object::mem::InMemElement;
use dicom_object::{DefaultDicomObject, InMemDicomObject, OpenFileOptions};
use glam::DVec3;

use super::mapped::open_regular;
use super::{
    Geometry, Limits, ReadReason, Rescale, ScalarType, Storage, Volume, VolumeData, VolumeError,
    VolumeHeader,
};
use nrrd::{ElementSink, ReadError};

/// Most files a series folder may hold.
const MAX_FILES: usize = 100_000;

/// Most slices (frames) a series may have.
const MAX_SLICES: usize = 100_000;

/// How far from 1 the length of either direction of ImageOrientationPatient may be:
/// GDCM's bound (1e-3 on the squared length), which cosines rounded to 4 digits stay
/// inside; the spacing is scaled by that length, so it is also the spacing's error.
const UNIT_TOLERANCE: f64 = 5e-4;

/// How far from 0 the dot product of the two directions may be (GDCM's bound).
const ORTHOGONAL_TOLERANCE: f64 = 1e-3;

/// A folder of DICOM slices (or one file, a multi-frame object) and the series to
/// render.
#[derive(Clone, Debug, PartialEq)]
pub struct DicomSpec {
    /// The folder, or one DICOM file.
    pub dir: PathBuf,
    /// `series = "UID"`: the SeriesInstanceUID to render (needed when the folder holds
    /// several series).
    pub series: Option<String>,
}

/// What one slice (a frame of a file) says about itself.
#[derive(Clone, Debug)]
struct Slice {
    path: PathBuf,
    /// The frame of the file (0 for a single-frame file) and how many it has.
    frame: usize,
    frames: usize,
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
    /// LossyImageCompression (0028,2110) when present: whether it is 01, and the
    /// attribute with its ratio and method, as `info` shows them.
    lossy: Option<(bool, String)>,
}

impl Slice {
    /// "frame k of n: " for a frame of a multi-frame file, for messages that name
    /// its file.
    fn frame_note(&self) -> String {
        if self.frames > 1 {
            format!("frame {} of {}: ", self.frame + 1, self.frames)
        } else {
            String::new()
        }
    }

    /// The file, and the frame of a multi-frame file, for messages.
    fn name(&self) -> String {
        if self.frames > 1 {
            format!(
                "{} (frame {} of {})",
                self.path.display(),
                self.frame + 1,
                self.frames
            )
        } else {
            self.path.display().to_string()
        }
    }
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

/// Whether `path` is a regular file holding `DICM` at byte 128 (a DICOM Part 10 file).
pub fn is_dicom_file(path: &Path) -> bool {
    use std::io::Read;
    let mut head = [0u8; 132];
    std::fs::metadata(path).is_ok_and(|m| m.is_file())
        && std::fs::File::open(path).is_ok_and(|mut f| f.read_exact(&mut head).is_ok())
        && &head[128..] == b"DICM"
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

/// Where a frame's attribute is found: its item of PerFrameFunctionalGroupsSequence,
/// then SharedFunctionalGroupsSequence (each in the functional group sequence `group`),
/// then the data set itself (PS3.3 C.7.6.16).
struct Groups<'a> {
    top: &'a InMemDicomObject,
    frame: Option<&'a InMemDicomObject>,
    shared: Option<&'a InMemDicomObject>,
}

impl<'a> Groups<'a> {
    fn find(&self, group: Tag, tag: Tag) -> Option<&'a InMemElement> {
        let in_group = |item: Option<&'a InMemDicomObject>| {
            item.and_then(|i| i.element_opt(group).ok().flatten())
                .and_then(|g| g.items())
                .and_then(|items| items.first())
                .and_then(|g| g.element_opt(tag).ok().flatten())
        };
        in_group(self.frame)
            .or_else(|| in_group(self.shared))
            .or_else(|| self.top.element_opt(tag).ok().flatten())
    }
}

/// The first item of sequence `tag`, if any.
fn first_item(obj: &InMemDicomObject, tag: Tag) -> Option<&InMemDicomObject> {
    obj.element_opt(tag)
        .ok()
        .flatten()
        .and_then(|e| e.items())
        .and_then(|i| i.first())
}

/// Reads the values of one file's elements, naming the file in errors.
struct Values<'p> {
    path: &'p Path,
}

/// The text of an element written with VR UN (unknown; some writers do so for
/// attributes of the standard, whose dictionary VR pydicom then applies): its bytes.
fn un_text(e: &InMemElement) -> Option<String> {
    (e.vr() == dicom_core::VR::UN).then(|| {
        let b = e.to_bytes().unwrap_or_default();
        String::from_utf8_lossy(&b)
            .trim_matches(['\0', ' '])
            .to_string()
    })
}

impl Values<'_> {
    fn bad(&self, what: &str, e: &dyn std::fmt::Display) -> VolumeError {
        header_err(self.path, format!("{what}: {e}"))
    }

    fn missing(&self, what: &str) -> VolumeError {
        header_err(
            self.path,
            format!("missing {what}: a slice of a volume needs it"),
        )
    }

    fn text(&self, e: Option<&InMemElement>, what: &str) -> Result<String, VolumeError> {
        if let Some(t) = e.and_then(un_text) {
            return Ok(t);
        }
        match e {
            Some(e) => Ok(e
                .to_str()
                .map_err(|x| self.bad(what, &x))?
                .trim_end_matches(['\0', ' '])
                .to_string()),
            None => Ok(String::new()),
        }
    }

    fn int(&self, e: Option<&InMemElement>, what: &str) -> Result<Option<i64>, VolumeError> {
        if let Some(t) = e.and_then(un_text) {
            return t.trim().parse().map(Some).map_err(|x| self.bad(what, &x));
        }
        match e {
            Some(e) => e.to_int::<i64>().map(Some).map_err(|x| self.bad(what, &x)),
            _ => Ok(None),
        }
    }

    fn floats(
        &self,
        e: Option<&InMemElement>,
        what: &str,
        n: usize,
    ) -> Result<Option<Vec<f64>>, VolumeError> {
        match e {
            Some(e) => {
                let v = match un_text(e) {
                    Some(t) => t
                        .split('\\')
                        .map(|x| x.trim().parse::<f64>())
                        .collect::<Result<Vec<_>, _>>()
                        .map_err(|x| self.bad(what, &x))?,
                    None => e.to_multi_float64().map_err(|x| self.bad(what, &x))?,
                };
                if v.len() != n || !v.iter().all(|x| x.is_finite()) {
                    return Err(header_err(
                        self.path,
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
    }
}

/// The slices of one file: one per frame (a single-frame file is a frame), each with
/// its own position, orientation, spacing and rescale (the functional groups of an
/// enhanced multi-frame object, or an RT dose's GridFrameOffsetVector).
fn read_frames(path: &Path, transfer_syntax: String) -> Result<Vec<Slice>, VolumeError> {
    let obj = open(path, true)?;
    let top: &InMemDicomObject = &obj;
    let v = Values { path };
    let el = |tag| top.element_opt(tag).ok().flatten();
    let frames = match v.int(el(tags::NUMBER_OF_FRAMES), "NumberOfFrames (0028,0008)")? {
        None => 1,
        Some(n) if (1..=MAX_SLICES as i64).contains(&n) => n as usize,
        Some(n) => {
            return Err(header_err(
                path,
                format!("NumberOfFrames (0028,0008) is {n}, expected 1 to {MAX_SLICES}"),
            ))
        }
    };
    let samples = v
        .int(el(tags::SAMPLES_PER_PIXEL), "SamplesPerPixel")?
        .unwrap_or(1);
    let photometric = v.text(
        el(tags::PHOTOMETRIC_INTERPRETATION),
        "PhotometricInterpretation",
    )?;
    if samples != 1 || !(photometric.is_empty() || photometric.starts_with("MONOCHROME")) {
        return Err(VolumeError::Unsupported {
            path: path.to_path_buf(),
            message: format!("SamplesPerPixel {samples}, PhotometricInterpretation {photometric:?}: volcast renders greyscale (MONOCHROME1/2) slices"),
        });
    }
    let positive = |n: Option<i64>, what: &str| -> Result<usize, VolumeError> {
        match n {
            Some(n) if (1..=65535).contains(&n) => Ok(n as usize),
            Some(n) => Err(header_err(
                path,
                format!("{what} is {n}, expected 1 to 65535"),
            )),
            None => Err(v.missing(what)),
        }
    };
    let rows = positive(
        v.int(el(tags::ROWS), "Rows (0028,0010)")?,
        "Rows (0028,0010)",
    )?;
    let columns = positive(
        v.int(el(tags::COLUMNS), "Columns (0028,0011)")?,
        "Columns (0028,0011)",
    )?;
    let bits_allocated = match v.int(el(tags::BITS_ALLOCATED), "BitsAllocated (0028,0100)")? {
        Some(b @ (8 | 16 | 32)) => b as u16,
        Some(b) => {
            return Err(VolumeError::Unsupported {
                path: path.to_path_buf(),
                message: format!("BitsAllocated (0028,0100) is {b}: volcast reads 8, 16 or 32"),
            })
        }
        None => return Err(v.missing("BitsAllocated (0028,0100)")),
    };
    let bits_stored = match v.int(el(tags::BITS_STORED), "BitsStored (0028,0101)")? {
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
    let high_bit = match v.int(el(tags::HIGH_BIT), "HighBit (0028,0102)")? {
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
    let signed = v.int(
        el(tags::PIXEL_REPRESENTATION),
        "PixelRepresentation (0028,0103)",
    )? == Some(1);
    let lossy = match v
        .text(el(tags::LOSSY_IMAGE_COMPRESSION), "LossyImageCompression")?
        .as_str()
    {
        "" => None,
        flag => {
            let mut s = format!("LossyImageCompression (0028,2110) {flag}");
            let ratio = v.text(
                el(tags::LOSSY_IMAGE_COMPRESSION_RATIO),
                "LossyImageCompressionRatio",
            )?;
            if !ratio.is_empty() {
                s += &format!(", ratio {}", ratio.replace('\\', " "));
            }
            let method = v.text(
                el(tags::LOSSY_IMAGE_COMPRESSION_METHOD),
                "LossyImageCompressionMethod",
            )?;
            if !method.is_empty() {
                s += &format!(", method {}", method.replace('\\', " "));
            }
            Some((flag == "01", s))
        }
    };
    let per_frame = top
        .element_opt(tags::PER_FRAME_FUNCTIONAL_GROUPS_SEQUENCE)
        .ok()
        .flatten()
        .and_then(|e| e.items());
    if let Some(items) = per_frame {
        if items.len() != frames {
            return Err(header_err(
                path,
                format!(
                    "PerFrameFunctionalGroupsSequence (5200,9230) has {} items for NumberOfFrames {frames}",
                    items.len()
                ),
            ));
        }
    }
    let shared = first_item(top, tags::SHARED_FUNCTIONAL_GROUPS_SEQUENCE);
    // an RT dose: the frames' offsets along the normal from ImagePositionPatient
    // read when a frame has no position of its own
    let mut grid: Option<Option<Vec<f64>>> = None;
    let dose_scaling = v.floats(
        el(tags::DOSE_GRID_SCALING),
        "DoseGridScaling (3004,000E)",
        1,
    )?;
    let common = Slice {
        path: path.to_path_buf(),
        frame: 0,
        frames,
        series: v.text(el(tags::SERIES_INSTANCE_UID), "SeriesInstanceUID")?,
        description: v.text(el(tags::SERIES_DESCRIPTION), "SeriesDescription")?,
        modality: v.text(el(tags::MODALITY), "Modality")?,
        transfer_syntax,
        rows,
        columns,
        bits_allocated,
        bits_stored,
        high_bit,
        signed,
        orientation: [0.0; 6],
        position: DVec3::ZERO,
        spacing: [0.0; 2],
        thickness: Ok(None),
        rescale: Rescale::default(),
        lossy,
    };
    let mut out = Vec::with_capacity(frames);
    for f in 0..frames {
        let g = Groups {
            top,
            frame: per_frame.map(|items| &items[f]),
            shared,
        };
        let orientation = v
            .floats(
                g.find(
                    tags::PLANE_ORIENTATION_SEQUENCE,
                    tags::IMAGE_ORIENTATION_PATIENT,
                ),
                "ImageOrientationPatient (0020,0037)",
                6,
            )?
            .ok_or_else(|| v.missing("ImageOrientationPatient (0020,0037)"))?;
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
        let in_frame = per_frame.is_some_and(|items| {
            first_item(&items[f], tags::PLANE_POSITION_SEQUENCE).is_some_and(|p| {
                p.element_opt(tags::IMAGE_POSITION_PATIENT)
                    .ok()
                    .flatten()
                    .is_some()
            })
        });
        let position = v
            .floats(
                g.find(tags::PLANE_POSITION_SEQUENCE, tags::IMAGE_POSITION_PATIENT),
                "ImagePositionPatient (0020,0032)",
                3,
            )?
            .ok_or_else(|| v.missing("ImagePositionPatient (0020,0032)"))?;
        let mut position = DVec3::new(position[0], position[1], position[2]);
        if frames > 1 && !in_frame {
            // the position of each frame: per frame, or the RT dose grid's offsets
            if grid.is_none() {
                grid = Some(v.floats(
                    el(tags::GRID_FRAME_OFFSET_VECTOR),
                    "GridFrameOffsetVector (3004,000C)",
                    frames,
                )?);
            }
            let offsets = match &grid {
                Some(Some(o)) => o,
                _ => {
                    return Err(VolumeError::Unsupported {
                        path: path.to_path_buf(),
                        message: format!("{frames} frames without a position each (PlanePositionSequence (0020,9113) in PerFrameFunctionalGroupsSequence (5200,9230), or GridFrameOffsetVector (3004,000C)): its frames are not slices of a volume (a cine loop, or a multi-frame secondary capture?)"),
                    })
                }
            };
            let normal = x.cross(y).normalize();
            // PS3.3 C.8.8.3.2: relative to ImagePositionPatient when the first offset
            // is 0; otherwise the frames' coordinates along the normal (axial grids)
            let first = offsets[0];
            let along = position.dot(normal);
            let base = if first == 0.0 {
                0.0
            } else if (first - along).abs() <= 1e-3 * along.abs().max(1.0) {
                first
            } else {
                return Err(header_err(
                    path,
                    format!("GridFrameOffsetVector (3004,000C) starts at {first}: neither 0 (offsets from ImagePositionPatient) nor the position's coordinate {} along the normal", short(along)),
                ));
            };
            position += normal * (offsets[f] - base);
        }
        let spacing = v
            .floats(
                g.find(tags::PIXEL_MEASURES_SEQUENCE, tags::PIXEL_SPACING),
                "PixelSpacing (0028,0030)",
                2,
            )?
            .ok_or_else(|| v.missing("PixelSpacing (0028,0030)"))?;
        if !spacing.iter().all(|&s| s > 0.0) {
            return Err(header_err(
                path,
                format!("PixelSpacing (0028,0030) is {spacing:?}, expected two positive numbers"),
            ));
        }
        let transform = tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE;
        let slope = match v.floats(
            g.find(transform, tags::RESCALE_SLOPE),
            "RescaleSlope (0028,1053)",
            1,
        )? {
            Some(s) => s[0],
            // an RT dose's values are DoseGridScaling x stored, in its DoseUnits
            None => dose_scaling.as_ref().map_or(1.0, |d| d[0]),
        };
        let intercept = v
            .floats(
                g.find(transform, tags::RESCALE_INTERCEPT),
                "RescaleIntercept (0028,1052)",
                1,
            )?
            .map_or(0.0, |v| v[0]);
        if slope == 0.0 {
            return Err(header_err(path, "RescaleSlope (0028,1053) is 0".into()));
        }
        // read leniently: only a series of one slice uses it, so a bad value elsewhere
        // must not refuse a readable series
        let thickness = match g.find(tags::PIXEL_MEASURES_SEQUENCE, tags::SLICE_THICKNESS) {
            Some(e) => {
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
        out.push(Slice {
            frame: f,
            orientation: std::array::from_fn(|i| orientation[i]),
            position,
            spacing: [spacing[0], spacing[1]],
            thickness,
            rescale: Rescale { slope, intercept },
            ..common.clone()
        });
    }
    Ok(out)
}

impl DicomSpec {
    /// The DICOM files of the folder (regular files holding `DICM` at byte 128), in
    /// name order, or the one file; every declared length checked.
    fn files(&self) -> Result<Vec<(PathBuf, String)>, VolumeError> {
        let io = |source| VolumeError::Io {
            path: self.dir.clone(),
            source,
        };
        if !self.dir.is_dir() {
            if !std::fs::metadata(&self.dir).is_ok_and(|m| m.is_file()) {
                return Err(invalid(
                    &self.dir,
                    "format = \"dicom\" reads a folder of slices or one DICOM file: no such folder or file".into(),
                ));
            }
            return match scan::scan(&self.dir)? {
                Some(s) if s.sop_class.as_deref() == Some("1.2.840.10008.1.3.10") => Err(invalid(
                    &self.dir,
                    "a DICOMDIR (media storage directory) holds no image: name the folder of its slices".into(),
                )),
                Some(s) => Ok(vec![(self.dir.clone(), s.transfer_syntax)]),
                None => Err(invalid(
                    &self.dir,
                    "not a DICOM file (no `DICM` at byte 128)".into(),
                )),
            };
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

    /// Every file the series is read from (each once, in slice order).
    pub fn input_files(&self) -> Result<Vec<PathBuf>, VolumeError> {
        let mut files: Vec<PathBuf> = Vec::new();
        for s in self.series()?.slices {
            if !files.contains(&s.path) {
                files.push(s.path);
            }
        }
        Ok(files)
    }

    fn series(&self) -> Result<Series, VolumeError> {
        let mut by_series: BTreeMap<String, Vec<Slice>> = BTreeMap::new();
        for (path, ts) in self.files()? {
            if pixels::readable(&ts).is_none() {
                return Err(VolumeError::Unsupported {
                    path,
                    message: format!(
                        "transfer syntax {} is not read: {}. volcast reads {}",
                        syntax_name(&ts),
                        pixels::refusal(&ts),
                        pixels::READABLE.map(|s| s.name).join(", ")
                    ),
                });
            }
            let frames = read_frames(&path, ts)?;
            let total: usize = by_series.values().map(Vec::len).sum();
            if total + frames.len() > MAX_SLICES {
                return Err(invalid(
                    &self.dir,
                    format!("more than {MAX_SLICES} slices (frames)"),
                ));
            }
            for s in frames {
                by_series.entry(s.series.clone()).or_default().push(s);
            }
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
                        "{}its Rows, Columns, BitsAllocated, BitsStored, HighBit, PixelRepresentation, PixelSpacing or ImageOrientationPatient differ from those of {}: the slices of a volume share them",
                        s.frame_note(),
                        first.name()
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
                        "{}two slices at the same position {:?} (also {}){}",
                        w[1].frame_note(),
                        w[0].position.to_array(),
                        w[0].name(),
                        if w[1].frames > 1 {
                            ": several stacks or time points in one multi-frame object are not read as one volume"
                        } else {
                            ""
                        }
                    ),
                });
            }
            if (d - step).length() > 1e-3 * step.length().max(1.0) {
                return Err(VolumeError::Unsupported {
                    path: w[1].path.clone(),
                    message: format!(
                        "{}uneven slice spacing: {:.4} from the previous slice ({}), {:.4} on average: missing or extra slices?",
                        w[1].frame_note(),
                        d.length(),
                        w[0].name(),
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
        // the files (each once, in slice order) and their transfer syntaxes
        let mut files: Vec<&Slice> = Vec::new();
        for x in &s.slices {
            if !files.iter().any(|f| f.path == x.path) {
                files.push(x);
            }
        }
        let mut syntaxes: Vec<&str> = Vec::new();
        for f in &files {
            if !syntaxes.contains(&f.transfer_syntax.as_str()) {
                syntaxes.push(&f.transfer_syntax);
            }
        }
        let multi_frame = files.iter().filter(|f| f.frames > 1).count();
        let format = if self.dir.is_dir() {
            "DICOM series"
        } else {
            "DICOM file"
        };
        let mut fields = vec![
            ("format".to_string(), format.to_string()),
            (
                "space".to_string(),
                "LPS (DICOM patient coordinates, kept as they are)".to_string(),
            ),
            ("series".to_string(), first.series.clone()),
            ("slices".to_string(), s.slices.len().to_string()),
            (
                "transfer syntax".to_string(),
                syntaxes
                    .iter()
                    .map(|t| syntax_name(t))
                    .collect::<Vec<_>>()
                    .join(", "),
            ),
        ];
        if multi_frame > 0 {
            fields.push((
                "frames".into(),
                if files.len() == 1 {
                    format!("{} in one multi-frame file", first.frames)
                } else {
                    format!("{} files, {multi_frame} of them multi-frame", files.len())
                },
            ));
        }
        // lossy: the syntax (JPEG baseline, JPEG 2000 that may be lossy), or the
        // data set's own LossyImageCompression (an image once compressed lossily)
        let lossy_syntaxes: Vec<&str> = syntaxes
            .iter()
            .filter_map(|t| pixels::readable(t).filter(|r| r.lossy).map(|r| r.name))
            .collect();
        let mut flags: Vec<&str> = Vec::new();
        for f in &files {
            if let Some((_, text)) = &f.lossy {
                if !flags.contains(&text.as_str()) {
                    flags.push(text);
                }
            }
        }
        let lossy_flag = files.iter().any(|f| f.lossy.as_ref().is_some_and(|l| l.0));
        let mut why = Vec::new();
        for name in &lossy_syntaxes {
            why.push(if name.starts_with("JPEG 2000") {
                format!("transfer syntax {name} (lossless or lossy compression)")
            } else {
                format!("transfer syntax {name} (lossy compression)")
            });
        }
        why.extend(flags.iter().map(|f| f.to_string()));
        let lossy = if lossy_flag || lossy_syntaxes.iter().any(|n| !n.starts_with("JPEG 2000")) {
            "yes"
        } else if !lossy_syntaxes.is_empty() {
            // JPEG 2000 Image Compression is lossless or lossy: the codestream's
            // wavelet says which, LossyImageCompression too when it is set
            "may be"
        } else {
            "no"
        };
        fields.push((
            "lossy".into(),
            if why.is_empty() {
                lossy.to_string()
            } else {
                format!("{lossy}: {}", why.join("; "))
            },
        ));
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
        // each file is opened once and kept while frames of it are still to come
        let mut last_use: BTreeMap<&Path, usize> = BTreeMap::new();
        for (i, s) in series.slices.iter().enumerate() {
            last_use.insert(&s.path, i);
        }
        // with its native pixel data as bytes, made once (not once per frame)
        let mut open_files: BTreeMap<&Path, (DefaultDicomObject, Option<Vec<u8>>)> =
            BTreeMap::new();
        for (i, s) in series.slices.iter().enumerate() {
            if !open_files.contains_key(s.path.as_path()) {
                open_files.insert(&s.path, (open(&s.path, false)?, None));
            }
            let Some((obj, native)) = open_files.get_mut(s.path.as_path()) else {
                unreachable!("opened above");
            };
            let bytes = frame_cells(obj, native, s)?;
            if last_use[s.path.as_path()] == i {
                open_files.remove(s.path.as_path());
            }
            let need = per_slice * stored.size();
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

/// The cells of slice `s` (a frame of its file `obj`), little-endian: cut from native
/// pixel data (its bytes kept in `native` for the file's other frames), or decoded
/// from the frame's fragments.
fn frame_cells(
    obj: &DefaultDicomObject,
    native: &mut Option<Vec<u8>>,
    s: &Slice,
) -> Result<Vec<u8>, VolumeError> {
    let data_err = |message: String| VolumeError::Data {
        path: s.path.clone(),
        message: format!("{}{message}", s.frame_note()),
    };
    let pixels = obj
        .element(tags::PIXEL_DATA)
        .map_err(|_| header_err(&s.path, "no PixelData (7FE0,0010)".into()))?;
    let layout = pixels::Layout {
        rows: s.rows,
        columns: s.columns,
        bits_allocated: s.bits_allocated,
        bits_stored: s.bits_stored,
    };
    let need = layout.frame_bytes();
    let syntax = pixels::readable(&s.transfer_syntax)
        .ok_or_else(|| data_err(format!("transfer syntax {} is not read", s.transfer_syntax)))?;
    if let (
        Some(fragments),
        pixels::Coding::Rle | pixels::Coding::Jpeg | pixels::Coding::Jpeg2000,
    ) = (pixels.fragments(), syntax.coding)
    {
        let table = pixels.offset_table().unwrap_or_default();
        let data = pixels::frame_fragments(fragments, table, s.frames, s.frame, syntax.coding)
            .map_err(|e| data_err(format!("PixelData (7FE0,0010): {e}")))?;
        return pixels::decode(syntax.uid, syntax.coding, &data, &layout)
            .map_err(|e| data_err(format!("PixelData (7FE0,0010), {}: {e}", syntax.name)));
    }
    if pixels.fragments().is_some() || syntax.coding != pixels::Coding::Native {
        return Err(data_err(format!(
            "PixelData (7FE0,0010) is {} in a file of transfer syntax {}",
            if pixels.fragments().is_some() {
                "encapsulated"
            } else {
                "native"
            },
            syntax.name
        )));
    }
    // the value's own bytes when it holds bytes (as the crate reads pixel data);
    // a conversion is made once and kept for the file's other frames
    let borrowed;
    let bytes: &[u8] = match native {
        Some(b) => b,
        None => match pixels
            .to_bytes()
            .map_err(|e| data_err(format!("PixelData (7FE0,0010): {e}")))?
        {
            std::borrow::Cow::Borrowed(b) => {
                borrowed = b;
                borrowed
            }
            std::borrow::Cow::Owned(v) => native.insert(v),
        },
    };
    let total = need * s.frames;
    if bytes.len() < total || bytes.len() > total + 1 {
        return Err(VolumeError::Data {
            path: s.path.clone(),
            message: format!(
                "PixelData (7FE0,0010) has {} bytes, but Columns x Rows x BitsAllocated/8{} = {} x {} x {}{} = {total}",
                bytes.len(),
                if s.frames > 1 { " x NumberOfFrames" } else { "" },
                s.columns,
                s.rows,
                s.bits_allocated / 8,
                if s.frames > 1 { format!(" x {}", s.frames) } else { String::new() },
            ),
        });
    }
    Ok(bytes[need * s.frame..need * (s.frame + 1)].to_vec())
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
            frame: 0,
            frames: 1,
            lossy: None,
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
