"""Helpers of the volcast Python tests: the command line to compare against, and
independent readers of the PNG and NRRD files it writes (no code of volcast's)."""

import json
import os
import struct
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest

import volcast

ROOT = Path(__file__).resolve().parents[2]


def _cli():
    exe = os.environ.get("VOLCAST_BIN")
    if exe:
        return exe
    exe = ROOT / "target" / "debug" / "volcast"
    if not exe.exists():
        subprocess.run(["cargo", "build", "--quiet", "--bin", "volcast"], cwd=ROOT, check=True)
    return str(exe)


@pytest.fixture(scope="session")
def cli():
    """Runs the volcast command; returns the completed process."""
    exe = _cli()

    def run(*args, check=True):
        p = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
        if check and p.returncode != 0:
            raise AssertionError(f"volcast {' '.join(map(str, args))} failed:\n{p.stderr}")
        return p

    return run


def write_scene(scene, path):
    """Writes a scene dict as the TOML file the command line reads (the module's own
    conversion, so both read the same text)."""
    Path(path).write_text(volcast._volcast.to_toml(scene))
    return Path(path)


def read_png(path):
    """A PNG's samples as an array (height, width[, channels]): 8- or 16-bit grey
    or RGB, not interlaced (what volcast writes), decoded here from the format."""
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, ihdr = 8, b"", None
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + n]
        pos += 12 + n
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        elif kind == b"IEND":
            break
    width, height, depth, color, _, _, interlace = ihdr
    assert interlace == 0 and depth in (8, 16) and color in (0, 2)
    channels = 3 if color == 2 else 1
    bpp = channels * depth // 8
    stride = width * bpp
    raw = zlib.decompress(idat)
    out = bytearray(height * stride)
    prev = bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1 : (y + 1) * (stride + 1)])
        for x in range(stride):
            a = line[x - bpp] if x >= bpp else 0
            b = prev[x]
            c = prev[x - bpp] if x >= bpp else 0
            if f == 1:
                line[x] = (line[x] + a) & 255
            elif f == 2:
                line[x] = (line[x] + b) & 255
            elif f == 3:
                line[x] = (line[x] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[x] = (line[x] + pred) & 255
        out[y * stride : (y + 1) * stride] = line
        prev = line
    a = np.frombuffer(bytes(out), dtype=">u2" if depth == 16 else np.uint8)
    a = a.astype(np.uint16 if depth == 16 else np.uint8)
    shape = (height, width, channels) if channels > 1 else (height, width)
    return a.reshape(shape)


def read_nrrd_image(path):
    """A float NRRD image volcast writes (raw or gzip): (height, width[, channels])."""
    data = Path(path).read_bytes()
    end = data.index(b"\n\n")
    fields = {}
    for line in data[:end].decode().splitlines()[1:]:
        if line.startswith("#") or ":=" in line:
            continue
        k, _, v = line.partition(":")
        fields[k.strip()] = v.strip()
    body = data[end + 2 :]
    if fields.get("encoding") in ("gzip", "gz"):
        body = zlib.decompress(body, 31)
    assert fields["type"] in ("float", "float32")
    order = "<" if fields.get("endian", "little") == "little" else ">"
    sizes = [int(s) for s in fields["sizes"].split()]
    a = np.frombuffer(body, dtype=order + "f4").astype(np.float32)
    if len(sizes) == 2:
        return a.reshape(sizes[1], sizes[0])
    return a.reshape(sizes[2], sizes[1], sizes[0])


def read_outputs(out, result_keys, frames, ext):
    """The files `NAME_{frame:04}.EXT` of each key in `out`, stacked as render returns."""
    read = read_nrrd_image if ext == "nrrd" else read_png

    def name(key, k):
        for eye in ("_left", "_right"):
            if key.endswith(eye) and not (Path(out) / f"{key}_{k:04}.{ext}").exists():
                return f"{key[: -len(eye)]}_{k:04}{eye}.{ext}"
        return f"{key}_{k:04}.{ext}"

    return {
        key: np.stack([read(Path(out) / name(key, k)) for k in frames])
        for key in result_keys
    }


def assert_same(got, expected):
    """The same keys, shapes, dtypes and bytes (NaN included)."""
    assert sorted(got) == sorted(expected)
    for k in expected:
        g, e = got[k], expected[k]
        assert g.shape == e.shape, (k, g.shape, e.shape)
        assert g.dtype == e.dtype, (k, g.dtype, e.dtype)
        if g.tobytes() != e.tobytes():
            diff = np.argwhere(g != e)
            raise AssertionError(f"{k}: {len(diff)} samples differ, first at {diff[:3].tolist()}")


def manifest_json(out):
    return json.loads((Path(out) / "manifest.json").read_text())
