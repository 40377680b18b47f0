//! The turntable page (`[viewer] html`, `--viewer`): written with the manifest once
//! every frame exists, the same bytes from shards and resumed runs, and, in real
//! headless Chromium driven over WebDriver, a page that loads every frame without a
//! console error, turns under a mouse drag and the arrow keys to the expected frame
//! (checked against the frame files themselves), switches passes and stereo views,
//! and shows a missing frame as missing.
//!
//! The browser test needs `chromium` and `chromedriver` on `PATH` (Debian:
//! `apt-get install chromium chromium-driver`); without them it is skipped with a
//! message, unless `VOLCAST_REQUIRE_BROWSER=1` (set by `.ci/run`), when it fails.

mod webdriver;

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde_json::json;
use webdriver::{which, Browser, ARROW_LEFT, ARROW_RIGHT};

use crate::util::volcast;

/// 12 frames of 96 x 96: a gold surface and a MIP of four blobs and a shell (not
/// symmetric about the orbit axis, so every frame differs).
const SCENE: &str = "[volume]\nsynthetic = \"blobs\"\nsizes = [40, 40, 40]\n\
    [camera]\nelevation = 20.0\nzoom = 1.4\n[orbit]\nframes = 12\n[image]\nsize = [96, 96]\n\
    [[render]]\nname = \"gold\"\nmode = \"surface\"\niso = 0.4\nmaterial = \"gold\"\n\
    [[render]]\nmode = \"mip\"\n";

fn render(dir: &Path, scene: &str, out: &str, extra: &[&str]) {
    std::fs::write(dir.join("spin.toml"), scene).unwrap();
    let mut args = vec!["render", "spin.toml", "--out", out];
    args.extend_from_slice(extra);
    let o = volcast(dir, &args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn the_page_is_written_once_complete_and_shards_and_resume_give_its_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("spin.toml"),
        format!("{SCENE}[viewer]\nhtml = true\n"),
    )
    .unwrap();
    // one run: the summary names the page; check says it will be written
    let o = volcast(d, &["render", "spin.toml", "--out", "one"]);
    assert!(o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("volcast: viewer one/index.html"),
        "the summary names the page: {err}"
    );
    let check = volcast(d, &["check", "spin.toml", "--out", "x"]);
    assert!(String::from_utf8_lossy(&check.stdout).contains("viewer   x/index.html"));
    let page_of = |out: &str| std::fs::read_to_string(d.join(out).join("index.html")).unwrap();
    let one = page_of("one");
    // every frame file of the manifest, in order, is named in the page
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("one/manifest.json")).unwrap()).unwrap();
    let page = &one;
    let mut at = 0;
    for r in manifest["frames"].as_array().unwrap() {
        let name = r["files"][0]["name"].as_str().unwrap();
        let i = page[at..]
            .find(&format!("\"{name}\""))
            .unwrap_or_else(|| panic!("{name} in the page, after the frame before it"));
        at += i;
    }
    assert_eq!(manifest["viewer"], "index.html");
    // a drag to the right must bring the near side of the object to the right: from
    // the recorded views, a point on the near side at frame 0 lies left of the
    // centre at frame 1, so the page steps back (`grab` -1) for a drag to the right
    let v = |k: usize, key: &str| -> Vec<f64> {
        let x = &manifest["frames"][k]["views"][0][key];
        match x.as_array() {
            Some(a) => a.iter().map(|c| c.as_f64().unwrap()).collect(),
            None => vec![x.as_f64().unwrap()],
        }
    };
    let (eye0, forward0, d0) = (
        v(0, "eye_position"),
        v(0, "forward"),
        v(0, "target_distance")[0],
    );
    let near: Vec<f64> = (0..3).map(|i| eye0[i] + forward0[i] * (d0 - 0.5)).collect();
    let (eye1, right1) = (v(1, "eye_position"), v(1, "right"));
    let x1: f64 = (0..3).map(|i| (near[i] - eye1[i]) * right1[i]).sum();
    assert!(
        x1 < -0.1,
        "the near side moves left from frame 0 to 1 ({x1})"
    );
    assert!(
        page.contains("\"grab\":-1"),
        "a drag to the right steps back"
    );
    // two shards: no page after the first, the second completes it, same bytes
    let o = volcast(d, &["render", "spin.toml", "--out", "sh", "--shard", "0/2"]);
    assert!(o.status.success());
    assert!(
        !d.join("sh/index.html").exists(),
        "not before every frame exists"
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("viewer page are written once"));
    let o = volcast(d, &["render", "spin.toml", "--out", "sh", "--shard", "1/2"]);
    assert!(o.status.success());
    assert!(
        page_of("sh") == one,
        "the page of shards and resumed runs is the single run's"
    );
    // a resumed run after losing a frame repairs it and writes the same page
    std::fs::remove_file(d.join("sh/gold_0004.png")).unwrap();
    std::fs::remove_file(d.join("sh/index.html")).unwrap();
    let o = volcast(d, &["render", "spin.toml", "--out", "sh", "--resume"]);
    assert!(o.status.success());
    assert!(
        page_of("sh") == one,
        "the page of shards and resumed runs is the single run's"
    );
    // --viewer on the command line for a scene without [viewer]: the same page;
    // and [viewer] does not change the scene hash, so --resume renders nothing
    std::fs::create_dir(d.join("plain")).unwrap();
    std::fs::write(d.join("plain/spin.toml"), SCENE).unwrap();
    let o = volcast(
        d,
        &[
            "render",
            "plain/spin.toml",
            "--out",
            "one",
            "--resume",
            "--viewer",
        ],
    );
    assert!(o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("24 images already complete"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        page_of("one") == one,
        "the page of --viewer is that of [viewer]"
    );
    // no page without [viewer] or --viewer
    let o = volcast(d, &["render", "plain/spin.toml", "--out", "none"]);
    assert!(o.status.success());
    assert!(!d.join("none/index.html").exists());
    assert!(!String::from_utf8_lossy(&o.stderr).contains("index.html"));
}

#[test]
fn a_page_of_nrrd_frames_is_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let nrrd = SCENE.replace("[image]\n", "[image]\nformat = \"nrrd\"\n");
    std::fs::write(d.join("a.toml"), format!("{nrrd}[viewer]\nhtml = true\n")).unwrap();
    let o = volcast(d, &["check", "a.toml"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        err.contains("a.toml:") && err.contains("[viewer] html = true") && err.contains("png"),
        "{err}"
    );
    std::fs::write(d.join("b.toml"), &nrrd).unwrap();
    let o = volcast(d, &["render", "b.toml", "--viewer"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1));
    assert!(err.contains("--viewer") && err.contains("nrrd"), "{err}");
    assert!(!d.join("out").exists(), "nothing written");
    // html = false writes nothing and is fine with nrrd
    std::fs::write(d.join("c.toml"), format!("{nrrd}[viewer]\nhtml = false\n")).unwrap();
    assert!(volcast(d, &["check", "c.toml"]).status.success());
}

/// An 8-bit RGB picture.
struct Rgb {
    width: usize,
    height: usize,
    data: Vec<u8>,
}

/// Decodes a PNG (grey, RGB, with or without alpha, 8 or 16 bits) to 8-bit RGB.
fn decode(bytes: &[u8]) -> Rgb {
    let mut d = png::Decoder::new(std::io::Cursor::new(bytes));
    d.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut r = d.read_info().unwrap();
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    let info = r.next_frame(&mut buf).unwrap();
    let c = info.color_type.samples();
    let data = buf[..info.buffer_size()]
        .chunks_exact(c)
        .flat_map(|px| match c {
            1 | 2 => [px[0]; 3],
            _ => [px[0], px[1], px[2]],
        })
        .collect();
    Rgb {
        width: info.width as usize,
        height: info.height as usize,
        data,
    }
}

fn read(path: &Path) -> Rgb {
    decode(&std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())))
}

/// The columns `x0..x0 + width` of `a`.
fn columns(a: &Rgb, x0: usize, width: usize) -> Rgb {
    let data = a
        .data
        .chunks_exact(3 * a.width)
        .flat_map(|row| row[3 * x0..3 * (x0 + width)].to_vec())
        .collect();
    Rgb {
        width,
        height: a.height,
        data,
    }
}

/// Mean absolute difference per sample (infinite for pictures of other sizes).
fn diff(a: &Rgb, b: &Rgb) -> f64 {
    if (a.width, a.height) != (b.width, b.height) {
        return f64::INFINITY;
    }
    let sum: u64 = a
        .data
        .iter()
        .zip(&b.data)
        .map(|(&x, &y)| u64::from(x.abs_diff(y)))
        .sum();
    sum as f64 / a.data.len() as f64
}

/// Asserts that `shot` is the picture of `files[want]` and nearer to it than to
/// any other of `files`.
fn assert_shows(shot: &Rgb, files: &[PathBuf], want: usize, what: &str) {
    let d: Vec<f64> = files.iter().map(|f| diff(shot, &read(f))).collect();
    assert!(
        d[want] < 0.5,
        "{what}: the canvas is not {} (mean difference {:.3}; all: {d:.2?})",
        files[want].display(),
        d[want]
    );
    for (j, &dj) in d.iter().enumerate() {
        assert!(
            j == want || dj > d[want] + 2.0,
            "{what}: frame {j} looks as close as frame {want} ({d:.2?})"
        );
    }
}

/// chromium and chromedriver, or `None` (after saying so) when the test may skip.
fn browser_tools() -> Option<(PathBuf, PathBuf)> {
    let chromium = which(&["chromium", "chromium-browser", "google-chrome"]);
    let driver = which(&["chromedriver"]);
    match (chromium, driver) {
        (Some(c), Some(d)) => Some((c, d)),
        (c, d) => {
            let missing: Vec<&str> = [(c.is_none(), "chromium"), (d.is_none(), "chromedriver")]
                .iter()
                .filter(|m| m.0)
                .map(|m| m.1)
                .collect();
            let message = format!(
                "the browser test of the viewer page needs {} on PATH (Debian: apt-get install chromium chromium-driver)",
                missing.join(" and ")
            );
            if std::env::var("VOLCAST_REQUIRE_BROWSER").as_deref() == Ok("1") {
                panic!("{message}, and VOLCAST_REQUIRE_BROWSER=1");
            }
            eprintln!("SKIPPED: {message}");
            None
        }
    }
}

fn file_url(path: &Path) -> String {
    let abs = std::fs::canonicalize(path).unwrap();
    let mut url = String::from("file://");
    for b in abs.to_string_lossy().bytes() {
        if b.is_ascii_alphanumeric() || b"/-_.~".contains(&b) {
            url.push(b as char);
        } else {
            url.push_str(&format!("%{b:02X}"));
        }
    }
    url
}

/// The console's errors since the last look (failed loads included).
fn errors(b: &Browser) -> Vec<String> {
    b.log()
        .into_iter()
        .filter(|(level, _)| level == "SEVERE")
        .map(|(_, m)| m)
        .collect()
}

/// Opens the page at `index` and waits until every image of the pass shown is
/// loaded or failed; returns (loaded, failed, total).
fn open(b: &Browser, index: &Path) -> (u64, u64, u64) {
    b.goto(&file_url(index));
    all_loaded(b, Duration::from_secs(10))
}

/// Waits until every image of the pass shown is loaded or failed; returns
/// (loaded, failed, total).
fn all_loaded(b: &Browser, timeout: Duration) -> (u64, u64, u64) {
    b.wait_for(
        "const c = window.volcastViewer && window.volcastViewer.counts(); return !!c && c.loaded + c.failed === c.total;",
        timeout,
        "the frames to load",
    );
    let c = b.eval("return window.volcastViewer.counts();", json!([]));
    let n = |k: &str| c[k].as_u64().unwrap();
    (n("loaded"), n("failed"), n("total"))
}

#[test]
fn in_chromium_the_page_turns_under_drag_and_keys_and_shows_every_frame() {
    let Some((chromium, driver)) = browser_tools() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render(d, SCENE, "mono", &["--viewer"]);
    let stereo = SCENE.replace(
        "[image]",
        "[stereo]\nlayout = \"pair\"\nangle = 30.0\n[image]",
    );
    render(d, &stereo, "pair", &["--viewer", "--frames", "0..2"]);
    render(d, &stereo, "pair", &["--viewer", "--resume"]);
    let gold: Vec<PathBuf> = (0..12)
        .map(|k| d.join(format!("mono/gold_{k:04}.png")))
        .collect();
    let mip: Vec<PathBuf> = (0..12)
        .map(|k| d.join(format!("mono/mip_{k:04}.png")))
        .collect();

    let b = Browser::start(&chromium, &driver, 640, 480);
    // every frame loads, the first is shown, and nothing went to the console
    assert_eq!(open(&b, &d.join("mono/index.html")), (12, 0, 12));
    let canvas = b.find("#view");
    let readout = b.find("#readout");
    let shot = |canvas: &webdriver::Element| decode(&b.screenshot(Some(canvas)));
    assert_eq!(b.attribute(&canvas, "data-frame"), "0");
    assert_eq!(b.attribute(&canvas, "data-state"), "ok");
    let first = shot(&canvas);
    assert_shows(&first, &gold, 0, "at load");
    // the object is there, not a blank page: lit pixels of many shades
    let lit = first.data.chunks_exact(3).filter(|p| p[0] > 40).count();
    let share = lit as f64 / (first.width * first.height) as f64;
    assert!(
        share > 0.03,
        "only {:.1}% of the canvas is lit",
        100.0 * share
    );
    let shades: std::collections::BTreeSet<u8> = first.data.iter().copied().collect();
    assert!(shades.len() > 40, "{} shades of grey", shades.len());
    assert!(b.text(&readout).contains("frame 0 of 12"));
    assert!(
        b.text(&readout).contains("azimuth 0.0°"),
        "{}",
        b.text(&readout)
    );
    assert!(b.text(&readout).contains("elevation 20.0°"));
    assert_eq!(errors(&b), Vec::<String>::new(), "console errors at load");

    // a drag of a quarter of the view's width to the right brings the near side
    // right: 3 frames back, to frame 9 (azimuth 9 x 30 = 270 degrees)
    b.drag(&canvas, -20, 0, 24, 4);
    assert_eq!(b.attribute(&canvas, "data-frame"), "9");
    assert_shows(&shot(&canvas), &gold, 9, "after the drag");
    let text = b.text(&readout);
    assert!(
        text.contains("frame 9 of 12") && text.contains("azimuth 270.0°"),
        "{text}"
    );
    // a finger does the same: a touch drag of 2 frames' width to the left, and back
    b.drag_with("touch", &canvas, 20, 0, -16, 4);
    assert_eq!(b.attribute(&canvas, "data-frame"), "11");
    b.drag_with("touch", &canvas, 0, 10, 16, 4);
    assert_eq!(b.attribute(&canvas, "data-frame"), "9");
    // the left arrow turns the other way, wrapping around after frame 11
    for _ in 0..3 {
        b.press(ARROW_LEFT);
    }
    assert_eq!(b.attribute(&canvas, "data-frame"), "0");
    b.press(ARROW_RIGHT);
    assert_eq!(b.attribute(&canvas, "data-frame"), "11");
    assert_shows(&shot(&canvas), &gold, 11, "after the arrow keys");
    // the other pass, at the same frame
    b.click(&b.find("#pass option[value=\"1\"]"));
    assert_eq!(b.attribute(&canvas, "data-pass"), "mip");
    b.wait_for(
        "return document.getElementById('view').dataset.state === 'ok';",
        Duration::from_secs(5),
        "the MIP frame",
    );
    assert_shows(&shot(&canvas), &mip, 11, "the mip pass");
    assert_eq!(errors(&b), Vec::<String>::new(), "console errors");

    // stereo pair: side by side, swapped, one eye; azimuths of both eyes
    assert_eq!(open(&b, &d.join("pair/index.html")), (24, 0, 24));
    let canvas = b.find("#view");
    let pair = |k: usize, eye: &str| d.join(format!("pair/gold_{k:04}_{eye}.png"));
    let sbs = shot(&canvas);
    let gap = sbs.width - 2 * 96;
    assert!(
        diff(&columns(&sbs, 0, 96), &read(&pair(0, "left"))) < 0.5,
        "left view on the left"
    );
    assert!(diff(&columns(&sbs, 96 + gap, 96), &read(&pair(0, "right"))) < 0.5);
    let text = b.text(&b.find("#readout"));
    assert!(text.contains("eyes 345.0°, 15.0°"), "{text}");
    b.click(&b.find("#swap"));
    let crossed = shot(&canvas);
    assert!(
        diff(&columns(&crossed, 0, 96), &read(&pair(0, "right"))) < 0.5,
        "cross-eyed: right view on the left"
    );
    b.click(&b.find("#eye option[value=\"right\"]"));
    assert!(diff(&shot(&canvas), &read(&pair(0, "right"))) < 0.5);
    assert_eq!(errors(&b), Vec::<String>::new(), "console errors (stereo)");

    // a frame file gone: that frame shows as missing, the others still turn
    let mut gold = gold;
    let gone = d.join("gone_0005.png");
    std::fs::rename(&gold[5], &gone).unwrap();
    gold[5] = gone;
    assert_eq!(open(&b, &d.join("mono/index.html")), (11, 1, 12));
    let canvas = b.find("#view");
    b.eval("window.volcastViewer.setFrame(5);", json!([]));
    assert_eq!(b.attribute(&canvas, "data-state"), "missing");
    assert!(b.text(&b.find("#readout")).contains("missing"));
    assert!(b.text(&b.find("#progress-text")).contains("1 missing"));
    // (and the console did report the failed load: the log is really read)
    let e = errors(&b);
    assert!(e.iter().any(|m| m.contains("gold_0005.png")), "{e:?}");
    b.press(ARROW_LEFT);
    assert_eq!(b.attribute(&canvas, "data-frame"), "6");
    assert_eq!(b.attribute(&canvas, "data-state"), "ok");
    assert_shows(&shot(&canvas), &gold, 6, "after a missing frame");
}

/// A 16 x 16 grey PNG of one level.
fn grey_png(level: u8) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut e = png::Encoder::new(&mut bytes, 16, 16);
    e.set_color(png::ColorType::Grayscale);
    let mut w = e.write_header().unwrap();
    w.write_image_data(&[level; 256]).unwrap();
    w.finish().unwrap();
    bytes
}

#[test]
fn in_chromium_a_page_of_3000_frames_stays_responsive() {
    use volcast::output::manifest::{FileRecord, FrameRecord, ViewRecord};
    let Some((chromium, driver)) = browser_tools() else {
        return;
    };
    const N: usize = 3000;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // frame k is a flat grey of level k % 251, so the picture tells the frame
    let level = |k: usize| (k % 251) as u8;
    let scene = volcast::scene::parse(
        &format!("[volume]\nsynthetic = \"ball\"\n[orbit]\nframes = {N}\n[image]\nsize = [16, 16]\n[[render]]\nmode = \"mip\"\n"),
        &d.join("many.toml"),
    )
    .unwrap();
    let records: Vec<FrameRecord> = (0..N)
        .map(|k| {
            let name = format!("mip_{k:04}.png");
            std::fs::write(d.join(&name), grey_png(level(k))).unwrap();
            FrameRecord {
                scene_hash: String::new(),
                volcast_version: String::new(),
                pass: "mip".into(),
                frame: k,
                files: vec![FileRecord {
                    name,
                    bytes: 0,
                    sha256: String::new(),
                }],
                views: vec![ViewRecord {
                    eye: "mono".into(),
                    view: (k as i64, "mono".into()),
                    azimuth_deg: k as f64 * 360.0 / N as f64,
                    elevation_deg: 0.0,
                    projection: "perspective".into(),
                    eye_position: [0.0; 3],
                    forward: [0.0; 3],
                    right: [0.0; 3],
                    up: [0.0; 3],
                    half_width: 1.0,
                    half_height: 1.0,
                    window_shift: 0.0,
                    target_distance: 1.0,
                    samples: 0,
                }],
                window: None,
                samples: 0,
                seconds: 0.0,
                shard: None,
            }
        })
        .collect();
    let data = volcast::output::viewer::page_data(
        &volcast::output::Outputs::of_scene(&scene),
        (16, 16),
        &records,
    );
    std::fs::write(d.join("index.html"), volcast::output::viewer::page(&data)).unwrap();

    let b = Browser::start(&chromium, &driver, 640, 480);
    let t0 = std::time::Instant::now();
    b.goto(&file_url(&d.join("index.html")));
    b.wait_for(
        "return document.getElementById('view').dataset.state === 'ok';",
        Duration::from_secs(5),
        "the first frame",
    );
    let first = t0.elapsed();
    // shown at once: while most frames are still to come
    let c = b.eval("return window.volcastViewer.counts();", json!([]));
    assert!(c["loaded"].as_u64().unwrap() < N as u64 / 2, "{c}");
    // preloading goes on in the background, a few images at a time; the page has
    // no element per frame
    let elements = b.eval(
        "return document.getElementsByTagName('*').length;",
        json!([]),
    );
    assert!(elements.as_u64().unwrap() < 100, "{elements} elements");
    // a hundred steps take milliseconds, while the frames still load
    let ms = b.eval(
        "const t = performance.now(); for (let i = 0; i < 100; i++) document.dispatchEvent(new KeyboardEvent('keydown', { key: 'ArrowLeft' })); return performance.now() - t;",
        json!([]),
    );
    assert!(ms.as_f64().unwrap() < 500.0, "100 key steps took {ms} ms");
    let canvas = b.find("#view");
    assert_eq!(b.attribute(&canvas, "data-frame"), "100");
    // a real key press and a drag reach frames by wrapping around
    b.press(ARROW_RIGHT);
    assert_eq!(b.attribute(&canvas, "data-frame"), "99");
    b.drag(&canvas, 0, 0, -8, 2); // half the view's width: 1500 frames on
    assert_eq!(b.attribute(&canvas, "data-frame"), "1599");
    let counts = all_loaded(&b, Duration::from_secs(30));
    let all = t0.elapsed();
    assert_eq!(counts, (N as u64, 0, N as u64));
    let shot = decode(&b.screenshot(Some(&canvas)));
    assert!(
        shot.data.iter().all(|&v| v == level(1599)),
        "frame 1599 is grey {}",
        level(1599)
    );
    assert_eq!(errors(&b), Vec::<String>::new());
    eprintln!(
        "3000 frames: the first shown after {:.2} s, all loaded after {:.2} s",
        first.as_secs_f64(),
        all.as_secs_f64()
    );
}

/// The README's picture of the page: `docs/make_images.sh` renders
/// `scenes/golden_skull.toml` and runs this with `VOLCAST_VIEWER_PAGE` (its
/// index.html) and `VOLCAST_VIEWER_PICTURE` (the PNG to write).
#[test]
#[ignore = "writes the README's picture; run by docs/make_images.sh"]
fn viewer_picture_for_the_readme() {
    let page = PathBuf::from(std::env::var("VOLCAST_VIEWER_PAGE").expect("VOLCAST_VIEWER_PAGE"));
    let picture =
        PathBuf::from(std::env::var("VOLCAST_VIEWER_PICTURE").expect("VOLCAST_VIEWER_PICTURE"));
    let (chromium, driver) = browser_tools().expect("chromium and chromedriver");
    let b = Browser::start(&chromium, &driver, 520, 560);
    let (loaded, failed, total) = open(&b, &page);
    assert_eq!((loaded, failed), (total, 0));
    // turn it a little: a drag to the left, 4 frames on
    let canvas = b.find("#view");
    let width = b.eval("return DATA.width;", json!([]));
    let frames = b.eval("return DATA.frames;", json!([]));
    let dx = -(4 * width.as_i64().unwrap() / frames.as_i64().unwrap());
    b.drag(&canvas, 0, 0, dx, 4);
    assert_eq!(b.attribute(&canvas, "data-frame"), "4");
    assert_eq!(errors(&b), Vec::<String>::new());
    std::fs::write(&picture, b.screenshot(None)).unwrap();
}
