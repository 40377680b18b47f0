"""Errors (with the command line's messages), info, check, the turntable page and
Ctrl-C."""

import _thread
import json
import threading
import time

import numpy as np
import pytest

import volcast
from conftest import ROOT, write_scene

BALL = {"synthetic": "ball", "sizes": [16, 16, 16]}


def small(**extra):
    s = {"volume": dict(BALL), "orbit": {"frames": 2}, "image": {"size": [24, 20]}, "render": [{"mode": "mip"}]}
    s.update(extra)
    return s


# ---- errors ----


def test_scene_error_has_the_command_lines_message_file_line_and_key(cli, tmp_path):
    text = '[volume]\nsynthetic = "ball"\n\n[[render]]\nmode = "mip"\n\n[[render]]\nname = "b"\nmode = "mipp"\n'
    file = tmp_path / "bad.toml"
    file.write_text(text)
    p = cli("render", file, "--out", tmp_path / "o", check=False)
    assert p.returncode != 0
    with pytest.raises(volcast.SceneError) as e:
        volcast.render(file)
    assert p.stderr.strip() == f"volcast: error: {e.value}"
    err = e.value
    assert (err.file, err.line, err.column, err.key) == (str(file), 9, 8, "render[1].mode")
    assert "did you mean `mip`?" in str(err)
    assert len(err.problems) == 1 and err.problems[0]["line"] == 9
    assert isinstance(err, volcast.VolcastError)


def test_scene_errors_of_text_and_dicts_name_them():
    with pytest.raises(volcast.SceneError) as e:
        volcast.render('[volume]\nsynthetic = "ball"\n[image]\nsize = [0, 10]\n[[render]]\nmode = "mip"\n')
    assert e.value.file == "<string>" and e.value.line == 4 and e.value.key == "image.size"
    assert str(e.value).startswith("<string>:4:")
    with pytest.raises(volcast.SceneError) as e:
        volcast.render(small(camera={"fovv": 30}))
    assert e.value.file == "<dict>" and e.value.key is not None and "fovv" in str(e.value)
    # every problem, as the command line lists them
    with pytest.raises(volcast.SceneError) as e:
        volcast.render(small(camera={"fovv": 30}, image={"size": [0, 1]}))
    assert len(e.value.problems) == 2 and "2 problems" in str(e.value)


def test_unreadable_volume_is_a_volcast_error_with_the_path(tmp_path):
    with pytest.raises(volcast.VolcastError, match="nowhere.nrrd"):
        volcast.render({"volume": {"path": str(tmp_path / "nowhere.nrrd")}, "render": [{"mode": "mip"}]})


def test_bad_scene_arguments():
    with pytest.raises(TypeError):
        volcast.render(42)
    with pytest.raises(TypeError):
        volcast.render({"volume": {"synthetic": object()}, "render": []})


# ---- info and check ----


def test_info_is_the_command_lines_json(cli):
    for name in ["ct_head_vtk_quarter.nrrd", "ct_head_vtk_quarter.nii.gz"]:
        path = ROOT / "data" / name
        expected = json.loads(cli("info", "--json", path).stdout)
        assert volcast.info(path) == expected
        assert volcast.info(str(path)) == expected


def test_info_of_an_array():
    a = np.arange(24, dtype=np.int16).reshape(2, 3, 4) - 5
    i = volcast.info(a, spacing=[2, 3, 4], origin=[1, 1, 1])
    assert (i["sizes"], i["type"], i["min"], i["max"]) == ([2, 3, 4], "int16", -5.0, 18.0)
    assert i["spacing"] == [2.0, 3.0, 4.0] and i["origin"] == [1.0, 1.0, 1.0]
    assert i["finite"] == 24


def test_check_gives_the_plan_and_the_command_lines_text(cli, tmp_path):
    scene = small(render=[{"mode": "mip"}, {"name": "iso", "mode": "surface"}])
    file = write_scene(scene, tmp_path / "s.toml")
    plan = volcast.check(file)
    assert plan["text"] == cli("check", file).stdout
    assert (plan["width"], plan["height"], plan["frames"]) == (24, 20, 2)
    assert [p["name"] for p in plan["passes"]] == ["mip", "iso"]
    assert plan["passes"][0]["files"][0].endswith("mip_0000.png")
    assert plan["memory_bytes"] > 0 and plan["volume"]["sizes"] == [16, 16, 16]
    by_dict = volcast.check(scene)
    assert by_dict["text"].startswith("scene    <dict>")
    a = np.zeros((5, 6, 7), np.float32, order="F")
    with_array = volcast.check(scene, volume=a)
    assert with_array["volume"]["sizes"] == [5, 6, 7]
    assert "in memory" in with_array["volume"]["storage"]


# ---- the turntable ----


def test_turntable_page_inlines_its_frames(tmp_path):
    t = volcast.turntable(small(orbit={"frames": 4}))
    assert t.images["mip"].shape == (4, 20, 24) and t.out is None
    assert t.html.count("data:image/png;base64,") == 4
    assert "mip_0000.png" not in t.html
    page = t._repr_html_()
    assert page.startswith("<iframe srcdoc=") and "&lt;script" in page
    t.save(tmp_path / "page.html")
    assert (tmp_path / "page.html").read_text() == t.html
    # with out, the folder keeps the frames and the page
    out = tmp_path / "tt"
    t2 = volcast.turntable(small(orbit={"frames": 4}), out=out)
    assert (out / "index.html").exists() and (out / "mip_0003.png").exists()
    assert t2.images["mip"].tobytes() == t.images["mip"].tobytes()
    assert t2.html == t.html


def test_turntable_needs_png_frames():
    with pytest.raises(ValueError, match="PNG"):
        volcast.turntable(small(image={"size": [8, 8], "format": "nrrd"}))


# ---- Ctrl-C and the GIL ----


def long_scene():
    """A render of seconds on any machine, its films few: 60 frames of a composite
    that is nowhere transparent (nothing is skipped), at a fine step."""
    return {
        "volume": {"synthetic": "blobs", "sizes": [96, 96, 96]},
        "orbit": {"frames": 60},
        "image": {"size": [192, 192]},
        "transfer": {"fog": {"color": [[0.0, [1.0, 1.0, 1.0]]], "alpha": [[0.0, 0.002], [1.0, 0.02]]}},
        "render": [{"mode": "composite", "transfer": "fog", "step": 0.05, "early_stop": 1.0}],
    }


def test_ctrl_c_stops_a_render_with_keyboard_interrupt():
    timer = threading.Timer(1.0, _thread.interrupt_main)
    start = time.monotonic()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        volcast.render(long_scene())
    took = time.monotonic() - start
    timer.cancel()
    # the run stops at its next view, not at the end of 60 frames
    assert took < 15, took


def test_the_gil_is_released_while_rendering():
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.01)

    t = threading.Thread(target=tick)
    t.start()
    scene = long_scene()
    scene["orbit"]["frames"] = 2
    start = time.monotonic()
    volcast.render(scene)
    took = time.monotonic() - start
    stop.set()
    t.join()
    assert took > 0.2, "the scene renders too fast to tell"
    during = [x for x in ticks if start < x < start + took]
    assert len(during) > took / 0.05, (len(during), took)
