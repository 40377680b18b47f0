//! One parser per header field (teem's `nrrdFieldInfoParse[]`), in a table that maps
//! the spec's field names (case-insensitive, with the spellings without spaces) to
//! parsers. The table order is the parse order: a field is parsed after the fields it
//! depends on (`dimension` before per-axis fields, `space` before space vectors), so
//! the lines themselves may come in any order.

use std::path::Path;

use super::data::NumberFormat;
use super::{DataFile, Encoding, Endian, NrrdHeader, Space};
use crate::{Error, ScalarType};

/// Why a field descriptor was refused.
pub(super) enum FieldError {
    /// Malformed or inconsistent (a header error).
    Bad(String),
    /// Valid NRRD this reader does not implement.
    Unsupported(String),
}

impl From<String> for FieldError {
    fn from(m: String) -> Self {
        FieldError::Bad(m)
    }
}

type FieldResult = Result<(), FieldError>;

/// A field: its names (canonical first) and its parser.
pub(super) struct FieldSpec {
    pub names: &'static [&'static str],
    parse: fn(&mut Builder, &str) -> FieldResult,
}

macro_rules! field {
    ($parse:ident, $($name:literal),+) => {
        FieldSpec { names: &[$($name),+], parse: $parse }
    };
}

/// Every NRRD field, in parse order.
pub(super) static FIELDS: [FieldSpec; 30] = [
    field!(parse_dimension, "dimension"),
    field!(parse_type, "type"),
    field!(parse_block_size, "block size", "blocksize"),
    field!(parse_encoding, "encoding"),
    field!(parse_endian, "endian"),
    field!(parse_space, "space"),
    field!(parse_space_dimension, "space dimension", "spacedimension"),
    field!(parse_sizes, "sizes"),
    field!(parse_spacings, "spacings"),
    field!(parse_thicknesses, "thicknesses"),
    field!(parse_axis_mins, "axis mins", "axismins"),
    field!(parse_axis_maxs, "axis maxs", "axismaxs"),
    field!(
        parse_space_directions,
        "space directions",
        "spacedirections"
    ),
    field!(parse_centers, "centers", "centerings"),
    field!(parse_kinds, "kinds"),
    field!(parse_labels, "labels"),
    field!(parse_units, "units"),
    field!(parse_min, "min"),
    field!(parse_max, "max"),
    field!(parse_old_min, "old min", "oldmin"),
    field!(parse_old_max, "old max", "oldmax"),
    field!(parse_content, "content"),
    field!(parse_sample_units, "sample units", "sampleunits"),
    field!(parse_space_units, "space units", "spaceunits"),
    field!(parse_space_origin, "space origin", "spaceorigin"),
    field!(
        parse_measurement_frame,
        "measurement frame",
        "measurementframe"
    ),
    field!(parse_line_skip, "line skip", "lineskip"),
    field!(parse_byte_skip, "byte skip", "byteskip"),
    field!(parse_number, "number"),
    field!(parse_data_file, "data file", "datafile"),
];

/// Index of `data file` in [`FIELDS`].
pub(super) const DATA_FILE: usize = 29;

/// The fields every header must have (teem's `_nrrdFieldRequired`).
const REQUIRED: [&str; 4] = ["type", "dimension", "sizes", "encoding"];

/// Largest dimension (teem's `NRRD_DIM_MAX`).
const MAX_DIMENSION: usize = 16;

/// Axis kinds of the spec (`nrrdKind`), plus `???`/`none` for "unknown".
const KINDS: [&str; 33] = [
    "domain",
    "space",
    "time",
    "list",
    "point",
    "vector",
    "covariant-vector",
    "normal",
    "stub",
    "scalar",
    "complex",
    "2-vector",
    "3-color",
    "RGB-color",
    "HSV-color",
    "XYZ-color",
    "4-color",
    "RGBA-color",
    "3-vector",
    "3-gradient",
    "3-normal",
    "4-vector",
    "quaternion",
    "2D-symmetric-matrix",
    "2D-masked-symmetric-matrix",
    "2D-matrix",
    "2D-masked-matrix",
    "3D-symmetric-matrix",
    "3D-masked-symmetric-matrix",
    "3D-matrix",
    "3D-masked-matrix",
    "???",
    "none",
];

/// Sample centerings.
const CENTERS: [&str; 4] = ["cell", "node", "???", "none"];

/// The index in [`FIELDS`] of a field name, ignoring case.
pub(super) fn field_index(name: &str) -> Option<usize> {
    FIELDS
        .iter()
        .position(|f| f.names.iter().any(|n| n.eq_ignore_ascii_case(name)))
}

/// True when `kind` is an axis kind of the spec (case-insensitive).
pub(super) fn is_kind(kind: &str) -> bool {
    KINDS.iter().any(|k| k.eq_ignore_ascii_case(kind))
}

/// True when `center` is a centering of the spec (case-insensitive).
pub(super) fn is_center(center: &str) -> bool {
    CENTERS.iter().any(|c| c.eq_ignore_ascii_case(center))
}

/// The header being built while fields are parsed.
struct Builder<'a> {
    h: NrrdHeader,
    dimension: Option<usize>,
    list_names: &'a [(usize, String)],
}

/// A parsed header and where each field was.
pub(super) struct Parsed {
    /// The header.
    pub header: NrrdHeader,
    /// (canonical field name, 1-based line) of every field present.
    pub lines: Vec<(&'static str, usize)>,
}

impl Parsed {
    /// The line of field `name`, or 0 when absent.
    pub fn line(&self, name: &str) -> usize {
        self.lines
            .iter()
            .find(|(n, _)| *n == name)
            .map_or(0, |&(_, l)| l)
    }

    /// True when field `name` was given.
    pub fn has(&self, name: &str) -> bool {
        self.line(name) != 0
    }
}

/// One `<field>: <desc>` line.
#[derive(Debug)]
pub(super) struct FieldLine {
    /// 1-based line number.
    pub line: usize,
    /// Index into [`FIELDS`].
    pub field: usize,
    /// The descriptor after `: `.
    pub desc: String,
}

/// The header as text, split into its parts but not yet interpreted.
#[derive(Debug, Default)]
pub(super) struct RawHeader {
    /// Format version from the magic (1..=5).
    pub version: u8,
    /// Field lines in file order.
    pub fields: Vec<FieldLine>,
    /// `#` comments.
    pub comments: Vec<String>,
    /// `key:=value` pairs, unescaped, with their line numbers.
    pub key_values: Vec<(usize, String, String)>,
    /// File names after `data file: LIST`, with their line numbers.
    pub list_names: Vec<(usize, String)>,
    /// Byte offset just after the blank line, when the header ended with one.
    pub data_offset: Option<u64>,
}

/// Interprets the header lines: duplicates and missing required fields are errors,
/// then every field is parsed in table order.
pub(super) fn parse_fields(path: &Path, raw: &RawHeader) -> Result<Parsed, Error> {
    let mut first_line = [0usize; FIELDS.len()];
    for fl in &raw.fields {
        let first = &mut first_line[fl.field];
        if *first != 0 {
            return Err(Error::Header {
                path: path.to_path_buf(),
                line: fl.line,
                message: format!(
                    "duplicate field `{}` (first given on line {first})",
                    FIELDS[fl.field].names[0]
                ),
            });
        }
        *first = fl.line;
    }
    let missing: Vec<&str> = REQUIRED
        .iter()
        .copied()
        .filter(|name| field_index(name).is_none_or(|i| first_line[i] == 0))
        .collect();
    if !missing.is_empty() {
        return Err(Error::Header {
            path: path.to_path_buf(),
            line: 0,
            message: format!(
                "missing required field{} `{}` (a NRRD header needs type, dimension, sizes and encoding)",
                if missing.len() > 1 { "s" } else { "" },
                missing.join("`, `")
            ),
        });
    }
    let mut b = Builder {
        h: NrrdHeader::new(ScalarType::Uint8, Vec::new()),
        dimension: None,
        list_names: &raw.list_names,
    };
    b.h.version = raw.version;
    let mut lines = Vec::new();
    for (index, spec) in FIELDS.iter().enumerate() {
        let Some(fl) = raw.fields.iter().find(|f| f.field == index) else {
            continue;
        };
        let name = spec.names[0];
        (spec.parse)(&mut b, &fl.desc).map_err(|e| match e {
            FieldError::Bad(m) => Error::Header {
                path: path.to_path_buf(),
                line: fl.line,
                message: format!("{name}: {m}"),
            },
            FieldError::Unsupported(m) => Error::Unsupported {
                path: path.to_path_buf(),
                message: format!("line {}: {name}: {m}", fl.line),
            },
        })?;
        lines.push((name, fl.line));
    }
    b.h.comments = raw.comments.clone();
    // As teem does, a repeated key replaces the earlier value (found through an
    // index, so that a header of many pairs parses in linear time).
    let mut index: std::collections::HashMap<&str, usize> = std::collections::HashMap::new();
    for (_, key, value) in &raw.key_values {
        match index.get(key.as_str()) {
            Some(&i) => b.h.key_values[i].1 = value.clone(),
            None => {
                index.insert(key, b.h.key_values.len());
                b.h.key_values.push((key.clone(), value.clone()));
            }
        }
    }
    Ok(Parsed { header: b.h, lines })
}

// ---------------------------------------------------------------- helpers

fn dimension(b: &Builder) -> Result<usize, FieldError> {
    b.dimension
        .ok_or_else(|| FieldError::Bad("needs a valid `dimension` field".into()))
}

fn space_dimension(b: &Builder) -> Result<usize, FieldError> {
    b.h.space_dimension.ok_or_else(|| {
        FieldError::Bad(
            "needs a `space` or `space dimension` field to know the vector length".into(),
        )
    })
}

fn parse_f64(token: &str) -> Option<f64> {
    token.trim().parse::<f64>().ok()
}

/// Exactly `dim` whitespace-separated numbers (`nan` allowed).
fn per_axis_f64(desc: &str, dim: usize, what: &str) -> Result<Vec<f64>, FieldError> {
    let values: Option<Vec<f64>> = desc.split_whitespace().map(parse_f64).collect();
    match values {
        Some(v) if v.len() == dim => Ok(v),
        _ => Err(FieldError::Bad(format!(
            "expected {dim} {what} (dimension {dim}), got {desc:?}"
        ))),
    }
}

/// Exactly `dim` whitespace-separated words, each accepted by `valid`.
fn per_axis_words(
    desc: &str,
    dim: usize,
    what: &str,
    valid: fn(&str) -> bool,
) -> Result<Vec<String>, FieldError> {
    let words: Vec<String> = desc.split_whitespace().map(str::to_string).collect();
    if words.len() != dim {
        return Err(FieldError::Bad(format!(
            "expected {dim} {what} (dimension {dim}), got {desc:?}"
        )));
    }
    match words.iter().find(|w| !valid(w)) {
        Some(w) => Err(FieldError::Bad(format!(
            "{w:?} is not one of the {what} of the NRRD format"
        ))),
        None => Ok(words),
    }
}

/// Double-quoted strings (`"mm" "mm"`); `\"` stands for a quote inside one.
pub(super) fn parse_quoted(desc: &str) -> Result<Vec<String>, String> {
    let mut out = Vec::new();
    let mut chars = desc.chars().peekable();
    loop {
        while chars.next_if(|c| c.is_whitespace()).is_some() {}
        match chars.next() {
            None => return Ok(out),
            Some('"') => {}
            Some(c) => {
                return Err(format!(
                    "expected a double-quoted string, found {c:?} in {desc:?}"
                ))
            }
        }
        let mut s = String::new();
        loop {
            match chars.next() {
                None => return Err(format!("missing closing quote in {desc:?}")),
                Some('"') => break,
                Some('\\') if chars.peek() == Some(&'"') => {
                    chars.next();
                    s.push('"');
                }
                Some(c) => s.push(c),
            }
        }
        out.push(s);
    }
}

fn quoted_per_axis(
    desc: &str,
    count: usize,
    what: &str,
    of: &str,
) -> Result<Vec<String>, FieldError> {
    let v = parse_quoted(desc)?;
    if v.len() != count {
        return Err(FieldError::Bad(format!(
            "expected {count} quoted {what} ({of} {count}), got {desc:?}"
        )));
    }
    Ok(v)
}

/// Space vectors `(x,y,z)`, or `none` where `allow_none`; each of `len` finite numbers.
pub(super) fn parse_vectors(
    desc: &str,
    len: usize,
    allow_none: bool,
) -> Result<Vec<Option<Vec<f64>>>, String> {
    let mut out = Vec::new();
    let mut rest = desc.trim_start();
    while !rest.is_empty() {
        if let Some(after) = rest.strip_prefix("none") {
            if allow_none && (after.is_empty() || after.starts_with(char::is_whitespace)) {
                out.push(None);
                rest = after.trim_start();
                continue;
            }
        }
        let Some(inner) = rest.strip_prefix('(') else {
            return Err(format!(
                "expected a vector like ({}){} at {rest:?}",
                vec!["0"; len].join(","),
                if allow_none { " or `none`" } else { "" }
            ));
        };
        let Some(close) = inner.find(')') else {
            return Err(format!("missing ')' in {rest:?}"));
        };
        let parts: Vec<&str> = inner[..close].split(',').collect();
        let values: Option<Vec<f64>> = parts.iter().map(|p| parse_f64(p)).collect();
        match values {
            Some(v) if v.len() == len && v.iter().all(|x| x.is_finite()) => out.push(Some(v)),
            _ => {
                return Err(format!(
                    "vector ({}) should have {len} finite numbers (space dimension {len})",
                    &inner[..close]
                ))
            }
        }
        rest = inner[close + 1..].trim_start();
    }
    Ok(out)
}

fn single_f64(desc: &str) -> Result<f64, FieldError> {
    parse_f64(desc).ok_or_else(|| FieldError::Bad(format!("expected a number, got {desc:?}")))
}

// ---------------------------------------------------------------- parsers

fn parse_dimension(b: &mut Builder, desc: &str) -> FieldResult {
    match desc.parse::<usize>() {
        Ok(d) if (1..=MAX_DIMENSION).contains(&d) => {
            b.dimension = Some(d);
            Ok(())
        }
        _ => Err(format!("expected an integer from 1 to {MAX_DIMENSION}, got {desc:?}").into()),
    }
}

fn parse_type(b: &mut Builder, desc: &str) -> FieldResult {
    if desc.eq_ignore_ascii_case("block") {
        return Err(FieldError::Unsupported(
            "`block` (opaque elements) is not supported: a volume needs numeric elements".into(),
        ));
    }
    b.h.scalar_type = ScalarType::parse(desc).ok_or_else(|| {
        format!("unknown type {desc:?} (expected e.g. uchar, uint8, short, int16, float, double)")
    })?;
    Ok(())
}

fn parse_block_size(_: &mut Builder, desc: &str) -> FieldResult {
    // Only meaningful for type `block`, which is refused; checked, then ignored.
    desc.parse::<usize>()
        .map(drop)
        .map_err(|_| format!("expected a byte count, got {desc:?}").into())
}

fn parse_encoding(b: &mut Builder, desc: &str) -> FieldResult {
    if desc.eq_ignore_ascii_case("zrl") {
        return Err(FieldError::Unsupported(
            "encoding `zrl` is not supported".into(),
        ));
    }
    b.h.encoding = Encoding::parse(desc).ok_or_else(|| {
        format!("expected raw, gzip (gz), bzip2 (bz2), ascii (text, txt) or hex, got {desc:?}")
    })?;
    Ok(())
}

fn parse_endian(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.endian = match desc.to_ascii_lowercase().as_str() {
        "little" => Endian::Little,
        "big" => Endian::Big,
        _ => return Err(format!("expected little or big, got {desc:?}").into()),
    };
    Ok(())
}

fn parse_space(b: &mut Builder, desc: &str) -> FieldResult {
    let space = Space::parse(desc).ok_or_else(|| {
        format!(
            "unknown space {desc:?} (expected one of {})",
            Space::TABLE.map(|r| r.1).join(", ")
        )
    })?;
    b.h.space = Some(space);
    b.h.space_dimension = Some(space.dimension());
    Ok(())
}

fn parse_space_dimension(b: &mut Builder, desc: &str) -> FieldResult {
    let d = match desc.parse::<usize>() {
        Ok(d) if (1..=MAX_DIMENSION).contains(&d) => d,
        _ => {
            return Err(
                format!("expected an integer from 1 to {MAX_DIMENSION}, got {desc:?}").into(),
            )
        }
    };
    if let Some(space) = b.h.space {
        if space.dimension() != d {
            return Err(format!(
                "{d} contradicts `space: {}`, whose dimension is {}",
                space.name(),
                space.dimension()
            )
            .into());
        }
    }
    b.h.space_dimension = Some(d);
    Ok(())
}

fn parse_sizes(b: &mut Builder, desc: &str) -> FieldResult {
    let dim = dimension(b)?;
    let sizes: Option<Vec<usize>> = desc
        .split_whitespace()
        .map(|t| t.parse::<usize>().ok().filter(|&s| s > 0))
        .collect();
    match sizes {
        Some(s) if s.len() == dim => {
            b.h.sizes = s;
            Ok(())
        }
        _ => {
            Err(format!("expected {dim} positive integers (dimension {dim}), got {desc:?}").into())
        }
    }
}

fn parse_spacings(b: &mut Builder, desc: &str) -> FieldResult {
    let v = per_axis_f64(desc, dimension(b)?, "spacings")?;
    if let Some(bad) = v.iter().find(|s| **s == 0.0 || s.is_infinite()) {
        return Err(format!("spacing {bad} is invalid (use a non-zero finite number, or nan for a non-spatial axis)").into());
    }
    b.h.spacings = Some(v);
    Ok(())
}

fn parse_thicknesses(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.thicknesses = Some(per_axis_f64(desc, dimension(b)?, "thicknesses")?);
    Ok(())
}

fn parse_axis_mins(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.axis_mins = Some(per_axis_f64(desc, dimension(b)?, "axis mins")?);
    Ok(())
}

fn parse_axis_maxs(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.axis_maxs = Some(per_axis_f64(desc, dimension(b)?, "axis maxs")?);
    Ok(())
}

fn parse_space_directions(b: &mut Builder, desc: &str) -> FieldResult {
    let dim = dimension(b)?;
    let sd = space_dimension(b)?;
    let v = parse_vectors(desc, sd, true)?;
    if v.len() != dim {
        return Err(format!(
            "expected {dim} vectors or `none` (dimension {dim}), got {} in {desc:?}",
            v.len()
        )
        .into());
    }
    b.h.space_directions = Some(v);
    Ok(())
}

fn parse_centers(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.centers = Some(per_axis_words(desc, dimension(b)?, "centers", is_center)?);
    Ok(())
}

fn parse_kinds(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.kinds = Some(per_axis_words(desc, dimension(b)?, "kinds", is_kind)?);
    Ok(())
}

fn parse_labels(b: &mut Builder, desc: &str) -> FieldResult {
    let dim = dimension(b)?;
    b.h.labels = Some(quoted_per_axis(desc, dim, "labels", "dimension")?);
    Ok(())
}

fn parse_units(b: &mut Builder, desc: &str) -> FieldResult {
    let dim = dimension(b)?;
    b.h.units = Some(quoted_per_axis(desc, dim, "units", "dimension")?);
    Ok(())
}

fn parse_min(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.min = Some(single_f64(desc)?);
    Ok(())
}

fn parse_max(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.max = Some(single_f64(desc)?);
    Ok(())
}

fn parse_old_min(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.old_min = Some(single_f64(desc)?);
    Ok(())
}

fn parse_old_max(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.old_max = Some(single_f64(desc)?);
    Ok(())
}

fn parse_content(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.content = Some(desc.to_string());
    Ok(())
}

fn parse_sample_units(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.sample_units = Some(desc.to_string());
    Ok(())
}

fn parse_space_units(b: &mut Builder, desc: &str) -> FieldResult {
    let sd = space_dimension(b)?;
    b.h.space_units = Some(quoted_per_axis(desc, sd, "units", "space dimension")?);
    Ok(())
}

fn parse_space_origin(b: &mut Builder, desc: &str) -> FieldResult {
    let sd = space_dimension(b)?;
    match parse_vectors(desc, sd, false)?.as_slice() {
        [Some(v)] => {
            b.h.space_origin = Some(v.clone());
            Ok(())
        }
        _ => Err(format!(
            "expected one vector of {sd} numbers (space dimension {sd}), got {desc:?}"
        )
        .into()),
    }
}

fn parse_measurement_frame(b: &mut Builder, desc: &str) -> FieldResult {
    let sd = space_dimension(b)?;
    let v = parse_vectors(desc, sd, false)?;
    if v.len() != sd {
        return Err(format!("expected {sd} vectors (space dimension {sd}), got {desc:?}").into());
    }
    b.h.measurement_frame = Some(v.into_iter().flatten().collect());
    Ok(())
}

fn parse_line_skip(b: &mut Builder, desc: &str) -> FieldResult {
    b.h.line_skip = desc
        .parse::<usize>()
        .map_err(|_| format!("expected a number of lines (0 or more), got {desc:?}"))?;
    Ok(())
}

fn parse_byte_skip(b: &mut Builder, desc: &str) -> FieldResult {
    match desc.parse::<i64>() {
        Ok(n) if n >= -1 => {
            b.h.byte_skip = n;
            Ok(())
        }
        _ => Err(format!(
            "expected a number of bytes (0 or more), or -1 for data at the end of the file, got {desc:?}"
        )
        .into()),
    }
}

fn parse_number(_: &mut Builder, _: &str) -> FieldResult {
    // Redundant with `sizes`; teem ignores it, and so do we.
    Ok(())
}

fn parse_subdim(text: Option<&str>, dim: usize) -> Result<Option<usize>, FieldError> {
    match text {
        None => Ok(None),
        Some(t) => match t.parse::<usize>() {
            Ok(s) if (1..=dim).contains(&s) => Ok(Some(s)),
            _ => Err(format!(
                "data file dimension should be an integer from 1 to {dim}, got {t:?}"
            )
            .into()),
        },
    }
}

fn parse_data_file(b: &mut Builder, desc: &str) -> FieldResult {
    if desc.is_empty() {
        return Err(
            "expected a file name, `LIST [<subdim>]`, or `<format> <min> <max> <step> [<subdim>]`"
                .to_string()
                .into(),
        );
    }
    let mut words = desc.split_whitespace();
    let first = words.next().unwrap_or_default();
    if first == "LIST" {
        let subdim = parse_subdim(words.next(), dimension(b)?)?;
        if b.list_names.is_empty() {
            return Err("LIST is not followed by any file names (one per line, up to the end of the header)".to_string().into());
        }
        let names = b.list_names.iter().map(|(_, n)| n.clone()).collect();
        b.h.data_file = DataFile::List { names, subdim };
        return Ok(());
    }
    if NumberFormat::parse(first)
        .map_err(FieldError::Bad)?
        .is_none()
    {
        b.h.data_file = DataFile::Single(desc.to_string());
        return Ok(());
    }
    let nums: Vec<&str> = words.collect();
    let ints: Option<Vec<i64>> = nums.iter().take(3).map(|t| t.parse().ok()).collect();
    let (Some([min, max, step]), 3..=4) =
        (ints.and_then(|v| <[i64; 3]>::try_from(v).ok()), nums.len())
    else {
        return Err(format!("{first:?} is a file name format: expected `{first} <min> <max> <step> [<subdim>]`, got {desc:?}").into());
    };
    if step == 0 {
        return Err("file number step must not be 0".to_string().into());
    }
    if (max as i128 - min as i128) * (step as i128) < 0 {
        return Err(
            format!("file number {max} cannot be reached from {min} by steps of {step}").into(),
        );
    }
    let subdim = parse_subdim(nums.get(3).copied(), dimension(b)?)?;
    b.h.data_file = DataFile::Pattern {
        format: first.to_string(),
        min,
        max,
        step,
        subdim,
    };
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_is_consistent() {
        assert_eq!(FIELDS[DATA_FILE].names[0], "data file");
        assert_eq!(field_index("DataFile"), Some(DATA_FILE));
        assert_eq!(field_index("Byte Skip"), field_index("byteskip"));
        assert_eq!(
            field_index("space directions"),
            field_index("spacedirections")
        );
        assert_eq!(field_index("colour"), None);
        for r in REQUIRED {
            assert!(field_index(r).is_some());
        }
    }

    #[test]
    fn quoted_strings() {
        assert_eq!(
            parse_quoted(r#" "mm" "a \"b\"" "" "#).unwrap(),
            vec!["mm", "a \"b\"", ""]
        );
        assert!(parse_quoted(r#""mm" mm"#).is_err());
        assert!(parse_quoted(r#""mm"#).is_err());
    }

    #[test]
    fn vectors() {
        let v = parse_vectors("none (1, 0,0) (0.5,2,-1e-3)", 3, true).unwrap();
        assert_eq!(
            v,
            vec![None, Some(vec![1.0, 0.0, 0.0]), Some(vec![0.5, 2.0, -1e-3])]
        );
        assert!(parse_vectors("(1,0)", 3, true).is_err());
        assert!(parse_vectors("(1,0,nan)", 3, true).is_err());
        assert!(parse_vectors("none", 3, false).is_err());
        assert!(parse_vectors("(1,0,0", 3, true).is_err());
        assert!(parse_vectors("nonesuch", 3, true).is_err());
    }
}
