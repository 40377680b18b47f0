"""The notebook examples/python_turntable.ipynb runs top to bottom: its code cells,
in order, in one namespace, from the examples folder (no Jupyter server needed);
the last cell's turntable shows as HTML."""

import json
import os

import volcast
from conftest import ROOT

NOTEBOOK = ROOT / "examples" / "python_turntable.ipynb"


def test_notebook_runs_top_to_bottom(monkeypatch):
    nb = json.loads(NOTEBOOK.read_text())
    cells = ["".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code"]
    assert len(cells) >= 3
    monkeypatch.chdir(NOTEBOOK.parent)
    namespace = {"__name__": "__notebook__"}
    for n, code in enumerate(cells):
        exec(compile(code, f"{NOTEBOOK.name} cell {n}", "exec"), namespace)
    tt = namespace["tt"]
    assert isinstance(tt, volcast.Turntable)
    assert tt._repr_html_().startswith("<iframe")
    assert namespace["images"]["skin"].shape == (24, 192, 192, 3)
    assert os.getcwd() == str(NOTEBOOK.parent)
