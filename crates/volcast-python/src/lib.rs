//! `volcast._volcast`, the native half of the Python package `volcast`
//! (python/volcast wraps it; docs/python.md is the user's guide).
//!
//! ```text
//! scene (dict | TOML text | path) --scene::input/load--> Scene ([volume] replaced by
//! volume (NumPy array) --array::source----------------> VolumeSource::Memory, in place)
//!   render:    pipeline::render_images (no out)  --images::of_stored--> arrays
//!              pipeline::render (out: the files)  --images::read_back--> arrays
//!   check:     Plan::build -> the plan as JSON;  info: volume::info::json
//!   turntable: pipeline::render with the viewer page, the frames inlined in it
//! ```
//!
//! Every run happens on a thread of its own with the GIL released, while the
//! calling thread polls for signals (`run::cancellable`): Ctrl-C cancels the run
//! between views ([`volcast::pipeline::Progress::cancelled`]) and raises
//! `KeyboardInterrupt`.

mod array;
mod errors;
mod images;
mod run;
mod scene;

use std::path::{Path, PathBuf};

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use volcast::plan::{Plan, RunOptions};
use volcast::volume::{Limits, VolumeSource};

/// An array given as `volume=`: the array, its buffer's address and length, its
/// dtype name, shape (i, j, k), spacing and origin (see `python/volcast`).
type ArraySpec = (
    Py<PyAny>,
    usize,
    usize,
    String,
    [usize; 3],
    [f64; 3],
    [f64; 3],
);

/// One output array: its key (the pass, or `pass_left`/`pass_right`), NumPy dtype
/// name, shape and bytes.
type Output = (String, &'static str, Vec<usize>, Py<PyAny>);

/// A resolved scene and the label of a scene given as a dict or text.
struct Prepared {
    scene: volcast::scene::Scene,
    label: Option<&'static str>,
}

fn prepare(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    volume: Option<ArraySpec>,
) -> PyResult<Prepared> {
    let input = scene::input(scene)?;
    let label = match &input {
        scene::Input::Text { label, .. } => Some(*label),
        scene::Input::File(_) => None,
    };
    let mut scene = scene::load(py, &input, volume.is_some())?;
    if let Some((a, ptr, nbytes, dtype, shape, spacing, origin)) = volume {
        scene.volumes[0].spec.source =
            array::source(a, ptr, nbytes, &dtype, shape, spacing, origin)?;
    }
    Ok(Prepared { scene, label })
}

/// `render(scene, volume, out)`: the images of every pass, as the files hold them.
#[pyfunction]
#[pyo3(signature = (scene, volume=None, out=None))]
fn render(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    volume: Option<ArraySpec>,
    out: Option<PathBuf>,
) -> PyResult<Vec<Output>> {
    let Prepared { scene, label } = prepare(py, scene, volume)?;
    let limits = Limits::default();
    let opts = RunOptions {
        out: out.clone(),
        ..Default::default()
    };
    match out {
        None => {
            let (stored, _) = run::cancellable(py, |progress| {
                volcast::pipeline::render_images(&scene, &opts, &limits, progress)
            })?
            .map_err(|e| errors::run(py, &e, label))?;
            let format = scene.image.format;
            images::of_stored(py, &scene, format, &stored)
        }
        Some(out) => {
            run::cancellable(py, |progress| {
                volcast::pipeline::render(&scene, &opts, &limits, progress)
            })?
            .map_err(|e| errors::run(py, &e, label))?;
            let plan = plan_of(py, &scene, &opts, label)?;
            images::read_back(py, &plan, &out)
        }
    }
}

/// The plan of a scene (reads only the volume's header).
fn plan_of(
    py: Python<'_>,
    scene: &volcast::scene::Scene,
    opts: &RunOptions,
    label: Option<&str>,
) -> PyResult<Plan> {
    let headers = volcast::pipeline::headers(scene).map_err(|e| errors::run(py, &e, label))?;
    Plan::build(scene, &headers, opts).map_err(|e| errors::run(py, &e, label))
}

/// `check(scene, volume)`: the plan as JSON text, with the text `volcast check`
/// prints.
#[pyfunction]
#[pyo3(signature = (scene, volume=None))]
fn check(py: Python<'_>, scene: &Bound<'_, PyAny>, volume: Option<ArraySpec>) -> PyResult<String> {
    let Prepared { scene, label } = prepare(py, scene, volume)?;
    let opts = RunOptions::default();
    let headers = volcast::pipeline::headers(&scene).map_err(|e| errors::run(py, &e, label))?;
    let plan = Plan::build(&scene, &headers, &opts).map_err(|e| errors::run(py, &e, label))?;
    plan.check_memory(&Limits::default())
        .map_err(|e| errors::run(py, &e, label))?;
    let mut text = plan.describe(&scene);
    if let Some(l) = label {
        // the scene line names the dict or text, as its errors do
        text = text.replacen(&scene.path.display().to_string(), l, 1);
    }
    text.push('\n');
    for w in &scene.warnings {
        text += &format!("warning  {w}\n");
    }
    text += "ok\n";
    let eyes = images::eyes(&plan);
    let (eyes_ref, out_ref) = (&eyes, &plan.out);
    let passes: Vec<serde_json::Value> = plan
        .output
        .passes
        .iter()
        .map(|p| {
            let files: Vec<String> = plan
                .frame_list
                .iter()
                .flat_map(|&k| {
                    eyes_ref.iter().map(move |&e| {
                        volcast::output::frame_path(
                            out_ref,
                            &p.name,
                            k,
                            e,
                            plan.output.format.extension(),
                        )
                        .display()
                        .to_string()
                    })
                })
                .collect();
            serde_json::json!({ "name": p.name, "mode": p.mode, "files": files })
        })
        .collect();
    let file = errors::shown_path(&scene.path, label);
    // each volume as the plan places it (the first also as `volume`)
    let volumes: Vec<serde_json::Value> = plan
        .volumes
        .iter()
        .map(|v| {
            let header = &v.header;
            serde_json::json!({
                "name": v.name,
                "source": header.source,
                "sizes": header.sizes,
                "type": header.scalar_type.nrrd_name(),
                "spacing": header.geometry.spacings(),
                "origin": header.geometry.origin.to_array(),
                "storage": match &v.storage {
                    volcast::volume::Storage::Mapped { .. } => "mapped".to_string(),
                    volcast::volume::Storage::Read { reason, .. } => format!("read ({reason})"),
                },
                "passes": v.passes,
            })
        })
        .collect();
    let json = serde_json::json!({
        "scene": file,
        "volume": volumes[0],
        "volumes": volumes,
        "width": plan.width,
        "height": plan.height,
        "frames": plan.frame_list.len(),
        "frame_list": plan.frame_list,
        "format": plan.output.format.extension(),
        "passes": passes,
        "files_per_frame": eyes.len() * plan.output.passes.len(),
        "out": plan.out.display().to_string(),
        "memory": plan.memory.iter().map(|(what, b)| serde_json::json!({ "what": what, "bytes": b })).collect::<Vec<_>>(),
        "memory_bytes": plan.memory_bytes(),
        "samples_estimate": plan.samples_estimate,
        "threads": plan.threads,
        "warnings": scene.warnings,
        "resolved": volcast::output::manifest::resolved_scene(&scene),
        "text": text,
    });
    Ok(json.to_string())
}

/// `info(path)`: the `volcast info --json` object of a volume file (or of a scene
/// file's volume), as JSON text.
#[pyfunction]
fn info_path(py: Python<'_>, path: PathBuf) -> PyResult<String> {
    let source = if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
    {
        volcast::scene::load(&path)
            .map_err(|e| errors::scene(py, &e, None))?
            .volumes
            .swap_remove(0)
            .spec
            .source
    } else {
        VolumeSource::from_path(&path).map_err(|e| errors::run(py, &e.into(), None))?
    };
    info_of(py, &source)
}

/// `info(array)`: the `volcast info --json` object of an array, as JSON text.
#[pyfunction]
fn info_array(py: Python<'_>, volume: ArraySpec) -> PyResult<String> {
    let (a, ptr, nbytes, dtype, shape, spacing, origin) = volume;
    let source = array::source(a, ptr, nbytes, &dtype, shape, spacing, origin)?;
    info_of(py, &source)
}

fn info_of(py: Python<'_>, source: &VolumeSource) -> PyResult<String> {
    let limits = Limits::default();
    let json = run::cancellable(py, |_| {
        source
            .load(&limits)
            .map(|v| volcast::volume::info::json(&v))
    })?
    .map_err(|e| errors::run(py, &e.into(), None))?;
    Ok(json.to_string())
}

/// `turntable(scene, volume, out)`: renders the scene with its turntable page and
/// returns the page with the frames inlined (data: URLs), the images, and the folder
/// written (`None` when `out` was not given: a temporary folder, removed).
#[pyfunction]
#[pyo3(signature = (scene, volume=None, out=None))]
fn turntable(
    py: Python<'_>,
    scene: &Bound<'_, PyAny>,
    volume: Option<ArraySpec>,
    out: Option<PathBuf>,
) -> PyResult<(String, Vec<Output>, Option<String>)> {
    let Prepared { scene, label } = prepare(py, scene, volume)?;
    if scene.image.format == volcast::scene::Format::Nrrd {
        return Err(PyValueError::new_err(
            "turntable: the page shows PNG frames; this scene writes format = \"nrrd\" (use png or png16)",
        ));
    }
    let temp = match &out {
        Some(_) => None,
        None => Some(
            tempfile::Builder::new()
                .prefix("volcast-turntable")
                .tempdir()
                .map_err(|e| PyValueError::new_err(format!("a temporary folder: {e}")))?,
        ),
    };
    let folder: PathBuf = out
        .clone()
        .unwrap_or_else(|| temp.as_ref().expect("made above").path().to_path_buf());
    let opts = RunOptions {
        out: Some(folder.clone()),
        viewer: true,
        ..Default::default()
    };
    let limits = Limits::default();
    let summary = run::cancellable(py, |progress| {
        volcast::pipeline::render(&scene, &opts, &limits, progress)
    })?
    .map_err(|e| errors::run(py, &e, label))?;
    let page = summary.viewer.ok_or_else(|| {
        PyValueError::new_err(
            "turntable: the run wrote no turntable page (was every frame rendered?)",
        )
    })?;
    let plan = plan_of(py, &scene, &opts, label)?;
    let html = inline_page(&page, &folder, &plan)?;
    let arrays = images::read_back(py, &plan, &folder)?;
    Ok((html, arrays, out.map(|o| o.display().to_string())))
}

/// The page at `page` with each frame file of `plan` in `folder` inlined as a
/// `data:` URL where the page names it.
fn inline_page(page: &Path, folder: &Path, plan: &Plan) -> PyResult<String> {
    use base64::Engine as _;
    let read = |p: &Path| {
        std::fs::read(p).map_err(|e| PyValueError::new_err(format!("reading {}: {e}", p.display())))
    };
    let mut html = String::from_utf8(read(page)?)
        .map_err(|_| PyValueError::new_err("the turntable page is not UTF-8"))?;
    let eyes = images::eyes(plan);
    for p in &plan.output.passes {
        for &k in &plan.frame_list {
            for &e in &eyes {
                let path = volcast::output::frame_path(folder, &p.name, k, e, "png");
                let name = path
                    .file_name()
                    .expect("frame files have names")
                    .to_string_lossy()
                    .into_owned();
                let data = base64::engine::general_purpose::STANDARD.encode(read(&path)?);
                html = html.replace(
                    &format!("\"{name}\""),
                    &format!("\"data:image/png;base64,{data}\""),
                );
            }
        }
    }
    Ok(html)
}

/// `to_toml(dict)`: the TOML text of a scene given as a dict (what `render` reads).
#[pyfunction]
fn to_toml(scene: &Bound<'_, pyo3::types::PyDict>) -> PyResult<String> {
    match scene::input(scene.as_any())? {
        scene::Input::Text { text, .. } => Ok(text),
        scene::Input::File(_) => unreachable!("a dict is text"),
    }
}

/// The native module; `volcast` (python/volcast/__init__.py) re-exports it.
#[pymodule]
fn _volcast(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("VolcastError", py.get_type::<errors::VolcastError>())?;
    m.add("SceneError", py.get_type::<errors::SceneError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(check, m)?)?;
    m.add_function(wrap_pyfunction!(info_path, m)?)?;
    m.add_function(wrap_pyfunction!(info_array, m)?)?;
    m.add_function(wrap_pyfunction!(turntable, m)?)?;
    m.add_function(wrap_pyfunction!(to_toml, m)?)?;
    Ok(())
}
