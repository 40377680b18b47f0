//! Camera paths and keyframes (issue 8, item 5): a keyframed frame is the single
//! render at the interpolated values, bit for bit; the smooth path is the uniform
//! Catmull-Rom spline; rock and elevation paths follow their formulas; and the
//! mistakes a scene can make are reported at their place.

use std::path::Path;

use volcast::pipeline::{render_films, RenderedView};
use volcast::plan::RunOptions;
use volcast::scene::Scene;
use volcast::volume::Limits;

const VOLUME: &str = "[volume]\nsynthetic = \"blobs\"\nsizes = [40, 40, 40]\n\
                      [image]\nsize = [48, 40]\nformat = \"nrrd\"\n";

fn parse(text: &str) -> Scene {
    volcast::scene::parse(text, Path::new("keys.toml")).unwrap_or_else(|e| panic!("{e}"))
}

fn render(scene: &Scene, frames: std::ops::Range<usize>) -> Vec<RenderedView> {
    let opts = RunOptions {
        frames: Some(frames),
        ..RunOptions::default()
    };
    render_films(scene, &opts, &Limits::default())
        .expect("renders")
        .0
}

fn bits(v: &RenderedView) -> Vec<u32> {
    v.film.data.iter().map(|x| x.to_bits()).collect()
}

const PASSES: &str = "[[render]]\nname = \"s\"\nmode = \"surface\"\niso = {ISO}\n\
                      [[render]]\nname = \"d\"\nmode = \"depth\"\nthreshold = {ISO}\n\
                      [[render]]\nname = \"m\"\nmode = \"mip\"\n\
                      [[clip]]\nname = \"peel\"\npoint = [0, 0, 0]\nnormal = [0, -1, 0.3]\noffset = {OFFSET}\ncap = true\n";

#[test]
fn a_keyframed_frame_is_the_render_at_the_interpolated_values() {
    // frame 2 of 5 is halfway between the keyframes at 0 and 4 (values chosen so
    // that the halfway values are exact in binary)
    let keyed = parse(&format!(
        "{VOLUME}[camera]\nprojection = \"perspective\"\n[orbit]\nframes = 5\n{}\
         [[keyframe]]\nframe = 0\nazimuth = 10\nelevation = 0\nzoom = 1.0\nrender.s.iso = 0.25\nrender.d.threshold = 0.25\nclip.peel.offset = 0.0\n\
         [[keyframe]]\nframe = 4\nazimuth = 50\nelevation = 20\nzoom = 1.5\nrender.s.iso = 0.75\nrender.d.threshold = 0.75\nclip.peel.offset = 0.5\n",
        PASSES.replace("{ISO}", "0.5").replace("{OFFSET}", "0.0")
    ));
    let single = parse(&format!(
        "{VOLUME}[camera]\nprojection = \"perspective\"\nazimuth = 30\nelevation = 10\nzoom = 1.25\n{}",
        PASSES.replace("{ISO}", "0.5").replace("{OFFSET}", "0.25")
    ));
    let a = render(&keyed, 2..3);
    let b = render(&single, 0..1);
    assert_eq!(a.len(), 3);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.pass, y.pass);
        assert_eq!(bits(x), bits(y), "pass {} differs", x.pass);
    }
    // and the frames before the first and after the last key hold their values
    let held = parse(&format!(
        "{VOLUME}[camera]\nprojection = \"perspective\"\n[orbit]\nframes = 6\n{}\
         [[keyframe]]\nframe = 1\nazimuth = 10\nrender.s.iso = 0.25\n\
         [[keyframe]]\nframe = 4\nazimuth = 50\nrender.s.iso = 0.75\n",
        PASSES.replace("{ISO}", "0.5").replace("{OFFSET}", "0.0")
    ));
    let v = render(&held, 0..6);
    let frame = |k: usize| v.iter().find(|r| r.frame == k && r.pass == 0).unwrap();
    assert_eq!(bits(frame(0)), bits(frame(1)));
    assert_eq!(bits(frame(4)), bits(frame(5)));
    assert_ne!(bits(frame(1)), bits(frame(2)));
}

#[test]
fn a_smooth_path_is_the_uniform_catmull_rom_spline() {
    let keys = [(0.0, 0.0), (3.0, 90.0), (5.0, 100.0), (9.0, 370.0)];
    let mut text = format!(
        "{VOLUME}[orbit]\nframes = 12\ninterpolation = \"smooth\"\n[[render]]\nmode = \"mip\"\n"
    );
    for (f, a) in keys {
        text += &format!(
            "[[keyframe]]\nframe = {f}\nazimuth = {a}\nelevation = {}\n",
            a / 10.0
        );
    }
    let scene = parse(&text);
    // independently: the segment holding frame k, its local parameter, and the
    // Catmull-Rom basis with the end keys repeated
    let cr = |k: f64, scale: f64| {
        let v: Vec<f64> = keys.iter().map(|&(_, a)| a * scale).collect();
        if k <= keys[0].0 {
            return v[0];
        }
        if k >= keys[3].0 {
            return v[3];
        }
        let i = (0..3).find(|&i| k < keys[i + 1].0).unwrap();
        let u = (k - keys[i].0) / (keys[i + 1].0 - keys[i].0);
        let p = |j: isize| v[j.clamp(0, 3) as usize];
        let (p0, p1, p2, p3) = (
            p(i as isize - 1),
            p(i as isize),
            p(i as isize + 1),
            p(i as isize + 2),
        );
        let (u2, u3) = (u * u, u * u * u);
        0.5 * ((-u3 + 2.0 * u2 - u) * p0
            + (3.0 * u3 - 5.0 * u2 + 2.0) * p1
            + (-3.0 * u3 + 4.0 * u2 + u) * p2
            + (u3 - u2) * p3)
    };
    for k in 0..12 {
        let c = scene.camera_at(k);
        let (az, el) = (cr(k as f64, 1.0), cr(k as f64, 0.1));
        assert!(
            (c.azimuth_deg - az).abs() < 1e-9,
            "frame {k}: azimuth {} vs {az}",
            c.azimuth_deg
        );
        assert!(
            (c.elevation_deg - el).abs() < 1e-9,
            "frame {k}: elevation {} vs {el}",
            c.elevation_deg
        );
    }
    // the keys themselves are hit; 370 is not wrapped to 10
    assert_eq!(scene.camera_at(9).azimuth_deg, 370.0);
    assert_eq!(scene.camera_at(11).azimuth_deg, 370.0);
}

#[test]
fn rock_and_elevation_paths_follow_their_formulas() {
    use std::f64::consts::PI;
    let rock = parse(&format!(
        "{VOLUME}[camera]\nazimuth = 20\nelevation = 5\n[orbit]\nframes = 8\npath = \"rock\"\ndegrees = 40\n[[render]]\nmode = \"mip\"\n"
    ));
    let swing = parse(&format!(
        "{VOLUME}[camera]\nazimuth = 20\n[orbit]\nframes = 8\npath = \"elevation\"\nelevations = [-30, 60]\n[[render]]\nmode = \"mip\"\n"
    ));
    for k in 0..8 {
        let phase = 2.0 * PI * k as f64 / 8.0;
        let c = rock.camera_at(k);
        assert!((c.azimuth_deg - (20.0 + 20.0 * phase.sin())).abs() < 1e-12);
        assert_eq!(c.elevation_deg, 5.0);
        let c = swing.camera_at(k);
        assert_eq!(c.azimuth_deg, 20.0);
        assert!((c.elevation_deg - (-30.0 + 90.0 * (1.0 - phase.cos()) / 2.0)).abs() < 1e-12);
    }
    // the rendered views are those cameras: frame 2 of the rock is at azimuth 40,
    // the same view as a single render there
    let single = parse(&format!(
        "{VOLUME}[camera]\nazimuth = {}\nelevation = 5\n[[render]]\nmode = \"mip\"\n",
        rock.camera_at(2).azimuth_deg
    ));
    assert_eq!(
        bits(&render(&rock, 2..3)[0]),
        bits(&render(&single, 0..1)[0])
    );
    // a default rock swings 30 degrees
    let default = parse(&format!(
        "{VOLUME}[orbit]\nframes = 4\npath = \"rock\"\n[[render]]\nmode = \"mip\"\n"
    ));
    assert!((default.camera_at(1).azimuth_deg - 15.0).abs() < 1e-12);
}

#[test]
fn stereo_works_on_every_path() {
    for path in [
        "path = \"rock\"",
        "path = \"elevation\"\nelevations = [0, 40]",
    ] {
        let scene = parse(&format!(
            "{VOLUME}[orbit]\nframes = 4\n{path}\n[stereo]\nangle = 6\n[[render]]\nmode = \"mip\"\n"
        ));
        let v = render(&scene, 0..4);
        assert_eq!(v.len(), 8);
        for k in 0..4 {
            let eyes: Vec<&RenderedView> = v.iter().filter(|r| r.frame == k).collect();
            let (l, r) = (&eyes[0].view, &eyes[1].view);
            // toe-in: the eyes are turned 6 degrees apart about the frame's camera
            let cos = l.forward.dot(r.forward).clamp(-1.0, 1.0);
            let angle = cos.acos().to_degrees();
            let cam = scene.camera_at(k);
            // turning about up by 6 degrees moves the view direction by 6 cos(elevation)
            let want = 2.0
                * ((3.0f64.to_radians().sin()) * cam.elevation_deg.to_radians().cos())
                    .asin()
                    .to_degrees();
            assert!(
                (angle - want).abs() < 1e-6,
                "{path} frame {k}: {angle} vs {want}"
            );
        }
    }
}

#[test]
fn keyframe_mistakes_are_reported_at_their_place() {
    let base = format!("{VOLUME}[[render]]\nname = \"s\"\nmode = \"surface\"\n[[render]]\nname = \"m\"\nmode = \"mip\"\n[[clip]]\npoint = [0, 0, 0]\nnormal = [1, 0, 0]\n");
    let bad = [
        (
            "[orbit]\nframes = 4\ndegrees = 90\n[[keyframe]]\nframe = 0\nazimuth = 0\n",
            "`degrees` cannot be combined",
        ),
        (
            "[orbit]\nframes = 4\n[[keyframe]]\nframe = 4\nazimuth = 0\n",
            "expected a frame from 0 to 3",
        ),
        (
            "[orbit]\nframes = 4\n[[keyframe]]\nframe = 1\n[[keyframe]]\nframe = 1\n",
            "two [[keyframe]] tables have frame = 1",
        ),
        (
            "[orbit]\nframes = 4\n[[keyframe]]\nframe = 1\nrender.x.iso = 0.5\n",
            "no pass is named `x`",
        ),
        (
            "[orbit]\nframes = 4\n[[keyframe]]\nframe = 1\nrender.m.iso = 0.5\n",
            "no iso value or threshold",
        ),
        (
            "[orbit]\nframes = 4\n[[keyframe]]\nframe = 1\nrender.s.threshold = 0.5\n",
            "whose value is `iso`",
        ),
        (
            "[orbit]\nframes = 4\n[[keyframe]]\nframe = 1\nclip.a.offset = 1\n",
            "give the plane a `name`",
        ),
        (
            "[orbit]\nframes = 4\n[[keyframe]]\nframe = 1\nelevation = 95\n",
            "from -90 to 90",
        ),
        (
            "[orbit]\nframes = 4\n[[keyframe]]\nframe = 1\nroll = 5\n",
            "unknown field `roll`",
        ),
        (
            "[orbit]\nframes = 4\npath = \"elevation\"\n",
            "needs `elevations",
        ),
        (
            "[orbit]\nframes = 4\npath = \"elevation\"\nelevations = [0, 100]\n",
            "from -90 to 90",
        ),
        (
            "[orbit]\nframes = 4\npath = \"spiral\"\n",
            "expected one of",
        ),
        (
            "[orbit]\nframes = 4\npath = \"rock\"\n[[keyframe]]\nframe = 0\n",
            "cannot be combined with [[keyframe]]",
        ),
    ];
    for (extra, want) in bad {
        let err = volcast::scene::parse(&format!("{base}{extra}"), Path::new("keys.toml"))
            .expect_err(extra)
            .to_string();
        assert!(err.contains(want), "{extra}: {err}");
        assert!(err.contains("keys.toml:"), "{extra}: no location in {err}");
    }
}
