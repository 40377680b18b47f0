//! TIFF stacks (issue 46, item 3), against files written by tifffile
//! (`tests/fixtures/formats/make_tiff.py`; the voxels, geometry and renders equal their
//! reference NRRDs in `formats.rs`'s PAIRS): what tifffile reports of each file, the
//! spacing and unit of the ImageJ description, resolution tags and OME-XML; channels
//! and time-series frames chosen and refused by count; colour, pages of another size,
//! truncated and hostile files refused by name, quickly; a folder's files under
//! `--confine`.

use std::path::PathBuf;
use std::time::Instant;

use volcast::volume::tiff::TiffSpec;
use volcast::volume::{Limits, ScalarType, VolumeError, VolumeSource};

use crate::util::{root, volcast};

fn fixture(name: &str) -> PathBuf {
    root().join("tests/fixtures/formats").join(name)
}

fn tiff(name: &str, channel: Option<usize>) -> VolumeSource {
    VolumeSource::Tiff(TiffSpec {
        path: fixture(name),
        channel,
        index: None,
    })
}

fn expected() -> serde_json::Value {
    let text = std::fs::read_to_string(fixture("tiff.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn field<'a>(fields: &'a [(String, String)], key: &str) -> &'a str {
    fields
        .iter()
        .find(|(k, _)| k == key)
        .map_or("", |(_, v)| v.as_str())
}

#[test]
fn each_file_holds_what_tifffile_reads() {
    let e = expected();
    let files = [
        "tiff_u8.tif",
        "tiff_u16_lzw.tif",
        "tiff_i16.tif",
        "tiff_f32_deflate.tif",
        "tiff_packbits.tif",
        "tiff_hyper.tif",
        "tiff_ome.ome.tif",
    ];
    for name in files {
        let x = &e[name];
        let channels = x["imagej"]["channels"].as_u64().unwrap_or(1) as usize;
        let shape: Vec<usize> = x["shape"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_u64().unwrap() as usize)
            .collect();
        // tifffile's shape is [(slices), (channels), rows, columns]
        let n = shape.len();
        let sizes = [shape[n - 1], shape[n - 2], shape[0]];
        let (mut sum, mut min, mut max) = (0.0, f64::INFINITY, f64::NEG_INFINITY);
        for c in 0..channels {
            let channel = (channels > 1).then_some(c);
            let v = tiff(name, channel).load(&Limits::default()).unwrap();
            assert_eq!(v.header.sizes, sizes, "{name}");
            assert_eq!(
                v.header.scalar_type,
                ScalarType::parse(x["dtype"].as_str().unwrap()).unwrap(),
                "{name}"
            );
            for i in 0..v.data.len() {
                let y = v.data.get_f64(i);
                sum += y;
                min = min.min(y);
                max = max.max(y);
            }
        }
        crate::assert_close!(sum, x["sum"].as_f64().unwrap(), 1e-9, "{name} sum");
        assert_eq!(min, x["min"].as_f64().unwrap(), "{name} min");
        assert_eq!(max, x["max"].as_f64().unwrap(), "{name} max");
        // the spacing is what ImageJ's description and resolution tags say
        let h = tiff(name, (channels > 1).then_some(0)).header().unwrap();
        let s = h.geometry.spacings();
        if let Some(ij) = x["imagej"].as_object() {
            let res = &x["resolution"];
            let per = |i: usize| res[i][1].as_f64().unwrap() / res[i][0].as_f64().unwrap();
            assert_eq!([s[0], s[1]], [per(0), per(1)], "{name}");
            assert_eq!(Some(s[2]), ij["spacing"].as_f64(), "{name}");
            assert_eq!(field(&h.fields, "unit"), "µm", "{name}");
        }
        assert_eq!(h.geometry.origin, glam::DVec3::ZERO, "{name}");
        let compression = field(&h.fields, "compression");
        let tifffile = x["compression"].as_str().unwrap();
        let same = matches!(
            (compression, tifffile),
            ("uncompressed", "NONE")
                | ("LZW", "LZW")
                | ("Deflate", "ADOBE_DEFLATE")
                | ("PackBits", "PACKBITS")
        );
        assert!(same, "{name}: {compression} vs tifffile's {tifffile}");
    }
    // OME-XML: PhysicalSizeZ in nm, read in the unit of X (µm)
    let ome = &e["tiff_ome.ome.tif"]["ome"];
    assert_eq!(ome["PhysicalSizeZ"], "1500.0");
    let h = tiff("tiff_ome.ome.tif", None).header().unwrap();
    assert_eq!(h.geometry.spacings(), [0.25, 0.4, 1.5]);
    assert_eq!(field(&h.fields, "format"), "OME-TIFF");
    // no ImageJ or OME description: resolution per centimetre is a pixel size, per
    // inch (or unitless) is not, and `info` says so
    let h = tiff("tiff_i16.tif", None).header().unwrap();
    assert_eq!(e["tiff_i16.tif"]["resolution_unit"], 3);
    assert_eq!(h.geometry.spacings(), [0.4, 0.5, 1.0]);
    assert_eq!(field(&h.fields, "unit"), "cm");
    assert!(field(&h.fields, "spacing z").starts_with("assumed 1"));
    let h = tiff("tiff_u8.tif", None).header().unwrap();
    assert!(field(&h.fields, "spacing").starts_with("assumed 1"));
}

#[test]
fn a_folder_or_glob_is_read_in_natural_name_order() {
    let e = expected();
    // the names sort img_10, img_11, img_12, img_8, img_9 as text
    assert_eq!(e["tiff_slices"]["files"][0], "img_10.tif");
    let folder = tiff("tiff_slices", None);
    let files = folder.input_files().unwrap();
    let names: Vec<String> = files
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "img_8.tif",
            "img_9.tif",
            "img_10.tif",
            "img_11.tif",
            "img_12.tif"
        ]
    );
    assert_eq!(
        tiff("tiff_slices/*.tif", None).input_files().unwrap(),
        files
    );
    assert_eq!(
        tiff("tiff_slices/img_1?.tif", None).input_files().unwrap(),
        files[2..]
    );
    // `volcast info` on the folder reads it as a TIFF series, not as DICOM
    assert!(matches!(
        VolumeSource::from_path(&fixture("tiff_slices")).unwrap(),
        VolumeSource::Tiff(_)
    ));
    let h = folder.header().unwrap();
    assert!(field(&h.fields, "format").starts_with("TIFF series (5 files"));
    // a slice of another size is refused by its name, with the first file's
    let err = tiff("tiff_bad_slices", None)
        .header()
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("s1.tif: 7 x 6 int32") && err.contains("s0.tif has 8 x 6 int32"),
        "{err}"
    );
    let err = tiff("tiff_slices/*.tiff", None)
        .header()
        .unwrap_err()
        .to_string();
    assert!(err.contains("no TIFF files"), "{err}");
}

#[test]
fn channels_are_chosen_and_counted() {
    let err = |s: VolumeSource| s.header().unwrap_err().to_string();
    let e = err(tiff("tiff_hyper.tif", None));
    assert!(
        e.contains("tiff_hyper.tif")
            && e.contains("2 channels")
            && e.contains("`channel = 0` to 1"),
        "{e}"
    );
    let e = err(tiff("tiff_hyper.tif", Some(2)));
    assert!(
        e.contains("channel = 2 is out of range") && e.contains("2 channels"),
        "{e}"
    );
    let e = err(tiff("tiff_u8.tif", Some(1)));
    assert!(e.contains("1 channel (channel = 0)"), "{e}");
    assert!(tiff("tiff_u8.tif", Some(0)).header().is_ok());
    let h = tiff("tiff_hyper.tif", Some(1)).header().unwrap();
    assert_eq!(field(&h.fields, "channel"), "1 of 2");
    assert_eq!(field(&h.fields, "pages"), "10");
    // the two channels differ, and each is its reference (formats.rs)
    let a = tiff("tiff_hyper.tif", Some(0))
        .load(&Limits::default())
        .unwrap();
    let b = tiff("tiff_hyper.tif", Some(1))
        .load(&Limits::default())
        .unwrap();
    assert!(a.data != b.data);
}

#[test]
fn a_time_series_shows_the_frame_of_its_index() {
    let frames = |index| {
        VolumeSource::Tiff(TiffSpec {
            path: fixture("tiff_frames.tif"),
            channel: None,
            index,
        })
    };
    let e = frames(None).header().unwrap_err().to_string();
    assert!(
        e.contains("tiff_frames.tif") && e.contains("2 frames") && e.contains("`index = 0` to 1"),
        "{e}"
    );
    let e = frames(Some(2)).header().unwrap_err().to_string();
    assert!(e.contains("index = 2 is out of range"), "{e}");
    let h = frames(Some(1)).header().unwrap();
    assert_eq!(field(&h.fields, "frame"), "1 of 2 (index)");
    assert_eq!(h.sizes, [8, 6, 5]);
    // OME: the frame and channel strides follow DimensionOrder
    let h = tiff("tiff_ome_c2.ome.tif", Some(1)).header().unwrap();
    assert_eq!(field(&h.fields, "format"), "OME-TIFF (2 channels)");
    assert_eq!(
        expected()["tiff_ome_c2.ome.tif"]["ome"]["DimensionOrder"],
        "XYZCT"
    );
}

#[test]
fn colour_and_damaged_files_are_refused_by_name() {
    let cases: &[(&str, &[&str])] = &[
        (
            "tiff_rgb.tif",
            &[
                "tiff_rgb.tif",
                "page 0",
                "colour",
                "RGB, 3 samples per pixel",
            ],
        ),
        (
            "tiff_mixed.tif",
            &[
                "tiff_mixed.tif",
                "page 2 has 8 x 4 uint8",
                "page 0 8 x 6 uint8",
            ],
        ),
        (
            "tiff_truncated.tif",
            &[
                "tiff_truncated.tif",
                "page 2",
                "past the end of the file",
                "truncated",
            ],
        ),
    ];
    for &(name, needles) in cases {
        let e = tiff(name, None).load(&Limits::default()).unwrap_err();
        let text = e.to_string();
        for n in needles {
            assert!(text.contains(n), "{name}: expected {n:?} in {text}");
        }
    }
    // WhiteIsZero (the fifth entry's value, PhotometricInterpretation, set to 0)
    let tmp = tempfile::tempdir().unwrap();
    let mut bytes = hostile(2, 4, 1, 0);
    assert_eq!(u16::from_le_bytes([bytes[58], bytes[59]]), 262);
    bytes[66] = 0;
    let p = tmp.path().join("white.tif");
    std::fs::write(&p, bytes).unwrap();
    let e = VolumeSource::Tiff(TiffSpec {
        path: p,
        channel: None,
        index: None,
    })
    .header()
    .unwrap_err()
    .to_string();
    assert!(e.contains("white.tif") && e.contains("WhiteIsZero"), "{e}");
    // a file that is not a TIFF at all
    let e = tiff("u8.mha", None).header().unwrap_err().to_string();
    assert!(e.contains("u8.mha") && e.contains("not a TIFF file"), "{e}");
}

/// A little-endian TIFF of one page of `width` x `height` 16-bit samples whose one
/// strip holds 16 bytes, compressed with `compression`, the next directory at `next`.
fn hostile(width: u32, height: u32, compression: u16, next: u32) -> Vec<u8> {
    let entries: [(u16, u16, u32); 8] = [
        (256, 4, width),
        (257, 4, height),
        (258, 3, 16),
        (259, 3, u32::from(compression)),
        (262, 3, 1),
        (273, 4, 200),
        (278, 4, height),
        (279, 4, 16),
    ];
    let mut b = b"II*\0".to_vec();
    b.extend_from_slice(&8u32.to_le_bytes());
    b.extend_from_slice(&(entries.len() as u16).to_le_bytes());
    for (tag, ty, value) in entries {
        b.extend_from_slice(&tag.to_le_bytes());
        b.extend_from_slice(&ty.to_le_bytes());
        b.extend_from_slice(&1u32.to_le_bytes());
        if ty == 3 {
            b.extend_from_slice(&(value as u16).to_le_bytes());
            b.extend_from_slice(&[0, 0]);
        } else {
            b.extend_from_slice(&value.to_le_bytes());
        }
    }
    b.extend_from_slice(&next.to_le_bytes());
    b.resize(216, 0);
    b
}

#[test]
fn hostile_sizes_are_refused_before_allocating() {
    let tmp = tempfile::tempdir().unwrap();
    let write = |name: &str, bytes: Vec<u8>| {
        let p = tmp.path().join(name);
        std::fs::write(&p, bytes).unwrap();
        VolumeSource::Tiff(TiffSpec {
            path: p,
            channel: None,
            index: None,
        })
    };
    // a sane page of 2 x 4 samples in its 16 bytes reads
    let ok = write("ok.tif", hostile(2, 4, 1, 0));
    assert_eq!(ok.load(&Limits::default()).unwrap().header.sizes, [2, 4, 1]);
    let start = Instant::now();
    // 100000 x 100000 16-bit samples (20 GB) from 16 bytes, raw or Deflate; 4000 x
    // 4000 (32 MB, within any limit) from 16 bytes of PackBits
    for (name, w, h, c) in [
        ("huge.tif", 100_000, 100_000, 1),
        ("huge_deflate.tif", 100_000, 100_000, 8),
        ("packbits.tif", 4000, 4000, 32773),
    ] {
        let e = write(name, hostile(w, h, c, 0)).load(&Limits::default());
        let text = e.unwrap_err().to_string();
        assert!(
            text.contains(name) && text.contains("cannot come from its 16 bytes"),
            "{text}"
        );
    }
    // a readable page beyond volcast's limit: TooLarge, naming the file
    let e = write("big.tif", hostile(2, 4, 1, 0))
        .load(&Limits { max_bytes: 8 })
        .unwrap_err();
    assert!(
        matches!(&e, VolumeError::TooLarge { what, .. } if what.contains("big.tif")),
        "{e}"
    );
    // a directory that names itself as the next: a cycle, not an endless stack
    let e = write("cycle.tif", hostile(2, 4, 1, 8))
        .header()
        .unwrap_err();
    assert!(e.to_string().contains("cycle.tif"), "{e}");
    assert!(
        start.elapsed().as_millis() < 500,
        "refusing took {:?}",
        start.elapsed()
    );
}

#[test]
fn scenes_choose_tiff_and_channel() {
    let tmp = tempfile::tempdir().unwrap();
    let check = |volume: &str| {
        std::fs::write(
            tmp.path().join("s.toml"),
            format!("[volume]\n{volume}\n[image]\nsize = [8, 8]\n[[render]]\nmode = \"mip\"\n"),
        )
        .unwrap();
        volcast(tmp.path(), &["check", "s.toml"])
    };
    let path = |name: &str| format!("path = {:?}", fixture(name).display().to_string());
    let o = check(&format!("{}\nchannel = 1", path("tiff_hyper.tif")));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = check(&format!("{}\nindex = 1", path("tiff_frames.tif")));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = check(&format!("{}\nformat = \"tiff\"", path("tiff_slices")));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (volume, needle) in [
        (
            format!("{}\nchannel = 0", path("u8.mha")),
            "`channel` is only used by TIFF files",
        ),
        (
            format!("{}\nchannel = -1", path("tiff_hyper.tif")),
            "channel = -1: expected",
        ),
        (path("tiff_hyper.tif"), "`channel = 0` to 1"),
    ] {
        let o = check(&volume);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && err.contains(needle),
            "{volume}: {err}"
        );
    }
}

#[test]
fn info_describes_a_tiff() {
    let o = volcast(
        &root(),
        &["info", "tests/fixtures/formats/tiff_u16_lzw.tif", "--json"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let f = &j["fields"];
    assert_eq!(f["format"], "TIFF (ImageJ)");
    assert_eq!(f["pages"], "5");
    assert_eq!(f["compression"], "LZW");
    assert_eq!(f["unit"], "µm");
    assert_eq!(f["spacing z"], "spacing= (ImageJ)");
    // a hyperstack: `info` describes its first channel, and says so
    let o = volcast(
        &root(),
        &["info", "tests/fixtures/formats/tiff_hyper.tif", "--json"],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["fields"]["channel"], "0 of 2");
    assert_eq!(
        j["fields"]["format"],
        "TIFF (ImageJ hyperstack, 2 channels)"
    );
}

#[cfg(unix)]
#[test]
fn confinement_covers_every_file_of_a_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let sub = tmp.path().join("submission");
    let slices = sub.join("slices");
    std::fs::create_dir_all(&slices).unwrap();
    // slices linking to files outside the folder the run is confined to
    for e in std::fs::read_dir(fixture("tiff_slices")).unwrap() {
        let p = e.unwrap().path();
        std::os::unix::fs::symlink(&p, slices.join(p.file_name().unwrap())).unwrap();
    }
    std::os::unix::fs::symlink(fixture("tiff_u8.tif"), sub.join("link.tif")).unwrap();
    for volume in ["slices\"\nformat = \"tiff", "slices/*.tif", "link.tif"] {
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
            "{volume}: {err}"
        );
        let o = volcast(&sub, &["check", "s.toml"]);
        assert!(
            o.status.success(),
            "{volume} without --confine: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}
