"""volcast: declarative TOML scenes in, rendered images of 3D volumes out.

The renderer of the ``volcast`` command line, for NumPy arrays and Jupyter::

    import nibabel as nib, volcast
    img = nib.load("head.nii.gz")
    scene = {"render": [{"mode": "mip"}], "image": {"size": [256, 256]}}
    images = volcast.render(scene, volume=img.dataobj, spacing=img.header.get_zooms()[:3])
    images["mip"].shape  # (36, 256, 256): frames, height, width

A scene is a dict with the structure of a scene file, TOML text, or the path of a
scene file (docs/scene-reference.md has every key). ``volume`` is an array indexed
``[i, j, k]`` (as nibabel and pynrrd give them) that takes the place of
``[volume] path``. See docs/python.md.
"""

import json as _json
import os as _os

import numpy as _np

from . import _volcast
from ._volcast import SceneError, VolcastError, __version__

__all__ = [
    "render",
    "check",
    "info",
    "turntable",
    "Turntable",
    "SceneError",
    "VolcastError",
    "__version__",
]

# the voxel types of the readers (NRRD's ten number types), by NumPy dtype name
_DTYPES = (
    "int8",
    "uint8",
    "int16",
    "uint16",
    "int32",
    "uint32",
    "int64",
    "uint64",
    "float32",
    "float64",
)


def _triple(value, name, default):
    if value is None:
        return [default] * 3
    try:
        t = [float(x) for x in value]
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected three numbers, got {value!r}") from None
    if len(t) != 3:
        raise ValueError(f"{name}: expected three numbers (one per axis i, j, k), got {len(t)}")
    return t


def _array_spec(volume, spacing, origin):
    """The array as the native module takes it: Fortran-ordered (i fastest, as
    volcast stores voxels) in native byte order, without a copy when it is already so;
    with its buffer's address, length, dtype, shape, spacing and origin."""
    a = _np.asanyarray(volume)
    if isinstance(a, _np.ma.MaskedArray):
        raise ValueError("volume: a masked array is not supported (fill it first: a.filled())")
    if a.ndim != 3:
        raise ValueError(
            f"volume: expected a 3D array indexed [i, j, k], got {a.ndim} dimensions (shape {a.shape})"
        )
    if a.dtype.name not in _DTYPES:
        raise ValueError(
            f"volume: dtype {a.dtype} is not supported: expected one of {', '.join(_DTYPES)}"
        )
    if 0 in a.shape:
        raise ValueError(f"volume: the array is empty (shape {a.shape})")
    if not a.dtype.isnative:
        a = a.astype(a.dtype.newbyteorder("="))
    if not a.flags.f_contiguous:
        a = _np.asfortranarray(a)
    a = _np.asarray(a)
    return (
        a,
        int(a.ctypes.data),
        int(a.nbytes),
        a.dtype.name,
        [int(n) for n in a.shape],
        _triple(spacing, "spacing", 1.0),
        _triple(origin, "origin", 0.0),
    )


def _scene_arg(scene):
    if isinstance(scene, (dict, str)):
        return scene
    if isinstance(scene, _os.PathLike):
        return _os.fspath(scene)
    raise TypeError(f"scene: expected a dict, TOML text or a path, got {type(scene).__name__}")


def _arrays(outputs):
    return {
        key: _np.frombuffer(data, dtype=dtype).reshape(shape)
        for key, dtype, shape, data in outputs
    }


def _volume_args(volume, spacing, origin):
    if volume is None:
        if spacing is not None or origin is not None:
            raise ValueError("spacing and origin describe an array given as volume=")
        return None
    return _array_spec(volume, spacing, origin)


def render(scene, volume=None, spacing=None, origin=None, out=None):
    """Renders ``scene`` and returns ``{pass name: array}``: shape
    ``(frames, height, width)`` for grey passes and ``(frames, height, width,
    channels)`` for colour ones, the samples the PNG files would hold (``uint8``,
    ``uint16`` for ``format = "png16"``, ``float32`` for ``format = "nrrd"``). The two
    eyes of a stereo ``pair`` are ``"NAME_left"`` and ``"NAME_right"``.

    ``scene``: a dict with a scene file's structure, TOML text, or a path.
    ``volume``: an optional array indexed ``[i, j, k]`` (any of the ten number dtypes,
    C or Fortran order; a Fortran-ordered array of native byte order is used in
    place), replacing the scene's ``[volume]`` source; ``spacing`` and ``origin``
    (three numbers each, default 1 and 0) place its voxels in the world.
    ``out``: also write the files into this folder, as ``volcast render --out`` does.

    Raises ``SceneError`` for a bad scene, ``ValueError`` for a bad array,
    ``VolcastError`` for other failures, ``KeyboardInterrupt`` on Ctrl-C.
    """
    spec = _volume_args(volume, spacing, origin)
    if out is not None:
        out = _os.fspath(out)
    return _arrays(_volcast.render(_scene_arg(scene), spec, out))


def check(scene, volume=None, spacing=None, origin=None):
    """The plan of ``scene`` as a dict, reading only the volume's header: sizes, frames,
    passes and their files, the memory estimate, warnings, the resolved scene, and
    ``text``, what ``volcast check`` prints."""
    spec = _volume_args(volume, spacing, origin)
    return _json.loads(_volcast.check(_scene_arg(scene), spec))


def info(path_or_array, spacing=None, origin=None):
    """What ``volcast info --json`` prints about a volume file (or a scene file's
    volume), or about an array, as a dict."""
    if isinstance(path_or_array, (str, _os.PathLike)):
        if spacing is not None or origin is not None:
            raise ValueError("spacing and origin describe an array, not a file")
        return _json.loads(_volcast.info_path(_os.fspath(path_or_array)))
    return _json.loads(_volcast.info_array(_array_spec(path_or_array, spacing, origin)))


class Turntable:
    """A rendered turntable: shown inline in Jupyter (the page ``volcast render
    --viewer`` writes, with the frames inside it); drag or use the arrow keys to turn
    the object.

    ``html``: the page; ``images``: ``{pass name: array}`` as ``render`` returns;
    ``out``: the folder written, or None.
    """

    def __init__(self, html, images, out):
        self.html = html
        self.images = images
        self.out = out

    def _size(self):
        first = next(iter(self.images.values()), None)
        if first is None:
            return 640, 480
        height, width = first.shape[1], first.shape[2]
        return width, height

    def _repr_html_(self):
        import html as _html

        width, height = self._size()
        return (
            f'<iframe srcdoc="{_html.escape(self.html, quote=True)}" '
            f'style="width: {max(width + 40, 480)}px; height: {height + 160}px; border: 0" '
            'sandbox="allow-scripts"></iframe>'
        )

    def save(self, path):
        """Writes the page (a self-contained HTML file) to ``path``."""
        with open(path, "w", encoding="utf-8") as f:
            f.write(self.html)

    def __repr__(self):
        passes = ", ".join(f"{k} {v.shape}" for k, v in self.images.items())
        return f"<volcast.Turntable {passes}>"


def turntable(scene, volume=None, spacing=None, origin=None, out=None):
    """Renders ``scene`` (as ``render``) with its turntable page and returns a
    ``Turntable``, which Jupyter shows inline. With ``out``, the frames and the page
    (``index.html``) are written there too."""
    spec = _volume_args(volume, spacing, origin)
    if out is not None:
        out = _os.fspath(out)
    html, outputs, written = _volcast.turntable(_scene_arg(scene), spec, out)
    return Turntable(html, _arrays(outputs), written)
