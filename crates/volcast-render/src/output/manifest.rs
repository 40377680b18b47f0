//! The output folder's manifest: what was rendered, from what, and how, so that a
//! folder of images can be reproduced (and resumed) from itself.
//!
//! - `manifest.d/{pass}_{frame:04}.json`: one record per (pass, frame), written
//!   atomically right after that frame's images. It holds the scene hash, the
//!   files (size and SHA-256), each eye's view parameters, the grey window, the
//!   samples and the seconds. Records are the source of truth: concurrent shards
//!   write disjoint records and never a shared file, so none can clobber another's.
//! - `manifest.json`: the merge of the records that belong to the current scene,
//!   with the scene file's text, the resolved scene, the volume's description, and
//!   whether the sequence is complete. Every run rewrites it at its end; a run
//!   re-reads the records after writing it and merges again if another shard added
//!   records meanwhile, so the last shard to finish leaves the full manifest.
//!
//! The scene hash ([`scene_digest`] then [`data_digest`]) is a SHA-256 over a
//! canonical encoding of the scene as parsed (comments, spacing and key order do
//! not matter; `[image] out`, `[animation]` and `[viewer]` are left out because
//! they do not change any image), the volume's header, the image size, the program version and
//! the voxel data's XXH3-128 (computed while the data is decoded; a run with nothing
//! left to render may take it from `manifest.json` when the volume's files have the
//! size and modification time recorded there). `--resume` skips a (pass, frame) only
//! when its record has this hash and every file it lists exists with the recorded
//! size and SHA-256. `manifest.json` also records each animation's size and SHA-256
//! and the frames it was made from, so a damaged or stale animation is rebuilt.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use super::write::{Folder, Kind};
use crate::error::Error;
use crate::render::View;
use crate::scene::{
    AnaglyphColors, Layout, LightKindSpec, Projection, Scene, Separation, StereoMethod,
};
use crate::views::ViewKey;
use crate::volume::{FileStamp, VolumeHeader, VolumeIdentity};
use sha2::{Digest, Sha256};

/// File name of the merged manifest.
pub const MANIFEST: &str = "manifest.json";
/// Folder of the per-(pass, frame) records.
pub const RECORDS: &str = "manifest.d";
/// Identifies the manifest's layout. Version 2 adds the voxel data to the scene
/// hash, the volume's identity and the animations' hashes; the records of a
/// version 1 manifest never match a version 2 scene hash, so their images are
/// rendered again (and the run says so).
pub const MANIFEST_FORMAT: &str = "volcast-manifest-2";

/// One written file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FileRecord {
    /// File name in the output folder.
    pub name: String,
    /// Size in bytes.
    pub bytes: u64,
    /// SHA-256 of the file's bytes (hex).
    pub sha256: String,
}

/// The parameters of one eye's view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViewRecord {
    /// `mono`, `left` or `right`.
    pub eye: String,
    /// The distinct view shown: orbit position (frames) and eye there (a reused
    /// toe-in left eye names the right eye of an earlier position).
    pub view: (i64, String),
    /// Camera azimuth plus orbit and toe-in offsets, degrees.
    pub azimuth_deg: f64,
    /// Camera elevation, degrees.
    pub elevation_deg: f64,
    /// `perspective` or `orthographic`.
    pub projection: String,
    /// Eye position (orthographic: centre of the plane the rays start from).
    pub eye_position: [f64; 3],
    /// Unit viewing direction.
    pub forward: [f64; 3],
    /// Unit image right.
    pub right: [f64; 3],
    /// Unit image up.
    pub up: [f64; 3],
    /// Half the image width (perspective: as a tangent; orthographic: world units).
    pub half_width: f64,
    /// Half the image height, likewise.
    pub half_height: f64,
    /// Horizontal offset of the image window (off-axis stereo), units of `half_width`.
    pub window_shift: f64,
    /// Distance from the eye to the target along `forward`.
    pub target_distance: f64,
    /// Field samples taken to render this view.
    pub samples: u64,
}

impl ViewRecord {
    /// The record of `view`, shown to `eye` as the distinct view `key`.
    pub fn new(
        eye: super::Eye,
        key: ViewKey,
        azimuth_deg: f64,
        elevation_deg: f64,
        view: &View,
        samples: u64,
    ) -> ViewRecord {
        ViewRecord {
            eye: eye_name(eye).into(),
            view: (key.position, eye_name(key.eye).into()),
            azimuth_deg,
            elevation_deg,
            projection: match view.projection {
                Projection::Perspective => "perspective",
                Projection::Orthographic => "orthographic",
            }
            .into(),
            eye_position: view.eye.to_array(),
            forward: view.forward.to_array(),
            right: view.right.to_array(),
            up: view.up.to_array(),
            half_width: view.half_width,
            half_height: view.half_height,
            window_shift: view.shift,
            target_distance: view.distance,
            samples,
        }
    }
}

/// What was written for one (pass, frame).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// [`scene_digest`] of the scene the images belong to.
    pub scene_hash: String,
    /// The program version that wrote them.
    pub volcast_version: String,
    /// Pass name.
    pub pass: String,
    /// Frame number.
    pub frame: usize,
    /// The files, in eye order.
    pub files: Vec<FileRecord>,
    /// The views, in eye order.
    pub views: Vec<ViewRecord>,
    /// Grey window `[lo, hi]` of intensity passes written as PNG.
    pub window: Option<[f64; 2]>,
    /// Field samples of this frame's views (a view shared with another frame is
    /// counted in both).
    pub samples: u64,
    /// Seconds spent rendering this frame's views (a shared view counts where it
    /// was rendered) and writing its files.
    pub seconds: f64,
    /// `K/N` when written by a shard.
    pub shard: Option<String>,
}

fn eye_name(eye: super::Eye) -> &'static str {
    match eye {
        super::Eye::Mono => "mono",
        super::Eye::Left => "left",
        super::Eye::Right => "right",
    }
}

/// Where the record of (`pass`, `frame`) lives.
pub fn record_path(out: &Path, pass: &str, frame: usize) -> PathBuf {
    out.join(RECORDS).join(format!("{pass}_{frame:04}.json"))
}

/// Largest record or manifest volcast reads back (a planted giant is an error, not
/// an allocation).
const MAX_JSON: u64 = 64 << 20;

/// The output folder `out` (followed as given).
pub(crate) fn out_folder(out: &Path) -> Result<Folder, Error> {
    Folder::open(out).map_err(|source| Error::Output {
        path: out.to_path_buf(),
        source,
    })
}

/// The records folder of `out`, created if missing (never through a link).
pub(crate) fn records_folder(out: &Path) -> Result<Folder, Error> {
    out_folder(out)?
        .subfolder(RECORDS)
        .map_err(|source| Error::Output {
            path: out.join(RECORDS),
            source,
        })
}

/// The records folder of `out` if it exists (never through a link).
fn existing_records(out: &Path) -> Result<Option<Folder>, Error> {
    let folder = match Folder::open(out) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => {
            return Err(Error::Output {
                path: out.to_path_buf(),
                source,
            })
        }
    };
    match folder.open_subfolder(RECORDS) {
        Ok(f) => Ok(Some(f)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(source) => Err(Error::Output {
            path: out.join(RECORDS),
            source,
        }),
    }
}

/// The (pass, frame) of every file in `out`'s records folder named as a record
/// is named ([`record_name`]), by pass: which records there are to read.
fn record_frames(out: &Path) -> Result<HashMap<String, BTreeSet<usize>>, Error> {
    let mut found: HashMap<String, BTreeSet<usize>> = HashMap::new();
    if existing_records(out)?.is_none() {
        return Ok(found);
    }
    let dir = out.join(RECORDS);
    let entries = std::fs::read_dir(&dir).map_err(|source| Error::Read {
        path: dir.clone(),
        source,
    })?;
    for e in entries {
        let e = e.map_err(|source| Error::Read {
            path: dir.clone(),
            source,
        })?;
        let name = e.file_name();
        let Some(name) = name.to_str() else { continue };
        let parsed = name
            .strip_suffix(".json")
            .and_then(|s| s.rsplit_once('_'))
            .and_then(|(pass, k)| Some((pass, k.parse::<usize>().ok()?)));
        if let Some((pass, k)) = parsed.filter(|&(p, k)| record_name(p, k) == name) {
            found.entry(pass.to_string()).or_default().insert(k);
        }
    }
    Ok(found)
}

/// The file name of the record of (`pass`, `frame`).
fn record_name(pass: &str, frame: usize) -> String {
    format!("{pass}_{frame:04}.json")
}

/// Writes a record atomically into `out`'s records folder (created if missing).
pub fn write_record(out: &Path, record: &FrameRecord) -> Result<(), Error> {
    let path = record_path(out, &record.pass, record.frame);
    let text = serde_json::to_vec_pretty(record).map_err(|e| Error::Manifest {
        path: path.clone(),
        message: e.to_string(),
    })?;
    records_folder(out)?
        .write_atomic(&record_name(&record.pass, record.frame), &text)
        .map_err(|source| Error::Output { path, source })
}

/// Reads the record of (`pass`, `frame`): `None` if there is none. A file that is
/// not a record (or a link, or not a regular file) is an error that says what was
/// expected.
pub fn read_record(out: &Path, pass: &str, frame: usize) -> Result<Option<FrameRecord>, Error> {
    let path = record_path(out, pass, frame);
    let Some(folder) = existing_records(out)? else {
        return Ok(None);
    };
    let bytes = match folder.read_regular(&record_name(pass, frame), MAX_JSON) {
        Ok(Some(b)) => b,
        Ok(None) => return Ok(None),
        Err(source) => return Err(Error::Read { path, source }),
    };
    match serde_json::from_slice::<FrameRecord>(&bytes) {
        Ok(r) if r.pass == pass && r.frame == frame => Ok(Some(r)),
        Ok(r) => Err(Error::Manifest {
            path,
            message: format!(
                "the record is for pass `{}` frame {}, not pass `{pass}` frame {frame} as its name says",
                r.pass, r.frame
            ),
        }),
        Err(e) => Err(Error::Manifest {
            path,
            message: format!(
                "not a volcast frame record (expected a JSON object with scene_hash, volcast_version, pass, frame, files, views, window, samples, seconds, shard): {e}"
            ),
        }),
    }
}

/// Whether `record` shows a complete (pass, frame) of the scene hashed `digest`:
/// the same hash, exactly the files `names` (the names the plan gives that pass
/// and frame, so a record cannot point outside the folder or at another frame's
/// file), and every one present (a regular file, not a link) with its recorded size
/// and SHA-256.
pub fn is_complete(out: &Path, record: &FrameRecord, digest: &str, names: &[String]) -> bool {
    if record.scene_hash != digest || !names_match(record, names) {
        return false;
    }
    let Ok(folder) = Folder::open(out) else {
        return false;
    };
    !record.files.is_empty()
        && record
            .files
            .iter()
            .all(|f| file_matches(&folder, &f.name, f.bytes, &f.sha256))
}

/// Whether `record` lists exactly the files `names`, in order.
fn names_match(record: &FrameRecord, names: &[String]) -> bool {
    record.files.len() == names.len() && record.files.iter().zip(names).all(|(f, n)| f.name == *n)
}

/// The error that says a record of the scene hashed `digest` names files other
/// than `names` (the plan's for its pass and frame), if it does: such a record is
/// damaged, or was planted to make volcast read a file outside the folder.
pub fn foreign_files(
    out: &Path,
    record: &FrameRecord,
    digest: &str,
    names: &[String],
) -> Option<Error> {
    (record.scene_hash == digest && !names_match(record, names)).then(|| Error::Manifest {
        path: record_path(out, &record.pass, record.frame),
        message: format!(
            "the record names the files {}, not {} as this scene writes them: it is treated as damaged",
            quoted(record.files.iter().map(|f| f.name.as_str())),
            quoted(names.iter().map(String::as_str)),
        ),
    })
}

/// File names as messages list them: quoted, control characters escaped.
fn quoted<'a>(names: impl Iterator<Item = &'a str>) -> String {
    names
        .map(|n| format!("{n:?}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Whether `name` in `folder` is a regular file of `bytes` bytes whose SHA-256 is
/// `sha256` (hex). The size is compared first, so a file of another size is not read;
/// a file this process wrote or hashed, unchanged since, is not read again ([`known`]).
pub(crate) fn file_matches(folder: &Folder, name: &str, bytes: u64, sha256: &str) -> bool {
    let Ok(mut file) = folder.open_regular(name) else {
        return false;
    };
    let Ok(before) = file.metadata() else {
        return false;
    };
    if before.len() != bytes {
        return false;
    }
    if let Some(known) = known::sha256(&before) {
        return known == sha256;
    }
    let Ok((n, h)) = hash_open(&mut file) else {
        return false;
    };
    if file
        .metadata()
        .is_ok_and(|after| known::same(&before, &after))
    {
        known::remember(&before, &h);
    }
    n == bytes && h == sha256
}

/// SHA-256 (hex) and size of the regular file `name` in `folder`.
pub(crate) fn hash_file(folder: &Folder, name: &str) -> std::io::Result<(u64, String)> {
    hash_open(&mut folder.open_regular(name)?)
}

/// SHA-256 (hex) and size of an open file, read from its current position.
fn hash_open(file: &mut std::fs::File) -> std::io::Result<(u64, String)> {
    use std::io::Read as _;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    let mut total = 0u64;
    loop {
        match file.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => {
                h.update(&buf[..n]);
                total += n as u64;
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok((total, hex(&h.finalize())))
}

/// The SHA-256 of files this process wrote, or read whole, for as long as they stay
/// as they were then: a file is known by its device and inode, size, and
/// modification and status-change times (the times in nanoseconds; a rename, a
/// write or a `chmod` changes one of them). This is the trust git's index and make
/// place in a file's metadata; it spares the end of a run reading back and hashing
/// again every image it has just written and hashed. Unix only: elsewhere every
/// file is read.
mod known {
    use std::collections::BTreeMap;
    use std::fs::Metadata;
    use std::sync::{Mutex, PoisonError};

    /// Device, inode, size, modification time and status-change time (s, ns).
    type Stamp = (u64, u64, u64, i64, i64, i64, i64);

    static KNOWN: Mutex<BTreeMap<Stamp, String>> = Mutex::new(BTreeMap::new());

    #[cfg(unix)]
    fn stamp(m: &Metadata) -> Option<Stamp> {
        use std::os::unix::fs::MetadataExt;
        Some((
            m.dev(),
            m.ino(),
            m.len(),
            m.mtime(),
            m.mtime_nsec(),
            m.ctime(),
            m.ctime_nsec(),
        ))
    }

    #[cfg(not(unix))]
    fn stamp(_: &Metadata) -> Option<Stamp> {
        None
    }

    /// Whether two reads of a file's metadata show it unchanged.
    pub(super) fn same(a: &Metadata, b: &Metadata) -> bool {
        stamp(a).is_some() && stamp(a) == stamp(b)
    }

    /// Files remembered at most: a cache, emptied when full (a run of more frames
    /// than this reads back the images of its earlier ones), so a long-lived process
    /// does not grow with every file it writes.
    const CAPACITY: usize = 1 << 16;

    /// Records that the file `m` describes has SHA-256 `sha256`.
    pub(super) fn remember(m: &Metadata, sha256: &str) {
        if let Some(s) = stamp(m) {
            let mut known = KNOWN.lock().unwrap_or_else(PoisonError::into_inner);
            if known.len() >= CAPACITY {
                known.clear();
            }
            known.insert(s, sha256.to_owned());
        }
    }

    /// The SHA-256 recorded for the file `m` describes, if it is unchanged since.
    pub(super) fn sha256(m: &Metadata) -> Option<String> {
        let s = stamp(m)?;
        let known = KNOWN.lock().unwrap_or_else(PoisonError::into_inner);
        known.get(&s).cloned()
    }
}

/// Writes `bytes` to `path` atomically (see [`super::write::write_atomic`]) and
/// returns the file's record (its SHA-256 from `bytes`), remembering the hash so
/// that the manifest at the end of the run does not read the file back.
pub fn write_recorded(path: &Path, bytes: &[u8]) -> std::io::Result<FileRecord> {
    let meta = super::write::write_atomic_stat(path, bytes)?;
    let record = file_record(path, bytes);
    if let Some(meta) = meta {
        known::remember(&meta, &record.sha256);
    }
    Ok(record)
}

/// SHA-256 (hex) of a list of strings, each length-prefixed (the identity of the
/// frames an animation is made of).
pub fn digest_of_list<'a>(items: impl IntoIterator<Item = &'a str>) -> String {
    let mut h = Sha256::new();
    for s in items {
        put_str(&mut h, s);
    }
    hex(&h.finalize())
}

/// SHA-256 of a file's bytes, with its size.
pub fn file_record(path: &Path, bytes: &[u8]) -> FileRecord {
    let mut h = Sha256::new();
    h.update(bytes);
    FileRecord {
        name: path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        bytes: bytes.len() as u64,
        sha256: hex(&h.finalize()),
    }
}

/// The identity of a scene's images: see the module documentation.
pub fn scene_digest(
    scene: &Scene,
    headers: &[VolumeHeader],
    width: usize,
    height: usize,
) -> String {
    let mut h = Sha256::new();
    h.update(b"volcast scene digest 2\0");
    put_str(&mut h, env!("CARGO_PKG_VERSION"));
    match scene.text.parse::<toml::Table>() {
        Ok(mut table) => {
            if let Some(toml::Value::Table(image)) = table.get_mut("image") {
                image.remove("out");
            }
            table.remove("animation");
            table.remove("viewer");
            h.update(b"T");
            put_toml(&mut h, &toml::Value::Table(table));
        }
        // (Only reachable for a scene built without its text.)
        Err(_) => {
            h.update(b"R");
            put_str(&mut h, &scene.text);
        }
    }
    // each volume's header, as placed (a scene of one volume hashes as before)
    for header in headers {
        put_str(&mut h, &header.source);
        for n in header.sizes {
            h.update((n as u64).to_le_bytes());
        }
        put_str(&mut h, header.scalar_type.nrrd_name());
        for v in std::iter::once(header.geometry.origin).chain(header.geometry.axes) {
            for x in v.to_array() {
                h.update(x.to_bits().to_le_bytes());
            }
        }
        h.update((header.fields.len() as u64).to_le_bytes());
        for (k, v) in &header.fields {
            put_str(&mut h, k);
            put_str(&mut h, v);
        }
    }
    h.update((width as u64).to_le_bytes());
    h.update((height as u64).to_le_bytes());
    hex(&h.finalize())
}

/// The scene hash recorded with every image: [`scene_digest`] combined with the
/// voxel data's hash (`None` for synthetic fields, which the scene defines).
pub fn data_digest(scene_digest: &str, data_xxh3: Option<&str>) -> String {
    let mut h = Sha256::new();
    h.update(b"volcast data digest 1\0");
    put_str(&mut h, scene_digest);
    match data_xxh3 {
        Some(d) => {
            h.update(b"D");
            put_str(&mut h, d);
        }
        None => h.update(b"S"),
    }
    hex(&h.finalize())
}

fn put_str(h: &mut Sha256, s: &str) {
    h.update((s.len() as u64).to_le_bytes());
    h.update(s.as_bytes());
}

/// A canonical, type-tagged encoding of a TOML value (tables in key order; floats
/// by their bits, so `1.0` and `1` differ, which at worst re-renders).
fn put_toml(h: &mut Sha256, v: &toml::Value) {
    match v {
        toml::Value::String(s) => {
            h.update(b"s");
            put_str(h, s);
        }
        toml::Value::Integer(i) => {
            h.update(b"i");
            h.update(i.to_le_bytes());
        }
        toml::Value::Float(f) => {
            h.update(b"f");
            h.update(f.to_bits().to_le_bytes());
        }
        toml::Value::Boolean(b) => h.update(if *b { b"bT" } else { b"bF" }),
        toml::Value::Datetime(d) => {
            h.update(b"d");
            put_str(h, &d.to_string());
        }
        toml::Value::Array(a) => {
            h.update(b"a");
            h.update((a.len() as u64).to_le_bytes());
            for x in a {
                put_toml(h, x);
            }
        }
        toml::Value::Table(t) => {
            h.update(b"t");
            h.update((t.len() as u64).to_le_bytes());
            let sorted: BTreeMap<&String, &toml::Value> = t.iter().collect();
            for (k, x) in sorted {
                put_str(h, k);
                put_toml(h, x);
            }
        }
    }
}

/// The resolved scene as JSON (the values the renderer used, defaults filled in).
pub fn resolved_scene(scene: &Scene) -> Value {
    let c = &scene.camera;
    let stereo = scene.stereo.map(|s| {
        let (method, separation) = match s.method {
            StereoMethod::ToeIn => ("toe-in", Value::Null),
            StereoMethod::Parallel(Separation::World(w)) => {
                ("parallel", json!({ "world_units": w }))
            }
            StereoMethod::Parallel(Separation::Fraction(f)) => {
                ("parallel", json!({ "fraction_of_distance": f }))
            }
        };
        json!({
            "method": method,
            "angle_deg": s.angle_deg,
            "separation": separation,
            "layout": match s.layout {
                Layout::Pair => "pair",
                Layout::SideBySide => "side-by-side",
                Layout::CrossEyed => "cross-eyed",
                Layout::Anaglyph => "anaglyph",
            },
            "anaglyph": match s.anaglyph {
                crate::scene::Anaglyph::RedCyan => "red-cyan",
                crate::scene::Anaglyph::RedGreen => "red-green",
            },
            "anaglyph_colors": match s.anaglyph_colors {
                AnaglyphColors::Color => "color",
                AnaglyphColors::HalfColor => "half-color",
                AnaglyphColors::Gray => "gray",
            },
            "gap": s.gap,
        })
    });
    let passes: Vec<Value> = scene
        .passes
        .iter()
        .map(|p| {
            let mut o = json!({
                "name": p.name,
                "mode": p.mode.name(),
                "step_voxels": p.step_voxels,
                "interpolation": p.interpolation.name(),
                "window": p.window,
                "volumes": p.volumes.iter().map(|&k| scene.volumes[k].name.clone()).collect::<Vec<_>>(),
            });
            let extra = Value::Object(p.mode.manifest());
            if let (Value::Object(o), Value::Object(e)) = (&mut o, extra) {
                o.extend(e);
                if let Some(sh) = p.mode.shading() {
                    o.insert(
                        "shading".into(),
                        json!({
                            "model": format!("{:?}", sh.model).to_lowercase(),
                            "material": sh.material_name,
                            "gradient": sh.gradient.name(),
                        }),
                    );
                }
            }
            o
        })
        .collect();
    let light = match scene.light.kind {
        LightKindSpec::Headlight => json!({ "kind": "headlight" }),
        LightKindSpec::Directional(d) => {
            json!({ "kind": "directional", "direction": d.to_array() })
        }
        LightKindSpec::Point(p) => json!({ "kind": "point", "position": p.to_array() }),
    };
    json!({
        "volume": { "window": scene.volume().window },
        "volumes": scene.volumes.iter().map(|v| json!({
            "name": v.name,
            "window": v.spec.window,
            "transform": v.transform.map(|t| {
                let (m, x) = (t.matrix, t.translation);
                [
                    [m.x_axis.x, m.y_axis.x, m.z_axis.x, x.x],
                    [m.x_axis.y, m.y_axis.y, m.z_axis.y, x.y],
                    [m.x_axis.z, m.y_axis.z, m.z_axis.z, x.z],
                    [0.0, 0.0, 0.0, 1.0],
                ]
            }),
        })).collect::<Vec<_>>(),
        "camera": {
            "projection": match c.projection {
                Projection::Perspective => "perspective",
                Projection::Orthographic => "orthographic",
            },
            "fov_deg": c.fov_deg,
            "azimuth_deg": c.azimuth_deg,
            "elevation_deg": c.elevation_deg,
            "up": c.up.to_array(),
            "zoom": c.zoom,
            "distance": c.distance,
            "target": c.target.map(|t| t.to_array()),
        },
        "orbit": {
            "frames": scene.orbit.frames,
            "degrees": scene.orbit.degrees,
            "path": scene.orbit.path.name(),
        },
        "stereo": stereo,
        "image": {
            "size": [scene.image.width, scene.image.height],
            "background": scene.image.background,
            "format": format!("{:?}", scene.image.format).to_lowercase(),
        },
        "passes": passes,
        "clips": scene.clips.iter().map(|c| json!({
            "name": c.name,
            "point": c.point.to_array(),
            "normal": c.normal.to_array(),
            "offset": c.offset,
            "cap": c.cap,
            "passes": c.passes,
        })).collect::<Vec<_>>(),
        "light": {
            "kind": light,
            "color": scene.light.color.to_array(),
            "intensity": scene.light.intensity,
        },
        "animation": scene.animation.as_ref().map(|a| json!({
            "formats": a.formats.iter().map(|f| f.extension()).collect::<Vec<_>>(),
            "fps": a.fps,
            "loop": a.looping,
        })),
    })
}

/// The volume's description, with the identity of its data.
pub fn volume_json(header: &VolumeHeader, identity: &VolumeIdentity) -> Value {
    json!({
        "source": header.source,
        "sizes": header.sizes,
        "type": header.scalar_type.nrrd_name(),
        "spacing": header.geometry.spacings(),
        "origin": header.geometry.origin.to_array(),
        "axes": header.geometry.axes.map(|a| a.to_array()),
        "fields": header.fields.iter().map(|(k, v)| json!([k, v])).collect::<Vec<_>>(),
        "data": {
            "xxh3_128": identity.data_xxh3,
            "files": identity.files,
        },
    })
}

/// The format of a manifest read back (`None` when it names none).
pub fn manifest_format(manifest: &Value) -> Option<&str> {
    manifest.get("format").and_then(Value::as_str)
}

/// The volume identity a current-format manifest recorded, if any.
pub fn recorded_identity(manifest: &Value) -> Option<VolumeIdentity> {
    if manifest_format(manifest) != Some(MANIFEST_FORMAT) {
        return None;
    }
    let data = manifest.get("volume")?.get("data")?;
    let data_xxh3 = match data.get("xxh3_128")? {
        Value::Null => None,
        Value::String(s) => Some(s.clone()),
        _ => return None,
    };
    let files: Vec<FileStamp> = serde_json::from_value(data.get("files")?.clone()).ok()?;
    Some(VolumeIdentity { data_xxh3, files })
}

/// What the merged manifest found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ManifestStatus {
    /// Where it was written.
    pub path: PathBuf,
    /// (pass, frame) images of the orbit with a valid record.
    pub done: usize,
    /// (pass, frame) images of the orbit in all.
    pub total: usize,
    /// Records that could not be read (named, with the reason).
    pub unreadable: Vec<String>,
    /// The (pass, frame) images of the orbit that are missing (or damaged, or of
    /// another scene), in pass and frame order.
    pub missing: Vec<(String, usize)>,
    /// The shard counts `N` named by the records present (`K/N`), in order.
    pub shard_counts: Vec<usize>,
}

impl ManifestStatus {
    /// Whether every (pass, frame) of the orbit is present.
    pub fn complete(&self) -> bool {
        self.done == self.total
    }
}

/// What the manifest records of the scene, fixed when it is planned: its file, its
/// text, its resolved form and its [`scene_digest`].
#[derive(Clone, Debug)]
pub struct SceneRecord {
    /// The scene file.
    pub file: PathBuf,
    /// The scene file's text as read.
    pub text: String,
    /// [`resolved_scene`].
    pub resolved: Value,
    /// [`scene_digest`] for the volume and image size planned.
    pub digest: String,
}

impl SceneRecord {
    /// The record of `scene` rendered from volumes described by `headers` (in the
    /// order of its volumes, as placed) at `width` x `height`.
    pub fn new(
        scene: &Scene,
        headers: &[VolumeHeader],
        width: usize,
        height: usize,
    ) -> SceneRecord {
        SceneRecord {
            file: scene.path.clone(),
            text: scene.text.clone(),
            resolved: resolved_scene(scene),
            digest: scene_digest(scene, headers, width, height),
        }
    }
}

/// Everything the merged manifest says besides the records.
pub struct ManifestHead<'a> {
    /// The scene.
    pub scene: &'a SceneRecord,
    /// The run's outputs: the passes and frames whose records are merged.
    pub outputs: &'a super::Outputs,
    /// Its volumes' names and headers (as placed), in the scene's order.
    pub headers: Vec<(&'a str, &'a VolumeHeader)>,
    /// Its voxel data's identity.
    pub identity: &'a VolumeIdentity,
    /// [`data_digest`].
    pub digest: &'a str,
    /// Image size of one view.
    pub size: (usize, usize),
}

/// Extra top-level entries of the manifest (animations, ffmpeg commands), made from
/// the records merged and how complete they are (it may assemble the animations).
pub type Extra<'a> = dyn FnMut(&ManifestStatus, &[FrameRecord]) -> Result<Value, Error> + 'a;

/// Merges the records of the current scene into `manifest.json` (see the module
/// documentation), with the entries `extra` makes, and reports how complete the
/// sequence is. The file is written whole each time: a reader never sees a
/// manifest without its animation entries.
pub fn write_manifest(
    out: &Path,
    head: &ManifestHead,
    extra: &mut Extra,
) -> Result<ManifestStatus, Error> {
    let path = out.join(MANIFEST);
    let mut previous: Option<Vec<(String, usize)>> = None;
    // Merge until the set of records did not change while writing (at most a few
    // rounds, even with many shards finishing at once).
    for _ in 0..8 {
        let (records, status) = collect(out, head)?;
        let keys: Vec<(String, usize)> =
            records.iter().map(|r| (r.pass.clone(), r.frame)).collect();
        if previous.as_ref() == Some(&keys) {
            return Ok(status);
        }
        let scene = head.scene;
        let mut windows = serde_json::Map::new();
        for r in &records {
            windows
                .entry(r.pass.clone())
                .or_insert_with(|| json!(r.window));
        }
        let seconds: f64 = records.iter().map(|r| r.seconds).sum();
        let samples: u64 = records.iter().map(|r| r.samples).sum();
        let mut doc = json!({
            "format": MANIFEST_FORMAT,
            "volcast_version": env!("CARGO_PKG_VERSION"),
            "scene_hash": head.digest,
            "complete": status.complete(),
            "images_done": status.done,
            "images_total": status.total,
            "scene": {
                "file": scene.file,
                "text": scene.text,
                "resolved": scene.resolved,
            },
            "render_size": [head.size.0, head.size.1],
            "volume": volume_json(head.headers[0].1, head.identity),
            "windows": windows,
            "totals": { "seconds": seconds, "samples": samples },
            "frames": records,
        });
        if let (Value::Object(d), [_, _, ..]) = (&mut doc, head.headers.as_slice()) {
            // every volume of a scene of several (the data's identity is of all)
            let volumes = head.headers.iter().map(|(name, h)| {
                let mut v = volume_json(
                    h,
                    &VolumeIdentity {
                        data_xxh3: None,
                        files: Vec::new(),
                    },
                );
                if let Value::Object(m) = &mut v {
                    m.remove("data");
                    m.insert("name".into(), json!(name));
                }
                v
            });
            d.insert("volumes".into(), Value::Array(volumes.collect()));
        }
        if let (Value::Object(d), Value::Object(e)) = (&mut doc, extra(&status, &records)?) {
            d.extend(e);
        }
        let mut text = serde_json::to_vec_pretty(&doc).map_err(|e| Error::Manifest {
            path: path.clone(),
            message: e.to_string(),
        })?;
        text.push(b'\n');
        write_manifest_file(out, &text)?;
        previous = Some(keys);
    }
    Ok(collect(out, head)?.1)
}

/// Writes `manifest.json` atomically; a link there is an error, not replaced.
fn write_manifest_file(out: &Path, text: &[u8]) -> Result<(), Error> {
    write_unlinked(&out_folder(out)?, out, MANIFEST, text)
}

/// Writes `name` into `folder` (the output folder `out`) atomically; a link there
/// is an error, not replaced.
pub(crate) fn write_unlinked(
    folder: &Folder,
    out: &Path,
    name: &str,
    bytes: &[u8],
) -> Result<(), Error> {
    let path = out.join(name);
    if folder.kind_of(name) == Some(Kind::Link) {
        return Err(Error::Output {
            path: path.clone(),
            source: std::io::Error::other(format!(
                "{} is a symbolic link: volcast does not follow links inside its output folder (someone else may have planted it); remove it, or use another output folder",
                path.display()
            )),
        });
    }
    folder
        .write_atomic(name, bytes)
        .map_err(|source| Error::Output { path, source })
}

/// Reads `manifest.json` of `out` as JSON: `None` when there is none or it is not
/// JSON; a link or a special file there is an error.
pub fn read_manifest(out: &Path) -> Result<Option<Value>, Error> {
    let path = out.join(MANIFEST);
    let folder = match Folder::open(out) {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => return Err(Error::Output { path, source }),
    };
    match folder.read_regular(MANIFEST, MAX_JSON) {
        Ok(Some(bytes)) => Ok(serde_json::from_slice(&bytes).ok()),
        Ok(None) => Ok(None),
        Err(source) => Err(Error::Read { path, source }),
    }
}

/// The valid records of the current scene, in (pass, frame) order.
fn collect(out: &Path, head: &ManifestHead) -> Result<(Vec<FrameRecord>, ManifestStatus), Error> {
    let outputs = head.outputs;
    let mut status = ManifestStatus {
        path: out.join(MANIFEST),
        total: outputs.passes.len() * outputs.frames,
        ..Default::default()
    };
    // only the records that exist are read: a long orbit with few frames rendered
    // costs one listing, not a file lookup per frame
    let present = record_frames(out)?;
    let keys: Vec<(&str, usize)> = outputs
        .passes
        .iter()
        .flat_map(|p| {
            let frames = present.get(p.name.as_str());
            frames
                .into_iter()
                .flatten()
                .filter(|&&k| k < outputs.frames)
                .map(move |&k| (p.name.as_str(), k))
        })
        .collect();
    // every file of every record is checked (hashed, unless `known` has it): in parallel
    let found: Vec<Result<Option<FrameRecord>, Error>> = {
        use rayon::prelude::*;
        keys.par_iter()
            .map(|&(pass, k)| {
                let names = outputs.file_names(pass, k);
                let Some(r) = read_record(out, pass, k)? else {
                    return Ok(None);
                };
                if let Some(e) = foreign_files(out, &r, head.digest, &names) {
                    return Err(e);
                }
                Ok(is_complete(out, &r, head.digest, &names).then_some(r))
            })
            .collect()
    };
    let mut records = Vec::new();
    let mut good: HashMap<&str, BTreeSet<usize>> = HashMap::new();
    for (r, &(pass, k)) in found.into_iter().zip(&keys) {
        match r {
            Ok(Some(r)) => {
                status.done += 1;
                records.push(r);
                good.entry(pass).or_default().insert(k);
            }
            Ok(None) => {}
            Err(e) => status.unreadable.push(e.to_string()),
        }
    }
    for p in &outputs.passes {
        let good = good.get(p.name.as_str());
        status.missing.extend(
            (0..outputs.frames)
                .filter(|k| !good.is_some_and(|g| g.contains(k)))
                .map(|k| (p.name.clone(), k)),
        );
    }
    let mut counts: Vec<usize> = records
        .iter()
        .filter_map(|r| r.shard.as_deref()?.split_once('/')?.1.parse().ok())
        .collect();
    counts.sort_unstable();
    counts.dedup();
    status.shard_counts = counts;
    Ok((records, status))
}

/// Bytes as lowercase hex digits.
fn hex(bytes: &[u8]) -> String {
    use std::fmt::Write as _;
    bytes
        .iter()
        .fold(String::with_capacity(2 * bytes.len()), |mut s, b| {
            let _ = write!(s, "{b:02x}");
            s
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(text: &str) -> Scene {
        crate::scene::parse(text, Path::new("/tmp/s.toml")).unwrap()
    }

    fn digest(text: &str) -> String {
        let s = scene(text);
        let h = vec![s.volume().source.header().unwrap()];
        scene_digest(&s, &h, 8, 8)
    }

    #[test]
    fn the_digest_follows_what_changes_images() {
        let base =
            "[volume]\nsynthetic = \"ball\"\nsizes = [4, 4, 4]\n[[render]]\nmode = \"mip\"\n";
        let d = digest(base);
        assert_eq!(d.len(), 64);
        // comments, spacing, key order, the output folder, the animation and the
        // viewer page do not count
        assert_eq!(
            d,
            digest(
                "# a comment\n[volume]\nsizes = [4,4,4]\nsynthetic = \"ball\"\n\n[[render]]\nmode = \"mip\"  # mip\n[animation]\nfps = 12\n[viewer]\nhtml = true\n"
            )
        );
        assert_eq!(
            digest(&format!("{base}[image]\nout = \"a/b\"\n")),
            digest(&format!("{base}[image]\nout = \"c\"\n"))
        );
        // anything else does
        assert_ne!(d, digest(&base.replace("mip", "minip")));
        assert_ne!(d, digest(&base.replace("[4, 4, 4]", "[4, 4, 5]")));
        assert_ne!(d, digest(&format!("{base}[camera]\nzoom = 1.5\n")));
        let s = scene(base);
        let h = vec![s.volume().source.header().unwrap()];
        assert_ne!(scene_digest(&s, &h, 8, 8), scene_digest(&s, &h, 8, 9));
    }

    #[test]
    fn a_written_file_is_known_until_it_changes() {
        let dir = std::env::temp_dir().join(format!("volcast-known-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("a_0001.png");
        let r = write_recorded(&path, b"12345").unwrap();
        assert_eq!(r.bytes, 5);
        let folder = Folder::open(&dir).unwrap();
        let meta = folder
            .open_regular("a_0001.png")
            .unwrap()
            .metadata()
            .unwrap();
        if cfg!(unix) {
            assert_eq!(known::sha256(&meta), Some(r.sha256.clone()), "remembered");
        }
        assert!(file_matches(&folder, "a_0001.png", 5, &r.sha256));
        assert!(!file_matches(&folder, "a_0001.png", 5, &"0".repeat(64)));
        // replaced by another file of the same size and time (a new inode): read again
        let modified = meta.modified().unwrap();
        std::fs::write(dir.join("other"), b"54321").unwrap();
        let f = std::fs::File::options()
            .write(true)
            .open(dir.join("other"))
            .unwrap();
        f.set_modified(modified).unwrap();
        std::fs::rename(dir.join("other"), &path).unwrap();
        assert!(
            !file_matches(&folder, "a_0001.png", 5, &r.sha256),
            "replaced"
        );
        // changed in place, size and modification time kept (the status-change time moves)
        let r = write_recorded(&path, b"12345").unwrap();
        assert!(file_matches(&folder, "a_0001.png", 5, &r.sha256));
        let modified = std::fs::metadata(&path).unwrap().modified().unwrap();
        std::thread::sleep(std::time::Duration::from_millis(30));
        std::fs::write(&path, b"12346").unwrap();
        let f = std::fs::File::options().write(true).open(&path).unwrap();
        f.set_modified(modified).unwrap();
        assert!(
            !file_matches(&folder, "a_0001.png", 5, &r.sha256),
            "changed"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn records_round_trip_and_bad_ones_are_named() {
        let dir = std::env::temp_dir().join(format!("volcast-records-{}", std::process::id()));
        std::fs::create_dir_all(dir.join(RECORDS)).unwrap();
        std::fs::write(dir.join("a_0003.png"), b"12345").unwrap();
        let r = FrameRecord {
            scene_hash: "abc".into(),
            volcast_version: "0".into(),
            pass: "a".into(),
            frame: 3,
            files: vec![file_record(&dir.join("a_0003.png"), b"12345")],
            views: vec![],
            window: Some([0.0, 1.0]),
            samples: 7,
            seconds: 0.5,
            shard: None,
        };
        write_record(&dir, &r).unwrap();
        let back = read_record(&dir, "a", 3).unwrap().unwrap();
        assert_eq!(back, r);
        let names = ["a_0003.png".to_string()];
        assert!(is_complete(&dir, &back, "abc", &names));
        assert!(!is_complete(&dir, &back, "abd", &names));
        // a record naming a file the plan does not give that frame is not complete,
        // even when that file has the recorded bytes
        std::fs::write(dir.join("a_0004.png"), b"12345").unwrap();
        assert!(!is_complete(
            &dir,
            &back,
            "abc",
            &["a_0004.png".to_string()]
        ));
        assert!(!is_complete(&dir, &back, "abc", &[]));
        std::fs::write(dir.join("a_0003.png"), b"1234").unwrap();
        assert!(
            !is_complete(&dir, &back, "abc", &names),
            "a file of another size"
        );
        assert_eq!(read_record(&dir, "a", 4).unwrap(), None);
        std::fs::write(record_path(&dir, "a", 4), b"{\"scene_hash\": 1").unwrap();
        let e = read_record(&dir, "a", 4).unwrap_err().to_string();
        assert!(
            e.contains("a_0004.json") && e.contains("expected a JSON object"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
