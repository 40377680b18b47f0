//! The turntable page: `{out}/index.html`, one self-contained file (inline script
//! and style, no network) that shows the frames beside it and turns the object
//! under the mouse.
//!
//! The page is the template `viewer.html` with the data of [`page_data`] injected as
//! JSON. That data comes from the manifest's records only (file names, order, each
//! eye's azimuth and elevation), never from guessing file names, and holds nothing
//! that differs between runs (no times, shards or absolute paths), so one run,
//! shards and `--resume` runs write the same bytes. It is written with the manifest
//! once every frame of the orbit exists.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use super::manifest::FrameRecord;
use super::write::Folder;
use super::Outputs;
use crate::error::Error;
use crate::scene::Layout;

/// File name of the page in the output folder.
pub const PAGE: &str = "index.html";

/// The page's HTML, script and style; `DATA_SLOT` is replaced by the data.
const TEMPLATE: &str = include_str!("viewer.html");
/// The placeholder in [`TEMPLATE`] that the data replaces (a valid script value on
/// its own, so the template can be opened and checked as it is).
const DATA_SLOT: &str = "/*VOLCAST_DATA*/null";

/// Where the page finds one eye in a frame's files: the file's index in the record
/// and the left edge of the view in it (pixels).
fn source(file: usize, x: usize) -> Value {
    json!({ "file": file, "x": x })
}

/// The views a frame's files hold, by name (`mono`, `left`, `right`, `anaglyph`),
/// and how many files a frame has.
fn sources(outputs: &Outputs, width: usize) -> (Value, usize) {
    let Some(st) = outputs.stereo else {
        return (json!({ "mono": source(0, 0) }), 1);
    };
    match st.layout {
        Layout::Pair => (json!({ "left": source(0, 0), "right": source(1, 0) }), 2),
        Layout::SideBySide => (
            json!({ "left": source(0, 0), "right": source(0, width + st.gap) }),
            1,
        ),
        Layout::CrossEyed => (
            json!({ "left": source(0, width + st.gap), "right": source(0, 0) }),
            1,
        ),
        Layout::Anaglyph => (json!({ "anaglyph": source(0, 0) }), 1),
    }
}

/// The data the page shows, from the run's outputs and the records of its frames (in any
/// order; a (pass, frame) without a record, or whose record does not have the
/// files the layout writes, is `null`: the page shows it as missing). `size` is the
/// image size of one view.
pub fn page_data(outputs: &Outputs, size: (usize, usize), records: &[FrameRecord]) -> Value {
    let (eyes, files_per_frame) = sources(outputs, size.0);
    let frames = outputs.frames;
    let passes: Vec<Value> = outputs
        .passes
        .iter()
        .map(|p| {
            let mut list = vec![Value::Null; frames];
            for r in records.iter().filter(|r| r.pass == p.name) {
                if r.frame < frames && r.files.len() == files_per_frame {
                    list[r.frame] = json!({
                        "files": r.files.iter().map(|f| f.name.as_str()).collect::<Vec<_>>(),
                        "views": r.views.iter().map(|v| json!({
                            "eye": v.eye,
                            "azimuth": v.azimuth_deg,
                            "elevation": v.elevation_deg,
                        })).collect::<Vec<_>>(),
                    });
                }
            }
            json!({ "name": p.name, "mode": p.mode, "frames": list })
        })
        .collect();
    let layout = outputs.stereo.map(|s| match s.layout {
        Layout::Pair => "pair",
        Layout::SideBySide => "side-by-side",
        Layout::CrossEyed => "cross-eyed",
        Layout::Anaglyph => "anaglyph",
    });
    json!({
        "title": outputs.title,
        "frames": frames,
        "degrees": outputs.degrees,
        // a drag to the right moves the object's near side to the right: towards
        // lower azimuths, so lower frames when the orbit turns the positive way
        "grab": if outputs.degrees >= 0.0 { -1 } else { 1 },
        "fps": outputs.animation.as_ref().map_or(24.0, |a| a.fps),
        "width": size.0,
        "height": size.1,
        "gap": outputs.stereo.map_or(0, |s| s.gap),
        "layout": layout,
        "eyes": eyes,
        "passes": passes,
    })
}

/// JSON safe inside an HTML `<script>` element: `<`, `>` and `&` (so no
/// `</script>` or `<!--` can end it early) and the line separators U+2028/U+2029
/// are written as `\u` escapes, which JSON and JavaScript read back unchanged.
fn script_json(data: &Value) -> String {
    let text = data.to_string();
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '<' => out.push_str("\\u003c"),
            '>' => out.push_str("\\u003e"),
            '&' => out.push_str("\\u0026"),
            '\u{2028}' => out.push_str("\\u2028"),
            '\u{2029}' => out.push_str("\\u2029"),
            c => out.push(c),
        }
    }
    out
}

/// The page's bytes for `data` (see [`page_data`]).
pub fn page(data: &Value) -> String {
    TEMPLATE.replacen(DATA_SLOT, &script_json(data), 1)
}

/// Writes the page of `records` into `folder` (the output folder `out`)
/// atomically; a link there is an error, not replaced.
pub fn write_page(
    folder: &Folder,
    out: &Path,
    outputs: &Outputs,
    size: (usize, usize),
    records: &[FrameRecord],
) -> Result<PathBuf, Error> {
    let html = page(&page_data(outputs, size, records));
    super::manifest::write_unlinked(folder, out, PAGE, html.as_bytes())?;
    Ok(out.join(PAGE))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::manifest::{FileRecord, ViewRecord};

    /// The outputs of a scene of two passes and 4 frames (`orbit` adds to the
    /// `[orbit]` table).
    fn scene_of(orbit: &str, extra: &str) -> Outputs {
        let text = format!(
            "[volume]\nsynthetic = \"ball\"\nsizes = [4, 4, 4]\n[orbit]\nframes = 4\n{orbit}[image]\nsize = [10, 8]\n[[render]]\nmode = \"mip\"\n[[render]]\nname = \"iso\"\nmode = \"surface\"\n{extra}"
        );
        Outputs::of_scene(&crate::scene::parse(&text, Path::new("/tmp/spin.toml")).unwrap())
    }

    fn scene(extra: &str) -> Outputs {
        scene_of("", extra)
    }

    fn view(eye: &str, azimuth_deg: f64) -> ViewRecord {
        ViewRecord {
            eye: eye.into(),
            view: (0, eye.into()),
            azimuth_deg,
            elevation_deg: 25.0,
            projection: "perspective".into(),
            eye_position: [0.0; 3],
            forward: [0.0, 1.0, 0.0],
            right: [1.0, 0.0, 0.0],
            up: [0.0, 0.0, 1.0],
            half_width: 1.0,
            half_height: 1.0,
            window_shift: 0.0,
            target_distance: 1.0,
            samples: 0,
        }
    }

    fn record(pass: &str, frame: usize, files: &[&str], views: Vec<ViewRecord>) -> FrameRecord {
        FrameRecord {
            scene_hash: "h".into(),
            volcast_version: "0".into(),
            pass: pass.into(),
            frame,
            files: files
                .iter()
                .map(|n| FileRecord {
                    name: (*n).into(),
                    bytes: 1,
                    sha256: "0".into(),
                })
                .collect(),
            views,
            window: None,
            samples: 1,
            seconds: 0.25,
            shard: Some("1/2".into()),
        }
    }

    #[test]
    fn frames_come_from_the_records_in_frame_order_and_missing_ones_are_null() {
        let s = scene("");
        // records out of order, one frame of `iso` missing, one record of a pass
        // or frame the scene does not have
        let records = vec![
            record("mip", 2, &["mip_0002.png"], vec![view("mono", 180.0)]),
            record("mip", 0, &["mip_0000.png"], vec![view("mono", 0.0)]),
            record("mip", 3, &["mip_0003.png"], vec![view("mono", 270.0)]),
            record("mip", 1, &["mip_0001.png"], vec![view("mono", 90.0)]),
            record("iso", 0, &["iso_0000.png"], vec![view("mono", 0.0)]),
            record("iso", 1, &["iso_0001.png"], vec![view("mono", 90.0)]),
            record("iso", 3, &["iso_0003.png"], vec![view("mono", 270.0)]),
            record("gone", 0, &["gone_0000.png"], vec![view("mono", 0.0)]),
            record("mip", 9, &["mip_0009.png"], vec![view("mono", 0.0)]),
        ];
        let d = page_data(&s, (10, 8), &records);
        assert_eq!(d["title"], "spin");
        assert_eq!(d["frames"], 4);
        assert_eq!(
            (d["width"].as_u64(), d["height"].as_u64()),
            (Some(10), Some(8))
        );
        assert_eq!(d["fps"], 24.0);
        assert_eq!(d["grab"], -1, "360 degrees: a drag to the right goes back");
        assert_eq!(d["layout"], Value::Null);
        assert_eq!(d["eyes"], json!({ "mono": { "file": 0, "x": 0 } }));
        let passes = d["passes"].as_array().unwrap();
        assert_eq!(passes.len(), 2);
        assert_eq!(
            (&passes[0]["name"], &passes[0]["mode"]),
            (&json!("mip"), &json!("mip"))
        );
        assert_eq!(passes[1]["mode"], "surface");
        let names = |p: usize| -> Vec<Value> {
            passes[p]["frames"]
                .as_array()
                .unwrap()
                .iter()
                .map(|f| f.get("files").map_or(Value::Null, |f| f[0].clone()))
                .collect()
        };
        assert_eq!(
            names(0),
            vec![
                json!("mip_0000.png"),
                json!("mip_0001.png"),
                json!("mip_0002.png"),
                json!("mip_0003.png")
            ]
        );
        assert_eq!(
            names(1),
            vec![
                json!("iso_0000.png"),
                json!("iso_0001.png"),
                Value::Null,
                json!("iso_0003.png")
            ]
        );
        let v = &passes[0]["frames"][2]["views"][0];
        assert_eq!(
            (&v["eye"], &v["azimuth"], &v["elevation"]),
            (&json!("mono"), &json!(180.0), &json!(25.0))
        );
        // nothing that changes between runs: times and shards stay out
        let text = page(&d);
        assert!(!text.contains("0.25") && !text.contains("1/2"));
    }

    #[test]
    fn stereo_layouts_say_where_each_eye_is() {
        let w = 10;
        let eyes = |stereo: &str| page_data(&scene(stereo), (w, 8), &[])["eyes"].clone();
        assert_eq!(
            eyes("[stereo]\nlayout = \"pair\"\n"),
            json!({ "left": { "file": 0, "x": 0 }, "right": { "file": 1, "x": 0 } })
        );
        assert_eq!(
            eyes("[stereo]\nlayout = \"side-by-side\"\ngap = 6\n"),
            json!({ "left": { "file": 0, "x": 0 }, "right": { "file": 0, "x": 16 } })
        );
        // cross-eyed: the right view on the left
        assert_eq!(
            eyes("[stereo]\nlayout = \"cross-eyed\"\ngap = 6\n"),
            json!({ "left": { "file": 0, "x": 16 }, "right": { "file": 0, "x": 0 } })
        );
        assert_eq!(
            eyes("[stereo]\nlayout = \"anaglyph\"\n"),
            json!({ "anaglyph": { "file": 0, "x": 0 } })
        );
        // a pair record with one file does not fit the layout: missing, not broken
        let s = scene("[stereo]\nlayout = \"pair\"\n");
        let one = record("mip", 0, &["mip_0000_left.png"], vec![view("left", -4.0)]);
        let two = record(
            "mip",
            1,
            &["mip_0001_left.png", "mip_0001_right.png"],
            vec![view("left", 86.0), view("right", 94.0)],
        );
        let d = page_data(&s, (w, 8), &[one, two]);
        assert_eq!(d["layout"], "pair");
        assert_eq!(d["passes"][0]["frames"][0], Value::Null);
        assert_eq!(
            d["passes"][0]["frames"][1]["files"][1],
            "mip_0001_right.png"
        );
        assert_eq!(d["passes"][0]["frames"][1]["views"][1]["azimuth"], 94.0);
    }

    #[test]
    fn the_orbit_direction_and_frame_rate_reach_the_page() {
        let d = page_data(&scene_of("degrees = -90.0\n", ""), (10, 8), &[]);
        assert_eq!(d["grab"], 1);
        let d = page_data(&scene("[animation]\nfps = 12.5\n"), (10, 8), &[]);
        assert_eq!(d["fps"], 12.5);
    }

    #[test]
    fn the_data_cannot_end_the_script_early() {
        let data = json!({ "title": "</script><!-- & \u{2028}" });
        let text = script_json(&data);
        assert!(!text.contains('<') && !text.contains('>') && !text.contains('&'));
        assert!(!text.contains('\u{2028}'));
        // and it reads back as the same value
        let back: Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back, data);
        let html = page(&data);
        assert_eq!(
            html.matches("</script>").count(),
            TEMPLATE.matches("</script>").count()
        );
        assert!(!html.contains(DATA_SLOT));
    }

    #[test]
    fn the_template_is_self_contained() {
        assert_eq!(TEMPLATE.matches(DATA_SLOT).count(), 1);
        // no network: nothing is fetched from another place
        for banned in [
            "http://",
            "https://",
            "//cdn",
            "src=\"http",
            "@import",
            "fetch(",
        ] {
            assert!(!TEMPLATE.contains(banned), "the template mentions {banned}");
        }
    }
}
