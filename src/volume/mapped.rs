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
//! [`memmap2::Mmap::map`] is `unsafe` because Rust assumes that memory behind a `&[u8]`
//! does not change, while another process may write to, or shorten, the file while it
//! is mapped. volcast accepts this the way other tools that map their inputs do
//! (databases, `ripgrep`, image viewers):
//!
//! - the mapping is read-only and private (`PROT_READ`, `MAP_PRIVATE`): volcast never
//!   writes through it;
//! - its bytes are only ever copied out as plain numbers ([`Voxels`](super::Voxels) reads each voxel
//!   with `read_unaligned`), and every bit pattern is a valid voxel of every type, so a
//!   concurrent write by another process yields other voxel values, that is a wrong
//!   image, not a memory-safety failure (formally, memory changing behind a shared
//!   reference is undefined behaviour: this is the trade-off every mmap user makes);
//! - only regular files are mapped (a FIFO, device, socket or directory is refused,
//!   judged from the opened file, not the path), and the file's length is checked on
//!   the opened file right before mapping, so the mapping never extends past the end
//!   of the file as it was then;
//! - **known limit**: if another process truncates the file while volcast has it
//!   mapped, touching a page past the new end raises `SIGBUS` and the process dies
//!   (there is no portable way to turn that into an error). Do not shorten or rewrite
//!   a volume while volcast renders it; replacing it by a new file (write, then rename)
//!   is safe, since the mapping keeps the old file's pages.

use std::fmt;
use std::fs::{File, Metadata};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::nrrd::Encoding;
use super::{ScalarType, VolumeError};

/// True when `ty` elements stored in the given byte order can be used as they are on
/// this machine (single bytes, or the machine's byte order).
pub fn is_native_order(ty: ScalarType, little_endian: bool) -> bool {
    ty.size() == 1 || little_endian == cfg!(target_endian = "little")
}

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
        }
    }
}

/// Voxels of one element type mapped read-only from a file (see the module docs for
/// what is mapped and why that is sound). Cloning shares the mapping.
#[derive(Clone)]
pub struct MappedVoxels {
    scalar_type: ScalarType,
    map: Arc<memmap2::Mmap>,
    path: PathBuf,
    offset: u64,
}

impl MappedVoxels {
    /// The element type.
    pub fn scalar_type(&self) -> ScalarType {
        self.scalar_type
    }

    /// The data's bytes, in native byte order, at whatever alignment the file gave them.
    pub fn bytes(&self) -> &[u8] {
        &self.map
    }

    /// The mapped file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Where the data starts in the file.
    pub fn offset(&self) -> u64 {
        self.offset
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.map.len() / self.scalar_type.size()
    }

    /// True when there are no elements (never, for a mapped volume).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl fmt::Debug for MappedVoxels {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("MappedVoxels")
            .field("scalar_type", &self.scalar_type)
            .field("path", &self.path)
            .field("offset", &self.offset)
            .field("len", &self.len())
            .finish()
    }
}

/// Opens `path` for reading without blocking (a FIFO would otherwise wait for a
/// writer before its type could be checked).
pub(crate) fn open_nonblocking(path: &Path) -> io::Result<File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    options.open(path)
}

/// Opens a volume file (header or data) for reading without blocking; inside a
/// [`confine::Scope`](super::confine::Scope), the opened file must lie in its folder.
pub(crate) fn open_for_mapping(path: &Path) -> io::Result<File> {
    let file = open_nonblocking(path)?;
    super::confine::check_opened(path, &file)?;
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
    let ft = meta.file_type();
    if ft.is_file() {
        return Ok(());
    }
    let kind = file_kind(&ft);
    Err(VolumeError::Unsupported {
        path: path.to_path_buf(),
        message: format!("is {kind}, not a regular file: {what} is read only from regular files"),
    })
}

/// "a directory", "a FIFO (named pipe)", "a character device", ... for a file that is
/// not regular.
pub(crate) fn file_kind(ft: &std::fs::FileType) -> &'static str {
    if ft.is_dir() {
        "a directory"
    } else {
        special_kind(ft)
    }
}

#[cfg(unix)]
fn special_kind(ft: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if ft.is_fifo() {
        "a FIFO (named pipe)"
    } else if ft.is_block_device() {
        "a block device"
    } else if ft.is_char_device() {
        "a character device"
    } else if ft.is_socket() {
        "a socket"
    } else {
        "a special file"
    }
}

#[cfg(not(unix))]
fn special_kind(_: &std::fs::FileType) -> &'static str {
    "a special file"
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
    let io_err = |source| VolumeError::Io {
        path: path.to_path_buf(),
        source,
    };
    let meta = file.metadata().map_err(io_err)?;
    check_regular_file(path, &meta)?;
    let end = offset.checked_add(bytes);
    if end.is_none_or(|end| end > meta.len()) {
        return Err(VolumeError::Data {
            path: path.to_path_buf(),
            message: format!(
                "file is {} bytes, shorter than the {bytes} bytes of data at offset {offset} \
                 (did it change while being opened?)",
                meta.len()
            ),
        });
    }
    let len = usize::try_from(bytes).map_err(|_| VolumeError::TooLarge {
        what: format!("mapping {}", path.display()),
        bytes: Some(bytes),
        limit: usize::MAX as u64,
    })?;
    debug_assert!(len % ty.size() == 0 && len > 0);
    // SAFETY: a read-only, private mapping of a regular file whose length covers the
    // mapped range (checked just above on the open file). Its bytes are only read, as
    // plain numbers for which every bit pattern is valid. What remains is that another
    // process may change or truncate the file meanwhile: see the module docs
    // (changed values only change the image; truncation raises SIGBUS, a documented
    // limit).
    let map = unsafe {
        memmap2::MmapOptions::new()
            .offset(offset)
            .len(len)
            .map(file)
    }
    .map_err(io_err)?;
    Ok(MappedVoxels {
        scalar_type: ty,
        map: Arc::new(map),
        path: path.to_path_buf(),
        offset,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_at_odd_offsets() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.raw");
        let mut bytes = vec![7u8; 3];
        for v in [1u16, 2, 0xfffe] {
            bytes.extend(v.to_ne_bytes());
        }
        std::fs::write(&path, &bytes).unwrap();
        let f = open_for_mapping(&path).unwrap();
        let m = map(&f, &path, ScalarType::Uint16, 3, 6).unwrap();
        assert_eq!(m.len(), 3);
        assert_eq!(m.bytes(), &bytes[3..]);
        assert!(map(&f, &path, ScalarType::Uint16, 5, 6).is_err());
        assert!(map(&f, &path, ScalarType::Uint16, u64::MAX, 6).is_err());
    }

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

    #[test]
    fn native_order() {
        assert!(is_native_order(ScalarType::Uint8, false));
        assert_eq!(
            is_native_order(ScalarType::Int16, true),
            cfg!(target_endian = "little")
        );
        assert_eq!(
            is_native_order(ScalarType::Float64, false),
            cfg!(target_endian = "big")
        );
    }
}
