//! The `scene` argument (a dict, TOML text or a path) as a resolved [`Scene`], and
//! scene errors as `volcast.SceneError` with the file, line, column and key of
//! the first problem.

use std::path::PathBuf;

use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use volcast::scene::{Scene, SceneError};

use crate::errors;

/// Where a scene's text came from.
pub enum Input {
    /// A scene file.
    File(PathBuf),
    /// A dict (serialised to TOML) or TOML text, read as if it were the file
    /// `scene.toml` in the working directory (its relative paths resolve there;
    /// `{scene}` is `scene`); messages name it `label` (`<dict>`, `<string>`).
    Text { text: String, label: &'static str },
}

/// The keys of `[volume]` that say where the voxels come from: an array given
/// with `volume=` replaces them all.
const SOURCE_KEYS: [&str; 13] = [
    "path",
    "format",
    "index",
    "series",
    "channel",
    "sizes",
    "type",
    "endian",
    "spacing",
    "offset",
    "synthetic",
    "sigma",
    "radius",
];

/// The `[volume] path` an array stands in for while the scene is resolved (a NRRD
/// name, so that nothing else about the volume is assumed; it is never opened).
pub const ARRAY_PATH: &str = "<array>.nrrd";

/// Reads the `scene` argument: a dict, a path (`os.PathLike`, or a `str` ending in
/// `.toml` on one line), or TOML text (any other `str`).
pub fn input(scene: &Bound<'_, PyAny>) -> PyResult<Input> {
    if let Ok(d) = scene.cast::<PyDict>() {
        let table = table_of(d, "scene")?;
        let text =
            toml::to_string(&table).map_err(|e| PyValueError::new_err(format!("scene: {e}")))?;
        return Ok(Input::Text {
            text,
            label: "<dict>",
        });
    }
    if let Ok(s) = scene.cast::<PyString>() {
        let s: String = s.extract()?;
        let s = s.as_str();
        if !s.contains('\n') && s.trim_end().to_ascii_lowercase().ends_with(".toml") {
            return Ok(Input::File(PathBuf::from(s)));
        }
        return Ok(Input::Text {
            text: s.to_string(),
            label: "<string>",
        });
    }
    let os = scene.py().import("os")?;
    match os.call_method1("fspath", (scene,)) {
        Ok(p) => Ok(Input::File(PathBuf::from(p.extract::<String>()?))),
        Err(_) => Err(PyTypeError::new_err(format!(
            "scene: expected a dict, TOML text or a path, got {}",
            scene.get_type().name()?
        ))),
    }
}

/// Resolves the scene; with `array`, its `[volume]` source keys are replaced by the
/// array's stand-in path first (the caller then sets the source).
pub fn load(py: Python<'_>, input: &Input, array: bool) -> PyResult<Scene> {
    let (text, path, label) = match input {
        Input::File(p) => {
            if !array {
                return volcast::scene::load(p).map_err(|e| errors::scene(py, &e, None));
            }
            let text = std::fs::read_to_string(p).map_err(|e| {
                errors::scene(
                    py,
                    &SceneError::whole_file(p, format!("cannot read the scene file: {e}")),
                    None,
                )
            })?;
            (text, p.clone(), None)
        }
        Input::Text { text, label } => {
            let cwd = std::env::current_dir()
                .map_err(|e| PyValueError::new_err(format!("the working directory: {e}")))?;
            // named `scene` (`{scene}` in `out`); messages name it by its label
            (text.clone(), cwd.join("scene.toml"), Some(*label))
        }
    };
    let text = if array {
        with_array_source(&text).map_err(|e| {
            let err = SceneError {
                path: path.clone(),
                text: text.clone(),
                diagnostics: vec![volcast::scene::Diagnostic {
                    span: e.span(),
                    message: e.message().to_string(),
                }],
            };
            errors::scene(py, &err, label)
        })?
    } else {
        text
    };
    volcast::scene::parse(&text, &path).map_err(|e| errors::scene(py, &e, label))
}

/// The scene text with `[volume]`'s source keys replaced by [`ARRAY_PATH`].
fn with_array_source(text: &str) -> Result<String, toml::de::Error> {
    let mut table: toml::Table = toml::from_str(text)?;
    let volume = table
        .entry("volume")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    if let toml::Value::Table(v) = volume {
        for k in SOURCE_KEYS {
            v.remove(k);
        }
        v.insert("path".into(), toml::Value::String(ARRAY_PATH.into()));
    }
    Ok(toml::to_string(&table).expect("a parsed table serialises"))
}

/// A Python dict as a TOML table (`what` names it in messages).
fn table_of(d: &Bound<'_, PyDict>, what: &str) -> PyResult<toml::Table> {
    let mut t = toml::Table::new();
    for (k, v) in d.iter() {
        let key: String = k.extract().map_err(|_| {
            PyTypeError::new_err(format!(
                "{what}: keys are strings, not {}",
                k.repr().map(|r| r.to_string()).unwrap_or_default()
            ))
        })?;
        let inner = format!("{what}.{key}");
        if v.is_none() {
            continue;
        }
        t.insert(key, value_of(&v, &inner)?);
    }
    Ok(t)
}

/// A Python value as a TOML value: bool, int, float, str, list or tuple, dict
/// (and NumPy scalars and arrays, through `.tolist()`).
fn value_of(v: &Bound<'_, PyAny>, what: &str) -> PyResult<toml::Value> {
    if v.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(v.extract()?));
    }
    if v.is_instance_of::<PyInt>() {
        let i: i64 = v
            .extract()
            .map_err(|_| PyValueError::new_err(format!("{what}: {v} does not fit in 64 bits")))?;
        return Ok(toml::Value::Integer(i));
    }
    if v.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(v.extract()?));
    }
    if let Ok(s) = v.cast::<PyString>() {
        return Ok(toml::Value::String(s.extract()?));
    }
    if let Ok(d) = v.cast::<PyDict>() {
        return Ok(toml::Value::Table(table_of(d, what)?));
    }
    if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut out = Vec::new();
        for (i, x) in v.try_iter()?.enumerate() {
            out.push(value_of(&x?, &format!("{what}[{i}]"))?);
        }
        return Ok(toml::Value::Array(out));
    }
    if v.hasattr("tolist")? {
        return value_of(&v.call_method0("tolist")?, what);
    }
    if let Ok(p) = v.py().import("os")?.call_method1("fspath", (v,)) {
        return value_of(&p, what);
    }
    Err(PyTypeError::new_err(format!(
        "{what}: {} is not a TOML value (bool, int, float, str, list, dict)",
        v.get_type().name()?
    )))
}
