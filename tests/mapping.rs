//! Memory-mapped volumes: raw data in the machine's byte order is mapped, at any byte
//! offset (hence any alignment), and reads exactly like the same data read and
//! decoded into memory; the other byte order and other encodings are still read; the
//! errors for data that does not fit are the same either way; `--max-memory` limits
//! only what is read.

use std::fmt::Debug;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use volcast::volume::nrrd::{self, Encoding, Endian, NrrdHeader};
use volcast::volume::raw::RawSpec;
use volcast::volume::{
    Limits, ReadReason, ScalarType, Stats, Storage, Volume, VolumeData, VolumeError, VolumeSource,
    Voxel,
};
use volcast::with_voxels;

const SIZES: [usize; 3] = [5, 3, 2];
const COUNT: usize = 30;

/// The byte order NRRD headers call native here, and the other one.
fn native() -> &'static str {
    if cfg!(target_endian = "little") {
        "little"
    } else {
        "big"
    }
}

fn swapped() -> &'static str {
    if cfg!(target_endian = "little") {
        "big"
    } else {
        "little"
    }
}

/// No room for anything read: only mapped data loads under this limit.
fn tiny() -> Limits {
    Limits { max_bytes: 1 }
}

/// 30 values of `ty` covering its range (negative and fractional where it allows).
fn reference(ty: ScalarType) -> VolumeData {
    let values: Vec<f64> = (0..COUNT)
        .map(|i| {
            let i = i as f64;
            match ty {
                ScalarType::Uint8 => (i * 37.0) % 256.0,
                ScalarType::Int16 => i * 2111.0 - 30000.0,
                ScalarType::Uint16 => i * 2203.0 + 1.0,
                ScalarType::Float32 | ScalarType::Float64 => (i - 11.0) * 0.375 + 1e-3,
                _ => i,
            }
        })
        .collect();
    VolumeData::from_f64s(ty, &values)
}

/// The data's bytes in native order, or swapped.
fn bytes(d: &VolumeData, native: bool) -> Vec<u8> {
    let size = d.scalar_type().size();
    let b = with_voxels!(d, v => v.as_bytes().to_vec());
    if native {
        b
    } else {
        b.chunks(size)
            .flat_map(|c| c.iter().rev().copied())
            .collect()
    }
}

fn write(path: &Path, parts: &[&[u8]]) -> PathBuf {
    let mut f = std::fs::File::create(path).unwrap();
    for p in parts {
        f.write_all(p).unwrap();
    }
    path.to_path_buf()
}

fn raw(path: &Path, ty: ScalarType, little_endian: bool, offset: i64) -> VolumeSource {
    VolumeSource::Raw(RawSpec {
        path: path.to_path_buf(),
        sizes: SIZES,
        scalar_type: ty,
        little_endian,
        spacing: [1.0, 1.0, 1.0],
        offset,
    })
}

/// A NRRD header's text for `SIZES` of `ty` with the given endian and extra lines,
/// ending with the blank line when `attached`.
fn header_text(ty: ScalarType, endian: &str, extra: &str, attached: bool) -> String {
    format!(
        "NRRD0005\ntype: {}\ndimension: 3\nsizes: 5 3 2\nendian: {endian}\nencoding: raw\n{extra}{}",
        ty.nrrd_name(),
        if attached { "\n" } else { "" }
    )
}

/// An attached header padded with a comment so that the data starts at an offset
/// that is 3 more than a multiple of 8 (misaligned for every multi-byte type).
fn odd_header(ty: ScalarType, endian: &str, extra: &str) -> String {
    let mut pad = String::new();
    loop {
        let h = header_text(ty, endian, &format!("{extra}# pad{pad}\n"), true);
        if h.len() % 8 == 3 {
            return h;
        }
        pad.push('x');
    }
}

/// Loads `source` under a limit that admits nothing read: it must be mapped, at
/// `offset`, hold `want`, and agree with `storage()`.
fn assert_mapped<T: Voxel + PartialEq + Debug>(
    what: &str,
    source: &VolumeSource,
    want: &VolumeData,
    file: &Path,
    offset: u64,
) -> Volume {
    let v = source
        .load(&tiny())
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    let m = v
        .data
        .mapped()
        .unwrap_or_else(|| panic!("{what}: not mapped"));
    assert_eq!(m.path(), file, "{what}: mapped file");
    assert_eq!(m.offset(), offset, "{what}: offset");
    let size = T::TYPE.size() as u64;
    assert_eq!(
        source.storage().unwrap(),
        Storage::Mapped {
            path: file.to_path_buf(),
            offset,
            bytes: COUNT as u64 * size,
        },
        "{what}"
    );
    let got: Vec<T> = v.data.voxels::<T>().unwrap().iter().collect();
    let exp: Vec<T> = want.voxels::<T>().unwrap().iter().collect();
    assert_eq!(got, exp, "{what}: voxels");
    assert_eq!(&v.data, want, "{what}: data");
    assert_eq!(v.data.allocated_bytes(), 0, "{what}");
    assert_eq!(v.data.byte_len() as u64, COUNT as u64 * size, "{what}");
    // aligned views are borrowed, misaligned ones copied, with the same values
    let vox = v.data.voxels::<T>().unwrap();
    assert_eq!(
        vox.as_slice().is_some(),
        offset.is_multiple_of(std::mem::align_of::<T>() as u64),
        "{what}: alignment"
    );
    assert_eq!(
        &*vox.to_aligned(&Limits::default()).unwrap(),
        &exp[..],
        "{what}: to_aligned"
    );
    assert_eq!(
        vox.to_aligned(&tiny()).is_ok(),
        offset.is_multiple_of(std::mem::align_of::<T>() as u64),
        "{what}: an aligned copy is checked against the limit"
    );
    v
}

/// Loads `source`, which must be read (not mapped), and checks its values; with a
/// limit that admits nothing, it must be refused.
fn assert_read(what: &str, source: &VolumeSource, want: &VolumeData, reason: ReadReason) {
    let v = source
        .load(&Limits::default())
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    assert!(!v.data.is_mapped(), "{what}: mapped");
    assert_eq!(&v.data, want, "{what}: data");
    assert_eq!(
        source.storage().unwrap(),
        Storage::Read {
            bytes: want.byte_len() as u64,
            reason
        },
        "{what}"
    );
    let e = source.load(&tiny()).unwrap_err();
    assert!(matches!(e, VolumeError::TooLarge { .. }), "{what}: {e}");
}

fn mapped_equals_read<T: Voxel + PartialEq + Debug>() {
    let ty = T::TYPE;
    let size = ty.size() as u64;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let want = reference(ty);
    let (nat, swp) = (bytes(&want, true), bytes(&want, false));
    let le = cfg!(target_endian = "little");
    let name = |s: &str| format!("{ty} {s}");

    // the read reference: the same values, gzip-compressed
    let mut h = NrrdHeader::new(ty, SIZES.to_vec()).with_encoding(Encoding::Gzip);
    h.endian = Endian::Little;
    let gz = write(&d.join("ref.nrrd"), &[&nrrd::encode(&h, &want).unwrap()]);
    assert_read(
        &name("gzip"),
        &VolumeSource::Nrrd(gz),
        &want,
        ReadReason::Encoding(Encoding::Gzip),
    );

    // raw, offset 3
    let p = write(&d.join("o3.raw"), &[b"abc", &nat]);
    assert_mapped::<T>(&name("raw offset 3"), &raw(&p, ty, le, 3), &want, &p, 3);
    let p = write(&d.join("o3_swapped.raw"), &[b"abc", &swp]);
    let src = raw(&p, ty, !le, 3);
    if size == 1 {
        assert_mapped::<T>(&name("raw offset 3, other order"), &src, &want, &p, 3);
    } else {
        assert_read(
            &name("raw offset 3, other order"),
            &src,
            &want,
            ReadReason::ByteOrder,
        );
    }

    // raw, offset -1 after 5 bytes of something else
    let p = write(&d.join("tail.raw"), &[b"12345", &nat]);
    assert_mapped::<T>(&name("raw offset -1"), &raw(&p, ty, le, -1), &want, &p, 5);

    // attached header of a length that misaligns the data
    let text = odd_header(ty, native(), "");
    let p = write(&d.join("odd.nrrd"), &[text.as_bytes(), &nat]);
    let off = text.len() as u64;
    assert_eq!(off % 8, 3);
    assert_mapped::<T>(
        &name("attached, odd header"),
        &VolumeSource::Nrrd(p),
        &want,
        &d.join("odd.nrrd"),
        off,
    );
    let text = odd_header(ty, swapped(), "");
    let p = write(&d.join("odd_swapped.nrrd"), &[text.as_bytes(), &swp]);
    if size == 1 {
        assert!(VolumeSource::Nrrd(p)
            .load(&tiny())
            .unwrap()
            .data
            .is_mapped());
    } else {
        assert_read(
            &name("attached, other order"),
            &VolumeSource::Nrrd(p),
            &want,
            ReadReason::ByteOrder,
        );
    }

    // attached, `byte skip: -1`: the data is the last bytes, after 7 bytes of junk
    let text = odd_header(ty, native(), "byte skip: -1\n");
    let p = write(&d.join("skip-1.nrrd"), &[text.as_bytes(), b"junk..!", &nat]);
    let off = text.len() as u64 + 7;
    assert_mapped::<T>(
        &name("byte skip -1"),
        &VolumeSource::Nrrd(p.clone()),
        &want,
        &p,
        off,
    );

    // detached: the header maps its data file, after `line skip` lines and a byte skip
    let text = header_text(
        ty,
        native(),
        "line skip: 2\nbyte skip: 1\ndata file: lines.raw\n",
        false,
    );
    let nhdr = write(&d.join("lines.nhdr"), &[text.as_bytes()]);
    let data = write(&d.join("lines.raw"), &[b"first line\nsecond\n", b"#", &nat]);
    assert_mapped::<T>(
        &name("line skip"),
        &VolumeSource::Nrrd(nhdr),
        &want,
        &data,
        19,
    );

    // detached, plain: offset 0, aligned
    let text = header_text(ty, native(), "data file: plain.raw\n", false);
    let nhdr = write(&d.join("plain.nhdr"), &[text.as_bytes()]);
    let data = write(&d.join("plain.raw"), &[&nat]);
    let v = assert_mapped::<T>(
        &name("detached"),
        &VolumeSource::Nrrd(nhdr),
        &want,
        &data,
        0,
    );
    assert_eq!(Stats::of(&v.data), Stats::of(&want), "{ty}: stats");
    let text = header_text(ty, swapped(), "data file: plain_swapped.raw\n", false);
    let nhdr = write(&d.join("plain_swapped.nhdr"), &[text.as_bytes()]);
    write(&d.join("plain_swapped.raw"), &[&swp]);
    if size > 1 {
        assert_read(
            &name("detached, other order"),
            &VolumeSource::Nrrd(nhdr),
            &want,
            ReadReason::ByteOrder,
        );
    }
}

#[test]
fn mapped_loads_equal_read_loads_at_odd_offsets() {
    mapped_equals_read::<u8>();
    mapped_equals_read::<i16>();
    mapped_equals_read::<u16>();
    mapped_equals_read::<f32>();
    mapped_equals_read::<f64>();
}

#[test]
fn multi_file_data_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let want = reference(ScalarType::Int16);
    let nat = bytes(&want, true);
    let text = header_text(
        ScalarType::Int16,
        native(),
        "data file: LIST\nslab0.raw\nslab1.raw",
        false,
    );
    let nhdr = write(&d.join("list.nhdr"), &[text.as_bytes()]);
    write(&d.join("slab0.raw"), &[&nat[..30]]);
    write(&d.join("slab1.raw"), &[&nat[30..]]);
    assert_read(
        "LIST",
        &VolumeSource::Nrrd(nhdr),
        &want,
        ReadReason::DataFiles(2),
    );
}

/// The error of loading `native_bytes` and then `swapped_bytes` from the same path,
/// described by `source_for(little_endian)`: they must be the same.
fn same_error(
    path: &Path,
    native_bytes: &[&[u8]],
    swapped_bytes: &[&[u8]],
    source_for: impl Fn(bool) -> VolumeSource,
) -> String {
    let le = cfg!(target_endian = "little");
    write(path, native_bytes);
    let mapped = source_for(le)
        .load(&Limits::default())
        .unwrap_err()
        .to_string();
    let storage = source_for(le).storage().unwrap_err().to_string();
    write(path, swapped_bytes);
    let read = source_for(!le)
        .load(&Limits::default())
        .unwrap_err()
        .to_string();
    assert_eq!(mapped, read);
    assert_eq!(mapped, storage);
    mapped
}

#[test]
fn data_that_does_not_fit_gives_the_same_errors_mapped_or_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ty = ScalarType::Int16;
    let want = reference(ty);
    let (nat, swp) = (bytes(&want, true), bytes(&want, false));

    // raw: too short, too long, too short for offset -1
    let p = d.join("v.raw");
    let e = same_error(&p, &[b"abc", &nat[1..]], &[b"abc", &swp[1..]], |le| {
        raw(&p, ty, le, 3)
    });
    assert!(
        e.contains("file is 62 bytes, but offset 3 + 5 × 3 × 2 int16 = 60 bytes needs 63"),
        "{e}"
    );
    let e = same_error(&p, &[b"abcd", &nat], &[b"abcd", &swp], |le| {
        raw(&p, ty, le, 3)
    });
    assert!(e.contains("use offset 4 (or -1)"), "{e}");
    let e = same_error(&p, &[&nat[1..]], &[&swp[1..]], |le| raw(&p, ty, le, -1));
    assert!(e.contains("file is 59 bytes, shorter than the"), "{e}");

    // NRRD attached: too short; `byte skip: -1` too short
    let p = d.join("v.nrrd");
    let (hn, hs) = (
        header_text(ty, native(), "", true),
        header_text(ty, swapped(), "", true),
    );
    let e = same_error(
        &p,
        &[hn.as_bytes(), &nat[..59]],
        &[hs.as_bytes(), &swp[..59]],
        |_| VolumeSource::Nrrd(p.clone()),
    );
    assert!(
        e.contains("data shorter than declared: expected 60 bytes (sizes × type), got 59"),
        "{e}"
    );
    // `byte skip: -1` with a data file shorter than the data
    let nhdr = d.join("tail.nhdr");
    write(&d.join("tail.raw"), &[&nat[..59]]);
    let e = same_error(
        &nhdr,
        &[header_text(ty, native(), "byte skip: -1\ndata file: tail.raw\n", false).as_bytes()],
        &[header_text(ty, swapped(), "byte skip: -1\ndata file: tail.raw\n", false).as_bytes()],
        |_| VolumeSource::Nrrd(nhdr.clone()),
    );
    assert!(
        e.contains(
            "`byte skip: -1` takes the last 60 bytes (sizes × type), but the file has only 59"
        ),
        "{e}"
    );

    // NRRD detached, line skip past the end of the data file
    let nhdr = d.join("v.nhdr");
    let data = d.join("v.raw");
    write(&data, &[b"only one line\n"]);
    let e = same_error(
        &nhdr,
        &[header_text(ty, native(), "line skip: 3\ndata file: v.raw\n", false).as_bytes()],
        &[header_text(ty, swapped(), "line skip: 3\ndata file: v.raw\n", false).as_bytes()],
        |_| VolumeSource::Nrrd(nhdr.clone()),
    );
    assert!(
        e.contains("file ends after 1 of the 3 lines that `line skip` skips"),
        "{e}"
    );
    assert!(e.contains("data file 1 of 1 named by"), "{e}");
}

#[test]
fn special_files_are_refused_quickly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ty = ScalarType::Uint8;

    // a directory as data file
    std::fs::create_dir(d.join("folder.raw")).unwrap();
    let nhdr = write(
        &d.join("dir.nhdr"),
        &[header_text(ty, native(), "data file: folder.raw\n", false).as_bytes()],
    );
    let e = VolumeSource::Nrrd(nhdr)
        .load(&Limits::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("folder.raw: is a directory, not a regular file")
            && e.contains("(data file 1 of 1 named by"),
        "{e}"
    );
    let e = raw(&d.join("folder.raw"), ty, true, 0)
        .header()
        .unwrap_err();
    assert!(
        e.to_string().contains("is a directory, not a regular file"),
        "{e}"
    );

    // a FIFO: refused without waiting for a writer
    let fifo = d.join("pipe.raw");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success());
    if !made {
        eprintln!("mkfifo not available: FIFO case skipped");
        return;
    }
    let nhdr = write(
        &d.join("fifo.nhdr"),
        &[header_text(ty, native(), "data file: pipe.raw\n", false).as_bytes()],
    );
    let t = Instant::now();
    let e = VolumeSource::Nrrd(nhdr.clone())
        .load(&Limits::default())
        .unwrap_err();
    assert!(
        e.to_string()
            .contains("is a FIFO (named pipe), not a regular file"),
        "{e}"
    );
    let e = VolumeSource::Nrrd(nhdr).storage().unwrap_err();
    assert!(e.to_string().contains("FIFO"), "{e}");
    let e = raw(&fifo, ty, true, 0)
        .load(&Limits::default())
        .unwrap_err();
    assert!(e.to_string().contains("FIFO"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(5));
}

#[test]
fn synthetic_volumes_are_computed_into_memory() {
    let s = volcast::volume::Synthetic::new(
        volcast::volume::synthetic::Field::Gaussian { sigma: 0.25 },
        [4, 4, 4],
    );
    assert_eq!(
        VolumeSource::Synthetic(s).storage().unwrap(),
        Storage::Read {
            bytes: 256,
            reason: ReadReason::Synthetic
        }
    );
}

/// A small MIP of a uint16 raw volume renders the same bytes mapped at a misaligned
/// offset (the old render core gets an aligned copy) and read from big-endian data.
#[test]
fn mapped_and_read_volumes_render_alike() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = [12usize, 10, 8];
    let values: Vec<f64> = (0..n[0] * n[1] * n[2])
        .map(|i| ((i * 7919) % 4001) as f64)
        .collect();
    let data = VolumeData::from_f64s(ScalarType::Uint16, &values);
    write(&d.join("native.raw"), &[b"xyz", &bytes(&data, true)]);
    write(&d.join("swapped.raw"), &[b"xyz", &bytes(&data, false)]);
    let films = |file: &str, endian: &str| {
        let text = format!(
            "[volume]\npath = \"{file}\"\nsizes = [12, 10, 8]\ntype = \"uint16\"\nendian = \"{endian}\"\noffset = 3\n\
             [camera]\nazimuth = 30\nelevation = 20\n[image]\nsize = [16, 16]\nformat = \"nrrd\"\n\
             [[render]]\nmode = \"mip\"\n[[render]]\nmode = \"xray\"\n"
        );
        let scene =
            volcast::scene::parse(&text, &d.join("s.toml")).unwrap_or_else(|e| panic!("{e}"));
        let (views, _) =
            volcast::pipeline::render_films(&scene, &Default::default(), &Limits::default())
                .unwrap_or_else(|e| panic!("{e}"));
        views
            .into_iter()
            .flat_map(|v| v.film.data.into_iter().map(f32::to_bits))
            .collect::<Vec<u32>>()
    };
    let mapped = films("native.raw", native());
    let read = films("swapped.raw", swapped());
    assert!(!mapped.is_empty());
    assert_eq!(mapped, read);
}

/// `--max-memory` limits what is read (and everything else volcast allocates), not
/// what is mapped: `check`, `render` and `info` accept a mapped volume larger than
/// the limit and refuse the read one.
#[test]
fn max_memory_applies_to_read_volumes_only() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let values: Vec<f64> = (0..64 * 64 * 64).map(|i| (i % 97) as f64).collect();
    let data = VolumeData::from_f64s(ScalarType::Uint16, &values);
    write(&d.join("native.raw"), &[&bytes(&data, true)]);
    write(&d.join("swapped.raw"), &[&bytes(&data, false)]);
    for (name, file, endian) in [
        ("native", "native.raw", native()),
        ("swapped", "swapped.raw", swapped()),
    ] {
        std::fs::write(
            d.join(format!("{name}.toml")),
            format!(
                "[volume]\npath = \"{file}\"\nsizes = [64, 64, 64]\ntype = \"uint16\"\nendian = \"{endian}\"\n\
                 [image]\nsize = [8, 8]\nout = \"out/{name}\"\n[[render]]\nmode = \"mip\"\n"
            ),
        )
        .unwrap();
    }
    let run = |args: &[&str]| {
        let o = crate::util::volcast(d, args);
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stdout).into_owned(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    for cmd in ["check", "render", "info"] {
        // 512 KiB of voxels; the rest of the run (tables, images) needs about 300 KiB
        let (ok, out, err) = run(&[cmd, "native.toml", "--max-memory", "400K"]);
        assert!(ok, "{cmd} native: {out}{err}");
        if cmd == "info" {
            assert!(out.contains("mapped from"), "{out}");
        }
        let (ok, out, err) = run(&[cmd, "swapped.toml", "--max-memory", "400K"]);
        assert!(!ok, "{cmd} swapped: {out}");
        let expected = if cmd == "info" {
            "set --max-memory to raise it"
        } else {
            "allowed by --max-memory"
        };
        assert!(err.contains(expected), "{cmd}: {err}");
    }
    let (ok, out, _) = run(&["info", "swapped.toml", "--json"]);
    assert!(ok && out.contains("\"storage\": \"read\""), "{out}");

    // The render core reads mapped voxels where they are: 16-bit voxels at an odd
    // offset need no aligned copy, so the limit does not apply to them either.
    write(&d.join("odd.raw"), &[b"x", &bytes(&data, true)]);
    let scene = std::fs::read_to_string(d.join("native.toml"))
        .unwrap()
        .replace("native.raw\"", "odd.raw\"\noffset = 1")
        .replace("out/native", "out/odd");
    std::fs::write(d.join("odd.toml"), scene).unwrap();
    let (ok, out, err) = run(&["render", "odd.toml", "--max-memory", "400K"]);
    assert!(ok, "{out}{err}");
    assert_eq!(
        std::fs::read(d.join("out/odd/mip_0000.png")).unwrap(),
        std::fs::read(d.join("out/native/mip_0000.png")).unwrap(),
        "the unaligned mapping renders the same image"
    );
}
