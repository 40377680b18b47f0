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
    assert_has(&err, &["bad.toml", "missing field `volume`"]);
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
