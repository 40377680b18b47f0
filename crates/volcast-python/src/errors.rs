//! volcast's errors as Python exceptions, with the messages the command line
//! prints: `volcast.SceneError` (a scene that is malformed, or does not fit its
//! volume), `volcast.VolcastError` (its base: volumes that cannot be read, outputs
//! that cannot be written), `KeyboardInterrupt` for a cancelled run.

use std::path::{Path, PathBuf};

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use volcast::scene::SceneError as RsSceneError;

create_exception!(
    volcast,
    VolcastError,
    PyException,
    "A volcast run failed: the message is the one the command line prints."
);
create_exception!(
    volcast,
    SceneError,
    VolcastError,
    "A scene is malformed or does not fit its volume. Attributes: `file` (the scene \
     file, or `<dict>`, `<string>`), `line`, `column` and `key` of the first problem \
     (None where unknown), and `problems`, a list of dicts with the same keys and \
     `message` for each problem."
);

/// The message of an error and its sources, as anyhow's `{:#}` prints it (what
/// `volcast: ...` shows on the command line).
pub fn chain(e: &(dyn std::error::Error + 'static)) -> String {
    let mut s = e.to_string();
    let mut source = e.source();
    while let Some(inner) = source {
        s.push_str(": ");
        s.push_str(&inner.to_string());
        source = inner.source();
    }
    s
}

/// A scene error as `volcast.SceneError`; `label` replaces the path of a scene given
/// as a dict or text.
pub fn scene(py: Python<'_>, e: &RsSceneError, label: Option<&str>) -> PyErr {
    let mut e = e.clone();
    if let Some(l) = label {
        e.path = PathBuf::from(l);
    }
    let file = shown_path(&e.path, label);
    let err = SceneError::new_err(e.to_string());
    let problems = PyList::empty(py);
    let mut first: Option<(Option<usize>, Option<usize>, Option<String>)> = None;
    for d in &e.diagnostics {
        let (line, column, key) = match &d.span {
            Some(span) if !e.text.is_empty() => {
                let (l, c) = e.line_col(span.start);
                (Some(l), Some(c), key_at(&e.text, span.start))
            }
            _ => (None, None, None),
        };
        let p = PyDict::new(py);
        let _ = p.set_item("file", &file);
        let _ = p.set_item("line", line);
        let _ = p.set_item("column", column);
        let _ = p.set_item("key", key.clone());
        let _ = p.set_item("message", &d.message);
        let _ = problems.append(p);
        first.get_or_insert((line, column, key));
    }
    let (line, column, key) = first.unwrap_or((None, None, None));
    set_attrs(py, &err, &file, line, column, key, problems);
    err
}

fn set_attrs(
    py: Python<'_>,
    err: &PyErr,
    file: &str,
    line: Option<usize>,
    column: Option<usize>,
    key: Option<String>,
    problems: Bound<'_, PyList>,
) {
    let v = err.value(py);
    let _ = v.setattr("file", file);
    let _ = v.setattr("line", line);
    let _ = v.setattr("column", column);
    let _ = v.setattr("key", key);
    let _ = v.setattr("problems", problems);
}

/// Any error of a run: scene and plan errors as `SceneError`, a cancelled run as
/// `KeyboardInterrupt`, the rest as `VolcastError`.
pub fn run(py: Python<'_>, e: &volcast::Error, label: Option<&str>) -> PyErr {
    match e {
        volcast::Error::Scene(s) => scene(py, s, label),
        volcast::Error::Plan { scene, message } => {
            let file = shown_path(scene, label);
            let err = SceneError::new_err(format!("{file}: {message}"));
            let problems = PyList::empty(py);
            let p = PyDict::new(py);
            let _ = p.set_item("file", &file);
            let _ = p.set_item("line", py.None());
            let _ = p.set_item("column", py.None());
            let _ = p.set_item("key", py.None());
            let _ = p.set_item("message", message);
            let _ = problems.append(p);
            set_attrs(py, &err, &file, None, None, None, problems);
            err
        }
        volcast::Error::Cancelled => PyKeyboardInterrupt::new_err("the render was cancelled"),
        other => VolcastError::new_err(chain(other)),
    }
}

/// The key a byte offset of a scene's text belongs to: `table.key` from the last
/// table header above it and the `key =` of its line (`render[1].mode` for the
/// second `[[render]]`), or what of that is known.
pub fn key_at(text: &str, offset: usize) -> Option<String> {
    let offset = offset.min(text.len());
    let start = text[..offset].rfind('\n').map_or(0, |i| i + 1);
    let line = text[start..].lines().next().unwrap_or("");
    let key = line
        .split_once('=')
        .map(|(k, _)| k.trim())
        .filter(|k| !k.is_empty() && !k.starts_with('[') && !k.starts_with('#'))
        .map(|k| k.replace(['"', ' '], ""));
    let mut table: Option<String> = None;
    let mut counts: std::collections::HashMap<String, usize> = Default::default();
    for l in text[..start].lines() {
        let l = l.trim();
        if let Some(name) = l
            .strip_prefix("[[")
            .and_then(|r| r.split_once("]]"))
            .map(|r| r.0)
        {
            let name = name.trim().replace(['"', ' '], "");
            let n = counts.entry(name.clone()).or_insert(0);
            table = Some(format!("{name}[{n}]"));
            *n += 1;
        } else if let Some(name) = l
            .strip_prefix('[')
            .and_then(|r| r.split_once(']'))
            .map(|r| r.0)
        {
            table = Some(name.trim().replace(['"', ' '], ""));
        }
    }
    // a header line itself names its table
    if key.is_none() {
        let l = line.trim();
        if let Some(name) = l
            .strip_prefix("[[")
            .and_then(|r| r.split_once("]]"))
            .map(|r| r.0)
        {
            let name = name.trim().replace(['"', ' '], "");
            let n = counts.get(&name).copied().unwrap_or(0);
            return Some(format!("{name}[{n}]"));
        }
        if let Some(name) = l
            .strip_prefix('[')
            .and_then(|r| r.split_once(']'))
            .map(|r| r.0)
        {
            return Some(name.trim().replace(['"', ' '], ""));
        }
    }
    match (table, key) {
        (Some(t), Some(k)) => Some(format!("{t}.{k}")),
        (None, Some(k)) => Some(k),
        (Some(t), None) => Some(t),
        (None, None) => None,
    }
}

/// The file a scene error names in Python: the scene file, or `<dict>`/`<string>`.
pub fn shown_path(path: &Path, label: Option<&str>) -> String {
    label.map_or_else(|| path.display().to_string(), str::to_string)
}
