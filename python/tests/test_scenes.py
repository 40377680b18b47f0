"""`volcast.render` returns the command line's pixels bit for bit for every example
scene (shrunk through the dict to a few small frames), and writes its files with
`out`."""

import sys
from pathlib import Path

import numpy as np
import pytest

import volcast
from conftest import ROOT, assert_same, read_outputs, write_scene

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    tomllib = pytest.importorskip("tomli")

SCENES = sorted((ROOT / "scenes").glob("*.toml"))


def shrunk(path):
    """The scene of `path` as a dict, at 40 x 32 pixels and 2 frames, its volume paths
    absolute (of `[volume]`, or of each `[[volume]]`)."""
    scene = tomllib.loads(path.read_text())
    vol = scene.get("volume", {})
    for v in vol if isinstance(vol, list) else [vol]:
        if "path" in v:
            v["path"] = str((path.parent / v["path"]).resolve())
    scene.setdefault("image", {})["size"] = [40, 32]
    scene["image"].pop("width", None)
    scene["image"].pop("height", None)
    if "keyframe" not in scene:
        scene.setdefault("orbit", {})["frames"] = 2
    scene.pop("animation", None)
    scene.pop("viewer", None)
    return scene


def cli_images(cli, scene, tmp_path, result):
    tmp_path.mkdir(parents=True, exist_ok=True)
    file = write_scene(scene, tmp_path / "scene.toml")
    out = tmp_path / "cli"
    cli("render", file, "--quiet", "--out", out)
    ext = "nrrd" if scene.get("image", {}).get("format") == "nrrd" else "png"
    frames = range(next(iter(result.values())).shape[0])
    return read_outputs(out, result.keys(), frames, ext)


def test_every_example_scene_is_covered():
    assert len(SCENES) >= 10


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_example_scene_pixels_match_the_command_line(cli, tmp_path, path):
    scene = shrunk(path)
    result = volcast.render(scene)
    assert result, "no passes"
    for k, a in result.items():
        assert a.ndim in (3, 4) and a.shape[0] >= 1, (k, a.shape)
    assert_same(result, cli_images(cli, scene, tmp_path, result))


def test_out_writes_the_command_lines_files(cli, tmp_path):
    scene = shrunk(ROOT / "scenes" / "head_modes.toml")
    out = tmp_path / "py"
    result = volcast.render(scene, out=out)
    files = sorted(p.name for p in out.glob("*.png"))
    assert files and (out / "manifest.json").exists()
    assert_same(result, read_outputs(out, result.keys(), range(2), "png"))
    cli_out = tmp_path / "cli"
    cli("render", write_scene(scene, tmp_path / "s.toml"), "--quiet", "--out", cli_out)
    for name in files:
        assert (out / name).read_bytes() == (cli_out / name).read_bytes(), name
    # the same pixels as without out
    assert_same(result, volcast.render(scene))


def test_scene_as_toml_text_and_as_path(tmp_path):
    scene = shrunk(ROOT / "scenes" / "mip_head.toml")
    file = write_scene(scene, tmp_path / "mip.toml")
    by_dict = volcast.render(scene)
    assert_same(volcast.render(file.read_text()), by_dict)
    assert_same(volcast.render(file), by_dict)
    assert_same(volcast.render(str(file)), by_dict)


def test_formats_give_their_dtypes(tmp_path, cli):
    base = {
        "volume": {"synthetic": "ball", "sizes": [24, 24, 24]},
        "orbit": {"frames": 2},
        "render": [{"mode": "mip"}, {"name": "shaded", "mode": "surface", "iso": 0.5}],
    }
    for fmt, dtype in [("png", np.uint8), ("png16", np.uint16), ("nrrd", np.float32)]:
        scene = dict(base, image={"size": [20, 16], "format": fmt})
        result = volcast.render(scene)
        assert result["mip"].dtype == dtype and result["mip"].shape == (2, 16, 20)
        channels = 4 if fmt == "nrrd" else 3
        assert result["shaded"].shape == (2, 16, 20, channels), (fmt, result["shaded"].shape)
        assert_same(result, cli_images(cli, scene, tmp_path / fmt, result))
