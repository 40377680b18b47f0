//! A pass over a DICOM file's elements before the `dicom` crate reads it: the crate
//! allocates each value from its declared length (up to 4 GiB) before reading it, so
//! every declared length is checked here against the bytes left in the file first.
//! Also reads the transfer syntax from the file meta group, so that compressed data is
//! refused by name before it is parsed.

use std::io::{self, BufRead, BufReader, Read};
use std::path::Path;

use crate::volume::mapped::open_regular;
use crate::volume::VolumeError;

/// The value representations of the standard (PS3.5 6.2).
const KNOWN_VRS: [&[u8; 2]; 34] = [
    b"AE", b"AS", b"AT", b"CS", b"DA", b"DS", b"DT", b"FL", b"FD", b"IS", b"LO", b"LT", b"OB",
    b"OD", b"OF", b"OL", b"OV", b"OW", b"PN", b"SH", b"SL", b"SQ", b"SS", b"ST", b"SV", b"TM",
    b"UC", b"UI", b"UL", b"UN", b"UR", b"US", b"UT", b"UV",
];

/// Deepest nesting of sequences accepted.
const MAX_DEPTH: usize = 32;

/// What the scan found.
#[derive(Debug)]
pub(super) struct Scanned {
    /// The transfer syntax UID (trailing NUL and spaces removed).
    pub transfer_syntax: String,
    /// The media storage SOP class UID of the file meta group, if any.
    pub sop_class: Option<String>,
}

/// `None` when the file is not a DICOM Part 10 file (no `DICM` at byte 128).
pub(super) fn scan(path: &Path) -> Result<Option<Scanned>, VolumeError> {
    let (file, meta) = open_regular(path, "a DICOM file")?;
    let len = meta.len();
    let mut r = Walker {
        r: BufReader::new(file),
        pos: 0,
        len,
        path,
    };
    let mut head = [0u8; 132];
    if len < 132 || r.read_exact(&mut head).is_err() || &head[128..] != b"DICM" {
        return Ok(None);
    }
    // the file meta group: explicit VR little endian, group 0002
    let mut ts = None;
    let mut sop_class = None;
    loop {
        let peek = r.peek2()?;
        if peek != Some(2) {
            break;
        }
        let ElementHeader { tag, length, .. } = r.element_header_vr(true, true)?;
        let Some(length) = length else {
            return Err(r.error(format!(
                "file meta element {} has an undefined length",
                show(tag)
            )));
        };
        r.check_length(tag, length)?;
        if tag == (0x0002, 0x0010) || tag == (0x0002, 0x0002) {
            let mut v = vec![0u8; length as usize];
            r.read_exact(&mut v)?;
            let s = String::from_utf8_lossy(&v)
                .trim_end_matches(['\0', ' '])
                .to_string();
            if tag.1 == 0x0010 {
                ts = Some(s);
            } else {
                sop_class = Some(s);
            }
        } else {
            r.skip(length as u64)?;
        }
    }
    let Some(transfer_syntax) = ts else {
        return Err(r.error("the file meta group has no transfer syntax (0002,0010)".into()));
    };
    let (explicit, little) = match transfer_syntax.as_str() {
        "1.2.840.10008.1.2" => (false, true),
        "1.2.840.10008.1.2.1" => (true, true),
        // any other syntax is refused by name before the crate reads the data set
        // (which may be deflated, so not walkable here)
        _ => {
            return Ok(Some(Scanned {
                transfer_syntax,
                sop_class,
            }))
        }
    };
    // the data set: only the lengths matter
    r.walk(explicit, little, 0, None)?;
    Ok(Some(Scanned {
        transfer_syntax,
        sop_class,
    }))
}

fn io_error(path: &Path, pos: u64, e: io::Error) -> VolumeError {
    if e.kind() == io::ErrorKind::UnexpectedEof {
        return VolumeError::Data {
            path: path.to_path_buf(),
            message: format!("the file ends inside an element header at byte {pos}"),
        };
    }
    VolumeError::Io {
        path: path.to_path_buf(),
        source: e,
    }
}

fn show(tag: (u16, u16)) -> String {
    format!("({:04X},{:04X})", tag.0, tag.1)
}

/// An element's tag, length (`None` = undefined) and whether its VR is SQ.
struct ElementHeader {
    tag: (u16, u16),
    length: Option<u32>,
    sq: bool,
}

struct Walker<'a> {
    r: BufReader<std::fs::File>,
    pos: u64,
    len: u64,
    path: &'a Path,
}

impl Walker<'_> {
    fn error(&self, message: String) -> VolumeError {
        VolumeError::Data {
            path: self.path.to_path_buf(),
            message,
        }
    }

    fn io(&self, e: io::Error) -> VolumeError {
        io_error(self.path, self.pos, e)
    }

    /// The buffered bytes ahead (empty at the end of the file).
    fn fill(&mut self) -> Result<&[u8], VolumeError> {
        let (path, pos) = (self.path, self.pos);
        self.r.fill_buf().map_err(move |e| io_error(path, pos, e))
    }

    fn read_exact(&mut self, buf: &mut [u8]) -> Result<(), VolumeError> {
        self.r.read_exact(buf).map_err(|e| self.io(e))?;
        self.pos += buf.len() as u64;
        Ok(())
    }

    fn skip(&mut self, n: u64) -> Result<(), VolumeError> {
        let got = io::copy(&mut (&mut self.r).take(n), &mut io::sink()).map_err(|e| self.io(e))?;
        self.pos += got;
        if got < n {
            return Err(self.error(format!("the file ends at byte {}", self.pos)));
        }
        Ok(())
    }

    /// The group of the next element (little-endian), `None` at the end of the file.
    fn peek2(&mut self) -> Result<Option<u16>, VolumeError> {
        let buf = self.fill()?;
        Ok(match buf {
            [] => None,
            [a, b, ..] => Some(u16::from_le_bytes([*a, *b])),
            [_] => Some(u16::MAX),
        })
    }

    fn at_end(&mut self) -> Result<bool, VolumeError> {
        Ok(self.fill()?.is_empty())
    }

    /// The header of the next element: its tag, length (`None` = undefined) and
    /// whether its VR is SQ (explicit VR only).
    fn element_header_vr(
        &mut self,
        explicit: bool,
        little: bool,
    ) -> Result<ElementHeader, VolumeError> {
        let u16_of = |b: [u8; 2]| {
            if little {
                u16::from_le_bytes(b)
            } else {
                u16::from_be_bytes(b)
            }
        };
        let u32_of = |b: [u8; 4]| {
            if little {
                u32::from_le_bytes(b)
            } else {
                u32::from_be_bytes(b)
            }
        };
        let mut t = [0u8; 4];
        self.read_exact(&mut t)?;
        let tag = (u16_of([t[0], t[1]]), u16_of([t[2], t[3]]));
        let mut l = [0u8; 4];
        // items and delimiters have no VR
        if tag.0 == 0xFFFE || !explicit {
            self.read_exact(&mut l)?;
            let n = u32_of(l);
            return Ok(ElementHeader {
                tag,
                length: (n != u32::MAX).then_some(n),
                sq: false,
            });
        }
        let mut vr = [0u8; 2];
        self.read_exact(&mut vr)?;
        if !KNOWN_VRS.contains(&&vr) {
            // a parser may read another length field for a VR it does not know
            return Err(self.error(format!(
                "element {} at byte {} has an unknown value representation {:?}",
                show(tag),
                self.pos - 6,
                String::from_utf8_lossy(&vr)
            )));
        }
        let long = matches!(
            &vr,
            b"OB"
                | b"OD"
                | b"OF"
                | b"OL"
                | b"OV"
                | b"OW"
                | b"SQ"
                | b"UC"
                | b"UN"
                | b"UR"
                | b"UT"
                | b"SV"
                | b"UV"
        );
        let n = if long {
            let mut skip = [0u8; 2];
            self.read_exact(&mut skip)?;
            self.read_exact(&mut l)?;
            u32_of(l)
        } else {
            let mut s = [0u8; 2];
            self.read_exact(&mut s)?;
            u32::from(u16_of(s))
        };
        Ok(ElementHeader {
            tag,
            length: (n != u32::MAX).then_some(n),
            sq: &vr == b"SQ",
        })
    }

    fn check_length(&self, tag: (u16, u16), length: u32) -> Result<(), VolumeError> {
        let left = self.len.saturating_sub(self.pos);
        if u64::from(length) > left {
            return Err(self.error(format!(
                "element {} at byte {} declares {length} bytes, but only {left} are left in the file",
                show(tag),
                self.pos
            )));
        }
        Ok(())
    }

    /// Walks elements until the end of the file, of a defined-length container (`end`),
    /// or of an undefined-length one (its delimiter).
    fn walk(
        &mut self,
        explicit: bool,
        little: bool,
        depth: usize,
        end: Option<u64>,
    ) -> Result<(), VolumeError> {
        if depth > MAX_DEPTH {
            return Err(self.error(format!(
                "sequences nested deeper than {MAX_DEPTH} levels at byte {}",
                self.pos
            )));
        }
        loop {
            if end.is_some_and(|e| self.pos >= e) || (end.is_none() && self.at_end()?) {
                if let Some(e) = end {
                    if self.pos > e {
                        return Err(self.error(format!(
                            "an element runs past the end of its item or sequence (byte {e})"
                        )));
                    }
                }
                return Ok(());
            }
            let ElementHeader { tag, length, sq } = self.element_header_vr(explicit, little)?;
            match (tag, length) {
                // item and sequence delimiters end an undefined-length container
                ((0xFFFE, 0xE00D), _) | ((0xFFFE, 0xE0DD), _) => {
                    if depth == 0 {
                        return Err(self.error(format!(
                            "a delimiter {} outside any sequence at byte {}",
                            show(tag),
                            self.pos
                        )));
                    }
                    return Ok(());
                }
                // an item (or a fragment of encapsulated pixel data): its elements
                ((0xFFFE, 0xE000), Some(n)) => {
                    self.check_length(tag, n)?;
                    let e = self.pos + u64::from(n);
                    if self.looks_like_elements(n)? {
                        self.walk(explicit, little, depth + 1, Some(e))?;
                    } else {
                        self.skip(u64::from(n))?;
                    }
                }
                (_, None) => self.walk(explicit, little, depth + 1, None)?,
                (_, Some(n)) => {
                    self.check_length(tag, n)?;
                    let e = self.pos + u64::from(n);
                    if sq || (!explicit && n >= 8 && self.next_is_item(little)?) {
                        self.walk(explicit, little, depth + 1, Some(e))?;
                    } else {
                        self.skip(u64::from(n))?;
                    }
                }
            }
        }
    }

    /// True when the next 4 bytes are an item tag (FFFE,E000).
    fn next_is_item(&mut self, little: bool) -> Result<bool, VolumeError> {
        let buf = self.fill()?;
        let item: [u8; 4] = if little {
            [0xFE, 0xFF, 0x00, 0xE0]
        } else {
            [0xFF, 0xFE, 0xE0, 0x00]
        };
        Ok(buf.len() >= 4 && buf[..4] == item)
    }

    /// An item holds elements unless it is a fragment of encapsulated pixel data:
    /// fragments are skipped as bytes (their length was checked).
    fn looks_like_elements(&mut self, n: u32) -> Result<bool, VolumeError> {
        Ok(n >= 8 && {
            let buf = self.fill()?;
            // an element starts with an even group below FFFE, or a small odd one
            buf.len() >= 4 && {
                let g = u16::from_le_bytes([buf[0], buf[1]]);
                g != 0 && g < 0x7FE1 && (g % 2 == 0 || g < 0x10)
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(body: &[u8]) -> (tempfile::TempDir, std::path::PathBuf) {
        file_with(b"1.2.840.10008.1.2.1\0", body)
    }

    fn file_with(ts: &[u8], body: &[u8]) -> (tempfile::TempDir, std::path::PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.dcm");
        let mut b = vec![0u8; 128];
        b.extend(b"DICM");
        // (0002,0010) UI, explicit VR LE
        b.extend([0x02, 0x00, 0x10, 0x00, b'U', b'I']);
        b.extend((ts.len() as u16).to_le_bytes());
        b.extend(ts);
        b.extend(body);
        std::fs::write(&p, b).unwrap();
        (dir, p)
    }

    #[test]
    fn declared_lengths_beyond_the_file_are_refused() {
        // (0028,0010) US 2 bytes: fine
        let (_d, p) = file(&[0x28, 0, 0x10, 0, b'U', b'S', 2, 0, 8, 0]);
        let s = scan(&p).unwrap().unwrap();
        assert_eq!(s.transfer_syntax, "1.2.840.10008.1.2.1");
        // (7FE0,0010) OW claiming 4 GiB - 2
        let (_d, p) = file(&[
            0xE0, 0x7F, 0x10, 0, b'O', b'W', 0, 0, 0xFE, 0xFF, 0xFF, 0xFF, 1, 2,
        ]);
        let e = scan(&p).unwrap_err().to_string();
        assert!(
            e.contains("(7FE0,0010)") && e.contains("declares 4294967294 bytes"),
            "{e}"
        );
        // a deflated data set is not walked: its syntax is refused by name later
        let (_d, p) = file_with(b"1.2.840.10008.1.2.1.99", &[0x78, 0x9c, 1, 2, 3]);
        assert_eq!(
            scan(&p).unwrap().unwrap().transfer_syntax,
            "1.2.840.10008.1.2.1.99"
        );
        // not DICOM
        let dir = tempfile::tempdir().unwrap();
        let q = dir.path().join("notes.txt");
        std::fs::write(&q, b"hello").unwrap();
        assert!(scan(&q).unwrap().is_none());
    }
}
