//! Element decoding and encoding shared by every encoding (and by the headerless raw
//! reader): bytes of either endianness → native-typed buffers that grow only as data
//! arrives, hex and ASCII adapters that turn text into those bytes, and the inverse
//! conversions for writing.

use std::borrow::Cow;
use std::io::{self, BufRead, Read};

use crate::{Data, Element, Elements, ScalarType};

/// Bytes read per step (a multiple of every element size).
const CHUNK: usize = 1 << 16;
/// Smallest first allocation, in elements.
const MIN_CAPACITY: usize = 1 << 12;

/// Why [`ElementSink::read`] stopped.
#[derive(Debug)]
pub enum ReadError {
    /// The stream ended after `bytes` bytes, before the requested elements.
    Short {
        /// Bytes of the requested piece that did arrive.
        bytes: u64,
    },
    /// The stream failed (including corrupt compressed data and bad hex/ASCII text).
    Io(io::Error),
    /// The buffer for the elements could not be allocated (`bytes` were asked for).
    Memory {
        /// Bytes of the allocation that failed.
        bytes: u64,
    },
}

/// A native-typed buffer filled from a byte stream, never allocating beyond `total`
/// elements nor much beyond what has arrived: what the reader decodes every encoding
/// into, usable by readers of other formats as well.
pub struct ElementSink {
    data: Data,
    total: usize,
    little_endian: bool,
    /// XXH3-128 of the element bytes as stored, fed as they arrive (when asked for).
    hasher: Option<Box<xxhash_rust::xxh3::Xxh3>>,
}

fn empty(ty: ScalarType) -> Data {
    Data::from_bytes(ty, &[], true)
}

/// Appends the elements in `bytes`, growing geometrically but never past `total`;
/// an allocation that fails is an error, not an abort.
fn push<T: Element>(v: &mut Vec<T>, bytes: &[u8], le: bool, total: usize) -> Result<(), ReadError> {
    let size = std::mem::size_of::<T>();
    let n = bytes.len() / size;
    if v.capacity() - v.len() < n {
        let want = (v.capacity() * 2)
            .max(MIN_CAPACITY)
            .min(total)
            .max(v.len() + n);
        v.try_reserve_exact(want - v.len())
            .map_err(|_| ReadError::Memory {
                bytes: (want as u64).saturating_mul(size as u64),
            })?;
    }
    v.extend(bytes.chunks_exact(size).map(|c| T::from_bytes(c, le)));
    Ok(())
}

impl ElementSink {
    /// An empty sink for `total` elements of `ty` stored with the given byte order.
    pub fn new(ty: ScalarType, total: usize, little_endian: bool) -> ElementSink {
        ElementSink {
            data: empty(ty),
            total,
            little_endian,
            hasher: None,
        }
    }

    /// Also hashes the element bytes as they arrive (XXH3-128 of the data as stored,
    /// in file order), at no extra pass over the data.
    pub fn hashing(mut self) -> ElementSink {
        self.hasher = Some(Box::default());
        self
    }

    /// The hash of the bytes read so far, when hashing.
    pub fn hash(&self) -> Option<u128> {
        self.hasher.as_ref().map(|h| h.digest128())
    }

    fn push(&mut self, bytes: &[u8]) -> Result<(), ReadError> {
        if let Some(h) = &mut self.hasher {
            h.update(bytes);
        }
        let (le, total) = (self.little_endian, self.total);
        match &mut self.data {
            Data::I8(v) => push(v, bytes, le, total),
            Data::U8(v) => push(v, bytes, le, total),
            Data::I16(v) => push(v, bytes, le, total),
            Data::U16(v) => push(v, bytes, le, total),
            Data::I32(v) => push(v, bytes, le, total),
            Data::U32(v) => push(v, bytes, le, total),
            Data::I64(v) => push(v, bytes, le, total),
            Data::U64(v) => push(v, bytes, le, total),
            Data::F32(v) => push(v, bytes, le, total),
            Data::F64(v) => push(v, bytes, le, total),
            Data::Mapped(_) => unreachable!("an ElementSink only holds owned data"),
        }
    }

    /// Reads exactly `count` more elements from `r`.
    pub fn read(&mut self, r: &mut impl Read, count: usize) -> Result<(), ReadError> {
        let size = self.data.scalar_type().size();
        let mut remaining = count.saturating_mul(size);
        let mut buf = vec![0u8; CHUNK.min(remaining.max(size))];
        let mut fill = 0;
        let mut done: u64 = 0;
        while remaining > 0 {
            let want = buf.len().min(remaining);
            let n = match r.read(&mut buf[fill..want]) {
                Ok(0) => {
                    return Err(ReadError::Short {
                        bytes: done + fill as u64,
                    })
                }
                Ok(n) => n,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(ReadError::Io(e)),
            };
            fill += n;
            let whole = fill / size * size;
            self.push(&buf[..whole])?;
            buf.copy_within(whole..fill, 0);
            fill -= whole;
            remaining -= whole;
            done += whole as u64;
        }
        Ok(())
    }

    /// The elements read so far.
    pub fn finish(self) -> Data {
        self.data
    }
}

/// Reads exactly `count` elements of `ty` from `r`.
#[cfg(test)]
pub(crate) fn read_elements(
    r: &mut impl Read,
    ty: ScalarType,
    count: usize,
    little_endian: bool,
) -> Result<Data, ReadError> {
    let mut sink = ElementSink::new(ty, count, little_endian);
    sink.read(r, count)?;
    Ok(sink.finish())
}

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message)
}

/// Two hex digits per byte, whitespace ignored.
pub(super) struct HexReader<R> {
    inner: R,
    high: Option<u8>,
    offset: u64,
}

impl<R: BufRead> HexReader<R> {
    /// Decodes the hex text of `inner`.
    pub fn new(inner: R) -> Self {
        HexReader {
            inner,
            high: None,
            offset: 0,
        }
    }
}

impl<R: BufRead> Read for HexReader<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let mut n = 0;
        while n < out.len() {
            let buf = self.inner.fill_buf()?;
            if buf.is_empty() {
                if self.high.is_some() {
                    return Err(invalid(
                        "hex data ends in the middle of a byte (odd number of hex digits)".into(),
                    ));
                }
                break;
            }
            let mut used = 0;
            for &c in buf {
                if n == out.len() {
                    break;
                }
                used += 1;
                if c.is_ascii_whitespace() {
                    continue;
                }
                let Some(v) = (c as char).to_digit(16) else {
                    return Err(invalid(format!(
                        "hex data: {:?} at byte {} of the data is not a hex digit",
                        c as char,
                        self.offset + used as u64
                    )));
                };
                match self.high.take() {
                    Some(h) => {
                        out[n] = (h << 4) | v as u8;
                        n += 1;
                    }
                    None => self.high = Some(v as u8),
                }
            }
            self.inner.consume(used);
            self.offset += used as u64;
        }
        Ok(n)
    }
}

/// Longest ASCII value accepted.
const MAX_TOKEN: usize = 1024;

/// Whitespace- or comma-separated decimal values, turned into little-endian bytes of
/// the element type (integers parsed exactly, floats rounded once).
pub(super) struct AsciiReader<R> {
    inner: R,
    ty: ScalarType,
    pending: [u8; 8],
    pending_len: usize,
    pending_pos: usize,
    values: u64,
    line: u64,
    token: Vec<u8>,
}

impl<R: BufRead> AsciiReader<R> {
    /// Parses values of type `ty` from `inner`.
    pub fn new(inner: R, ty: ScalarType) -> Self {
        AsciiReader {
            inner,
            ty,
            pending: [0; 8],
            pending_len: 0,
            pending_pos: 0,
            values: 0,
            line: 1,
            token: Vec::new(),
        }
    }

    fn is_separator(c: u8) -> bool {
        c.is_ascii_whitespace() || c == b','
    }

    /// The next token into `self.token`; false at end of input.
    fn next_token(&mut self) -> io::Result<bool> {
        self.token.clear();
        loop {
            let buf = self.inner.fill_buf()?;
            if buf.is_empty() {
                return Ok(!self.token.is_empty());
            }
            let mut used = 0;
            let mut ended = false;
            for &c in buf {
                used += 1;
                if Self::is_separator(c) {
                    if c == b'\n' {
                        self.line += 1;
                    }
                    if !self.token.is_empty() {
                        ended = true;
                        break;
                    }
                } else if self.token.len() == MAX_TOKEN {
                    return Err(invalid(format!(
                        "ascii data: value {} (line {} of the data) is longer than {MAX_TOKEN} characters",
                        self.values + 1,
                        self.line
                    )));
                } else {
                    self.token.push(c);
                }
            }
            self.inner.consume(used);
            if ended {
                return Ok(true);
            }
        }
    }

    fn bad_value(&self, why: &str) -> io::Error {
        invalid(format!(
            "ascii data: {:?} {why} (value {}, line {} of the data)",
            String::from_utf8_lossy(&self.token),
            self.values + 1,
            self.line
        ))
    }
}

/// Parses an integer token exactly; `1.0`-style integral numbers are accepted too.
fn parse_integer(token: &str) -> Option<i128> {
    token.parse::<i128>().ok().or_else(|| {
        let f = token.parse::<f64>().ok()?;
        (f.is_finite() && f.fract() == 0.0 && f.abs() < 1.7e38).then_some(f as i128)
    })
}

/// `token` as little-endian bytes of `ty`, or why not.
fn ascii_value(ty: ScalarType, token: &str) -> Result<([u8; 8], usize), String> {
    fn int<T: TryFrom<i128> + NativeBytes>(
        token: &str,
        name: &str,
    ) -> Result<([u8; 8], usize), String> {
        let v = parse_integer(token).ok_or_else(|| format!("is not an integer ({name})"))?;
        let t = T::try_from(v).map_err(|_| format!("is out of range for {name}"))?;
        Ok(t.bytes8(true))
    }
    match ty {
        ScalarType::Int8 => int::<i8>(token, "int8"),
        ScalarType::Uint8 => int::<u8>(token, "uint8"),
        ScalarType::Int16 => int::<i16>(token, "int16"),
        ScalarType::Uint16 => int::<u16>(token, "uint16"),
        ScalarType::Int32 => int::<i32>(token, "int32"),
        ScalarType::Uint32 => int::<u32>(token, "uint32"),
        ScalarType::Int64 => int::<i64>(token, "int64"),
        ScalarType::Uint64 => int::<u64>(token, "uint64"),
        ScalarType::Float32 => token
            .parse::<f32>()
            .map(|v| v.bytes8(true))
            .map_err(|_| "is not a number (float)".into()),
        ScalarType::Float64 => token
            .parse::<f64>()
            .map(|v| v.bytes8(true))
            .map_err(|_| "is not a number (double)".into()),
    }
}

impl<R: BufRead> Read for AsciiReader<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let mut n = 0;
        while n < out.len() {
            if self.pending_pos < self.pending_len {
                let k = (self.pending_len - self.pending_pos).min(out.len() - n);
                out[n..n + k]
                    .copy_from_slice(&self.pending[self.pending_pos..self.pending_pos + k]);
                self.pending_pos += k;
                n += k;
                continue;
            }
            if !self.next_token()? {
                break;
            }
            let text =
                std::str::from_utf8(&self.token).map_err(|_| self.bad_value("is not text"))?;
            let (bytes, len) = ascii_value(self.ty, text).map_err(|why| self.bad_value(&why))?;
            self.pending = bytes;
            self.pending_len = len;
            self.pending_pos = 0;
            self.values += 1;
        }
        Ok(n)
    }
}

/// Native bytes of an element, in either byte order, and its ASCII form.
pub(super) trait NativeBytes: Copy {
    /// The element's bytes in the first `size` of 8.
    fn bytes8(self, little_endian: bool) -> ([u8; 8], usize);
    /// The shortest text that parses back to the same value.
    fn ascii(self) -> String;
}

macro_rules! impl_native_bytes {
    ($fmt:literal: $($t:ty),*) => {$(
        impl NativeBytes for $t {
            fn bytes8(self, little_endian: bool) -> ([u8; 8], usize) {
                let b = if little_endian { self.to_le_bytes() } else { self.to_be_bytes() };
                let mut out = [0u8; 8];
                out[..b.len()].copy_from_slice(&b);
                (out, b.len())
            }
            fn ascii(self) -> String {
                format!($fmt, self)
            }
        }
    )*};
}

impl_native_bytes!("{}": i8, u8, i16, u16, i32, u32, i64, u64);
// Debug: exponent notation for very large and small magnitudes (Display never uses it).
impl_native_bytes!("{:?}": f32, f64);

/// Calls `$body` with `$v` bound to the elements of `$e` ([`Elements`]) decoded as
/// an iterator of their Rust type.
macro_rules! with_values {
    ($e:expr, $v:ident => $body:expr) => {{
        let e: Elements<'_> = $e;
        match e.scalar_type() {
            ScalarType::Int8 => {
                let $v = values::<i8>(e);
                $body
            }
            ScalarType::Uint8 => {
                let $v = values::<u8>(e);
                $body
            }
            ScalarType::Int16 => {
                let $v = values::<i16>(e);
                $body
            }
            ScalarType::Uint16 => {
                let $v = values::<u16>(e);
                $body
            }
            ScalarType::Int32 => {
                let $v = values::<i32>(e);
                $body
            }
            ScalarType::Uint32 => {
                let $v = values::<u32>(e);
                $body
            }
            ScalarType::Int64 => {
                let $v = values::<i64>(e);
                $body
            }
            ScalarType::Uint64 => {
                let $v = values::<u64>(e);
                $body
            }
            ScalarType::Float32 => {
                let $v = values::<f32>(e);
                $body
            }
            ScalarType::Float64 => {
                let $v = values::<f64>(e);
                $body
            }
        }
    }};
}

/// The elements decoded one by one from their native bytes (at any alignment).
fn values<T: Element>(e: Elements<'_>) -> impl ExactSizeIterator<Item = T> + '_ {
    e.bytes()
        .chunks_exact(T::TYPE.size())
        .map(|c| T::from_bytes(c, cfg!(target_endian = "little")))
}

/// The data as stored bytes in the given byte order: the data's own bytes when
/// that is the native order (no copy), else a converted copy.
pub(super) fn element_bytes(data: Elements<'_>, little_endian: bool) -> Cow<'_, [u8]> {
    fn conv<T: Element + NativeBytes>(v: impl Iterator<Item = T>, n: usize, le: bool) -> Vec<u8> {
        let mut out = Vec::with_capacity(n);
        for x in v {
            let (b, n) = x.bytes8(le);
            out.extend_from_slice(&b[..n]);
        }
        out
    }
    if little_endian == cfg!(target_endian = "little") || data.scalar_type().size() == 1 {
        return Cow::Borrowed(data.bytes());
    }
    let n = data.bytes().len();
    Cow::Owned(with_values!(data, v => conv(v, n, little_endian)))
}

/// The data as ASCII text, `per_line` values per line (Rust's shortest round-trip
/// formatting, `1.0e300`-style for extreme floats; NaN and infinities as `NaN`, `inf`,
/// `-inf`).
pub(super) fn ascii_text(data: Elements<'_>, per_line: usize) -> Vec<u8> {
    fn conv<T: NativeBytes>(v: impl Iterator<Item = T>, per_line: usize) -> Vec<u8> {
        let per_line = per_line.max(1);
        let mut out = String::new();
        let mut v = v.peekable();
        while v.peek().is_some() {
            let line: Vec<String> = v.by_ref().take(per_line).map(|x| x.ascii()).collect();
            out.push_str(&line.join(" "));
            out.push('\n');
        }
        out.into_bytes()
    }
    with_values!(data, v => conv(v, per_line))
}

/// Bytes as hex text, 32 bytes (64 digits) per line.
pub(super) fn hex_text(bytes: &[u8]) -> Vec<u8> {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    let mut out = Vec::with_capacity(bytes.len() * 2 + bytes.len() / 32 + 1);
    for line in bytes.chunks(32) {
        for &b in line {
            out.push(DIGITS[usize::from(b >> 4)]);
            out.push(DIGITS[usize::from(b & 15)]);
        }
        out.push(b'\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader that returns one byte per call, to exercise partial elements.
    struct Trickle<'a>(&'a [u8]);

    impl Read for Trickle<'_> {
        fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
            if self.0.is_empty() || out.is_empty() {
                return Ok(0);
            }
            out[0] = self.0[0];
            self.0 = &self.0[1..];
            Ok(1)
        }
    }

    #[test]
    fn sink_handles_partial_elements_and_endianness() {
        let bytes = [0x01, 0x02, 0x03, 0x04, 0xff, 0xfe, 0xfd, 0xfc];
        let d = read_elements(&mut Trickle(&bytes), ScalarType::Int32, 2, false).unwrap();
        assert_eq!(
            d,
            Data::I32(vec![
                0x01020304,
                i32::from_be_bytes([0xff, 0xfe, 0xfd, 0xfc])
            ])
        );
        let d = read_elements(&mut &bytes[..], ScalarType::Uint16, 4, true).unwrap();
        assert_eq!(d, Data::U16(vec![0x0201, 0x0403, 0xfeff, 0xfcfd]));
    }

    #[test]
    fn sink_reports_short_data() {
        match read_elements(&mut &[1u8, 2, 3][..], ScalarType::Uint16, 2, true) {
            Err(ReadError::Short { bytes }) => assert_eq!(bytes, 3),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn huge_declared_count_allocates_little() {
        // 2^40 elements declared, 10 bytes present: fails without a huge allocation.
        let r = read_elements(&mut &[0u8; 10][..], ScalarType::Uint8, 1 << 40, true);
        assert!(matches!(r, Err(ReadError::Short { bytes: 10 })));
    }

    #[test]
    fn hex_reader() {
        let mut r = HexReader::new(&b" 0a FF\n10"[..]);
        let mut out = Vec::new();
        r.read_to_end(&mut out).unwrap();
        assert_eq!(out, vec![0x0a, 0xff, 0x10]);
        let mut out = Vec::new();
        assert!(HexReader::new(&b"0a1"[..]).read_to_end(&mut out).is_err());
        let e = HexReader::new(&b"0a zz"[..])
            .read_to_end(&mut out)
            .unwrap_err();
        assert!(e.to_string().contains("'z'"), "{e}");
    }

    #[test]
    fn ascii_reader_types_and_errors() {
        let text = b"1, -2\t3.0\n 1e2\n";
        let d = read_elements(
            &mut AsciiReader::new(&text[..], ScalarType::Int16),
            ScalarType::Int16,
            4,
            true,
        )
        .unwrap();
        assert_eq!(d, Data::I16(vec![1, -2, 3, 100]));
        let text = b"18446744073709551615 0";
        let d = read_elements(
            &mut AsciiReader::new(&text[..], ScalarType::Uint64),
            ScalarType::Uint64,
            2,
            true,
        )
        .unwrap();
        assert_eq!(d, Data::U64(vec![u64::MAX, 0]));
        let text = b"nan -inf 0.1 1e-45";
        let d = read_elements(
            &mut AsciiReader::new(&text[..], ScalarType::Float32),
            ScalarType::Float32,
            4,
            true,
        )
        .unwrap();
        let Data::F32(v) = d else { panic!() };
        assert!(v[0].is_nan() && v[1] == f32::NEG_INFINITY && v[2] == 0.1f32 && v[3] > 0.0);
        for (bad, ty) in [
            (&b"1 x2"[..], ScalarType::Uint8),
            (b"1 256", ScalarType::Uint8),
            (b"1 1.5", ScalarType::Int8),
        ] {
            let r = read_elements(&mut AsciiReader::new(bad, ty), ty, 2, true);
            let Err(ReadError::Io(e)) = r else {
                panic!("{r:?}")
            };
            assert!(e.to_string().contains("value 2, line 1"), "{e}");
        }
    }

    #[test]
    fn writers() {
        let d = Data::U16(vec![0x0102, 0xa0b0]);
        assert_eq!(*element_bytes(d.elements(), true), [2, 1, 0xb0, 0xa0]);
        assert_eq!(*element_bytes(d.elements(), false), [1, 2, 0xa0, 0xb0]);
        assert_eq!(hex_text(&[0, 0xff, 0x10]), b"00ff10\n");
        let d = Data::F32(vec![0.1, f32::NAN, -f32::INFINITY, 3.0]);
        assert_eq!(ascii_text(d.elements(), 2), b"0.1 NaN\n-inf 3.0\n");
        let d = Data::F64(vec![f64::MAX, 5e-324]);
        assert_eq!(
            ascii_text(d.elements(), 2),
            b"1.7976931348623157e308 5e-324\n"
        );
    }
}
