//! NRRD volumes: the `nrrd` crate ([`::nrrd`]) reads and writes the files; this adapter
//! gives it volcast's memory limit and `--confine` check, turns its data and errors
//! into volcast's, and makes the 3D [`VolumeHeader`] of an N-D header ([`volume_header`]).

mod view;

use std::path::{Path, PathBuf};

pub use ::nrrd::{DataFile, Encoding, Endian, NrrdHeader, Space};

use super::{mapped, Limits, Storage, TypedVoxels, VolumeData, VolumeError, VolumeHeader};

/// The crate's reader with volcast's limit and the confinement check of every opened
/// file (see [`super::confine`]).
fn reader(limits: &Limits) -> ::nrrd::Reader {
    ::nrrd::Reader::new()
        .max_bytes(limits.max_bytes)
        .on_open(mapped::check_opened)
}

/// A reader for headers only (no data is allocated).
fn header_reader() -> ::nrrd::Reader {
    ::nrrd::Reader::new().on_open(mapped::check_opened)
}

/// The 3D view of a header used by the renderer: sizes (2D data → one slice, extra
/// size-1 axes dropped), geometry from `space directions`/`space origin` or
/// `spacings`, and the descriptive fields.
pub fn volume_header(header: &NrrdHeader, path: &Path) -> Result<VolumeHeader, VolumeError> {
    view::volume_header(header, path)
}

/// [`volume_header`] as a method of the crate's header.
pub trait NrrdHeaderExt {
    /// See [`volume_header`].
    fn volume_header(&self, path: &Path) -> Result<VolumeHeader, VolumeError>;
}

impl NrrdHeaderExt for NrrdHeader {
    fn volume_header(&self, path: &Path) -> Result<VolumeHeader, VolumeError> {
        view::volume_header(self, path)
    }
}

/// Reads and checks the header only (no data file is opened).
pub fn read_header(path: &Path) -> Result<NrrdHeader, VolumeError> {
    Ok(header_reader().read_header(path)?)
}

/// Whether [`read`] will map the data (raw encoding in native byte order, attached or
/// in one `data file`) or read it, and how many bytes. For mapped data the data file is
/// opened to apply `line skip` and `byte skip` and to check its type and length.
pub fn storage(path: &Path) -> Result<Storage, VolumeError> {
    Ok(header_reader().storage(path)?.into())
}

/// Reads header and data; `limits` is checked before any voxel memory is allocated.
/// Raw data in native byte order in one file is mapped instead (see
/// [`crate::volume::mapped`]) and does not count against `limits`.
pub fn read(path: &Path, limits: &Limits) -> Result<(NrrdHeader, VolumeData), VolumeError> {
    let (header, data) = reader(limits).read(path)?;
    Ok((header, data.into()))
}

/// [`read`], also returning the XXH3-128 of the data's bytes as stored (after
/// decompression, before byte swapping), computed while they are decoded (mapped
/// data: over the mapped bytes).
pub fn read_hashed(
    path: &Path,
    limits: &Limits,
) -> Result<(NrrdHeader, VolumeData, u128), VolumeError> {
    let (header, data, hash) = reader(limits).read_hashed(path)?;
    Ok((header, data.into(), hash))
}

/// Every file the volume at `path` is read from: the header, and each data file.
pub fn input_files(path: &Path) -> Result<Vec<PathBuf>, VolumeError> {
    Ok(header_reader().input_files(path)?)
}

/// The voxels as the crate's borrowed elements.
fn elements(data: TypedVoxels<'_>) -> ::nrrd::Elements<'_> {
    let bytes = crate::with_voxels!(data, v => v.as_bytes());
    ::nrrd::Elements::new(data.scalar_type(), bytes)
        .expect("voxel bytes are whole elements of their type")
}

/// Encodes a complete attached-header NRRD file in memory (see [`::nrrd::encode`]).
pub fn encode(header: &NrrdHeader, data: &VolumeData) -> Result<Vec<u8>, VolumeError> {
    encode_voxels(header, data.typed())
}

/// [`encode`] from a borrowed view of the values (an image's samples, say): the file's
/// bytes are the one buffer this allocates.
pub fn encode_voxels(header: &NrrdHeader, data: TypedVoxels<'_>) -> Result<Vec<u8>, VolumeError> {
    Ok(::nrrd::encode_elements(header, elements(data))?)
}

/// Writes a detached header to `nhdr_path` naming `data_file_name` (relative to the
/// header's folder), and the data, in `header.encoding`, to that file.
pub fn write_detached(
    nhdr_path: &Path,
    data_file_name: &str,
    header: &NrrdHeader,
    data: &VolumeData,
) -> Result<(), VolumeError> {
    Ok(::nrrd::write_detached_elements(
        nhdr_path,
        data_file_name,
        header,
        elements(data.typed()),
    )?)
}
