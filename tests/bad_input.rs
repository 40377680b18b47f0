//! Bad input of every class gets one clear message naming the file, the place and
//! what was expected: never a panic (exit status 101), never an output file.

use std::path::Path;
use std::time::Instant;

use crate::util::volcast;

/// Writes `scene` as `bad.toml` in a fresh folder, runs `render` on it, asserts it
/// failed cleanly without writing anything, and returns stderr.
fn reject(scene: &str, files: &[(&str, &[u8])]) -> String {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("bad.toml"), scene).unwrap();
    for (name, bytes) in files {
        std::fs::write(tmp.path().join(name), bytes).unwrap();
    }
    let o = volcast(tmp.path(), &["render", "bad.toml"]);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(
        o.status.code(),
        Some(1),
        "expected a clean failure, got {:?}: {err}",
        o.status
    );
    assert!(
        !tmp.path().join("out").exists(),
        "an output folder was created for a bad scene: {err}"
    );
    assert!(err.starts_with("volcast: error: "), "{err}");
    err
}

fn assert_has(err: &str, needles: &[&str]) {
    for n in needles {
        assert!(err.contains(n), "`{n}` missing from:\n{err}");
    }
}

#[test]
fn toml_syntax_errors_have_line_and_column() {
    let err = reject("[volume]\nsynthetic = \"ball\"\n[camera\n", &[]);
    assert_has(&err, &["bad.toml:3:8", "[camera"]);
}

#[test]
fn unknown_keys_get_a_suggestion() {
    let err = reject(
        "[volume]\nsynthetic = \"ball\"\n[camera]\nazimth = 3\n",
        &[],
    );
    assert_has(
        &err,
        &[
            "bad.toml:4:1",
            "unknown field `azimth`",
            "did you mean `azimuth`?",
        ],
    );
    let err = reject(
        "[volume]\nsynthetic = \"ball\"\n[[render]]\nmode = \"surfce\"\n",
        &[],
    );
    assert_has(&err, &["bad.toml:4:8", "did you mean `surface`?"]);
    let err = reject(
        "[volume]\nsynthetic = \"ball\"\n[[render]]\nmode = \"surface\"\nmaterial = \"gld\"\n",
        &[],
    );
    assert_has(&err, &["bad.toml:5:12", "did you mean `gold`?"]);
}

#[test]
fn wrong_types_and_ranges_name_what_was_expected() {
    let err = reject(
        "[volume]\nsynthetic = \"ball\"\n[camera]\nfov = \"wide\"\n",
        &[],
    );
    assert_has(&err, &["bad.toml:4:7", "expected"]);
    let err = reject("[volume]\nsynthetic = \"ball\"\n[camera]\nfov = 300\n", &[]);
    assert_has(&err, &["bad.toml:4:7", "fov = 300", "degrees in (0, 180)"]);
    let err = reject(
        "[volume]\nsynthetic = \"ball\"\n[image]\nsize = [10]\n",
        &[],
    );
    assert_has(&err, &["bad.toml:4:8", "length"]);
}

#[test]
fn a_parameter_the_mode_does_not_use_names_the_modes_that_do() {
    let err = reject(
        "[volume]\nsynthetic = \"ball\"\n[[render]]\nmode = \"mip\"\niso = 0.5\n",
        &[],
    );
    assert_has(
        &err,
        &[
            "bad.toml:5:7",
            "`iso` is not used by mode = \"mip\"",
            "\"surface\"",
        ],
    );
    let err = reject(
        "[volume]\nsynthetic = \"ball\"\n[[render]]\nmode = \"depth\"\ntransfer = \"bone\"\n",
        &[],
    );
    assert_has(
        &err,
        &[
            "`transfer` is not used by mode = \"depth\"",
            "\"composite\"",
        ],
    );
}

#[test]
fn all_problems_are_reported_at_once() {
    let err = reject(
        "[volume]\nsynthetic = \"ball\"\n[[render]]\nmode = \"mip\"\nthreshold = 2\n[[render]]\nmode = \"composite\"\ntransfer = \"nope\"\n",
        &[],
    );
    assert_has(&err, &["bad.toml:5:", "bad.toml:8:", "2 problems"]);
}

#[test]
fn missing_and_conflicting_sources() {
    let err = reject("[camera]\nfov = 20\n", &[]);
    assert_has(&err, &["bad.toml:1:1", "missing [volume] table"]);
    let err = reject("[volume]\n", &[]);
    assert_has(&err, &["needs `path`", "or `synthetic`"]);
    let err = reject("[volume]\npath = \"a.nrrd\"\nsynthetic = \"ball\"\n", &[]);
    assert_has(&err, &["either `path` or `synthetic`"]);
    // synthetic fields come as float32, uint8 or uint16; the raw-file keys stay refused
    let err = reject(
        "[volume]\nsynthetic = \"blobs\"\ntype = \"int8\"\nendian = \"big\"\n",
        &[],
    );
    assert_has(
        &err,
        &[
            "type = \"int8\" is not known",
            "`float32`, `uint8`, `uint16`",
            "`endian`",
        ],
    );
    let err = reject("[volume]\npath = \"a.nrrd\"\nsizes = [2, 2, 2]\n", &[]);
    assert_has(&err, &["`sizes` is not used by NRRD files"]);
    let err = reject("[volume]\npath = \"a.dat\"\n", &[]);
    assert_has(&err, &["cannot tell the format", "format = \"raw\""]);
}

#[test]
fn missing_volume_files_name_the_file() {
    let err = reject("[volume]\npath = \"gone.nrrd\"\n", &[]);
    assert_has(&err, &["rendering bad.toml", "gone.nrrd", "No such file"]);
}

#[test]
fn bad_nrrd_headers_name_the_file_and_line() {
    let nrrd = b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2\nencoding: raw\n\n12345678";
    let err = reject("[volume]\npath = \"v.nrrd\"\n", &[("v.nrrd", nrrd)]);
    assert_has(&err, &["v.nrrd:4", "sizes"]);
}

#[test]
fn hostile_sizes_fail_fast_in_little_memory() {
    let start = Instant::now();
    let nrrd = b"NRRD0004\ntype: float\ndimension: 3\nsizes: 4000000000 4000000000 4000000000\nendian: little\nencoding: raw\n\n";
    let err = reject("[volume]\npath = \"v.nrrd\"\n", &[("v.nrrd", nrrd)]);
    assert_has(&err, &["v.nrrd", "limit"]);
    // within the memory limit but far larger than the data: the 2000^3 gzip volume
    // is 8 GB of floats; the few bytes present must be found short, quickly
    let mut gz = Vec::new();
    {
        use std::io::Write;
        let mut e = flate2::write::GzEncoder::new(&mut gz, flate2::Compression::default());
        e.write_all(&[0u8; 1000]).unwrap();
        e.finish().unwrap();
    }
    let mut file =
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2000 2000 2000\nencoding: gzip\n\n".to_vec();
    file.extend_from_slice(&gz);
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("v.nrrd"), &file).unwrap();
    let o = volcast(tmp.path(), &["info", "v.nrrd"]);
    assert_eq!(o.status.code(), Some(1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("v.nrrd"), "{err}");
    assert!(
        start.elapsed().as_secs_f64() < 10.0,
        "took {:?}",
        start.elapsed()
    );
}

#[test]
fn raw_files_of_the_wrong_length_are_rejected() {
    let err = reject(
        "[volume]\npath = \"v.raw\"\nformat = \"raw\"\nsizes = [4, 4, 4]\ntype = \"uint16\"\n",
        &[("v.raw", &[0u8; 100])],
    );
    assert_has(&err, &["v.raw", "128"]);
}

#[test]
fn anaglyph_needs_a_picture_format() {
    let err = reject(
        "[volume]\nsynthetic = \"ball\"\n[stereo]\nlayout = \"anaglyph\"\n[image]\nformat = \"nrrd\"\n",
        &[],
    );
    assert_has(&err, &["bad.toml:4:10", "anaglyph"]);
}

#[test]
fn frame_ranges_outside_the_orbit_are_rejected_before_writing() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("s.toml"),
        "[volume]\nsynthetic = \"ball\"\n[orbit]\nframes = 3\n",
    )
    .unwrap();
    let o = volcast(tmp.path(), &["render", "s.toml", "--frames", "2..5"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not within the orbit's 3 frames"));
    assert!(!tmp.path().join("out").exists());
}

/// Non-finite voxels in float data must not poison an image: a raw float volume
/// with NaN and infinities renders finite pixels in every mode.
#[test]
fn non_finite_voxels_do_not_poison_images() {
    let tmp = tempfile::tempdir().unwrap();
    let n = 12usize;
    let mut bytes = Vec::new();
    for idx in 0..n * n * n {
        let v: f32 = match idx % 7 {
            0 => f32::NAN,
            1 => f32::INFINITY,
            2 => f32::NEG_INFINITY,
            _ => (idx % 13) as f32 / 13.0,
        };
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    std::fs::write(tmp.path().join("v.raw"), &bytes).unwrap();
    let mut scene = String::from(
        "[volume]\npath = \"v.raw\"\nformat = \"raw\"\nsizes = [12, 12, 12]\ntype = \"float32\"\n\
         [camera]\nprojection = \"orthographic\"\nzoom = 2.0\n[image]\nsize = [16, 16]\nformat = \"nrrd\"\n",
    );
    for mode in [
        "xray",
        "mip",
        "minip",
        "average",
        "lmip",
        "depth",
        "surface",
        "composite",
    ] {
        scene += &format!("[[render]]\nmode = \"{mode}\"\n");
    }
    scene += "[[render]]\nname = \"shaded\"\nmode = \"composite\"\nshading = \"phong\"\ninterpolation = \"cubic\"\n";
    std::fs::write(tmp.path().join("s.toml"), scene).unwrap();
    let parsed = volcast::scene::load(&tmp.path().join("s.toml")).unwrap();
    let (views, _) =
        volcast::pipeline::render_films(&parsed, &Default::default(), &Default::default()).unwrap();
    assert_eq!(views.len(), 9);
    for v in &views {
        let mode = parsed.passes[v.pass].mode.name();
        for (i, x) in v.film.data.iter().enumerate() {
            // zoom 2 keeps every ray inside the box, so only depth may be NaN (where
            // the ray never crosses the threshold)
            assert!(
                x.is_finite() || (mode == "depth" && x.is_nan()),
                "{mode}: value {i} is {x}"
            );
        }
    }
    assert!(Path::new(&tmp.path().join("v.raw")).exists());
}

#[test]
fn unknown_keys_are_reported_with_every_other_problem() {
    // the reproducer: a misspelt `windw` hid the five other problems
    let err = reject(
        "[volume]\nsynthetic = \"ball\"\nwindw = [0, 1]\n[camera]\nfov = 500\nzoom = -1\n\
         [[render]]\nmode = \"mip\"\nstep = -1\niso = 0.3\n[[render]]\nmode = \"surface\"\nmaterial = \"gld\"\n",
        &[],
    );
    assert_has(
        &err,
        &[
            "bad.toml:3:1: unknown field `windw`",
            "did you mean `window`?",
            "bad.toml:5:7: fov = 500",
            "bad.toml:6:8: zoom = -1",
            "bad.toml:9:8: step = -1",
            "bad.toml:10:7: `iso` is not used by mode = \"mip\"",
            "bad.toml:13:12: material = \"gld\"",
            "(6 problems in this scene)",
        ],
    );
    // several unknown keys and wrong types, in different tables, all at once, in
    // file order; a key of the wrong type does not also count as missing
    let err = reject(
        "[volume]\nsynthetic = 5\nwindw = 1\n[camera]\nfov = \"x\"\nazimut = 3\n\
         [[render]]\nmode = \"mip\"\nisoo = 3\n",
        &[],
    );
    assert_has(
        &err,
        &[
            "bad.toml:2:13: invalid type: integer `5`",
            "bad.toml:3:1: unknown field `windw`",
            "bad.toml:5:7: invalid type: string \"x\"",
            "bad.toml:6:1: unknown field `azimut`",
            "bad.toml:9:1: unknown field `isoo`",
            "(5 problems in this scene)",
        ],
    );
    assert!(!err.contains("needs `path`"), "{err}");
    let lines: Vec<usize> = err
        .lines()
        .filter_map(|l| l.split(':').nth(1)?.parse().ok())
        .collect();
    assert!(lines.windows(2).all(|w| w[0] <= w[1]), "{lines:?}");
}

#[test]
fn every_message_has_a_location() {
    // nesting beyond the reader's limit, a truncated file, an empty one
    let deep = format!("[volume]\nx = {}1{}\n", "[".repeat(300), "]".repeat(300));
    let err = reject(&deep, &[]);
    assert_has(&err, &["bad.toml:2:", "nesting too deep"]);
    let dotted = format!("[volume]\n{}b = 1\n", "a.".repeat(300));
    assert_has(&reject(&dotted, &[]), &["bad.toml:2:", "nesting too deep"]);
    for (truncated, at) in [
        ("[volume", "bad.toml:1:8"),
        ("[volume]\npath = \"a", "bad.toml:2:10"),
        ("a = [1,", "bad.toml:1:8"),
        ("a = {", "bad.toml:1:6"),
    ] {
        let err = reject(truncated, &[]);
        assert_has(&err, &[at]);
    }
    assert_has(&reject("", &[]), &["bad.toml: missing [volume] table"]);
    assert_has(
        &reject("[camera]\n", &[]),
        &["bad.toml:1:1: missing [volume] table"],
    );
    // not UTF-8: the place of the first bad byte
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("bin.toml"),
        b"[volume]\nsynthetic = \"b\xffall\"\n",
    )
    .unwrap();
    let o = volcast(tmp.path(), &["check", "bin.toml"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("bin.toml:2:15: the scene file is not UTF-8"),
        "{err}"
    );
    // a folder where a file is expected names the folder and says what it is
    let err = reject("[volume]\npath = \"sub.nrrd\"\n", &[]);
    assert!(
        err.contains("No such file") || err.contains("sub.nrrd"),
        "{err}"
    );
    let tmp = tempfile::tempdir().unwrap();
    std::fs::create_dir(tmp.path().join("vol.nrrd")).unwrap();
    std::fs::write(
        tmp.path().join("s.toml"),
        "[volume]\npath = \"vol.nrrd\"\n[[render]]\nmode = \"mip\"\n",
    )
    .unwrap();
    let o = volcast(tmp.path(), &["render", "s.toml"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        err.contains("vol.nrrd: is a directory, not a regular file"),
        "{err}"
    );
    assert!(!tmp.path().join("out").exists());
}

#[test]
fn raw_sizes_too_large_are_called_too_large() {
    for sizes in ["[4e9, 1, 1]", "[4000000000, 1, 1]"] {
        let err = reject(
            &format!("[volume]\npath = \"v.raw\"\nsizes = {sizes}\ntype = \"uint8\"\n"),
            &[("v.raw", &[0u8; 8])],
        );
        assert_has(&err, &["bad.toml:3:9:", "4000000000 is too large"]);
        assert!(!err.contains("at least"), "{err}");
    }
    let err = reject(
        "[volume]\npath = \"v.raw\"\nsizes = [0, 2.5, 1]\ntype = \"uint8\"\n",
        &[("v.raw", &[0u8; 8])],
    );
    assert_has(&err, &["0 is too small"]);
}

#[test]
fn a_refused_run_leaves_no_stray_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    std::fs::write(
        dir.join("s.toml"),
        "[volume]\npath = \"v.nrrd\"\n[[render]]\nmode = \"mip\"\n",
    )
    .unwrap();
    // a volume whose data turns out short: refused after the header was read
    std::fs::write(
        dir.join("v.nrrd"),
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n\x01\x02",
    )
    .unwrap();
    let o = volcast(dir, &["render", "s.toml", "--out", "a/b/c"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        !dir.join("a").exists(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // a folder that existed before is left alone
    std::fs::create_dir(dir.join("mine")).unwrap();
    let o = volcast(dir, &["render", "s.toml", "--out", "mine/x"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(dir.join("mine").is_dir() && !dir.join("mine/x").exists());
}
