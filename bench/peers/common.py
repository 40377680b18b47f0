"""Shared definitions of the peer benchmark: the volume, the views, the grey mappings and the
error measures (bench/peers/README.md explains each choice). Every runner imports this file, so
the conventions live in one place."""
import json
import math
import os

import numpy as np

N = 256                      # voxels per axis; voxel (i, j, k) sits at world (i, j, k)
IMG = 512                    # image width and height in pixels
CENTRE = (N - 1) / 2.0       # 127.5: centre of the box of voxel centres [0, 255]^3
HALF = N / 2.0               # 128: half the side of the world rectangle every image covers
# Orthographic view: parallel rays along +y, image right = +x, image up = +z; the image covers
# x, z in [-0.5, 255.5] (the 256-voxel cube, voxel faces included): 0.5 voxel per pixel,
# pixel (col i, row j) centred at x = -0.25 + 0.5 i, z = 255.25 - 0.5 j.
# Perspective view: eye on -y at EYE_DISTANCE from the centre, looking +y, vertical fov 30
# degrees; the near face of that cube (y = -0.5) exactly fills the frame.
FOV_DEG = 30.0
EYE_DISTANCE = HALF + HALF / math.tan(math.radians(FOV_DEG / 2))   # 605.70
STEP = 0.5                   # sample spacing of the peers, in voxels
XRAY_LENGTH = 64.0           # X-ray grey = 255 * (line integral of v in voxel lengths) / 64
ISO = 0.5
PHONG = dict(ka=0.1, kd=0.6, ks=0.3, exponent=30.0)
MODES = ("mip", "xray", "composite", "iso")
VIEWS = ("ortho", "persp")


def opacity_per_voxel(v):
    """Composite opacity per voxel length: 0.2 (v - 0.1) / 0.9 above 0.1, 0 below."""
    return np.where(v > 0.1, 0.2 * (v - 0.1) / 0.9, 0.0)


def volume_path(data_dir, kind):
    """The benchmark volume as NRRD: kind 'f32' (float32 in [0, 1]) or 'u8' (round(255 v))."""
    return os.path.join(data_dir, f"volume_{kind}.nrrd")


def load_volume(data_dir, kind="f32"):
    """The volume as float32 values in [0, 1], indexed [z, y, x] (x fastest in memory)."""
    path = volume_path(data_dir, kind)
    with open(path, "rb") as f:
        head = f.read(4096)
    skip = head.index(b"\n\n") + 2
    dtype = np.float32 if kind == "f32" else np.uint8
    vol = np.fromfile(path, dtype=dtype, offset=skip).reshape(N, N, N)
    return vol.astype(np.float32) / (1.0 if kind == "f32" else 255.0)


def pixel_grid():
    """World x (columns) and z (rows, row 0 at the top) of the pixel centres, orthographic."""
    x = -0.5 + (np.arange(IMG) + 0.5) * (2 * HALF / IMG)
    z = (N - 0.5) - (np.arange(IMG) + 0.5) * (2 * HALF / IMG)
    return x, z


def rays(view):
    """Origins and unit directions, arrays (IMG*IMG, 3) in row-major pixel order."""
    x, z = pixel_grid()
    X, Z = np.meshgrid(x, z)
    n = IMG * IMG
    if view == "ortho":
        o = np.stack([X.ravel(), np.full(n, -10.0), Z.ravel()], axis=1)
        d = np.tile([0.0, 1.0, 0.0], (n, 1))
        return o, d
    t = math.tan(math.radians(FOV_DEG / 2))
    px = (np.arange(IMG) + 0.5) / IMG * 2 - 1
    PX, PY = np.meshgrid(px, -px)
    d = np.stack([PX.ravel() * t, np.ones(n), PY.ravel() * t], axis=1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.tile([CENTRE, CENTRE - EYE_DISTANCE, CENTRE], (n, 1))
    return o, d


def grey(mode, image):
    """A mode's image (as each runner stores it, see to_common) in grey levels 0..255."""
    return np.nan_to_num(np.asarray(image, dtype=np.float64), nan=0.0) * 255.0


def errors(mode, got, ref):
    """Error of a peer's image against the reference, both in the common form: a float image
    in [0, 1] ('mip': value, 'xray': integral / XRAY_LENGTH, 'composite': premultiplied grey
    over black), and for 'iso' a dict with 'mask' (covered pixels) and 'shade' (grey)."""
    if mode != "iso":
        g, r = grey(mode, got), grey(mode, ref)
        return {"rmse": float(np.sqrt(np.mean((g - r) ** 2))), "max": float(np.abs(g - r).max())}
    m, rm = got["mask"].astype(bool), ref["mask"].astype(bool)
    both = m & rm
    union = (m | rm).sum()
    d = (grey(mode, got["shade"]) - grey(mode, ref["shade"]))[both]
    return {"iou": float(both.sum() / union) if union else 1.0,
            "rmse": float(np.sqrt(np.mean(d ** 2))) if both.any() else float("nan")}


def save_result(out_dir, peer, mode, view, image):
    """Stores a peer's image in the common form as .npy (plus a PNG to look at)."""
    os.makedirs(out_dir, exist_ok=True)
    base = os.path.join(out_dir, f"{peer}_{view}_{mode}")
    if mode == "iso":
        np.save(base + "_mask.npy", image["mask"].astype(bool))
        np.save(base + ".npy", np.asarray(image["shade"], dtype=np.float32))
        shown = np.where(image["mask"], image["shade"], 0.0)
    else:
        np.save(base + ".npy", np.asarray(image, dtype=np.float32))
        shown = image
    try:
        from PIL import Image
        g = np.clip(np.nan_to_num(np.asarray(shown, dtype=np.float64)) * 255 + 0.5, 0, 255)
        Image.fromarray(g.astype(np.uint8)).save(base + ".png")
    except ImportError:
        pass


def load_result(out_dir, peer, mode, view):
    base = os.path.join(out_dir, f"{peer}_{view}_{mode}")
    if mode == "iso":
        return {"mask": np.load(base + "_mask.npy"), "shade": np.load(base + ".npy")}
    return np.load(base + ".npy")


def emit(record):
    """One timing record as a JSON line on stdout (the driver collects them)."""
    print("RESULT " + json.dumps(record), flush=True)
