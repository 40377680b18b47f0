//! `volcast histogram`: counts against counts made here (exact bins of integer data,
//! the one gradient of a linear ramp, the value-gradient arc of a Gaussian in closed
//! form), the scene's values converted to data values, the overlays drawn at the
//! pixels the plot's axis map gives, byte-identical output for any thread count,
//! and clear errors.

use std::path::Path;
use std::process::Command;

use volcast::histogram::{self, plot, Marker, Options, Overlays, WidgetBox};
use volcast::sample::Normalize;
use volcast::transfer::WidgetShape;
use volcast::volume::{Geometry, Rescale, ScalarType, Volume, VolumeData, VolumeHeader};

use crate::util::{root, volcast};

/// Writes a raw NRRD of `ty` (`uint8` or `float`, little-endian) with `sizes` and
/// `spacings`.
fn nrrd(path: &Path, ty: &str, sizes: [usize; 3], spacings: [f64; 3], bytes: &[u8]) {
    let [a, b, c] = sizes;
    let [s, t, u] = spacings;
    let mut f = format!(
        "NRRD0004\ntype: {ty}\ndimension: 3\nsizes: {a} {b} {c}\nspacings: {s} {t} {u}\nendian: little\nencoding: raw\n\n"
    )
    .into_bytes();
    f.extend_from_slice(bytes);
    std::fs::write(path, f).unwrap();
}

fn floats(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// The rows of a CSV file below its header, as numbers.
fn csv(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// Runs `volcast histogram` in `dir` and asserts it succeeds; returns stdout.
fn histogram_ok(dir: &Path, args: &[&str]) -> String {
    let mut all = vec!["histogram"];
    all.extend_from_slice(args);
    let o = volcast(dir, &all);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap()
}

#[test]
fn integer_values_land_in_their_own_bins() {
    let tmp = tempfile::tempdir().unwrap();
    let sizes = [5, 4, 3];
    let values: Vec<u8> = (0..60u32).map(|i| ((i * 7 + i / 9) % 10) as u8).collect();
    nrrd(
        &tmp.path().join("v.nrrd"),
        "uint8",
        sizes,
        [1.0; 3],
        &values,
    );
    let out = histogram_ok(tmp.path(), &["v.nrrd", "--out", "h", "--bins", "10"]);
    assert!(out.contains("60 voxels"), "{out}");
    assert!(out.contains("histogram2d.png"), "{out}");
    // the values 0..=9 on 10 bins over [-0.5, 9.5]: bin i holds the value i
    let rows = csv(&tmp.path().join("h/histogram.csv"));
    assert_eq!(rows.len(), 10);
    for (i, row) in rows.iter().enumerate() {
        let want = values.iter().filter(|&&v| usize::from(v) == i).count();
        assert_eq!(row[3] as usize, want, "value {i}");
        assert_eq!([row[1], row[2]], [i as f64 - 0.5, i as f64 + 0.5]);
    }
    // 5 bins of width 2: bin i holds the values 2i and 2i + 1
    histogram_ok(tmp.path(), &["v.nrrd", "--out", "h5", "--bins", "5"]);
    let rows = csv(&tmp.path().join("h5/histogram.csv"));
    for (i, row) in rows.iter().enumerate() {
        let want = values.iter().filter(|&&v| usize::from(v) / 2 == i).count();
        assert_eq!(row[3] as usize, want, "bin {i}");
    }
    // the 2D histogram holds the same voxels, bin by bin
    let cells = csv(&tmp.path().join("h5/histogram2d.csv"));
    for (i, row) in rows.iter().enumerate() {
        let sum: f64 = cells
            .iter()
            .filter(|c| c[0] as usize == i)
            .map(|c| c[6])
            .sum();
        assert_eq!(sum, row[3], "bin {i}");
    }
    for name in ["histogram.png", "histogram2d.png"] {
        let img = image::open(tmp.path().join("h5").join(name)).unwrap();
        assert_eq!(img.width(), plot::WIDTH, "{name}");
    }
}

#[test]
fn a_linear_ramp_has_one_gradient_in_normalised_value_per_voxel() {
    // f = x on 16 voxels: normalised by the data's range, x / 15, whose gradient is
    // 1/15 per voxel along x (one-sided differences at the ends give it too); with a
    // spacing of 2 along x and 1 along y and z, 1/30 per mm, times the smallest
    // spacing (1): 1/30 per voxel of the smallest spacing
    let tmp = tempfile::tempdir().unwrap();
    let sizes = [16, 4, 4];
    let values: Vec<f32> = (0..256).map(|i| (i % 16) as f32).collect();
    for (spacing, bin) in [
        ([2.0, 1.0, 1.0], 33),
        ([1.0, 1.0, 1.0], 66),
        ([1.0, 0.5, 0.5], 33),
    ] {
        nrrd(
            &tmp.path().join("ramp.nrrd"),
            "float",
            sizes,
            spacing,
            &floats(&values),
        );
        histogram_ok(
            tmp.path(),
            &[
                "ramp.nrrd",
                "--out",
                "h",
                "--bins",
                "16",
                "--gradient-bins",
                "100",
                "--gradient-max",
                "0.1",
            ],
        );
        let cells = csv(&tmp.path().join("h/histogram2d.csv"));
        let total: f64 = cells.iter().map(|c| c[6]).sum();
        assert_eq!(total, 256.0);
        for c in &cells {
            assert_eq!(c[1] as usize, bin, "spacing {spacing:?}: {c:?}");
            assert_eq!(c[6], 16.0, "each value has 16 voxels: {c:?}");
        }
    }
}

#[test]
fn a_gaussian_follows_its_value_gradient_arc() {
    // f = exp(-r^2 / (2 s^2)): |grad f| = (r / s^2) f = f sqrt(-2 ln f) / s, so in
    // normalised value (window [0, 1]) per voxel, g(v) = v sqrt(-2 ln v) / s_voxels
    let tmp = tempfile::tempdir().unwrap();
    let (n, spacing, sigma_voxels) = (25usize, 0.5, 4.0);
    let c = (n - 1) as f64 / 2.0;
    let mut values = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r2 = [i, j, k]
                    .iter()
                    .map(|&x| (x as f64 - c).powi(2))
                    .sum::<f64>();
                values.push((-r2 / (2.0 * sigma_voxels * sigma_voxels)).exp() as f32);
            }
        }
    }
    nrrd(
        &tmp.path().join("g.nrrd"),
        "float",
        [n; 3],
        [spacing; 3],
        &floats(&values),
    );
    std::fs::write(
        tmp.path().join("s.toml"),
        "[volume]\npath = \"g.nrrd\"\nwindow = [0.0, 1.0]\n[[render]]\nmode = \"surface\"\niso = 0.5\n",
    )
    .unwrap();
    histogram_ok(
        tmp.path(),
        &[
            "s.toml",
            "--out",
            "h",
            "--bins",
            "64",
            "--gradient-bins",
            "64",
        ],
    );
    let arc = |v: f64| {
        if v > 0.0 {
            v * (-2.0 * v.ln()).sqrt() / sigma_voxels
        } else {
            0.0
        }
    };
    let peak = arc((-0.5f64).exp());
    let cells = csv(&tmp.path().join("h/histogram2d.csv"));
    let (mut on_arc, mut total) = (0.0, 0.0);
    for cell in &cells {
        let [v0, v1, g0, g1, count] = [cell[2], cell[3], cell[4], cell[5], cell[6]];
        // the arc over the value bin, widened by 4% of its peak (central differences
        // are second-order accurate: a few percent at 4 voxels per sigma)
        let (lo, hi) = (0..=20)
            .map(|s| arc((v0 + (v1 - v0) * f64::from(s) / 20.0).clamp(0.0, 1.0)))
            .fold((f64::MAX, f64::MIN), |(a, b), g| (a.min(g), b.max(g)));
        let tol = 0.04 * peak;
        if g1 >= lo - tol && g0 <= hi + tol {
            on_arc += count;
        }
        total += count;
    }
    assert_eq!(total, (n * n * n) as f64);
    assert!(
        on_arc >= 0.99 * total,
        "{on_arc} of {total} voxels on the arc"
    );
    // and the top of the axis is the largest magnitude, near the arc's peak
    let top = cells.iter().map(|c| c[5]).fold(0.0, f64::max);
    assert!((top - peak).abs() < 0.05 * peak, "top {top}, peak {peak}");
}

/// An in-memory float volume with structure along every axis.
fn bumpy() -> Volume {
    let n = [20, 16, 12];
    let mut v = Vec::new();
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let (x, y, z) = (i as f64, j as f64, k as f64);
                v.push(100.0 + 80.0 * (0.5 * x).sin() * (0.3 * y + 0.2 * z).cos());
            }
        }
    }
    Volume {
        header: VolumeHeader {
            sizes: n,
            scalar_type: ScalarType::Float32,
            geometry: Geometry::from_spacing([1.0; 3]),
            source: "bumpy".into(),
            fields: Vec::new(),
            rescale: Rescale::IDENTITY,
        },
        data: VolumeData::from_f64s(ScalarType::Float32, &v),
    }
}

/// Pixel `(x, y)` of a PNG as RGB.
fn pixel(png: &image::RgbImage, x: i32, y: i32) -> [u8; 3] {
    png.get_pixel(x as u32, y as u32).0
}

#[test]
fn overlays_are_drawn_where_the_axis_map_puts_them() {
    let vol = bumpy();
    let norm = Normalize::new(20.0, 180.0);
    let h = histogram::compute(&vol, norm, &Options::default()).unwrap();
    let marks = Overlays {
        markers: vec![Marker {
            label: "iso".into(),
            at: 70.0,
        }],
        widgets: vec![WidgetBox {
            label: "w".into(),
            shape: WidgetShape::Rectangle,
            value: [120.0, 150.0],
            gradient: [0.05, 0.1],
            color: [1.0, 0.0, 0.0],
            alpha: 1.0,
        }],
        ..Overlays::default()
    };
    let decode = |p: &plot::Plot| image::load_from_memory(&p.png).unwrap().to_rgb8();
    for two_d in [false, true] {
        let draw = |o: &Overlays| {
            if two_d {
                plot::gradient_plot(&h, o, "t").unwrap()
            } else {
                plot::value_plot(&h, o, "t").unwrap()
            }
        };
        let (plain, marked) = (draw(&Overlays::default()), draw(&marks));
        assert_eq!(plain.area, marked.area);
        let a = marked.area;
        let (p, m) = (decode(&plain), decode(&marked));
        // the iso line: its column differs over the lower half of the area (its
        // label is at the top), and 12 columns to the left nothing does
        let x = a.column(70.0);
        assert!(a.columns[0] < x && x < a.columns[1]);
        let rows = (a.rows[0] + a.rows[1]) / 2..a.rows[1];
        assert!(
            rows.clone().all(|y| pixel(&p, x, y) != pixel(&m, x, y)),
            "2D {two_d}: no line at column {x}"
        );
        assert!(
            rows.clone().all(|y| pixel(&m, x, y) == [214, 39, 40]),
            "2D {two_d}: not the pass colour"
        );
        assert!(rows
            .clone()
            .all(|y| pixel(&p, x - 12, y) == pixel(&m, x - 12, y)));
        if two_d {
            // the widget's left edge at value 120, between gradient 0.05 and 0.1
            let (x, y0, y1) = (a.column(120.0), a.row(0.1), a.row(0.05));
            assert!(y0 < y1);
            for y in y0 + 4..y1 - 4 {
                assert_eq!(pixel(&m, x, y), [255, 0, 0], "widget edge at ({x}, {y})");
            }
            let outside = a.column(100.0);
            for y in y0 + 4..y1 - 4 {
                assert_eq!(pixel(&m, outside, y), pixel(&p, outside, y));
            }
        }
    }
}

#[test]
fn scene_values_are_drawn_at_their_data_values() {
    let tmp = tempfile::tempdir().unwrap();
    let path = root().join("data/ct_head_vtk_quarter.nrrd");
    let scene = format!(
        "[volume]\npath = {:?}\nwindow = [-1000.0, 3000.0]\nunits = \"data\"\n\
         [[render]]\nname = \"iso\"\nmode = \"surface\"\niso = 500.0\n\
         [[render]]\nname = \"lmip\"\nmode = \"lmip\"\nthreshold = 1150.0\n\
         [[render]]\nname = \"tf\"\nmode = \"composite\"\ntransfer = \"bone\"\n\
         [[render]]\nname = \"edges\"\nmode = \"composite\"\ntransfer = \"edges\"\n\
         [transfer.bone]\ncolor = [[-1000.0, [1.0, 0.0, 0.0]], [3000.0, [0.0, 0.0, 1.0]]]\n\
         alpha = [[-1000.0, 0.0], [200.0, 0.0], [1000.0, 0.8]]\n\
         [transfer.edges]\nkind = \"2d\"\ngradient_max = 0.4\n\
         [[transfer.edges.widget]]\nvalue = [0.0, 2000.0]\ngradient = [0.1, 0.2]\n",
        path.display().to_string()
    );
    let file = tmp.path().join("s.toml");
    std::fs::write(&file, scene).unwrap();
    let scene = volcast::scene::load(&file).unwrap();
    let norm = Normalize::new(-1000.0, 3000.0);
    let o = Overlays::of_scene(&scene, norm, Rescale::IDENTITY);
    let close = |a: f64, b: f64| (a - b).abs() < 1e-6 * b.abs().max(1.0);
    let w = o.window.unwrap();
    assert!(close(w[0], -1000.0) && close(w[1], 3000.0), "{w:?}");
    let at: Vec<f64> = o.markers.iter().map(|m| m.at).collect();
    assert!(close(at[0], 500.0) && close(at[1], 1150.0), "{at:?}");
    assert!(
        o.markers[0].label.starts_with("iso: iso 500"),
        "{}",
        o.markers[0].label
    );
    // the opacity knots at their data values
    let curve = &o.curves[0];
    for (x, want) in [
        (-1000.0, 0.0),
        (200.0, 0.0),
        (600.0, 0.4),
        (1000.0, 0.8),
        (3000.0, 0.8),
    ] {
        let (_, a) = curve.at(x);
        assert!((f64::from(a) - want).abs() < 2e-3, "alpha at {x}: {a}");
    }
    let (rgb, _) = curve.at(1000.0);
    assert!(
        (rgb[0] - 0.5).abs() < 1e-2 && (rgb[2] - 0.5).abs() < 1e-2,
        "{rgb:?}"
    );
    let wb = &o.widgets[0];
    assert!(
        close(wb.value[0], 0.0) && close(wb.value[1], 2000.0),
        "{:?}",
        wb.value
    );
    assert_eq!(wb.gradient, [0.1f32, 0.2f32].map(f64::from));
    assert!(close(o.gradient_max[0].at, 0.4));
    // and through the command line, with the scene's window on the axis
    let out = histogram_ok(tmp.path(), &["s.toml", "--out", "h"]);
    assert!(out.contains("window [-1000, 3000]"), "{out}");
}

#[test]
fn the_same_files_for_any_number_of_threads() {
    let tmp = tempfile::tempdir().unwrap();
    let values: Vec<u8> = (0..8000u32).map(|i| ((i * 37) % 251) as u8).collect();
    nrrd(
        &tmp.path().join("v.nrrd"),
        "uint8",
        [20, 20, 20],
        [1.0; 3],
        &values,
    );
    let run = |threads: &str, out: &str| {
        let o = Command::new(env!("CARGO_BIN_EXE_volcast"))
            .args(["histogram", "v.nrrd", "--out", out])
            .env("RAYON_NUM_THREADS", threads)
            .current_dir(tmp.path())
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run("1", "one");
    run("3", "three");
    for f in [
        "histogram.png",
        "histogram2d.png",
        "histogram.csv",
        "histogram2d.csv",
    ] {
        let a = std::fs::read(tmp.path().join("one").join(f)).unwrap();
        let b = std::fs::read(tmp.path().join("three").join(f)).unwrap();
        assert!(a == b, "{f} differs");
    }
}

#[test]
fn bad_input_gets_a_clear_error_and_no_files() {
    let tmp = tempfile::tempdir().unwrap();
    nrrd(
        &tmp.path().join("v.nrrd"),
        "uint8",
        [2, 2, 2],
        [1.0; 3],
        &[1, 2, 3, 4, 5, 6, 7, 8],
    );
    nrrd(
        &tmp.path().join("nan.nrrd"),
        "float",
        [2, 1, 1],
        [1.0; 3],
        &floats(&[f32::NAN, f32::NAN]),
    );
    std::fs::write(tmp.path().join("file"), "not a folder").unwrap();
    let cases: [(&[&str], i32, &[&str]); 7] = [
        (&["missing.nrrd", "--out", "o"], 1, &["missing.nrrd"]),
        (
            &["v.nrrd", "--out", "o", "--bins", "0"],
            2,
            &["--bins", "0"],
        ),
        (
            &["v.nrrd", "--out", "o", "--bins", "5000"],
            2,
            &["--bins", "5000"],
        ),
        (
            &["v.nrrd", "--out", "o", "--gradient-bins", "x"],
            2,
            &["--gradient-bins"],
        ),
        (
            &["v.nrrd", "--out", "o", "--gradient-max", "-1"],
            2,
            &["--gradient-max", "greater than 0"],
        ),
        (
            &["v.nrrd", "--out", "file/o"],
            1,
            &["creating the output folder", "file/o"],
        ),
        (
            &["nan.nrrd", "--out", "o"],
            1,
            &["nan.nrrd", "no finite values"],
        ),
    ];
    for (args, code, needles) in cases {
        let mut all = vec!["histogram"];
        all.extend_from_slice(args);
        let o = volcast(tmp.path(), &all);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(code), "{args:?}: {err}");
        for n in needles {
            assert!(err.contains(n), "{args:?}: `{n}` missing from {err}");
        }
        assert!(!err.contains("internal error"), "{err}");
        assert!(
            !tmp.path().join("o").exists(),
            "{args:?} created the output folder"
        );
    }
}
