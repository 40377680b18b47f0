//! Reading the header text: magic, field lines, comments, `key:=value` pairs, the file
//! names of a `data file: LIST`, and where attached data starts.

use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use super::fields::{self, field_index, FieldLine, RawHeader};
use super::{check, DataFile, NrrdHeader};
use crate::{file, Error, Reader};

/// Longest header line accepted (a hostile file cannot make us buffer more).
const MAX_LINE: u64 = 1 << 20;
/// Largest header accepted, in bytes.
const MAX_HEADER: u64 = 64 << 20;

/// Reads, parses and checks the header of `path`; also returns where attached data
/// starts (`None` for detached data).
pub(super) fn load_header(
    reader: &Reader,
    path: &Path,
) -> Result<(NrrdHeader, Option<u64>), Error> {
    let io_err = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = reader.open(path).map_err(io_err)?;
    let meta = file.metadata().map_err(io_err)?;
    file::check_regular(path, &meta, "a NRRD header")?;
    let raw = read_raw_header(path, &mut BufReader::new(file))?;
    let parsed = fields::parse_fields(path, &raw)?;
    check::check_header(path, &parsed)?;
    let offset = match parsed.header.data_file {
        DataFile::Attached => Some(raw.data_offset.ok_or_else(|| {
            Error::Header {
                path: path.to_path_buf(),
                line: 0,
                message: "the header ends at the end of the file, without the blank line that \
                      precedes attached data, and there is no `data file` field"
                    .into(),
            }
        })?),
        _ => None,
    };
    Ok((parsed.header, offset))
}

fn header_error(path: &Path, line: usize, message: impl Into<String>) -> Error {
    Error::Header {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

/// Reads one line of at most [`MAX_LINE`] bytes; returns the bytes consumed (0 at end
/// of file) and leaves the line, without `\n` or `\r\n`, in `buf`.
fn next_line(
    path: &Path,
    line: usize,
    reader: &mut impl BufRead,
    buf: &mut Vec<u8>,
) -> Result<u64, Error> {
    buf.clear();
    let n = reader
        .take(MAX_LINE + 1)
        .read_until(b'\n', buf)
        .map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })? as u64;
    if n > MAX_LINE {
        return Err(header_error(
            path,
            line,
            format!("line is longer than {MAX_LINE} bytes: not a NRRD header line (is the blank line between header and data missing?)"),
        ));
    }
    if buf.last() == Some(&b'\n') {
        buf.pop();
        if buf.last() == Some(&b'\r') {
            buf.pop();
        }
    }
    Ok(n)
}

/// Checks the magic line and returns the format version.
fn parse_magic(path: &Path, bytes: &[u8]) -> Result<u8, Error> {
    let shown = String::from_utf8_lossy(&bytes[..bytes.len().min(40)]).into_owned();
    match bytes {
        [b'N', b'R', b'R', b'D', b'0', b'0', b'0', v @ b'1'..=b'5'] => Ok(v - b'0'),
        [b'N', b'R', b'R', b'D', ..] => Err(Error::Unsupported {
            path: path.to_path_buf(),
            message: format!(
                "line 1: magic {shown:?} is not a supported NRRD version (expected NRRD0001 to NRRD0005)"
            ),
        }),
        _ => Err(header_error(
            path,
            1,
            format!("not a NRRD file: expected the magic NRRD0001 to NRRD0005, got {shown:?}"),
        )),
    }
}

/// What a non-blank, non-comment header line is.
enum LineKind<'a> {
    Field(usize, &'a str),
    KeyValue(&'a str, &'a str),
}

/// Teem's rule: a known field name before the first `: ` makes a field; otherwise a
/// `:=` makes a key/value pair; anything else is an error.
fn classify(text: &str) -> Result<LineKind<'_>, String> {
    let field = text
        .split_once(": ")
        .or_else(|| text.strip_suffix(':').map(|name| (name, "")));
    if let Some((name, desc)) = field {
        if let Some(index) = field_index(name) {
            return Ok(LineKind::Field(index, desc.trim()));
        }
    }
    if let Some((key, value)) = text.split_once(":=") {
        if key.is_empty() {
            return Err(format!("key/value line {text:?} has an empty key"));
        }
        return Ok(LineKind::KeyValue(key, value));
    }
    match field {
        Some((name, _)) => Err(format!(
            "unknown field {name:?} in {text:?} (not a NRRD field; key/value pairs are written `key:=value`)"
        )),
        None => Err(format!(
            "expected `<field>: <value>`, `<key>:=<value>` or a `#` comment, got {text:?}"
        )),
    }
}

/// Undoes the key/value escapes of the spec: `\n` → newline, `\\` → `\`.
pub(super) fn unescape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut chars = s.chars();
    while let Some(c) = chars.next() {
        if c != '\\' {
            out.push(c);
            continue;
        }
        match chars.next() {
            Some('n') => out.push('\n'),
            Some('\\') => out.push('\\'),
            Some(other) => {
                out.push('\\');
                out.push(other);
            }
            None => out.push('\\'),
        }
    }
    out
}

/// True for `LIST` or `LIST <subdim>` (not for a file that happens to start with LIST).
fn is_list(desc: &str) -> bool {
    desc.strip_prefix("LIST")
        .is_some_and(|rest| rest.is_empty() || rest.starts_with(char::is_whitespace))
}

/// Reads the header lines up to the blank line (attached data), the end of the file,
/// or the end of a `data file: LIST` name list.
pub(super) fn read_raw_header(path: &Path, reader: &mut impl BufRead) -> Result<RawHeader, Error> {
    let mut buf = Vec::new();
    let mut consumed = next_line(path, 1, reader, &mut buf)?;
    if consumed == 0 {
        return Err(header_error(
            path,
            1,
            "empty file: expected the magic NRRD0001 to NRRD0005",
        ));
    }
    let mut raw = RawHeader {
        version: parse_magic(path, &buf)?,
        ..RawHeader::default()
    };
    let mut line = 1;
    loop {
        line += 1;
        let n = next_line(path, line, reader, &mut buf)?;
        if n == 0 {
            return Ok(raw);
        }
        consumed += n;
        if consumed > MAX_HEADER {
            return Err(header_error(
                path,
                line,
                format!("header is longer than {MAX_HEADER} bytes"),
            ));
        }
        let text = std::str::from_utf8(&buf).map_err(|_| {
            header_error(
                path,
                line,
                "line is not UTF-8 text (binary data inside the header? the blank line between header and data may be missing)",
            )
        })?;
        if text.is_empty() {
            raw.data_offset = Some(consumed);
            return Ok(raw);
        }
        if let Some(comment) = text.strip_prefix('#') {
            raw.comments.push(
                comment
                    .trim_start_matches([' ', '#', '\t'])
                    .trim_end()
                    .to_string(),
            );
            continue;
        }
        match classify(text).map_err(|m| header_error(path, line, m))? {
            LineKind::KeyValue(k, v) => raw.key_values.push((line, unescape(k), unescape(v))),
            LineKind::Field(field, desc) => {
                let list = field == fields::DATA_FILE && is_list(desc);
                raw.fields.push(FieldLine {
                    line,
                    field,
                    desc: desc.to_string(),
                });
                if list {
                    read_list_names(path, reader, line, consumed, &mut raw)?;
                    return Ok(raw);
                }
            }
        }
    }
}

/// The file names after `data file: LIST`, one per line, up to a blank line or the end.
fn read_list_names(
    path: &Path,
    reader: &mut impl BufRead,
    mut line: usize,
    mut consumed: u64,
    raw: &mut RawHeader,
) -> Result<(), Error> {
    let mut buf = Vec::new();
    loop {
        line += 1;
        let n = next_line(path, line, reader, &mut buf)?;
        consumed += n;
        if n == 0 || buf.is_empty() {
            return Ok(());
        }
        if consumed > MAX_HEADER {
            return Err(header_error(
                path,
                line,
                format!("header is longer than {MAX_HEADER} bytes"),
            ));
        }
        let name = std::str::from_utf8(&buf)
            .map_err(|_| header_error(path, line, "data file name is not UTF-8 text"))?;
        raw.list_names.push((line, name.trim().to_string()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raw(text: &[u8]) -> Result<RawHeader, Error> {
        read_raw_header(Path::new("t.nrrd"), &mut &text[..])
    }

    #[test]
    fn magic_versions() {
        for v in 1..=5u8 {
            let text = format!("NRRD000{v}\n\n");
            assert_eq!(raw(text.as_bytes()).unwrap().version, v);
        }
        let e = raw(b"NRRD0009\n\n").unwrap_err().to_string();
        assert!(e.contains("NRRD0009"), "{e}");
        let e = raw(b"P5\n").unwrap_err().to_string();
        assert!(e.contains("t.nrrd:1: not a NRRD file"), "{e}");
        assert!(raw(b"").is_err());
    }

    #[test]
    fn lines_comments_key_values_and_offset() {
        let r =
            raw(b"NRRD0004\r\n# hello # world\ntype: uchar\nk\\\\ey:=a\\nb:=c\n\nDATA").unwrap();
        assert_eq!(r.comments, vec!["hello # world"]);
        assert_eq!(r.fields.len(), 1);
        assert_eq!(r.fields[0].line, 3);
        assert_eq!(r.fields[0].desc, "uchar");
        assert_eq!(
            r.key_values,
            vec![(4, "k\\ey".to_string(), "a\nb:=c".to_string())]
        );
        assert_eq!(r.data_offset, Some(54));
    }

    #[test]
    fn classify_rules() {
        assert!(matches!(
            classify("Space Directions: none"),
            Ok(LineKind::Field(_, "none"))
        ));
        assert!(matches!(
            classify("datafile: x.raw"),
            Ok(LineKind::Field(..))
        ));
        assert!(matches!(
            classify("my key: x:=y"),
            Ok(LineKind::KeyValue("my key: x", "y"))
        ));
        let e = classify("colour: red").err().unwrap();
        assert!(e.contains("unknown field \"colour\""), "{e}");
        assert!(classify("garbage").is_err());
        assert!(classify(":=x").is_err());
    }

    #[test]
    fn list_names_end_the_header() {
        let r = raw(b"NRRD0004\ndata file: LIST 2\na.raw\n b.raw \n\nignored").unwrap();
        assert_eq!(r.list_names, vec![(3, "a.raw".into()), (4, "b.raw".into())]);
        assert!(r.data_offset.is_none());
        assert!(!is_list("LISTING.raw"));
    }

    #[test]
    fn binary_inside_header_is_an_error() {
        let e = raw(b"NRRD0004\ntype: uchar\n\xff\xfe\x00\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.nrrd:3"), "{e}");
    }
}
