//! Volumes: where the voxels come from, what type they are, where they sit.
//!
//! ```text
//! VolumeSource --header()--> VolumeHeader (sizes, type, geometry: no voxel memory yet)
//!              --load()----> Volume        (data in its native type, limits checked first)
//! ```
//! Sources are NRRD files (attached or detached header, [`nrrd`]), NIfTI-1 and NIfTI-2 files
//! ([`nifti`]), MetaImage files ([`metaimage`]), DICOM series ([`dicom`]), headerless
//! raw files ([`raw`]) and analytic fields sampled on a grid ([`synthetic`]). Each file
//! keeps its own world coordinates; a stored-to-physical map (NIfTI `scl_slope`, DICOM
//! rescale) is kept beside the voxels as a [`Rescale`], never applied to them. Raw data
//! in the machine's byte order, in one file, is memory-mapped rather than read
//! ([`mapped`]); [`VolumeSource::storage`] tells which before loading. Nothing in this
//! module knows about cameras or render modes.

pub mod confine;
pub mod dicom;
mod errors;
pub mod geometry;
pub mod info;
pub mod limits;
pub mod mapped;
pub mod metaimage;
pub mod nifti;
pub mod nrrd;
pub mod raw;
pub mod rescale;
pub mod scalar;
pub mod shared;
pub mod stats;
mod stream;
pub mod synthetic;
pub mod tiff;

use std::path::{Path, PathBuf};

pub use geometry::Geometry;
pub use limits::Limits;
pub use mapped::{MappedVoxels, ReadReason, Storage};
pub use rescale::Rescale;
pub use scalar::{ScalarType, TypedVoxels, VolumeData, Voxel, Voxels};
pub use shared::{SharedVoxels, VoxelBytes};
pub use stats::Stats;
pub use synthetic::Synthetic;

/// Errors from reading or describing a volume, sorted by who is at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VolumeError {
    /// The file system refused (missing file, permissions, ...). The OS message is
    /// the error's `source()`, printed after the path by error-chain printers.
    #[error("{}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// A header line is malformed or inconsistent (`line` is 1-based; 0 = not tied to a line).
    #[error("{}{}: {message}", path.display(), line_suffix(*line))]
    Header {
        /// The header file.
        path: PathBuf,
        /// 1-based line number, or 0 when the problem concerns the header as a whole.
        line: usize,
        /// What is wrong and what was expected.
        message: String,
    },
    /// The voxel data does not match its description (too short, too long, unparseable).
    #[error("{}: {message}", path.display())]
    Data {
        /// The data file.
        path: PathBuf,
        /// What is wrong and what was expected.
        message: String,
    },
    /// A feature of the format this reader does not implement.
    #[error("{}: {message}", path.display())]
    Unsupported {
        /// The file concerned.
        path: PathBuf,
        /// What is not supported.
        message: String,
    },
    /// The volume would need more memory than allowed.
    #[error("{what} needs {} but the limit is {} (set --max-memory to raise it)",
        bytes.map(human_bytes).unwrap_or_else(|| "more bytes than this machine can address".into()),
        human_bytes(*limit))]
    TooLarge {
        /// What was being sized.
        what: String,
        /// Bytes needed, when that number fits in a u64.
        bytes: Option<u64>,
        /// The limit in force.
        limit: u64,
    },
    /// Memory the limit allowed could not be allocated (the machine has less free
    /// than `--max-memory` assumed).
    #[error("{}: out of memory: allocating {} for the voxels failed (the machine has less memory free than --max-memory allows: lower it, or free memory)", path.display(), human_bytes(*bytes))]
    OutOfMemory {
        /// The file being read.
        path: PathBuf,
        /// Bytes of the allocation that failed.
        bytes: u64,
    },
    /// A file outside the folder the run is confined to (`--confine`).
    #[error("{}: {what} is outside {} (--confine): it resolves to {}", path.display(), root.display(), real.display())]
    Outside {
        /// The path as named (in the scene or a header).
        path: PathBuf,
        /// What it is ("the volume", "a data file named by x.nhdr", "the output folder").
        what: String,
        /// Where it resolves to.
        real: PathBuf,
        /// The folder the run is confined to.
        root: PathBuf,
    },
    /// Parameters of a raw or synthetic source that make no sense.
    #[error("{0}")]
    Invalid(String),
}

/// The crate's errors carry the same messages; only the limit's hints name volcast's
/// flags.
impl From<::nrrd::Error> for VolumeError {
    fn from(e: ::nrrd::Error) -> VolumeError {
        use ::nrrd::Error as E;
        match e {
            E::Io { path, source } => VolumeError::Io { path, source },
            E::Header {
                path,
                line,
                message,
            } => VolumeError::Header {
                path,
                line,
                message,
            },
            E::Data { path, message } => VolumeError::Data { path, message },
            E::Unsupported { path, message } => VolumeError::Unsupported { path, message },
            E::TooLarge { what, bytes, limit } => VolumeError::TooLarge { what, bytes, limit },
            E::OutOfMemory { path, bytes } => VolumeError::OutOfMemory { path, bytes },
            E::Invalid(message) => VolumeError::Invalid(message),
            // the crate's enum is non-exhaustive: a future variant keeps its message
            other => VolumeError::Invalid(other.to_string()),
        }
    }
}

fn line_suffix(line: usize) -> String {
    if line == 0 {
        String::new()
    } else {
        format!(":{line}")
    }
}

/// Bytes as a short human string (`3.1 MiB`).
pub fn human_bytes(b: u64) -> String {
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else {
        format!("{v:.1} {}", UNITS[u])
    }
}

/// Where a volume comes from, fully resolved (paths absolute).
#[derive(Clone, Debug, PartialEq)]
pub enum VolumeSource {
    /// A `.nrrd` or `.nhdr` file.
    Nrrd(PathBuf),
    /// A NIfTI-1 or NIfTI-2 file (`.nii`, `.nii.gz`) and the volume of it to render.
    Nifti(nifti::NiftiSpec),
    /// A MetaImage file (`.mha`, or a `.mhd` header and its data file).
    MetaImage(PathBuf),
    /// A folder of DICOM slices (`format = "dicom"`) and the series to render.
    Dicom(dicom::DicomSpec),
    /// A TIFF stack: a multi-page file, or a folder or glob of single-page files
    /// (`format = "tiff"`), and the channel to render.
    Tiff(tiff::TiffSpec),
    /// A headerless file described by the scene.
    Raw(raw::RawSpec),
    /// An analytic field sampled on a grid spanning [-1, 1]^3.
    Synthetic(Synthetic),
    /// A volume already in memory (a NumPy array given to the Python module, its
    /// voxels [`VolumeData::Shared`]): loading it shares the voxels, never copies them.
    Memory(std::sync::Arc<Volume>),
}

/// What is known about a volume before its voxels are read.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeHeader {
    /// Voxels along x, y, z (x fastest in memory).
    pub sizes: [usize; 3],
    /// Element type in memory.
    pub scalar_type: ScalarType,
    /// Index-to-world map.
    pub geometry: Geometry,
    /// Human-readable origin ("path/to/file.nrrd", "synthetic gaussian").
    pub source: String,
    /// Descriptive fields worth showing (`content`, `key:=value` pairs, units, ...).
    pub fields: Vec<(String, String)>,
    /// What the stored values stand for (NIfTI `scl_slope`/`scl_inter`); folded into
    /// the value window, never applied to the voxels.
    pub rescale: Rescale,
}

impl VolumeHeader {
    /// Number of voxels (saturating: a hostile header's product does not overflow;
    /// [`Limits::check`] rejects it before anything is allocated).
    pub fn voxel_count(&self) -> usize {
        self.sizes.iter().fold(1usize, |a, &n| a.saturating_mul(n))
    }

    /// Bytes the voxels occupy in memory (saturating).
    pub fn data_bytes(&self) -> u64 {
        (self.voxel_count() as u64).saturating_mul(self.scalar_type.size() as u64)
    }
}

/// A loaded volume: header plus native-typed voxels, x fastest (in memory or mapped
/// from a file).
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    /// Sizes, type and geometry.
    pub header: VolumeHeader,
    /// The voxels.
    pub data: VolumeData,
}

impl Volume {
    /// Value at integer index (no bounds clamping), as `f64`.
    pub fn value(&self, i: usize, j: usize, k: usize) -> f64 {
        let [nx, ny, _] = self.header.sizes;
        self.data.get_f64(i + nx * (j + ny * k))
    }
}

/// The file formats a volume path can name, told by its extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileFormat {
    /// `.nrrd`, `.nhdr`
    Nrrd,
    /// `.nii`, `.nii.gz`
    Nifti,
    /// `.mha`, `.mhd`
    MetaImage,
    /// `.tif`, `.tiff` (and `.ome.tif`)
    Tiff,
    /// `.dcm`, `.dicom`: one DICOM file (a multi-frame object, or a single slice)
    Dicom,
}

impl FileFormat {
    /// The format a file name's extension names (case-insensitive), if any.
    pub fn from_path(path: &Path) -> Option<FileFormat> {
        let name = path.file_name()?.to_string_lossy().to_ascii_lowercase();
        let ext = |e: &str| name.ends_with(e);
        if ext(".nrrd") || ext(".nhdr") {
            Some(FileFormat::Nrrd)
        } else if ext(".nii") || ext(".nii.gz") {
            Some(FileFormat::Nifti)
        } else if ext(".mha") || ext(".mhd") {
            Some(FileFormat::MetaImage)
        } else if ext(".tif") || ext(".tiff") {
            Some(FileFormat::Tiff)
        } else if ext(".dcm") || ext(".dicom") {
            Some(FileFormat::Dicom)
        } else {
            None
        }
    }
}

impl VolumeSource {
    /// The source of a volume file named on the command line (`volcast info`): its
    /// format from the extension (NRRD when unknown); the first volume of a 4D NIfTI;
    /// the first channel and frame of a multi-channel TIFF time series; a folder is a DICOM series, unless it
    /// holds TIFF files (then a TIFF series, as is a glob of them, `slices/*.tif`).
    pub fn from_path(path: &Path) -> Result<VolumeSource, VolumeError> {
        let tiff = |path: &Path| {
            VolumeSource::Tiff(tiff::TiffSpec {
                path: path.to_path_buf(),
                // channel 0 of 1 is every page: a single-channel file reads the same
                channel: Some(0),
                index: Some(0),
            })
        };
        let tiff_glob =
            tiff::is_glob(path) && FileFormat::from_path(path) == Some(FileFormat::Tiff);
        if tiff_glob || (path.is_dir() && tiff::holds_tiffs(path)) {
            return Ok(tiff(path));
        }
        // a folder of slices, or one DICOM file (by its extension, or `DICM` at byte
        // 128 of a file of no other known format)
        let dicom_file = || {
            FileFormat::from_path(path).is_none_or(|f| f == FileFormat::Dicom)
                && dicom::is_dicom_file(path)
        };
        if path.is_dir() || dicom_file() {
            return Ok(VolumeSource::Dicom(dicom::DicomSpec {
                dir: path.to_path_buf(),
                series: None,
            }));
        }
        Ok(match FileFormat::from_path(path) {
            Some(FileFormat::Nifti) => {
                let (h, _) = nifti::read_header(path)?;
                VolumeSource::Nifti(nifti::NiftiSpec {
                    path: path.to_path_buf(),
                    index: (h.volumes() > 1).then_some(0),
                })
            }
            Some(FileFormat::MetaImage) => VolumeSource::MetaImage(path.to_path_buf()),
            Some(FileFormat::Tiff) => tiff(path),
            // not a DICOM file: the reader says why
            Some(FileFormat::Dicom) => VolumeSource::Dicom(dicom::DicomSpec {
                dir: path.to_path_buf(),
                series: None,
            }),
            Some(FileFormat::Nrrd) | None => VolumeSource::Nrrd(path.to_path_buf()),
        })
    }

    /// Reads only what describes the volume: sizes, type, geometry.
    pub fn header(&self) -> Result<VolumeHeader, VolumeError> {
        match self {
            VolumeSource::Nrrd(path) => nrrd::volume_header(&nrrd::read_header(path)?, path),
            VolumeSource::Nifti(spec) => spec.header(),
            VolumeSource::MetaImage(path) => metaimage::MetaSpec { path }.header(),
            VolumeSource::Dicom(spec) => spec.header(),
            VolumeSource::Tiff(spec) => spec.header(),
            VolumeSource::Raw(spec) => spec.header(),
            VolumeSource::Synthetic(s) => Ok(s.header()),
            VolumeSource::Memory(v) => Ok(v.header.clone()),
        }
    }

    /// Loads the voxels: maps them when [`VolumeSource::storage`] says
    /// [`Storage::Mapped`], otherwise reads them, checking `limits` before allocating
    /// (mapped data does not count against `limits`).
    pub fn load(&self, limits: &Limits) -> Result<Volume, VolumeError> {
        match self {
            VolumeSource::Nrrd(path) => load_nrrd(path, limits),
            VolumeSource::Nifti(spec) => spec.load(limits),
            VolumeSource::MetaImage(path) => metaimage::MetaSpec { path }
                .load_hashed(limits, false)
                .map(|(v, _)| v),
            VolumeSource::Dicom(spec) => spec.load_hashed(limits, false).map(|(v, _)| v),
            VolumeSource::Tiff(spec) => spec.load_hashed(limits, false).map(|(v, _)| v),
            VolumeSource::Raw(spec) => spec.load(limits),
            VolumeSource::Synthetic(s) => s.load(limits),
            VolumeSource::Memory(v) => Ok(v.as_ref().clone()),
        }
    }

    /// Whether [`VolumeSource::load`] will map the voxels from a file or read them into
    /// memory, and how many bytes, without loading them. Reads the NRRD header again
    /// (the [`VolumeHeader`] does not keep the encoding and the data file), and for
    /// mapped data opens the data file to find where the data starts (`line skip`,
    /// `byte skip`) and to check its type and length, giving the errors the load would.
    pub fn storage(&self) -> Result<Storage, VolumeError> {
        match self {
            VolumeSource::Nrrd(path) => nrrd::storage(path),
            VolumeSource::Nifti(spec) => spec.storage(),
            VolumeSource::MetaImage(path) => metaimage::MetaSpec { path }.storage(),
            VolumeSource::Dicom(spec) => spec.storage(),
            VolumeSource::Tiff(spec) => spec.storage(),
            VolumeSource::Raw(spec) => spec.storage(),
            VolumeSource::Synthetic(s) => Ok(Storage::Read {
                bytes: s.header().data_bytes(),
                reason: ReadReason::Synthetic,
            }),
            VolumeSource::Memory(v) => Ok(Storage::Read {
                bytes: v.header.data_bytes(),
                reason: ReadReason::Memory,
            }),
        }
    }

    /// Every file a load reads (a NRRD header and each of its data files, or the raw
    /// file; none for a synthetic field), stamped now (size and modification time;
    /// reads only the NRRD header).
    pub fn stamps(&self) -> Result<Vec<FileStamp>, VolumeError> {
        let files = self.input_files()?;
        files.iter().map(|p| FileStamp::of(p)).collect()
    }

    /// Every file a load reads: a NRRD or MetaImage header first, then its data
    /// files; the NIfTI or raw file; each slice of a DICOM series; the TIFF file, or
    /// each file of a TIFF folder or glob; none for a
    /// synthetic field. Reads only the headers.
    pub fn input_files(&self) -> Result<Vec<PathBuf>, VolumeError> {
        Ok(match self {
            VolumeSource::Nrrd(path) => nrrd::input_files(path)?,
            VolumeSource::Nifti(spec) => vec![spec.path.clone()],
            VolumeSource::MetaImage(path) => metaimage::input_files(path)?,
            VolumeSource::Dicom(spec) => spec.input_files()?,
            VolumeSource::Tiff(spec) => spec.input_files()?,
            VolumeSource::Raw(spec) => vec![spec.path.clone()],
            VolumeSource::Synthetic(_) | VolumeSource::Memory(_) => Vec::new(),
        })
    }

    /// [`VolumeSource::load`], also returning the volume's identity: the files, stamped
    /// before they are read, and the XXH3-128 of the data, computed while it is
    /// decoded (no extra pass; mapped data is hashed over its mapping, which reads
    /// every page of the file once).
    pub fn load_identified(
        &self,
        limits: &Limits,
    ) -> Result<(Volume, VolumeIdentity), VolumeError> {
        let files = self.stamps()?;
        let (volume, hash) = match self {
            VolumeSource::Nrrd(path) => {
                let (header, data, hash) = nrrd::read_hashed(path, limits)?;
                let vh = nrrd::volume_header(&header, path)?;
                (Volume { header: vh, data }, Some(hash))
            }
            VolumeSource::Nifti(spec) => spec.load_hashed(limits, true)?,
            VolumeSource::MetaImage(path) => {
                metaimage::MetaSpec { path }.load_hashed(limits, true)?
            }
            VolumeSource::Dicom(spec) => spec.load_hashed(limits, true)?,
            VolumeSource::Tiff(spec) => spec.load_hashed(limits, true)?,
            VolumeSource::Raw(spec) => spec.load_hashed(limits, true)?,
            VolumeSource::Synthetic(s) => (s.load(limits)?, None),
            VolumeSource::Memory(v) => {
                let hash =
                    crate::with_voxels!(&v.data, x => xxhash_rust::xxh3::xxh3_128(x.as_bytes()));
                (v.as_ref().clone(), Some(hash))
            }
        };
        Ok((
            volume,
            VolumeIdentity {
                data_xxh3: hash.map(|h| format!("{h:032x}")),
                files,
            },
        ))
    }

    /// True for a synthetic field (no files; its scene defines its voxels).
    pub fn is_synthetic(&self) -> bool {
        matches!(self, VolumeSource::Synthetic(_))
    }

    /// A file path this source reads, if any.
    pub fn path(&self) -> Option<&Path> {
        match self {
            VolumeSource::Nrrd(p) => Some(p),
            VolumeSource::Nifti(n) => Some(&n.path),
            VolumeSource::MetaImage(p) => Some(p),
            VolumeSource::Dicom(d) => Some(&d.dir),
            VolumeSource::Tiff(t) => Some(&t.path),
            VolumeSource::Raw(r) => Some(&r.path),
            VolumeSource::Synthetic(_) | VolumeSource::Memory(_) => None,
        }
    }
}

/// A file a volume is read from, as it was when read: enough to tell cheaply
/// whether it changed since (same size and modification time).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct FileStamp {
    /// The file.
    pub path: PathBuf,
    /// Its length in bytes.
    pub bytes: u64,
    /// Its modification time, as `seconds.nanoseconds` since the Unix epoch.
    pub modified: String,
}

impl FileStamp {
    /// The stamp of `path` now.
    pub fn of(path: &Path) -> Result<FileStamp, VolumeError> {
        let meta = std::fs::metadata(path).map_err(|source| VolumeError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let modified = meta
            .modified()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or_else(
                || "unknown".to_string(),
                |d| format!("{}.{:09}", d.as_secs(), d.subsec_nanos()),
            );
        Ok(FileStamp {
            path: path.to_path_buf(),
            bytes: meta.len(),
            modified,
        })
    }
}

/// What the voxels of a loaded volume are: a hash of their bytes as stored (in file
/// order, after decompression), computed while they are decoded, and the files they
/// came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VolumeIdentity {
    /// XXH3-128 of the data, as 32 hex digits (`None` for a synthetic field, which
    /// its scene defines).
    pub data_xxh3: Option<String>,
    /// The files read, stamped before they were read.
    pub files: Vec<FileStamp>,
}

/// Reads a NRRD file as a 3D volume.
pub fn load_nrrd(path: &Path, limits: &Limits) -> Result<Volume, VolumeError> {
    let (header, data) = nrrd::read(path, limits)?;
    let vh = nrrd::volume_header(&header, path)?;
    debug_assert_eq!(vh.voxel_count(), data.len());
    Ok(Volume { header: vh, data })
}
