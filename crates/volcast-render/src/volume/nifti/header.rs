//! The header of a NIfTI file: the 348 bytes of NIfTI-1 or the 540 of NIfTI-2 (the
//! same fields, wider and reordered: 64-bit sizes and offsets, doubles for the
//! geometry), by byte offset, in the byte order that `sizeof_hdr` reveals, checked one
//! by one, and the index-to-world map they define (the sform when `sform_code > 0`,
//! else the qform when `qform_code > 0`, else the voxel sizes: "method 1" of
//! `nifti1.h`, which NIfTI-2 keeps).

use crate::volume::errors::{header_err, unsupported};
use std::io::Read;
use std::path::Path;

use glam::{DMat3, DVec3};

use crate::volume::{Geometry, Rescale, ScalarType, VolumeError};

/// Bytes of a NIfTI-1 header.
pub(super) const HEADER_BYTES: usize = 348;
/// Bytes of a NIfTI-2 header.
const HEADER2_BYTES: usize = 540;

/// What the reader uses of a NIfTI-1 or NIfTI-2 header, checked (NIfTI-1's single
/// precision fields widened exactly to double).
#[derive(Clone, Debug, PartialEq)]
pub struct NiftiHeader {
    /// 1 or 2: NIfTI-1 or NIfTI-2.
    pub version: u8,
    /// Byte order of the header and the data.
    pub little_endian: bool,
    /// `dim[0]`: number of axes (1 to 7).
    pub ndim: usize,
    /// `dim[1..=7]`, 1 beyond `ndim`.
    pub dims: [usize; 7],
    /// `datatype` as a scalar type.
    pub scalar_type: ScalarType,
    /// `pixdim[0..8]` (`pixdim[0]` is qfac).
    pub pixdim: [f64; 8],
    /// `vox_offset`: where the data starts in the file.
    pub vox_offset: u64,
    /// `scl_slope`, `scl_inter` as stored.
    pub scl: [f64; 2],
    /// `qform_code`, `sform_code`.
    pub codes: [i32; 2],
    /// `quatern_b, c, d`, then `qoffset_x, y, z`.
    pub quatern: [f64; 6],
    /// `srow_x`, `srow_y`, `srow_z`.
    pub srow: [[f64; 4]; 3],
    /// `xyzt_units`.
    pub xyzt_units: i32,
    /// `descrip`.
    pub descrip: String,
    /// `intent_name`.
    pub intent_name: String,
}

/// The scalar type of a `datatype` code, or the name of a type volcast cannot render.
fn datatype(code: i16) -> Result<ScalarType, String> {
    Ok(match code {
        2 => ScalarType::Uint8,
        4 => ScalarType::Int16,
        8 => ScalarType::Int32,
        16 => ScalarType::Float32,
        64 => ScalarType::Float64,
        256 => ScalarType::Int8,
        512 => ScalarType::Uint16,
        768 => ScalarType::Uint32,
        1024 => ScalarType::Int64,
        1280 => ScalarType::Uint64,
        1 => return Err("1 (binary, one bit per voxel)".into()),
        32 => return Err("32 (complex64)".into()),
        128 => return Err("128 (RGB24, colour)".into()),
        1536 => return Err("1536 (float128)".into()),
        1792 => return Err("1792 (complex128)".into()),
        2048 => return Err("2048 (complex256)".into()),
        2304 => return Err("2304 (RGBA32, colour)".into()),
        other => return Err(format!("{other} (not a NIfTI datatype)")),
    })
}

/// Reads the fields of a header in one byte order.
struct Fields<'a> {
    b: &'a [u8],
    le: bool,
}

impl Fields<'_> {
    fn bytes<const N: usize>(&self, at: usize) -> [u8; N] {
        let mut v: [u8; N] = self.b[at..at + N].try_into().expect("N bytes");
        if !self.le {
            v.reverse();
        }
        v
    }

    fn i16(&self, at: usize) -> i16 {
        i16::from_le_bytes(self.bytes(at))
    }

    fn i32(&self, at: usize) -> i32 {
        i32::from_le_bytes(self.bytes(at))
    }

    fn i64(&self, at: usize) -> i64 {
        i64::from_le_bytes(self.bytes(at))
    }

    fn f32(&self, at: usize) -> f64 {
        f64::from(f32::from_le_bytes(self.bytes(at)))
    }

    fn f64(&self, at: usize) -> f64 {
        f64::from_le_bytes(self.bytes(at))
    }

    fn text(&self, at: usize, len: usize) -> String {
        let s = &self.b[at..at + len];
        let end = s.iter().position(|&c| c == 0).unwrap_or(len);
        String::from_utf8_lossy(&s[..end]).trim().to_string()
    }
}

/// Reads and checks the header at the start of `r` (the file, or its gzip stream):
/// NIfTI-1 or NIfTI-2, as `sizeof_hdr` says.
pub(super) fn read_header(path: &Path, r: &mut impl Read) -> Result<NiftiHeader, VolumeError> {
    let mut b = [0u8; HEADER2_BYTES];
    let mut got = fill(path, r, &mut b[..4])?;
    if got < 4 {
        return Err(header_err(
            path,
            format!("file has {got} bytes: not a NIfTI file (expected a 348-byte NIfTI-1 or 540-byte NIfTI-2 header)"),
        ));
    }
    let size = [b[0], b[1], b[2], b[3]];
    let (version, le, len) = match (i32::from_le_bytes(size), i32::from_be_bytes(size)) {
        (348, _) => (1, true, HEADER_BYTES),
        (_, 348) => (1, false, HEADER_BYTES),
        (540, _) => (2, true, HEADER2_BYTES),
        (_, 540) => (2, false, HEADER2_BYTES),
        (n, _) => {
            return Err(header_err(
                path,
                format!("not a NIfTI file: header field `sizeof_hdr` (bytes 0-3) is {n}, expected 348 (NIfTI-1) or 540 (NIfTI-2)"),
            ))
        }
    };
    got += fill(path, r, &mut b[4..len])?;
    if got < len {
        return Err(header_err(
            path,
            format!("file ends after {got} bytes, inside the {len}-byte NIfTI-{version} header"),
        ));
    }
    let f = Fields { b: &b[..len], le };
    if version == 1 {
        parse(path, &f)
    } else {
        parse2(path, &f)
    }
}

/// Reads `r` into `buf` until it is full or the stream ends; the bytes read.
fn fill(path: &Path, r: &mut impl Read, buf: &mut [u8]) -> Result<usize, VolumeError> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => {
                return Err(VolumeError::Data {
                    path: path.to_path_buf(),
                    message: format!("cannot read the NIfTI header: {e}"),
                })
            }
        }
    }
    Ok(got)
}

/// Where a version keeps the fields that are checked, and how wide they are, for
/// the messages: (offset, bytes) of `dim`'s entries, `datatype`, `bitpix`,
/// `vox_offset`.
struct Layout {
    version: u8,
    dim: (usize, usize),
    datatype: usize,
    bitpix: usize,
    vox_offset: (usize, usize),
    header_bytes: usize,
}

const NIFTI1: Layout = Layout {
    version: 1,
    dim: (40, 2),
    datatype: 70,
    bitpix: 72,
    vox_offset: (108, 4),
    header_bytes: HEADER_BYTES,
};

const NIFTI2: Layout = Layout {
    version: 2,
    dim: (16, 8),
    datatype: 12,
    bitpix: 14,
    vox_offset: (168, 8),
    header_bytes: HEADER2_BYTES,
};

/// `bytes A-B` of a field of `width` bytes at `at`.
fn bytes(at: usize, width: usize) -> String {
    format!("bytes {at}-{}", at + width - 1)
}

/// A NIfTI-1 header's fields.
fn parse(path: &Path, f: &Fields<'_>) -> Result<NiftiHeader, VolumeError> {
    let magic = &f.b[344..348];
    match magic {
        b"n+1\0" => {}
        b"ni1\0" => {
            return Err(unsupported(
                path,
                "magic \"ni1\": the header of a .hdr/.img pair; only single-file NIfTI-1 (.nii, .nii.gz, magic \"n+1\") is read: convert it (e.g. nibabel: nib.save(nib.load('x.hdr'), 'x.nii'))".into(),
            ))
        }
        _ => {
            return Err(header_err(
                path,
                format!(
                    "header field `magic` (bytes 344-347) is {:?}, expected \"n+1\" (a single-file NIfTI-1)",
                    String::from_utf8_lossy(magic)
                ),
            ))
        }
    }
    let h = NiftiHeader {
        version: 1,
        little_endian: f.le,
        ndim: 0,
        dims: [1; 7],
        scalar_type: ScalarType::Uint8,
        pixdim: std::array::from_fn(|i| f.f32(76 + 4 * i)),
        vox_offset: 0,
        scl: [f.f32(112), f.f32(116)],
        codes: [i32::from(f.i16(252)), i32::from(f.i16(254))],
        quatern: std::array::from_fn(|i| f.f32(256 + 4 * i)),
        srow: std::array::from_fn(|r| std::array::from_fn(|c| f.f32(280 + 16 * r + 4 * c))),
        xyzt_units: i32::from(f.b[123]),
        descrip: f.text(148, 80),
        intent_name: f.text(328, 16),
    };
    let dim: [i64; 8] = std::array::from_fn(|i| i64::from(f.i16(40 + 2 * i)));
    checked(path, &NIFTI1, h, dim, f.i16(70), f.i16(72), f.f32(108))
}

/// A NIfTI-2 header's fields (`nifti2.h`: magic after `sizeof_hdr`, 64-bit sizes).
fn parse2(path: &Path, f: &Fields<'_>) -> Result<NiftiHeader, VolumeError> {
    let magic = &f.b[4..12];
    match (&magic[..4], &magic[4..]) {
        (b"n+2\0", b"\r\n\x1a\n") => {}
        (b"n+2\0", _) => {
            return Err(header_err(
                path,
                format!(
                    "header field `magic` (bytes 4-11) is {magic:?}: \"n+2\" without its check bytes \\r\\n\\x1a\\n, the mark of a file copied as text (line endings changed): copy it again in binary mode"
                ),
            ))
        }
        (b"ni2\0", _) => {
            return Err(unsupported(
                path,
                "magic \"ni2\": the header of a NIfTI-2 .hdr/.img pair; only single-file NIfTI-2 (.nii, .nii.gz, magic \"n+2\") is read: convert it (e.g. nibabel: nib.save(nib.load('x.hdr'), 'x.nii'))".into(),
            ))
        }
        _ => {
            return Err(header_err(
                path,
                format!(
                    "header field `magic` (bytes 4-11) is {:?}, expected \"n+2\" (a single-file NIfTI-2)",
                    String::from_utf8_lossy(&magic[..4])
                ),
            ))
        }
    }
    let h = NiftiHeader {
        version: 2,
        little_endian: f.le,
        ndim: 0,
        dims: [1; 7],
        scalar_type: ScalarType::Uint8,
        pixdim: std::array::from_fn(|i| f.f64(104 + 8 * i)),
        vox_offset: 0,
        scl: [f.f64(176), f.f64(184)],
        codes: [f.i32(344), f.i32(348)],
        quatern: std::array::from_fn(|i| f.f64(352 + 8 * i)),
        srow: std::array::from_fn(|r| std::array::from_fn(|c| f.f64(400 + 32 * r + 8 * c))),
        xyzt_units: f.i32(500),
        descrip: f.text(240, 80),
        intent_name: f.text(508, 16),
    };
    let dim: [i64; 8] = std::array::from_fn(|i| f.i64(16 + 8 * i));
    // (a whole number of bytes either way; beyond 2^53 the check below refuses it)
    let off = f.i64(168) as f64;
    checked(path, &NIFTI2, h, dim, f.i16(12), f.i16(14), off)
}

/// `h` with its sizes, type and data offset filled in from the raw `dim`,
/// `datatype`, `bitpix` and `vox_offset`, each checked, with the messages naming
/// the field and its bytes in version `at`'s layout.
fn checked(
    path: &Path,
    at: &Layout,
    mut h: NiftiHeader,
    dim: [i64; 8],
    code: i16,
    bitpix: i16,
    off: f64,
) -> Result<NiftiHeader, VolumeError> {
    let (d0, dw) = at.dim;
    let ndim = dim[0];
    if !(1..=7).contains(&ndim) {
        return Err(header_err(
            path,
            format!(
                "header field `dim[0]` (number of axes, {}) is {ndim}, expected 1 to 7",
                bytes(d0, dw)
            ),
        ));
    }
    let ndim = ndim as usize;
    let mut dims = [1usize; 7];
    for (i, d) in dims.iter_mut().enumerate().take(ndim) {
        let v = dim[i + 1];
        if !(1..=i64::from(i32::MAX)).contains(&v) {
            return Err(header_err(
                path,
                format!(
                    "header field `dim[{}]` (size of axis {}, {}) is {v}, expected 1 to {}",
                    i + 1,
                    i + 1,
                    bytes(d0 + dw * (i + 1), dw),
                    i32::MAX
                ),
            ));
        }
        *d = v as usize;
    }
    if let Some(i) = (4..7).find(|&i| dims[i] > 1) {
        return Err(unsupported(
            path,
            format!(
                "dim = {:?}: axis {} (dim[{}] = {}) beyond time is not supported: volcast renders one 3D volume of a 3D or 4D file",
                &dims[..ndim],
                i + 1,
                i + 1,
                dims[i]
            ),
        ));
    }
    let scalar_type = datatype(code).map_err(|name| {
        unsupported(
            path,
            format!(
                "header field `datatype` ({}) is {name}: volcast renders scalar volumes of uint8, int8, uint16, int16, uint32, int32, uint64, int64, float32 or float64",
                bytes(at.datatype, 2)
            ),
        )
    })?;
    if bitpix as usize != scalar_type.size() * 8 {
        return Err(header_err(
            path,
            format!(
                "header field `bitpix` ({}) is {bitpix}, but datatype {code} ({scalar_type}) has {} bits per voxel",
                bytes(at.bitpix, 2),
                scalar_type.size() * 8
            ),
        ));
    }
    let first = at.header_bytes as f64;
    if !(off.is_finite() && off >= first && off.fract() == 0.0 && off < 1e15) {
        return Err(header_err(
            path,
            format!(
                "header field `vox_offset` ({}) is {off}, expected a whole number of bytes, at least {} (where the voxels start)",
                bytes(at.vox_offset.0, at.vox_offset.1),
                at.header_bytes
            ),
        ));
    }
    h.version = at.version;
    h.ndim = ndim;
    h.dims = dims;
    h.scalar_type = scalar_type;
    h.vox_offset = off as u64;
    Ok(h)
}

impl NiftiHeader {
    /// Voxels along x, y, z (`dim[1..=3]`).
    pub fn sizes(&self) -> [usize; 3] {
        [self.dims[0], self.dims[1], self.dims[2]]
    }

    /// Number of 3D volumes (`dim[4]`, 1 for a 3D file).
    pub fn volumes(&self) -> usize {
        self.dims[3]
    }

    /// `scl_slope` and `scl_inter` as a map; the identity when the slope is 0 or not
    /// finite (the standard's "no scaling").
    pub fn rescale(&self) -> Rescale {
        let [slope, inter] = self.scl;
        if slope == 0.0 || !slope.is_finite() {
            return Rescale::IDENTITY;
        }
        Rescale {
            slope,
            intercept: if inter.is_finite() { inter } else { 0.0 },
        }
    }

    /// Which transform places the voxels: `"sform"`, `"qform"` or `"pixdim"`.
    pub fn transform(&self) -> &'static str {
        match self.codes {
            [_, s] if s > 0 => "sform",
            [q, _] if q > 0 => "qform",
            _ => "pixdim",
        }
    }

    /// Voxel sizes along x, y, z for the qform and method 1 (`nifti1_io`: a size that
    /// is not positive counts as 1).
    fn voxel_sizes(&self) -> [f64; 3] {
        [1, 2, 3].map(|i| {
            let d = self.pixdim[i];
            if d > 0.0 {
                d
            } else {
                1.0
            }
        })
    }

    /// The index-to-world map (NIfTI's RAS+ world, kept as it is).
    pub fn geometry(&self, path: &Path) -> Result<Geometry, VolumeError> {
        let g = match self.transform() {
            "sform" => {
                let r = self.srow;
                Geometry {
                    origin: DVec3::new(r[0][3], r[1][3], r[2][3]),
                    axes: std::array::from_fn(|c| DVec3::new(r[0][c], r[1][c], r[2][c])),
                }
            }
            "qform" => self.qform(),
            _ => Geometry::from_spacing(self.voxel_sizes()),
        };
        if !g.is_valid() {
            return Err(header_err(
                path,
                format!(
                    "the {} (sform_code {}, qform_code {}) gives degenerate axes {:?}, {:?}, {:?} with origin {:?}: they must be finite, non-zero and independent",
                    self.transform(),
                    self.codes[1],
                    self.codes[0],
                    g.axes[0].to_array(),
                    g.axes[1].to_array(),
                    g.axes[2].to_array(),
                    g.origin.to_array()
                ),
            ));
        }
        Ok(g)
    }

    /// The qform: rotation from the quaternion (b, c, d; a from unit length), voxel
    /// sizes, `qfac = pixdim[0]` (-1 flips the third axis), offset (`nifti1_io`'s
    /// `nifti_quatern_to_mat44`).
    fn qform(&self) -> Geometry {
        let [b, c, d, x, y, z] = self.quatern;
        let (mut a, mut b, mut c, mut d) = (1.0 - (b * b + c * c + d * d), b, c, d);
        if a < 1e-7 {
            let s = 1.0 / (b * b + c * c + d * d).sqrt();
            (a, b, c, d) = (0.0, b * s, c * s, d * s);
        } else {
            a = a.sqrt();
        }
        let rotation = DMat3::from_cols(
            DVec3::new(
                a * a + b * b - c * c - d * d,
                2.0 * (b * c + a * d),
                2.0 * (b * d - a * c),
            ),
            DVec3::new(
                2.0 * (b * c - a * d),
                a * a + c * c - b * b - d * d,
                2.0 * (c * d + a * b),
            ),
            DVec3::new(
                2.0 * (b * d + a * c),
                2.0 * (c * d - a * b),
                a * a + d * d - c * c - b * b,
            ),
        );
        let [dx, dy, mut dz] = self.voxel_sizes();
        if self.pixdim[0] < 0.0 {
            dz = -dz;
        }
        Geometry {
            origin: DVec3::new(x, y, z),
            axes: [
                rotation.x_axis * dx,
                rotation.y_axis * dy,
                rotation.z_axis * dz,
            ],
        }
    }

    /// Descriptive fields for `volcast info`.
    pub fn fields(&self) -> Vec<(String, String)> {
        let mut f = vec![
            ("format".to_string(), format!("NIfTI-{}", self.version)),
            (
                "space".to_string(),
                "RAS (NIfTI world coordinates, kept as they are)".to_string(),
            ),
            (
                "transform".to_string(),
                format!(
                    "{} (sform_code {}, qform_code {})",
                    self.transform(),
                    self.codes[1],
                    self.codes[0]
                ),
            ),
        ];
        if self.volumes() > 1 {
            f.push(("volumes".into(), format!("{} (4D)", self.volumes())));
        }
        let r = self.rescale();
        if !r.is_identity() {
            f.push((
                "rescale".into(),
                format!(
                    "value = {} * stored + {} (scl_slope, scl_inter)",
                    r.slope, r.intercept
                ),
            ));
        }
        let units = match self.xyzt_units & 7 {
            1 => "m",
            2 => "mm",
            3 => "um",
            _ => "",
        };
        if !units.is_empty() {
            f.push(("space units".into(), units.into()));
        }
        if !self.descrip.is_empty() {
            f.push(("descrip".into(), self.descrip.clone()));
        }
        if !self.intent_name.is_empty() {
            f.push(("intent".into(), self.intent_name.clone()));
        }
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> [u8; HEADER_BYTES] {
        let mut b = [0u8; HEADER_BYTES];
        b[0..4].copy_from_slice(&348i32.to_le_bytes());
        for (i, d) in [3i16, 4, 3, 2, 1, 1, 1, 1].iter().enumerate() {
            b[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_le_bytes());
        }
        b[70..72].copy_from_slice(&4i16.to_le_bytes());
        b[72..74].copy_from_slice(&16i16.to_le_bytes());
        for (i, p) in [1f32, 2.0, 3.0, 4.0].iter().enumerate() {
            b[76 + 4 * i..80 + 4 * i].copy_from_slice(&p.to_le_bytes());
        }
        b[108..112].copy_from_slice(&352f32.to_le_bytes());
        b[344..348].copy_from_slice(b"n+1\0");
        b
    }

    fn parse_bytes(b: &[u8]) -> Result<NiftiHeader, VolumeError> {
        read_header(Path::new("t.nii"), &mut &b[..])
    }

    #[test]
    fn method_one_and_qform() {
        let mut b = header();
        let h = parse_bytes(&b).unwrap();
        assert_eq!(h.sizes(), [4, 3, 2]);
        assert_eq!(h.transform(), "pixdim");
        let g = h.geometry(Path::new("t.nii")).unwrap();
        assert_eq!(g, Geometry::from_spacing([2.0, 3.0, 4.0]));
        // qform: 180 degrees about z (b = c = 0, d = 1 -> a = 0), qfac -1
        b[252..254].copy_from_slice(&1i16.to_le_bytes());
        b[264..268].copy_from_slice(&1f32.to_le_bytes());
        b[76..80].copy_from_slice(&(-1f32).to_le_bytes());
        b[268..272].copy_from_slice(&5f32.to_le_bytes());
        let g = parse_bytes(&b)
            .unwrap()
            .geometry(Path::new("t.nii"))
            .unwrap();
        assert_eq!(g.axes[0], DVec3::new(-2.0, 0.0, 0.0));
        assert_eq!(g.axes[1], DVec3::new(0.0, -3.0, 0.0));
        assert_eq!(g.axes[2], DVec3::new(0.0, 0.0, -4.0));
        assert_eq!(g.origin, DVec3::new(5.0, 0.0, 0.0));
    }

    #[test]
    fn bad_fields_are_named() {
        let e = |edit: &dyn Fn(&mut [u8; HEADER_BYTES])| {
            let mut b = header();
            edit(&mut b);
            parse_bytes(&b).unwrap_err().to_string()
        };
        assert!(e(&|b| b[344] = b'x').contains("`magic`"));
        assert!(e(&|b| b[40] = 9).contains("`dim[0]`"));
        assert!(e(&|b| b[72] = 8).contains("`bitpix`"));
        assert!(e(&|b| b[70..72].copy_from_slice(&128i16.to_le_bytes())).contains("RGB24"));
        assert!(e(&|b| b[108..112].copy_from_slice(&f32::NAN.to_le_bytes())).contains("vox_offset"));
        assert!(e(&|b| b[0..4].copy_from_slice(&540i32.to_le_bytes())).contains("NIfTI-2"));
        assert!(e(&|b| {
            b[40] = 5;
            b[50..52].copy_from_slice(&3i16.to_le_bytes());
        })
        .contains("beyond time"));
        let short = parse_bytes(&header()[..100]).unwrap_err().to_string();
        assert!(short.contains("ends after 100 bytes"), "{short}");
    }

    #[test]
    fn big_endian_headers() {
        let mut b = header();
        b[0..4].copy_from_slice(&348i32.to_be_bytes());
        for (i, d) in [3i16, 4, 3, 2, 1, 1, 1, 1].iter().enumerate() {
            b[40 + 2 * i..42 + 2 * i].copy_from_slice(&d.to_be_bytes());
        }
        b[70..72].copy_from_slice(&4i16.to_be_bytes());
        b[72..74].copy_from_slice(&16i16.to_be_bytes());
        b[108..112].copy_from_slice(&352f32.to_be_bytes());
        let h = parse_bytes(&b).unwrap();
        assert!(!h.little_endian);
        assert_eq!(h.sizes(), [4, 3, 2]);
    }

    /// A little-endian NIfTI-2 header: int16 4 x 3 x 2, pixdim 2 3 4, data at 544.
    fn header2() -> [u8; HEADER2_BYTES] {
        let mut b = [0u8; HEADER2_BYTES];
        b[0..4].copy_from_slice(&540i32.to_le_bytes());
        b[4..12].copy_from_slice(b"n+2\0\r\n\x1a\n");
        b[12..14].copy_from_slice(&4i16.to_le_bytes());
        b[14..16].copy_from_slice(&16i16.to_le_bytes());
        for (i, d) in [3i64, 4, 3, 2, 1, 1, 1, 1].iter().enumerate() {
            b[16 + 8 * i..24 + 8 * i].copy_from_slice(&d.to_le_bytes());
        }
        for (i, p) in [1f64, 2.0, 3.0, 4.0].iter().enumerate() {
            b[104 + 8 * i..112 + 8 * i].copy_from_slice(&p.to_le_bytes());
        }
        b[168..176].copy_from_slice(&544i64.to_le_bytes());
        b
    }

    #[test]
    fn nifti2_fields_are_read_at_their_offsets_and_named_when_bad() {
        let mut b = header2();
        let h = parse_bytes(&b).unwrap();
        assert_eq!((h.version, h.sizes(), h.vox_offset), (2, [4, 3, 2], 544));
        assert_eq!(h.scalar_type, ScalarType::Int16);
        let g = h.geometry(Path::new("t.nii")).unwrap();
        assert_eq!(g, Geometry::from_spacing([2.0, 3.0, 4.0]));
        // an sform in doubles, kept to the last bit
        b[348..352].copy_from_slice(&1i32.to_le_bytes());
        let third = 1.0f64 / 3.0;
        for (r, row) in [
            [third, 0.0, 0.0, 10.0],
            [0.0, 2.0, 0.0, 20.0],
            [0.0, 0.0, 3.0, 30.0],
        ]
        .iter()
        .enumerate()
        {
            for (c, v) in row.iter().enumerate() {
                b[400 + 32 * r + 8 * c..408 + 32 * r + 8 * c].copy_from_slice(&v.to_le_bytes());
            }
        }
        let g = parse_bytes(&b)
            .unwrap()
            .geometry(Path::new("t.nii"))
            .unwrap();
        assert_eq!(g.axes[0], DVec3::new(third, 0.0, 0.0));
        assert_eq!(g.origin, DVec3::new(10.0, 20.0, 30.0));
        let e = |edit: &dyn Fn(&mut [u8; HEADER2_BYTES])| {
            let mut b = header2();
            edit(&mut b);
            parse_bytes(&b).unwrap_err().to_string()
        };
        let text_copy = e(&|b| b[8] = b'\n');
        assert!(text_copy.contains("copied as text"), "{text_copy}");
        assert!(e(&|b| b[4] = b'x').contains("`magic` (bytes 4-11)"));
        assert!(e(&|b| b[4..8].copy_from_slice(b"ni2\0")).contains(".hdr/.img pair"));
        let d0 = e(&|b| b[16..24].copy_from_slice(&9i64.to_le_bytes()));
        assert!(
            d0.contains("`dim[0]` (number of axes, bytes 16-23) is 9"),
            "{d0}"
        );
        let d2 = e(&|b| b[32..40].copy_from_slice(&(1i64 << 40).to_le_bytes()));
        assert!(
            d2.contains("`dim[2]` (size of axis 2, bytes 32-39)"),
            "{d2}"
        );
        let off = e(&|b| b[168..176].copy_from_slice(&400i64.to_le_bytes()));
        assert!(
            off.contains("`vox_offset` (bytes 168-175) is 400") && off.contains("at least 540"),
            "{off}"
        );
        assert!(e(&|b| b[14] = 8).contains("`bitpix` (bytes 14-15)"));
        let short = parse_bytes(&header2()[..400]).unwrap_err().to_string();
        assert!(
            short.contains("ends after 400 bytes, inside the 540-byte NIfTI-2 header"),
            "{short}"
        );
        // big-endian
        let mut be = [0u8; HEADER2_BYTES];
        be[0..4].copy_from_slice(&540i32.to_be_bytes());
        be[4..12].copy_from_slice(b"n+2\0\r\n\x1a\n");
        be[12..14].copy_from_slice(&4i16.to_be_bytes());
        be[14..16].copy_from_slice(&16i16.to_be_bytes());
        for (i, d) in [3i64, 4, 3, 2, 1, 1, 1, 1].iter().enumerate() {
            be[16 + 8 * i..24 + 8 * i].copy_from_slice(&d.to_be_bytes());
        }
        be[168..176].copy_from_slice(&544i64.to_be_bytes());
        let h = parse_bytes(&be).unwrap();
        assert!(!h.little_endian);
        assert_eq!(h.sizes(), [4, 3, 2]);
    }

    #[test]
    fn slope_zero_means_no_scaling() {
        let mut b = header();
        assert!(parse_bytes(&b).unwrap().rescale().is_identity());
        b[112..116].copy_from_slice(&2f32.to_le_bytes());
        b[116..120].copy_from_slice(&(-3f32).to_le_bytes());
        assert_eq!(
            parse_bytes(&b).unwrap().rescale(),
            Rescale {
                slope: 2.0,
                intercept: -3.0
            }
        );
    }
}
