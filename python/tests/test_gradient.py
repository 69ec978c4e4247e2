"""Scenario.gradient and deasim.calibrate against the command line (`deasim gradient`,
`deasim calibrate`) and against finite differences computed here."""

import json
import shutil

import numpy as np
import pytest

import deasim

from conftest import REPO

# the static film of tests/gradient.rs: the thickness stretch at the end against a target and
# the in-plane stretch's history against data, in μ, Λ, εᵣ and the voltage amplitude
PARAMETERS = """
[[parameters]]
path = "materials.elastomer.mu"
[[parameters]]
path = "materials.elastomer.lambda"
[[parameters]]
path = "materials.elastomer.permittivity"
[[parameters]]
path = "electrodes.top.voltage.amplitude"

[[objective]]
kind = "probe-final"
probe = "thickness_stretch"
target = 0.9
weight = 100.0

[[objective]]
kind = "probe-misfit"
probe = "inplane_stretch"
data = "data.csv"
"""
# a coarse mesh, the top electrode ramped to 20 kV in 5 steps
OVERRIDES = [
    ("mesh.divisions", [2, 2, 1]),
    ("stages.0.steps", 5),
    ("electrodes.top.voltage.amplitude", 20e3),
    ("solver.newton_rtol", 1e-13),
]


@pytest.fixture
def film(tmp_path):
    """The film scenario file (and its data) in tmp_path; returns its path."""
    (tmp_path / "data.csv").write_text("time,value\n0,1\n0.5,0.99\n1,0.96\n")
    path = tmp_path / "film.toml"
    path.write_text(deasim.Scenario.from_example("film").text + "\n" + PARAMETERS)
    return path


def scenario(path, **more):
    s = deasim.Scenario.from_file(path)
    for k, v in OVERRIDES + list(more.items()):
        s.set(k, v)
    return s


def test_gradient_is_the_command_lines(cli, film, tmp_path):
    args = ["gradient", str(film), "--out", "cli", "--check"]
    for k, v in OVERRIDES:
        args += ["--set", f"{k}={json.dumps(v)}"]
    cli(args, tmp_path)
    expect = json.loads((tmp_path / "cli" / "gradient.json").read_text())
    g = scenario(film).gradient(check=True, out=tmp_path / "py")
    assert g["objective"] == expect["objective"] > 0.0
    assert g["gradient"] == expect["gradient"]
    assert list(g["gradient"]) == [
        "materials.elastomer.mu",
        "materials.elastomer.lambda",
        "materials.elastomer.permittivity",
        "electrodes.top.voltage.amplitude",
    ]
    assert g["check"] == expect["check"]
    assert g["taylor"] == expect["taylor"]
    assert g["values"]["electrodes.top.voltage.amplitude"] == 20e3
    assert g["forward_s"] > 0.0 and g["adjoint_s"] > 0.0
    for path, d in g["gradient"].items():
        fd = g["check"][path]["finite_difference"]
        assert d != 0.0 and d == pytest.approx(fd, rel=1e-6), path
    assert all(abs(o - 2.0) <= 0.1 for o in g["taylor"]["order"][:2])
    # out= writes the forward run's files and gradient.json, as the command does
    written = json.loads((tmp_path / "py" / "gradient.json").read_text())
    assert written["gradient"] == expect["gradient"] and "values" not in written
    assert (tmp_path / "py" / "history.csv").is_file()


def test_gradient_against_a_central_difference_of_two_runs(film):
    # without check=True: no finite differences; computed here from the objectives of two runs
    g = scenario(film).gradient()
    assert "check" not in g and "taylor" not in g
    key = "materials.elastomer.mu"
    mu = g["values"][key]
    h = 1e-4 * mu
    up = scenario(film, **{key: mu + h}).gradient()["objective"]
    down = scenario(film, **{key: mu - h}).gradient()["objective"]
    assert g["gradient"][key] == pytest.approx((up - down) / (2 * h), rel=1e-6)


def test_gradient_needs_parameters():
    with pytest.raises(deasim.ScenarioError) as e:
        deasim.Scenario.from_example("film").gradient()
    assert e.value.key == "parameters"


def test_calibration_is_the_command_lines(cli, tmp_path):
    spec = REPO / "tests" / "data" / "calibrate" / "hossain2012.toml"
    cli(["calibrate", str(spec), "--out", "cli"], tmp_path)
    expect = json.loads((tmp_path / "cli" / "calibration.json").read_text())
    c = deasim.calibrate(spec, out=tmp_path / "py")
    assert c["converged"] and c["rms"] == expect["rms"] > 0.0
    assert c["parameters"] == expect["parameters"]
    assert c["fitted"] == {k: v["fitted"] for k, v in expect["parameters"].items()}
    for key in ["rms_by_experiment", "iterations", "reason", "correlation", "warnings"]:
        assert c[key] == expect[key], key
    assert c["model"] == "neo-hooke-split"
    assert (tmp_path / "py" / "fitted.toml").read_text() == c["fitted_toml"] == (
        tmp_path / "cli" / "fitted.toml"
    ).read_text()
    e = c["experiments"][0]
    assert e["name"] == "rate-0.01" and e["model"].shape == e["measured"].shape
    assert np.sqrt(np.mean((e["model"] - e["measured"]) ** 2)) == pytest.approx(e["rms"])
    # the spec as TOML text: its data paths from `base`
    text = spec.read_text()
    again = deasim.calibrate(text, base=spec.parent)
    assert again["fitted"] == c["fitted"]


def test_calibration_errors_keep_their_kind(tmp_path):
    with pytest.raises(FileNotFoundError) as e:
        deasim.calibrate(tmp_path / "no-such-spec.toml")
    assert isinstance(e.value, deasim.DeasimIOError) and "no-such-spec.toml" in str(e.value)
    spec = REPO / "tests" / "data" / "calibrate" / "hossain2012.toml"
    bad = spec.read_text().replace('path = "material.mu"', 'path = "material.mux"')
    with pytest.raises(deasim.ScenarioError) as e:
        deasim.calibrate(bad, base=spec.parent)
    assert e.value.key is not None and "parameters" in e.value.key
    with pytest.raises(deasim.ScenarioError) as e:
        deasim.calibrate(spec, starts=0)
    assert e.value.key == "starts"
