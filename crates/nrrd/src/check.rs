//! The header check between parsing and reading data (teem's `_nrrdHeaderCheck` plus
//! the cross-field rules of the spec): everything the data reader relies on.

use std::path::Path;

use super::data::file_count;
use super::fields::Parsed;
use super::{DataFile, Encoding};
use crate::Error;

fn err(path: &Path, line: usize, message: String) -> Error {
    Error::Header {
        path: path.to_path_buf(),
        line,
        message,
    }
}

/// Checks a parsed header for consistency.
pub(super) fn check_header(path: &Path, p: &Parsed) -> Result<(), Error> {
    check_endian(path, p)?;
    check_byte_skip(path, p)?;
    check_spacings_vs_directions(path, p)?;
    check_data_files(path, p)
}

/// `endian` is required when the stored bytes of multi-byte elements are visible.
fn check_endian(path: &Path, p: &Parsed) -> Result<(), Error> {
    let h = &p.header;
    if h.scalar_type.size() > 1 && h.encoding.endian_matters() && !p.has("endian") {
        return Err(err(
            path,
            0,
            format!(
                "missing field `endian` (little or big): type {} with {} encoding needs it",
                h.scalar_type,
                h.encoding.name()
            ),
        ));
    }
    Ok(())
}

/// `byte skip: -1` only makes sense for raw data (the spec; teem's `_nrrdByteSkipSkip`).
fn check_byte_skip(path: &Path, p: &Parsed) -> Result<(), Error> {
    let h = &p.header;
    if h.byte_skip < 0 && h.encoding != Encoding::Raw {
        return Err(err(
            path,
            p.line("byte skip"),
            format!(
                "byte skip: -1 (data at the end of the file) works only with raw encoding, not {}",
                h.encoding.name()
            ),
        ));
    }
    Ok(())
}

/// An axis has either a spacing or a space direction, not both.
fn check_spacings_vs_directions(path: &Path, p: &Parsed) -> Result<(), Error> {
    let h = &p.header;
    let (Some(spacings), Some(dirs)) = (&h.spacings, &h.space_directions) else {
        return Ok(());
    };
    for (axis, (s, d)) in spacings.iter().zip(dirs).enumerate() {
        if !s.is_nan() && d.is_some() {
            return Err(err(
                path,
                p.line("spacings"),
                format!(
                    "spacings: axis {axis} has both a spacing ({s}) and a space direction (line {}); \
                     the format allows only one (use nan in spacings)",
                    p.line("space directions")
                ),
            ));
        }
    }
    Ok(())
}

/// Several data files must split the elements into equal pieces (teem's
/// `_nrrdDataFNCheck`).
fn check_data_files(path: &Path, p: &Parsed) -> Result<(), Error> {
    let h = &p.header;
    let line = p.line("data file");
    let dim = h.dimension();
    let stdin = match &h.data_file {
        DataFile::Single(name) => name == "-",
        DataFile::List { names, .. } => names.iter().any(|n| n == "-"),
        _ => false,
    };
    if stdin {
        return Err(Error::Unsupported {
            path: path.to_path_buf(),
            message: format!("line {line}: data file \"-\" (standard input) is not supported"),
        });
    }
    let subdim = match &h.data_file {
        DataFile::Attached | DataFile::Single(_) => return Ok(()),
        DataFile::Pattern { subdim, .. } | DataFile::List { subdim, .. } => {
            subdim.unwrap_or(dim - 1)
        }
    };
    let files = file_count(&h.data_file);
    if subdim < dim {
        let expected: u128 = h.sizes[subdim..].iter().map(|&s| s as u128).product();
        if files != expected {
            return Err(err(
                path,
                line,
                format!(
                    "data file: expected {expected} files of {subdim}-D pieces (sizes {:?}), got {files}",
                    h.sizes
                ),
            ));
        }
    } else {
        let last = h.sizes[dim - 1] as u128;
        if files > last || !last.is_multiple_of(files) {
            return Err(err(
                path,
                line,
                format!(
                    "data file: {files} files cannot hold equal slabs of the {last} slices of axis {}",
                    dim - 1
                ),
            ));
        }
    }
    Ok(())
}
