//! A pass over a DICOM file's elements before the `dicom` crate reads it: the crate
//! allocates each value from its declared length (up to 4 GiB) before reading it, so
//! every length the crate will read is checked here against the bytes left in the
//! file first. The walk follows the crate's own reading step by step (its file meta
//! loop bounded by (0002,0000), then the token states of its data set reader), so
//! that no element it reads escapes the check. A deflated data set is inflated twice
//! as it streams (nothing kept): once to learn its length (at most
//! [`MAX_INFLATED`]), once to walk it against that length. Also reads the transfer
//! syntax from the file meta group, so that a syntax not read is refused by name
//! before its data set is parsed.

use std::io::{self, BufRead, BufReader, Read};
use std::path::Path;

use dicom_core::dictionary::{DataDictionary, DataDictionaryEntry};
use dicom_dictionary_std::StandardDataDictionary;

use crate::volume::mapped::open_regular;
use crate::volume::VolumeError;

/// The value representations of the standard (PS3.5 6.2).
const KNOWN_VRS: [&[u8; 2]; 34] = [
    b"AE", b"AS", b"AT", b"CS", b"DA", b"DS", b"DT", b"FL", b"FD", b"IS", b"LO", b"LT", b"OB",
    b"OD", b"OF", b"OL", b"OV", b"OW", b"PN", b"SH", b"SL", b"SQ", b"SS", b"ST", b"SV", b"TM",
    b"UC", b"UI", b"UL", b"UN", b"UR", b"US", b"UT", b"UV",
];

/// The longest a deflated data set may inflate to (element lengths are 32-bit).
const MAX_INFLATED: u64 = 1 << 32;

/// Deepest nesting of sequences accepted.
const MAX_DEPTH: usize = 32;

const ITEM: (u16, u16) = (0xFFFE, 0xE000);
const ITEM_END: (u16, u16) = (0xFFFE, 0xE00D);
const SEQUENCE_END: (u16, u16) = (0xFFFE, 0xE0DD);
const PIXEL_DATA: (u16, u16) = (0x7FE0, 0x0010);

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
        inflated: false,
    };
    let mut head = [0u8; 132];
    if len < 132 || r.read_exact(&mut head).is_err() || &head[128..] != b"DICM" {
        return Ok(None);
    }
    // the file meta group as the crate reads it: (0002,0000) first, then explicit VR
    // little-endian elements of any group while its value is not used up
    let first = r.element_header_vr(true, true)?;
    if first.tag != (0x0002, 0x0000) || first.length != Some(4) {
        return Err(r.error(format!(
            "the file meta group starts with {} of length {}, expected its group length (0002,0000) UL of 4 bytes",
            show(first.tag),
            first.length.map_or("undefined".to_string(), |n| n.to_string())
        )));
    }
    let mut g = [0u8; 4];
    r.read_exact(&mut g)?;
    let group_length = u32::from_le_bytes(g);
    let mut used = 0u32;
    let mut ts = None;
    let mut sop_class = None;
    while used < group_length {
        let at = r.pos;
        let ElementHeader { tag, length, .. } = r.element_header_vr(true, true)?;
        let Some(length) = length else {
            return Err(r.error(format!(
                "file meta element {} at byte {at} has an undefined length",
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
            r.skip(u64::from(length))?;
        }
        used = used.saturating_add((r.pos - at) as u32);
    }
    let Some(transfer_syntax) = ts else {
        return Err(r.error(format!(
            "the file meta group (its {group_length} bytes by (0002,0000)) has no transfer syntax (0002,0010)"
        )));
    };
    match transfer_syntax.as_str() {
        "1.2.840.10008.1.2" => r.walk(false, true)?,
        "1.2.840.10008.1.2.1.99" => {
            // the rest of the file is a raw deflate stream of an explicit VR
            // little-endian data set
            let at = r.pos;
            let inflated = |r: &mut Walker<BufReader<std::fs::File>>| {
                let mut file = r.r.get_ref().try_clone().map_err(|e| r.io(e))?;
                io::Seek::seek(&mut file, io::SeekFrom::Start(at)).map_err(|e| r.io(e))?;
                Ok::<_, VolumeError>(flate2::read::DeflateDecoder::new(BufReader::new(file)))
            };
            let inflate_err = |e: io::Error| VolumeError::Data {
                path: path.to_path_buf(),
                message: format!("the deflated data set (from byte {at}) does not inflate: {e}"),
            };
            let stream = inflated(&mut r)?;
            let n = io::copy(&mut stream.take(MAX_INFLATED + 1), &mut io::sink())
                .map_err(inflate_err)?;
            if n > MAX_INFLATED {
                return Err(r.error(format!(
                    "the deflated data set (from byte {at}) inflates to more than {MAX_INFLATED} bytes"
                )));
            }
            let stream = inflated(&mut r)?;
            let mut d = Walker {
                r: BufReader::new(stream),
                pos: 0,
                len: n,
                path,
                inflated: true,
            };
            d.walk(true, true)?;
        }
        // the compressed syntaxes read: explicit VR little-endian data sets
        ts if super::pixels::readable(ts).is_some() => r.walk(true, true)?,
        // any other syntax is refused by name before the crate reads the data set
        _ => {}
    }
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

/// An element's tag, length (`None` = undefined) and whether it is read as a
/// sequence (VR SQ, or in implicit VR the dictionary's SQ).
struct ElementHeader {
    tag: (u16, u16),
    length: Option<u32>,
    sq: bool,
}

/// An open sequence or item, as the crate's reader keeps them on its stack.
struct Open {
    item: bool,
    tag: (u16, u16),
    /// The byte after its last, for a defined length.
    end: Option<u64>,
    /// In encapsulated pixel data: its items are fragments (bytes).
    pixel: bool,
}

struct Walker<'a, R> {
    r: R,
    pos: u64,
    len: u64,
    path: &'a Path,
    /// Walking an inflated data set: positions are bytes of it, not of the file.
    inflated: bool,
}

impl<R: BufRead> Walker<'_, R> {
    fn error(&self, message: String) -> VolumeError {
        VolumeError::Data {
            path: self.path.to_path_buf(),
            message: if self.inflated {
                format!("{message} (of the inflated data set)")
            } else {
                message
            },
        }
    }

    fn io(&self, e: io::Error) -> VolumeError {
        if self.inflated && e.kind() != io::ErrorKind::UnexpectedEof {
            return self.error(format!("the deflated data set does not inflate: {e}"));
        }
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

    fn at_end(&mut self) -> Result<bool, VolumeError> {
        Ok(self.fill()?.is_empty())
    }

    /// The header of the next element: its tag, length (`None` = undefined) and
    /// whether the crate reads it as a sequence.
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
            // implicit VR: the crate takes the VR from the standard dictionary
            let sq = !explicit
                && tag.0 != 0xFFFE
                && tag != PIXEL_DATA
                && StandardDataDictionary
                    .by_tag(dicom_core::Tag(tag.0, tag.1))
                    .is_some_and(|e| e.vr().relaxed() == dicom_core::VR::SQ);
            return Ok(ElementHeader {
                tag,
                length: (n != u32::MAX).then_some(n),
                sq,
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

    /// Opens a sequence or item whose header was just read.
    fn push(
        &self,
        stack: &mut Vec<Open>,
        open: (bool, (u16, u16), Option<u32>, bool),
    ) -> Result<(), VolumeError> {
        let (item, tag, length, pixel) = open;
        if let Some(n) = length {
            self.check_length(tag, n)?;
        }
        if !item && stack.iter().filter(|o| !o.item).count() >= MAX_DEPTH {
            return Err(self.error(format!(
                "sequences nested deeper than {MAX_DEPTH} levels at byte {}",
                self.pos
            )));
        }
        stack.push(Open {
            item,
            tag,
            end: length.map(|n| self.pos + u64::from(n)),
            pixel,
        });
        Ok(())
    }

    /// Walks the data set as the crate's data set reader does, to the end of the
    /// file: element values, sequences (SQ, or any other undefined length), their
    /// items (always elements, except the fragments of encapsulated pixel data) and
    /// delimiters, with every length checked before the crate would allocate it.
    fn walk(&mut self, explicit: bool, little: bool) -> Result<(), VolumeError> {
        let mut stack: Vec<Open> = Vec::new();
        // between the items of a sequence (an item header comes next)
        let mut in_sequence = false;
        loop {
            // containers of defined length end where their length says
            while let Some(top) = stack.last() {
                let Some(end) = top.end else { break };
                if self.pos < end {
                    break;
                }
                if self.pos > end {
                    return Err(self.error(format!(
                        "an element runs past the end of {} {} (byte {end})",
                        if top.item { "the item in" } else { "sequence" },
                        show(top.tag)
                    )));
                }
                in_sequence = top.item;
                stack.pop();
            }
            if in_sequence {
                if self.at_end()? {
                    if stack.last().is_some_and(|o| o.pixel) {
                        return Ok(());
                    }
                    return Err(self.error(format!(
                        "the file ends inside a sequence at byte {}",
                        self.pos
                    )));
                }
                let mut h = [0u8; 8];
                self.read_exact(&mut h)?;
                let u16_at = |i: usize| {
                    if little {
                        u16::from_le_bytes([h[i], h[i + 1]])
                    } else {
                        u16::from_be_bytes([h[i], h[i + 1]])
                    }
                };
                let tag = (u16_at(0), u16_at(2));
                let raw = [h[4], h[5], h[6], h[7]];
                let n = if little {
                    u32::from_le_bytes(raw)
                } else {
                    u32::from_be_bytes(raw)
                };
                let length = (n != u32::MAX).then_some(n);
                match tag {
                    ITEM => {
                        let Some(parent) = stack.last() else {
                            return Err(self.error(format!(
                                "an item outside any sequence at byte {}",
                                self.pos - 8
                            )));
                        };
                        let (pixel, parent) = (parent.pixel, parent.tag);
                        if pixel && length.is_none() {
                            return Err(self.error(format!(
                                "a pixel data fragment of undefined length at byte {}",
                                self.pos - 8
                            )));
                        }
                        self.push(&mut stack, (true, parent, length, pixel))?;
                        in_sequence = false;
                    }
                    ITEM_END => {
                        stack.pop();
                        in_sequence = true;
                    }
                    SEQUENCE_END => {
                        stack.pop();
                        in_sequence = false;
                    }
                    other => {
                        return Err(self.error(format!(
                            "expected an item (FFFE,E000) at byte {} of sequence {}, found {}",
                            self.pos - 8,
                            stack.last().map_or("?".into(), |o| show(o.tag)),
                            show(other)
                        )));
                    }
                }
                continue;
            }
            if let Some(top) = stack.last() {
                if top.item && top.pixel {
                    // a fragment: bytes (its length was checked when it opened)
                    let end = top.end.unwrap_or(self.pos);
                    self.skip(end - self.pos)?;
                    continue;
                }
            }
            // the crate ends a data set where the file ends, at any depth
            if self.at_end()? {
                return Ok(());
            }
            let ElementHeader { tag, length, sq } = self.element_header_vr(explicit, little)?;
            if sq {
                self.push(&mut stack, (false, tag, length, false))?;
                in_sequence = true;
            } else if tag == ITEM_END {
                // outside any sequence the crate ignores it
                if !stack.is_empty() {
                    stack.pop();
                    in_sequence = true;
                }
            } else if length.is_none() {
                // encapsulated pixel data holds fragments; any other undefined
                // length is read as a sequence of items holding elements
                self.push(&mut stack, (false, tag, None, tag == PIXEL_DATA))?;
                in_sequence = true;
            } else if let Some(n) = length {
                self.check_length(tag, n)?;
                self.skip(u64::from(n))?;
            }
        }
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
        // (0002,0000) UL: the group length, then (0002,0010) UI, explicit VR LE
        b.extend([0x02, 0x00, 0x00, 0x00, b'U', b'L', 4, 0]);
        b.extend((8 + ts.len() as u32).to_le_bytes());
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
        // a data set of a syntax not read is not walked: it is refused by name later
        let (_d, p) = file_with(b"1.2.840.10008.1.2.4.80", &[0x78, 0x9c, 1, 2, 3]);
        assert_eq!(
            scan(&p).unwrap().unwrap().transfer_syntax,
            "1.2.840.10008.1.2.4.80"
        );
        // a deflated data set is walked inflated: the huge element inside it is
        // refused against the inflated length, and bytes that do not inflate too
        let deflated = |body: &[u8]| {
            use std::io::Write;
            let mut z = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
            z.write_all(body).unwrap();
            z.finish().unwrap()
        };
        let mut body = vec![0x28, 0, 0x10, 0, b'U', b'S', 2, 0, 8, 0];
        body.extend(huge_ob((0x0029, 0x1010)));
        let (_d, p) = file_with(b"1.2.840.10008.1.2.1.99", &deflated(&body));
        let e = scan(&p).unwrap_err().to_string();
        assert!(
            e.contains("(0029,1010)")
                && e.contains("but only 8 are left")
                && e.contains("inflated data set"),
            "{e}"
        );
        let (_d, p) = file_with(b"1.2.840.10008.1.2.1.99", &deflated(&body[..10]));
        assert!(scan(&p).unwrap().is_some());
        let (_d, p) = file_with(b"1.2.840.10008.1.2.1.99", &[0xFF, 0xFF, 1, 2, 3]);
        let e = scan(&p).unwrap_err().to_string();
        assert!(e.contains("does not inflate"), "{e}");
        // not DICOM
        let dir = tempfile::tempdir().unwrap();
        let q = dir.path().join("notes.txt");
        std::fs::write(&q, b"hello").unwrap();
        assert!(scan(&q).unwrap().is_none());
    }

    /// A sequence (0008,1140) of undefined length with one item of `item` bytes.
    fn sequence(item: &[u8]) -> Vec<u8> {
        let mut v = vec![
            0x08, 0x00, 0x40, 0x11, b'S', b'Q', 0, 0, 0xFF, 0xFF, 0xFF, 0xFF,
        ];
        v.extend([0xFE, 0xFF, 0x00, 0xE0]);
        v.extend((item.len() as u32).to_le_bytes());
        v.extend(item);
        v.extend([0xFE, 0xFF, 0xDD, 0xE0, 0, 0, 0, 0]);
        v
    }

    /// `tag` OB declaring 0xFFFFFFF0 bytes, followed by 8.
    fn huge_ob(tag: (u16, u16)) -> Vec<u8> {
        let mut v = Vec::new();
        v.extend(tag.0.to_le_bytes());
        v.extend(tag.1.to_le_bytes());
        v.extend([b'O', b'B', 0, 0, 0xF0, 0xFF, 0xFF, 0xFF]);
        v.extend([7u8; 8]);
        v
    }

    #[test]
    fn every_item_of_a_sequence_is_walked() {
        // items whose first element is private or in group 0000 hold elements too
        for tag in [(0x0029, 0x1010), (0x0000, 0x1010), (0x0009, 0x0010)] {
            let (_d, p) = file(&sequence(&huge_ob(tag)));
            let e = scan(&p).unwrap_err().to_string();
            assert!(
                e.contains(&show(tag)) && e.contains("declares 4294967280 bytes"),
                "{e}"
            );
        }
        // the same bytes as a pixel data fragment are bytes, not elements
        let mut pixels = vec![
            0xE0, 0x7F, 0x10, 0x00, b'O', b'B', 0, 0, 0xFF, 0xFF, 0xFF, 0xFF,
        ];
        pixels.extend(&sequence(&huge_ob((0x0029, 0x1010)))[12..]);
        let (_d, p) = file(&pixels);
        assert!(scan(&p).unwrap().is_some());
        // a well-formed item is walked through
        let mut item = vec![0x08, 0x00, 0x50, 0x11, b'U', b'I', 4, 0];
        item.extend(b"1.2\0");
        let (_d, p) = file(&sequence(&item));
        assert!(scan(&p).unwrap().is_some());
    }

    #[test]
    fn the_meta_group_ends_where_its_length_says() {
        // a group length 8 bytes short of (0002,0010): the crate finds no transfer syntax
        let (_d, p) = file(&[]);
        let mut b = std::fs::read(&p).unwrap();
        b[140..144].copy_from_slice(&0u32.to_le_bytes());
        std::fs::write(&p, &b).unwrap();
        let e = scan(&p).unwrap_err().to_string();
        assert!(e.contains("no transfer syntax (0002,0010)"), "{e}");
        // implicit VR: a meta element left out of the group is a data set element
        // whose VR and 16-bit length make a 32-bit length
        let (_d, p) = file_with(
            b"1.2.840.10008.1.2\0",
            &[0x02, 0, 0x13, 0, b'S', b'H', 2, 0, b'A', b' '],
        );
        let e = scan(&p).unwrap_err().to_string();
        assert!(
            e.contains("(0002,0013)") && e.contains(&format!("declares {} bytes", 0x0002_4853)),
            "{e}"
        );
        // no group length first
        let (_d, p) = file(&[]);
        let mut b = std::fs::read(&p).unwrap();
        b[134..136].copy_from_slice(&[0x01, 0x00]);
        std::fs::write(&p, &b).unwrap();
        let e = scan(&p).unwrap_err().to_string();
        assert!(e.contains("expected its group length (0002,0000)"), "{e}");
    }

    #[test]
    fn nesting_is_bounded() {
        let mut b = Vec::new();
        for _ in 0..40 {
            b.extend([
                0x08, 0x00, 0x40, 0x11, b'S', b'Q', 0, 0, 0xFF, 0xFF, 0xFF, 0xFF,
            ]);
            b.extend([0xFE, 0xFF, 0x00, 0xE0, 0xFF, 0xFF, 0xFF, 0xFF]);
        }
        let (_d, p) = file(&b);
        let e = scan(&p).unwrap_err().to_string();
        assert!(e.contains("nested deeper than 32"), "{e}");
    }
}
