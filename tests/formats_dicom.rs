//! Multi-frame and compressed DICOM (issue 46, item 1), against files written by
//! pydicom and imagecodecs and pydicom's own test files
//! (`tests/fixtures/formats/make_dicom_mf.py`; the lossless ones render the bytes of
//! their reference NRRDs in `formats.rs`'s PAIRS): what pydicom reads from each file;
//! lossy files within a stated tolerance of the values pydicom decodes, and `info`
//! saying they are lossy; an RT dose's DoseGridScaling as its rescale; refusals by
//! name (JPEG-LS, frames without positions, several stacks); damaged and hostile
//! encapsulated pixel data refused before anything is allocated from it; a file or
//! a series of multi-frame files under `--confine`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use volcast::volume::dicom::DicomSpec;
use volcast::volume::{Limits, ScalarType, VolumeSource};

use crate::util::{root, volcast};

fn fixture(name: &str) -> PathBuf {
    root().join("tests/fixtures/formats").join(name)
}

fn dicom(path: PathBuf) -> VolumeSource {
    VolumeSource::Dicom(DicomSpec {
        dir: path,
        series: None,
    })
}

fn expected() -> serde_json::Value {
    let text = std::fs::read_to_string(fixture("dicom.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn field<'a>(fields: &'a [(String, String)], key: &str) -> &'a str {
    fields
        .iter()
        .find(|(k, _)| k == key)
        .map_or("", |(_, v)| v.as_str())
}

fn load(path: PathBuf) -> volcast::volume::Volume {
    dicom(path.clone())
        .load(&Limits::default())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn each_file_holds_what_pydicom_reads() {
    let e = expected();
    let mut seen = 0;
    let mut parts = 0.0;
    for (name, x) in e.as_object().unwrap() {
        if name == "tools" || x.get("shape").is_none() {
            continue;
        }
        // the files of a series are read as their folder (alone, their frames are
        // unevenly spaced)
        if name.starts_with("dicom_mf_series/") {
            parts += x["sum"].as_f64().unwrap();
            continue;
        }
        let v = load(fixture(name));
        let shape: Vec<usize> = x["shape"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s.as_u64().unwrap() as usize)
            .collect();
        // pydicom: (frames, rows, columns), or (rows, columns) for one frame
        let (frames, rows, columns) = match shape[..] {
            [f, r, c] => (f, r, c),
            [r, c] => (1, r, c),
            _ => panic!("{name}: shape {shape:?}"),
        };
        assert_eq!(v.header.sizes, [columns, rows, frames], "{name}");
        assert_eq!(x["frames"].as_u64(), Some(frames as u64), "{name}");
        let h = &v.header;
        assert_eq!(
            field(&h.fields, "transfer syntax").split(' ').next(),
            x["transfer_syntax"].as_str(),
            "{name}"
        );
        // the stored values pydicom decodes, summed (a rescale per frame makes
        // float32 physical values: dicom_mf_mr.dcm, whose voxels formats.rs compares)
        if h.scalar_type != ScalarType::Float32 && x.get("lossy").is_none() {
            let sum: f64 = (0..h.voxel_count()).map(|i| v.data.get_f64(i)).sum();
            assert_eq!(sum, x["sum"].as_f64().unwrap(), "{name}");
        }
        if let Some(s) = x.get("dose_grid_scaling") {
            assert_eq!(h.rescale.slope, s.as_f64().unwrap(), "{name}");
        }
        seen += 1;
    }
    assert!(seen >= 13, "{seen} files");
    let v = load(fixture("dicom_mf_series"));
    assert_eq!(v.header.sizes, [8, 6, 5]);
    let sum: f64 = (0..v.header.voxel_count()).map(|i| v.data.get_f64(i)).sum();
    assert_eq!(sum, parts);
}

/// The lossy files' voxels against what pydicom decodes with pylibjpeg (libjpeg,
/// OpenJPEG): the same geometry, values within one grey level of 255 for JPEG
/// (jpeg-decoder and libjpeg round their inverse DCTs differently) and equal for
/// JPEG 2000 (openjp2 is a port of OpenJPEG); and within what the compression lost
/// of the original voxels.
#[test]
fn lossy_files_are_read_within_tolerance_of_pydicom() {
    let e = expected();
    let original = VolumeSource::Nrrd(fixture("dicom_u8_original.nrrd"))
        .load(&Limits::default())
        .unwrap();
    for (name, tolerance, lost) in [
        ("dicom_jpeg_lossy.dcm", 1.0, 16.0),
        ("dicom_j2k_lossy.dcm", 0.0, 32.0),
    ] {
        let v = load(fixture(name));
        let reference = e[name]["pydicom_values"].as_str().unwrap();
        let r = VolumeSource::Nrrd(fixture(reference))
            .load(&Limits::default())
            .unwrap();
        assert_eq!(v.header.sizes, r.header.sizes, "{name}");
        assert_eq!(v.header.scalar_type, ScalarType::Uint8, "{name}");
        for k in 0..3 {
            let d = (v.header.geometry.axes[k] - r.header.geometry.axes[k]).length();
            assert!(d < 1e-9, "{name} axis {k}");
        }
        assert!((v.header.geometry.origin - r.header.geometry.origin).length() < 1e-9);
        let n = v.header.voxel_count();
        let worst = (0..n)
            .map(|i| (v.data.get_f64(i) - r.data.get_f64(i)).abs())
            .fold(0.0, f64::max);
        assert!(
            worst <= tolerance,
            "{name}: {worst} grey levels from pydicom's values"
        );
        let lost_here = (0..n)
            .map(|i| (v.data.get_f64(i) - original.data.get_f64(i)).abs())
            .fold(0.0, f64::max);
        assert!(
            lost_here > 0.0 && lost_here <= lost,
            "{name}: {lost_here} from the original"
        );
        assert_eq!(e[name]["lossy"], "01", "{name}");
    }
}

#[test]
fn info_says_what_is_lossy() {
    for (name, want) in [
        (
            "dicom_jpeg_lossy.dcm",
            "yes: transfer syntax JPEG Baseline (Process 1) (lossy compression); LossyImageCompression (0028,2110) 01, ratio 4, method ISO_10918_1",
        ),
        (
            "dicom_j2k_lossy.dcm",
            "yes: transfer syntax JPEG 2000 Image Compression (lossless or lossy compression); LossyImageCompression (0028,2110) 01, ratio 4, method ISO_15444_1",
        ),
        ("dicom_rle_ct.dcm", "no"),
        ("dicom_j2k_ct.dcm", "no"),
        ("pydicom_rtdose.dcm", "no"),
    ] {
        let path = fixture(name).display().to_string();
        let o = volcast(&root(), &["info", &path, "--json"]);
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(j["fields"]["lossy"], want, "{name}");
        assert_eq!(j["fields"]["format"], "DICOM file", "{name}");
        let o = volcast(&root(), &["info", &path]);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(text.contains(&format!("lossy      {want}\n")), "{name}: {text}");
    }
    // a folder of multi-frame files
    let path = fixture("dicom_mf_series").display().to_string();
    let o = volcast(&root(), &["info", &path, "--json"]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["fields"]["frames"], "2 files, 2 of them multi-frame");
    assert_eq!(j["fields"]["format"], "DICOM series");
    assert_eq!(j["sizes"], serde_json::json!([8, 6, 5]));
}

/// pydicom's rtdose.dcm, the file of issue 46: 15 frames at GridFrameOffsetVector
/// along the normal, uint32 doses scaled by DoseGridScaling (Gy).
#[test]
fn an_rt_dose_is_read_in_gray() {
    let h = dicom(fixture("pydicom_rtdose.dcm")).header().unwrap();
    assert_eq!(h.sizes, [10, 10, 15]);
    assert_eq!(h.scalar_type, ScalarType::Uint32);
    assert_eq!(h.rescale.slope, 1e-6);
    assert!((h.geometry.axes[2] - glam::DVec3::new(0.0, 0.0, 5.0)).length() < 1e-9);
    let o = volcast(
        &root(),
        &[
            "info",
            "tests/fixtures/formats/pydicom_rtdose.dcm",
            "--json",
        ],
    );
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["fields"]["frames"], "15 in one multi-frame file");
    let max = j["value_max"].as_f64().unwrap();
    assert!((max - 1.254).abs() < 1e-9, "{max}");
    // a scene names the file; a window in Gy
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("s.toml"),
        format!(
            "[volume]\npath = {:?}\nwindow = [0.8, 1.2]\nunits = \"data\"\n[image]\nsize = [16, 16]\n[[render]]\nmode = \"mip\"\n",
            fixture("pydicom_rtdose.dcm").display().to_string()
        ),
    )
    .unwrap();
    let o = volcast(tmp.path(), &["check", "s.toml"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn what_is_not_read_is_refused_by_name() {
    let err = |name: &str| {
        dicom(fixture(name))
            .load(&Limits::default())
            .unwrap_err()
            .to_string()
    };
    let e = err("pydicom_MR_small_jpeg_ls_lossless.dcm");
    assert!(
        e.contains("1.2.840.10008.1.2.4.80 (JPEG-LS Lossless Image Compression) is not read")
            && e.contains("CharLS")
            && e.contains("volcast reads")
            && e.contains("RLE Lossless"),
        "{e}"
    );
    let e = err("dicom_mf_cine.dcm");
    assert!(
        e.contains("3 frames without a position each") && e.contains("GridFrameOffsetVector"),
        "{e}"
    );
    let e = err("dicom_mf_two_stacks.dcm");
    assert!(
        e.contains("two slices at the same position")
            && e.contains("(frame 1 of 5)")
            && e.contains("several stacks or time points"),
        "{e}"
    );
    // not a DICOM file, named as one
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("notes.dcm");
    std::fs::write(&p, b"hello").unwrap();
    let e = dicom(p.clone()).header().unwrap_err().to_string();
    assert!(e.contains("not a DICOM file"), "{e}");
    let o = volcast(tmp.path(), &["info", "notes.dcm"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a DICOM file"));
}

/// A copy of fixture `name` in `dir`, changed by `edit`.
fn damaged(dir: &Path, name: &str, edit: impl FnOnce(&mut Vec<u8>)) -> PathBuf {
    let mut bytes = std::fs::read(fixture(name)).unwrap();
    edit(&mut bytes);
    let p = dir.join(name.replace('/', "_"));
    std::fs::write(&p, bytes).unwrap();
    p
}

fn find(b: &[u8], what: &[u8]) -> usize {
    b.windows(what.len())
        .position(|w| w == what)
        .unwrap_or_else(|| panic!("{what:02X?} not found"))
}

/// Encapsulated pixel data made to mislead the decoders: fragment lengths past the
/// file, codestream headers claiming 65535 x 65535 pixels, one-pixel JPEG 2000 tiles,
/// RLE segment offsets out of the frame, an offset table pointing between fragments,
/// NumberOfFrames past the per-frame groups or the pixel data: each refused by name,
/// fast, before anything is allocated from it.
#[test]
fn hostile_encapsulated_pixel_data_is_refused_before_allocating() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let limits = Limits {
        max_bytes: 64 << 20,
    };
    let check = |p: PathBuf, wants: &[&str]| {
        let start = Instant::now();
        let e = dicom(p.clone()).load(&limits).unwrap_err().to_string();
        for w in wants {
            assert!(e.contains(w), "{}: {e}", p.display());
        }
        assert!(start.elapsed().as_secs_f64() < 5.0, "{e}");
    };
    // the first fragment after the offset table declares 4 GiB - 16
    let p = damaged(d, "dicom_rle_ct.dcm", |b| {
        let pixel = find(b, &[0xE0, 0x7F, 0x10, 0x00, b'O', b'B']);
        let bot = pixel + 12;
        let bot_len = u32::from_le_bytes(b[bot + 4..bot + 8].try_into().unwrap()) as usize;
        let first = bot + 8 + bot_len;
        b[first + 4..first + 8].copy_from_slice(&0xFFFF_FFF0u32.to_le_bytes());
    });
    check(p, &["declares 4294967280 bytes"]);
    // a JPEG frame header of 65535 x 65535
    let p = damaged(d, "dicom_jpegll_ct.dcm", |b| {
        let sof = find(b, &[0xFF, 0xC3]);
        b[sof + 5..sof + 9].copy_from_slice(&[0xFF; 4]);
    });
    check(p, &["frame 1 of 5", "JPEG frame header says 65535 x 65535"]);
    // a JPEG 2000 image of 65535 x 65535 in one-pixel tiles
    let p = damaged(d, "dicom_j2k_ct.dcm", |b| {
        let siz = find(b, &[0xFF, 0x4F, 0xFF, 0x51]) + 4;
        b[siz + 4..siz + 12].copy_from_slice(&[0, 0, 0xFF, 0xFF, 0, 0, 0xFF, 0xFF]);
    });
    check(p, &["SIZ marker says 65535 x 65535"]);
    // tiles of width 0 (the unit tests refuse a 65535 x 65535 image of one-pixel tiles)
    let p = damaged(d, "dicom_j2k_ct.dcm", |b| {
        let siz = find(b, &[0xFF, 0x4F, 0xFF, 0x51]) + 4;
        b[siz + 20..siz + 24].copy_from_slice(&[0, 0, 0, 0]);
    });
    check(p, &["tiles (0 x 6 from 0, 0) do not cover the image"]);
    // an RLE header whose second segment starts past the frame
    let p = damaged(d, "dicom_rle_ct.dcm", |b| {
        let pixel = find(b, &[0xE0, 0x7F, 0x10, 0x00, b'O', b'B']);
        let bot = pixel + 12;
        let bot_len = u32::from_le_bytes(b[bot + 4..bot + 8].try_into().unwrap()) as usize;
        let header = bot + 16 + bot_len;
        b[header + 8..header + 12].copy_from_slice(&60000u32.to_le_bytes());
    });
    check(p, &["RLE header's segment offsets"]);
    // an offset table pointing inside a fragment (the fragmented JPEG)
    let p = damaged(d, "dicom_jpegll_fragments.dcm", |b| {
        let pixel = find(b, &[0xE0, 0x7F, 0x10, 0x00, b'O', b'B']);
        let bot = pixel + 12 + 8;
        b[bot + 4..bot + 8].copy_from_slice(&7u32.to_le_bytes());
    });
    check(p, &["not where a fragment starts"]);
    // NumberOfFrames larger than the per-frame groups, and than the grid's offsets
    // (explicit VR IS of 2 bytes, implicit VR: a 4-byte length)
    let frames = |n: &'static [u8; 2], name: &'static str, header: &'static [u8]| {
        damaged(d, name, move |b| {
            let at = find(b, header) + header.len();
            b[at..at + 2].copy_from_slice(n);
        })
    };
    let explicit: &[u8] = &[0x28, 0x00, 0x08, 0x00, b'I', b'S', 2, 0];
    let implicit: &[u8] = &[0x28, 0x00, 0x08, 0x00, 2, 0, 0, 0];
    check(
        frames(b"9 ", "dicom_mf_ct.dcm", explicit),
        &["5 items for NumberOfFrames 9"],
    );
    check(
        frames(b"99", "pydicom_rtdose.dcm", implicit),
        &["GridFrameOffsetVector (3004,000C) has 15 values"],
    );
}

#[cfg(unix)]
#[test]
fn confinement_covers_a_dicom_file_and_a_series_of_multi_frame_files() {
    let tmp = tempfile::tempdir().unwrap();
    let sub = tmp.path().join("submission");
    std::fs::create_dir(&sub).unwrap();
    std::os::unix::fs::symlink(fixture("dicom_rle_ct.dcm"), sub.join("link.dcm")).unwrap();
    let series = sub.join("series");
    std::fs::create_dir(&series).unwrap();
    std::fs::copy(
        fixture("dicom_mf_series/part1.dcm"),
        series.join("part1.dcm"),
    )
    .unwrap();
    std::os::unix::fs::symlink(
        fixture("dicom_mf_series/part2.dcm"),
        series.join("part2.dcm"),
    )
    .unwrap();
    for volume in ["link.dcm", "series\"\nformat = \"dicom"] {
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
