#!/usr/bin/env python3
"""Writes the peer-benchmark volume (bench/peers/README.md, shared PEERS.md) as two NRRD files,
volume_f32.nrrd (float32 in [0, 1]) and volume_u8.nrrd (round(255 v)), into a data folder
(default /work/peers-data; keep it out of the repository: 64 MB + 16 MB).

256^3 voxels, x fastest, spacings 1 and no origin: voxel (i, j, k) sits at world (i, j, k) for
volcast, VTK and teem alike. Values: four Gaussian blobs plus a thin spherical shell, defined on
the voxel centres' [-1, 1] coordinates c = (i + 0.5) / 256 * 2 - 1, values < 1e-3 set to 0,
clipped to [0, 1]. Usage: make_volume.py [DATA_DIR]"""
import os
import sys

import numpy as np

N = 256
BLOBS = [  # centre x, y, z in [-1, 1], sigma, amplitude
    (-0.30, -0.20, 0.10, 0.18, 1.00),
    (0.35, 0.10, -0.20, 0.12, 0.80),
    (0.05, 0.40, 0.35, 0.10, 0.60),
    (0.00, -0.35, -0.35, 0.22, 0.45),
]
SHELL = (0.35, 0.8, 0.015)  # amplitude, radius, width


def field():
    """The volume as float32 [z, y, x] (C order: x fastest)."""
    c = (np.arange(N) + 0.5) / N * 2 - 1
    z, y, x = c[:, None, None], c[None, :, None], c[None, None, :]
    v = np.zeros((N, N, N), np.float64)
    for cx, cy, cz, s, a in BLOBS:  # separable: a product of three 1D Gaussians
        g = lambda u, m: np.exp(-((u - m) ** 2) / (2 * s * s))
        v += a * g(z, cz) * g(y, cy) * g(x, cx)
    amp, radius, width = SHELL
    r = np.sqrt(x * x + y * y + z * z)
    v += amp * np.exp(-((r - radius) ** 2) / (2 * width * width))
    v[v < 1e-3] = 0.0
    return np.clip(v, 0.0, 1.0).astype(np.float32)


def write_nrrd(path, data, nrrd_type):
    header = (
        "NRRD0004\n"
        "# volcast peer benchmark volume (bench/peers/make_volume.py)\n"
        f"type: {nrrd_type}\n"
        "dimension: 3\n"
        f"sizes: {N} {N} {N}\n"
        "spacings: 1 1 1\n"
        "endian: little\n"
        "encoding: raw\n"
        "\n"
    )
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(data.astype(data.dtype.newbyteorder("<"), copy=False).tobytes())
    os.replace(tmp, path)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "/work/peers-data"
    os.makedirs(out, exist_ok=True)
    v = field()
    write_nrrd(os.path.join(out, "volume_f32.nrrd"), v, "float")
    write_nrrd(os.path.join(out, "volume_u8.nrrd"), np.round(v * 255).astype(np.uint8), "uchar")
    print(f"make_volume: {out}/volume_f32.nrrd, volume_u8.nrrd: {N}^3, "
          f"{100 * np.mean(v > 0):.1f} % non-zero, max {v.max():.3f}, mean {v.mean():.4f}")


if __name__ == "__main__":
    main()
