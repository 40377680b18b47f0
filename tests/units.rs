//! `[volume] units = "data"`: thresholds, iso values, transfer-function knots and the
//! grey windows of the value-based passes written in the volume's own values render the
//! same bytes as the normalised values `(x - lo) / (hi - lo)` computed here, values
//! outside the window and a missing window are errors, and `check` shows both numbers.

use crate::util::{rendered_nrrds, root, volcast};

/// The scene of `passes` over the shipped CT head (values 0..3926), with its window,
/// 32 x 32 NRRD images, one frame; `units` is the `[volume] units` line (or nothing).
fn scene(units: &str, rest: &str) -> String {
    let path = root().join("data/ct_head_vtk_quarter.nrrd");
    format!(
        "[volume]\npath = {:?}\nwindow = [-1000.0, 3000.0]\n{units}\n\
         [camera]\nazimuth = 30.0\nelevation = 20.0\n\
         [image]\nsize = [32, 32]\nformat = \"nrrd\"\n\
         {rest}",
        path.display().to_string()
    )
}

/// Renders `text` and returns the bytes of every image, by file name.
fn render(text: &str) -> Vec<(String, Vec<u8>)> {
    rendered_nrrds(text, &["--frames", "0"])
}

/// `(x - lo) / (hi - lo)` in f64 for the window above, written so TOML reads back the
/// same f64 (Rust's shortest round-trip form).
fn t(x: f64) -> String {
    format!("{:?}", (x - -1000.0) / (3000.0 - -1000.0))
}

#[test]
fn data_values_render_the_bytes_of_their_normalised_values() {
    let data = |x: f64| format!("{x:?}");
    let passes = |v: &dyn Fn(f64) -> String| {
        format!(
            "[transfer.bone]\n\
             color = [[{}, [0.8, 0.5, 0.3]], [{}, [1.0, 1.0, 0.9]]]\n\
             alpha = [[{}, 0.0], [{}, 0.0], [{}, 0.6]]\n\
             [[render]]\nname = \"depth\"\nmode = \"depth\"\nthreshold = {}\n\
             [[render]]\nname = \"iso\"\nmode = \"surface\"\niso = {}\n\
             [[render]]\nname = \"lmip\"\nmode = \"lmip\"\nthreshold = {}\n\
             [[render]]\nname = \"mip\"\nmode = \"mip\"\nwindow = [{}, {}]\n\
             [[render]]\nname = \"bone\"\nmode = \"composite\"\ntransfer = \"bone\"\n",
            v(-1000.0),
            v(3000.0),
            v(-1000.0),
            v(500.0),
            v(2500.0),
            v(1150.0),
            v(1150.0),
            v(600.0),
            v(0.0),
            v(2000.0),
        )
    };
    let in_data = render(&scene("units = \"data\"", &passes(&data)));
    let normalised = render(&scene("", &passes(&t)));
    assert_eq!(in_data.len(), 5);
    for ((name, a), (_, b)) in in_data.iter().zip(&normalised) {
        assert!(a == b, "{name}: different bytes");
    }
    // and the conversion does something: another threshold gives another image
    let other = render(&scene(
        "units = \"data\"",
        "[[render]]\nname = \"depth\"\nmode = \"depth\"\nthreshold = 500.0\n",
    ));
    assert!(other[0].1 != in_data[0].1, "depth at 500 and at 1150 agree");
}

#[test]
fn data_values_outside_the_window_or_without_one_are_errors() {
    let reject = |text: &str, needles: &[&str]| {
        let tmp = tempfile::tempdir().unwrap();
        std::fs::write(tmp.path().join("s.toml"), text).unwrap();
        let o = volcast(tmp.path(), &["check", "s.toml"]);
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert_eq!(o.status.code(), Some(1), "{err}");
        for n in needles {
            assert!(err.contains(n), "`{n}` missing from:\n{err}");
        }
    };
    reject(
        &scene(
            "units = \"data\"",
            "[[render]]\nmode = \"surface\"\niso = 3500.0\n",
        ),
        &["s.toml:13:7: iso = 3500: expected a value of the volume in its window [-1000, 3000]"],
    );
    reject(
        &scene(
            "units = \"data\"",
            "[transfer.t]\nalpha = [[-2000.0, 0.0], [3000.0, 1.0]]\n\
             [[render]]\nmode = \"composite\"\ntransfer = \"t\"\n",
        ),
        &["alpha knot = -2000"],
    );
    let path = root().join("data/ct_head_vtk_quarter.nrrd");
    reject(
        &format!(
            "[volume]\npath = {:?}\nunits = \"data\"\n[[render]]\nmode = \"depth\"\nthreshold = 1150.0\n",
            path.display().to_string()
        ),
        &["units = \"data\" needs `window = [lo, hi]`"],
    );
    reject(
        &scene("units = \"hounsfield\"", "[[render]]\nmode = \"mip\"\n"),
        &["units", "normalised", "data"],
    );
}

#[test]
fn check_shows_data_and_normalised_values() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("s.toml"),
        scene(
            "units = \"data\"",
            "[[render]]\nmode = \"surface\"\niso = 1150.0\n\
             [[render]]\nname = \"m\"\nmode = \"mip\"\nwindow = [0.0, 2000.0]\n",
        ),
    )
    .unwrap();
    let o = volcast(tmp.path(), &["check", "s.toml"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("iso value 0.5375 (data value 1150)"), "{out}");
    assert!(
        out.contains("grey window [0.25, 0.75] (data values [0, 2000])"),
        "{out}"
    );
    assert!(out.contains("units = \"data\""), "{out}");
}
