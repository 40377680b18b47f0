"""An array given as `volume=` renders the pixels of a NRRD file holding the same
voxels, for every dtype, in C and Fortran order, strided and byte-swapped; bad
arrays are ValueErrors."""

import numpy as np
import pytest

import volcast
from conftest import assert_same, read_outputs, write_scene

DTYPES = ["int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64", "float32", "float64"]
NRRD_TYPES = {"float32": "float", "float64": "double"}
SPACING = [1.0, 1.25, 0.75]
ORIGIN = [-3.0, 2.0, 0.5]
SHAPE = (14, 12, 10)  # i, j, k


def field(dtype):
    """A blob in a box, as values of `dtype` (negative ones for signed types)."""
    i, j, k = np.meshgrid(*[np.linspace(-1, 1, n) for n in SHAPE], indexing="ij")
    f = np.exp(-3 * ((i - 0.2) ** 2 + j**2 + (k + 0.1) ** 2)) + 0.3 * np.exp(-20 * (i + 0.5) ** 2)
    info = np.iinfo(dtype) if np.dtype(dtype).kind in "iu" else None
    if info is None:
        return f.astype(dtype)
    lo = -50 if info.min < 0 else 0
    return np.round(lo + f * 100).astype(dtype)


def write_nrrd(a, path):
    """A raw little-endian NRRD of `a` (indexed [i, j, k], i fastest in the file)."""
    t = NRRD_TYPES.get(a.dtype.name, a.dtype.name)
    sx, sy, sz = SPACING
    header = (
        "NRRD0004\n"
        f"type: {t}\ndimension: 3\nsizes: {' '.join(map(str, a.shape))}\n"
        "space dimension: 3\n"
        f"space directions: ({sx},0,0) (0,{sy},0) (0,0,{sz})\n"
        f"space origin: ({ORIGIN[0]},{ORIGIN[1]},{ORIGIN[2]})\n"
        "endian: little\nencoding: raw\n\n"
    )
    data = a.astype(a.dtype.newbyteorder("<")).tobytes(order="F")
    path.write_bytes(header.encode() + data)
    return path


def scene_for(path=None):
    s = {
        "orbit": {"frames": 2},
        "image": {"size": [24, 20]},
        "camera": {"elevation": 20.0},
        "render": [
            {"mode": "mip"},
            {"name": "iso", "mode": "surface", "iso": 0.4},
            {"name": "xr", "mode": "xray"},
        ],
    }
    if path is not None:
        s["volume"] = {"path": str(path)}
    return s


@pytest.fixture(scope="module")
def references(tmp_path_factory, cli):
    """The command line's images of each dtype's NRRD file."""
    refs = {}
    for dtype in DTYPES:
        d = tmp_path_factory.mktemp(dtype)
        nrrd = write_nrrd(field(dtype), d / "v.nrrd")
        file = write_scene(scene_for(nrrd), d / "scene.toml")
        cli("render", file, "--quiet", "--out", d / "out")
        refs[dtype] = read_outputs(d / "out", ["mip", "iso", "xr"], range(2), "png")
    return refs


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("order", ["F", "C"])
def test_array_renders_the_nrrd_files_pixels(references, dtype, order):
    a = np.asarray(field(dtype), order=order)
    assert a.flags.f_contiguous == (order == "F")
    got = volcast.render(scene_for(), volume=a, spacing=SPACING, origin=ORIGIN)
    assert_same(got, references[dtype])


def test_strided_and_byte_swapped_arrays(references):
    a = field("int16")
    big = a.astype(">i2")
    assert_same(volcast.render(scene_for(), volume=big, spacing=SPACING, origin=ORIGIN), references["int16"])
    wide = np.zeros((SHAPE[0] * 2, SHAPE[1], SHAPE[2]), np.int16)
    wide[::2] = a
    strided = wide[::2]
    assert not strided.flags.c_contiguous and not strided.flags.f_contiguous
    assert_same(volcast.render(scene_for(), volume=strided, spacing=SPACING, origin=ORIGIN), references["int16"])


def test_the_scenes_volume_source_is_replaced(references, tmp_path):
    """A scene naming a file (or a synthetic field) renders the array instead."""
    a = np.asfortranarray(field("float32"))
    for vol in [{"path": "missing.nrrd"}, {"synthetic": "ball", "sizes": [8, 8, 8]}]:
        s = dict(scene_for(), volume=vol)
        assert_same(volcast.render(s, volume=a, spacing=SPACING, origin=ORIGIN), references["float32"])


def test_a_fortran_array_is_used_in_place():
    a = np.asfortranarray(field("uint16"))
    i = volcast.info(a)
    assert i["storage"] == "memory"
    assert i["sizes"] == list(SHAPE) and i["type"] == "uint16"
    assert i["min"] == float(a.min()) and i["max"] == float(a.max())


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.zeros((4, 4)), "3D array"),
        (np.zeros((4, 4, 4, 2)), "3D array"),
        (np.zeros((4, 4, 4), bool), "dtype bool is not supported"),
        (np.zeros((4, 4, 4), np.complex64), "not supported"),
        (np.zeros((4, 4, 4), np.float16), "not supported"),
        (np.zeros((0, 4, 4)), "empty"),
    ],
)
def test_bad_arrays_are_value_errors(bad, message):
    with pytest.raises(ValueError, match=message):
        volcast.render(scene_for(), volume=bad)


def test_bad_spacing_is_a_value_error():
    a = field("uint8")
    with pytest.raises(ValueError, match="spacing"):
        volcast.render(scene_for(), volume=a, spacing=[1, 2])
    with pytest.raises(ValueError, match="spacing"):
        volcast.render(scene_for(), volume=a, spacing=[1, 0, 1])
    with pytest.raises(ValueError, match="spacing and origin"):
        volcast.render(scene_for("x.nrrd"), spacing=[1, 1, 1])
