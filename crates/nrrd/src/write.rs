//! Writing: the header text (checked so that the reader accepts it back unchanged),
//! then the data in the header's encoding, attached or in a detached data file.

use std::io::Write;
use std::path::Path;

use super::codec::{ascii_text, element_bytes, hex_text};
use super::data::NumberFormat;
use super::fields::{is_center, is_kind};
use super::{Encoding, Endian, NrrdHeader};
use crate::{Data, Elements, Error};

/// Encodes a complete attached-header NRRD file in memory: magic, fields, `key:=value`
/// pairs (escaped), a blank line, then the data in `header.encoding` and
/// `header.endian`. `data_file`, `line_skip` and `byte_skip` are not written: the data
/// follows the header directly.
pub fn encode(header: &NrrdHeader, data: &Data) -> Result<Vec<u8>, Error> {
    encode_elements(header, data.elements())
}

/// [`encode`] from a borrowed view of the values (an image's samples, say): the file's
/// bytes are the one buffer this allocates.
pub fn encode_elements(header: &NrrdHeader, data: Elements<'_>) -> Result<Vec<u8>, Error> {
    check_for_writing(header, data)?;
    let mut out = header_text(header, None).into_bytes();
    out.push(b'\n');
    encode_data(header, data, out)
}

/// Writes a detached header to `nhdr_path` naming `data_file_name` (relative to the
/// header's folder), and the data, in `header.encoding`, to that file.
pub fn write_detached(
    nhdr_path: &Path,
    data_file_name: &str,
    header: &NrrdHeader,
    data: &Data,
) -> Result<(), Error> {
    write_detached_elements(nhdr_path, data_file_name, header, data.elements())
}

/// [`write_detached`] from a borrowed view of the values.
pub fn write_detached_elements(
    nhdr_path: &Path,
    data_file_name: &str,
    header: &NrrdHeader,
    data: Elements<'_>,
) -> Result<(), Error> {
    check_for_writing(header, data)?;
    check_data_file_name(data_file_name)?;
    let text = header_text(header, Some(data_file_name));
    let data_path = nhdr_path
        .parent()
        .unwrap_or(Path::new(""))
        .join(data_file_name);
    let bytes = encode_data(header, data, Vec::new())?;
    write_file(&data_path, &bytes)?;
    write_file(nhdr_path, text.as_bytes())
}

fn write_file(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    std::fs::write(path, bytes).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn invalid(message: String) -> Error {
    Error::Invalid(format!("cannot write NRRD: {message}"))
}

/// A name the reader would take as one plain file name.
fn check_data_file_name(name: &str) -> Result<(), Error> {
    let first = name.split_whitespace().next().unwrap_or_default();
    let plain = name.trim() == name
        && !name.is_empty()
        && !name.contains(['\n', '\r'])
        && first != "LIST"
        && matches!(NumberFormat::parse(first), Ok(None));
    if plain {
        Ok(())
    } else {
        Err(invalid(format!(
            "data file name {name:?} would not read back as a single file name"
        )))
    }
}

// ---------------------------------------------------------------- checks

fn check_len<T>(v: &Option<Vec<T>>, n: usize, what: &str, of: &str) -> Result<(), Error> {
    match v {
        Some(v) if v.len() != n => Err(invalid(format!(
            "{what} has {} entries, {of} is {n}",
            v.len()
        ))),
        _ => Ok(()),
    }
}

fn check_line(s: &str, what: &str) -> Result<(), Error> {
    if s.contains(['\n', '\r']) {
        return Err(invalid(format!("{what} {s:?} contains a line break")));
    }
    Ok(())
}

fn check_words(v: &Option<Vec<String>>, what: &str, valid: fn(&str) -> bool) -> Result<(), Error> {
    match v.iter().flatten().find(|w| !valid(w)) {
        Some(w) => Err(invalid(format!(
            "{w:?} is not one of the {what} of the NRRD format"
        ))),
        None => Ok(()),
    }
}

fn check_key_value(key: &str, value: &str) -> Result<(), Error> {
    let ok_key = !key.is_empty()
        && !key.contains(":=")
        && !key.contains(": ")
        && !key.starts_with('#')
        && !key.contains('\r');
    if !ok_key {
        return Err(invalid(format!(
            "key {key:?} cannot be written (it must be non-empty, not start with '#', and not contain \":=\", \": \" or a carriage return)"
        )));
    }
    if value.contains('\r') {
        return Err(invalid(format!(
            "value of key {key:?} contains a carriage return"
        )));
    }
    Ok(())
}

fn check_space(h: &NrrdHeader) -> Result<(), Error> {
    if let (Some(space), Some(sd)) = (h.space, h.space_dimension) {
        if space.dimension() != sd {
            return Err(invalid(format!(
                "space dimension {sd} contradicts space {}",
                space.name()
            )));
        }
    }
    let sd = h.space.map(|s| s.dimension()).or(h.space_dimension);
    let uses_space = h.space_directions.is_some()
        || h.space_origin.is_some()
        || h.space_units.is_some()
        || h.measurement_frame.is_some();
    let Some(sd) = sd else {
        return match uses_space {
            true => Err(invalid(
                "space directions/origin/units/measurement frame need `space` or `space_dimension`"
                    .into(),
            )),
            false => Ok(()),
        };
    };
    let finite = |v: &Vec<f64>| v.len() == sd && v.iter().all(|x| x.is_finite());
    let dirs_ok = h.space_directions.iter().flatten().flatten().all(finite);
    let origin_ok = h.space_origin.as_ref().is_none_or(finite);
    let mf_ok = h
        .measurement_frame
        .as_ref()
        .is_none_or(|m| m.len() == sd && m.iter().all(finite));
    if !(dirs_ok && origin_ok && mf_ok) {
        return Err(invalid(format!(
            "space vectors must have {sd} finite components (space dimension {sd})"
        )));
    }
    check_len(&h.space_units, sd, "space units", "space dimension")
}

fn check_for_writing(h: &NrrdHeader, data: Elements<'_>) -> Result<(), Error> {
    let dim = h.dimension();
    if !(1..=16).contains(&dim) || h.sizes.contains(&0) {
        return Err(invalid(format!(
            "sizes {:?}: need 1 to 16 axes, each of size ≥ 1",
            h.sizes
        )));
    }
    if data.scalar_type() != h.scalar_type {
        return Err(invalid(format!(
            "header type {} but data type {}",
            h.scalar_type,
            data.scalar_type()
        )));
    }
    if h.element_count() != Some(data.len()) {
        return Err(invalid(format!(
            "sizes {:?} do not match {} elements",
            h.sizes,
            data.len()
        )));
    }
    check_len(&h.spacings, dim, "spacings", "dimension")?;
    check_len(&h.thicknesses, dim, "thicknesses", "dimension")?;
    check_len(&h.axis_mins, dim, "axis mins", "dimension")?;
    check_len(&h.axis_maxs, dim, "axis maxs", "dimension")?;
    check_len(&h.centers, dim, "centers", "dimension")?;
    check_len(&h.kinds, dim, "kinds", "dimension")?;
    check_len(&h.labels, dim, "labels", "dimension")?;
    check_len(&h.units, dim, "units", "dimension")?;
    check_len(&h.space_directions, dim, "space directions", "dimension")?;
    check_words(&h.kinds, "kinds", is_kind)?;
    check_words(&h.centers, "centers", is_center)?;
    if let Some(s) = h
        .spacings
        .iter()
        .flatten()
        .find(|s| **s == 0.0 || s.is_infinite())
    {
        return Err(invalid(format!(
            "spacing {s} (use a non-zero finite number or NaN)"
        )));
    }
    if let (Some(s), Some(d)) = (&h.spacings, &h.space_directions) {
        if s.iter().zip(d).any(|(s, d)| !s.is_nan() && d.is_some()) {
            return Err(invalid(
                "an axis has both a spacing and a space direction".into(),
            ));
        }
    }
    check_space(h)?;
    for s in h.content.iter().chain(&h.sample_units).chain(&h.comments) {
        check_line(s, "text")?;
    }
    for s in [&h.labels, &h.units, &h.space_units]
        .into_iter()
        .flatten()
        .flatten()
    {
        check_line(s, "quoted string")?;
    }
    for (k, v) in &h.key_values {
        check_key_value(k, v)?;
    }
    Ok(())
}

// ---------------------------------------------------------------- header text

/// A number as the reader parses it back exactly (`nan` for NaN).
fn num(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{v}")
    } else {
        format!("{v:?}")
    }
}

fn nums(v: &[f64]) -> String {
    v.iter().map(|&x| num(x)).collect::<Vec<_>>().join(" ")
}

fn vector(v: &[f64]) -> String {
    format!(
        "({})",
        v.iter().map(|&x| num(x)).collect::<Vec<_>>().join(",")
    )
}

fn quoted(v: &[String]) -> String {
    v.iter()
        .map(|s| format!("\"{}\"", s.replace('"', "\\\"")))
        .collect::<Vec<_>>()
        .join(" ")
}

fn escape(s: &str) -> String {
    s.replace('\\', "\\\\").replace('\n', "\\n")
}

/// The oldest magic that holds these fields (teem's rule), or the header's own version
/// if newer.
fn version(h: &NrrdHeader) -> u8 {
    let needed = if h.measurement_frame.is_some() {
        5
    } else if h.space.is_some()
        || h.space_dimension.is_some()
        || h.sample_units.is_some()
        || h.thicknesses.is_some()
    {
        4
    } else if h.kinds.is_some() {
        3
    } else if !h.key_values.is_empty() {
        2
    } else {
        1
    };
    needed.max(h.version.clamp(1, 5))
}

/// The header lines (without the blank line that precedes attached data).
fn header_text(h: &NrrdHeader, data_file: Option<&str>) -> String {
    let mut lines = vec![format!("NRRD000{}", version(h))];
    let mut field = |name: &str, value: String| lines.push(format!("{name}: {value}"));
    if let Some(c) = &h.content {
        field("content", c.clone());
    }
    field("type", h.scalar_type.nrrd_name().into());
    field("dimension", h.dimension().to_string());
    match (h.space, h.space_dimension) {
        (Some(space), _) => field("space", space.name().into()),
        (None, Some(sd)) => field("space dimension", sd.to_string()),
        (None, None) => {}
    }
    field(
        "sizes",
        h.sizes
            .iter()
            .map(|s| s.to_string())
            .collect::<Vec<_>>()
            .join(" "),
    );
    if let Some(d) = &h.space_directions {
        let v: Vec<String> = d
            .iter()
            .map(|v| v.as_deref().map_or("none".into(), vector))
            .collect();
        field("space directions", v.join(" "));
    }
    let optional_lists = [
        ("spacings", &h.spacings),
        ("thicknesses", &h.thicknesses),
        ("axis mins", &h.axis_mins),
        ("axis maxs", &h.axis_maxs),
    ];
    for (name, v) in optional_lists {
        if let Some(v) = v {
            field(name, nums(v));
        }
    }
    if let Some(c) = &h.centers {
        field("centers", c.join(" "));
    }
    if let Some(k) = &h.kinds {
        field("kinds", k.join(" "));
    }
    if let Some(l) = &h.labels {
        field("labels", quoted(l));
    }
    if let Some(u) = &h.units {
        field("units", quoted(u));
    }
    for (name, v) in [
        ("min", h.min),
        ("max", h.max),
        ("old min", h.old_min),
        ("old max", h.old_max),
    ] {
        if let Some(v) = v {
            field(name, num(v));
        }
    }
    if h.scalar_type.size() > 1 && h.encoding.endian_matters() {
        field("endian", h.endian.name().into());
    }
    field("encoding", h.encoding.name().into());
    if let Some(u) = &h.sample_units {
        field("sample units", u.clone());
    }
    if let Some(u) = &h.space_units {
        field("space units", quoted(u));
    }
    if let Some(o) = &h.space_origin {
        field("space origin", vector(o));
    }
    if let Some(m) = &h.measurement_frame {
        field(
            "measurement frame",
            m.iter().map(|v| vector(v)).collect::<Vec<_>>().join(" "),
        );
    }
    if let Some(name) = data_file {
        field("data file", name.into());
    }
    for c in &h.comments {
        lines.push(format!("# {c}"));
    }
    for (k, v) in &h.key_values {
        lines.push(format!("{}:={}", escape(k), escape(v)));
    }
    let mut text = lines.join("\n");
    text.push('\n');
    text
}

// ---------------------------------------------------------------- data

/// `out` with the data appended in the header's encoding.
fn encode_data(h: &NrrdHeader, data: Elements<'_>, mut out: Vec<u8>) -> Result<Vec<u8>, Error> {
    let le = h.endian == Endian::Little;
    let compress_err =
        |e: std::io::Error| invalid(format!("{} compression failed: {e}", h.encoding.name()));
    match h.encoding {
        Encoding::Raw => {
            let bytes = element_bytes(data, le);
            out.reserve_exact(bytes.len());
            out.extend_from_slice(&bytes);
        }
        Encoding::Hex => out.extend(hex_text(&element_bytes(data, le))),
        Encoding::Ascii => out.extend(ascii_text(data, h.sizes[0])),
        Encoding::Gzip => {
            let mut e = flate2::write::GzEncoder::new(out, flate2::Compression::default());
            e.write_all(&element_bytes(data, le))
                .map_err(compress_err)?;
            out = e.finish().map_err(compress_err)?;
        }
        Encoding::Bzip2 => {
            let mut e = bzip2::write::BzEncoder::new(out, bzip2::Compression::default());
            e.write_all(&element_bytes(data, le))
                .map_err(compress_err)?;
            out = e.finish().map_err(compress_err)?;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ScalarType;

    #[test]
    fn numbers_round_trip() {
        for v in [1.0, -0.5, 0.1, 1e-7, 1e300, -3.0e15, 123456.789] {
            assert_eq!(num(v).parse::<f64>().unwrap(), v, "{}", num(v));
        }
        assert_eq!(num(1.0), "1");
        assert_eq!(num(f64::NAN), "nan");
    }

    #[test]
    fn header_layout() {
        let mut h = NrrdHeader::new(ScalarType::Uint16, vec![2, 1]).with_spacings([0.5, f64::NAN]);
        h.key_values.push(("a\\b".into(), "x\ny".into()));
        let t = header_text(&h, None);
        assert_eq!(
            t,
            "NRRD0004\ntype: uint16\ndimension: 2\nsizes: 2 1\nspacings: 0.5 nan\nendian: little\nencoding: raw\na\\\\b:=x\\ny\n"
        );
    }

    #[test]
    fn refuses_what_would_not_read_back() {
        let d = Data::U8(vec![0; 2]);
        let h = NrrdHeader::new(ScalarType::Uint8, vec![2]);
        assert!(encode(&h, &Data::U8(vec![0; 3])).is_err());
        assert!(encode(&h, &Data::I8(vec![0; 2])).is_err());
        let mut bad = h.clone();
        bad.key_values.push(("type: x".into(), "y".into()));
        assert!(encode(&bad, &d).is_err());
        let bad = h.clone().with_kinds(["colour"]);
        assert!(encode(&bad, &d).is_err());
        let mut bad = h.clone();
        bad.space_origin = Some(vec![0.0; 3]);
        assert!(encode(&bad, &d).is_err());
        assert!(check_data_file_name("x%03d.raw").is_err());
        assert!(check_data_file_name("LIST").is_err());
        assert!(check_data_file_name("x.raw").is_ok());
    }
}
