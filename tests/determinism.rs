//! The same scene gives the same bytes whatever the thread count, and any subset of
//! frames gives the same bytes as the full run (the grey window covers the whole orbit).

use std::collections::BTreeMap;
use std::path::Path;

use crate::util::volcast;

const SCENE: &str = r#"
[volume]
synthetic = "marschner-lobb"
sizes = [24, 24, 24]
[orbit]
frames = 5
degrees = 90.0
[stereo]
layout = "pair"
[image]
size = [40, 30]
[[render]]
mode = "mip"
[[render]]
mode = "xray"
[[render]]
mode = "surface"
material = "ruby"
shading = "cook-torrance"
gradient = "sobel"
[[render]]
mode = "composite"
transfer = "bone"
shading = "phong"
interpolation = "cubic"
"#;

/// The images of an output folder (not its manifest, which records timings).
fn files(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "png" || e == "nrrd"))
        .map(|p| {
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect()
}

#[test]
fn bytes_do_not_depend_on_threads_or_frame_ranges() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("s.toml"), SCENE).unwrap();
    let run = |out: &str, extra: &[&str]| {
        let mut args = vec!["render", "s.toml", "--quiet", "--out", out];
        args.extend_from_slice(extra);
        let o = volcast(tmp.path(), &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        files(&tmp.path().join(out))
    };
    let one = run("t1", &["--threads", "1"]);
    let two = run("t2", &["--threads", "2"]);
    let five = run("t5", &["--threads", "5"]);
    assert_eq!(one.len(), 4 * 5 * 2);
    assert!(
        one == two && two == five,
        "outputs differ between thread counts"
    );
    let part = run("part", &["--frames", "2..4"]);
    assert_eq!(part.len(), 4 * 2 * 2);
    for (name, bytes) in &part {
        assert_eq!(
            Some(bytes),
            one.get(name),
            "{name} differs from the full run"
        );
    }
}
