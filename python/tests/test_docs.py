"""The worked example of docs/python.md runs as written: its python blocks in order, in one
namespace, in an empty directory, with matplotlib's Agg backend."""

import re

import pytest

from conftest import REPO


def test_the_worked_example_of_the_python_docs_runs(tmp_path, monkeypatch):
    matplotlib = pytest.importorskip("matplotlib")
    pytest.importorskip("scipy")
    pytest.importorskip("control")
    matplotlib.use("Agg")
    import numpy as np

    text = (REPO / "docs" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) >= 4
    monkeypatch.chdir(tmp_path)
    ns = {}
    for i, code in enumerate(blocks):
        exec(compile(code, f"docs/python.md block {i + 1}", "exec"), ns)
    for png in ["deflection.png", "sweep.png", "bode.png"]:
        assert (tmp_path / png).stat().st_size > 1000, png
    assert (tmp_path / "diaphragm" / "history.csv").is_file()
    # the run, the sweep, the reduced model and the fit give what the text says
    assert ns["r"].converged and len(ns["r"]) > 1000
    added = ns["deflection"] - ns["deflection"][0]
    assert np.all(np.diff(added) > 0), "the deflection grows with the voltage"
    m = ns["m"]
    k = ns["k"]
    gain = (-m.C @ np.linalg.solve(m.A, m.B) + m.D)[k, 0]
    assert ns["gain"] == pytest.approx(gain, rel=1e-9) and gain > 0
    assert ns["fit"].success
    assert ns["fit"].x[0] == pytest.approx(120.0, rel=0.02)
    matplotlib.pyplot.close("all")
