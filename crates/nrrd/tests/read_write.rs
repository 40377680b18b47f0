//! The reader and writer on files: every encoding and type read back as written,
//! prefixes of valid files, hostile sizes and overlong lines.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use nrrd::{Data, DataFile, Encoding, Endian, Error, NrrdHeader, Reader, ScalarType, Space};

/// The NRRD fixtures of the workspace (teem- and pynrrd-written files).
fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/fixtures/nrrd")
        .join(name)
}

fn temp_file(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn every_prefix_of_a_file_is_an_error_never_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let strict = [
        "u8_raw.nrrd",
        "i8_gzip.nrrd",
        "u16_bzip2.nrrd",
        "i32_hex_big.nrrd",
        "i16_raw_big.nrrd",
    ];
    for name in strict.into_iter().chain(["f32_ascii.nrrd"]) {
        let bytes = std::fs::read(fixture(name)).unwrap();
        assert!(nrrd::read(&temp_file(dir.path(), name, &bytes)).is_ok());
        for len in 0..bytes.len() {
            let p = temp_file(dir.path(), name, &bytes[..len]);
            match nrrd::read(&p) {
                Err(e) => assert!(e.to_string().contains(name), "{name}[..{len}]: {e}"),
                // Text data cut after (or inside) its last value can still be complete.
                Ok(_)
                    if name == "f32_ascii.nrrd"
                        || bytes[len..].iter().all(|b| b.is_ascii_whitespace()) =>
                {
                    assert!(
                        !strict.contains(&name) || name == "i32_hex_big.nrrd",
                        "{name}[..{len}] accepted"
                    )
                }
                Ok(_) => panic!("{name}: prefix of {len} bytes accepted"),
            }
        }
    }
}

#[test]
fn hostile_sizes_fail_fast_with_little_memory() {
    let dir = tempfile::tempdir().unwrap();
    // 4e9^3 voxels: the element count overflows, refused before reading anything.
    let p = temp_file(
        dir.path(),
        "huge.nrrd",
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4000000000 4000000000 4000000000\nencoding: raw\n\n\x00",
    );
    let e = nrrd::read(&p).unwrap_err();
    assert!(matches!(e, Error::TooLarge { bytes: None, .. }), "{e}");
    assert!(e.to_string().contains("huge.nrrd"), "{e}");

    // A small gzip stream claiming 2000^3 voxels (8 GB): allowed by the limits, so the
    // reader must find out that the data is short without allocating 8 GB.
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    std::io::Write::write_all(&mut gz, &[7u8; 1000]).unwrap();
    let mut file =
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2000 2000 2000\nencoding: gzip\n\n".to_vec();
    file.extend(gz.finish().unwrap());
    let p = temp_file(dir.path(), "bomb.nrrd", &file);
    let t = Instant::now();
    let e = nrrd::read(&p).unwrap_err().to_string();
    assert!(
        t.elapsed() < Duration::from_secs(2),
        "took {:?}",
        t.elapsed()
    );
    assert!(
        e.contains("data shorter than declared: expected 8000000000 bytes")
            && e.contains("got 1000"),
        "{e}"
    );

    // The same with raw data: the file length is checked before reading.
    let p = temp_file(
        dir.path(),
        "raw.nrrd",
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2000 2000 2000\nendian: little\nencoding: raw\n\n1234",
    );
    let t = Instant::now();
    let e = nrrd::read(&p).unwrap_err().to_string();
    assert!(t.elapsed() < Duration::from_secs(1));
    assert!(
        e.contains("expected 32000000000 bytes") && e.contains("got 4"),
        "{e}"
    );

    // Native-order raw data is mapped, not allocated: the memory limit does not apply,
    // the length check does.
    let e = Reader::new().max_bytes(1 << 20).read(&p).unwrap_err();
    assert!(matches!(e, Error::Data { .. }), "{e}");
    assert!(e.to_string().contains("got 4"), "{e}");

    // Data that has to be read (here byte-swapped) is refused by the limit itself.
    let p = temp_file(
        dir.path(),
        "raw_big.nrrd",
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2000 2000 2000\nendian: big\nencoding: raw\n\n1234",
    );
    let e = Reader::new().max_bytes(1 << 20).read(&p).unwrap_err();
    assert!(
        matches!(
            e,
            Error::TooLarge {
                bytes: Some(32_000_000_000),
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn overlong_header_line_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let mut file = b"NRRD0004\ncontent: ".to_vec();
    file.extend(std::iter::repeat_n(b'x', 2 << 20));
    let p = temp_file(dir.path(), "long.nrrd", &file);
    let e = nrrd::read(&p).unwrap_err().to_string();
    assert!(e.contains("long.nrrd:2: line is longer than"), "{e}");
}

// ------------------------------------------------------------------ round trips

/// Values that exercise every bit pattern class of a type.
fn samples(ty: ScalarType, n: usize, ascii: bool) -> Data {
    let ints: Vec<i128> = (0..n as i128).map(|i| i * 37 - 100).collect();
    macro_rules! int {
        ($t:ty, $v:ident) => {{
            let mut v: Vec<$t> = ints.iter().map(|&x| x as $t).collect();
            v[0] = <$t>::MIN;
            v[1] = <$t>::MAX;
            Data::$v(v)
        }};
    }
    match ty {
        ScalarType::Int8 => int!(i8, I8),
        ScalarType::Uint8 => int!(u8, U8),
        ScalarType::Int16 => int!(i16, I16),
        ScalarType::Uint16 => int!(u16, U16),
        ScalarType::Int32 => int!(i32, I32),
        ScalarType::Uint32 => int!(u32, U32),
        ScalarType::Int64 => int!(i64, I64),
        ScalarType::Uint64 => int!(u64, U64),
        ScalarType::Float32 => {
            let mut v: Vec<f32> = ints.iter().map(|&x| x as f32 / 7.0).collect();
            v[..6].copy_from_slice(&[
                f32::NAN,
                f32::INFINITY,
                f32::NEG_INFINITY,
                -0.0,
                f32::MIN_POSITIVE / 4.0,
                f32::MAX,
            ]);
            if !ascii {
                v[6] = f32::from_bits(0xffc0_1234); // negative NaN with a payload
            }
            Data::F32(v)
        }
        ScalarType::Float64 => {
            let mut v: Vec<f64> = ints.iter().map(|&x| x as f64 / 7.0).collect();
            v[..6].copy_from_slice(&[
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
                -0.0,
                5e-324,
                f64::MAX,
            ]);
            if !ascii {
                v[6] = f64::from_bits(0xfff8_0000_dead_beef);
            }
            Data::F64(v)
        }
    }
}

fn rich_header(ty: ScalarType, encoding: Encoding, endian: Endian) -> NrrdHeader {
    let mut h = NrrdHeader::new(ty, vec![3, 4, 5]).with_encoding(encoding);
    h.endian = endian;
    h.version = 5;
    h.content = Some("round trip".into());
    h.space = Some(Space::LeftPosteriorSuperior);
    h.space_dimension = Some(3);
    h.space_directions = Some(vec![
        Some(vec![0.5, 0.0, 0.0]),
        Some(vec![0.1, 1.0, 0.0]),
        Some(vec![0.0, -0.25, 3.0]),
    ]);
    h.space_origin = Some(vec![-1.5, 2.0, 1e-7]);
    h.space_units = Some(vec!["mm".into(), "mm".into(), "a \"quoted\" unit".into()]);
    h.measurement_frame = Some(vec![
        vec![1.0, 0.0, 0.0],
        vec![0.0, 1.0, 0.0],
        vec![0.0, 0.0, 1.0],
    ]);
    h.thicknesses = Some(vec![f64::NAN, 1.0, 2.5]);
    h.axis_mins = Some(vec![0.0, -1.0, 1e300]);
    h.centers = Some(vec!["cell".into(), "node".into(), "???".into()]);
    h.kinds = Some(vec!["domain".into(), "space".into(), "space".into()]);
    h.labels = Some(vec!["x".into(), "y y".into(), String::new()]);
    h.units = Some(vec!["mm".into(), "cm".into(), "m".into()]);
    h.sample_units = Some("HU".into());
    h.min = Some(-3.5);
    h.old_max = Some(4096.0);
    h.comments = vec!["a comment".into()];
    h.key_values = vec![
        ("plain".into(), "value".into()),
        ("with\\backslash".into(), "two\nlines and a \\n".into()),
        ("spaces in key".into(), "x:=y: z".into()),
    ];
    h
}

fn same_header(a: &NrrdHeader, b: &NrrdHeader, what: &str) {
    // NaN fields never compare equal: compare their formatting instead.
    assert_eq!(format!("{a:?}"), format!("{b:?}"), "{what}");
}

#[test]
fn round_trip_every_type_encoding_and_endian() {
    let dir = tempfile::tempdir().unwrap();
    let encodings = [
        Encoding::Raw,
        Encoding::Gzip,
        Encoding::Bzip2,
        Encoding::Ascii,
        Encoding::Hex,
    ];
    for ty in ScalarType::ALL {
        for enc in encodings {
            for endian in [Endian::Little, Endian::Big] {
                let what = format!("{ty} {} {}", enc.name(), endian.name());
                let h = rich_header(ty, enc, endian);
                let data = samples(ty, 60, enc == Encoding::Ascii);
                let bytes = nrrd::encode(&h, &data).unwrap();
                let p = temp_file(dir.path(), "rt.nrrd", &bytes);
                let (h2, d2) = nrrd::read(&p).unwrap_or_else(|e| panic!("{what}: {e}"));
                let mut want = h.clone();
                if ty.size() == 1 || enc == Encoding::Ascii {
                    want.endian = Endian::Little; // no endian line is written
                }
                same_header(&h2, &want, &what);
                assert_eq!(d2.as_bytes(), data.as_bytes(), "{what}");

                // detached
                let nhdr = dir.path().join("rt.nhdr");
                nrrd::write_detached(&nhdr, "rt data.bin", &h, &data).unwrap();
                let (h3, d3) = nrrd::read(&nhdr).unwrap_or_else(|e| panic!("{what} detached: {e}"));
                want.data_file = DataFile::Single("rt data.bin".into());
                same_header(&h3, &want, &format!("{what} detached"));
                assert_eq!(d3.as_bytes(), data.as_bytes(), "{what} detached");
            }
        }
    }
}

// ------------------------------------------------------------------ bad files

/// Every header of tests/bad/nrrd that is bad as a NRRD file (the others are valid
/// files that volcast refuses as 3D volumes) is refused, with a message naming it.
#[test]
fn bad_files_are_refused_with_a_message_naming_them() {
    // valid NRRD files, bad only as 3D volumes
    const VALID_NRRD: &[&str] = &[
        "directions_degenerate.nrrd",
        "directions_none_on_axis.nrrd",
        "four_d_not_droppable.nrrd",
        "space_time_4d.nrrd",
    ];
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/bad/nrrd");
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
    assert!(files.len() >= 60, "only {} bad files", files.len());
    let mut accepted = Vec::new();
    for path in files {
        let name = path.file_name().unwrap().to_str().unwrap().to_string();
        match Reader::new().max_bytes(1 << 30).read(&path) {
            Ok(_) => accepted.push(name),
            Err(e) => assert!(e.to_string().contains(&name), "{name}: {e}"),
        }
    }
    assert_eq!(accepted, VALID_NRRD, "accepted");
}
