#!/usr/bin/env python3
"""Writes the malformed NRRD files of this folder (see README.md). Each `.nrrd`/`.nhdr`
here must be rejected by volcast with a message naming the file; `.raw`/`.gz` files
are data files that some of the headers name. Run: python3 make_bad.py
"""
import gzip
import os

os.chdir(os.path.dirname(os.path.abspath(__file__)))

U8 = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
DATA8 = bytes(range(8))


def hdr(*lines):
    return "NRRD0004\n" + "".join(line + "\n" for line in lines)


def u8(*extra):
    """A valid 2x2x2 uint8 raw header with extra lines."""
    return hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", *extra)


def gz(data):
    return gzip.compress(data, mtime=0)


FILES = {
    # ---- magic and header structure
    "empty.nrrd": b"",
    "not_nrrd.nrrd": b"P5\n2 2\n255\n" + DATA8,
    "magic_0006.nrrd": ("NRRD0006\n" + U8[9:] + "\n").encode() + DATA8,
    "non_utf8_header.nrrd": b"NRRD0004\ntype: uint8\ndimension: 3\xff\xfe\nsizes: 2 2 2\nencoding: raw\n\n" + DATA8,
    "no_blank_line.nrrd": U8.encode(),
    "garbage_line.nrrd": (u8("this line has no colon") + "\n").encode() + DATA8,
    "unknown_field.nrrd": (u8("colour: red") + "\n").encode() + DATA8,
    "empty_key.nrrd": (u8(":=value") + "\n").encode() + DATA8,
    "duplicate_field.nrrd": (u8("sizes: 2 2 2") + "\n").encode() + DATA8,
    # ---- required fields
    "missing_sizes.nhdr": hdr("type: uint8", "dimension: 3", "encoding: raw", "data file: x.raw").encode(),
    "missing_encoding.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2") + "\n").encode() + DATA8,
    "missing_type.nrrd": (hdr("dimension: 3", "sizes: 2 2 2", "encoding: raw") + "\n").encode() + DATA8,
    "missing_endian.nrrd": (hdr("type: int16", "dimension: 3", "sizes: 2 2 2", "encoding: raw") + "\n").encode()
    + DATA8 * 2,
    # ---- field values
    "dimension_zero.nrrd": (hdr("type: uint8", "dimension: 0", "sizes: 2 2 2", "encoding: raw") + "\n").encode(),
    "dimension_17.nrrd": (hdr("type: uint8", "dimension: 17", "sizes: 2 2 2", "encoding: raw") + "\n").encode(),
    "sizes_count.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 256 256", "encoding: raw", "data file: x.raw").encode(),
    "sizes_zero.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 0 2", "encoding: raw") + "\n").encode(),
    "sizes_negative.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 -2 2", "encoding: raw") + "\n").encode(),
    "sizes_garbage.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2 x", "encoding: raw") + "\n").encode(),
    "type_unknown.nrrd": (hdr("type: float128", "dimension: 3", "sizes: 2 2 2", "encoding: raw") + "\n").encode(),
    "type_block.nrrd": (hdr("type: block", "block size: 4", "dimension: 3", "sizes: 2 2 2", "encoding: raw") + "\n").encode(),
    "encoding_unknown.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: lzma") + "\n").encode(),
    "encoding_zrl.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: zrl") + "\n").encode(),
    "endian_middle.nrrd": (hdr("type: int16", "dimension: 3", "sizes: 2 2 2", "endian: middle", "encoding: raw") + "\n").encode(),
    "spacings_count.nrrd": (u8("spacings: 1 1") + "\n").encode() + DATA8,
    "spacings_zero.nrrd": (u8("spacings: 1 0 1") + "\n").encode() + DATA8,
    "spacings_text.nrrd": (u8("spacings: 1 one 1") + "\n").encode() + DATA8,
    "kinds_unknown.nrrd": (u8("kinds: domain domain colour") + "\n").encode() + DATA8,
    "centers_unknown.nrrd": (u8("centers: cell cell middle") + "\n").encode() + DATA8,
    "units_unquoted.nrrd": (u8("units: mm mm mm") + "\n").encode() + DATA8,
    "labels_unclosed.nrrd": (u8('labels: "x" "y" "z') + "\n").encode() + DATA8,
    "min_text.nrrd": (u8("min: low") + "\n").encode() + DATA8,
    "line_skip_negative.nrrd": (u8("line skip: -1") + "\n").encode() + DATA8,
    "byte_skip_minus2.nrrd": (u8("byte skip: -2") + "\n").encode() + DATA8,
    # ---- space fields
    "space_unknown.nrrd": (u8("space: up-down-left") + "\n").encode() + DATA8,
    "space_dimension_conflict.nrrd": (u8("space: RAS", "space dimension: 2") + "\n").encode() + DATA8,
    "directions_without_space.nrrd": (u8("space directions: (1,0,0) (0,1,0) (0,0,1)") + "\n").encode() + DATA8,
    "directions_short_vector.nrrd": (u8("space: RAS", "space directions: (1,0) (0,1,0) (0,0,1)") + "\n").encode() + DATA8,
    "directions_count.nrrd": (u8("space: RAS", "space directions: (1,0,0) (0,1,0)") + "\n").encode() + DATA8,
    "directions_nan.nrrd": (u8("space: RAS", "space directions: (1,0,0) (0,nan,0) (0,0,1)") + "\n").encode() + DATA8,
    "directions_degenerate.nrrd": (u8("space: RAS", "space directions: (1,0,0) (2,0,0) (0,0,1)") + "\n").encode() + DATA8,
    "directions_none_on_axis.nrrd": (u8("space: RAS", "space directions: (1,0,0) none (0,0,1)") + "\n").encode() + DATA8,
    "spacings_and_directions.nrrd": (u8("space: RAS", "space directions: (1,0,0) (0,1,0) (0,0,1)", "spacings: 1 1 1") + "\n").encode() + DATA8,
    "origin_without_space.nrrd": (u8("space origin: (0,0,0)") + "\n").encode() + DATA8,
    "origin_nan.nrrd": (u8("space: RAS", "space origin: (nan,0,0)") + "\n").encode() + DATA8,
    "space_time_4d.nrrd": (u8("space: RAST", "space directions: (1,0,0,0) (0,1,0,0) (0,0,1,0)") + "\n").encode() + DATA8,
    "measurement_frame_short.nrrd": (u8("space: RAS", "measurement frame: (1,0,0) (0,1,0)") + "\n").encode() + DATA8,
    "four_d_not_droppable.nrrd": (hdr("type: uint8", "dimension: 4", "sizes: 2 2 2 2", "encoding: raw") + "\n").encode()
    + DATA8 * 2,
    # ---- data
    "short_raw.nrrd": (U8 + "\n").encode() + DATA8[:7],
    "short_gzip.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: gzip") + "\n").encode() + gz(DATA8[:5]),
    "truncated_gzip.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: gzip") + "\n").encode() + gz(DATA8)[:-6],
    "long_gzip.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: gzip") + "\n").encode() + gz(DATA8 + b"\x00"),
    "corrupt_gzip.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: gzip") + "\n").encode() + b"not gzip at all",
    "corrupt_bzip2.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: bzip2") + "\n").encode() + b"BZh9 not bzip2",
    "ascii_too_few.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: ascii") + "\n1 2 3 4 5 6 7\n").encode(),
    "ascii_too_many.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: ascii") + "\n1 2 3 4 5 6 7 8 9\n").encode(),
    "ascii_garbage.nrrd": (hdr("type: float", "dimension: 3", "sizes: 2 2 2", "encoding: ascii") + "\n1 2 3\n4 five 6 7 8\n").encode(),
    "ascii_out_of_range.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: ascii") + "\n1 2 3 4 5 6 7 256\n").encode(),
    "ascii_fraction_for_int.nrrd": (hdr("type: int16", "dimension: 3", "sizes: 2 2 2", "encoding: ascii") + "\n1 2 3 4 5 6 7 8.5\n").encode(),
    "hex_bad_digit.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: hex") + "\n0001020304050g07\n").encode(),
    "hex_odd.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: hex") + "\n000102030405060\n").encode(),
    "hex_too_long.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: hex") + "\n000102030405060708\n").encode(),
    "hostile_sizes.nrrd": (hdr("type: uint8", "dimension: 3", "sizes: 4000000000 4000000000 4000000000", "encoding: raw") + "\n").encode()
    + DATA8,
    "byteskip_minus1_gzip.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: gzip", "byte skip: -1", "data file: data8.raw.gz").encode(),
    "byteskip_past_end.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "byte skip: 4", "data file: data8.raw").encode(),
    "lineskip_past_end.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "line skip: 3", "data file: data8.raw").encode(),
    "gzip_byteskip_past_end.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: gzip", "byte skip: 20", "data file: data8.raw.gz").encode(),
    # ---- data files
    "data_file_missing.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file: does_not_exist.raw").encode(),
    "data_file_stdin.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file: -").encode(),
    "data_file_empty.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file:").encode(),
    "pattern_count.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file: data%d.raw 1 3 1").encode(),
    "pattern_step_zero.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file: data%d.raw 1 2 0").encode(),
    "pattern_unreachable.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file: data%d.raw 5 1 1").encode(),
    "pattern_subdim.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file: data%d.raw 1 2 1 4").encode(),
    "pattern_bad_conversion.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file: data%s.raw 1 2 1").encode(),
    "pattern_missing_file.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file: data%d.raw 7 8 1").encode(),
    "list_empty.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file: LIST").encode(),
    "list_count.nhdr": hdr("type: uint8", "dimension: 3", "sizes: 2 2 2", "encoding: raw", "data file: LIST", "data1.raw", "data2.raw", "data1.raw").encode(),
    "list_not_last.nhdr": hdr("type: uint8", "dimension: 3", "encoding: raw", "data file: LIST", "data1.raw", "sizes: 2 2 2").encode(),
    # ---- auxiliary data files (not headers)
    "data8.raw": DATA8,
    "data8.raw.gz": gz(DATA8),
    "data1.raw": DATA8[:4],
    "data2.raw": DATA8[4:],
}

for name, content in FILES.items():
    with open(name, "wb") as fh:
        fh.write(content)
print(f"wrote {len(FILES)} files")
