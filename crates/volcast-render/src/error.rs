//! The library's error type: every failure, sorted by who is at fault.

use std::path::PathBuf;

use crate::scene::SceneError;
use crate::volume::VolumeError;

/// Any error of a volcast run.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The scene file is malformed or inconsistent.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The volume cannot be read or described.
    #[error(transparent)]
    Volume(#[from] VolumeError),
    /// The scene and the volume (or the command line) do not fit together.
    #[error("{scene}: {message}")]
    Plan {
        /// The scene file.
        scene: PathBuf,
        /// What is wrong and what was expected.
        message: String,
    },
    /// An output file or folder could not be written.
    #[error("writing {}", path.display())]
    Output {
        /// The file or folder.
        path: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// A file in an output folder could not be read back (a record, an image to
    /// verify, the manifest).
    #[error("reading {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What the OS said, or what is wrong with it.
        source: std::io::Error,
    },
    /// A manifest record in an output folder is not what volcast writes.
    #[error("{}: {message}", path.display())]
    Manifest {
        /// The record or manifest file.
        path: PathBuf,
        /// What is wrong and what was expected.
        message: String,
    },
    /// The caller stopped the run ([`Progress::cancelled`](crate::pipeline::Progress::cancelled)
    /// said so between views): the images written before stay, the rest are not
    /// rendered.
    #[error("the run was cancelled")]
    Cancelled,
    /// An image could not be encoded.
    #[error("encoding {}: {message}", path.display())]
    Encode {
        /// The file being written.
        path: PathBuf,
        /// The encoder's message.
        message: String,
    },
}
