//! The 348 bytes of a NIfTI-1 header: fields by byte offset, in the byte order that
//! `sizeof_hdr` reveals, checked one by one, and the index-to-world map they define
//! (the sform when `sform_code > 0`, else the qform when `qform_code > 0`, else the
//! voxel sizes: "method 1" of `nifti1.h`).

use std::io::Read;
use std::path::Path;

use glam::{DMat3, DVec3};

use crate::volume::{Geometry, Rescale, ScalarType, VolumeError};

/// Bytes of a NIfTI-1 header.
pub(super) const HEADER_BYTES: usize = 348;

/// What the reader uses of a NIfTI-1 header, checked.
#[derive(Clone, Debug, PartialEq)]
pub struct NiftiHeader {
    /// Byte order of the header and the data.
    pub little_endian: bool,
    /// `dim[0]`: number of axes (1 to 7).
    pub ndim: usize,
    /// `dim[1..=7]`, 1 beyond `ndim`.
    pub dims: [usize; 7],
    /// `datatype` as a scalar type.
    pub scalar_type: ScalarType,
    /// `pixdim[0..8]` (`pixdim[0]` is qfac).
    pub pixdim: [f32; 8],
    /// `vox_offset`: where the data starts in the file.
    pub vox_offset: u64,
    /// `scl_slope`, `scl_inter` as stored.
    pub scl: [f32; 2],
    /// `qform_code`, `sform_code`.
    pub codes: [i16; 2],
    /// `quatern_b, c, d`, then `qoffset_x, y, z`.
    pub quatern: [f32; 6],
    /// `srow_x`, `srow_y`, `srow_z`.
    pub srow: [[f32; 4]; 3],
    /// `xyzt_units`.
    pub xyzt_units: u8,
    /// `descrip`.
    pub descrip: String,
    /// `intent_name`.
    pub intent_name: String,
}

fn header_err(path: &Path, message: String) -> VolumeError {
    VolumeError::Header {
        path: path.to_path_buf(),
        line: 0,
        message,
    }
}

fn unsupported(path: &Path, message: String) -> VolumeError {
    VolumeError::Unsupported {
        path: path.to_path_buf(),
        message,
    }
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
        other => return Err(format!("{other} (not a NIfTI-1 datatype)")),
    })
}

/// Reads the fields of a header in one byte order.
struct Fields<'a> {
    b: &'a [u8; HEADER_BYTES],
    le: bool,
}

impl Fields<'_> {
    fn i16(&self, at: usize) -> i16 {
        let v = [self.b[at], self.b[at + 1]];
        if self.le {
            i16::from_le_bytes(v)
        } else {
            i16::from_be_bytes(v)
        }
    }

    fn f32(&self, at: usize) -> f32 {
        let v = [self.b[at], self.b[at + 1], self.b[at + 2], self.b[at + 3]];
        if self.le {
            f32::from_le_bytes(v)
        } else {
            f32::from_be_bytes(v)
        }
    }

    fn text(&self, at: usize, len: usize) -> String {
        let s = &self.b[at..at + len];
        let end = s.iter().position(|&c| c == 0).unwrap_or(len);
        String::from_utf8_lossy(&s[..end]).trim().to_string()
    }
}

/// Reads and checks the header at the start of `r` (the file, or its gzip stream).
pub(super) fn read_header(path: &Path, r: &mut impl Read) -> Result<NiftiHeader, VolumeError> {
    let mut b = [0u8; HEADER_BYTES];
    let mut got = 0;
    while got < HEADER_BYTES {
        match r.read(&mut b[got..]) {
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
    if got < 4 {
        return Err(header_err(
            path,
            format!("file has {got} bytes: not a NIfTI file (expected a 348-byte header)"),
        ));
    }
    let size = [b[0], b[1], b[2], b[3]];
    let le = match (i32::from_le_bytes(size), i32::from_be_bytes(size)) {
        (348, _) => true,
        (_, 348) => false,
        (540, _) | (_, 540) => {
            return Err(unsupported(
                path,
                "NIfTI-2 (sizeof_hdr 540) is not supported: convert it to NIfTI-1 (nibabel, or ITK/SimpleITK writing .nii)".into(),
            ))
        }
        (n, _) => {
            return Err(header_err(
                path,
                format!("not a NIfTI-1 file: header field `sizeof_hdr` (bytes 0-3) is {n}, expected 348"),
            ))
        }
    };
    if got < HEADER_BYTES {
        return Err(header_err(
            path,
            format!("file ends after {got} bytes, inside the {HEADER_BYTES}-byte NIfTI-1 header"),
        ));
    }
    parse(path, &Fields { b: &b, le })
}

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
    let ndim = f.i16(40);
    if !(1..=7).contains(&ndim) {
        return Err(header_err(
            path,
            format!(
                "header field `dim[0]` (number of axes, bytes 40-41) is {ndim}, expected 1 to 7"
            ),
        ));
    }
    let ndim = ndim as usize;
    let mut dims = [1usize; 7];
    for (i, d) in dims.iter_mut().enumerate().take(ndim) {
        let v = f.i16(42 + 2 * i);
        if v < 1 {
            return Err(header_err(
                path,
                format!(
                    "header field `dim[{}]` (size of axis {}) is {v}, expected at least 1",
                    i + 1,
                    i + 1
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
    let code = f.i16(70);
    let scalar_type = datatype(code).map_err(|name| {
        unsupported(
            path,
            format!(
                "header field `datatype` (bytes 70-71) is {name}: volcast renders scalar volumes of uint8, int8, uint16, int16, uint32, int32, uint64, int64, float32 or float64"
            ),
        )
    })?;
    let bitpix = f.i16(72);
    if bitpix as usize != scalar_type.size() * 8 {
        return Err(header_err(
            path,
            format!(
                "header field `bitpix` (bytes 72-73) is {bitpix}, but datatype {code} ({scalar_type}) has {} bits per voxel",
                scalar_type.size() * 8
            ),
        ));
    }
    let pixdim: [f32; 8] = std::array::from_fn(|i| f.f32(76 + 4 * i));
    let off = f.f32(108);
    if !(off.is_finite() && off >= HEADER_BYTES as f32 && off.fract() == 0.0 && off < 1e15) {
        return Err(header_err(
            path,
            format!(
                "header field `vox_offset` (bytes 108-111) is {off}, expected a whole number of bytes, at least {HEADER_BYTES} (where the voxels start)"
            ),
        ));
    }
    let codes = [f.i16(252), f.i16(254)];
    Ok(NiftiHeader {
        little_endian: f.le,
        ndim,
        dims,
        scalar_type,
        pixdim,
        vox_offset: off as u64,
        scl: [f.f32(112), f.f32(116)],
        codes,
        quatern: std::array::from_fn(|i| f.f32(256 + 4 * i)),
        srow: std::array::from_fn(|r| std::array::from_fn(|c| f.f32(280 + 16 * r + 4 * c))),
        xyzt_units: f.b[123],
        descrip: f.text(148, 80),
        intent_name: f.text(328, 16),
    })
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
        let [slope, inter] = self.scl.map(f64::from);
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
            let d = f64::from(self.pixdim[i]);
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
                let r = self.srow.map(|row| row.map(f64::from));
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
        let [b, c, d, x, y, z] = self.quatern.map(f64::from);
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
            ("format".to_string(), "NIfTI-1".to_string()),
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
