//! The errors the readers share, built the same way by each: the file and what is
//! wrong with its header, its data, or what it holds that volcast does not read.

use std::path::Path;

use super::VolumeError;

/// A header field that is wrong (no line number: binary headers).
pub(crate) fn header_err(path: &Path, message: String) -> VolumeError {
    VolumeError::Header {
        path: path.to_path_buf(),
        line: 0,
        message,
    }
}

/// Something the file holds that volcast does not read.
pub(crate) fn unsupported(path: &Path, message: String) -> VolumeError {
    VolumeError::Unsupported {
        path: path.to_path_buf(),
        message,
    }
}

/// Data that is not what the header says.
pub(crate) fn data_err(path: &Path, message: String) -> VolumeError {
    VolumeError::Data {
        path: path.to_path_buf(),
        message,
    }
}
