#!/usr/bin/env python3
"""VTK 9.7.2 (PyPI wheel) on the peer benchmark, offscreen, no GPU (EGL on Mesa llvmpipe).

MIP, composite and iso use vtkFixedPointVolumeRayCastMapper (CPU); its "additive" blend is not a
plain sum, so X-ray uses vtkGPUVolumeRayCastMapper in ADDITIVE mode on llvmpipe (a CPU
rasteriser), whose sum is sum(opacity(v) v) per sample: a constant opacity OPACITY_XRAY makes it
a plain sum (bench/peers/README.md). Iso: FixedPoint has no iso-surface mode; a steep opacity
ramp at 0.5 (0 below 0.5 - ISO_RAMP, 1 above 0.5 + ISO_RAMP) with Phong shading stands in.
Settings: SampleDistance 0.5, ImageSampleDistance 1, AutoAdjustSampleDistancesOff, 2 threads,
linear interpolation, ScalarOpacityUnitDistance 1, black background.
Timing: render call only (Render + WaitForCompletion), after one cold render, camera touched
between renders; prints the median of --renders warm renders per case as a RESULT line, and
stores the image in the common form (common.py).
Usage: run_vtk.py --out DIR [--data DIR] [--modes ...] [--views ...] [--renders 5] [--kind u8]"""
import argparse
import os
import statistics
import time

os.environ.setdefault("LP_NUM_THREADS", "2")    # llvmpipe worker threads

import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy

import common as C

ISO_RAMP = 0.005
# The GPU mapper scales its opacity table by SampleDistance / ScalarOpacityUnitDistance (0.5)
# in additive mode, so the sum over samples 0.5 apart of OPACITY_XRAY * 0.5 * v is
# OPACITY_XRAY * (integral of v) = integral / XRAY_LENGTH.
OPACITY_XRAY = 1.0 / C.XRAY_LENGTH


def make_property(mode, scale=1.0):
    """The mode's property over values in [0, scale] (1 for float32, 255 for uint8): the
    transfer functions' points are placed at value * scale, so both read the same function of
    the normalised value."""
    prop = vtk.vtkVolumeProperty()
    prop.SetInterpolationTypeToLinear()
    prop.SetScalarOpacityUnitDistance(1.0)
    colour = vtk.vtkColorTransferFunction()
    opacity = vtk.vtkPiecewiseFunction()
    if mode == "iso":
        colour.AddRGBPoint(0.0, 1, 1, 1)
        colour.AddRGBPoint(scale, 1, 1, 1)
        for v, a in ((0.0, 0.0), (C.ISO - ISO_RAMP, 0.0), (C.ISO + ISO_RAMP, 1.0), (1.0, 1.0)):
            opacity.AddPoint(v * scale, a)
        prop.ShadeOn()
        prop.SetAmbient(C.PHONG["ka"])
        prop.SetDiffuse(C.PHONG["kd"])
        prop.SetSpecular(C.PHONG["ks"])
        prop.SetSpecularPower(C.PHONG["exponent"])
    else:
        colour.AddRGBPoint(0.0, 0, 0, 0)
        colour.AddRGBPoint(scale, 1, 1, 1)
        # the GPU mapper's additive sum takes each sample's value as its texture holds it,
        # normalised to [0, 1] for uint8 as well: the opacity is the same for both (checked:
        # dividing it by 255 for uint8 gave an image 62 grey levels off the reference)
        points = {"mip": ((0.0, 1.0), (1.0, 1.0)),
                  "composite": ((0.0, 0.0), (0.1, 0.0), (1.0, 0.2)),
                  "xray": ((0.0, OPACITY_XRAY), (1.0, OPACITY_XRAY))}[mode]
        for v, a in points:
            opacity.AddPoint(v * scale, a)
    prop.SetColor(colour)
    prop.SetScalarOpacity(opacity)
    return prop


def make_mapper(mode, image):
    if mode == "xray":
        m = vtk.vtkGPUVolumeRayCastMapper()
        m.SetBlendModeToAdditive()
        m.SetUseJittering(0)
    else:
        m = vtk.vtkFixedPointVolumeRayCastMapper()
        m.SetNumberOfThreads(2)
        m.SetImageSampleDistance(1.0)
        {"mip": m.SetBlendModeToMaximumIntensity,
         "composite": m.SetBlendModeToComposite,
         "iso": m.SetBlendModeToComposite}[mode]()
    m.SetInputData(image)
    m.SetSampleDistance(C.STEP)
    m.AutoAdjustSampleDistancesOff()
    return m


def set_camera(ren, view):
    cam = ren.GetActiveCamera()
    c = C.CENTRE
    cam.SetFocalPoint(c, c, c)
    cam.SetViewUp(0, 0, 1)
    if view == "ortho":
        cam.ParallelProjectionOn()
        cam.SetPosition(c, c - 1000.0, c)
        cam.SetParallelScale(C.HALF)          # half the image height in world units
    else:
        cam.ParallelProjectionOff()
        cam.SetPosition(c, c - C.EYE_DISTANCE, c)
        cam.SetViewAngle(C.FOV_DEG)
    ren.ResetCameraClippingRange()
    return cam


def grab(rw):
    w2i = vtk.vtkWindowToImageFilter()
    w2i.SetInput(rw)
    w2i.SetInputBufferTypeToRGBA()
    w2i.ReadFrontBufferOff()
    w2i.Update()
    img = w2i.GetOutput()
    w, h, _ = img.GetDimensions()
    a = vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h, w, 4)
    return np.flipud(a).astype(np.float64) / 255.0   # row 0 at the top


def to_common(mode, rgba):
    if mode == "iso":
        return {"mask": rgba[..., 3] > 0.5, "shade": rgba[..., 0]}
    return rgba[..., 0]        # mip: value; xray: integral / 64; composite: grey over black


def run_case(image, mode, view, renders, scale=1.0):
    rw = vtk.vtkRenderWindow()
    rw.SetOffScreenRendering(1)
    rw.SetSize(C.IMG, C.IMG)
    rw.SetMultiSamples(0)
    ren = vtk.vtkRenderer()
    ren.SetBackground(0, 0, 0)
    ren.SetBackgroundAlpha(0.0)
    rw.SetAlphaBitPlanes(1)
    rw.AddRenderer(ren)
    vol = vtk.vtkVolume()
    vol.SetMapper(make_mapper(mode, image))
    vol.SetProperty(make_property(mode, scale))
    ren.AddVolume(vol)
    cam = set_camera(ren, view)
    wait = getattr(rw, "WaitForCompletion", lambda: None)
    rw.Render()
    wait()   # cold: builds tables and textures
    times = []
    for _ in range(renders):
        cam.Modified()
        start = time.perf_counter()
        rw.Render()
        wait()
        times.append(time.perf_counter() - start)
    rgba = grab(rw)
    rw.Finalize()
    return statistics.median(times), rgba


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", default="/work/peers-data")
    ap.add_argument("--out", required=True)
    ap.add_argument("--modes", default=",".join(C.MODES))
    ap.add_argument("--views", default=",".join(C.VIEWS))
    ap.add_argument("--renders", type=int, default=5)
    ap.add_argument("--kind", choices=("f32", "u8"), default="f32",
                    help="the volume read: float32 (the benchmark's) or uint8 (the issue's)")
    a = ap.parse_args()
    scale = 255.0 if a.kind == "u8" else 1.0
    vtk.vtkMultiThreader.SetGlobalMaximumNumberOfThreads(2)
    reader = vtk.vtkNrrdReader()
    reader.SetFileName(C.volume_path(a.data, a.kind))
    reader.Update()
    image = reader.GetOutput()
    for view in a.views.split(","):
        for mode in a.modes.split(","):
            secs, rgba = run_case(image, mode, view, a.renders, scale)
            C.save_result(a.out, "vtk", mode, view, to_common(mode, rgba))
            np.save(os.path.join(a.out, f"vtk_{view}_{mode}_rgba.npy"), rgba.astype(np.float32))
            mapper = "gpu-llvmpipe" if mode == "xray" else "fixedpoint"
            C.emit({"peer": "vtk", "mode": mode, "view": view, "seconds": secs, "mapper": mapper})


if __name__ == "__main__":
    main()
