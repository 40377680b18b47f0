//! Atomic, exclusive file writes: the bytes go to a new temporary file in the
//! destination folder, which is then renamed over the destination, so an
//! interrupted run never leaves a truncated image under a final name.
//!
//! Output folders may be shared with other users (a cluster's scratch space), who
//! could plant symbolic links where volcast is about to write. So:
//!
//! - the path of the output folder itself is followed as given (it is the user's
//!   choice), but everything volcast creates inside it is created exclusively
//!   (`O_CREAT | O_EXCL | O_NOFOLLOW`: never through an existing file or link);
//! - temporary files are named `.{name}.{pid}@{host}.{random}.tmp`: the process and
//!   host let a later run find and remove those of a killed run
//!   ([`Folder::remove_stale_temporaries`]), the random part makes the name
//!   unpredictable, and a name that exists anyway is skipped for another one;
//! - the rename replaces whatever is at the final name (a planted link is replaced,
//!   its target is never written);
//! - subfolders (`manifest.d`) are opened without following a link, and every
//!   later write and read in them goes through that open folder (`openat`), so
//!   replacing the folder by a link while volcast runs changes nothing;
//! - files read back from the folder (records, images to verify) are opened
//!   without following links and without blocking, and must be regular files.
//!
//! Temporary files that a killed run left behind are removed by the next run:
//! those of processes of this host that are gone, and any not written to for an
//! hour (a shard on another machine of a cluster).

use std::fs::File;
use std::io::{self, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::OnceLock;
use std::time::{Duration, SystemTime};

/// The largest piece handed to the file in one `write(2)` by a writer callback
/// ([`Folder::write_atomic_with`]): large writes into a new file cost much more
/// system time per byte than pieces of this size on the virtual machines measured
/// (`bench/write_pieces.py` measures it; see [`DIRECT_FROM`]).
const WRITE_PIECE: usize = 64 << 10;

/// Files written whole from memory ([`Folder::write_atomic`], [`write_atomic_stat`])
/// of at least this many bytes go around the page cache (`O_DIRECT`, on Linux,
/// where the file system takes it): the bytes are copied into an aligned buffer
/// kept for the next file, written in one call, and the file cut to its length. Every
/// file is synced before its rename anyway, so the call waits for the device as
/// the sync did. On the virtual machines of this project (Linux 6.18 guests that
/// hand free memory back to their host) the page cache's fresh pages for a new
/// 4 MiB file cost 20-35 ms of system time in spells, 1-3 ms between them, while
/// the direct write takes 0.2 ms (`bench/write_pieces.py`); and a long run's
/// frames no longer push a mapped volume's pages out of the cache.
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
const DIRECT_FROM: usize = 256 << 10;

/// The alignment of a direct write's buffer address, file offset and length: 4 KiB,
/// the largest logical block of common devices.
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
const DIRECT_ALIGN: usize = 4096;

/// Writes `file` from the start through a buffer, in pieces of at most
/// [`WRITE_PIECE`] bytes.
fn buffered(file: File, fill: impl FnOnce(&mut dyn Write) -> io::Result<()>) -> io::Result<File> {
    let mut w = BufWriter::with_capacity(WRITE_PIECE, Pieces(file));
    fill(&mut w)?;
    let Pieces(file) = w.into_inner().map_err(|e| e.into_error())?;
    Ok(file)
}

/// Direct writes (`O_DIRECT`): see [`DIRECT_FROM`].
#[cfg(target_os = "linux")]
mod direct {
    use std::fs::File;
    use std::io;
    use std::os::unix::fs::FileExt;
    use std::sync::Mutex;

    use rustix::fs::{fcntl_getfl, fcntl_setfl, OFlags};

    use super::DIRECT_ALIGN;

    /// One aligned block of a direct write's buffer.
    #[derive(Clone, Copy)]
    #[repr(C, align(4096))]
    struct Block([u8; DIRECT_ALIGN]);

    /// Aligned buffers kept from file to file (one per file being written at
    /// once), so that writing a frame does not touch fresh memory either.
    static BUFFERS: Mutex<Vec<Vec<Block>>> = Mutex::new(Vec::new());

    /// Writes `bytes` into the new, empty `file` around the page cache: `Ok(true)`
    /// once written, `Ok(false)` if the file system does not take direct writes
    /// (the file is then empty again, its cursor at the start, to be written
    /// otherwise).
    pub(super) fn write(file: &File, bytes: &[u8]) -> io::Result<bool> {
        let flags = fcntl_getfl(file)?;
        if fcntl_setfl(file, flags | OFlags::DIRECT).is_err() {
            return Ok(false);
        }
        let mut blocks = BUFFERS
            .lock()
            .ok()
            .and_then(|mut b| b.pop())
            .unwrap_or_default();
        let written = {
            let n = bytes.len().div_ceil(DIRECT_ALIGN);
            if blocks.len() < n {
                blocks.resize(n, Block([0; DIRECT_ALIGN]));
            }
            // SAFETY: `blocks` holds `n` blocks of `DIRECT_ALIGN` plain bytes, one
            // after the other (`repr(C)`, its size a multiple of its alignment)
            let buf: &mut [u8] = unsafe {
                std::slice::from_raw_parts_mut(blocks.as_mut_ptr().cast::<u8>(), n * DIRECT_ALIGN)
            };
            buf[..bytes.len()].copy_from_slice(bytes);
            buf[bytes.len()..].fill(0);
            // at offset 0, not through the cursor: a refused write leaves it at the
            // start for the buffered one
            file.write_all_at(buf, 0)
        };
        if let Ok(mut b) = BUFFERS.lock() {
            b.push(blocks);
        }
        fcntl_setfl(file, flags)?;
        match written {
            Ok(()) => {
                // the zeros after the bytes were only there to fill the last block
                file.set_len(bytes.len() as u64)?;
                Ok(true)
            }
            Err(e) if e.raw_os_error() == Some(libc::EINVAL) => {
                file.set_len(0)?;
                Ok(false)
            }
            Err(e) => Err(e),
        }
    }
}

/// A writer that hands `W` at most [`WRITE_PIECE`] bytes per write (a
/// [`BufWriter`] hands larger slices on whole).
struct Pieces<W>(W);

impl<W: Write> Write for Pieces<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.write(&buf[..buf.len().min(WRITE_PIECE)])
    }

    fn flush(&mut self) -> io::Result<()> {
        self.0.flush()
    }
}

/// Writes `bytes` to `path` atomically (same-folder temporary file, fsync, rename).
/// The folder of `path` is followed as given; the file itself is never written
/// through a link.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomic_stat(path, bytes).map(drop)
}

/// [`write_atomic`], returning the metadata of the file written (see
/// [`Folder::write_atomic_stat`]).
pub fn write_atomic_stat(path: &Path, bytes: &[u8]) -> io::Result<Option<std::fs::Metadata>> {
    let (dir, name) = split(path)?;
    Folder::open(dir)?.write_atomic_bytes_stat(name, bytes)
}

/// Writes `path` atomically from a writer callback (for files too large to hold
/// in memory, such as animations): `fill` writes into a buffered temporary file,
/// which is synced and renamed over `path` only if `fill` succeeds.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> io::Result<()>,
) -> io::Result<()> {
    let (dir, name) = split(path)?;
    Folder::open(dir)?.write_atomic_with(name, fill)
}

/// The folder and file name of `path`.
fn split(path: &Path) -> io::Result<(&Path, &str)> {
    let name = path
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))?;
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    Ok((dir, name))
}

/// An open folder that files are written into and read from by name, never
/// following a link at the name (see the module documentation).
#[derive(Debug)]
pub struct Folder {
    path: PathBuf,
    #[cfg(unix)]
    fd: std::os::fd::OwnedFd,
}

/// The error for a link where volcast expects its own file or folder.
fn link_error(path: &Path) -> io::Error {
    io::Error::other(format!(
        "{} is a symbolic link: volcast does not follow links inside its output folder (someone else may have planted it); remove it, or use another output folder",
        path.display()
    ))
}

/// The error for something other than a regular file where one is expected.
fn not_regular(path: &Path, what: &str) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        format!("{} is {what}, not a regular file", path.display()),
    )
}

impl Folder {
    /// Opens an existing folder, following links in `path` as given.
    pub fn open(path: &Path) -> io::Result<Folder> {
        #[cfg(unix)]
        {
            use rustix::fs::{Mode, OFlags};
            let fd = rustix::fs::open(
                path,
                OFlags::RDONLY | OFlags::DIRECTORY | OFlags::CLOEXEC,
                Mode::empty(),
            )?;
            Ok(Folder {
                path: path.to_path_buf(),
                fd,
            })
        }
        #[cfg(not(unix))]
        {
            if !std::fs::metadata(path)?.is_dir() {
                return Err(io::Error::other(format!(
                    "{} is not a folder",
                    path.display()
                )));
            }
            Ok(Folder {
                path: path.to_path_buf(),
            })
        }
    }

    /// The folder's path as given.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Opens the subfolder `name`, creating it if it does not exist; a link or a
    /// file there is an error.
    pub fn subfolder(&self, name: &str) -> io::Result<Folder> {
        #[cfg(unix)]
        match rustix::fs::mkdirat(&self.fd, name, rustix::fs::Mode::from_raw_mode(0o777)) {
            Ok(()) | Err(rustix::io::Errno::EXIST) => {}
            Err(e) => return Err(e.into()),
        }
        #[cfg(not(unix))]
        match std::fs::create_dir(self.path.join(name)) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => {}
            Err(e) => return Err(e),
        }
        self.open_subfolder(name)
    }

    /// Opens the existing subfolder `name` (`NotFound` if there is none); a link or
    /// a file there is an error.
    pub fn open_subfolder(&self, name: &str) -> io::Result<Folder> {
        let path = self.path.join(name);
        let not_a_folder = || {
            io::Error::other(format!(
                "{} is not a folder (volcast keeps its frame records there); remove it, or use another output folder",
                path.display()
            ))
        };
        #[cfg(unix)]
        {
            use rustix::fs::{Mode, OFlags};
            match rustix::fs::openat(
                &self.fd,
                name,
                OFlags::RDONLY | OFlags::DIRECTORY | OFlags::NOFOLLOW | OFlags::CLOEXEC,
                Mode::empty(),
            ) {
                Ok(fd) => Ok(Folder { path, fd }),
                Err(rustix::io::Errno::LOOP) => Err(link_error(&path)),
                Err(rustix::io::Errno::NOTDIR) => match self.kind_of(name) {
                    Some(Kind::Link) => Err(link_error(&path)),
                    _ => Err(not_a_folder()),
                },
                Err(e) => Err(e.into()),
            }
        }
        #[cfg(not(unix))]
        {
            let meta = std::fs::symlink_metadata(&path)?;
            if meta.file_type().is_symlink() {
                return Err(link_error(&path));
            }
            if !meta.is_dir() {
                return Err(not_a_folder());
            }
            Folder::open(&path)
        }
    }

    /// What is at `name`, without following a link (`None`: nothing).
    pub fn kind_of(&self, name: &str) -> Option<Kind> {
        #[cfg(unix)]
        {
            use rustix::fs::{AtFlags, FileType};
            let st = rustix::fs::statat(&self.fd, name, AtFlags::SYMLINK_NOFOLLOW).ok()?;
            Some(match FileType::from_raw_mode(st.st_mode) {
                FileType::RegularFile => Kind::File,
                FileType::Directory => Kind::Folder,
                FileType::Symlink => Kind::Link,
                _ => Kind::Other,
            })
        }
        #[cfg(not(unix))]
        {
            let meta = std::fs::symlink_metadata(self.path.join(name)).ok()?;
            let ft = meta.file_type();
            Some(if ft.is_symlink() {
                Kind::Link
            } else if ft.is_dir() {
                Kind::Folder
            } else if ft.is_file() {
                Kind::File
            } else {
                Kind::Other
            })
        }
    }

    /// Creates a new file `name` for writing: never through an existing file or link.
    fn create_new(&self, name: &str) -> io::Result<File> {
        #[cfg(unix)]
        {
            use rustix::fs::{Mode, OFlags};
            let fd = rustix::fs::openat(
                &self.fd,
                name,
                OFlags::WRONLY | OFlags::CREATE | OFlags::EXCL | OFlags::NOFOLLOW | OFlags::CLOEXEC,
                Mode::from_raw_mode(0o666),
            )?;
            Ok(File::from(fd))
        }
        #[cfg(not(unix))]
        {
            std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(self.path.join(name))
        }
    }

    fn rename(&self, from: &str, to: &str) -> io::Result<()> {
        #[cfg(unix)]
        {
            Ok(rustix::fs::renameat(&self.fd, from, &self.fd, to)?)
        }
        #[cfg(not(unix))]
        {
            std::fs::rename(self.path.join(from), self.path.join(to))
        }
    }

    fn remove(&self, name: &str) -> io::Result<()> {
        #[cfg(unix)]
        {
            Ok(rustix::fs::unlinkat(
                &self.fd,
                name,
                rustix::fs::AtFlags::empty(),
            )?)
        }
        #[cfg(not(unix))]
        {
            std::fs::remove_file(self.path.join(name))
        }
    }

    /// Writes `bytes` to `name` in this folder atomically (from 256 KiB, around the
    /// page cache where the file system allows it).
    pub fn write_atomic(&self, name: &str, bytes: &[u8]) -> io::Result<()> {
        self.write_atomic_bytes_stat(name, bytes).map(drop)
    }

    /// [`Folder::write_atomic`], returning the metadata as
    /// [`Folder::write_atomic_stat`] does.
    pub fn write_atomic_bytes_stat(
        &self,
        name: &str,
        bytes: &[u8],
    ) -> io::Result<Option<std::fs::Metadata>> {
        self.write_then_rename(name, |file| {
            #[cfg(target_os = "linux")]
            if bytes.len() >= DIRECT_FROM && direct::write(&file, bytes)? {
                return Ok(file);
            }
            buffered(file, |w| w.write_all(bytes))
        })
    }

    /// Writes `name` in this folder atomically from a writer callback: a new
    /// temporary file (created exclusively), synced, then renamed over `name`.
    pub fn write_atomic_with(
        &self,
        name: &str,
        fill: impl FnOnce(&mut dyn Write) -> io::Result<()>,
    ) -> io::Result<()> {
        self.write_atomic_stat(name, fill).map(drop)
    }

    /// [`Folder::write_atomic_with`], returning the metadata of the file it wrote,
    /// read from the open file after the rename (so it is that file's, whatever
    /// happens to the name meanwhile; on other systems than Unix, read by name),
    /// or `None` when it cannot be read (the file is written all the same).
    pub fn write_atomic_stat(
        &self,
        name: &str,
        fill: impl FnOnce(&mut dyn Write) -> io::Result<()>,
    ) -> io::Result<Option<std::fs::Metadata>> {
        self.write_then_rename(name, |file| buffered(file, fill))
    }

    /// A new temporary file for `name`, written by `write`, synced, then renamed
    /// over `name` (removed instead if anything fails); the metadata as
    /// [`Folder::write_atomic_stat`] returns it.
    fn write_then_rename(
        &self,
        name: &str,
        write: impl FnOnce(File) -> io::Result<File>,
    ) -> io::Result<Option<std::fs::Metadata>> {
        let (tmp, file) = self.create_temporary(name)?;
        let result = (|| {
            let file = write(file)?;
            file.sync_all()?;
            #[cfg(not(unix))]
            drop(file);
            self.rename(&tmp, name)?;
            #[cfg(unix)]
            let metadata = file.metadata();
            #[cfg(not(unix))]
            let metadata = std::fs::metadata(self.path.join(name));
            Ok(metadata.ok())
        })();
        if result.is_err() {
            let _ = self.remove(&tmp);
        }
        result
    }

    /// A new temporary file for `name`: tries fresh random names until one can be
    /// created exclusively.
    fn create_temporary(&self, name: &str) -> io::Result<(String, File)> {
        let mut last = None;
        for _ in 0..16 {
            let tmp = temporary_name(name);
            match self.create_new(&tmp) {
                Ok(f) => return Ok((tmp, f)),
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last = Some(e),
                Err(e) => return Err(e),
            }
        }
        Err(last.unwrap_or_else(|| io::Error::other("no temporary name")))
    }

    /// Opens `name` for reading: never through a link, never blocking (a FIFO is
    /// refused, not waited on), and only if it is a regular file.
    pub fn open_regular(&self, name: &str) -> io::Result<File> {
        let path = self.path.join(name);
        #[cfg(unix)]
        let file = {
            use rustix::fs::{Mode, OFlags};
            match rustix::fs::openat(
                &self.fd,
                name,
                OFlags::RDONLY | OFlags::NOFOLLOW | OFlags::NONBLOCK | OFlags::CLOEXEC,
                Mode::empty(),
            ) {
                Ok(fd) => File::from(fd),
                Err(rustix::io::Errno::LOOP) => return Err(link_error(&path)),
                Err(e) => return Err(e.into()),
            }
        };
        #[cfg(not(unix))]
        let file = {
            if std::fs::symlink_metadata(&path)?.file_type().is_symlink() {
                return Err(link_error(&path));
            }
            File::open(&path)?
        };
        let meta = file.metadata()?;
        if meta.is_dir() {
            return Err(not_regular(&path, "a folder"));
        }
        if !meta.is_file() {
            return Err(not_regular(&path, "a special file"));
        }
        Ok(file)
    }

    /// Reads all of `name` (see [`Folder::open_regular`]) if it has at most `max`
    /// bytes; `Ok(None)` when it does not exist.
    pub fn read_regular(&self, name: &str, max: u64) -> io::Result<Option<Vec<u8>>> {
        let file = match self.open_regular(name) {
            Ok(f) => f,
            Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e),
        };
        let len = file.metadata()?.len();
        if len > max {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "{} is {len} bytes, more than the {max} volcast would ever write there",
                    self.path.join(name).display()
                ),
            ));
        }
        let mut bytes = Vec::new();
        bytes
            .try_reserve_exact(len as usize)
            .map_err(|_| io::Error::new(io::ErrorKind::OutOfMemory, "out of memory"))?;
        file.take(max + 1).read_to_end(&mut bytes)?;
        if bytes.len() as u64 > max {
            return Err(io::Error::new(
                io::ErrorKind::InvalidData,
                format!(
                    "{} grew past the {max} bytes volcast would ever write there",
                    self.path.join(name).display()
                ),
            ));
        }
        Ok(Some(bytes))
    }

    /// The names of the entries of this folder.
    fn names(&self) -> io::Result<Vec<String>> {
        #[cfg(unix)]
        {
            let mut names = Vec::new();
            for entry in rustix::fs::Dir::read_from(&self.fd)? {
                let entry = entry?;
                if let Ok(n) = entry.file_name().to_str() {
                    names.push(n.to_string());
                }
            }
            Ok(names)
        }
        #[cfg(not(unix))]
        {
            let mut names = Vec::new();
            for e in std::fs::read_dir(&self.path)? {
                if let Ok(n) = e?.file_name().into_string() {
                    names.push(n);
                }
            }
            Ok(names)
        }
    }

    /// Modification age of the regular file `name` (not following links), or `None`
    /// when it is not a regular file.
    fn file_age(&self, name: &str) -> Option<Option<Duration>> {
        #[cfg(unix)]
        {
            use rustix::fs::{AtFlags, FileType};
            let st = rustix::fs::statat(&self.fd, name, AtFlags::SYMLINK_NOFOLLOW).ok()?;
            if FileType::from_raw_mode(st.st_mode) != FileType::RegularFile {
                return None;
            }
            let modified = SystemTime::UNIX_EPOCH
                .checked_add(Duration::new(
                    u64::try_from(st.st_mtime).unwrap_or(0),
                    u32::try_from(st.st_mtime_nsec).unwrap_or(0),
                ))
                .unwrap_or(SystemTime::UNIX_EPOCH);
            Some(SystemTime::now().duration_since(modified).ok())
        }
        #[cfg(not(unix))]
        {
            let meta = std::fs::symlink_metadata(self.path.join(name)).ok()?;
            if !meta.is_file() {
                return None;
            }
            Some(
                meta.modified()
                    .ok()
                    .and_then(|t| SystemTime::now().duration_since(t).ok()),
            )
        }
    }

    /// Removes the temporary files of our own naming in this folder that no running
    /// process will finish: those of this machine whose process has ended, and any
    /// not written to for an hour. Returns how many were removed. Other files, and
    /// anything that is not a regular file, are never touched.
    pub fn remove_stale_temporaries(&self) -> io::Result<usize> {
        let mut removed = 0;
        for name in self.names()? {
            let Some((pid, host)) = parse_temporary(&name) else {
                continue;
            };
            let Some(age) = self.file_age(&name) else {
                continue;
            };
            let old = age.is_some_and(|age| age > Duration::from_secs(3600));
            let orphan = host == host_name() && !may_be_running(pid);
            if old || orphan {
                match self.remove(&name) {
                    Ok(()) => removed += 1,
                    Err(e) if e.kind() == io::ErrorKind::NotFound => {}
                    Err(e) => return Err(e),
                }
            }
        }
        Ok(removed)
    }
}

/// What is at a name in a folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A regular file.
    File,
    /// A folder.
    Folder,
    /// A symbolic link (not followed).
    Link,
    /// A FIFO, socket or device.
    Other,
}

/// Removes the stale temporaries (see [`Folder::remove_stale_temporaries`]) of the
/// folder `dir`; a folder that does not exist has none.
pub fn remove_stale_temporaries(dir: &Path) -> io::Result<usize> {
    match Folder::open(dir) {
        Ok(f) => f.remove_stale_temporaries(),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(0),
        Err(e) => Err(e),
    }
}

/// A fresh temporary name for `name`: `.{name}.{pid}@{host}.{random}.tmp`.
pub(crate) fn temporary_name(name: &str) -> String {
    format!(
        ".{name}.{}@{}.{:016x}.tmp",
        std::process::id(),
        host_name(),
        random_u64()
    )
}

/// 64 unpredictable bits: std's per-process random hash keys over a counter and
/// the time (no cryptographic strength is needed: the name only has to be hard to
/// guess, since it is created exclusively anyway).
fn random_u64() -> u64 {
    use std::collections::hash_map::RandomState;
    use std::hash::{BuildHasher, Hasher};
    static KEYS: OnceLock<RandomState> = OnceLock::new();
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let mut h = KEYS.get_or_init(RandomState::new).build_hasher();
    h.write_u64(COUNTER.fetch_add(1, Ordering::Relaxed));
    h.write_u128(
        SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos()),
    );
    h.finish()
}

/// This machine's name, reduced to characters safe in a file name.
fn host_name() -> &'static str {
    static HOST: OnceLock<String> = OnceLock::new();
    HOST.get_or_init(|| {
        let raw = std::fs::read_to_string("/proc/sys/kernel/hostname")
            .ok()
            .or_else(|| std::env::var("HOSTNAME").ok())
            .or_else(|| std::env::var("COMPUTERNAME").ok())
            .unwrap_or_default();
        let clean: String = raw
            .trim()
            .chars()
            .filter(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.'))
            .collect();
        if clean.is_empty() {
            "localhost".into()
        } else {
            clean
        }
    })
}

/// Splits one of our temporary names into (pid, host). Reads both the current
/// form `.{name}.{pid}@{host}.{random:016x}.tmp` and the older one without the
/// random part.
fn parse_temporary(name: &str) -> Option<(u32, &str)> {
    let rest = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let rest = match rest.rsplit_once('.') {
        Some((front, r)) if r.len() == 16 && r.bytes().all(|b| b.is_ascii_hexdigit()) => front,
        _ => rest,
    };
    let (front, host) = rest.rsplit_once('@')?;
    let (_, pid) = front.rsplit_once('.')?;
    Some((pid.parse().ok()?, host))
}

/// Whether process `pid` of this machine may still be running (`true` where that
/// cannot be told).
fn may_be_running(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    let proc = Path::new("/proc");
    if proc.join("self").exists() {
        proc.join(pid.to_string()).exists()
    } else {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Records the length of each write it is handed.
    struct Lengths(Vec<usize>);

    impl Write for Lengths {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            self.0.push(buf.len());
            Ok(buf.len())
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    /// `n` bytes that do not repeat with any short period.
    fn pattern(n: usize, seed: u8) -> Vec<u8> {
        (0..n as u32)
            .map(|i| i.wrapping_mul(2_654_435_761).to_le_bytes()[3] ^ seed)
            .collect()
    }

    #[test]
    fn whole_files_from_memory_are_exactly_their_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let folder = Folder::open(dir.path()).unwrap();
        // buffered and direct sizes, whole blocks and not, and small files after
        // large ones (a kept buffer must not show its older bytes)
        let sizes = [
            (4 << 20) + 123,
            100,
            DIRECT_FROM - 1,
            DIRECT_FROM,
            DIRECT_FROM + 1,
            DIRECT_FROM + DIRECT_ALIGN,
        ];
        for (k, n) in sizes.into_iter().enumerate() {
            let bytes = pattern(n, k as u8);
            let name = format!("f{k}");
            let meta = folder.write_atomic_bytes_stat(&name, &bytes).unwrap();
            assert_eq!(meta.map(|m| m.len()), Some(n as u64), "{n} bytes");
            assert!(
                std::fs::read(dir.path().join(&name)).unwrap() == bytes,
                "{n} bytes"
            );
        }
        // no temporary file is left
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), sizes.len());
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn direct_writes_leave_no_pages_in_the_page_cache() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d");
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&path)
            .unwrap();
        let bytes = pattern(DIRECT_FROM + 5, 9);
        let kind = rustix::fs::fstatfs(&file).unwrap().f_type;
        // tmpfs takes direct writes, but its files are the page cache
        const TMPFS_MAGIC: i64 = 0x0102_1994;
        if !direct::write(&file, &bytes).unwrap() || kind as i64 == TMPFS_MAGIC {
            eprintln!(
                "skipped: the file system of {} keeps direct writes in memory or refuses them",
                dir.path().display()
            );
            return;
        }
        // SAFETY: the file is this test's own, and nothing changes it while mapped
        let map = unsafe { memmap2::Mmap::map(&file) }.unwrap();
        // SAFETY: sysconf reads a constant of the system
        let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) } as usize;
        let mut resident = vec![0u8; map.len().div_ceil(page)];
        // SAFETY: the range is the mapping's, and `resident` has a byte per page
        let r = unsafe { libc::mincore(map.as_ptr() as *mut _, map.len(), resident.as_mut_ptr()) };
        assert_eq!(r, 0, "{}", io::Error::last_os_error());
        let cached = resident.iter().filter(|&&b| b & 1 == 1).count();
        assert_eq!(
            cached,
            0,
            "{cached} of {} pages in the page cache",
            resident.len()
        );
        assert!(map[..] == bytes[..]);
    }

    #[test]
    fn large_writes_reach_the_file_in_pieces() {
        let mut w = BufWriter::with_capacity(WRITE_PIECE, Pieces(Lengths(Vec::new())));
        w.write_all(b"header\n").unwrap();
        w.write_all(&vec![7u8; 4 << 20]).unwrap();
        w.write_all(&[1, 2, 3]).unwrap();
        let Pieces(Lengths(lengths)) = w.into_inner().map_err(|e| e.into_error()).unwrap();
        assert!(lengths.iter().all(|&n| n <= WRITE_PIECE), "{lengths:?}");
        assert_eq!(lengths.iter().sum::<usize>(), 7 + (4 << 20) + 3);
        // whole pieces, not a trickle: the short header and tail, and 64 whole ones
        assert!(
            lengths.len() <= (7 + (4 << 20) + 3) / WRITE_PIECE + 2,
            "{}",
            lengths.len()
        );
    }

    #[test]
    fn writes_and_leaves_no_temporary() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let p = dir.join("a.bin");
        write_atomic(&p, b"hello").unwrap();
        write_atomic(&p, b"bye").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"bye");
        // a failing writer leaves the old file and no temporary
        let e = write_atomic_with(&p, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("interrupted"))
        });
        assert!(e.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"bye");
        let names: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
    }

    #[test]
    fn temporary_names_are_fresh_and_parse() {
        let a = temporary_name("mip_0001.png");
        let b = temporary_name("mip_0001.png");
        assert_ne!(a, b);
        assert_eq!(parse_temporary(&a), Some((std::process::id(), host_name())));
        // the form of earlier versions
        assert_eq!(
            parse_temporary(".a_0001.png.12@node1.cluster.tmp"),
            Some((12, "node1.cluster"))
        );
        assert_eq!(
            parse_temporary(".a_0001.png.12@node1.cluster.00000000deadbeef.tmp"),
            Some((12, "node1.cluster"))
        );
        assert_eq!(parse_temporary(".notes.tmp"), None);
    }

    #[cfg(unix)]
    #[test]
    fn planted_links_are_never_written_through() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let victim = dir.join("victim.txt");
        std::fs::write(&victim, b"precious").unwrap();
        let out = dir.join("out");
        std::fs::create_dir(&out).unwrap();
        let folder = Folder::open(&out).unwrap();
        // a link at a temporary name is never opened: creating it fails, and the
        // writer moves on to another name
        std::os::unix::fs::symlink(&victim, out.join(".x.png.tmp")).unwrap();
        let e = folder.create_new(".x.png.tmp").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::AlreadyExists);
        // a link at the final name is replaced, not followed
        std::os::unix::fs::symlink(&victim, out.join("x.png")).unwrap();
        folder.write_atomic("x.png", b"image").unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        assert!(std::fs::symlink_metadata(out.join("x.png"))
            .unwrap()
            .is_file());
        assert_eq!(std::fs::read(out.join("x.png")).unwrap(), b"image");
        // a link at a subfolder's name is an error, not followed
        let elsewhere = dir.join("elsewhere");
        std::fs::create_dir(&elsewhere).unwrap();
        std::os::unix::fs::symlink(&elsewhere, out.join("manifest.d")).unwrap();
        let e = folder.subfolder("manifest.d").unwrap_err().to_string();
        assert!(e.contains("is a symbolic link"), "{e}");
        // reading through a link is refused too
        let e = folder.open_regular("x.png.link");
        assert!(e.is_err());
        std::os::unix::fs::symlink(&victim, out.join("r.json")).unwrap();
        let e = folder.read_regular("r.json", 100).unwrap_err().to_string();
        assert!(e.contains("is a symbolic link"), "{e}");
        assert_eq!(folder.read_regular("missing.json", 100).unwrap(), None);
        assert_eq!(
            folder.read_regular("x.png", 100).unwrap().as_deref(),
            Some(&b"image"[..])
        );
        assert!(folder.read_regular("x.png", 2).is_err(), "too long");
        assert_eq!(std::fs::read_dir(&elsewhere).unwrap().count(), 0);
    }

    #[test]
    fn stale_temporaries_are_removed_and_others_kept() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let own = dir.join(temporary_name("mine.png"));
        // pid 4294967295 cannot be running (Linux pids are below 2^22)
        let dead = dir.join(format!(".a_0001.png.4294967295@{}.tmp", host_name()));
        let dead_new = dir.join(format!(
            ".a_0002.png.4294967295@{}.0123456789abcdef.tmp",
            host_name()
        ));
        let elsewhere = dir.join(".a_0002.png.4294967295@some-other-host.tmp");
        let unrelated = dir.join(".notes.tmp");
        for p in [&own, &dead, &dead_new, &elsewhere, &unrelated] {
            std::fs::write(p, b"x").unwrap();
        }
        let n = remove_stale_temporaries(dir).unwrap();
        let on_linux = Path::new("/proc/self").exists();
        assert_eq!(n, 2 * usize::from(on_linux));
        assert_eq!(dead.exists(), !on_linux);
        assert_eq!(dead_new.exists(), !on_linux);
        assert!(own.exists() && elsewhere.exists() && unrelated.exists());
        assert_eq!(remove_stale_temporaries(&dir.join("gone")).unwrap(), 0);
    }
}
