//! Empty-space skipping changes no pixel (issue 7, item 2): every mode, filter and
//! integration method rendered with and without skipping gives the same bits, and
//! skipping does skip. So does the sampler's other shortcut, float32 voxels read
//! without their clamp when all lie in the window [0, 1]; and 8-bit voxels that
//! the window covers, interpolated as bytes, render the interpolant of the
//! normalised voxels (the last two tests). The
//! volume is three blobs in air (a CT-like layout), stored as uint8, int16 and
//! float32, seen from several sides, orthographic and perspective.

use std::path::{Path, PathBuf};

use volcast::pipeline::{render_films, RenderedView, Summary};
use volcast::plan::RunOptions;
use volcast::volume::nrrd::{self, NrrdHeader};
use volcast::volume::{Limits, ScalarType, VolumeData};

/// Blobs in [0, 1] on a `n`^3 grid, exactly 0 away from them.
fn blobs(n: usize) -> Vec<f64> {
    let c = |i: usize| i as f64 / (n - 1) as f64 * 2.0 - 1.0;
    let mut v = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let (x, y, z) = (c(i), c(j), c(k));
                let f = [
                    (-0.4, -0.2, 0.1, 0.15, 1.0),
                    (0.35, 0.15, -0.25, 0.1, 0.7),
                    (0.0, 0.45, 0.4, 0.08, 0.5),
                ]
                .iter()
                .map(|&(cx, cy, cz, s, a): &(f64, f64, f64, f64, f64)| {
                    let d2 = (x - cx).powi(2) + (y - cy).powi(2) + (z - cz).powi(2);
                    a * (-d2 / (2.0 * s * s)).exp()
                })
                .sum::<f64>();
                v.push(if f < 0.02 { 0.0 } else { f.min(1.0) });
            }
        }
    }
    v
}

/// Writes the blobs as `ty` (values scaled to the type's range) and returns the
/// path and the value window.
fn write(dir: &Path, ty: ScalarType, n: usize) -> (PathBuf, [f64; 2]) {
    let v = blobs(n);
    let (data, window) = match ty {
        ScalarType::Uint8 => (
            VolumeData::U8(v.iter().map(|x| (x * 255.0).round() as u8).collect()),
            [0.0, 255.0],
        ),
        // negative values in the air, to exercise signed data read as bits
        ScalarType::Int16 => (
            VolumeData::I16(
                v.iter()
                    .map(|x| (x * 3000.0).round() as i16 - 1000)
                    .collect(),
            ),
            [-1000.0, 2000.0],
        ),
        _ => (
            VolumeData::F32(v.iter().map(|&x| x as f32).collect()),
            [0.0, 1.0],
        ),
    };
    let h = NrrdHeader::new(ty, vec![n, n, n]);
    let p = dir.join(format!("blobs_{ty}.nrrd"));
    std::fs::write(&p, nrrd::encode(&h, &data).expect("encodes")).expect("writes");
    (p, window)
}

fn render(scene: &str, dir: &Path, no_skip: bool) -> (Vec<RenderedView>, Summary) {
    let s = volcast::scene::parse(scene, &dir.join("s.toml")).expect("the scene is valid");
    let opts = RunOptions {
        no_skip,
        ..RunOptions::default()
    };
    render_films(&s, &opts, &Limits::default()).expect("renders")
}

/// Renders `passes` of the blobs as `ty` with and without skipping; asserts equal
/// bits and returns the fraction of samples skipped.
fn compare(ty: ScalarType, camera: &str, passes: &str) -> f64 {
    let dir = tempfile::tempdir().unwrap();
    let (path, [lo, hi]) = write(dir.path(), ty, 33);
    let scene = format!(
        "[volume]\npath = {:?}\nwindow = [{lo}, {hi}]\n{camera}\n[orbit]\nframes = 3\n\
         [image]\nsize = [40, 32]\nformat = \"nrrd\"\n\
         [transfer.ramp]\ncolor = [[0.0, [0.2, 0.4, 1.0]], [1.0, [1.0, 0.9, 0.8]]]\n\
         alpha = [[0.0, 0.0], [0.15, 0.0], [0.6, 0.3], [1.0, 0.9]]\n\
         [transfer.widgets]\nkind = \"2d\"\ngradient_max = 0.5\n\
         [[transfer.widgets.widget]]\nshape = \"rectangle\"\nvalue = [0.3, 0.8]\ngradient = [0.0, 0.5]\ncolor = [1.0, 0.5, 0.2]\nalpha = 0.4\n\
         {passes}",
        path.to_str().unwrap()
    );
    let (skipped, s1) = render(&scene, dir.path(), false);
    let (plain, s0) = render(&scene, dir.path(), true);
    assert_eq!(skipped.len(), plain.len());
    for (a, b) in skipped.iter().zip(&plain) {
        assert_eq!((a.pass, a.frame), (b.pass, b.frame));
        let bits = |f: &[f32]| f.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let (ba, bb) = (bits(&a.film.data), bits(&b.film.data));
        if ba != bb {
            let diff = a
                .film
                .data
                .iter()
                .zip(&b.film.data)
                .position(|(x, y)| x.to_bits() != y.to_bits())
                .unwrap();
            panic!(
                "{ty} {camera} pass {} frame {}: value {diff} differs: skipped {} vs marched {}\n{passes}",
                a.pass, a.frame, a.film.data[diff], b.film.data[diff]
            );
        }
    }
    assert_eq!(s1.nominal_samples, s0.nominal_samples, "the same march");
    assert!(s1.samples <= s0.samples, "skipping takes no more samples");
    1.0 - s1.samples as f64 / s1.nominal_samples as f64
}

const CAMERAS: &[&str] = &[
    "[camera]\nprojection = \"orthographic\"\nazimuth = 20\nelevation = 15",
    "[camera]\nprojection = \"perspective\"\nazimuth = -35\nelevation = 40\nzoom = 1.3",
    // down an axis: rays along index rows, on macrocell faces
    "[camera]\nprojection = \"orthographic\"\nelevation = 90",
];

fn all(passes: &str, min_skipped: f64) {
    for ty in [ScalarType::Uint8, ScalarType::Int16, ScalarType::Float32] {
        for camera in CAMERAS {
            let skipped = compare(ty, camera, passes);
            assert!(
                skipped >= min_skipped,
                "{ty} {camera}: only {:.0}% of the samples skipped\n{passes}",
                100.0 * skipped
            );
        }
    }
}

#[test]
fn projections_skip_without_changing_a_pixel() {
    all(
        "[[render]]\nname = \"x\"\nmode = \"xray\"\nstep = 0.5\n\
         [[render]]\nname = \"m\"\nmode = \"mip\"\nstep = 0.7\n\
         [[render]]\nname = \"n\"\nmode = \"minip\"\n\
         [[render]]\nname = \"a\"\nmode = \"average\"\nstep = 0.3\n\
         [[render]]\nname = \"l\"\nmode = \"lmip\"\nthreshold = 0.4\n",
        0.3,
    );
}

#[test]
fn crossings_skip_without_changing_a_pixel() {
    all(
        "[[render]]\nname = \"d\"\nmode = \"depth\"\nthreshold = 0.3\nstep = 0.6\n\
         [[render]]\nname = \"s\"\nmode = \"surface\"\niso = 0.45\nmaterial = \"gold\"\n\
         [[render]]\nname = \"e\"\nmode = \"surface\"\niso = 0.45\nintegration = \"exact\"\n\
         [[render]]\nname = \"f\"\nmode = \"depth\"\nthreshold = 0.2\nintegration = \"exact\"\n",
        0.3,
    );
}

#[test]
fn compositing_skips_without_changing_a_pixel() {
    all(
        "[[render]]\nname = \"c\"\nmode = \"composite\"\ntransfer = \"ramp\"\nstep = 0.5\n\
         [[render]]\nname = \"p\"\nmode = \"composite\"\ntransfer = \"ramp\"\npreintegrated = true\nstep = 1.5\n\
         [[render]]\nname = \"h\"\nmode = \"composite\"\ntransfer = \"ramp\"\nshading = \"phong\"\nmaterial = \"jade\"\n\
         [[render]]\nname = \"w\"\nmode = \"composite\"\ntransfer = \"widgets\"\nearly_stop = 1.0\n",
        0.3,
    );
}

#[test]
fn jitter_filters_and_exact_integration_skip_without_changing_a_pixel() {
    // jitter keeps its lattice; the cubic filters' wider support; exact passes skip
    // whole cells; the average keeps the skipped path length
    all(
        "[[render]]\nname = \"j\"\nmode = \"composite\"\ntransfer = \"ramp\"\njitter = true\n\
         [[render]]\nname = \"k\"\nmode = \"mip\"\njitter = true\nstep = 0.9\n\
         [[render]]\nname = \"b\"\nmode = \"xray\"\ninterpolation = \"cubic\"\n\
         [[render]]\nname = \"g\"\nmode = \"average\"\ninterpolation = \"bspline\"\n\
         [[render]]\nname = \"q\"\nmode = \"mip\"\ninterpolation = \"nearest\"\n\
         [[render]]\nname = \"r\"\nmode = \"surface\"\niso = 0.5\ninterpolation = \"cubic\"\ngradient = \"analytic\"\n\
         [[render]]\nname = \"t\"\nmode = \"xray\"\nintegration = \"exact\"\n\
         [[render]]\nname = \"u\"\nmode = \"average\"\nintegration = \"exact\"\n\
         [[render]]\nname = \"v\"\nmode = \"mip\"\nintegration = \"exact\"\n\
         [[render]]\nname = \"z\"\nmode = \"minip\"\nintegration = \"exact\"\n",
        0.2,
    );
}

#[test]
fn clipped_passes_skip_without_changing_a_pixel() {
    // two oblique planes through two blobs' centres (the volume spans 0..32 in
    // world units): rays enter through a plane inside an
    // object (capped and not), and the falling search for the far wall skips too
    all(
        "[[render]]\nname = \"m\"\nmode = \"mip\"\n\
         [[render]]\nname = \"c\"\nmode = \"composite\"\ntransfer = \"ramp\"\n\
         [[render]]\nname = \"s\"\nmode = \"surface\"\niso = 0.3\n\
         [[render]]\nname = \"d\"\nmode = \"depth\"\nthreshold = 0.3\nintegration = \"exact\"\n\
         [[render]]\nname = \"e\"\nmode = \"surface\"\niso = 0.3\nintegration = \"exact\"\n\
         [[clip]]\npoint = [9.6, 12.8, 17.6]\nnormal = [-0.3, -1, 0.2]\n\
         [[clip]]\npoint = [21.6, 18.4, 12]\nnormal = [1, -0.5, -0.4]\ncap = true\npasses = [\"m\", \"s\", \"e\"]\n",
        0.2,
    );
}

#[test]
fn depth_cued_mip_skips_without_changing_a_pixel() {
    all(
        "[[render]]\nname = \"v\"\nmode = \"mip\"\ndepth_cue = 0.6\n\
         [[render]]\nname = \"d\"\nmode = \"mip\"\ndepth_cue = 0.3\noutput = \"depth-of-max\"\n\
         [[render]]\nname = \"c\"\nmode = \"mip\"\noutput = \"depth-coded\"\ncolormap = \"viridis\"\n\
         [[render]]\nname = \"e\"\nmode = \"mip\"\ndepth_cue = 0.9\noutput = \"depth-of-max\"\nintegration = \"exact\"\n",
        0.2,
    );
}

/// float32 voxels that all lie in the window [0, 1] are sampled without their clamp
/// (the renderer checks them once per run), with the bits of clamped ones. One voxel
/// of the blobs' air is set to 3.0, outside the window, which makes the renderer
/// clamp every voxel, and to 1.0, which does not: the two images are the same bits,
/// and differ from the blobs' own where the odd voxel is seen.
/// A scene of X-ray, MIP and composite passes over the volume at `path`, with
/// `window` (else the data's range), orthographic, 48 x 40 pixels.
fn three_passes(path: &Path, window: Option<[f64; 2]>) -> String {
    let window = window.map_or(String::new(), |[lo, hi]| format!("window = [{lo}, {hi}]\n"));
    format!(
        "[volume]\npath = {:?}\n{window}\
         [camera]\nprojection = \"orthographic\"\nazimuth = 20\nelevation = 15\n\
         [image]\nsize = [48, 40]\nformat = \"nrrd\"\n\
         [[render]]\nname = \"x\"\nmode = \"xray\"\nstep = 0.5\n\
         [[render]]\nname = \"m\"\nmode = \"mip\"\nstep = 0.5\n\
         [[render]]\nname = \"c\"\nmode = \"composite\"\ntransfer = \"ramp\"\n\
         [transfer.ramp]\ncolor = [[0.0, [1.0, 1.0, 1.0]], [1.0, [1.0, 0.5, 0.2]]]\n\
         alpha = [[0.0, 0.0], [0.1, 0.0], [1.0, 0.8]]\n",
        path.to_str().unwrap()
    )
}

#[test]
fn float_voxels_inside_the_window_read_unclamped_give_the_clamped_bits() {
    let n = 33;
    let dir = tempfile::tempdir().unwrap();
    let blobs: Vec<f32> = blobs(n).iter().map(|&x| x as f32).collect();
    // a corner voxel, in the air
    assert_eq!(blobs[0], 0.0);
    let with = |v: f32| {
        let mut d = blobs.clone();
        d[0] = v;
        d
    };
    let mut films = Vec::new();
    for (name, data) in [
        ("blobs", blobs.clone()),
        ("three", with(3.0)),
        ("one", with(1.0)),
    ] {
        let h = NrrdHeader::new(ScalarType::Float32, vec![n, n, n]);
        let p = dir.path().join(format!("{name}.nrrd"));
        let bytes = nrrd::encode(&h, &VolumeData::F32(data)).expect("encodes");
        std::fs::write(&p, bytes).expect("writes");
        let scene = three_passes(&p, Some([0.0, 1.0]));
        films.push(render(&scene, dir.path(), false).0);
    }
    // the values whose bits differ between two images
    let differ = |a: &[f32], b: &[f32]| {
        a.iter()
            .zip(b)
            .filter(|(x, y)| x.to_bits() != y.to_bits())
            .count()
    };
    for ((plain, three), one) in films[0].iter().zip(&films[1]).zip(&films[2]) {
        let pass = plain.pass;
        let (plain, three, one) = (&plain.film.data, &three.film.data, &one.film.data);
        assert_eq!(
            differ(three, one),
            0,
            "pass {pass}: 3.0 clamped and 1.0 read as it is give other values"
        );
        assert!(
            differ(plain, one) > 0,
            "pass {pass}: the odd voxel is not seen"
        );
    }
}

#[test]
fn bytes_interpolated_as_they_are_render_the_normalised_interpolant() {
    // 8-bit blobs in [20, 220]; each window's render against a float32 volume of
    // the normalised voxels (window [0, 1]): the same interpolant up to rounding
    // where the window covers every voxel (the bytes interpolated as they are:
    // by the type's range, by the data's, by default) and where it clamps some
    // (normalised first, as a clamp must be: interpolating the bytes first would
    // put values between a clamped voxel and its neighbour elsewhere)
    let n = 33;
    let dir = tempfile::tempdir().unwrap();
    let bytes: Vec<u8> = blobs(n)
        .iter()
        .map(|&x| 20 + (x * 200.0).round() as u8)
        .collect();
    let write = |name: &str, ty: ScalarType, data: VolumeData| {
        let p = dir.path().join(format!("{name}.nrrd"));
        let h = NrrdHeader::new(ty, vec![n, n, n]);
        std::fs::write(&p, nrrd::encode(&h, &data).expect("encodes")).expect("writes");
        p
    };
    let u8_path = write("bytes", ScalarType::Uint8, VolumeData::U8(bytes.clone()));
    // (the default window is the data's range)
    let range = [bytes.iter().min(), bytes.iter().max()].map(|b| f64::from(*b.unwrap()));
    for (window, [lo, hi]) in [
        (Some([0.0, 255.0]), [0.0, 255.0]),
        (Some([10.0, 240.0]), [10.0, 240.0]),
        (None, range),
        (Some([60.0, 180.0]), [60.0, 180.0]),
    ] {
        let normalised: Vec<f32> = bytes
            .iter()
            .map(|&b| ((f64::from(b) - lo) / (hi - lo)).clamp(0.0, 1.0) as f32)
            .collect();
        let f32_path = write(
            "normalised",
            ScalarType::Float32,
            VolumeData::F32(normalised),
        );
        let (of_bytes, _) = render(&three_passes(&u8_path, window), dir.path(), false);
        let (of_floats, _) = render(
            &three_passes(&f32_path, Some([0.0, 1.0])),
            dir.path(),
            false,
        );
        for (a, b) in of_bytes.iter().zip(&of_floats) {
            let worst = a
                .film
                .data
                .iter()
                .zip(&b.film.data)
                .map(|(x, y)| (x - y).abs() / y.abs().max(1.0))
                .fold(0.0f32, f32::max);
            assert!(
                worst <= 2e-5,
                "window {window:?}, pass {}: the 8-bit render differs by {worst}",
                a.pass
            );
        }
    }
}
