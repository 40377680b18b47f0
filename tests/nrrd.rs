//! NRRD reader/writer against files written by teem and pynrrd.
//!
//! The fixtures (tests/fixtures/nrrd, made by make_fixtures.sh with teem's `unu` and by
//! make_pynrrd.py with pynrrd) hold 4×3×2 volumes whose value at (i, j, k) is a formula
//! of f = i + 10j + 100k; the expected values are computed here from the formulas, never
//! read back with our own code.

use std::path::{Path, PathBuf};

use glam::DVec3;
use volcast::volume::nrrd::{self, DataFile, Encoding, Endian, NrrdHeader, NrrdHeaderExt, Space};
use volcast::volume::{Limits, ScalarType, VolumeData, VolumeError, VolumeSource};

use crate::util::{root, shared_data};

fn fixture(name: &str) -> PathBuf {
    root().join("tests/fixtures/nrrd").join(name)
}

/// The 24 values of f = i + 10j + 100k in memory order (x fastest).
fn f_values() -> Vec<i128> {
    let mut v = Vec::new();
    for k in 0..2 {
        for j in 0..3 {
            for i in 0..4 {
                v.push(i + 10 * j + 100 * k);
            }
        }
    }
    v
}

/// Data as exact values (integers as i128, floats through their f64 value).
#[derive(Debug, PartialEq)]
enum Exact {
    Int(Vec<i128>),
    Float(Vec<f64>),
}

fn exact(d: &VolumeData) -> Exact {
    use volcast::volume::TypedVoxels as T;
    match d.typed() {
        T::I8(v) => Exact::Int(v.iter().map(i128::from).collect()),
        T::U8(v) => Exact::Int(v.iter().map(i128::from).collect()),
        T::I16(v) => Exact::Int(v.iter().map(i128::from).collect()),
        T::U16(v) => Exact::Int(v.iter().map(i128::from).collect()),
        T::I32(v) => Exact::Int(v.iter().map(i128::from).collect()),
        T::U32(v) => Exact::Int(v.iter().map(i128::from).collect()),
        T::I64(v) => Exact::Int(v.iter().map(i128::from).collect()),
        T::U64(v) => Exact::Int(v.iter().map(i128::from).collect()),
        T::F32(v) => Exact::Float(v.iter().map(f64::from).collect()),
        T::F64(v) => Exact::Float(v.iter().collect()),
    }
}

fn ints(formula: impl Fn(i128) -> i128) -> Exact {
    Exact::Int(f_values().into_iter().map(formula).collect())
}

fn floats(formula: impl Fn(f64) -> f64) -> Exact {
    Exact::Float(f_values().into_iter().map(|f| formula(f as f64)).collect())
}

/// Reads a fixture and checks type, sizes and values.
fn check_fixture(name: &str, ty: ScalarType, want: Exact) -> NrrdHeader {
    let (h, data) =
        nrrd::read(&fixture(name), &Limits::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(h.scalar_type, ty, "{name}: type");
    assert_eq!(data.scalar_type(), ty, "{name}: data type");
    assert_eq!(h.sizes, vec![4, 3, 2], "{name}: sizes");
    assert_eq!(exact(&data), want, "{name}: values");
    h
}

#[test]
fn every_type_endian_and_encoding_written_by_teem() {
    use ScalarType::*;
    let cases: Vec<(&str, ScalarType, Encoding, Endian, Exact)> = vec![
        (
            "u8_raw.nrrd",
            Uint8,
            Encoding::Raw,
            Endian::Little,
            ints(|f| f),
        ),
        (
            "i8_gzip.nrrd",
            Int8,
            Encoding::Gzip,
            Endian::Little,
            ints(|f| f - 60),
        ),
        (
            "i16_raw_big.nrrd",
            Int16,
            Encoding::Raw,
            Endian::Big,
            ints(|f| 100 * f - 5000),
        ),
        (
            "u16_bzip2.nrrd",
            Uint16,
            Encoding::Bzip2,
            Endian::Little,
            ints(|f| 500 * f),
        ),
        (
            "i32_hex_big.nrrd",
            Int32,
            Encoding::Hex,
            Endian::Big,
            ints(|f| 100_000 * f - 6_000_000),
        ),
        (
            "u32_ascii.nrrd",
            Uint32,
            Encoding::Ascii,
            Endian::Little,
            ints(|f| 30_000_000 * f),
        ),
        (
            "i64_gzip_big.nrrd",
            Int64,
            Encoding::Gzip,
            Endian::Big,
            ints(|f| 1_000_000_000_000 * f - 50_000_000_000_000),
        ),
        (
            "u64_raw.nrrd",
            Uint64,
            Encoding::Raw,
            Endian::Little,
            ints(|f| 100_000_000_000_000_000 * f),
        ),
        (
            "f32_gzip_big.nrrd",
            Float32,
            Encoding::Gzip,
            Endian::Big,
            floats(|f| 0.5 * f - 20.25),
        ),
        (
            "f64_bzip2.nrrd",
            Float64,
            Encoding::Bzip2,
            Endian::Little,
            floats(|f| 0.125 * f - 7.5),
        ),
        (
            "f32_ascii.nrrd",
            Float32,
            Encoding::Ascii,
            Endian::Little,
            floats(|f| 0.5 * f - 20.25),
        ),
        (
            "f64_hex_big.nrrd",
            Float64,
            Encoding::Hex,
            Endian::Big,
            floats(|f| 0.125 * f - 7.5),
        ),
    ];
    for (name, ty, enc, endian, want) in cases {
        let h = check_fixture(name, ty, want);
        assert_eq!(h.encoding, enc, "{name}: encoding");
        assert_eq!(h.version, 1, "{name}: teem writes NRRD0001 for these");
        if ty.size() > 1 && enc != Encoding::Ascii {
            assert_eq!(h.endian, endian, "{name}: endian");
        }
        assert_eq!(h.data_file, DataFile::Attached);
        assert_eq!(
            h.comments[1], "http://teem.sourceforge.net/nrrd/format.html",
            "{name}: comments"
        );
        let v = h.volume_header(&fixture(name)).unwrap();
        assert_eq!(v.sizes, [4, 3, 2]);
        assert_eq!(
            v.geometry,
            volcast::volume::Geometry::from_spacing([1.0; 3])
        );
    }
}

#[test]
fn two_d_image_with_spacings() {
    let path = fixture("u8_2d_spacings.nrrd");
    let vol = VolumeSource::Nrrd(path.clone())
        .load(&Limits::default())
        .unwrap();
    assert_eq!(vol.header.sizes, [5, 4, 1]);
    assert_eq!(vol.header.geometry.spacings(), [0.5, 2.0, 1.0]);
    for j in 0..4 {
        for i in 0..5 {
            assert_eq!(vol.value(i, j, 0), (i + 10 * j) as f64);
        }
    }
    assert_eq!(vol.header.source, path.display().to_string());
}

fn assert_vec(got: DVec3, want: [f64; 3], what: &str) {
    assert!(
        (got - DVec3::from(want)).length() < 1e-12,
        "{what}: got {got}, want {want:?}"
    );
}

#[test]
fn space_directions_sheared_and_origin() {
    let path = fixture("space_ras_sheared.nrrd");
    let h = check_fixture(
        "space_ras_sheared.nrrd",
        ScalarType::Float32,
        floats(|f| 0.5 * f - 20.25),
    );
    assert_eq!(h.space, Some(Space::RightAnteriorSuperior));
    assert_eq!(h.space_dimension, Some(3));
    assert_eq!(h.space_units, Some(vec!["mm".to_string(); 3]));
    let v = h.volume_header(&path).unwrap();
    assert_vec(v.geometry.axes[0], [1.0, 0.0, 0.0], "axis 0");
    assert_vec(v.geometry.axes[1], [0.5, 1.0, 0.0], "axis 1");
    assert_vec(v.geometry.axes[2], [0.0, 0.25, 2.0], "axis 2");
    assert_vec(v.geometry.origin, [1.0, 2.0, 3.0], "origin");
    // voxel (3, 2, 1) is at origin + 3 a0 + 2 a1 + 1 a2
    let w = v.geometry.world_from_index(DVec3::new(3.0, 2.0, 1.0));
    assert_vec(w, [5.0, 4.25, 5.0], "world position");
    assert!(v
        .fields
        .contains(&("space".into(), "right-anterior-superior".into())));
    assert!(v
        .fields
        .contains(&("space units".into(), "mm mm mm".into())));

    let h = check_fixture(
        "space_mf_gzip.nrrd",
        ScalarType::Float64,
        floats(|f| 0.125 * f - 7.5),
    );
    assert_eq!(h.version, 5);
    assert_eq!(h.space, None);
    assert_eq!(h.space_dimension, Some(3));
    assert_eq!(
        h.measurement_frame,
        Some(vec![
            vec![1.0, 0.0, 0.0],
            vec![0.0, 1.0, 0.0],
            vec![0.0, 0.0, 1.0]
        ])
    );
    let v = h.volume_header(&fixture("space_mf_gzip.nrrd")).unwrap();
    assert_eq!(v.geometry.spacings(), [2.0, 3.0, 4.0]);
    assert_vec(v.geometry.origin, [-1.0, -2.0, -3.0], "origin");
}

#[test]
fn detached_headers_single_file_and_named_data() {
    for name in ["detached_u16.nhdr", "named_data.nrrd"] {
        let h = check_fixture(name, ScalarType::Uint16, ints(|f| 500 * f));
        assert_eq!(h.endian, Endian::Big);
        assert!(
            matches!(&h.data_file, DataFile::Single(n) if n.ends_with("detached_u16.raw")),
            "{:?}",
            h.data_file
        );
    }
    let h = nrrd::read_header(&fixture("detached_u16.nhdr")).unwrap();
    assert_eq!(h.spacings, Some(vec![0.5, 1.0, 2.0]));
    assert_eq!(h.kinds, Some(vec!["domain".to_string(); 3]));
    assert_eq!(h.content.as_deref(), Some("detached test"));
    assert_eq!(
        h.key_values,
        vec![("k1".into(), "v1".into()), ("k2".into(), "v2".into())]
    );
    let v = h.volume_header(&fixture("detached_u16.nhdr")).unwrap();
    assert_eq!(v.geometry.spacings(), [0.5, 1.0, 2.0]);
    assert!(v
        .fields
        .contains(&("content".into(), "detached test".into())));
    assert!(v.fields.contains(&("k1".into(), "v1".into())));
}

#[test]
fn several_data_files_pattern_and_list() {
    let h = check_fixture(
        "pattern_slices.nhdr",
        ScalarType::Int16,
        ints(|f| 100 * f - 5000),
    );
    assert_eq!(
        h.data_file,
        DataFile::Pattern {
            format: "slice%03d.raw".into(),
            min: 1,
            max: 2,
            step: 1,
            subdim: None
        }
    );
    let h = check_fixture("pattern_rows.nhdr", ScalarType::Int8, ints(|f| f - 60));
    assert!(matches!(
        h.data_file,
        DataFile::Pattern {
            subdim: Some(1),
            ..
        }
    ));
    let h = check_fixture(
        "list.nhdr",
        ScalarType::Float32,
        floats(|f| 0.5 * f - 20.25),
    );
    assert_eq!(
        h.data_file,
        DataFile::List {
            names: vec!["list_0.raw".into(), "list_1.raw".into()],
            subdim: None
        }
    );
}

#[test]
fn line_and_byte_skips() {
    let h = check_fixture(
        "skips_lines_bytes.nhdr",
        ScalarType::Uint16,
        ints(|f| 500 * f),
    );
    assert_eq!((h.line_skip, h.byte_skip), (2, 5));
    let h = check_fixture(
        "byteskip_tail.nhdr",
        ScalarType::Float32,
        floats(|f| 0.5 * f - 20.25),
    );
    assert_eq!(h.byte_skip, -1);
    // gzip: the byte skip applies to the decompressed stream (teem's rule).
    let h = check_fixture(
        "gzip_byteskip.nhdr",
        ScalarType::Int32,
        ints(|f| 100_000 * f - 6_000_000),
    );
    assert_eq!((h.encoding, h.byte_skip), (Encoding::Gzip, 7));
    // ascii: a text line skipped, values separated by commas.
    let h = check_fixture(
        "ascii_lineskip.nhdr",
        ScalarType::Int16,
        ints(|f| 100 * f - 5000),
    );
    assert_eq!(h.line_skip, 1);
}

#[test]
fn field_names_in_other_cases_and_spellings() {
    let h = check_fixture("hand_aliases.nhdr", ScalarType::Uint16, ints(|f| 500 * f));
    assert_eq!(
        h.comments,
        vec![
            "hand-written by make_fixtures.sh",
            "a comment between fields"
        ]
    );
    let v = h.volume_header(&fixture("hand_aliases.nhdr")).unwrap();
    // a nan spacing counts as 1
    assert_eq!(v.geometry.spacings(), [2.0, 1.0, 3.0]);
}

#[test]
fn files_written_by_pynrrd() {
    let name = "py_lps_sheared_gzip.nrrd";
    let h = check_fixture(name, ScalarType::Int16, ints(|f| 100 * f - 5000));
    assert_eq!(h.version, 5);
    assert_eq!(h.space, Some(Space::LeftPosteriorSuperior));
    assert_eq!(h.content.as_deref(), Some("pynrrd test"));
    assert_eq!(h.sample_units.as_deref(), Some("HU"));
    assert_eq!(
        h.key_values,
        vec![
            (
                "patient name".to_string(),
                "Jane Doe: test = yes".to_string()
            ),
            ("path".to_string(), "C:\\data".to_string())
        ]
    );
    let v = h.volume_header(&fixture(name)).unwrap();
    assert_vec(v.geometry.axes[1], [0.5, 1.0, 0.0], "sheared axis");
    assert_vec(v.geometry.origin, [1.5, -2.0, 3.0], "origin");
    assert!(v
        .fields
        .contains(&("patient name".into(), "Jane Doe: test = yes".into())));

    let h = check_fixture(
        "py_detached_bz2.nhdr",
        ScalarType::Float64,
        floats(|f| 0.125 * f - 7.5),
    );
    assert_eq!(h.encoding, Encoding::Bzip2);
    assert_eq!(
        h.data_file,
        DataFile::Single("py_detached_bz2.raw.bz2".into())
    );
    assert_eq!(h.spacings, Some(vec![2.0, 1.5, 0.25]));
    check_fixture(
        "py_u64_big.nrrd",
        ScalarType::Uint64,
        ints(|f| f + (1 << 60)),
    );
    check_fixture(
        "py_i64_ascii.nrrd",
        ScalarType::Int64,
        ints(|f| 1_000_000_000_000 * f - 50_000_000_000_000),
    );
    check_fixture(
        "py_f32_ascii.nrrd",
        ScalarType::Float32,
        floats(|f| 0.25 * f - 7.5),
    );

    // 2D data in a 2D space: the z = 0 plane, unit z axis.
    let vol = VolumeSource::Nrrd(fixture("py_2d_space.nrrd"))
        .load(&Limits::default())
        .unwrap();
    assert_eq!(vol.header.sizes, [5, 4, 1]);
    assert_vec(vol.header.geometry.axes[0], [0.5, 0.0, 0.0], "2D axis 0");
    assert_vec(vol.header.geometry.axes[1], [0.0, 2.0, 0.0], "2D axis 1");
    assert_vec(vol.header.geometry.axes[2], [0.0, 0.0, 1.0], "2D axis 2");
    assert_vec(vol.header.geometry.origin, [10.0, 20.0, 0.0], "2D origin");
    assert_eq!(vol.value(4, 3, 0), 34.0);

    // 4D with a leading non-spatial axis of size 1 (`none`): dropped.
    let vol = VolumeSource::Nrrd(fixture("py_4d_none.nrrd"))
        .load(&Limits::default())
        .unwrap();
    assert_eq!(vol.header.sizes, [4, 3, 2]);
    assert_eq!(exact(&vol.data), ints(|f| f));
    assert_eq!(
        vol.header.geometry,
        volcast::volume::Geometry::from_spacing([1.0; 3])
    );
}

// ------------------------------------------------------------------ bad input

fn bad_files() -> Vec<PathBuf> {
    let dir = root().join("tests/bad/nrrd");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            matches!(
                p.extension().and_then(|e| e.to_str()),
                Some("nrrd" | "nhdr")
            )
        })
        .collect();
    files.sort();
    files
}

#[test]
fn every_bad_file_is_rejected_with_a_message_naming_it() {
    let files = bad_files();
    assert!(files.len() >= 60, "only {} bad files", files.len());
    for path in files {
        let name = path.file_name().unwrap().to_str().unwrap();
        let err = match VolumeSource::Nrrd(path.clone()).load(&Limits::default()) {
            Ok(_) => panic!("{name} was accepted"),
            Err(e) => e.to_string(),
        };
        assert!(
            err.contains(name),
            "{name}: message does not name the file: {err}"
        );
        println!("{err}");
    }
}

/// The error of a bad file, for checks of the wording.
fn bad(name: &str) -> (VolumeError, String) {
    let e = VolumeSource::Nrrd(root().join("tests/bad/nrrd").join(name))
        .load(&Limits::default())
        .unwrap_err();
    let s = e.to_string();
    (e, s)
}

#[test]
fn bad_headers_name_line_field_and_expectation() {
    let (e, s) = bad("sizes_count.nhdr");
    assert!(matches!(e, VolumeError::Header { line: 4, .. }), "{e:?}");
    assert!(
        s.ends_with("sizes_count.nhdr:4: sizes: expected 3 positive integers (dimension 3), got \"256 256\""),
        "{s}"
    );
    let (_, s) = bad("duplicate_field.nrrd");
    assert!(
        s.contains(":6: duplicate field `sizes` (first given on line 4)"),
        "{s}"
    );
    let (_, s) = bad("unknown_field.nrrd");
    assert!(s.contains(":6: unknown field \"colour\""), "{s}");
    let (_, s) = bad("missing_endian.nrrd");
    assert!(s.contains("missing field `endian`"), "{s}");
    let (_, s) = bad("missing_encoding.nrrd");
    assert!(s.contains("missing required field `encoding`"), "{s}");
    let (e, s) = bad("type_block.nrrd");
    assert!(
        matches!(e, VolumeError::Unsupported { .. }) && s.contains("block"),
        "{s}"
    );
    let (_, s) = bad("non_utf8_header.nrrd");
    assert!(
        s.contains("non_utf8_header.nrrd:3: line is not UTF-8"),
        "{s}"
    );
    let (_, s) = bad("byteskip_minus1_gzip.nhdr");
    assert!(
        s.contains(":6: byte skip: -1") && s.contains("only with raw"),
        "{s}"
    );
    let (e, _) = bad("directions_degenerate.nrrd");
    assert!(matches!(e, VolumeError::Header { line: 0, .. }), "{e:?}");
    let (e, s) = bad("hostile_sizes.nrrd");
    assert!(matches!(e, VolumeError::TooLarge { .. }), "{s}");
}

#[test]
fn bad_data_says_expected_and_got() {
    let (e, s) = bad("short_raw.nrrd");
    assert!(matches!(e, VolumeError::Data { .. }));
    assert!(
        s.contains("data shorter than declared: expected 8 bytes") && s.ends_with("got 7"),
        "{s}"
    );
    let (_, s) = bad("short_gzip.nrrd");
    assert!(s.contains("expected 8 bytes") && s.contains("got 5"), "{s}");
    let (_, s) = bad("long_gzip.nrrd");
    assert!(
        s.contains("gzip data continues past the 8 bytes that sizes × type declare"),
        "{s}"
    );
    let (_, s) = bad("ascii_too_few.nrrd");
    assert!(s.contains("7 values, but sizes declare 8"), "{s}");
    let (_, s) = bad("ascii_too_many.nrrd");
    assert!(s.contains("more than the 8 values"), "{s}");
    let (_, s) = bad("ascii_garbage.nrrd");
    assert!(
        s.contains("\"five\"") && s.contains("value 5, line 2"),
        "{s}"
    );
    let (_, s) = bad("hex_bad_digit.nrrd");
    assert!(s.contains("'g'"), "{s}");
    let (_, s) = bad("pattern_missing_file.nhdr");
    assert!(
        s.contains("data7.raw") && s.contains("data file 1 of 2 named by"),
        "{s}"
    );
}

fn temp_file(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn altered_headers_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let bytes = std::fs::read(fixture("space_ras_sheared.nrrd")).unwrap();
    let header_len = bytes.windows(2).position(|w| w == b"\n\n").unwrap();
    for pos in 0..header_len {
        for replacement in [b'0', b'9', b'-', b' ', b'\n', b':', b'(', 0xff] {
            let mut b = bytes.clone();
            b[pos] = replacement;
            let p = temp_file(dir.path(), "mutant.nrrd", &b);
            // Either outcome is fine; panics are not.
            let _ = VolumeSource::Nrrd(p).load(&Limits::default());
        }
    }
}

// ------------------------------------------------------------------ round trips

#[test]
fn renderer_output_headers() {
    // What the output module writes: float images, optionally RGBA with kinds.
    let dir = tempfile::tempdir().unwrap();
    let h = NrrdHeader::new(ScalarType::Float32, vec![4, 3, 2])
        .with_kinds(["RGBA-color", "space", "space"])
        .with_spacings([f64::NAN, 1.0, 1.0]);
    let data = VolumeData::F32((0..24).map(|i| i as f32 * 0.25).collect());
    let bytes = nrrd::encode(&h, &data).unwrap();
    let text = String::from_utf8_lossy(&bytes[..bytes.len() - 96]).into_owned();
    assert!(
        text.starts_with("NRRD0004\ntype: float\ndimension: 3\nsizes: 4 3 2\n"),
        "{text}"
    );
    assert!(
        text.contains(
            "spacings: nan 1 1\nkinds: RGBA-color space space\nendian: little\nencoding: raw\n\n"
        ),
        "{text}"
    );
    let p = temp_file(dir.path(), "img.nrrd", &bytes);
    let (h2, d2) = nrrd::read(&p, &Limits::default()).unwrap();
    assert_eq!(d2, data);
    assert_eq!(h2.kinds, h.kinds);
    // dimension 3: the sizes are taken as they are
    assert!(h2.volume_header(&p).unwrap().sizes == [4, 3, 2]);
}

// ------------------------------------------------------------------ real data

/// sizes, type, spacing (x y z), min, max, sum of all voxels, value at (10, 20, 30).
type Expected = ([usize; 3], ScalarType, [f64; 3], f64, f64, i64, f64);

#[test]
fn real_volumes_in_shared_data() {
    let Some(dir) = shared_data() else {
        println!("skipping: ../shared/data not found");
        return;
    };
    // sizes/type/spacing: ../shared/data/README.md.
    // min/max: `teem-unu minmax FILE` (teem 1.12.0, Debian teem-apps 1.12.0~20160122-5).
    // sum and value: pynrrd 1.1.3, `d, _ = nrrd.read(FILE)` (index order F = x, y, z),
    //   `int(d.astype("int64").sum())` and `d[10, 20, 30]`.
    let cases: [(&str, Expected); 8] = [
        (
            "ct_engine.nrrd",
            (
                [256, 256, 110],
                ScalarType::Uint8,
                [1.0, 1.0, 1.0],
                0.0,
                255.0,
                187_475_047,
                0.0,
            ),
        ),
        (
            "ct_head_0051.nrrd",
            (
                [256, 256, 108],
                ScalarType::Int16,
                [0.9570312, 0.9570312, 1.5],
                -1024.0,
                2986.0,
                -4_147_325_847,
                -1009.0,
            ),
        ),
        (
            "ct_head_stanford.nrrd",
            (
                [256, 256, 113],
                ScalarType::Int16,
                [1.0, 1.0, 2.0],
                0.0,
                3272.0,
                2_810_724_494,
                25.0,
            ),
        ),
        (
            "ct_head_vtk_quarter.nrrd",
            (
                [64, 64, 93],
                ScalarType::Int16,
                [3.2, 3.2, 1.5],
                0.0,
                3926.0,
                193_392_317,
                861.0,
            ),
        ),
        (
            "cta_stent.nrrd",
            (
                [128, 128, 256],
                ScalarType::Int16,
                [1.0, 1.0, 1.0],
                0.0,
                2000.0,
                148_470_906,
                62.0,
            ),
        ),
        (
            "embryo.nrrd",
            (
                [256, 256, 256],
                ScalarType::Uint8,
                [1.0, 1.0, 1.0],
                0.0,
                197.0,
                63_724_611,
                0.0,
            ),
        ),
        (
            "mr_head_colin27.nrrd",
            (
                [181, 217, 181],
                ScalarType::Uint8,
                [1.0, 1.0, 1.0],
                0.0,
                254.0,
                317_151_210,
                0.0,
            ),
        ),
        (
            "mr_head_unc.nrrd",
            (
                [256, 256, 109],
                ScalarType::Uint8,
                [1.0, 1.0, 1.5],
                0.0,
                255.0,
                101_266_709,
                2.0,
            ),
        ),
    ];
    for (name, (sizes, ty, spacing, min, max, sum, value)) in cases {
        let path = dir.join(name);
        let vol = VolumeSource::Nrrd(path.clone())
            .load(&Limits::default())
            .unwrap_or_else(|e| panic!("{e}"));
        let h = &vol.header;
        assert_eq!(h.sizes, sizes, "{name}");
        assert_eq!(h.scalar_type, ty, "{name}");
        for (got, want) in h.geometry.spacings().into_iter().zip(spacing) {
            crate::assert_close!(got, want, 1e-9, "{name} spacing");
        }
        let n = vol.data.len();
        let (mut lo, mut hi, mut total) = (f64::INFINITY, f64::NEG_INFINITY, 0i64);
        for i in 0..n {
            let v = vol.data.get_f64(i);
            lo = lo.min(v);
            hi = hi.max(v);
            total += v as i64;
        }
        assert_eq!((lo, hi), (min, max), "{name} min/max");
        assert_eq!(total, sum, "{name} sum");
        assert_eq!(vol.value(10, 20, 30), value, "{name} value at (10, 20, 30)");
        assert!(
            h.fields.iter().any(|(k, _)| k == "license"),
            "{name}: key/value pairs kept"
        );
    }
    let h = nrrd::read_header(&dir.join("mr_head_colin27.nrrd")).unwrap();
    assert_eq!(h.space, Some(Space::RightAnteriorSuperior));
    let v = h.volume_header(&dir.join("mr_head_colin27.nrrd")).unwrap();
    assert_vec(v.geometry.origin, [-90.0, -125.0, -71.0], "colin27 origin");
}
