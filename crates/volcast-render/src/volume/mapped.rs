//! Memory-mapped voxels: raw data in the machine's byte order is used in place, from
//! the operating system's page cache, instead of being read into a buffer.
//!
//! # What is mapped
//!
//! A single file's raw bytes in native byte order: headerless raw files and NRRD
//! `encoding: raw` data (attached, or one detached `data file`) whose `endian` is the
//! machine's (little-endian on x86-64 and aarch64), or whose elements are single bytes.
//! Everything else is read and decoded into memory as before: the other byte order
//! (swapped while reading), gzip and bzip2, ascii and hex, and `data file` patterns and
//! lists (several files). [`Storage`] tells which, before loading.
//!
//! The data may start at any byte of the file (after an attached header, a raw
//! `offset`, NRRD `line skip` and `byte skip`, or `byte skip: -1`): the mapping covers
//! exactly the data's bytes, which therefore sit at any alignment; [`Voxels`](super::Voxels) reads
//! them with unaligned loads.
//!
//! Mapped bytes are not memory volcast allocates: they are file pages that the kernel
//! loads on first touch and may drop and reload at will. [`Limits`](super::Limits)
//! (`--max-memory`) therefore does not apply to them.
//!
//! # Soundness
//!
//! The mapping itself is made by [`nrrd::file::map`], whose documentation says what
//! makes it sound and where that stops (a file truncated while mapped).
//!
//! # Confinement
//!
//! This is also the one place volume files are opened: while a
//! [`confine::Scope`](super::confine::Scope) is active on a thread, every file opened
//! here (and by the NRRD reader, through its open check) must lie in its folder.

use std::cell::RefCell;
use std::fmt;
use std::fs::{File, Metadata};
use std::io;
use std::path::{Path, PathBuf};

pub use nrrd::file::{file_kind, is_native_order, open_nonblocking};
use nrrd::Encoding;
pub use nrrd::Mapped as MappedVoxels;

use super::{ScalarType, VolumeError};

/// How [`VolumeSource::load`](super::VolumeSource::load) will hold a volume's voxels,
/// known from the source and its header before loading (see
/// [`VolumeSource::storage`](super::VolumeSource::storage)).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Storage {
    /// Mapped read-only from `path`: `bytes` bytes starting at byte `offset` of the
    /// file. Costs address space and page cache, not allocated memory; not counted
    /// against [`Limits`](super::Limits).
    Mapped {
        /// The file that holds the data (the data file of a detached NRRD header).
        path: PathBuf,
        /// Where the data starts in that file, after every header and skip.
        offset: u64,
        /// Bytes mapped (voxels × type size).
        bytes: u64,
    },
    /// Read (decoded, decompressed, byte-swapped or computed) into `bytes` bytes that
    /// volcast allocates; counted against [`Limits`](super::Limits).
    Read {
        /// Bytes allocated for the voxels (voxels × type size).
        bytes: u64,
        /// Why the voxels cannot be mapped.
        reason: ReadReason,
    },
}

impl Storage {
    /// The storage of `bytes` uncompressed bytes of `ty` at `offset` of `path`, stored
    /// in the given byte order: mapped in the machine's byte order, else read (and
    /// byte-swapped).
    pub(crate) fn uncompressed(
        ty: ScalarType,
        little_endian: bool,
        path: &Path,
        offset: u64,
        bytes: u64,
    ) -> Storage {
        if is_native_order(ty, little_endian) {
            Storage::Mapped {
                path: path.to_path_buf(),
                offset,
                bytes,
            }
        } else {
            Storage::Read {
                bytes,
                reason: ReadReason::ByteOrder,
            }
        }
    }

    /// Bytes of voxel memory volcast allocates (0 when mapped).
    pub fn allocated_bytes(&self) -> u64 {
        match self {
            Storage::Mapped { .. } => 0,
            Storage::Read { bytes, .. } => *bytes,
        }
    }

    /// Bytes of the data file mapped (0 when read).
    pub fn mapped_bytes(&self) -> u64 {
        match self {
            Storage::Mapped { bytes, .. } => *bytes,
            Storage::Read { .. } => 0,
        }
    }

    /// True for [`Storage::Mapped`].
    pub fn is_mapped(&self) -> bool {
        matches!(self, Storage::Mapped { .. })
    }
}

/// Why a volume is read into memory rather than mapped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadReason {
    /// A synthetic field is computed, there is no file.
    Synthetic,
    /// Multi-byte elements in the other byte order: swapped while reading.
    ByteOrder,
    /// An encoding other than raw (gzip, bzip2, ascii, hex): decoded while reading.
    Encoding(Encoding),
    /// The data is split over this many files (`data file` pattern or `LIST`).
    DataFiles(u64),
    /// A compressed file or data section (what it is, for the message:
    /// "a gzip-compressed file (.nii.gz)", "zlib-compressed data").
    Compressed(&'static str),
    /// The voxels are a caller's buffer in memory ([`VolumeSource::Memory`](super::VolumeSource::Memory)),
    /// used in place.
    Memory,
}

impl fmt::Display for ReadReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReadReason::Synthetic => f.write_str("a synthetic field"),
            ReadReason::ByteOrder => f.write_str(if cfg!(target_endian = "little") {
                "big-endian data, byte-swapped on this little-endian machine"
            } else {
                "little-endian data, byte-swapped on this big-endian machine"
            }),
            ReadReason::Encoding(e) => write!(f, "{} encoding", e.name()),
            ReadReason::DataFiles(n) => write!(f, "data split over {n} files"),
            ReadReason::Compressed(what) => f.write_str(what),
            ReadReason::Memory => f.write_str("an array in memory, used in place"),
        }
    }
}

/// Opens a volume file (header or data) for reading without blocking; inside a
/// [`confine::Scope`](super::confine::Scope), the opened file must lie in its folder.
pub(crate) fn open_for_mapping(path: &Path) -> io::Result<File> {
    let file = nrrd::file::open_nonblocking(path)?;
    check_opened(path, &file)?;
    Ok(file)
}

/// Opens `path` for reading without blocking and checks, on the opened file, that it
/// is a regular file (a FIFO, device, socket or directory is refused with a message
/// naming it; there is no window between the check and the open). `what` names the
/// file's role in the message ("a NRRD header", "volume data").
pub(crate) fn open_regular(path: &Path, what: &str) -> Result<(File, Metadata), VolumeError> {
    let io_err = |source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = open_for_mapping(path).map_err(io_err)?;
    let meta = file.metadata().map_err(io_err)?;
    check_regular(path, &meta, what)?;
    Ok((file, meta))
}

/// An error unless `meta` (of `path`) describes a regular file.
pub(crate) fn check_regular_file(path: &Path, meta: &Metadata) -> Result<(), VolumeError> {
    check_regular(path, meta, "volume data")
}

/// An error unless `meta` (of `path`, holding `what`) describes a regular file.
fn check_regular(path: &Path, meta: &Metadata, what: &str) -> Result<(), VolumeError> {
    Ok(nrrd::file::check_regular(path, meta, what)?)
}

/// Maps `bytes` bytes of `file` (at `path`) from byte `offset` as elements of `ty`.
///
/// `file` must be a regular file opened for reading whose length was checked to hold
/// `offset + bytes`; the length is checked once more here, on the open file.
pub(crate) fn map(
    file: &File,
    path: &Path,
    ty: ScalarType,
    offset: u64,
    bytes: u64,
) -> Result<MappedVoxels, VolumeError> {
    Ok(nrrd::file::map(file, path, ty, offset, bytes)?)
}

thread_local! {
    /// The folder this thread's volume reads are confined to, while a scope is active.
    static ROOT: RefCell<Option<PathBuf>> = const { RefCell::new(None) };
}

/// Confines this thread's volume reads to the resolved folder `root` (or ends that,
/// with `None`); returns the previous setting.
pub(crate) fn set_confinement(root: Option<PathBuf>) -> Option<PathBuf> {
    ROOT.with(|r| r.replace(root))
}

/// Checks a volume file just opened from `path` against this thread's confinement,
/// if any: the path of the open file itself must lie in the root.
pub(crate) fn check_opened(path: &Path, file: &File) -> io::Result<()> {
    let Some(root) = ROOT.with(|r| r.borrow().clone()) else {
        return Ok(());
    };
    let real = opened_path(file).or_else(|| path.canonicalize().ok());
    match real {
        Some(real) if real.starts_with(&root) => Ok(()),
        Some(real) => Err(io::Error::new(
            io::ErrorKind::PermissionDenied,
            format!(
                "resolves to {}, outside {} (--confine)",
                real.display(),
                root.display()
            ),
        )),
        None => Err(io::Error::new(
            io::ErrorKind::PermissionDenied,
            format!(
                "cannot tell where it lies, so it is not read (--confine {})",
                root.display()
            ),
        )),
    }
}

/// The path the kernel reports for an open file (Linux).
fn opened_path(file: &File) -> Option<PathBuf> {
    #[cfg(unix)]
    {
        use std::os::fd::AsRawFd;
        std::fs::read_link(format!("/proc/self/fd/{}", file.as_raw_fd())).ok()
    }
    #[cfg(not(unix))]
    {
        let _ = file;
        None
    }
}

impl From<nrrd::ReadReason> for ReadReason {
    fn from(r: nrrd::ReadReason) -> ReadReason {
        match r {
            nrrd::ReadReason::ByteOrder => ReadReason::ByteOrder,
            nrrd::ReadReason::Encoding(e) => ReadReason::Encoding(e),
            nrrd::ReadReason::DataFiles(n) => ReadReason::DataFiles(n),
        }
    }
}

impl From<nrrd::Storage> for Storage {
    fn from(s: nrrd::Storage) -> Storage {
        match s {
            nrrd::Storage::Mapped {
                path,
                offset,
                bytes,
            } => Storage::Mapped {
                path,
                offset,
                bytes,
            },
            nrrd::Storage::Read { bytes, reason } => Storage::Read {
                bytes,
                reason: reason.into(),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_special_files() {
        let dir = tempfile::tempdir().unwrap();
        let f = open_for_mapping(dir.path()).unwrap();
        let e = map(&f, dir.path(), ScalarType::Uint8, 0, 1).unwrap_err();
        assert!(e.to_string().contains("is a directory"), "{e}");
        #[cfg(unix)]
        {
            let null = Path::new("/dev/null");
            let f = open_for_mapping(null).unwrap();
            let e = check_regular_file(null, &f.metadata().unwrap()).unwrap_err();
            assert!(e.to_string().contains("character device"), "{e}");
        }
    }
}
