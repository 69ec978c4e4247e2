"""The package against the command line, number for number: the default run's history, the
reduced model's matrices, the gradient and the calibration. Both run the same engine on the same
thread count (the command inherits this process's environment, RAYON_NUM_THREADS included)."""

import csv
import json

import numpy as np
import pytest

import deasim

from conftest import REPO


def bits(a):
    """The IEEE 754 bit patterns of float64 values: equal bits, equal numbers (−0 ≠ 0)."""
    return np.asarray(a, dtype=np.float64).view(np.int64)


def read_csv(path):
    """A CSV with a header as (names, rows of str)."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def test_default_run_history_is_the_command_lines_bit_for_bit(cli, tmp_path):
    # history.csv holds each number in the shortest form that reads back to the same f64
    # (`{:e}`), so the in-memory columns must equal the command's file exactly; the file writes
    # NaN for any non-finite value
    cli(["run", "--out", "cli"], tmp_path)
    r = deasim.Scenario.from_example(deasim.default_example()).run(out=tmp_path / "py")
    names, rows = read_csv(tmp_path / "cli" / "history.csv")
    h = r.history
    assert len(rows) == len(r) > 1000
    assert set(names) - {"stage"} <= set(h), "every column of history.csv is in Results.history"
    compared = 0
    for k, name in enumerate(names):
        text = [row[k] for row in rows]
        if name == "stage":
            assert h["stage"] == text
            continue
        value = np.array([float(t) for t in text])
        col = h[name]
        finite = np.isfinite(value)
        assert np.array_equal(bits(col[finite]), bits(value[finite])), name
        assert not np.isfinite(col[~finite]).any(), name
        compared += 1
    assert compared == len(names) - 1 and compared >= 15
    # out= writes the command's file byte for byte
    assert (tmp_path / "py" / "history.csv").read_bytes() == (
        tmp_path / "cli" / "history.csv"
    ).read_bytes()


def test_reduced_model_matrices_are_the_command_lines(cli, tmp_path):
    cli(
        ["reduce", "--modes", "3", "--bias", "1500", "--set", "mesh.radial=8",
         "--set", "mesh.layers=1", "--out", "r"],
        tmp_path,
    )
    doc = json.loads((tmp_path / "r" / "reduced_model.json").read_text())
    m = deasim.Scenario.from_example("diaphragm").set("mesh.radial", 8).set(
        "mesh.layers", 1
    ).reduce(modes=3, bias=1500.0)
    # JSON numbers are written in shortest round-trip form: exact
    for name, attr in [("a", m.A), ("b", m.B), ("c", m.C), ("d", m.D)]:
        expect = np.array(doc[name], dtype=np.float64)
        assert attr.shape == expect.shape, name
        assert np.array_equal(bits(attr), bits(expect)), name
    assert np.array_equal(m.frequencies, doc["frequencies_hz"])
    # JSON writes null for a non-finite number (the capacitance probe's NaN)
    offsets = np.array([np.nan if x is None else x for x in doc["output_offsets"]])
    assert np.array_equal(m.output_offsets, offsets, equal_nan=True)
    assert m.outputs == doc["outputs"] and m.electrode == doc["electrode"]
    assert m.bias == doc["bias_v"]
    # A.csv … D.csv: the same matrices
    for name, attr in [("A", m.A), ("B", m.B), ("C", m.C), ("D", m.D)]:
        lines = (tmp_path / "r" / f"{name}.csv").read_text().split()
        values = np.array([line.split(",") for line in lines], dtype=np.float64)
        assert np.array_equal(bits(values), bits(attr)), name
