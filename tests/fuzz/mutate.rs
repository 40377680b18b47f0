//! Seeded mutation of NRRD files, NIfTI and MetaImage files, and scene files, shared by the short fuzz run in
//! `cargo test` (`tests/fuzz/mod.rs`, in-process, panics caught) and the long run
//! (`examples/fuzz.rs`, every case its own process under a timeout and a memory
//! limit). Deterministic: a case is fully defined by (kind, seed, index), so any
//! failure can be reproduced from the three numbers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// SplitMix64: small, fast, good enough for choosing mutations.
pub struct Rng(u64);

impl Rng {
    /// The generator of case `index` of `kind` under `seed`.
    pub fn for_case(kind: Kind, seed: u64, index: u64) -> Rng {
        let mut r = Rng(seed ^ (kind as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
        r.0 ^= index.wrapping_mul(0xd1b5_4a32_d192_ed03);
        r.next();
        r
    }

    /// The next 64 random bits.
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A number in `0..n` (`n` > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    /// One of `items`.
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// What is fuzzed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// NRRD headers and their data (`volcast info`).
    Nrrd = 1,
    /// Scene files (`volcast check`).
    Scene = 2,
    /// NIfTI and MetaImage files (`volcast info`).
    Formats = 3,
}

impl Kind {
    /// The name used on the command line and in file names.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Nrrd => "nrrd",
            Kind::Scene => "scene",
            Kind::Formats => "formats",
        }
    }

    /// The folder of fixtures a case of this kind may name (data files), copied
    /// beside the cases.
    pub fn fixtures(self) -> Option<&'static str> {
        match self {
            Kind::Nrrd => Some("tests/fixtures/nrrd"),
            Kind::Formats => Some("tests/fixtures/formats"),
            Kind::Scene => None,
        }
    }
}

/// Header lines worth splicing into NRRD files: hostile sizes, special files,
/// skips, every encoding, data file forms.
pub const NRRD_LINES: &[&str] = &[
    "sizes: 4000000000 4000000000 4000000000",
    "sizes: 1100 1100 1100",
    "sizes: 0 1 1",
    "dimension: 17",
    "dimension: 1",
    "type: double",
    "type: block",
    "block size: 18446744073709551615",
    "encoding: gzip",
    "encoding: bzip2",
    "encoding: ascii",
    "encoding: hex",
    "encoding: raw",
    "endian: big",
    "line skip: 1",
    "line skip: 18446744073709551615",
    "byte skip: -1",
    "byte skip: 9223372036854775807",
    "data file: /dev/zero",
    "encoding: gzip\nline skip: 1\ndata file: /dev/zero",
    "encoding: ascii\nline skip: 3\ndata file: /dev/zero",
    "data file: fifo",
    "encoding: gzip\ndata file: fifo",
    "encoding: hex\nbyte skip: 1000000000000\ndata file: u8_raw.nrrd",
    "encoding: raw\nline skip: 1000000000\ndata file: u8_raw.nrrd",
    "data file: .",
    "data file: LIST",
    "data file: slice%03d.raw 1 2 1",
    "data file: x%d 0 1000000000 1 2",
    "data file: x%d -9223372036854775808 9223372036854775807 1",
    "space: RAS",
    "space dimension: 3",
    "space directions: (1,0,0) (0,1,0) (0,0,1)",
    "space directions: (0,0,0) (0,0,0) (0,0,0)",
    "space directions: (1e308,0,0) (0,1e-308,0) (0,0,nan)",
    "space origin: (1e308,-1e308,0)",
    "spacings: nan 1e-300 1e300",
    "kinds: RGBA-color space space",
    "measurement frame: (1,0,0) (0,1,0) (0,0,1)",
    "key:=value",
    "k\\\\ey:=a\\nb",
    "# comment",
    "",
];

/// MetaImage header lines worth splicing in: hostile sizes, special data files,
/// every compression and byte order, degenerate geometry.
pub const META_LINES: &[&str] = &[
    "DimSize = 4000000000 4000000000 4000000000",
    "DimSize = 1100 1100 1100",
    "DimSize = 0 1 1",
    "NDims = 4",
    "NDims = 1",
    "ElementType = MET_DOUBLE",
    "ElementType = MET_UCHAR_ARRAY",
    "ElementNumberOfChannels = 3",
    "CompressedData = True",
    "CompressedData = False",
    "CompressedDataSize = 18446744073709551615",
    "CompressedDataSize = 1",
    "HeaderSize = -1",
    "HeaderSize = 9223372036854775807",
    "BinaryDataByteOrderMSB = True",
    "BinaryData = False",
    "ElementSpacing = 1e308 1e-308 nan",
    "TransformMatrix = 0 0 0 0 0 0 0 0 0",
    "Offset = 1e308 -1e308 0",
    "Origin = 100 200 300",
    "Position = nan garbage",
    "Position = 1 2 3",
    "Rotation = 0 1 0 -1 0 0 0 0 1",
    "Orientation = 1 0 0",
    "ElementSize = 4 5 6",
    "FileFormatVersion = 1",
    "origin = 7 7 7",
    "ElementDataFile = /dev/zero",
    "ElementDataFile = fifo",
    "ElementDataFile = .",
    "ElementDataFile = LIST",
    "ElementDataFile = i16.raw",
    "ElementDataFile = LOCAL",
    "ObjectType = Mesh",
    "",
];

/// NIfTI-1 header fields (byte offset, little-endian bytes) worth overwriting:
/// hostile dimensions, types, offsets, transforms.
const NIFTI_FIELDS: &[(usize, &[u8])] = &[
    (40, &[4, 0]),                 // dim[0] = 4
    (40, &[8, 0]),                 // dim[0] = 8
    (42, &[0xff, 0x7f]),           // dim[1] = 32767
    (44, &[0xff, 0x7f]),           // dim[2] = 32767
    (46, &[0, 0x80]),              // dim[3] = -32768
    (48, &[0xff, 0x7f]),           // dim[4] = 32767
    (70, &[128, 0]),               // datatype RGB24
    (70, &[64, 0]),                // datatype float64
    (72, &[64, 0]),                // bitpix 64
    (108, &[0, 0, 0x80, 0x7f]),    // vox_offset = inf
    (108, &[0, 0, 0xc0, 0x7f]),    // vox_offset = nan
    (108, &[0, 0, 0x80, 0x4f]),    // vox_offset = 4.3e9
    (112, &[0, 0, 0, 0x80]),       // scl_slope = -0
    (112, &[0, 0, 0xc0, 0x7f]),    // scl_slope = nan
    (252, &[1, 0]),                // qform_code 1
    (254, &[0, 0]),                // sform_code 0
    (256, &[0, 0, 0x80, 0x7f]),    // quatern_b = inf
    (280, &[0, 0, 0, 0]),          // srow_x[0] = 0
    (0, &[0x1c, 2, 0, 0]),         // sizeof_hdr 540
    (344, &[b'n', b'i', b'1', 0]), // magic of a pair
];

/// NIfTI-2 header fields (byte offset, little-endian bytes) worth overwriting: the
/// 64-bit sizes and offset, the magic's check bytes, double-precision transforms.
const NIFTI2_FIELDS: &[(usize, &[u8])] = &[
    (16, &[8, 0, 0, 0, 0, 0, 0, 0]),             // dim[0] = 8
    (24, &[0, 0, 0, 0, 0, 1, 0, 0]),             // dim[1] = 2^40
    (32, &[0xff, 0xff, 0xff, 0x7f, 0, 0, 0, 0]), // dim[2] = 2^31 - 1
    (40, &[0, 0, 0, 0, 0, 0, 0, 0x80]),          // dim[3] = -2^63
    (48, &[0xff, 0xff, 0, 0, 0, 0, 0, 0]),       // dim[4] = 65535
    (12, &[128, 0]),                             // datatype RGB24
    (14, &[8, 0]),                               // bitpix 8
    (168, &[0, 0, 0, 0, 0, 0, 0, 0x7f]),         // vox_offset = 2^62-ish
    (168, &[0x10, 0, 0, 0, 0, 0, 0, 0]),         // vox_offset = 16
    (176, &[0, 0, 0, 0, 0, 0, 0xf8, 0x7f]),      // scl_slope = nan
    (344, &[1, 0, 0, 0]),                        // qform_code 1
    (348, &[0, 0, 0, 0]),                        // sform_code 0
    (352, &[0, 0, 0, 0, 0, 0, 0xf0, 0x7f]),      // quatern_b = inf
    (400, &[0, 0, 0, 0, 0, 0, 0, 0]),            // srow_x[0] = 0
    (8, &[b'\n', 0, 0, 0]),                      // magic's check bytes
    (4, &[b'n', b'i', b'2', 0]),                 // magic of a pair
    (0, &[0x5c, 1, 0, 0]),                       // sizeof_hdr 348
];

/// One to three NIfTI header fields overwritten with hostile values (NIfTI-2's
/// fields for a NIfTI-2 header).
fn mutate_nifti_fields(rng: &mut Rng, b: &mut [u8]) {
    let fields = if b.starts_with(&540i32.to_le_bytes()) {
        NIFTI2_FIELDS
    } else {
        NIFTI_FIELDS
    };
    for _ in 0..1 + rng.below(3) {
        let (at, bytes) = *rng.pick(fields);
        if let Some(dst) = b.get_mut(at..at + bytes.len()) {
            dst.copy_from_slice(bytes);
        }
    }
}

/// The byte after a DICOM file's meta group (by its (0002,0000)), if it has one.
fn dicom_meta_end(b: &[u8]) -> Option<usize> {
    if b.get(128..132)? != b"DICM" || b.get(132..140)? != [2, 0, 0, 0, b'U', b'L', 4, 0] {
        return None;
    }
    let g = u32::from_le_bytes(b.get(140..144)?.try_into().ok()?);
    Some((144 + g as usize).min(b.len()))
}

/// Declared lengths worth hiding in DICOM elements.
const DICOM_LENGTHS: &[u32] = &[
    0xFFFF_FFF0,
    0xFFFF_FFFE,
    0x7FFF_FFFF,
    0x0100_0000,
    65_536,
    9,
];

/// An element header (little endian, explicit VR unless `implicit`) of `tag`, `vr`
/// and `len`.
fn dicom_header(implicit: bool, tag: (u16, u16), vr: &[u8; 2], len: u32) -> Vec<u8> {
    let mut v = Vec::new();
    v.extend(tag.0.to_le_bytes());
    v.extend(tag.1.to_le_bytes());
    if implicit {
        v.extend(len.to_le_bytes());
        return v;
    }
    v.extend(vr);
    if matches!(vr, b"OB" | b"OW" | b"SQ" | b"UN" | b"UT" | b"UC") {
        v.extend([0, 0]);
        v.extend(len.to_le_bytes());
    } else {
        v.extend((len as u16).to_le_bytes());
    }
    v
}

/// Edits of a multi-frame or compressed DICOM file where its frames are found:
/// NumberOfFrames made larger, smaller or 0; in encapsulated pixel data a fragment's
/// length made huge or odd, the basic offset table's offsets changed, the bytes of a
/// codestream header (JPEG SOFn, JPEG 2000 SIZ, the RLE header) overwritten.
/// `false` when the file has neither.
fn mutate_frames(rng: &mut Rng, b: &mut [u8]) -> bool {
    let find = |b: &[u8], what: &[u8]| b.windows(what.len()).position(|w| w == what);
    let frames = find(b, &[0x28, 0, 0x08, 0, b'I', b'S'])
        .map(|i| (i + 8, usize::from(b[i + 6])))
        .or_else(|| find(b, &[0x28, 0, 0x08, 0, 2, 0, 0, 0]).map(|i| (i + 8, 2)));
    let pixels = find(
        b,
        &[
            0xE0, 0x7F, 0x10, 0x00, b'O', b'B', 0, 0, 0xFF, 0xFF, 0xFF, 0xFF,
        ],
    );
    match (frames, pixels, rng.below(2)) {
        (Some((at, len)), _, 0) | (Some((at, len)), None, _) => {
            let text = *rng.pick(&[&b"0"[..], b"1", b"2", b"99", b"65535", b"-1", b"2147483647"]);
            let mut v = text.to_vec();
            v.resize(len, b' ');
            v.truncate(len);
            if let Some(dst) = b.get_mut(at..at + len) {
                dst.copy_from_slice(&v);
            }
            true
        }
        (_, Some(p), _) => {
            // the offset table's item, then the fragments' items
            let mut items = Vec::new();
            let mut i = p + 12;
            while i + 8 <= b.len() && b[i..i + 4] == [0xFE, 0xFF, 0x00, 0xE0] {
                let n = u32::from_le_bytes(b[i + 4..i + 8].try_into().unwrap_or_default());
                items.push(i);
                i = i.saturating_add(8).saturating_add(n as usize);
            }
            let Some(&item) = items.get(rng.below(items.len().max(1))) else {
                return false;
            };
            match rng.below(3) {
                0 => {
                    let n = *rng.pick(&[0xFFFF_FFF0u32, 0x7FFF_FFFF, 3, 0, 65_536]);
                    b[item + 4..item + 8].copy_from_slice(&n.to_le_bytes());
                }
                1 => {
                    // values of the offset table (or of a fragment's first bytes)
                    let at = items[0] + 8 + 4 * rng.below(4);
                    let v = *rng.pick(&[0u32, 7, 8, 0xFFFF_FFFF, 24]);
                    if let Some(dst) = b.get_mut(at..at + 4) {
                        dst.copy_from_slice(&v.to_le_bytes());
                    }
                }
                _ => {
                    // a codestream header: bytes near the fragment's start
                    for _ in 0..1 + rng.below(4) {
                        let at = item + 8 + rng.below(64);
                        let v = *rng.pick(&[0u8, 0xFF, 0x01, 0x7F, 0x80]);
                        if let Some(x) = b.get_mut(at) {
                            *x = v;
                        }
                    }
                }
            }
            true
        }
        _ => false,
    }
}

/// Structural edits of a DICOM file where the readers look for lengths: a sequence
/// at the start of the data set whose item begins with an element of a private
/// group, of group 0000 or 0002, or an item tag, declaring a huge length over a few
/// real bytes; items of defined and undefined length, nested sequences, stray
/// delimiters; the file meta group length made short or long; and where a
/// multi-frame or compressed file's frames are found ([`mutate_frames`]).
fn mutate_dicom(rng: &mut Rng, b: &mut Vec<u8>) {
    let Some(meta_end) = dicom_meta_end(b) else {
        return;
    };
    if rng.below(2) == 0 && mutate_frames(rng, b) {
        return;
    }
    let implicit = b[..meta_end]
        .windows(18)
        .any(|w| w == b"1.2.840.10008.1.2\0");
    match rng.below(4) {
        0 => {
            // (0002,0000) off by a few bytes: meta elements read as data set
            // elements, or data set elements read as meta elements
            let g = u32::from_le_bytes(b[140..144].try_into().unwrap_or_default());
            let d = *rng.pick(&[8i64, 14, 22, 30, -2, -8, -22, 1, 12, 1000]);
            let g = (i64::from(g) - d).clamp(0, u32::MAX.into()) as u32;
            b[140..144].copy_from_slice(&g.to_le_bytes());
        }
        1 => {
            // a stray delimiter or item at the data set's start
            let tag = *rng.pick(&[0xE000u16, 0xE00D, 0xE0DD]);
            let mut v = vec![0xFE, 0xFF];
            v.extend(tag.to_le_bytes());
            v.extend(rng.pick(DICOM_LENGTHS).to_le_bytes());
            b.splice(meta_end..meta_end, v);
        }
        _ => {
            // sequences nested 1 to 3 deep, the innermost item's first element
            // declaring a huge length
            let group = *rng.pick(&[
                0x0029u16, 0x0000, 0x0002, 0x0009, 0x0011, 0x7FE0, 0xFFFE, 0x0008,
            ]);
            let vr = rng.pick(&[b"OB", b"UN", b"UT", b"SQ", b"OW", b"UI", b"LO"]);
            let mut inner = dicom_header(implicit, (group, 0x1010), vr, *rng.pick(DICOM_LENGTHS));
            inner.extend([7u8; 8]);
            for _ in 0..1 + rng.below(3) {
                let defined = rng.below(2) == 0;
                let mut item = vec![0xFE, 0xFF, 0x00, 0xE0];
                item.extend(
                    if defined {
                        inner.len() as u32
                    } else {
                        u32::MAX
                    }
                    .to_le_bytes(),
                );
                item.extend(&inner);
                if !defined {
                    item.extend([0xFE, 0xFF, 0x0D, 0xE0, 0, 0, 0, 0]);
                }
                let defined = rng.below(2) == 0;
                let len = if defined { item.len() as u32 } else { u32::MAX };
                let mut seq = dicom_header(implicit, (0x0008, 0x1140), b"SQ", len);
                seq.extend(&item);
                if !defined {
                    seq.extend([0xFE, 0xFF, 0xDD, 0xE0, 0, 0, 0, 0]);
                }
                inner = seq;
            }
            b.splice(meta_end..meta_end, inner);
        }
    }
}

/// Lines and tables worth splicing into scene files: huge requests, every mode and
/// option, bad types, deep nesting.
pub const SCENE_LINES: &[&str] = &[
    "[image]\nsize = [32768, 32768]",
    "[image]\nsize = [0, 1]",
    "[orbit]\nframes = 1000000",
    "[orbit]\nframes = 0",
    "[stereo]\nlayout = \"anaglyph\"",
    "[stereo]\nmethod = \"parallel\"\nlayout = \"side-by-side\"\ngap = 4096",
    "[animation]\nformats = [\"gif\", \"apng\"]\nfps = 0.001",
    "[[render]]\nmode = \"composite\"\ninterpolation = \"cubic\"\nshading = \"phong\"\ngradient = \"sobel\"",
    "[[render]]\nmode = \"surface\"\niso = 0.5\nintegration = \"exact\"",
    "[[render]]\nmode = \"xray\"\nstep = 0.0001",
    "[[render]]\nmode = \"composite\"\ntransfer = \"t\"\npreintegrated = true\n[transfer.t]\nkind = \"2d\"",
    // [volume] keys (a second [volume] table would only be a duplicate-key error)
    "sizes = [4e9, 2, 2]",
    "sizes = [2, 2, 2]",
    "path = \"/dev/zero\"",
    "path = \"fifo\"",
    "path = \"fifo.nrrd\"",
    "path = \".\"",
    "format = \"nrrd\"",
    "format = \"raw\"",
    "type = \"uint16\"",
    "endian = \"big\"",
    "offset = -1",
    "offset = 9223372036854775807",
    "crop = [[0, 4294967295], [0, 1], [0, 1]]",
    "[camera]\nfov = 1e308\nup = [0, 0, 0]",
    "[camera]\nelevation = 90\nzoom = 1e-300",
    "[light]\nkind = \"point\"\nposition = [nan, 0, 0]",
    "windw = [0, 1]",
    "window = [1, 0]",
    "step = -1",
    "a = [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]",
    "\"\\uD800\" = 1",
    "[volume",
    "",
];

/// Strings worth putting where quoted strings are (scene paths and names).
const STRINGS: &[&str] = &[
    "\"fifo\"",
    "\"fifo.nrrd\"",
    "\"fifo.nrrd\"",
    "\"/dev/zero\"",
    "\".\"",
    "\"\"",
    "\"../../../../../../etc/passwd\"",
    "\"a.nrrd\"",
    "\"composite\"",
    "\"cubic\"",
    "\"sobel\"",
    "\"exact\"",
    "\"anaglyph\"",
];

/// Numbers worth putting where numbers are.
const NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1",
    "2",
    "255",
    "65536",
    "2147483648",
    "4294967296",
    "9223372036854775807",
    "18446744073709551615",
    "1e308",
    "-1e308",
    "1e-320",
    "nan",
    "inf",
    "-0",
    "0.5",
];

fn line_starts(b: &[u8]) -> Vec<usize> {
    std::iter::once(0)
        .chain(
            b.iter()
                .enumerate()
                .filter(|(_, &c)| c == b'\n')
                .map(|(i, _)| i + 1),
        )
        .filter(|&i| i <= b.len())
        .collect()
}

/// One to four random mutations of `input`, splicing lines of `dict`.
pub fn mutate(rng: &mut Rng, input: &[u8], dict: &[&str]) -> Vec<u8> {
    let mut b = input.to_vec();
    for _ in 0..1 + rng.below(4) {
        let len = b.len();
        match rng.below(12) {
            11 => {
                // a quoted string replaced by another
                let quotes: Vec<usize> = (0..len).filter(|&i| b[i] == b'"').collect();
                if quotes.len() >= 2 {
                    let k = rng.below(quotes.len() - 1);
                    let (i, j) = (quotes[k], quotes[k + 1]);
                    let new = rng.pick(STRINGS).as_bytes().to_vec();
                    b.splice(i..=j, new);
                }
            }
            0 if len > 0 => {
                let i = rng.below(len);
                b[i] ^= 1 << rng.below(8);
            }
            1 if len > 0 => {
                let i = rng.below(len);
                b[i] = rng.next() as u8;
            }
            2 if len > 0 => {
                let i = rng.below(len);
                let n = (1 + rng.below(16)).min(len - i);
                b.drain(i..i + n);
            }
            3 => {
                let i = rng.below(len + 1);
                let n = 1 + rng.below(8);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
                b.splice(i..i, bytes);
            }
            4 if len > 0 => {
                let i = rng.below(len);
                let n = (1 + rng.below(64)).min(len - i);
                let chunk = b[i..i + n].to_vec();
                let at = rng.below(b.len() + 1);
                b.splice(at..at, chunk);
            }
            5 => {
                // a number where a number is
                let digits: Vec<usize> = (0..len).filter(|&i| b[i].is_ascii_digit()).collect();
                if !digits.is_empty() {
                    let mut i = *rng.pick(&digits);
                    while i > 0 && b[i - 1].is_ascii_digit() {
                        i -= 1;
                    }
                    let mut j = i;
                    while j < len && (b[j].is_ascii_digit() || b[j] == b'.') {
                        j += 1;
                    }
                    let n = rng.pick(NUMBERS).as_bytes().to_vec();
                    b.splice(i..j, n);
                }
            }
            6 | 10 => {
                // a dictionary line at a line start (replacing a line, for 10)
                let starts = line_starts(&b);
                let i = *rng.pick(&starts);
                let mut line = rng.pick(dict).as_bytes().to_vec();
                line.push(b'\n');
                let end = if rng.below(2) == 0 {
                    b[i..]
                        .iter()
                        .position(|&c| c == b'\n')
                        .map_or(b.len(), |p| i + p + 1)
                } else {
                    i
                };
                b.splice(i..end, line);
            }
            7 => {
                let starts = line_starts(&b);
                let i = *rng.pick(&starts);
                let end = b[i..]
                    .iter()
                    .position(|&c| c == b'\n')
                    .map_or(b.len(), |p| i + p + 1);
                b.drain(i..end);
            }
            8 => {
                let text = b.clone();
                let mut lines: Vec<&[u8]> = text.split(|&c| c == b'\n').collect();
                if lines.len() > 1 {
                    let (x, y) = (rng.below(lines.len()), rng.below(lines.len()));
                    lines.swap(x, y);
                    b = lines.join(&b'\n');
                }
            }
            9 if len > 0 => {
                b.truncate(rng.below(len));
            }
            _ => {}
        }
    }
    b
}

/// Many `key:=value` lines (a header that took 11.7 s to parse at 80,000 lines when
/// each pair was looked up linearly), inserted after the first line.
fn bulk_pairs(rng: &mut Rng, b: &mut Vec<u8>) {
    let n = 20_000 + rng.below(80_000);
    let at = b
        .iter()
        .position(|&c| c == b'\n')
        .map_or(b.len(), |p| p + 1);
    let mut lines = Vec::with_capacity(n * 12);
    for i in 0..n {
        lines.extend(format!("k{i}:=v\n").bytes());
    }
    b.splice(at..at, lines);
}

/// A case of `kind` made from `input`: [`mutate`] with the kind's dictionary, and,
/// rarely, a bulk of lines.
pub fn mutate_kind(rng: &mut Rng, input: &[u8], kind: Kind) -> Vec<u8> {
    let dict = match kind {
        Kind::Nrrd => NRRD_LINES,
        Kind::Scene => SCENE_LINES,
        Kind::Formats => META_LINES,
    };
    if kind == Kind::Formats && input.starts_with(&[0x1f, 0x8b]) && rng.below(2) == 0 {
        // a .nii.gz: mutate what it holds, compressed again
        use std::io::{Read, Write};
        let mut raw = Vec::new();
        let _ = flate2::read::MultiGzDecoder::new(input).read_to_end(&mut raw);
        let inner = mutate_kind(rng, &raw, kind);
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
        let _ = e.write_all(&inner);
        return e.finish().unwrap_or_default();
    }
    let nifti =
        input.starts_with(&348i32.to_le_bytes()) || input.starts_with(&540i32.to_le_bytes());
    if kind == Kind::Formats && nifti && rng.below(2) == 0 {
        let mut b = input.to_vec();
        mutate_nifti_fields(rng, &mut b);
        if rng.below(2) == 0 {
            return mutate(rng, &b, dict);
        }
        return b;
    }
    if kind == Kind::Formats && dicom_meta_end(input).is_some() && rng.below(2) == 0 {
        let mut b = input.to_vec();
        mutate_dicom(rng, &mut b);
        if rng.below(3) == 0 {
            return mutate(rng, &b, dict);
        }
        return b;
    }
    let mut b = mutate(rng, input, dict);
    if kind == Kind::Nrrd && rng.below(200) == 0 {
        bulk_pairs(rng, &mut b);
    }
    b
}

/// Creates what the dictionaries name besides the corpus (FIFOs called `fifo` and
/// `fifo.nrrd`) in the folder cases are written to.
pub fn prepare_dir(dir: &Path) {
    #[cfg(unix)]
    for name in ["fifo", "fifo.nrrd"] {
        let fifo = dir.join(name);
        if !fifo.exists() {
            let _ = std::process::Command::new("mkfifo").arg(&fifo).status();
        }
    }
    #[cfg(not(unix))]
    let _ = dir;
}

/// A corpus entry: its file name (the extension matters) and bytes.
pub struct Seed {
    /// File name.
    pub name: String,
    /// Contents.
    pub bytes: Vec<u8>,
}

/// The starting files of `kind`, from the project at `root`: the NRRD fixtures and
/// bad headers, or the example scenes (their volume paths made absolute) and a few
/// synthetic scenes.
pub fn corpus(kind: Kind, root: &Path) -> Vec<Seed> {
    let mut seeds = Vec::new();
    let read_dir = |dir: PathBuf, exts: &[&str]| -> Vec<Seed> {
        let mut v: Vec<Seed> = std::fs::read_dir(&dir)
            .map(|rd| {
                rd.filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.extension().is_some_and(|e| exts.iter().any(|x| e == *x)))
                    .filter_map(|p| {
                        Some(Seed {
                            name: p.file_name()?.to_string_lossy().into_owned(),
                            bytes: std::fs::read(&p).ok()?,
                        })
                    })
                    .collect()
            })
            .unwrap_or_default();
        v.sort_by(|a, b| a.name.cmp(&b.name));
        v
    };
    match kind {
        Kind::Nrrd => {
            seeds.extend(read_dir(
                root.join("tests/fixtures/nrrd"),
                &["nrrd", "nhdr"],
            ));
            seeds.extend(read_dir(root.join("tests/bad/nrrd"), &["nrrd", "nhdr"]));
        }
        Kind::Formats => {
            // with the multi-frame and compressed DICOM files (a case of a .dcm is
            // read as the one file of a folder, see `place`)
            seeds.extend(read_dir(
                root.join("tests/fixtures/formats"),
                &["nii", "gz", "mha", "mhd", "tif", "dcm"],
            ));
            // DICOM slices: a case is one slice in a folder of its own (see `place`)
            seeds.extend(read_dir(
                root.join("tests/fixtures/formats/dicom_ct"),
                &["dcm"],
            ));
        }
        Kind::Scene => {
            let data = root.join("data");
            for mut s in read_dir(root.join("scenes"), &["toml"]) {
                let text = String::from_utf8_lossy(&s.bytes)
                    .replace("\"../data/", &format!("\"{}/", data.display()));
                s.bytes = text.into_bytes();
                seeds.push(s);
            }
            for (i, text) in [
                "[volume]\nsynthetic = \"ball\"\nsizes = [8, 8, 8]\n[[render]]\nmode = \"mip\"\n",
                "[volume]\nsynthetic = \"gaussian\"\nsigma = 0.3\n[orbit]\nframes = 12\n[stereo]\nangle = 30\n[animation]\nformats = [\"gif\"]\n[[render]]\nmode = \"surface\"\nmaterial = \"gold\"\n",
                "[volume]\nsynthetic = \"marschner-lobb\"\nsizes = [16, 16, 16]\ncrop = [[0, 7], [0, 7], [0, 7]]\n[camera]\nprojection = \"orthographic\"\n[[render]]\nmode = \"composite\"\ntransfer = \"edges\"\n[transfer.edges]\nkind = \"2d\"\ngradient_max = 0.5\n[[transfer.edges.widget]]\nshape = \"gaussian\"\nvalue = [0.2, 0.6]\ngradient = [0.1, 0.5]\ncolor = [1.0, 0.6, 0.2]\nalpha = 0.6\n",
            ]
            .iter()
            .enumerate()
            {
                seeds.push(Seed {
                    name: format!("synthetic{i}.toml"),
                    bytes: text.as_bytes().to_vec(),
                });
            }
        }
    }
    seeds
}

/// Writes case `bytes` as `name` in `dir` and returns what volcast is given: the file,
/// or for a DICOM slice (`.dcm`) the folder `case_dicom` holding it alone.
pub fn place(dir: &Path, name: &str, bytes: &[u8]) -> std::io::Result<PathBuf> {
    if name.ends_with(".dcm") {
        let folder = dir.join("case_dicom");
        std::fs::create_dir_all(&folder)?;
        std::fs::write(folder.join(name), bytes)?;
        return Ok(folder);
    }
    let path = dir.join(name);
    std::fs::write(&path, bytes)?;
    Ok(path)
}

/// Case `index` of `kind` under `seed`: the file name to write it as, and its bytes.
pub fn case(kind: Kind, seeds: &[Seed], seed: u64, index: u64) -> (String, Vec<u8>) {
    let mut rng = Rng::for_case(kind, seed, index);
    let s = rng.pick(seeds);
    // everything after the first dot: `nii.gz` stays a compressed NIfTI
    let ext = s.name.split_once('.').map_or("", |(_, e)| e);
    (format!("case.{ext}"), mutate_kind(&mut rng, &s.bytes, kind))
}
