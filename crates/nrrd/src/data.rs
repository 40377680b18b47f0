//! Reading the data: which files, line and byte skips, then either a mapping of the
//! data's bytes (raw, native byte order, one file) or the encoding's decoder feeding
//! an [`ElementSink`].

use std::fs::File;
use std::io::{self, BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use super::codec::{AsciiReader, ElementSink, HexReader, ReadError};
use super::{DataFile, Encoding, Endian, NrrdHeader};
use crate::error::check_size;
use crate::file::{self, is_native_order};
use crate::{Data, Error, ReadReason, Reader, Storage};

/// A printf-style integer conversion in a data file name format (`slice%03d.raw`).
#[derive(Debug, PartialEq)]
pub(super) struct NumberFormat<'a> {
    prefix: &'a str,
    suffix: &'a str,
    left: bool,
    zero: bool,
    plus: bool,
    space: bool,
    width: usize,
}

/// Undoes `%%` in the literal parts of a format.
fn percent_literal(s: &str) -> String {
    s.replace("%%", "%")
}

impl<'a> NumberFormat<'a> {
    /// `Ok(None)` when `fmt` has no conversion (a plain file name); an error when it has
    /// a conversion other than one `%d`/`%i`/`%u` with flags and width.
    pub fn parse(fmt: &'a str) -> Result<Option<NumberFormat<'a>>, String> {
        let bytes = fmt.as_bytes();
        let mut i = 0;
        let mut found: Option<NumberFormat> = None;
        while i < bytes.len() {
            if bytes[i] != b'%' {
                i += 1;
                continue;
            }
            if bytes.get(i + 1) == Some(&b'%') {
                i += 2;
                continue;
            }
            let start = i;
            i += 1;
            let mut f = NumberFormat {
                prefix: &fmt[..start],
                suffix: "",
                left: false,
                zero: false,
                plus: false,
                space: false,
                width: 0,
            };
            while let Some(&c) = bytes.get(i) {
                match c {
                    b'-' => f.left = true,
                    b'0' => f.zero = true,
                    b'+' => f.plus = true,
                    b' ' => f.space = true,
                    _ => break,
                }
                i += 1;
            }
            let digits = bytes[i..].iter().take_while(|c| c.is_ascii_digit()).count();
            f.width = fmt[i..i + digits].parse().unwrap_or(0).min(64);
            i += digits;
            if !matches!(bytes.get(i), Some(b'd' | b'i' | b'u')) {
                return Err(format!(
                    "data file format {fmt:?}: only one integer conversion like %d or %03d is supported"
                ));
            }
            if found.is_some() {
                return Err(format!(
                    "data file format {fmt:?} has more than one % conversion"
                ));
            }
            i += 1;
            f.suffix = &fmt[i..];
            found = Some(f);
        }
        Ok(found)
    }

    /// The file name for number `n`.
    pub fn format(&self, n: i64) -> String {
        let sign = if n < 0 {
            "-"
        } else if self.plus {
            "+"
        } else if self.space {
            " "
        } else {
            ""
        };
        let digits = n.unsigned_abs().to_string();
        let len = sign.len() + digits.len();
        let pad = self.width.saturating_sub(len);
        let number = if self.left {
            format!("{sign}{digits}{}", " ".repeat(pad))
        } else if self.zero {
            format!("{sign}{}{digits}", "0".repeat(pad))
        } else {
            format!("{}{sign}{digits}", " ".repeat(pad))
        };
        format!(
            "{}{number}{}",
            percent_literal(self.prefix),
            percent_literal(self.suffix)
        )
    }
}

/// Number of files of a `%d` pattern (the range was checked by the parser).
pub(super) fn pattern_count(min: i64, max: i64, step: i64) -> u128 {
    ((max as i128 - min as i128) / step as i128) as u128 + 1
}

/// Number of data files the header names.
pub(super) fn file_count(data_file: &DataFile) -> u128 {
    match data_file {
        DataFile::Attached | DataFile::Single(_) => 1,
        DataFile::Pattern { min, max, step, .. } => pattern_count(*min, *max, *step),
        DataFile::List { names, .. } => names.len() as u128,
    }
}

/// A name from the header resolved against the header's folder.
fn resolve(header_path: &Path, name: &str) -> PathBuf {
    let p = Path::new(name);
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        header_path.parent().unwrap_or(Path::new("")).join(p)
    }
}

/// The `index`-th data file and where its data section starts before the skips.
fn data_file(
    header_path: &Path,
    h: &NrrdHeader,
    data_offset: Option<u64>,
    index: usize,
) -> (PathBuf, u64) {
    match &h.data_file {
        DataFile::Attached => (header_path.to_path_buf(), data_offset.unwrap_or(0)),
        DataFile::Single(name) => (resolve(header_path, name), 0),
        DataFile::List { names, .. } => (resolve(header_path, &names[index]), 0),
        DataFile::Pattern {
            format, min, step, ..
        } => {
            // The format was validated by the parser.
            let name = match NumberFormat::parse(format) {
                Ok(Some(f)) => f.format(min.saturating_add((index as i64).saturating_mul(*step))),
                _ => format.clone(),
            };
            (resolve(header_path, &name), 0)
        }
    }
}

/// How [`read_data`] will hold the data of a checked header: mapped (raw encoding in
/// native byte order, in one file) or read, and why.
pub(super) fn storage_kind(h: &NrrdHeader) -> Result<(), ReadReason> {
    if h.encoding != Encoding::Raw {
        return Err(ReadReason::Encoding(h.encoding));
    }
    if !matches!(h.data_file, DataFile::Attached | DataFile::Single(_)) {
        return Err(ReadReason::DataFiles(
            u64::try_from(file_count(&h.data_file)).unwrap_or(u64::MAX),
        ));
    }
    if !is_native_order(h.scalar_type, h.endian == Endian::Little) {
        return Err(ReadReason::ByteOrder);
    }
    Ok(())
}

/// Bytes of data a checked header declares (overflow checked, no limit).
fn data_bytes(header_path: &Path, h: &NrrdHeader) -> Result<u64, Error> {
    let (_, bytes) = check_size(&h.sizes, h.scalar_type.size(), u64::MAX)
        .map_err(|e| with_path(header_path, e))?;
    Ok(bytes as u64)
}

/// Names the header in a [`Error::TooLarge`].
fn with_path(header_path: &Path, e: Error) -> Error {
    match e {
        Error::TooLarge { what, bytes, limit } => Error::TooLarge {
            what: format!("{}: {what}", header_path.display()),
            bytes,
            limit,
        },
        other => other,
    }
}

/// The single piece of a mappable header.
fn single_piece<'a>(
    reader: &'a Reader,
    header_path: &'a Path,
    h: &'a NrrdHeader,
    path: &'a Path,
) -> Piece<'a> {
    Piece {
        reader,
        header: h,
        header_path,
        path,
        index: 0,
        files: 1,
        elements: h.element_count().unwrap_or(0),
    }
}

/// Where the data of a checked header will be: mapped from a file, or read.
pub(super) fn storage(
    reader: &Reader,
    header_path: &Path,
    h: &NrrdHeader,
    data_offset: Option<u64>,
) -> Result<Storage, Error> {
    let bytes = data_bytes(header_path, h)?;
    if let Err(reason) = storage_kind(h) {
        return Ok(Storage::Read { bytes, reason });
    }
    let (path, start) = data_file(header_path, h, data_offset, 0);
    let (_, offset) = single_piece(reader, header_path, h, &path).locate_raw(start)?;
    Ok(Storage::Mapped {
        path,
        offset,
        bytes,
    })
}

/// Reads all the data of a checked header, or maps it (raw encoding in native byte
/// order, in one file: not counted against the reader's byte limit).
pub(super) fn read_data(
    reader: &Reader,
    header_path: &Path,
    h: &NrrdHeader,
    data_offset: Option<u64>,
    hash: bool,
) -> Result<(Data, Option<u128>), Error> {
    if storage_kind(h).is_ok() {
        let bytes = data_bytes(header_path, h)?;
        let (path, start) = data_file(header_path, h, data_offset, 0);
        let (file, offset) = single_piece(reader, header_path, h, &path).locate_raw(start)?;
        let m = file::map(&file, &path, h.scalar_type, offset, bytes)?;
        let digest = hash.then(|| xxhash_rust::xxh3::xxh3_128(m.bytes()));
        return Ok((Data::Mapped(m), digest));
    }
    let elem = h.scalar_type.size();
    let (count, _) =
        check_size(&h.sizes, elem, reader.max_bytes).map_err(|e| with_path(header_path, e))?;
    // check_header made sure the count divides evenly and is at most `count`.
    let files = usize::try_from(file_count(&h.data_file))
        .unwrap_or(usize::MAX)
        .max(1);
    let per_file = count / files;
    let le = h.endian == Endian::Little || !h.encoding.endian_matters();
    let mut sink = ElementSink::new(h.scalar_type, count, le);
    if hash {
        sink = sink.hashing();
    }
    for index in 0..files {
        let (path, start) = data_file(header_path, h, data_offset, index);
        let piece = Piece {
            reader,
            header: h,
            header_path,
            path: &path,
            index,
            files,
            elements: per_file,
        };
        piece.read(start, &mut sink)?;
    }
    let digest = sink.hash();
    Ok((sink.finish(), digest))
}

/// Every file the data of a checked header is read from (the header's own file for
/// attached data), in order.
pub(super) fn data_files(
    header_path: &Path,
    h: &NrrdHeader,
    data_offset: Option<u64>,
) -> Vec<PathBuf> {
    let files = usize::try_from(file_count(&h.data_file))
        .unwrap_or(usize::MAX)
        .max(1);
    (0..files)
        .map(|i| data_file(header_path, h, data_offset, i).0)
        .collect()
}

/// One data file's share of the elements.
struct Piece<'a> {
    reader: &'a Reader,
    header: &'a NrrdHeader,
    header_path: &'a Path,
    path: &'a Path,
    index: usize,
    files: usize,
    elements: usize,
}

impl Piece<'_> {
    fn bytes(&self) -> u64 {
        self.elements as u64 * self.header.scalar_type.size() as u64
    }

    /// "(data file 3 of 93 of x.nhdr)" for detached data, "" for attached data.
    fn context(&self) -> String {
        match self.header.data_file {
            DataFile::Attached => String::new(),
            _ => format!(
                " (data file {} of {} named by {})",
                self.index + 1,
                self.files,
                self.header_path.display()
            ),
        }
    }

    fn error(&self, message: impl std::fmt::Display) -> Error {
        Error::Data {
            path: self.path.to_path_buf(),
            message: format!("{message}{}", self.context()),
        }
    }

    fn io_error(&self, source: io::Error) -> Error {
        Error::Io {
            path: self.path.to_path_buf(),
            source,
        }
    }

    /// Opens the data file without blocking and refuses anything but a regular file;
    /// returns it with its length.
    fn open(&self) -> Result<(File, u64), Error> {
        let file = self
            .reader
            .open(self.path)
            .map_err(|e| match self.header.data_file {
                DataFile::Attached => self.io_error(e),
                _ => self.error(format_args!("cannot open data file: {e}")),
            })?;
        let meta = file.metadata().map_err(|e| self.io_error(e))?;
        file::check_regular(self.path, &meta, "volume data").map_err(|e| match e {
            Error::Unsupported { path, message } => Error::Unsupported {
                path,
                message: format!("{message}{}", self.context()),
            },
            other => other,
        })?;
        Ok((file, meta.len()))
    }

    /// `line skip` and `byte skip` that go beyond the file are errors at once, before
    /// anything is read (`available`: bytes from where the data section starts).
    fn check_skips(&self, available: u64) -> Result<(), Error> {
        let h = self.header;
        let lines = h.line_skip as u64;
        if lines > available {
            return Err(self.error(format_args!(
                "`line skip: {}` skips more lines than the file has bytes ({available} from where the data starts): the file cannot hold them",
                h.line_skip
            )));
        }
        let Ok(bytes) = u64::try_from(h.byte_skip) else {
            return Ok(()); // -1: checked against the data's length by position_raw
        };
        let after_lines = available - lines;
        let (limit, what) = match h.encoding {
            // DEFLATE expands by at most 1032:1
            Encoding::Gzip => (
                after_lines.saturating_mul(1032),
                "the decompressed gzip data (at most 1032 times its compressed size)",
            ),
            // bzip2 can expand far more; its stream length bounds the skip as it is read
            Encoding::Bzip2 => (u64::MAX, ""),
            Encoding::Raw | Encoding::Ascii | Encoding::Hex => (after_lines, "the file"),
        };
        if bytes > limit {
            return Err(self.error(format_args!(
                "`byte skip: {bytes}` goes beyond the end of {what}: {after_lines} bytes are left after {} of line skip",
                h.line_skip
            )));
        }
        Ok(())
    }

    fn read(&self, start: u64, sink: &mut ElementSink) -> Result<(), Error> {
        let (file, file_len) = self.open()?;
        self.check_skips(file_len.saturating_sub(start))?;
        let mut r = BufReader::new(file);
        r.seek(SeekFrom::Start(start))
            .map_err(|e| self.io_error(e))?;
        self.skip_lines(&mut r)?;
        let h = self.header;
        match h.encoding {
            Encoding::Raw => {
                self.position_raw(&mut r, file_len)?;
                self.decode(&mut r, sink, "raw")
            }
            Encoding::Gzip => {
                let mut d = flate2::bufread::MultiGzDecoder::new(r);
                self.skip_bytes(&mut d, "gzip data")?;
                self.decode(&mut d, sink, "gzip")?;
                self.probe_end(&mut d, "gzip")
            }
            Encoding::Bzip2 => {
                let mut d = bzip2::bufread::MultiBzDecoder::new(r);
                self.skip_bytes(&mut d, "bzip2 data")?;
                self.decode(&mut d, sink, "bzip2")?;
                self.probe_end(&mut d, "bzip2")
            }
            Encoding::Hex => {
                self.skip_bytes(&mut r, "file")?;
                let mut d = HexReader::new(r);
                self.decode(&mut d, sink, "hex")?;
                self.probe_end(&mut d, "hex")
            }
            Encoding::Ascii => {
                self.skip_bytes(&mut r, "file")?;
                let mut d = AsciiReader::new(r, h.scalar_type);
                self.decode(&mut d, sink, "ascii")?;
                self.probe_end(&mut d, "ascii")
            }
        }
    }

    /// Raw data to be mapped: opens the file without blocking, refuses anything but a
    /// regular file, applies `line skip` and `byte skip` as [`Piece::read`] does (same
    /// errors for data that is too short), and returns the file and where the data
    /// starts.
    fn locate_raw(&self, start: u64) -> Result<(File, u64), Error> {
        let (file, file_len) = self.open()?;
        self.check_skips(file_len.saturating_sub(start))?;
        let mut r = BufReader::new(file);
        r.seek(SeekFrom::Start(start))
            .map_err(|e| self.io_error(e))?;
        self.skip_lines(&mut r)?;
        self.position_raw(&mut r, file_len)?;
        let offset = r.stream_position().map_err(|e| self.io_error(e))?;
        Ok((r.into_inner(), offset))
    }

    /// `line skip`: whole lines of the file as stored, without buffering them.
    fn skip_lines(&self, r: &mut impl BufRead) -> Result<(), Error> {
        for done in 0..self.header.line_skip {
            loop {
                let buf = r.fill_buf().map_err(|e| self.io_error(e))?;
                if buf.is_empty() {
                    return Err(self.error(format_args!(
                        "file ends after {done} of the {} lines that `line skip` skips",
                        self.header.line_skip
                    )));
                }
                match buf.iter().position(|&b| b == b'\n') {
                    Some(i) => {
                        r.consume(i + 1);
                        break;
                    }
                    None => {
                        let n = buf.len();
                        r.consume(n);
                    }
                }
            }
        }
        Ok(())
    }

    /// `byte skip` (≥ 0) on a stream, reading and discarding.
    fn skip_bytes(&self, r: &mut impl Read, what: &str) -> Result<(), Error> {
        let want = u64::try_from(self.header.byte_skip).unwrap_or(0);
        let got = io::copy(&mut r.take(want), &mut io::sink())
            .map_err(|e| self.error(format_args!("{what}: {e}")))?;
        if got < want {
            return Err(self.error(format_args!(
                "{what} ends after {got} of the {want} bytes that `byte skip` skips"
            )));
        }
        Ok(())
    }

    /// Raw data: apply the byte skip (-1 = last bytes) and check the length first, so
    /// a hostile header costs nothing.
    fn position_raw(&self, r: &mut BufReader<File>, file_len: u64) -> Result<(), Error> {
        let need = self.bytes();
        if self.header.byte_skip < 0 {
            if file_len < need {
                return Err(self.error(format_args!(
                    "data shorter than declared: `byte skip: -1` takes the last {need} bytes (sizes × type), but the file has only {file_len}"
                )));
            }
            r.seek(SeekFrom::Start(file_len - need))
                .map_err(|e| self.io_error(e))?;
            return Ok(());
        }
        let skip = self.header.byte_skip as u64;
        let pos = r.stream_position().map_err(|e| self.io_error(e))?;
        let available = file_len.saturating_sub(pos);
        if available < skip.saturating_add(need) {
            return Err(self.error(format_args!(
                "data shorter than declared: expected {need} bytes (sizes × type){}, got {}",
                if skip > 0 {
                    format!(" after a byte skip of {skip}")
                } else {
                    String::new()
                },
                available.saturating_sub(skip)
            )));
        }
        r.seek_relative(skip as i64).map_err(|e| self.io_error(e))
    }

    fn decode(&self, r: &mut impl Read, sink: &mut ElementSink, what: &str) -> Result<(), Error> {
        let elem = self.header.scalar_type.size() as u64;
        sink.read(r, self.elements).map_err(|e| match e {
            ReadError::Short { bytes } if what == "ascii" => self.error(format_args!(
                "ascii data has {} values, but sizes declare {}",
                bytes / elem,
                self.elements
            )),
            ReadError::Short { bytes } => self.error(format_args!(
                "data shorter than declared: expected {} bytes (sizes × type) of {what} data, got {bytes}",
                self.bytes()
            )),
            ReadError::Io(e) if e.kind() == io::ErrorKind::InvalidData && matches!(what, "ascii" | "hex") => {
                self.error(e)
            }
            ReadError::Io(e) if e.kind() == io::ErrorKind::InvalidData || e.kind() == io::ErrorKind::InvalidInput => {
                self.error(format_args!("{what} data is corrupt: {e}"))
            }
            ReadError::Io(e) if matches!(what, "gzip" | "bzip2") => self.error(format_args!(
                "{what} data is corrupt or truncated: {e} (while decoding the {} bytes that sizes × type declare)",
                self.bytes()
            )),
            ReadError::Io(e) => self.io_error(e),
            ReadError::Memory { bytes } => Error::OutOfMemory {
                path: self.path.to_path_buf(),
                bytes,
            },
        })
    }

    /// After the declared elements, one more byte means the data is longer than declared.
    fn probe_end(&self, r: &mut impl Read, what: &str) -> Result<(), Error> {
        let mut one = [0u8; 1];
        let more = loop {
            match r.read(&mut one) {
                Ok(n) => break n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) if matches!(what, "ascii" | "hex") => return Err(self.error(e)),
                Err(e) => {
                    return Err(self.error(format_args!(
                        "{what} data is corrupt after the {} declared bytes: {e}",
                        self.bytes()
                    )))
                }
            }
        };
        if more == 0 {
            return Ok(());
        }
        Err(match what {
            "ascii" => self.error(format_args!(
                "ascii data has more than the {} values that sizes declare",
                self.elements
            )),
            _ => self.error(format_args!(
                "{what} data continues past the {} bytes that sizes × type declare",
                self.bytes()
            )),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn printf_formats() {
        let f = NumberFormat::parse("slice%03d.raw").unwrap().unwrap();
        assert_eq!(f.format(7), "slice007.raw");
        assert_eq!(f.format(1234), "slice1234.raw");
        assert_eq!(f.format(-7), "slice-07.raw");
        let f = NumberFormat::parse("a%%b%d").unwrap().unwrap();
        assert_eq!(f.format(5), "a%b5");
        let f = NumberFormat::parse("x%-4d.").unwrap().unwrap();
        assert_eq!(f.format(5), "x5   .");
        let f = NumberFormat::parse("x%4u").unwrap().unwrap();
        assert_eq!(f.format(5), "x   5");
        assert_eq!(NumberFormat::parse("plain.raw").unwrap(), None);
        assert_eq!(NumberFormat::parse("100%%.raw").unwrap(), None);
        assert!(NumberFormat::parse("a%s").is_err());
        assert!(NumberFormat::parse("a%d%d").is_err());
    }

    #[test]
    fn counts() {
        assert_eq!(pattern_count(1, 93, 1), 93);
        assert_eq!(pattern_count(10, 0, -5), 3);
        assert_eq!(pattern_count(0, 9, 4), 3);
        assert_eq!(pattern_count(i64::MIN, i64::MAX, 1), 1u128 << 64);
    }
}
