//! NIfTI-1 and MetaImage input (issue 9, item 2), against files written by nibabel and
//! SimpleITK (`tests/fixtures/formats/make_formats.py`), and TIFF stacks written by
//! tifffile (`make_tiff.py`; their own tests are in `formats_tiff.rs`): the voxels, sizes and types
//! equal those of a reference NRRD written beside each file by the script; the
//! geometry equals the affine nibabel and SimpleITK report; each renders the bytes of
//! its reference NRRD; `scl_slope`/`scl_inter` fold into the window; damaged files,
//! 4D files without an index and data files outside `--confine` are refused with
//! messages naming the file and the field.

use std::path::{Path, PathBuf};

use volcast::volume::dicom::DicomSpec;
use volcast::volume::nifti::NiftiSpec;
use volcast::volume::tiff::TiffSpec;
use volcast::volume::{Limits, VolumeError, VolumeSource};

use crate::util::{rendered_nrrds, root, volcast};

fn fixture(name: &str) -> PathBuf {
    root().join("tests/fixtures/formats").join(name)
}

fn expected() -> serde_json::Value {
    let text = std::fs::read_to_string(fixture("expected.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn nifti(name: &str, index: Option<usize>) -> VolumeSource {
    VolumeSource::Nifti(NiftiSpec {
        path: fixture(name),
        index,
    })
}

/// Every file with its reference NRRD (same voxels, directions and origin) and the
/// `[volume]` lines that choose it.
const PAIRS: &[(&str, &str, &str)] = &[
    ("u8_sform.nii", "u8_sform_ref.nrrd", ""),
    ("u8_sform.nii.gz", "u8_sform_ref.nrrd", ""),
    ("i16_scaled.nii", "i16_scaled_ref.nrrd", ""),
    ("i16_big.nii", "i16_big_ref.nrrd", ""),
    ("f32_4d.nii.gz", "f32_4d_ref0.nrrd", "index = 0"),
    ("f32_4d.nii.gz", "f32_4d_ref1.nrrd", "index = 1"),
    ("f32_4d.nii.gz", "f32_4d_ref2.nrrd", "index = 2"),
    // NIfTI-2 twins of the NIfTI-1 files (make_nifti2.py): the same references
    ("n2_u8_sform.nii", "u8_sform_ref.nrrd", ""),
    ("n2_u8_sform.nii.gz", "u8_sform_ref.nrrd", ""),
    ("n2_i16_scaled.nii", "i16_scaled_ref.nrrd", ""),
    ("n2_i16_big.nii", "i16_big_ref.nrrd", ""),
    ("n2_f32_4d.nii.gz", "f32_4d_ref1.nrrd", "index = 1"),
    ("n2_f32_4d.nii.gz", "f32_4d_ref2.nrrd", "index = 2"),
    ("u8.mha", "u8_mha_ref.nrrd", ""),
    ("i16.mhd", "i16_mhd_ref.nrrd", ""),
    ("f32_zlib.mha", "f32_zlib_ref.nrrd", ""),
    ("dicom_ct", "dicom_ct_a_ref.nrrd", DICOM_A),
    ("dicom_ct", "dicom_ct_b_ref.nrrd", DICOM_B),
    // multi-frame and compressed DICOM (make_dicom_mf.py): series A's and B's voxels
    // and geometry as enhanced multi-frame objects, alone or as a series of them
    ("dicom_mf_ct.dcm", "dicom_ct_a_ref.nrrd", ""),
    ("dicom_mf_mr.dcm", "dicom_ct_b_ref.nrrd", ""),
    (
        "dicom_mf_series",
        "dicom_ct_a_ref.nrrd",
        "format = \"dicom\"",
    ),
    ("dicom_rle_ct.dcm", "dicom_ct_a_ref.nrrd", ""),
    ("dicom_deflate_ct.dcm", "dicom_ct_a_ref.nrrd", ""),
    ("dicom_jpegll_ct.dcm", "dicom_ct_a_ref.nrrd", ""),
    ("dicom_jpegll_fragments.dcm", "dicom_ct_a_ref.nrrd", ""),
    ("dicom_j2k_ct.dcm", "dicom_ct_a_ref.nrrd", ""),
    // pydicom's own test files: an RT dose of 15 frames, uncompressed and RLE; an MR
    // slice in RLE and JPEG 2000
    ("pydicom_rtdose.dcm", "pydicom_rtdose_ref.nrrd", ""),
    ("pydicom_rtdose_rle.dcm", "pydicom_rtdose_ref.nrrd", ""),
    ("pydicom_MR_small_RLE.dcm", "pydicom_mr_small_ref.nrrd", ""),
    (
        "pydicom_MR_small_jp2klossless.dcm",
        "pydicom_mr_small_ref.nrrd",
        "",
    ),
    // TIFF stacks written by tifffile (make_tiff.py)
    ("tiff_u8.tif", "tiff_u8_ref.nrrd", ""),
    ("tiff_u16_lzw.tif", "tiff_u16_lzw_ref.nrrd", ""),
    ("tiff_i16.tif", "tiff_i16_ref.nrrd", ""),
    ("tiff_f32_deflate.tif", "tiff_f32_deflate_ref.nrrd", ""),
    ("tiff_packbits.tif", "tiff_packbits_ref.nrrd", ""),
    ("tiff_hyper.tif", "tiff_hyper_c0_ref.nrrd", "channel = 0"),
    ("tiff_hyper.tif", "tiff_hyper_c1_ref.nrrd", "channel = 1"),
    ("tiff_ome.ome.tif", "tiff_ome_ref.nrrd", ""),
    (
        "tiff_ome_c2.ome.tif",
        "tiff_ome_c2_c1_ref.nrrd",
        "channel = 1",
    ),
    ("tiff_frames.tif", "tiff_frames_t1_ref.nrrd", "index = 1"),
    ("tiff_slices", "tiff_slices_ref.nrrd", "format = \"tiff\""),
    ("tiff_slices/*.tif", "tiff_slices_ref.nrrd", ""),
];

/// The two series of `dicom_ct`: int16 with one rescale (-1024 HU), and uint16 whose
/// rescale differs from slice to slice (read as float32 values).
const DICOM_A: &str = "format = \"dicom\"\nseries = \"1.2.826.0.1.3680043.8.498.10\"";
const DICOM_B: &str = "format = \"dicom\"\nseries = \"1.2.826.0.1.3680043.8.498.20\"";

fn dicom(folder: &str, series: Option<&str>) -> VolumeSource {
    VolumeSource::Dicom(DicomSpec {
        dir: fixture(folder),
        series: series.map(str::to_string),
    })
}

fn source(name: &str, lines: &str) -> VolumeSource {
    if let Some(series) = lines.split("series = ").nth(1) {
        return dicom(name, Some(series.trim_matches('"')));
    }
    if name.ends_with(".dcm") || lines == "format = \"dicom\"" {
        return dicom(name, None);
    }
    if name.starts_with("tiff_") {
        return VolumeSource::Tiff(TiffSpec {
            path: fixture(name),
            channel: lines
                .strip_prefix("channel = ")
                .map(|c| c.parse::<usize>().unwrap()),
            index: lines
                .strip_prefix("index = ")
                .map(|c| c.parse::<usize>().unwrap()),
        });
    }
    if name.ends_with(".mha") || name.ends_with(".mhd") {
        VolumeSource::MetaImage(fixture(name))
    } else {
        let index = lines
            .strip_prefix("index = ")
            .map(|i| i.parse::<usize>().unwrap());
        nifti(name, index)
    }
}

#[test]
fn voxels_types_and_geometry_equal_the_reference_nrrds() {
    for &(name, reference, lines) in PAIRS {
        let (v, id) = source(name, lines)
            .load_identified(&Limits::default())
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let r = VolumeSource::Nrrd(fixture(reference))
            .load(&Limits::default())
            .unwrap();
        assert_eq!(v.header.sizes, r.header.sizes, "{name}");
        assert_eq!(v.header.scalar_type, r.header.scalar_type, "{name}");
        assert_eq!(v.header.geometry, r.header.geometry, "{name}");
        assert!(v.data == r.data, "{name}: voxels differ from {reference}");
        assert_eq!(id.data_xxh3.map(|h| h.len()), Some(32), "{name}");
    }
}

#[test]
fn nifti_geometry_is_the_affine_nibabel_reports() {
    let e = expected();
    for name in [
        "u8_sform.nii",
        "i16_scaled.nii",
        "i16_big.nii",
        "u16_qform.nii",
        "f32_4d.nii.gz",
    ] {
        let index = name.contains("4d").then_some(2);
        let g = nifti(name, index).header().unwrap().geometry;
        let affine = &e[name]["affine"];
        let at = |r: usize, c: usize| affine[r][c].as_f64().unwrap();
        for r in 0..3 {
            for c in 0..3 {
                crate::assert_close!(g.axes[c][r], at(r, c), 1e-9, "{name} axis {c}[{r}]");
            }
            crate::assert_close!(g.origin[r], at(r, 3), 1e-9, "{name} origin[{r}]");
        }
    }
    // the qform file really uses its qform: no sform, a negative qfac
    assert_eq!(e["u16_qform.nii"]["sform_code"], 0);
    let g = nifti("u16_qform.nii", None).header().unwrap().geometry;
    assert!(
        g.matrix().determinant() < 0.0,
        "qfac -1 makes a left-handed frame"
    );
}

#[test]
fn nifti2_is_read_as_nibabel_reads_it() {
    let text = std::fs::read_to_string(fixture("nifti2.json")).unwrap();
    let e: serde_json::Value = serde_json::from_str(&text).unwrap();
    let files = e.as_object().unwrap().keys().filter(|k| *k != "tools");
    let mut seen = 0;
    for name in files {
        let x = &e[name];
        let index = name.contains("4d").then_some(2);
        let h = nifti(name, index).header().unwrap();
        let affine = &x["affine"];
        let at = |r: usize, c: usize| affine[r][c].as_f64().unwrap();
        for r in 0..3 {
            for c in 0..3 {
                crate::assert_close!(
                    h.geometry.axes[c][r],
                    at(r, c),
                    1e-9,
                    "{name} axis {c}[{r}]"
                );
            }
            crate::assert_close!(h.geometry.origin[r], at(r, 3), 1e-9, "{name} origin[{r}]");
        }
        let shape: Vec<usize> = x["shape"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as usize)
            .collect();
        assert_eq!(h.sizes.to_vec(), shape[..3].to_vec(), "{name}");
        let [slope, inter] = [0, 1].map(|i| x["slope_inter"][i].as_f64().unwrap());
        assert_eq!(
            (h.rescale.slope, h.rescale.intercept),
            (slope, inter),
            "{name}"
        );
        assert!(
            h.fields
                .iter()
                .any(|(k, v)| k == "format" && v == "NIfTI-2"),
            "{name}"
        );
        // the physical values of a 3D file, summed, are nibabel's
        if index.is_none() {
            let v = nifti(name, None).load(&Limits::default()).unwrap();
            let sum: f64 = (0..v.header.voxel_count())
                .map(|i| h.rescale.apply(v.data.get_f64(i)))
                .sum();
            crate::assert_close!(sum, x["physical_sum"].as_f64().unwrap(), 1e-9, "{name} sum");
        }
        // and the header is its NIfTI-1 twin's but for the version
        let twin = x["twin_of"].as_str().unwrap();
        let t = nifti(twin, index).header().unwrap();
        assert_eq!(
            (t.sizes, t.scalar_type, t.geometry, t.rescale),
            (h.sizes, h.scalar_type, h.geometry, h.rescale),
            "{name}"
        );
        seen += 1;
    }
    assert_eq!(seen, 6);
}

#[test]
fn metaimage_geometry_is_what_simpleitk_reports() {
    let e = expected();
    for name in ["u8.mha", "i16.mhd", "f32_zlib.mha"] {
        let g = VolumeSource::MetaImage(fixture(name))
            .header()
            .unwrap()
            .geometry;
        let x = &e[name];
        let num = |v: &serde_json::Value, i: usize| v[i].as_f64().unwrap();
        for r in 0..3 {
            crate::assert_close!(g.origin[r], num(&x["origin"], r), 0.0, "{name} origin");
        }
        // SimpleITK's own index-to-physical map at the far corner [7, 5, 4]
        let far = g.world_from_index(glam::DVec3::new(7.0, 5.0, 4.0));
        for r in 0..3 {
            crate::assert_close!(far[r], num(&x["far_corner"], r), 1e-9, "{name} far corner");
        }
    }
}

/// Renders `volume` (the `[volume]` table's lines) with the passes `rest` through the
/// CLI and returns every image file's bytes, by name.
fn render(volume: &str, rest: &str) -> Vec<(String, Vec<u8>)> {
    rendered_nrrds(
        &format!(
            "[volume]\n{volume}\n[camera]\nazimuth = 35.0\nelevation = 20.0\n\
             [image]\nsize = [24, 20]\nformat = \"nrrd\"\n{rest}"
        ),
        &[],
    )
}

fn path_line(name: &str) -> String {
    format!("path = {:?}", fixture(name).display().to_string())
}

const PASSES: &str = "[[render]]\nmode = \"mip\"\n\
    [[render]]\nmode = \"xray\"\n\
    [[render]]\nmode = \"surface\"\niso = 0.4\n\
    [[render]]\nmode = \"composite\"\ntransfer = \"bone\"\n";

#[test]
fn each_file_renders_the_bytes_of_its_reference_nrrd() {
    for &(name, reference, lines) in PAIRS {
        let a = render(&format!("{}\n{lines}", path_line(name)), PASSES);
        let b = render(&path_line(reference), PASSES);
        assert_eq!(a.len(), 4, "{name}");
        // the pictures are not blank: the MIP (NRRD float32 after its header) varies
        let mip = &a.iter().find(|(f, _)| f.starts_with("mip")).unwrap().1;
        let data = &mip[mip.windows(2).position(|w| w == b"\n\n").unwrap() + 2..];
        let values: std::collections::BTreeSet<[u8; 4]> = data
            .chunks_exact(4)
            .map(|c| c.try_into().unwrap())
            .collect();
        assert!(values.len() > 20, "{name}: a nearly constant MIP");
        for ((file, x), (_, y)) in a.iter().zip(&b) {
            assert!(
                x == y,
                "{name}: {file} differs from the render of {reference}"
            );
        }
    }
}

#[test]
fn scl_slope_and_inter_fold_into_the_window() {
    // i16_scaled.nii: value = 2 * stored - 100 (patched into nibabel's file, read
    // back by nibabel); stored -40..680 are the values -180..1260
    let e = expected();
    let x = &e["i16_scaled.nii"];
    assert_eq!(x["slope_inter"], serde_json::json!([2.0, -100.0]));
    let nii = path_line("i16_scaled.nii");
    let nrrd = path_line("i16_scaled_ref.nrrd");
    let mip = "[[render]]\nmode = \"mip\"\n";
    // the default window: the data's range, in either units
    assert_eq!(render(&nii, mip), render(&nrrd, mip));
    // a window, an iso value and a threshold in data units are physical values
    let physical = |s: f64| 2.0 * s - 100.0;
    let passes = |v: &dyn Fn(f64) -> f64| {
        format!(
            "[[render]]\nmode = \"surface\"\niso = {:?}\n\
             [[render]]\nmode = \"depth\"\nthreshold = {:?}\n\
             [[render]]\nmode = \"mip\"\nwindow = [{:?}, {:?}]\n",
            v(300.0),
            v(120.0),
            v(0.0),
            v(500.0)
        )
    };
    let a = render(
        &format!("{nii}\nwindow = [-180.0, 1260.0]\nunits = \"data\""),
        &passes(&physical),
    );
    let b = render(
        &format!("{nrrd}\nwindow = [-40.0, 680.0]\nunits = \"data\""),
        &passes(&|s| s),
    );
    assert_eq!(a.len(), 3);
    for ((file, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "{file}: the physical window renders other bytes");
    }
    // volcast info reports the physical range nibabel computes
    let o = volcast(
        &root(),
        &["info", "tests/fixtures/formats/i16_scaled.nii", "--json"],
    );
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["value_min"], x["physical_min"]);
    assert_eq!(j["value_max"], x["physical_max"]);
    assert_eq!(j["rescale"]["slope"], 2.0);
    assert_eq!(j["type"], "int16", "voxels keep their stored type");
}

#[test]
fn a_4d_file_needs_an_index_in_bounds() {
    let e = nifti("f32_4d.nii.gz", None)
        .header()
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("f32_4d.nii.gz") && e.contains("index = 0` to 2"),
        "{e}"
    );
    let e = nifti("f32_4d.nii.gz", Some(3)).load(&Limits::default());
    let e = e.unwrap_err().to_string();
    assert!(
        e.contains("index = 3 is out of bounds") && e.contains("dim[4] = 3"),
        "{e}"
    );
    // through a scene: the index of another format is a scene error
    let tmp = tempfile::tempdir().unwrap();
    let write = |volume: String| {
        std::fs::write(
            tmp.path().join("s.toml"),
            format!("[volume]\n{volume}\n[[render]]\nmode = \"mip\"\n"),
        )
        .unwrap();
        let o = volcast(tmp.path(), &["check", "s.toml"]);
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let (code, err) = write(format!("{}\nindex = 1", path_line("u8_sform_ref.nrrd")));
    assert_eq!(code, Some(1));
    assert!(err.contains("`index` is only used by NIfTI files"), "{err}");
    let (code, err) = write(format!("{}\nindex = -1", path_line("f32_4d.nii.gz")));
    assert_eq!(code, Some(1));
    assert!(err.contains("index = -1"), "{err}");
    let (code, err) = write(path_line("f32_4d.nii.gz"));
    assert_eq!(code, Some(1));
    assert!(err.contains("4D NIfTI file of 3 volumes"), "{err}");
    let (code, err) = write(format!("{}\nindex = 2", path_line("f32_4d.nii.gz")));
    assert_eq!(code, Some(0), "{err}");
}

/// A copy of fixture `name` in `dir`, changed by `edit`.
fn damaged(dir: &Path, name: &str, edit: impl FnOnce(&mut Vec<u8>)) -> PathBuf {
    let mut bytes = std::fs::read(fixture(name)).unwrap();
    edit(&mut bytes);
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn load_err(source: VolumeSource, limits: Limits) -> String {
    match source.load(&limits) {
        Ok(_) => panic!("{source:?} loaded"),
        Err(e) => e.to_string(),
    }
}

fn gz(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

fn gunzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Read;
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(bytes)
        .read_to_end(&mut out)
        .unwrap();
    out
}

#[test]
fn damaged_nifti_files_are_refused_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let limits = Limits::default();
    let spec = |p: PathBuf| {
        VolumeSource::Nifti(NiftiSpec {
            path: p,
            index: None,
        })
    };
    let p = damaged(d, "u8_sform.nii", |b| b.truncate(b.len() - 1));
    let e = load_err(spec(p.clone()), limits);
    assert!(
        e.contains("u8_sform.nii") && e.contains("data shorter than declared"),
        "{e}"
    );
    assert!(
        spec(p).storage().is_err(),
        "the length is checked before mapping"
    );
    let p = damaged(d, "u8_sform.nii", |b| b.push(0));
    let e = load_err(spec(p), limits);
    assert!(e.contains("longer than the 592"), "{e}");
    let p = damaged(d, "u8_sform.nii", |b| b.truncate(200));
    let e = load_err(spec(p), limits);
    assert!(e.contains("inside the 348-byte NIfTI-1 header"), "{e}");
    let p = damaged(d, "u8_sform.nii", |b| b[70] = 128);
    let e = load_err(spec(p), limits);
    assert!(e.contains("`datatype`") && e.contains("RGB24"), "{e}");
    // a gzip stream cut short, and one whose header claims 30000^3 voxels: refused
    // before any allocation by the memory limit
    let p = damaged(d, "u8_sform.nii.gz", |b| b.truncate(b.len() - 20));
    let e = load_err(spec(p), limits);
    assert!(e.contains("u8_sform.nii.gz"), "{e}");
    let p = damaged(d, "u8_sform.nii.gz", |b| {
        let mut raw = gunzip(b);
        for i in 0..3 {
            raw[42 + 2 * i..44 + 2 * i].copy_from_slice(&30000i16.to_le_bytes());
        }
        *b = gz(&raw);
    });
    let small = Limits { max_bytes: 1 << 20 };
    match spec(p).load(&small) {
        Err(VolumeError::TooLarge { bytes, .. }) => assert_eq!(bytes, Some(27_000_000_000_000)),
        other => panic!("expected TooLarge, got {other:?}"),
    }
}

#[test]
fn damaged_metaimage_files_are_refused_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let limits = Limits::default();
    let meta = VolumeSource::MetaImage;
    let p = damaged(d, "u8.mha", |b| b.truncate(b.len() - 3));
    let e = load_err(meta(p), limits);
    assert!(
        e.contains("u8.mha") && e.contains("data shorter than declared"),
        "{e}"
    );
    // a .mhd without its data file: the error names the data file
    let p = damaged(d, "i16.mhd", |_| {});
    let e = load_err(meta(p.clone()), limits);
    assert!(e.contains("i16.raw"), "{e}");
    std::fs::copy(fixture("i16.raw"), d.join("i16.raw")).unwrap();
    assert!(meta(p).load(&limits).is_ok());
    // compressed data that cannot hold what DimSize declares, at once
    let p = damaged(d, "f32_zlib.mha", |b| {
        let text = String::from_utf8_lossy(b).replace("DimSize = 8 6 5", "DimSize = 800 600 500");
        *b = text.into_bytes();
    });
    let e = load_err(meta(p), limits);
    assert!(e.contains("cannot come from"), "{e}");
    let p = damaged(d, "f32_zlib.mha", |b| {
        let text = String::from_utf8_lossy(b).into_owned();
        let size = text.split("CompressedDataSize = ").nth(1).unwrap();
        let n: String = size.chars().take_while(char::is_ascii_digit).collect();
        *b = text
            .replacen(
                &format!("CompressedDataSize = {n}"),
                "CompressedDataSize = 99999",
                1,
            )
            .into_bytes();
    });
    let e = load_err(meta(p), limits);
    assert!(e.contains("CompressedDataSize = 99999"), "{e}");
    let p = damaged(d, "u8.mha", |b| {
        let text = String::from_utf8_lossy(b).replace("MET_UCHAR", "MET_FLOAT_ARRAY");
        *b = text.into_bytes();
    });
    let e = load_err(meta(p), limits);
    assert!(e.contains("line 12: `ElementType`"), "{e}");
}

#[test]
fn info_reads_every_format_by_its_extension() {
    for (name, format) in [
        ("u8_sform.nii", "NIfTI-1"),
        ("f32_4d.nii.gz", "NIfTI-1"),
        ("u8.mha", "MetaImage"),
        ("i16.mhd", "MetaImage"),
    ] {
        let path = fixture(name).display().to_string();
        let o = volcast(&root(), &["info", &path, "--json"]);
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(j["sizes"], serde_json::json!([8, 6, 5]), "{name}");
        assert_eq!(j["fields"]["format"], format, "{name}");
    }
}

#[cfg(unix)]
#[test]
fn confinement_covers_the_data_file_of_a_mhd() {
    let tmp = tempfile::tempdir().unwrap();
    let secret = tmp.path().join("secret.raw");
    std::fs::write(&secret, vec![7u8; 480]).unwrap();
    let sub = tmp.path().join("submission");
    std::fs::create_dir(&sub).unwrap();
    let header = std::fs::read_to_string(fixture("i16.mhd"))
        .unwrap()
        .replace(
            "ElementDataFile = i16.raw",
            "ElementDataFile = ../secret.raw",
        );
    std::fs::write(sub.join("v.mhd"), header).unwrap();
    std::os::unix::fs::symlink(fixture("u8_sform.nii"), sub.join("link.nii")).unwrap();
    // a DICOM folder whose slices link to files outside
    let slices = sub.join("slices");
    std::fs::create_dir(&slices).unwrap();
    for e in std::fs::read_dir(fixture("dicom_ct")).unwrap() {
        let p = e.unwrap().path();
        if p.file_name().unwrap().to_string_lossy().starts_with("10_") {
            std::os::unix::fs::symlink(&p, slices.join(p.file_name().unwrap())).unwrap();
        }
    }
    for volume in ["v.mhd", "link.nii", "slices\"\nformat = \"dicom"] {
        std::fs::write(
            sub.join("s.toml"),
            format!("[volume]\npath = \"{volume}\"\n[image]\nsize = [8, 8]\n[[render]]\nmode = \"mip\"\n"),
        )
        .unwrap();
        let o = volcast(&sub, &["check", "s.toml", "--confine", "."]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{volume}: {err}");
        assert!(
            err.contains("outside") && err.contains("(--confine)"),
            "{err}"
        );
        let o = volcast(&sub, &["check", "s.toml"]);
        assert!(
            o.status.success(),
            "{volume} without --confine: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

#[test]
fn a_negative_slope_inverts_the_window() {
    // i16_scaled.nii with scl_slope -1, scl_inter 0 stands for the negated voxels: it
    // renders the bytes of a NRRD holding them, with the default window and a window
    // of physical values
    let tmp = tempfile::tempdir().unwrap();
    let nii = damaged(tmp.path(), "i16_scaled.nii", |b| {
        b[112..116].copy_from_slice(&(-1f32).to_le_bytes());
        b[116..120].copy_from_slice(&0f32.to_le_bytes());
    });
    let nrrd = damaged(tmp.path(), "i16_scaled_ref.nrrd", |b| {
        let start = b.windows(2).position(|w| w == b"\n\n").unwrap() + 2;
        for v in b[start..].chunks_exact_mut(2) {
            let x = -i16::from_le_bytes([v[0], v[1]]);
            v.copy_from_slice(&x.to_le_bytes());
        }
    });
    let line = |p: &Path| format!("path = {:?}", p.display().to_string());
    let passes = "[[render]]\nmode = \"mip\"\n[[render]]\nmode = \"surface\"\niso = 0.3\n";
    for window in ["", "window = [-600.0, 20.0]"] {
        let a = render(&format!("{}\n{window}", line(&nii)), passes);
        let b = render(&format!("{}\n{window}", line(&nrrd)), passes);
        assert_eq!(a.len(), 2);
        for ((file, x), (_, y)) in a.iter().zip(&b) {
            assert!(
                x == y,
                "{file} ({window:?}): differs from the negated voxels"
            );
        }
    }
}

#[test]
fn dicom_rescale_is_hounsfield_units_in_the_window() {
    // series A: stored int16, RescaleIntercept -1024: a window in HU is the stored
    // window shifted by 1024, and the voxels keep their type
    let h = dicom("dicom_ct", Some("1.2.826.0.1.3680043.8.498.10"))
        .header()
        .unwrap();
    assert_eq!(h.scalar_type, volcast::volume::ScalarType::Int16);
    assert_eq!(h.rescale.intercept, -1024.0);
    let passes = "[[render]]\nmode = \"surface\"\niso = 100.0\n[[render]]\nmode = \"mip\"\n";
    let a = render(
        &format!(
            "{}\n{DICOM_A}\nwindow = [-1054.0, -724.0]\nunits = \"data\"",
            path_line("dicom_ct")
        ),
        &passes.replace("100.0", "-924.0"),
    );
    let b = render(
        &format!(
            "{}\nwindow = [-30.0, 300.0]\nunits = \"data\"",
            path_line("dicom_ct_a_ref.nrrd")
        ),
        passes,
    );
    assert_eq!(a.len(), 2);
    assert!(a == b, "the HU window renders other bytes");
    // series B: rescales differ, so the voxels are float32 values, no rescale left
    let h = dicom("dicom_ct", Some("1.2.826.0.1.3680043.8.498.20"))
        .header()
        .unwrap();
    assert_eq!(h.scalar_type, volcast::volume::ScalarType::Float32);
    assert!(h.rescale.is_identity());
    assert_eq!(h.sizes, [8, 6, 3]);
}

#[test]
fn dicom_series_problems_are_named() {
    let e = dicom("dicom_ct", None).header().unwrap_err().to_string();
    assert!(
        e.contains("holds 2 series")
            && e.contains("498.10\" (5 slices")
            && e.contains("498.20\" (3 slices"),
        "{e}"
    );
    let e = dicom("dicom_ct", Some("9.9"))
        .header()
        .unwrap_err()
        .to_string();
    assert!(e.contains("series = \"9.9\" is not in the folder"), "{e}");
    let e = dicom("dicom_tilt", None).header().unwrap_err().to_string();
    assert!(e.contains("gantry tilt"), "{e}");
    // a JPEG Baseline slice whose stream is a stub: read, but not decoded
    let e = dicom("dicom_jpeg", None)
        .load(&Limits::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("s.dcm") && e.contains("JPEG Baseline") && e.contains("JPEG marker segment"),
        "{e}"
    );
    // a missing slice: uneven spacing; a slice cut short: the declared length
    let tmp = tempfile::tempdir().unwrap();
    let copy = |skip: &str, cut: Option<&str>| {
        let d = tmp.path().join(format!("c{skip}{}", cut.unwrap_or("")));
        std::fs::create_dir(&d).unwrap();
        for e in std::fs::read_dir(fixture("dicom_ct")).unwrap() {
            let p = e.unwrap().path();
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            if name.starts_with("10_") && name != skip {
                let mut b = std::fs::read(&p).unwrap();
                if cut == Some(name.as_str()) {
                    b.truncate(b.len() - 10);
                }
                std::fs::write(d.join(&name), b).unwrap();
            }
        }
        VolumeSource::Dicom(DicomSpec {
            dir: d,
            series: None,
        })
    };
    // files 10_{3,0,7,4,1}.dcm hold slices 0..4: 10_7.dcm is the middle one
    let e = copy("10_7.dcm", None).header().unwrap_err().to_string();
    assert!(e.contains("uneven slice spacing"), "{e}");
    let e = copy("", Some("10_4.dcm")).header().unwrap_err().to_string();
    assert!(
        e.contains("10_4.dcm") && e.contains("(7FE0,0010)") && e.contains("declares 96 bytes"),
        "{e}"
    );
    // `series` belongs to DICOM folders only
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("s.toml"),
        format!(
            "[volume]\n{}\nseries = \"1.2\"\n[[render]]\nmode = \"mip\"\n",
            path_line("u8.mha")
        ),
    )
    .unwrap();
    let o = volcast(tmp.path(), &["check", "s.toml"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("`series` is only used by DICOM folders"),
        "{err}"
    );
}

/// The shipped NIfTI copy of VTK's CT head (`data/make_ct_head_nifti.py`, nibabel):
/// the voxels of the shipped NRRD, its geometry to float32 precision (NIfTI stores
/// float32: the spacing 3.2 becomes 3.200000047683716), and its example scene
/// `scenes/ct_head_nifti.toml` renders the bytes of the same scene on a NRRD of those
/// voxels with those spacings.
#[test]
fn the_shipped_nifti_head_is_the_shipped_nrrd_head() {
    let load = |p: &Path| {
        VolumeSource::from_path(p)
            .unwrap()
            .load(&Limits::default())
            .unwrap()
    };
    let nifti_path = root().join("data/ct_head_vtk_quarter.nii.gz");
    let (nii, nrrd) = (
        load(&nifti_path),
        load(&root().join("data/ct_head_vtk_quarter.nrrd")),
    );
    assert_eq!(nii.header.sizes, [64, 64, 93]);
    assert_eq!(nii.header.sizes, nrrd.header.sizes);
    assert_eq!(nii.header.scalar_type, nrrd.header.scalar_type);
    assert!(nii.data == nrrd.data, "the voxels differ");
    let (a, b) = (nii.header.geometry, nrrd.header.geometry);
    assert_eq!(a.origin, b.origin);
    for k in 0..3 {
        let d = (a.axes[k] - b.axes[k]).length();
        assert!(
            d <= 1e-7 * b.axes[k].length(),
            "axis {k}: {} vs {}",
            a.axes[k],
            b.axes[k]
        );
    }
    // the NRRD's voxels with the NIfTI's float32 spacings, as raw little-endian int16
    let tmp = tempfile::tempdir().unwrap();
    let sp = a.spacings();
    let mut file = format!(
        "NRRD0004\ntype: int16\ndimension: 3\nsizes: 64 64 93\nspacings: {:?} {:?} {:?}\nendian: little\nencoding: raw\n\n",
        sp[0], sp[1], sp[2]
    )
    .into_bytes();
    for i in 0..nrrd.data.len() {
        file.extend_from_slice(&(nrrd.data.get_f64(i) as i16).to_le_bytes());
    }
    let same = tmp.path().join("same.nrrd");
    std::fs::write(&same, file).unwrap();
    let scene = std::fs::read_to_string(root().join("scenes/ct_head_nifti.toml")).unwrap();
    let on = |path: &Path| {
        let text = scene
            .replace(
                "\"../data/ct_head_vtk_quarter.nii.gz\"",
                &format!("{:?}", path.display().to_string()),
            )
            .replace("size = [256, 256]", "size = [40, 40]\nformat = \"nrrd\"");
        assert!(text.contains("format = \"nrrd\"") && !text.contains("../data"));
        rendered_nrrds(&text, &["--frames", "0"])
    };
    let (x, y) = (on(&nifti_path), on(&same));
    assert_eq!(x.len(), 2);
    for ((file, p), (_, q)) in x.iter().zip(&y) {
        assert!(p == q, "{file} differs");
    }
}

/// `info` prints what a file stored in single precision as that number: the
/// NIfTI head's spacing 3.2 (stored as float32), a TIFF's float32 range -0.2 .. 2.2,
/// not their doubles 3.200000047683716 and -0.20000000298023224; `--json` keeps the
/// doubles.
#[test]
fn info_prints_single_precision_values_as_the_file_stored_them() {
    let o = volcast(&root(), &["info", "data/ct_head_vtk_quarter.nii.gz"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("spacing    3.2 3.2 1.5\n"), "{text}");
    assert!(
        text.contains("axes       (3.2, 0, 0) (0, 3.2, 0) (0, 0, 1.5)\n"),
        "{text}"
    );
    let tiff = std::fs::read_to_string(fixture("tiff.json")).unwrap();
    let e: serde_json::Value = serde_json::from_str(&tiff).unwrap();
    let name = e
        .as_object()
        .unwrap()
        .iter()
        .find(|(_, v)| v["min"].as_f64() == Some(f64::from(-0.2f32)))
        .map(|(k, _)| k.clone())
        .expect("a float32 TIFF fixture with minimum -0.2");
    let o = volcast(
        &root(),
        &["info", &format!("tests/fixtures/formats/{name}")],
    );
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("range      -0.2 .. 2.2 (mean"),
        "{name}: {text}"
    );
    let o = volcast(
        &root(),
        &["info", "data/ct_head_vtk_quarter.nii.gz", "--json"],
    );
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["spacing"][0].as_f64(), Some(f64::from(3.2f32)));
}
