//! Several volumes in one scene (`[[volume]]`): the blending rule against closed
//! forms, registration by `transform` against the same voxels placed by their
//! file, skipping across volumes, and the scene's checks.

use std::path::Path;

use volcast::pipeline::{render_films, RenderedView, Summary};
use volcast::plan::RunOptions;
use volcast::volume::Limits;

use crate::util::volcast;

/// Renders scene text (as if at the project root): its views and the summary.
fn render_with(text: &str, opts: &RunOptions) -> (Vec<RenderedView>, Summary) {
    let scene =
        volcast::scene::parse(text, Path::new("test.toml")).unwrap_or_else(|e| panic!("{e}"));
    render_films(&scene, opts, &Limits::default()).expect("renders")
}

fn render(text: &str) -> Vec<RenderedView> {
    render_with(text, &RunOptions::default()).0
}

/// The films' values as bits, view by view.
fn bits(views: &[RenderedView]) -> Vec<Vec<u32>> {
    views
        .iter()
        .map(|v| v.film.data.iter().map(|x| x.to_bits()).collect())
        .collect()
}

/// The largest difference between two renders' values.
fn max_diff(a: &[RenderedView], b: &[RenderedView]) -> f32 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| x.film.data.iter().zip(&y.film.data))
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f32::max)
}

/// An orthographic turntable of two frames, written as float NRRD.
const VIEW: &str = "[camera]\nprojection = \"orthographic\"\nelevation = 20.0\n[orbit]\nframes = 2\n[image]\nsize = [40, 32]\nformat = \"nrrd\"\n";

/// A ramp of opacity over the value (colour from blue to red), and a transfer
/// function that is transparent everywhere.
const TFS: &str = "[transfer.ramp]\ncolor = [[0.0, [0.0, 0.0, 1.0]], [1.0, [1.0, 0.0, 0.0]]]\nalpha = [[0.0, 0.0], [0.2, 0.0], [1.0, 0.6]]\n\
[transfer.hot2]\ncolor = [[0.0, [1.0, 1.0, 0.0]]]\nalpha = [[0.0, 0.0], [0.3, 0.0], [1.0, 0.9]]\n\
[transfer.clear]\ncolor = [[0.0, [1.0, 1.0, 1.0]]]\nalpha = [[0.0, 0.0], [1.0, 0.0]]\n";

/// The anatomy: a Gaussian blob over [-1, 1]^3.
const ANATOMY: &str =
    "[[volume]]\nname = \"anatomy\"\nsynthetic = \"gaussian\"\nsigma = 0.4\nsizes = [33, 33, 33]\n";

/// A volume that is transparent everywhere adds nothing: a composite of the
/// anatomy and it is the anatomy's own composite, bit for bit (its box inside the
/// anatomy's, so the camera frames the same sphere), unshaded and shaded.
#[test]
fn a_transparent_second_volume_leaves_the_image_unchanged() {
    for shading in ["", "shading = \"phong\"\n"] {
        let one = format!(
            "{ANATOMY}{VIEW}{TFS}[[render]]\nmode = \"composite\"\ntransfer = \"ramp\"\nstep = 0.7\njitter = true\n{shading}"
        );
        let two = format!(
            "{ANATOMY}[[volume]]\nname = \"overlay\"\nsynthetic = \"ball\"\nradius = 0.5\nsizes = [17, 17, 17]\n\
             transform = [[0.5, 0, 0, 0.1], [0, 0.5, 0, 0], [0, 0, 0.5, 0], [0, 0, 0, 1]]\n\
             {VIEW}{TFS}[[render]]\nmode = \"composite\"\nvolumes = [\"anatomy\", \"overlay\"]\n\
             transfer = {{ anatomy = \"ramp\", overlay = \"clear\" }}\nstep = 0.7\njitter = true\n{shading}"
        );
        let (a, b) = (render(&one), render(&two));
        assert_eq!(bits(&a), bits(&b), "{shading}");
        assert!(
            a[0].film.data.chunks(4).any(|p| p[3] > 0.2),
            "the anatomy shows"
        );
    }
}

/// The same homogeneous medium twice is one medium of opacity 1 - (1 - a)^2 per
/// reference step: opacities compose as the rule says, colours stay.
#[test]
fn the_same_medium_twice_is_one_of_composed_opacity() {
    let a: f64 = 0.07;
    let both = 1.0 - (1.0 - a) * (1.0 - a);
    let tf = |name: &str, alpha: f64| {
        format!("[transfer.{name}]\ncolor = [[0.0, [1.0, 0.5, 0.25]]]\nalpha = [[0.0, {alpha}], [1.0, {alpha}]]\n")
    };
    let second =
        "[[volume]]\nname = \"copy\"\nsynthetic = \"ball\"\nradius = 0.7\nsizes = [21, 21, 21]\n";
    let twice = format!(
        "{ANATOMY}{second}{VIEW}{}[[render]]\nmode = \"composite\"\nvolumes = [\"anatomy\", \"copy\"]\ntransfer = {{ anatomy = \"fog\", copy = \"fog\" }}\nstep = 0.6\nearly_stop = 1.0\n",
        tf("fog", a)
    );
    let once = format!(
        "{ANATOMY}{second}{VIEW}{}[[render]]\nmode = \"composite\"\nvolume = \"anatomy\"\ntransfer = \"fog2\"\nstep = 0.6\nearly_stop = 1.0\n",
        tf("fog2", both)
    );
    let (x, y) = (render(&twice), render(&once));
    let d = max_diff(&x, &y);
    assert!(d < 2e-6, "largest difference {d}");
    // and the medium is there: the centre pixel is far from empty
    let c = x[0].film.pixel(20, 16);
    assert!(c[3] > 0.5, "{c:?}");
    assert!(
        (c[0] - 1.0).abs() < 1e-6 && (c[1] - 0.5).abs() < 1e-6,
        "{c:?}"
    );
}

/// Blending does not depend on the order the volumes are listed in: the same
/// bits either way.
#[test]
fn blending_is_independent_of_the_volumes_order() {
    let scene = |order: &str| {
        format!(
            "{ANATOMY}[[volume]]\nname = \"blob\"\nsynthetic = \"ball\"\nradius = 0.6\nsizes = [25, 25, 25]\n\
             transform = [[1, 0, 0, 0.3], [0, 1, 0, -0.2], [0, 0, 1, 0.1], [0, 0, 0, 1]]\n\
             {VIEW}{TFS}[[render]]\nmode = \"composite\"\nvolumes = [{order}]\n\
             transfer = {{ anatomy = \"ramp\", blob = \"hot2\" }}\nstep = 0.5\nshading = \"phong\"\n"
        )
    };
    let (a, b) = (
        render(&scene("\"anatomy\", \"blob\"")),
        render(&scene("\"blob\", \"anatomy\"")),
    );
    assert_eq!(bits(&a), bits(&b));
    // where both contribute, the colour lies between the two transfer functions'
    assert!(a[0].film.data.chunks(4).any(|p| p[3] > 0.3));
}

/// Writes a NRRD of `n`^3 float32 voxels (a ball of value 1 around the centre,
/// falling off linearly) with `origin` and axis vectors `axes` (rows).
fn write_ball(path: &Path, n: usize, origin: [f64; 3], axes: [[f64; 3]; 3]) {
    let c = (n - 1) as f64 / 2.0;
    let mut data = Vec::with_capacity(n * n * n * 4);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let d = ((i as f64 - c).powi(2)
                    + (j as f64 - c).powi(2)
                    + (k as f64 - 0.6 * c).powi(2))
                .sqrt();
                let v = (1.0 - d / (0.8 * c)).clamp(0.0, 1.0) as f32;
                data.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    let v = |a: [f64; 3]| format!("({},{},{})", a[0], a[1], a[2]);
    let header = format!(
        "NRRD0004\ntype: float\ndimension: 3\nsizes: {n} {n} {n}\nspace: right-anterior-superior\nspace origin: {}\nspace directions: {} {} {}\nendian: little\nencoding: raw\n\n",
        v(origin),
        v(axes[0]),
        v(axes[1]),
        v(axes[2])
    );
    let mut bytes = header.into_bytes();
    bytes.extend_from_slice(&data);
    std::fs::write(path, bytes).unwrap();
}

/// A volume moved by `transform` renders as the same voxels placed there by their
/// file's own geometry, bit for bit: a translation, and a rotation with a scale
/// (in a MIP of one volume, and in a blend over a second volume).
#[test]
fn a_transform_places_a_volume_as_its_file_would() {
    let tmp = tempfile::tempdir().unwrap();
    let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    write_ball(&tmp.path().join("at_zero.nrrd"), 13, [0.0; 3], id);
    // translated by (5, -3, 2)
    write_ball(&tmp.path().join("moved.nrrd"), 13, [5.0, -3.0, 2.0], id);
    // rotated 90 degrees about z and scaled by 2, then translated: x' = (-2y, 2x, 2z) + t
    write_ball(
        &tmp.path().join("turned.nrrd"),
        13,
        [1.0, 2.0, 3.0],
        [[0.0, 2.0, 0.0], [-2.0, 0.0, 0.0], [0.0, 0.0, 2.0]],
    );
    let dir = tmp.path().display().to_string();
    let view = "[camera]\nprojection = \"perspective\"\nazimuth = 30.0\nelevation = 25.0\n[orbit]\nframes = 2\n[image]\nsize = [36, 30]\nformat = \"nrrd\"\n";
    let mip = "[[render]]\nmode = \"mip\"\nstep = 0.4\n";
    let one = |file: &str, transform: &str| {
        format!("[volume]\npath = \"{dir}/{file}\"\n{transform}{view}{mip}")
    };
    let cases = [
        (
            "moved.nrrd",
            "transform = [[1, 0, 0, 5], [0, 1, 0, -3], [0, 0, 1, 2], [0, 0, 0, 1]]\n",
        ),
        (
            "turned.nrrd",
            "transform = [0, -2, 0, 1, 2, 0, 0, 2, 0, 0, 2, 3, 0, 0, 0, 1]\n",
        ),
    ];
    for (file, transform) in cases {
        let by_file = render(&one(file, ""));
        let by_transform = render(&one("at_zero.nrrd", transform));
        assert_eq!(bits(&by_file), bits(&by_transform), "{file}");
        assert!(
            by_file[0].film.data.iter().any(|&x| x > 0.5),
            "{file}: the ball is in view"
        );
        // and in a blend, over a second volume
        let blend = |file: &str, transform: &str| {
            format!(
                "[[volume]]\nname = \"base\"\npath = \"{dir}/at_zero.nrrd\"\n[[volume]]\nname = \"b\"\npath = \"{dir}/{file}\"\n{transform}{view}{TFS}\
                 [[render]]\nmode = \"composite\"\nvolumes = [\"base\", \"b\"]\ntransfer = {{ base = \"ramp\", b = \"hot2\" }}\nstep = 0.5\n"
            )
        };
        let (x, y) = (
            render(&blend(file, "")),
            render(&blend("at_zero.nrrd", transform)),
        );
        assert_eq!(bits(&x), bits(&y), "{file} in a blend");
    }
}

/// A pass names the volume it reads: over two volumes of one box, `volume = "b"`
/// renders what a scene of `b` alone does.
#[test]
fn a_pass_reads_the_volume_it_names() {
    let b = "synthetic = \"ball\"\nradius = 0.6\nsizes = [25, 25, 25]\n";
    let alone = format!("[volume]\n{b}{VIEW}[[render]]\nmode = \"mip\"\n");
    let named = format!(
        "{ANATOMY}[[volume]]\nname = \"b\"\n{b}{VIEW}[[render]]\nmode = \"mip\"\nvolume = \"b\"\n[[render]]\nname = \"first\"\nmode = \"mip\"\n"
    );
    let (x, y) = (render(&alone), render(&named));
    let of_b: Vec<RenderedView> = y.iter().filter(|v| v.pass == 0).cloned().collect();
    assert_eq!(bits(&x), bits(&of_b));
    // the other pass reads the first volume: another image
    let first: Vec<RenderedView> = y.iter().filter(|v| v.pass == 1).cloned().collect();
    assert_ne!(bits(&x), bits(&first));
}

/// Skipping across volumes: an overlay that is empty in most of its box costs
/// little (far fewer samples than the march's), and skipping changes no bit.
#[test]
fn skipping_covers_the_union_of_the_volumes_occupancy() {
    let scene = format!(
        "{ANATOMY}[[volume]]\nname = \"blob\"\nsynthetic = \"ball\"\nradius = 0.15\nsizes = [41, 41, 41]\n\
         {VIEW}{TFS}[[render]]\nmode = \"composite\"\nvolumes = [\"anatomy\", \"blob\"]\n\
         transfer = {{ anatomy = \"hot2\", blob = \"ramp\" }}\nstep = 0.5\n"
    );
    let (a, sa) = render_with(&scene, &RunOptions::default());
    let no_skip = RunOptions {
        no_skip: true,
        ..RunOptions::default()
    };
    let (b, sb) = render_with(&scene, &no_skip);
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(sa.nominal_samples, sb.nominal_samples);
    assert!(
        sa.samples * 3 < sb.samples,
        "skipping took {} of {} samples",
        sa.samples,
        sb.samples
    );
}

/// `check` lists every volume with its box, memory and passes; the manifest
/// records them; a second run with --resume renders nothing.
#[test]
fn check_lists_the_volumes_and_resume_works() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = format!(
        "{ANATOMY}[[volume]]\nname = \"blob\"\nsynthetic = \"ball\"\nradius = 0.3\nsizes = [21, 21, 21]\n\
         transform = [[0.5, 0, 0, 0.2], [0, 0.5, 0, 0], [0, 0, 0.5, 0], [0, 0, 0, 1]]\n\
         [orbit]\nframes = 2\n[image]\nsize = [24, 24]\n{TFS}\
         [[render]]\nname = \"both\"\nmode = \"composite\"\nvolumes = [\"anatomy\", \"blob\"]\ntransfer = {{ anatomy = \"ramp\", blob = \"hot2\" }}\n\
         [[render]]\nname = \"blob_mip\"\nmode = \"mip\"\nvolume = \"blob\"\n"
    );
    std::fs::write(tmp.path().join("s.toml"), &scene).unwrap();
    let o = volcast(tmp.path(), &["check", "s.toml"]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("volumes  2"), "{text}");
    assert!(
        text.contains("anatomy") && text.contains("read by `both`"),
        "{text}"
    );
    assert!(text.contains("read by `both`, `blob_mip`"), "{text}");
    assert!(text.contains("box x -0.3000..0.7000"), "{text}");
    assert!(text.contains("moved by its transform"), "{text}");
    assert!(text.contains("blends volumes `anatomy`, `blob`"), "{text}");
    let o = volcast(tmp.path(), &["render", "s.toml", "--out", "out", "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(tmp.path().join("out/manifest.json")).unwrap())
            .unwrap();
    let names: Vec<&str> = manifest["volumes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["anatomy", "blob"]);
    assert_eq!(
        manifest["scene"]["resolved"]["passes"][0]["volumes"],
        serde_json::json!(["anatomy", "blob"])
    );
    let o = volcast(
        tmp.path(),
        &["render", "s.toml", "--out", "out", "--resume"],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("0 views rendered, 4 images already complete"),
        "{err}"
    );
}

/// Scenes of several volumes that cannot be rendered are refused, each error
/// located and naming the volume, and nothing is written.
#[test]
fn bad_volume_references_are_located_errors() {
    let two = format!(
        "{ANATOMY}[[volume]]\nname = \"blob\"\nsynthetic = \"ball\"\nsizes = [9, 9, 9]\n{TFS}"
    );
    let cases: Vec<(String, &str)> = vec![
        (
            format!("{two}[[render]]\nmode = \"mip\"\nvolume = \"blobb\"\n"),
            "volume = \"blobb\" is not a volume of this scene: its volumes are `anatomy`, `blob`; did you mean `blob`?",
        ),
        (
            format!("{ANATOMY}[[volume]]\nname = \"anatomy\"\nsynthetic = \"ball\"\n[[render]]\nmode = \"mip\"\n"),
            "two volumes are named `anatomy`",
        ),
        (
            format!("{two}[[render]]\nmode = \"composite\"\nvolumes = [\"anatomy\", \"blob\"]\ntransfer = {{ anatomy = \"ramp\" }}\n"),
            "transfer has no transfer function for volume `blob`",
        ),
        (
            format!("{two}[[render]]\nmode = \"composite\"\nvolumes = [\"anatomy\", \"blob\"]\ntransfer = \"ramp\"\n"),
            "a composite of several volumes takes one transfer function per volume",
        ),
        (
            format!("{two}[[render]]\nmode = \"composite\"\nvolumes = [\"anatomy\", \"blob\"]\ntransfer = {{ anatomy = \"ramp\", blob = \"ramp\", other = \"ramp\" }}\n"),
            "transfer: `other` is not a volume this pass reads",
        ),
        (
            format!("{two}[[render]]\nmode = \"mip\"\nvolumes = [\"anatomy\", \"blob\"]\n"),
            "`volumes` is not used by mode = \"mip\"",
        ),
        (
            format!("{two}[[render]]\nmode = \"composite\"\nvolumes = [\"anatomy\", \"anatomy\"]\ntransfer = {{ anatomy = \"ramp\" }}\n"),
            "volumes: `anatomy` is named twice",
        ),
        (
            format!("{two}[[render]]\nmode = \"composite\"\nvolumes = [\"anatomy\", \"blob\"]\ntransfer = {{ anatomy = \"ramp\", blob = \"ramp\" }}\npreintegrated = true\n"),
            "preintegrated = true tabulates the segments of one transfer function",
        ),
        (
            "[[volume]]\nsynthetic = \"ball\"\n[[render]]\nmode = \"mip\"\n".to_string(),
            "[[volume]] needs `name`",
        ),
        (
            format!("{ANATOMY}transform = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]\n[[render]]\nmode = \"mip\"\n"),
            "volume `anatomy`: transform: its 3 x 3 part is not invertible",
        ),
        (
            format!("{ANATOMY}transform = [[1, 0, 0, nan], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]\n[[render]]\nmode = \"mip\"\n"),
            "volume `anatomy`: transform: every entry must be a finite number",
        ),
        (
            format!("{ANATOMY}transform = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0.5, 1]]\n[[render]]\nmode = \"mip\"\n"),
            "the last row must be [0, 0, 0, 1]",
        ),
        (
            format!("{ANATOMY}transform = [1, 0, 0]\n[[render]]\nmode = \"mip\"\n"),
            "expected a 4 x 4 row-major matrix",
        ),
    ];
    for (text, want) in cases {
        let tmp = tempfile::tempdir().unwrap();
        std::fs::write(tmp.path().join("s.toml"), &text).unwrap();
        let o = volcast(tmp.path(), &["render", "s.toml", "--out", "out"]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{text}\n{err}");
        assert!(err.contains(want), "{text}\nwant: {want}\ngot: {err}");
        // located: the message points at a line of the scene
        assert!(err.contains("s.toml:"), "{err}");
        assert!(
            !tmp.path().join("out").exists(),
            "{text}: nothing is written"
        );
    }
}

/// Each volume's values are in its own units: a pass over a second volume of
/// `units = "data"` reads its iso value, its keyframed iso value and its transfer
/// function's knots in that volume's data values, as a scene of that volume alone.
#[test]
fn a_pass_takes_the_units_of_its_volume() {
    let b = "synthetic = \"ball\"\nradius = 0.6\nsizes = [25, 25, 25]\nwindow = [0, 2]\nunits = \"data\"\n";
    let passes = |volume: &str| {
        format!(
            "[transfer.datatf]\ncolor = [[0.0, [1.0, 0.8, 0.6]]]\nalpha = [[0.0, 0.0], [0.4, 0.0], [1.6, 0.7]]\n\
             [[render]]\nname = \"iso\"\nmode = \"surface\"\niso = 0.8\n{volume}\
             [[render]]\nname = \"tf\"\nmode = \"composite\"\ntransfer = \"datatf\"\n{volume}\
             [[keyframe]]\nframe = 0\nazimuth = 0.0\nrender.iso.iso = 0.8\n\
             [[keyframe]]\nframe = 1\nazimuth = 30.0\nrender.iso.iso = 1.2\n"
        )
    };
    let view = VIEW;
    let alone = format!("[volume]\n{b}{view}{}", passes(""));
    let named = format!(
        "{ANATOMY}[[volume]]\nname = \"b\"\n{b}{view}{}",
        passes("volume = \"b\"\n")
    );
    let (x, y) = (render(&alone), render(&named));
    assert_eq!(bits(&x), bits(&y));
    assert!(x.iter().any(|v| v.film.data.iter().any(|&p| p > 0.1)));
}

/// The peak memory of a run of two volumes is at most the sum of the two runs of
/// one volume each (each volume and its precomputations counted once).
#[cfg(unix)]
#[test]
fn two_volumes_take_at_most_the_memory_of_two_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let a = "synthetic = \"gaussian\"\nsigma = 0.4\nsizes = [160, 160, 160]\n";
    let b = "synthetic = \"ball\"\nradius = 0.5\nsizes = [160, 160, 160]\n";
    let tail = "[orbit]\nframes = 2\n[image]\nsize = [64, 64]\n[transfer.r]\ncolor = [[0.0, [1.0, 1.0, 1.0]]]\nalpha = [[0.0, 0.0], [0.2, 0.0], [1.0, 0.5]]\n";
    let scenes = [
        ("a.toml", format!("[volume]\n{a}{tail}[[render]]\nmode = \"composite\"\ntransfer = \"r\"\nshading = \"phong\"\n")),
        ("b.toml", format!("[volume]\n{b}{tail}[[render]]\nmode = \"composite\"\ntransfer = \"r\"\nshading = \"phong\"\n")),
        ("ab.toml", format!("[[volume]]\nname = \"a\"\n{a}[[volume]]\nname = \"b\"\n{b}{tail}[[render]]\nmode = \"composite\"\nvolumes = [\"a\", \"b\"]\ntransfer = {{ a = \"r\", b = \"r\" }}\nshading = \"phong\"\n")),
    ];
    let mut peaks = Vec::new();
    for (name, text) in &scenes {
        std::fs::write(tmp.path().join(name), text).unwrap();
        let out = format!("out_{name}");
        let m = crate::util::measured(tmp.path(), &["render", name, "--out", &out, "--quiet"]);
        assert_eq!(m.code, Some(0), "{name}: {}", m.stderr);
        peaks.push(m.peak_rss);
    }
    let (a, b, ab) = (peaks[0], peaks[1], peaks[2]);
    // each run holds its volume (16 MiB) and its gradient volume (48 MiB)
    assert!(a > 60 << 20 && b > 60 << 20, "{a} {b}");
    assert!(ab <= a + b, "two volumes: {ab} bytes, one each: {a} + {b}");
    assert!(
        ab > a.max(b),
        "two volumes hold more than one: {ab} vs {a}, {b}"
    );
}
