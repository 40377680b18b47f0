//! Colour maps (issue 9, item 1) against matplotlib's published tables
//! (`tests/fixtures/colormaps/matplotlib.csv`, written by matplotlib itself: see
//! `make_colormaps.py` there), and colour-mapped intensity passes against their own
//! unquantised values pushed through those tables.

use std::collections::BTreeMap;
use std::path::Path;

use volcast::pipeline::{render, render_films, NoProgress};
use volcast::plan::RunOptions;
use volcast::transfer::Colormap;
use volcast::volume::Limits;

/// matplotlib's tables: map name -> 256 RGB entries at t = i / 255.
pub fn tables() -> BTreeMap<String, Vec<[f64; 3]>> {
    let path = crate::util::root().join("tests/fixtures/colormaps/matplotlib.csv");
    let text = std::fs::read_to_string(&path).expect("the matplotlib fixture is committed");
    let mut out: BTreeMap<String, Vec<[f64; 3]>> = BTreeMap::new();
    for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let rgb = [f[2], f[3], f[4]].map(|x| x.parse::<f64>().unwrap());
        let entries = out.entry(f[0].to_string()).or_default();
        assert_eq!(entries.len(), f[1].parse::<usize>().unwrap(), "{line}");
        entries.push(rgb);
    }
    out
}

/// The table at `t` in [0, 1], linear between its entries.
pub fn table_at(table: &[[f64; 3]], t: f64) -> [f64; 3] {
    let x = t.clamp(0.0, 1.0) * 255.0;
    let (i, f) = (x.floor() as usize, x.fract());
    let j = (i + 1).min(255);
    [0, 1, 2].map(|c| table[i][c] * (1.0 - f) + table[j][c] * f)
}

#[test]
fn every_map_matches_matplotlibs_table() {
    let tables = tables();
    assert_eq!(tables.len(), Colormap::ALL.len(), "a table for every map");
    let mut bad = Vec::new();
    for (name, map) in Colormap::ALL {
        let table = &tables[*name];
        assert_eq!(table.len(), 256, "{name}");
        // turbo: colorous's polynomial fit of Mikhailov's table
        let tol = if *name == "turbo" { 4.0 } else { 2.0 } / 255.0;
        let (mut worst, mut at) = (0.0f64, (0, 0));
        for (i, want) in table.iter().enumerate() {
            let got = map.at(i as f64 / 255.0);
            for c in 0..3 {
                let d = (f64::from(got[c]) - want[c]).abs();
                if d > worst {
                    worst = d;
                    at = (i, c);
                }
            }
        }
        eprintln!(
            "{name}: worst difference {:.2}/255 at {at:?}",
            worst * 255.0
        );
        bad.extend((worst > tol).then(|| format!("{name}: {:.2}/255 at {at:?}", worst * 255.0)));
    }
    assert!(bad.is_empty(), "over the tolerance: {bad:?}");
}

const SCENE: &str = r#"
[volume]
synthetic = "gaussian"
sigma = 0.3
sizes = [33, 33, 33]
[camera]
projection = "orthographic"
azimuth = 20
elevation = 10
[image]
size = [32, 32]
background = [0.2, 0.3, 0.4]
[[render]]
name = "mip"
mode = "mip"
colormap = "viridis"
window = [0.1, 0.9]
[[render]]
name = "depth"
mode = "depth"
threshold = 0.05
colormap = "hot"
[[render]]
name = "grey"
mode = "average"
colormap = "grey"
window = [0.0, 0.5]
"#;

/// A colour-mapped pass's PNG is the matplotlib table at its windowed value
/// (`1 - ` it for depth: near bright), and the background where the ray has no
/// value; `colormap = "grey"` is the plain grey image.
#[test]
fn colour_mapped_passes_show_their_values_through_the_map() {
    let tables = tables();
    let scene = volcast::scene::parse(SCENE, Path::new("cmap.toml")).unwrap();
    let (films, _) =
        render_films(&scene, &RunOptions::default(), &Limits::default()).expect("renders");
    let dir = tempfile::tempdir().unwrap();
    let opts = RunOptions {
        out: Some(dir.path().to_path_buf()),
        ..RunOptions::default()
    };
    let summary = render(&scene, &opts, &Limits::default(), &NoProgress).expect("renders");
    let bg = [0.2, 0.3, 0.4];
    for (p, (name, map)) in [("mip", "viridis"), ("depth", "hot")].iter().enumerate() {
        let png = image::open(dir.path().join(format!("{name}_0000.png")))
            .unwrap()
            .into_rgb8();
        let w = summary.windows[p].expect("a window");
        let film = &films[p].film;
        let (mut misses, mut hits) = (0, 0);
        for j in 0..32 {
            for i in 0..32 {
                let v = f64::from(film.pixel(i, j)[0]);
                let got = png.get_pixel(i as u32, j as u32).0;
                let want = if v.is_nan() {
                    misses += 1;
                    bg
                } else {
                    hits += 1;
                    let t = ((v - w.lo) / (w.hi - w.lo)).clamp(0.0, 1.0);
                    let t = if *name == "depth" { 1.0 - t } else { t };
                    table_at(&tables[*map], t)
                };
                for c in 0..3 {
                    // the map within 2/255 of the table, plus 8-bit rounding
                    let d = (f64::from(got[c]) / 255.0 - want[c]).abs();
                    assert!(
                        d <= 2.6 / 255.0,
                        "{name} ({i},{j}) channel {c}: value {v}, got {got:?}, want {want:?}"
                    );
                }
            }
        }
        assert!(
            misses > 0 && hits > 100,
            "{name}: {misses} misses, {hits} hits"
        );
    }
    // grey: one channel, the plain windowed value
    let png = image::open(dir.path().join("grey_0000.png")).unwrap();
    assert_eq!(png.color(), image::ColorType::Rgb8, "a coloured background");
    let png = png.into_rgb8();
    for j in 0..32 {
        for i in 0..32 {
            let v = f64::from(films[2].film.pixel(i, j)[0]);
            let g = (v / 0.5).clamp(0.0, 1.0);
            let want = if v.is_nan() { bg } else { [g; 3] };
            let got = png.get_pixel(i as u32, j as u32).0;
            for c in 0..3 {
                assert!((f64::from(got[c]) / 255.0 - want[c]).abs() <= 0.5 / 255.0 + 1e-9);
            }
        }
    }
}

#[test]
fn colormap_errors_name_the_key() {
    let bad = [
        (
            "mode = \"composite\"\ncolormap = \"viridis\"\n",
            "`colormap` is not used by mode = \"composite\"",
        ),
        (
            "mode = \"xray\"\ncolormap = \"jet\"\n",
            "colormap = \"jet\" is not known",
        ),
    ];
    for (pass, want) in bad {
        let text = format!("[volume]\nsynthetic = \"ball\"\n[[render]]\n{pass}");
        let err = volcast::scene::parse(&text, Path::new("c.toml"))
            .expect_err(pass)
            .to_string();
        assert!(err.contains(want), "{pass}: {err}");
        assert!(err.contains("c.toml:5:"), "{pass}: {err}");
    }
}
