"""Scenario.control and Scenario.calibrate against the command line (`deasim control`,
`deasim calibrate` on a scenario): the same optimised drive and history of the objective, bounds
respected, the controlled scenario repeating J; the same fitted parameters."""

import json

import numpy as np

import deasim

# a short stage and a few iterations keep the test to seconds
SETS = {"stages.1.duration": 0.05, "output.plots": False, "output.fields_every": 0}


def test_control_equals_the_command_line(cli, tmp_path):
    s = deasim.Scenario.from_example("diaphragm-control")
    for key, value in SETS.items():
        s = s.set(key, value)
    r = s.control(max_iterations=4, out=tmp_path / "py")
    args = ["control", "diaphragm-control", "--out", str(tmp_path / "cli"), "--max-iterations", "4"]
    for key, value in SETS.items():
        args += ["--set", f"{key}={str(value).lower()}"]
    cli(args, tmp_path)
    doc = json.loads((tmp_path / "cli" / "control.json").read_text())
    assert r["objective"] == doc["objective"]
    assert r["final_objective"] == doc["final_objective"]
    assert r["iterations"] == 4 and r["objective"][-1] < r["objective"][0]
    (drive,) = r["drives"]
    assert drive["electrode"] == "top" and drive["stage"] == "actuate"
    assert drive["quantity"] == "voltage"
    assert isinstance(drive["voltage"], np.ndarray) and len(drive["voltage"]) == 51
    assert np.all((drive["voltage"] >= 0.0) & (drive["voltage"] <= 5000.0))
    table = np.loadtxt(tmp_path / "cli" / "control.csv", delimiter=",", skiprows=1)
    np.testing.assert_array_equal(table[:, 1], drive["voltage"])
    np.testing.assert_array_equal(table[:, 0], drive["time"])
    # the controlled scenario runs the optimised drive
    again = deasim.Scenario.from_toml(r["controlled"]).run()
    assert again.summary["converged"]
    # without the response model, as `--no-model`: the same start, another path
    plain = s.control(max_iterations=4, response_model=False)
    cli(args[:3] + [str(tmp_path / "cli-plain")] + args[4:] + ["--no-model"], tmp_path)
    doc = json.loads((tmp_path / "cli-plain" / "control.json").read_text())
    assert plain["objective"] == doc["objective"]
    assert plain["objective"][0] == r["objective"][0]
    assert plain["objective"][1:] != r["objective"][1:]


DEVICE = """
[[parameters]]
path = "materials.vhb.c10"
lower = 1e3
upper = 1e6
scale = "log"

[[objective]]
kind = "probe-final"
probe = "center_deflection"
stage = "load"
target = 2e-3
weight = 1e6
"""


def test_device_calibration_equals_the_command_line(cli, tmp_path):
    text = deasim.Scenario.from_example("diaphragm").text.replace(
        "duration = 1.0 ", "duration = 0.002 "
    ) + DEVICE
    (tmp_path / "dev.toml").write_text(text)
    r = deasim.Scenario.from_toml(text).calibrate()
    cli(["calibrate", "dev.toml", "--out", "cal"], tmp_path)
    doc = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    fitted = r["parameters"]["materials.vhb.c10"]["fitted"]
    assert fitted == doc["parameters"]["materials.vhb.c10"]["fitted"]
    assert abs(fitted / 17.85e3 - 1.0) < 5e-3
    assert r["converged"] and "c10 = " in r["fitted"]
    (curve,) = r["curves"]
    assert curve["term"] == "objective.0" and curve["probe"] == "center_deflection"
    assert len(curve["time"]) == len(curve["fitted"]) == 1
    assert abs(curve["fitted"][0] - curve["measured"][0]) < 1e-9
    assert (tmp_path / "cal" / "fit_objective_0.png").exists()
