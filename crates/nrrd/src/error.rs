//! The reader's and writer's errors, each naming the file (and for header problems
//! the 1-based line) so that a message can be shown as it is.

use std::path::PathBuf;

/// Errors from reading or writing NRRD files, sorted by who is at fault.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The file system refused (missing file, permissions, or the
    /// [`Reader::on_open`](crate::Reader::on_open) check). The OS message is the
    /// error's `source()`, printed after the path by error-chain printers.
    #[error("{}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// What the OS (or the open check) said.
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
    /// The data does not match its description (too short, too long, unparseable).
    #[error("{}: {message}", path.display())]
    Data {
        /// The data file.
        path: PathBuf,
        /// What is wrong and what was expected.
        message: String,
    },
    /// A feature of the format this reader does not implement, or a file that is not
    /// a regular file.
    #[error("{}: {message}", path.display())]
    Unsupported {
        /// The file concerned.
        path: PathBuf,
        /// What is not supported.
        message: String,
    },
    /// The data would need more memory than [`Reader::max_bytes`](crate::Reader::max_bytes) allows.
    #[error("{what} needs {} but the limit is {}",
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
    /// Memory the limit allowed could not be allocated.
    #[error("{}: out of memory: allocating {} for the voxels failed", path.display(), human_bytes(*bytes))]
    OutOfMemory {
        /// The file being read.
        path: PathBuf,
        /// Bytes of the allocation that failed.
        bytes: u64,
    },
    /// A header and data that cannot be written as a file that reads back the same.
    #[error("{0}")]
    Invalid(String),
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

/// Number of elements of a grid of `sizes` and its byte count for elements of
/// `elem_size` bytes, or [`Error::TooLarge`] if either overflows or exceeds `max_bytes`.
pub(crate) fn check_size(
    sizes: &[usize],
    elem_size: usize,
    max_bytes: u64,
) -> Result<(usize, usize), Error> {
    let too_large = |bytes| Error::TooLarge {
        what: format!("sizes {sizes:?}"),
        bytes,
        limit: max_bytes,
    };
    let count = sizes
        .iter()
        .try_fold(1usize, |acc, &s| acc.checked_mul(s))
        .ok_or_else(|| too_large(None))?;
    let bytes = count
        .checked_mul(elem_size)
        .ok_or_else(|| too_large(None))?;
    if bytes as u64 > max_bytes {
        return Err(too_large(Some(bytes as u64)));
    }
    Ok((count, bytes))
}
