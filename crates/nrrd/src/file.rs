//! Low-level file access shared by the reader (and usable by other readers): opening
//! without blocking, refusing files that are not regular, and mapping a file's bytes.
//!
//! # Soundness of the mapping
//!
//! [`memmap2::Mmap::map`] is `unsafe` because Rust assumes that memory behind a `&[u8]`
//! does not change, while another process may write to, or shorten, the file while it
//! is mapped. This crate accepts this the way other tools that map their inputs do
//! (databases, `ripgrep`, image viewers):
//!
//! - the mapping is read-only and private (`PROT_READ`, `MAP_PRIVATE`): nothing is
//!   written through it;
//! - its bytes are only ever copied out as plain numbers, and every bit pattern is a
//!   valid element of every type, so a concurrent write by another process yields
//!   other values, not a memory-safety failure (formally, memory changing behind a
//!   shared reference is undefined behaviour: this is the trade-off every mmap user
//!   makes);
//! - only regular files are mapped (a FIFO, device, socket or directory is refused,
//!   judged from the opened file, not the path), and the file's length is checked on
//!   the opened file right before mapping, so the mapping never extends past the end
//!   of the file as it was then;
//! - **known limit**: if another process truncates the file while it is mapped,
//!   touching a page past the new end raises `SIGBUS` and the process dies (there is
//!   no portable way to turn that into an error). Do not shorten or rewrite a file
//!   while its mapping is in use; replacing it by a new file (write, then rename) is
//!   safe, since the mapping keeps the old file's pages.

use std::fmt;
use std::fs::{File, Metadata};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::{Error, ScalarType};

/// True when `ty` elements stored in the given byte order can be used as they are on
/// this machine (single bytes, or the machine's byte order).
pub fn is_native_order(ty: ScalarType, little_endian: bool) -> bool {
    ty.size() == 1 || little_endian == cfg!(target_endian = "little")
}

/// Elements of one type mapped read-only from a file (see the module docs for what
/// makes that sound). Cloning shares the mapping.
#[derive(Clone)]
pub struct Mapped {
    scalar_type: ScalarType,
    map: Arc<memmap2::Mmap>,
    path: PathBuf,
    offset: u64,
}

impl Mapped {
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

    /// True when there are no elements (never, for a mapping [`map`] made).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

impl fmt::Debug for Mapped {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Mapped")
            .field("scalar_type", &self.scalar_type)
            .field("path", &self.path)
            .field("offset", &self.offset)
            .field("len", &self.len())
            .finish()
    }
}

/// Opens `path` for reading without blocking (a FIFO would otherwise wait for a
/// writer before its type could be checked).
pub fn open_nonblocking(path: &Path) -> io::Result<File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK);
    }
    options.open(path)
}

/// An error unless `meta` (of `path`, holding `what`: "a NRRD header", "volume data")
/// describes a regular file.
pub fn check_regular(path: &Path, meta: &Metadata, what: &str) -> Result<(), Error> {
    let ft = meta.file_type();
    if ft.is_file() {
        return Ok(());
    }
    let kind = file_kind(&ft);
    Err(Error::Unsupported {
        path: path.to_path_buf(),
        message: format!("is {kind}, not a regular file: {what} is read only from regular files"),
    })
}

/// "a directory", "a FIFO (named pipe)", "a character device", ... for a file that is
/// not regular.
pub fn file_kind(ft: &std::fs::FileType) -> &'static str {
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
/// `file` should be a regular file opened for reading whose length was checked to
/// hold `offset + bytes`; both are checked once more here, on the open file.
pub fn map(
    file: &File,
    path: &Path,
    ty: ScalarType,
    offset: u64,
    bytes: u64,
) -> Result<Mapped, Error> {
    let io_err = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let meta = file.metadata().map_err(io_err)?;
    check_regular(path, &meta, "volume data")?;
    let end = offset.checked_add(bytes);
    if end.is_none_or(|end| end > meta.len()) {
        return Err(Error::Data {
            path: path.to_path_buf(),
            message: format!(
                "file is {} bytes, shorter than the {bytes} bytes of data at offset {offset} \
                 (did it change while being opened?)",
                meta.len()
            ),
        });
    }
    let len = usize::try_from(bytes).map_err(|_| Error::TooLarge {
        what: format!("mapping {}", path.display()),
        bytes: Some(bytes),
        limit: usize::MAX as u64,
    })?;
    debug_assert!(len % ty.size() == 0 && len > 0);
    // SAFETY: a read-only, private mapping of a regular file whose length covers the
    // mapped range (checked just above on the open file). Its bytes are only read, as
    // plain numbers for which every bit pattern is valid. What remains is that another
    // process may change or truncate the file meanwhile: see the module docs
    // (changed values only change the data; truncation raises SIGBUS, a documented
    // limit).
    let map = unsafe {
        memmap2::MmapOptions::new()
            .offset(offset)
            .len(len)
            .map(file)
    }
    .map_err(io_err)?;
    Ok(Mapped {
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
        let f = open_nonblocking(&path).unwrap();
        let m = map(&f, &path, ScalarType::Uint16, 3, 6).unwrap();
        assert_eq!(m.len(), 3);
        assert_eq!(m.bytes(), &bytes[3..]);
        assert!(map(&f, &path, ScalarType::Uint16, 5, 6).is_err());
        assert!(map(&f, &path, ScalarType::Uint16, u64::MAX, 6).is_err());
    }

    #[test]
    fn refuses_special_files() {
        let dir = tempfile::tempdir().unwrap();
        let f = open_nonblocking(dir.path()).unwrap();
        let e = map(&f, dir.path(), ScalarType::Uint8, 0, 1).unwrap_err();
        assert!(e.to_string().contains("is a directory"), "{e}");
        #[cfg(unix)]
        {
            let null = Path::new("/dev/null");
            let f = open_nonblocking(null).unwrap();
            let e = check_regular(null, &f.metadata().unwrap(), "volume data").unwrap_err();
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
