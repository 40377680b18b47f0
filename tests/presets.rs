//! Transfer-function presets (issue 9, item 1): Slicer's knots in data values, placed
//! on the volume's window. A preset renders what the same knots, cut to the window by
//! hand here and written as a `[transfer.NAME]` table in data units, render.

use std::path::Path;

use crate::analytic::render;

const VOLUME: &str = r#"
[volume]
synthetic = "gaussian"
sigma = 0.35
sizes = [33, 33, 33]
type = "uint8"
"#;

const PASS: &str = r#"
[camera]
projection = "orthographic"
azimuth = 30
[image]
size = [24, 24]
format = "nrrd"
[[render]]
mode = "composite"
"#;

/// Slicer's MR-Default (presets.xml: scalarOpacity and colorTransfer), data values.
const ALPHA: [(f64, f64); 6] = [
    (0.0, 0.0),
    (20.0, 0.0),
    (40.0, 0.15),
    (120.0, 0.3),
    (220.0, 0.375),
    (1024.0, 0.5),
];
const COLOR: [(f64, [f64; 3]); 6] = [
    (0.0, [0.0, 0.0, 0.0]),
    (20.0, [0.168627, 0.0, 0.0]),
    (40.0, [0.403922, 0.145098, 0.0784314]),
    (120.0, [0.780392, 0.607843, 0.380392]),
    (220.0, [0.847059, 0.835294, 0.788235]),
    (1024.0, [1.0, 1.0, 1.0]),
];

#[test]
fn a_preset_is_its_knots_cut_to_the_window() {
    // the uint8 field's window is [0, 255]: Slicer's last segment (220 to 1024) is
    // cut at 255
    let f = (255.0 - 220.0) / (1024.0 - 220.0);
    let mut alpha: Vec<String> = ALPHA[..5]
        .iter()
        .map(|(x, a)| format!("[{x:?}, {a:?}]"))
        .collect();
    alpha.push(format!("[255.0, {:?}]", 0.375 + (0.5 - 0.375) * f));
    let mut color: Vec<String> = COLOR[..5]
        .iter()
        .map(|(x, c)| format!("[{x:?}, [{:?}, {:?}, {:?}]]", c[0], c[1], c[2]))
        .collect();
    let end: Vec<String> = (0..3)
        .map(|c| format!("{:?}", COLOR[4].1[c] + (COLOR[5].1[c] - COLOR[4].1[c]) * f))
        .collect();
    color.push(format!("[255.0, [{}]]", end.join(", ")));
    let by_hand = format!(
        "{VOLUME}units = \"data\"\nwindow = [0, 255]\n{PASS}transfer = \"mine\"\n\
         [transfer.mine]\ncolor = [{}]\nalpha = [{}]\n",
        color.join(", "),
        alpha.join(", ")
    );
    let preset = format!("{VOLUME}{PASS}transfer = \"mr-default\"\n");
    let (a, b) = (render(&preset), render(&by_hand));
    let (a, b) = (&a[0].film, &b[0].film);
    assert_eq!(a.data.len(), b.data.len());
    let opaque = a.data.chunks(4).filter(|p| p[3] > 0.2).count();
    assert!(opaque > 50, "the preset shows the blob: {opaque} pixels");
    for (k, (x, y)) in a.data.iter().zip(&b.data).enumerate() {
        assert!((x - y).abs() <= 1e-6, "sample {k}: preset {x}, by hand {y}");
    }
}

#[test]
fn preset_errors_name_the_key() {
    let scene = crate::util::root().join("scenes/preset_test.toml");
    let no_window = "[volume]\npath = \"../data/mr_head_unc.nrrd\"\n[[render]]\nmode = \"composite\"\ntransfer = \"ct-bone\"\n";
    let err = volcast::scene::parse(no_window, &scene)
        .expect_err("a preset needs a window")
        .to_string();
    assert!(
        err.contains("preset_test.toml:5:12")
            && err.contains("needs `window = [lo, hi]` in [volume]"),
        "{err}"
    );
    let typo = format!("{VOLUME}[[render]]\nmode = \"composite\"\ntransfer = \"ct-bones\"\n");
    let err = volcast::scene::parse(&typo, Path::new("p.toml"))
        .expect_err("not a preset")
        .to_string();
    assert!(err.contains("did you mean `ct-bone`?"), "{err}");
    assert!(
        err.contains("`mr-default`"),
        "the presets are listed: {err}"
    );
}
