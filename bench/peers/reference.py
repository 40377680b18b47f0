#!/usr/bin/env python3
"""Brute-force reference images of the peer benchmark (bench/peers/README.md "Reference").

Independent of every renderer measured: plain numpy, vectorised over rays. The field is the
trilinear interpolant of the voxels, defined on the box of voxel centres [0, 255]^3 (indices
clamped to the edge); rays outside it see nothing. Each ray is sampled at its entry, every
`--step` voxels (default 0.05, ten times finer than the peers) and at its exit; one march gives
all four modes:
  mip        max of the samples
  xray       trapezoid rule of v along the ray, in voxel lengths, divided by XRAY_LENGTH (64)
  composite  front to back, no early stop; segment value = mean of its two end samples,
             opacity 1 - (1 - a(v))^length with a(v) per voxel length; premultiplied grey
  iso        first sample >= 0.5, the crossing refined linearly between the two samples;
             normal = -(trilinear interpolation of central-difference voxel gradients), turned
             to the eye; Phong with a headlight (light and eye along -ray): ka + kd n.l +
             ks max(r.v, 0)^30
Results are cached in OUT as ref_{kind}_{view}_{mode}.npy (iso: also _mask.npy) with a
meta.json naming the step and the volume file's size and time; a run with the same inputs
reuses them. Usage: reference.py [--data DIR] [--out DIR] [--views ortho,persp] [--kinds f32]"""
import argparse
import json
import os
import time

import numpy as np

import common as C


def trilinear(vol_flat, p):
    """Trilinear interpolation of a [z, y, x] volume (flattened) at points p (n, 3) = (x, y, z)."""
    p = np.clip(p, 0.0, C.N - 1.0)
    i = np.minimum(p.astype(np.int64), C.N - 2)
    f = (p - i).astype(np.float32)
    base = i[:, 0] + C.N * i[:, 1] + C.N * C.N * i[:, 2]
    fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
    sy, sz = C.N, C.N * C.N

    def lerp_x(b):
        a0, a1 = vol_flat[b], vol_flat[b + 1]
        return a0 + fx * (a1 - a0)

    c00, c10 = lerp_x(base), lerp_x(base + sy)
    c01, c11 = lerp_x(base + sz), lerp_x(base + sy + sz)
    c0 = c00 + fy * (c10 - c00)
    c1 = c01 + fy * (c11 - c01)
    return c0 + fz * (c1 - c0)


def slab(o, d):
    """Entry and exit distances of rays against the box [0, N-1]^3 (t1 < t0: a miss)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        a = (0.0 - o) * inv
        b = (C.N - 1.0 - o) * inv
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    lo = np.where(np.isnan(lo), -np.inf, lo)   # parallel rays inside the slab
    hi = np.where(np.isnan(hi), np.inf, hi)
    return np.maximum(lo.max(axis=1), 0.0), hi.min(axis=1)


def gradient_volume(vol):
    """Central differences per voxel (clamped at the edges), as a flat (N^3, 3) x, y, z array."""
    g = np.empty(vol.shape + (3,), np.float32)
    for axis, comp in ((2, 0), (1, 1), (0, 2)):
        up = np.take(vol, np.r_[1:C.N, C.N - 1], axis=axis)
        down = np.take(vol, np.r_[0, 0:C.N - 1], axis=axis)
        g[..., comp] = (up - down) / 2
    return g.reshape(-1, 3)


def march(vol, o, d, step):
    """All four modes for the rays (o, d)."""
    flat = vol.ravel()
    n = len(o)
    t0, t1 = slab(o, d)
    hit = t1 > t0
    t0, t1 = np.where(hit, t0, 0.0), np.where(hit, t1, 0.0)
    mip, xray, col = np.zeros(n), np.zeros(n), np.zeros(n)
    trans = np.ones(n)
    t_iso = np.full(n, np.nan)
    k_max = int(np.ceil((t1[hit] - t0[hit]).max() / step)) if hit.any() else 0
    t_prev = t0.copy()
    v_prev = np.where(hit, trilinear(flat, o + t0[:, None] * d), 0.0)
    mip = v_prev.copy()
    t_iso[hit & (v_prev >= C.ISO)] = t0[hit & (v_prev >= C.ISO)]
    for k in range(1, k_max + 1):
        t = np.minimum(t0 + k * step, t1)
        seg = np.where(hit, t - t_prev, 0.0)
        v = np.where(hit, trilinear(flat, o + t[:, None] * d), 0.0)
        mip = np.maximum(mip, v)
        xray += 0.5 * (v + v_prev) * seg
        vm = 0.5 * (v + v_prev)
        alpha = 1.0 - (1.0 - C.opacity_per_voxel(vm)) ** seg
        col += trans * alpha * vm
        trans *= 1.0 - alpha
        up = np.isnan(t_iso) & (v >= C.ISO) & (seg > 0)
        frac = (C.ISO - v_prev[up]) / (v[up] - v_prev[up])
        t_iso[up] = t_prev[up] + frac * seg[up]
        t_prev, v_prev = t, v
    return dict(mip=mip, xray=xray / C.XRAY_LENGTH, composite=col, t_iso=t_iso)


def shade_iso(grad, o, d, t_iso):
    mask = ~np.isnan(t_iso)
    shade = np.zeros(len(o))
    p = o[mask] + t_iso[mask, None] * d[mask]
    g = np.stack([trilinear(grad[:, c].copy(), p) for c in range(3)], axis=1)
    norm = np.linalg.norm(g, axis=1)
    to_eye = -d[mask]
    nrm = -g / np.where(norm > 0, norm, 1.0)[:, None]
    nrm *= np.where((nrm * to_eye).sum(axis=1) < 0, -1.0, 1.0)[:, None]
    ndl = np.clip((nrm * to_eye).sum(axis=1), 0.0, 1.0)   # headlight: l = v = to_eye
    r_dot_v = 2 * ndl * ndl - 1                           # r = 2 (n.l) n - l
    spec = np.where(ndl > 0, np.clip(r_dot_v, 0, 1) ** C.PHONG["exponent"], 0.0)
    s = C.PHONG["ka"] + np.where(norm > 0, C.PHONG["kd"] * ndl + C.PHONG["ks"] * spec, 0.0)
    shade[mask] = s
    return {"mask": mask, "shade": shade}


def render(vol, grad, view, step, chunk=65536):
    o, d = C.rays(view)
    parts = [march(vol, o[s:s + chunk], d[s:s + chunk], step) for s in range(0, len(o), chunk)]
    out = {m: np.concatenate([p[m] for p in parts]) for m in ("mip", "xray", "composite", "t_iso")}
    iso = shade_iso(grad, o, d, out.pop("t_iso"))
    shape = (C.IMG, C.IMG)
    res = {m: out[m].reshape(shape) for m in ("mip", "xray", "composite")}
    res["iso"] = {"mask": iso["mask"].reshape(shape), "shade": iso["shade"].reshape(shape)}
    return res


def ensure(data_dir, out_dir, views, kinds, step):
    """Computes the missing reference images; returns nothing (load with common.load_result)."""
    os.makedirs(out_dir, exist_ok=True)
    for kind in kinds:
        st = os.stat(C.volume_path(data_dir, kind))
        for view in views:
            meta_path = os.path.join(out_dir, f"ref_{kind}_{view}.json")
            meta = {"step": step, "volume_size": st.st_size, "volume_mtime": st.st_mtime,
                    "box": "voxel centres [0, N-1]^3", "xray_length": C.XRAY_LENGTH}
            if os.path.exists(meta_path) and json.load(open(meta_path)) == meta:
                print(f"reference: {kind} {view}: cached in {out_dir}")
                continue
            start = time.time()
            vol = C.load_volume(data_dir, kind)
            res = render(vol, gradient_volume(vol), view, step)
            for mode, img in res.items():
                C.save_result(out_dir, f"ref_{kind}", mode, view, img)
            json.dump(meta, open(meta_path, "w"))
            print(f"reference: {kind} {view}: {time.time() - start:.0f} s (step {step}) -> {out_dir}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="/work/peers-data")
    ap.add_argument("--out", default="/work/peers-data/reference")
    ap.add_argument("--views", default="ortho,persp")
    ap.add_argument("--kinds", default="f32")
    ap.add_argument("--step", type=float, default=0.05)
    a = ap.parse_args()
    ensure(a.data, a.out, a.views.split(","), a.kinds.split(","), a.step)


if __name__ == "__main__":
    main()
