//! `[volume]`: a volume file (NRRD, NIfTI, MetaImage, TIFF), a DICOM folder, a TIFF
//! folder or glob, a raw file or a synthetic field, its window and crop.

use std::ops::Range;
use std::path::PathBuf;

use toml::Spanned;

use super::Resolver;
use crate::number::shown;
use crate::scene::diag::{quoted_list, suggest};
use crate::scene::schema::{MatrixValue, Sp, VolumeTable, VolumeTables};
use crate::scene::{SceneVolume, Transform, Units, VolumeSpec};
use crate::volume::dicom::DicomSpec;
use crate::volume::nifti::NiftiSpec;
use crate::volume::raw::RawSpec;
use crate::volume::synthetic::Field;
use crate::volume::tiff::TiffSpec;
use crate::volume::FileFormat;
use crate::volume::{ScalarType, Synthetic, VolumeSource};

/// The format of a volume file, from `format` or the file's name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Format {
    Nrrd,
    Nifti,
    MetaImage,
    Dicom,
    Tiff,
    Raw,
}

impl From<FileFormat> for Format {
    fn from(f: FileFormat) -> Format {
        match f {
            FileFormat::Nrrd => Format::Nrrd,
            FileFormat::Nifti => Format::Nifti,
            FileFormat::MetaImage => Format::MetaImage,
            FileFormat::Tiff => Format::Tiff,
            FileFormat::Dicom => Format::Dicom,
        }
    }
}

impl Resolver<'_> {
    /// The scene's volumes: `[volume]`, or each `[[volume]]` table with its name
    /// and transform. Leaves the first volume's units and window as the scene's.
    pub(super) fn volumes(&mut self, t: &Spanned<VolumeTables>) -> Vec<SceneVolume> {
        let tables: Vec<(Range<usize>, &VolumeTable)> = match t.get_ref() {
            VolumeTables::One(v) => vec![(t.span(), v)],
            VolumeTables::Many(list) => list.iter().map(|v| (v.span(), v.get_ref())).collect(),
        };
        let many = matches!(t.get_ref(), VolumeTables::Many(_));
        if tables.is_empty() {
            self.err(t.span(), "the scene has no volume: give a [volume] table, or [[volume]] tables each with a `name`");
        }
        let mut volumes: Vec<SceneVolume> = Vec::new();
        let mut contexts = Vec::new();
        for (span, v) in tables {
            let name = match &v.name {
                Some(n) if valid_volume_name(n.get_ref()) => n.get_ref().clone(),
                Some(n) => {
                    self.err(
                        n.span(),
                        format!(
                            "name = \"{}\": expected a volume name of letters, digits, '-' and '_'",
                            n.get_ref()
                        ),
                    );
                    n.get_ref().clone()
                }
                None if many => {
                    self.err(span.clone(), "[[volume]] needs `name`: passes name the volume they read (`volume = \"NAME\"`)");
                    format!("volume{}", volumes.len() + 1)
                }
                None => "volume".to_string(),
            };
            if let (Some(other), Some(n)) = (volumes.iter().find(|o| o.name == name), &v.name) {
                let _ = other;
                self.err(n.span(), format!("two volumes are named `{name}`: passes could not tell them apart; give each [[volume]] its own `name`"));
            }
            let transform = v.transform.as_ref().and_then(|m| self.transform(&name, m));
            let spec = self.volume(span, v);
            contexts.push((self.units, self.window));
            volumes.push(SceneVolume {
                name,
                spec,
                transform,
            });
        }
        if let Some(&(units, window)) = contexts.first() {
            self.units = units;
            self.window = window;
        }
        self.contexts = contexts;
        volumes
    }

    /// `transform`: a 4 x 4 row-major affine matrix (four rows of four numbers, or
    /// sixteen), finite, with an invertible linear part and a last row of
    /// `[0, 0, 0, 1]`.
    fn transform(&mut self, volume: &str, m: &Spanned<MatrixValue>) -> Option<Transform> {
        let numbers: Option<Vec<f64>> = match m.get_ref() {
            MatrixValue::Rows(rows) if rows.len() == 4 && rows.iter().all(|r| r.len() == 4) => {
                Some(rows.iter().flatten().copied().collect())
            }
            MatrixValue::Flat(v) if v.len() == 16 => Some(v.clone()),
            _ => None,
        };
        let at = format!("volume `{volume}`: transform");
        let Some(a) = numbers else {
            self.err(m.span(), format!("{at}: expected a 4 x 4 row-major matrix, four rows of four numbers ([[1, 0, 0, tx], [0, 1, 0, ty], [0, 0, 1, tz], [0, 0, 0, 1]]) or sixteen numbers"));
            return None;
        };
        if !a.iter().all(|x| x.is_finite()) {
            self.err(
                m.span(),
                format!("{at}: every entry must be a finite number (it has NaN or infinity)"),
            );
            return None;
        }
        if a[12..] != [0.0, 0.0, 0.0, 1.0] {
            self.err(m.span(), format!("{at}: its last row is [{}, {}, {}, {}], but a registration is affine: the last row must be [0, 0, 0, 1] (projective maps are not supported)", shown(a[12]), shown(a[13]), shown(a[14]), shown(a[15])));
            return None;
        }
        let matrix =
            glam::DMat3::from_cols_array(&[a[0], a[4], a[8], a[1], a[5], a[9], a[2], a[6], a[10]]);
        let placed = Transform {
            matrix,
            translation: glam::DVec3::new(a[3], a[7], a[11]),
        };
        // the same test as the file's own axes
        if !placed.place(&crate::volume::Geometry::default()).is_valid() {
            self.err(m.span(), format!("{at}: its 3 x 3 part is not invertible (determinant {}): a registration must keep the volume three-dimensional", shown(matrix.determinant())));
            return None;
        }
        Some(placed)
    }

    pub(super) fn volume(&mut self, span: Range<usize>, v: &VolumeTable) -> VolumeSpec {
        let window = self.window("window", &v.window);
        let raw_keys = [
            ("sizes", v.sizes.as_ref().map(|s| s.span())),
            ("type", v.ty.as_ref().map(|s| s.span())),
            ("endian", v.endian.as_ref().map(|s| s.span())),
            ("spacing", v.spacing.as_ref().map(|s| s.span())),
            ("offset", v.offset.as_ref().map(|s| s.span())),
        ];
        let placeholder = VolumeSource::Synthetic(Synthetic::new(Field::MarschnerLobb, [2, 2, 2]));
        let source = match (&v.path, &v.synthetic) {
            (Some(p), Some(s)) => {
                self.err(s.span(), "give either `path` or `synthetic`, not both");
                let _ = p;
                placeholder
            }
            (None, None) => {
                self.err(span.clone(), "[volume] needs `path` (a .nrrd/.nhdr, .nii/.nii.gz, .mha/.mhd, .tif/.tiff or raw file) or `synthetic` (gaussian, ball, sphere-distance, marschner-lobb, blobs)");
                placeholder
            }
            (None, Some(s)) => {
                self.not_for("by synthetic volumes (raw files only)", &raw_keys[2..]);
                if let Some(i) = &v.index {
                    self.err(
                        i.span(),
                        "`index` is only used by NIfTI files (.nii, .nii.gz) and TIFF time series",
                    );
                }
                if let Some(s) = &v.series {
                    self.err(
                        s.span(),
                        "`series` is only used by DICOM folders (format = \"dicom\")",
                    );
                }
                if let Some(c) = &v.channel {
                    self.err(
                        c.span(),
                        "`channel` is only used by multi-channel TIFF files",
                    );
                }
                if let Some(f) = &v.format {
                    self.err(f.span(), "`format` is not used by synthetic volumes");
                }
                self.synthetic(v, s).unwrap_or(placeholder)
            }
            (Some(p), None) => self.file_source(v, p, &raw_keys).unwrap_or(placeholder),
        };
        let window = window.or(match source {
            VolumeSource::Synthetic(s) => Some([0.0, s.max_value()]),
            _ => None,
        });
        let crop = v.crop.as_ref().and_then(|c| {
            let r = *c.get_ref();
            if r.iter().all(|&[a, b]| 0 <= a && a <= b && b <= (1 << 31)) {
                Some(r.map(|[a, b]| [a as usize, b as usize]))
            } else {
                self.err(c.span(), format!(
                    "crop = {r:?}: expected [[x0, x1], [y0, y1], [z0, z1]], voxel index ranges with 0 <= low <= high"
                ));
                None
            }
        });
        let data = self.choice(
            "units",
            &v.units,
            &[("normalised", false), ("data", true)],
            false,
        );
        let units = match (data, v.window.as_ref(), window) {
            (false, _, _) => Units::Normalised,
            (true, Some(_), Some([lo, hi])) => Units::Data { lo, hi },
            // a bad window is reported already
            (true, Some(_), None) => Units::Normalised,
            (true, None, _) => {
                let span = v.units.as_ref().map_or(span.clone(), |u| u.span());
                self.err(
                    span,
                    "units = \"data\" needs `window = [lo, hi]` in [volume]: the data values that \
                     thresholds, iso values and transfer-function knots are measured against",
                );
                Units::Normalised
            }
        };
        self.units = units;
        self.window = window;
        VolumeSpec {
            source,
            window,
            units,
            crop,
        }
    }

    pub(super) fn synthetic(
        &mut self,
        v: &VolumeTable,
        s: &Spanned<String>,
    ) -> Option<VolumeSource> {
        let kinds = [
            "gaussian",
            "ball",
            "sphere-distance",
            "marschner-lobb",
            "blobs",
        ];
        let sizes = self.sizes(&v.sizes, [64, 64, 64], 2);
        let positive = |x: f64| x > 0.0;
        let field = match s.get_ref().as_str() {
            "gaussian" => {
                if let Some(r) = &v.radius {
                    self.err(
                        r.span(),
                        "`radius` is not used by the gaussian field (it takes `sigma`)",
                    );
                }
                Field::Gaussian {
                    sigma: self.number("sigma", &v.sigma, 0.25, positive, "a positive number"),
                }
            }
            "ball" | "sphere-distance" => {
                if let Some(g) = &v.sigma {
                    self.err(
                        g.span(),
                        format!(
                            "`sigma` is not used by the {} field (it takes `radius`)",
                            s.get_ref()
                        ),
                    );
                }
                let ball = s.get_ref() == "ball";
                let radius = self.number(
                    "radius",
                    &v.radius,
                    if ball { 0.5 } else { 1.0 },
                    positive,
                    "a positive number",
                );
                if ball {
                    Field::Ball { radius }
                } else {
                    Field::SphereDistance { radius }
                }
            }
            "marschner-lobb" | "blobs" => {
                for (k, sp) in [("sigma", &v.sigma), ("radius", &v.radius)] {
                    if let Some(sp) = sp {
                        self.err(
                            sp.span(),
                            format!("`{k}` is not used by the {} field", s.get_ref()),
                        );
                    }
                }
                if s.get_ref() == "blobs" {
                    Field::Blobs
                } else {
                    Field::MarschnerLobb
                }
            }
            other => {
                let hint = suggest(other, kinds)
                    .map(|n| format!("; did you mean `{n}`?"))
                    .unwrap_or_default();
                self.err(
                    s.span(),
                    format!(
                        "synthetic = \"{other}\" is not known: expected one of {}{hint}",
                        quoted_list(kinds)
                    ),
                );
                return None;
            }
        };
        let scalar_type = self
            .choice(
                "type",
                &v.ty,
                &[
                    ("float32", Some(ScalarType::Float32)),
                    ("uint8", Some(ScalarType::Uint8)),
                    ("uint16", Some(ScalarType::Uint16)),
                ],
                Some(ScalarType::Float32),
            )
            .unwrap_or(ScalarType::Float32);
        Some(VolumeSource::Synthetic(Synthetic {
            field,
            sizes,
            scalar_type,
        }))
    }

    pub(super) fn sizes(&mut self, v: &Sp<Vec<f64>>, default: [usize; 3], min: i64) -> [usize; 3] {
        /// Largest size per axis (2^31 voxels).
        const MAX: f64 = (1u64 << 31) as f64;
        let Some(s) = v else { return default };
        let shown = |x: f64| {
            if x.fract() == 0.0 && x.abs() < 1e15 {
                format!("{x:.0}")
            } else {
                format!("{x}")
            }
        };
        let list = || {
            s.get_ref()
                .iter()
                .map(|&x| shown(x))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let problem = match s.get_ref().as_slice() {
            [_, _, _] => s.get_ref().iter().find_map(|&x| {
                if !x.is_finite() || x.fract() != 0.0 {
                    Some(format!("{} is not a whole number of voxels", shown(x)))
                } else if x > MAX {
                    Some(format!(
                        "{} is too large: at most {} voxels per axis",
                        shown(x),
                        1u64 << 31
                    ))
                } else if x < min as f64 {
                    Some(format!(
                        "{} is too small: at least {min} voxels per axis",
                        shown(x)
                    ))
                } else {
                    None
                }
            }),
            other => Some(format!(
                "expected three sizes [x, y, z], got {}",
                other.len()
            )),
        };
        match problem {
            None => {
                let a = s.get_ref();
                [a[0] as usize, a[1] as usize, a[2] as usize]
            }
            Some(p) => {
                self.err(s.span(), format!("sizes = [{}]: {p}", list()));
                default
            }
        }
    }

    pub(super) fn file_source(
        &mut self,
        v: &VolumeTable,
        p: &Spanned<String>,
        raw_keys: &[(&str, Option<Range<usize>>)],
    ) -> Option<VolumeSource> {
        for (k, sp) in [("sigma", &v.sigma), ("radius", &v.radius)] {
            if let Some(sp) = sp {
                self.err(
                    sp.span(),
                    format!("`{k}` is only used by synthetic volumes"),
                );
            }
        }
        let path = self.base_dir.join(p.get_ref());
        let has_raw_keys = raw_keys.iter().any(|(_, s)| s.is_some());
        let by_name = match FileFormat::from_path(&path) {
            Some(f) => Some(f.into()),
            None if has_raw_keys => Some(Format::Raw),
            None => None,
        };
        let format = self.choice(
            "format",
            &v.format,
            &[
                ("nrrd", Some(Format::Nrrd)),
                ("nifti", Some(Format::Nifti)),
                ("metaimage", Some(Format::MetaImage)),
                ("dicom", Some(Format::Dicom)),
                ("tiff", Some(Format::Tiff)),
                ("raw", Some(Format::Raw)),
            ],
            by_name,
        );
        let index = v.index.as_ref().and_then(|i| {
            let n = *i.get_ref();
            let frames = matches!(format, Some(Format::Nifti | Format::Tiff));
            if frames && !(0..=i64::from(i16::MAX)).contains(&n) {
                self.err(
                    i.span(),
                    format!("index = {n}: expected the number of a volume of the 4D file (a frame of a TIFF time series), from 0"),
                );
            }
            usize::try_from(n).ok()
        });
        if !matches!(format, Some(Format::Nifti | Format::Tiff)) {
            if let Some(i) = &v.index {
                self.err(
                    i.span(),
                    "`index` is only used by NIfTI files (.nii, .nii.gz) and TIFF time series: it chooses a volume of a 4D file",
                );
            }
        }
        if format != Some(Format::Dicom) {
            if let Some(s) = &v.series {
                self.err(
                    s.span(),
                    "`series` is only used by DICOM folders (format = \"dicom\"): it chooses a series by its SeriesInstanceUID",
                );
            }
        }
        if format != Some(Format::Tiff) {
            if let Some(c) = &v.channel {
                self.err(
                    c.span(),
                    "`channel` is only used by TIFF files (.tif, .tiff, format = \"tiff\"): it chooses a channel of a multi-channel file",
                );
            }
        }
        let channel = v.channel.as_ref().and_then(|c| {
            let n = *c.get_ref();
            let k = usize::try_from(n).ok().filter(|&k| k <= u16::MAX as usize);
            if k.is_none() && format == Some(Format::Tiff) {
                self.err(
                    c.span(),
                    format!("channel = {n}: expected the number of a channel of the file, from 0"),
                );
            }
            k
        });
        match format {
            None => {
                self.err(p.span(), format!(
                    "cannot tell the format of \"{}\": use a .nrrd/.nhdr, .nii/.nii.gz, .mha/.mhd, .tif/.tiff or .dcm file, or set format = \"raw\" with sizes and type, format = \"dicom\" for a folder of DICOM slices (or a DICOM file), or format = \"tiff\" for a folder of TIFF slices",
                    p.get_ref()
                ));
                None
            }
            Some(Format::Nrrd) => {
                self.not_for("by NRRD files (their header describes the data)", raw_keys);
                Some(VolumeSource::Nrrd(path))
            }
            Some(Format::Nifti) => {
                self.not_for("by NIfTI files (their header describes the data)", raw_keys);
                Some(VolumeSource::Nifti(NiftiSpec { path, index }))
            }
            Some(Format::MetaImage) => {
                self.not_for(
                    "by MetaImage files (their header describes the data)",
                    raw_keys,
                );
                Some(VolumeSource::MetaImage(path))
            }
            Some(Format::Dicom) => {
                self.not_for("by DICOM series (their files describe the data)", raw_keys);
                Some(VolumeSource::Dicom(DicomSpec {
                    dir: path,
                    series: v.series.as_ref().map(|s| s.get_ref().clone()),
                }))
            }
            Some(Format::Tiff) => {
                self.not_for("by TIFF files (their tags describe the data)", raw_keys);
                Some(VolumeSource::Tiff(TiffSpec {
                    path,
                    channel,
                    index,
                }))
            }
            Some(Format::Raw) => self.raw(v, path, p.span()),
        }
    }

    pub(super) fn raw(
        &mut self,
        v: &VolumeTable,
        path: PathBuf,
        span: Range<usize>,
    ) -> Option<VolumeSource> {
        let mut ok = true;
        if v.sizes.is_none() {
            self.err(span.clone(), "a raw volume needs `sizes = [x, y, z]`");
            ok = false;
        }
        let sizes = self.sizes(&v.sizes, [1, 1, 1], 1);
        let scalar_type = match &v.ty {
            None => {
                self.err(
                    span,
                    "a raw volume needs `type` (uint8, int16, uint16, float32, ...)",
                );
                ok = false;
                ScalarType::Uint8
            }
            Some(t) => match ScalarType::parse(t.get_ref()) {
                Some(ty) => ty,
                None => {
                    let names = ScalarType::ALL.map(|t| t.nrrd_name());
                    self.err(t.span(), format!("type = \"{}\" is not known: expected one of uint8, int8, uint16, int16, uint32, int32, uint64, int64, float32, float64 (or a NRRD alias such as {})", t.get_ref(), quoted_list(names)));
                    ok = false;
                    ScalarType::Uint8
                }
            },
        };
        let little_endian = self.choice(
            "endian",
            &v.endian,
            &[("little", true), ("big", false)],
            true,
        );
        let spacing = match &v.spacing {
            None => [1.0; 3],
            Some(s) if s.get_ref().iter().all(|x| x.is_finite() && *x > 0.0) => *s.get_ref(),
            Some(s) => {
                self.err(s.span(), "spacing: expected three positive numbers");
                [1.0; 3]
            }
        };
        let offset = match &v.offset {
            None => 0,
            Some(o) if *o.get_ref() >= -1 => *o.get_ref(),
            Some(o) => {
                self.err(o.span(), "offset: expected a byte count >= 0, or -1 for \"the data is at the end of the file\"");
                0
            }
        };
        ok.then_some(VolumeSource::Raw(RawSpec {
            path,
            sizes,
            scalar_type,
            little_endian,
            spacing,
            offset,
        }))
    }
}

/// A volume name: letters, digits, '-' and '_' (what a pass's `volume` key and a
/// composite's transfer table name it by).
fn valid_volume_name(s: &str) -> bool {
    !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_'))
}
