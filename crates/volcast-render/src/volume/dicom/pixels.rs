//! The pixel data of one frame: native (uncompressed, the frame's bytes cut from the
//! value), or encapsulated (PS3.5 A.4: the frame's fragments found by one fragment per
//! frame, the basic offset table, or the end-of-image marker that ends a frame's
//! last fragment) and decoded: RLE Lossless here (PS3.5 G), JPEG and JPEG 2000 by the
//! `dicom-transfer-syntax-registry` adapters (`jpeg-decoder`, `openjp2`, pure Rust),
//! after the codestream's own header is checked against Rows, Columns and
//! BitsAllocated, so that no size the decoder allocates from is larger than the frame.
//!
//! Every result is the frame's cells, little-endian, `BitsAllocated / 8` bytes each.

use std::borrow::Cow;

use dicom_encoding::adapters::{PixelDataObject, RawPixelData};
use dicom_encoding::transfer_syntax::{Codec, TransferSyntaxIndex};
use dicom_transfer_syntax_registry::TransferSyntaxRegistry;

/// How a transfer syntax stores pixel data, for those read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Coding {
    /// Native cells (implicit and explicit VR little endian, deflated).
    Native,
    /// RLE Lossless.
    Rle,
    /// JPEG: baseline, extended (8-bit), lossless (process 14).
    Jpeg,
    /// JPEG 2000 (lossless only, or lossless and lossy).
    Jpeg2000,
}

/// One transfer syntax volcast reads.
pub(super) struct Syntax {
    pub uid: &'static str,
    pub name: &'static str,
    pub coding: Coding,
    /// The syntax itself is lossy (or may be: JPEG 2000 Image Compression).
    pub lossy: bool,
}

/// The transfer syntaxes read, in the order the README lists them.
pub(super) const READABLE: [Syntax; 10] = [
    syntax(
        "1.2.840.10008.1.2",
        "Implicit VR Little Endian",
        Coding::Native,
        false,
    ),
    syntax(
        "1.2.840.10008.1.2.1",
        "Explicit VR Little Endian",
        Coding::Native,
        false,
    ),
    syntax(
        "1.2.840.10008.1.2.1.99",
        "Deflated Explicit VR Little Endian",
        Coding::Native,
        false,
    ),
    syntax("1.2.840.10008.1.2.5", "RLE Lossless", Coding::Rle, false),
    syntax(
        "1.2.840.10008.1.2.4.50",
        "JPEG Baseline (Process 1)",
        Coding::Jpeg,
        true,
    ),
    syntax(
        "1.2.840.10008.1.2.4.51",
        "JPEG Extended (Process 2 & 4), 8-bit",
        Coding::Jpeg,
        true,
    ),
    syntax(
        "1.2.840.10008.1.2.4.57",
        "JPEG Lossless (Process 14)",
        Coding::Jpeg,
        false,
    ),
    syntax(
        "1.2.840.10008.1.2.4.70",
        "JPEG Lossless (Process 14, SV1)",
        Coding::Jpeg,
        false,
    ),
    syntax(
        "1.2.840.10008.1.2.4.90",
        "JPEG 2000 Image Compression (Lossless Only)",
        Coding::Jpeg2000,
        false,
    ),
    syntax(
        "1.2.840.10008.1.2.4.91",
        "JPEG 2000 Image Compression",
        Coding::Jpeg2000,
        true,
    ),
];

const fn syntax(uid: &'static str, name: &'static str, coding: Coding, lossy: bool) -> Syntax {
    Syntax {
        uid,
        name,
        coding,
        lossy,
    }
}

/// The syntax of `uid`, if volcast reads it.
pub(super) fn readable(uid: &str) -> Option<&'static Syntax> {
    READABLE.iter().find(|s| s.uid == uid)
}

/// Why a known syntax is not read (the README's list of refusals).
pub(super) fn refusal(uid: &str) -> &'static str {
    match uid {
        "1.2.840.10008.1.2.4.80" | "1.2.840.10008.1.2.4.81" => {
            "JPEG-LS has no pure-Rust decoder (dicom-rs decodes it with CharLS, a C++ library built with CMake): convert the files first, e.g. gdcmconv --raw or dcmdjpls"
        }
        "1.2.840.10008.1.2.2" => {
            "big-endian DICOM is retired (PS3.5 since 2004): convert it first, e.g. gdcmconv --raw or dcmconv +te"
        }
        "1.2.840.10008.1.2.4.51" => "12-bit JPEG Extended is not decoded by the jpeg-decoder crate",
        _ => "decompress the files first (e.g. gdcmconv --raw, or dcmdjpeg)",
    }
}

/// What a frame's cells are: the attributes the decoders check against.
#[derive(Clone, Copy, Debug)]
pub(super) struct Layout {
    pub rows: usize,
    pub columns: usize,
    pub bits_allocated: u16,
    pub bits_stored: u16,
}

impl Layout {
    /// The bytes of one frame's cells.
    pub fn frame_bytes(&self) -> usize {
        self.rows * self.columns * usize::from(self.bits_allocated / 8)
    }
}

/// The encoded bytes of frame `frame` of `frames`, from the fragments of encapsulated
/// pixel data (the basic offset table `table`, possibly empty).
pub(super) fn frame_fragments<'a>(
    fragments: &'a [Vec<u8>],
    table: &[u32],
    frames: usize,
    frame: usize,
    coding: Coding,
) -> Result<Cow<'a, [u8]>, String> {
    if fragments.is_empty() {
        return Err("the encapsulated pixel data holds no fragment".into());
    }
    if frames == 1 {
        if fragments.len() == 1 {
            return Ok(Cow::Borrowed(&fragments[0]));
        }
        if coding == Coding::Rle {
            return Err(format!(
                "RLE Lossless pixel data of one frame in {} fragments (PS3.5 G.2 puts each frame in one)",
                fragments.len()
            ));
        }
        return Ok(Cow::Owned(fragments.concat()));
    }
    if fragments.len() == frames {
        return Ok(Cow::Borrowed(&fragments[frame]));
    }
    if coding == Coding::Rle {
        return Err(format!(
            "{frames} frames of RLE Lossless in {} fragments (PS3.5 G.2 puts each frame in one)",
            fragments.len()
        ));
    }
    // the item of fragment i starts `starts[i]` bytes after the first fragment's
    let mut starts = Vec::with_capacity(fragments.len() + 1);
    let mut at = 0u64;
    for f in fragments {
        starts.push(at);
        at += 8 + f.len() as u64;
    }
    starts.push(at);
    let (first, last) = if table.len() == frames {
        let index_of = |offset: u32| {
            starts[..fragments.len()]
                .binary_search(&u64::from(offset))
                .map_err(|_| {
                    format!(
                        "the basic offset table's offset {offset} is not where a fragment starts"
                    )
                })
        };
        if table.windows(2).any(|w| w[0] >= w[1]) || table[0] != 0 {
            return Err(format!(
                "the basic offset table ({} offsets) does not start at 0 and increase",
                table.len()
            ));
        }
        let first = index_of(table[frame])?;
        let last = match table.get(frame + 1) {
            Some(&next) => index_of(next)?,
            None => fragments.len(),
        };
        (first, last)
    } else if !table.is_empty() {
        return Err(format!(
            "the basic offset table has {} offsets for {frames} frames",
            table.len()
        ));
    } else {
        // no table: a frame ends with the fragment that ends with its end-of-image
        // (JPEG EOI, JPEG 2000 EOC: both FFD9), trailing padding aside
        let ends: Vec<usize> = fragments
            .iter()
            .enumerate()
            .filter(|(_, f)| {
                let t = f
                    .iter()
                    .rposition(|&b| b != 0)
                    .map_or(&[][..], |n| &f[..=n]);
                t.ends_with(&[0xFF, 0xD9])
            })
            .map(|(i, _)| i)
            .collect();
        if ends.len() != frames || ends.last() != Some(&(fragments.len() - 1)) {
            return Err(format!(
                "{frames} frames in {} fragments, without a basic offset table, and {} fragments end a frame (FFD9): cannot tell which fragments make which frame",
                fragments.len(),
                ends.len()
            ));
        }
        let first = if frame == 0 { 0 } else { ends[frame - 1] + 1 };
        (first, ends[frame] + 1)
    };
    if first >= last {
        return Err(format!("frame {frame} has no fragment"));
    }
    Ok(Cow::Owned(fragments[first..last].concat()))
}

/// Decodes one encoded frame into its cells.
pub(super) fn decode(
    uid: &str,
    coding: Coding,
    data: &[u8],
    layout: &Layout,
) -> Result<Vec<u8>, String> {
    match coding {
        Coding::Native => Err("native pixel data is not decoded".into()),
        Coding::Rle => rle(data, layout),
        Coding::Jpeg => {
            check_jpeg(data, layout)?;
            adapter(uid, data, layout)
        }
        Coding::Jpeg2000 => {
            check_jpeg2000(data, layout)?;
            adapter(uid, data, layout)
        }
    }
}

/// RLE Lossless (PS3.5 G): a 64-byte header (the number of segments, then 15
/// offsets), one PackBits segment per byte of a cell, most significant first.
fn rle(data: &[u8], layout: &Layout) -> Result<Vec<u8>, String> {
    let size = usize::from(layout.bits_allocated / 8);
    let pixels = layout.rows * layout.columns;
    if data.len() < 64 {
        return Err(format!(
            "an RLE frame of {} bytes: shorter than its 64-byte header",
            data.len()
        ));
    }
    let word = |i: usize| u32::from_le_bytes([data[i], data[i + 1], data[i + 2], data[i + 3]]);
    let segments = word(0) as usize;
    if segments != size {
        return Err(format!(
            "an RLE frame of {segments} segments; BitsAllocated {} with one sample per pixel makes {size}",
            layout.bits_allocated
        ));
    }
    let mut offsets: Vec<usize> = (0..segments).map(|s| word(4 + 4 * s) as usize).collect();
    offsets.push(data.len());
    if offsets[0] != 64 || offsets.windows(2).any(|w| w[0] > w[1]) {
        return Err(format!(
            "the RLE header's segment offsets {:?} do not start at 64 and increase within the {} bytes of the frame",
            &offsets[..segments],
            data.len()
        ));
    }
    let mut out = vec![0u8; pixels * size];
    for s in 0..segments {
        let mut seg = &data[offsets[s]..offsets[s + 1]];
        // segment s holds byte size-1-s of each cell (little-endian cells)
        let byte = size - 1 - s;
        let mut n = 0usize;
        let mut put = |b: u8, n: &mut usize| {
            if *n < pixels {
                out[*n * size + byte] = b;
            }
            *n += 1;
        };
        while n < pixels {
            let Some((&h, rest)) = seg.split_first() else {
                break;
            };
            seg = rest;
            let h = h as i8;
            if h >= 0 {
                let count = h as usize + 1;
                if seg.len() < count {
                    return Err(format!(
                        "RLE segment {s} ends inside a run of {count} literal bytes"
                    ));
                }
                for &b in &seg[..count] {
                    put(b, &mut n);
                }
                seg = &seg[count..];
            } else if h != -128 {
                let Some((&b, rest)) = seg.split_first() else {
                    return Err(format!("RLE segment {s} ends inside a repeat run"));
                };
                seg = rest;
                for _ in 0..(1 - isize::from(h)) {
                    put(b, &mut n);
                }
            }
        }
        if n < pixels {
            return Err(format!(
                "RLE segment {s} decodes to {n} bytes, Rows x Columns = {} x {} = {pixels}",
                layout.rows, layout.columns
            ));
        }
    }
    Ok(out)
}

/// The frame header (SOFn) of a JPEG stream checked against the layout: the decoder
/// allocates from its sizes.
fn check_jpeg(data: &[u8], layout: &Layout) -> Result<(), String> {
    if !data.starts_with(&[0xFF, 0xD8]) {
        return Err("the JPEG stream does not start with SOI (FFD8)".into());
    }
    let mut i = 2;
    loop {
        // markers may be preceded by fill bytes FF
        while data.get(i) == Some(&0xFF) && data.get(i + 1) == Some(&0xFF) {
            i += 1;
        }
        let (Some(&0xFF), Some(&m)) = (data.get(i), data.get(i + 1)) else {
            return Err(format!("no JPEG frame header (SOFn) before byte {i}"));
        };
        if m == 0xD9 || m == 0xDA {
            return Err("no JPEG frame header (SOFn) before the scan".into());
        }
        if (0xD0..=0xD7).contains(&m) || m == 0x01 {
            i += 2;
            continue;
        }
        let len = data
            .get(i + 2..i + 4)
            .map(|b| usize::from(u16::from_be_bytes([b[0], b[1]])))
            .ok_or("the JPEG stream ends inside a marker segment")?;
        let seg = data.get(i + 4..i + 2 + len.max(2)).ok_or_else(|| {
            format!("a JPEG marker segment FF{m:02X} of {len} bytes runs past the stream's end")
        })?;
        let sof = matches!(m, 0xC0..=0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF);
        if !sof {
            i += 2 + len;
            continue;
        }
        if seg.len() < 6 {
            return Err("a JPEG frame header shorter than 8 bytes".into());
        }
        let precision = seg[0];
        let lines = usize::from(u16::from_be_bytes([seg[1], seg[2]]));
        let samples = usize::from(u16::from_be_bytes([seg[3], seg[4]]));
        let components = seg[5];
        if m >= 0xC9 {
            return Err(format!(
                "arithmetic-coded JPEG (SOF{}) is not decoded by the jpeg-decoder crate",
                m - 0xC0
            ));
        }
        if m >= 0xC5 {
            return Err(format!(
                "hierarchical JPEG (SOF{}) is not decoded",
                m - 0xC0
            ));
        }
        let lossless = m == 0xC3;
        if !lossless && precision != 8 {
            return Err(format!(
                "a {precision}-bit DCT JPEG stream: the jpeg-decoder crate decodes 8-bit DCT streams only (12-bit JPEG Extended is refused)"
            ));
        }
        let cell_bits = if precision <= 8 { 8 } else { 16 };
        if (samples, lines) != (layout.columns, layout.rows)
            || components != 1
            || cell_bits != layout.bits_allocated
            || u16::from(precision) < layout.bits_stored
        {
            return Err(format!(
                "the JPEG frame header says {samples} x {lines} pixels of {components} component(s), {precision} bits; the data set says Columns x Rows {} x {}, one sample, BitsStored {} in BitsAllocated {}",
                layout.columns, layout.rows, layout.bits_stored, layout.bits_allocated
            ));
        }
        return Ok(());
    }
}

/// The image and tile sizes (SIZ) of a JPEG 2000 codestream (or of the codestream box
/// of a JP2 file) checked against the layout.
fn check_jpeg2000(data: &[u8], layout: &Layout) -> Result<(), String> {
    let mut cs = data;
    if data.starts_with(&[0, 0, 0, 12, b'j', b'P', b' ', b' ']) {
        // a JP2 file: its boxes, to the contiguous codestream box
        let mut i = 0usize;
        cs = loop {
            let head = data
                .get(i..i + 8)
                .ok_or("a JP2 file without a codestream box (jp2c)")?;
            let len = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as usize;
            let (start, end) = match len {
                0 => (i + 8, data.len()),
                1 => {
                    let l = data
                        .get(i + 8..i + 16)
                        .ok_or("a JP2 box ends inside its header")?;
                    let l = u64::from_be_bytes(l.try_into().unwrap_or_default());
                    (
                        i + 16,
                        i.saturating_add(usize::try_from(l).unwrap_or(usize::MAX)),
                    )
                }
                n if n < 8 => return Err(format!("a JP2 box of length {n}")),
                n => (i + 8, i.saturating_add(n)),
            };
            if end > data.len() || start > end {
                return Err("a JP2 box runs past the end of the frame".into());
            }
            if &head[4..8] == b"jp2c" {
                break &data[start..end];
            }
            i = end;
        };
    }
    if !cs.starts_with(&[0xFF, 0x4F, 0xFF, 0x51]) {
        return Err("the JPEG 2000 codestream does not start with SOC and SIZ (FF4F FF51)".into());
    }
    let siz = cs.get(4..).unwrap_or_default();
    if siz.len() < 41 {
        return Err("the JPEG 2000 codestream ends inside its SIZ marker".into());
    }
    let u32_at = |i: usize| {
        u64::from(u32::from_be_bytes([
            siz[i],
            siz[i + 1],
            siz[i + 2],
            siz[i + 3],
        ]))
    };
    let (x, y, x0, y0) = (u32_at(4), u32_at(8), u32_at(12), u32_at(16));
    let (tx, ty, tx0, ty0) = (u32_at(20), u32_at(24), u32_at(28), u32_at(32));
    let components = u16::from_be_bytes([siz[36], siz[37]]);
    let (ssiz, dx, dy) = (siz[38], siz[39], siz[40]);
    let bits = u16::from(ssiz & 0x7F) + 1;
    let cell_bits = if bits <= 8 { 8 } else { 16 };
    if x < x0
        || y < y0
        || (x - x0, y - y0) != (layout.columns as u64, layout.rows as u64)
        || components != 1
        || (dx, dy) != (1, 1)
        || cell_bits != layout.bits_allocated
        || bits > 16
    {
        return Err(format!(
            "the JPEG 2000 SIZ marker says {} x {} pixels of {components} component(s), {bits} bits, subsampling {dx} x {dy}; the data set says Columns x Rows {} x {}, one sample, BitsAllocated {}",
            x.saturating_sub(x0),
            y.saturating_sub(y0),
            layout.columns,
            layout.rows,
            layout.bits_allocated
        ));
    }
    // the decoder makes a structure per tile: as many tiles as pixels at most
    if tx == 0 || ty == 0 || tx0 > x0 || ty0 > y0 || tx0 + tx <= x0 || ty0 + ty <= y0 {
        return Err(format!(
            "the JPEG 2000 tiles ({tx} x {ty} from {tx0}, {ty0}) do not cover the image"
        ));
    }
    let tiles = (x - tx0).div_ceil(tx) * (y - ty0).div_ceil(ty);
    if tiles > 65_535 || tiles > layout.rows as u64 * layout.columns as u64 {
        return Err(format!(
            "the JPEG 2000 image is cut into {tiles} tiles of {tx} x {ty}"
        ));
    }
    Ok(())
}

/// A frame as the crate's adapters read it: one frame of one fragment.
struct Frame<'a> {
    uid: &'a str,
    data: &'a [u8],
    layout: &'a Layout,
}

impl PixelDataObject for Frame<'_> {
    fn transfer_syntax_uid(&self) -> &str {
        self.uid
    }
    fn rows(&self) -> Option<u16> {
        u16::try_from(self.layout.rows).ok()
    }
    fn cols(&self) -> Option<u16> {
        u16::try_from(self.layout.columns).ok()
    }
    fn samples_per_pixel(&self) -> Option<u16> {
        Some(1)
    }
    fn bits_allocated(&self) -> Option<u16> {
        Some(self.layout.bits_allocated)
    }
    fn bits_stored(&self) -> Option<u16> {
        Some(self.layout.bits_stored)
    }
    fn photometric_interpretation(&self) -> Option<&str> {
        Some("MONOCHROME2")
    }
    fn number_of_frames(&self) -> Option<u32> {
        Some(1)
    }
    fn number_of_fragments(&self) -> Option<u32> {
        Some(1)
    }
    fn fragment(&self, fragment: usize) -> Option<Cow<'_, [u8]>> {
        (fragment == 0).then_some(Cow::Borrowed(self.data))
    }
    fn offset_table(&self) -> Option<Cow<'_, [u32]>> {
        Some(Cow::Borrowed(&[]))
    }
    fn raw_pixel_data(&self) -> Option<RawPixelData> {
        Some(RawPixelData {
            fragments: vec![self.data.to_vec()].into(),
            offset_table: Default::default(),
        })
    }
}

/// Decodes a checked JPEG or JPEG 2000 frame with the registry's adapter.
fn adapter(uid: &str, data: &[u8], layout: &Layout) -> Result<Vec<u8>, String> {
    let ts = TransferSyntaxRegistry
        .get(uid)
        .ok_or_else(|| format!("transfer syntax {uid} is not registered"))?;
    let Codec::EncapsulatedPixelData(Some(reader), _) = ts.codec() else {
        return Err(format!("no decoder for transfer syntax {uid}"));
    };
    let frame = Frame { uid, data, layout };
    let mut out = Vec::new();
    reader
        .decode_frame(&frame, 0, &mut out)
        .map_err(|e| format!("{} decoder: {e}", ts.name()))?;
    if out.len() != layout.frame_bytes() {
        return Err(format!(
            "the {} decoder made {} bytes of a {}-byte frame",
            ts.name(),
            out.len(),
            layout.frame_bytes()
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layout(rows: usize, columns: usize, bits: u16) -> Layout {
        Layout {
            rows,
            columns,
            bits_allocated: bits,
            bits_stored: bits,
        }
    }

    fn rle_frame(segments: &[&[u8]]) -> Vec<u8> {
        let mut h = vec![0u8; 64];
        h[..4].copy_from_slice(&(segments.len() as u32).to_le_bytes());
        let mut at = 64u32;
        for (i, s) in segments.iter().enumerate() {
            h[4 + 4 * i..8 + 4 * i].copy_from_slice(&at.to_le_bytes());
            at += s.len() as u32;
        }
        h.extend(segments.concat());
        h
    }

    #[test]
    fn rle_decodes_packbits_segments_most_significant_first() {
        // 2 x 2 pixels of 16 bits: high bytes a run of 4 x 0x01, low bytes literal
        let f = rle_frame(&[&[0xFD, 0x01], &[0x03, 1, 2, 3, 4]]);
        let v = rle(&f, &layout(2, 2, 16)).unwrap();
        assert_eq!(v, [1, 1, 2, 1, 3, 1, 4, 1]);
        // short, bad counts and offsets are refused
        let e = rle(&f[..70], &layout(2, 2, 16)).unwrap_err();
        assert!(e.contains("segment"), "{e}");
        let e = rle(&f, &layout(2, 2, 8)).unwrap_err();
        assert!(e.contains("2 segments"), "{e}");
        let e = rle(&f, &layout(3, 2, 16)).unwrap_err();
        assert!(e.contains("decodes to 4 bytes"), "{e}");
        let mut g = f.clone();
        g[8..12].copy_from_slice(&9999u32.to_le_bytes());
        assert!(rle(&g, &layout(2, 2, 16)).is_err());
        assert!(rle(&[1, 0, 0], &layout(2, 2, 8)).is_err());
    }

    #[test]
    fn frames_are_found_by_offset_table_or_end_marker() {
        let frags = vec![
            vec![0xFF, 0xD8, 1, 2],
            vec![3, 0xFF, 0xD9, 0],
            vec![0xFF, 0xD8, 0xFF, 0xD9],
        ];
        // offset table: frame 0 = fragments 0, 1; frame 1 = fragment 2
        let f = frame_fragments(&frags, &[0, 24], 2, 0, Coding::Jpeg).unwrap();
        assert_eq!(&*f, &[0xFF, 0xD8, 1, 2, 3, 0xFF, 0xD9, 0]);
        let f = frame_fragments(&frags, &[0, 24], 2, 1, Coding::Jpeg).unwrap();
        assert_eq!(&*f, &[0xFF, 0xD8, 0xFF, 0xD9]);
        // no table: the end markers
        let f = frame_fragments(&frags, &[], 2, 1, Coding::Jpeg).unwrap();
        assert_eq!(&*f, &[0xFF, 0xD8, 0xFF, 0xD9]);
        // a table not at fragment starts, or out of order
        assert!(frame_fragments(&frags, &[0, 20], 2, 1, Coding::Jpeg).is_err());
        assert!(frame_fragments(&frags, &[24, 0], 2, 1, Coding::Jpeg).is_err());
        assert!(frame_fragments(&frags, &[], 3, 0, Coding::Rle).is_ok());
        assert!(frame_fragments(&frags, &[], 4, 0, Coding::Jpeg).is_err());
        assert!(frame_fragments(&[], &[], 1, 0, Coding::Jpeg).is_err());
    }

    #[test]
    fn codestream_sizes_must_be_the_data_sets() {
        // SOI, SOF3 16-bit 6 x 8 one component
        let sof = [0xFF, 0xD8, 0xFF, 0xC3, 0, 11, 16, 0, 6, 0, 8, 1, 1, 0x11, 0];
        assert!(check_jpeg(&sof, &layout(6, 8, 16)).is_ok());
        let e = check_jpeg(&sof, &layout(600, 8, 16)).unwrap_err();
        assert!(e.contains("8 x 6 pixels"), "{e}");
        assert!(check_jpeg(&sof[..9], &layout(6, 8, 16)).is_err());
        let mut dct12 = sof;
        dct12[3] = 0xC1;
        dct12[6] = 12;
        assert!(check_jpeg(&dct12, &layout(6, 8, 16))
            .unwrap_err()
            .contains("12-bit"));
        // SOC, SIZ 8 x 6 one 16-bit component, one tile
        let mut j = vec![0xFF, 0x4F, 0xFF, 0x51, 0, 41, 0, 0];
        for v in [8u32, 6, 0, 0, 8, 6, 0, 0] {
            j.extend(v.to_be_bytes());
        }
        j.extend([0, 1, 15, 1, 1]);
        assert!(check_jpeg2000(&j, &layout(6, 8, 16)).is_ok());
        assert!(check_jpeg2000(&j, &layout(6, 8, 8)).is_err());
        // one-pixel tiles of a 65535 x 65535 image
        let mut big = j.clone();
        for (i, v) in [65535u32, 65535, 0, 0, 1, 1].iter().enumerate() {
            big[8 + 4 * i..12 + 4 * i].copy_from_slice(&v.to_be_bytes());
        }
        let e = check_jpeg2000(&big, &layout(65535, 65535, 16)).unwrap_err();
        assert!(e.contains("tiles"), "{e}");
        assert!(check_jpeg2000(&j[..20], &layout(6, 8, 16)).is_err());
    }
}
