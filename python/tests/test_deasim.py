"""The Python package against the command line on the same scenarios, and its own behaviour:
overrides, errors, array shapes, progress and cancellation."""

import json
import os
import signal
import threading

import numpy as np
import pytest

import deasim

# a coarse diaphragm: the modes and the reduced model in well under a second
COARSE = {"mesh.radial": 8, "mesh.layers": 1}


def coarse():
    s = deasim.Scenario.from_example("diaphragm")
    for k, v in COARSE.items():
        s.set(k, v)
    return s


def test_examples_list_the_default():
    names = deasim.examples()
    assert deasim.default_example() in names
    assert "film" in names


def test_default_example_matches_the_command_line(cli, tmp_path):
    cli(["run", "--out", "cli"], tmp_path)
    summary = json.loads((tmp_path / "cli" / "summary.json").read_text())
    r = deasim.Scenario.from_example(deasim.default_example()).run(out=tmp_path / "py")
    assert r.converged and not r.interrupted
    expect = summary["probe_stats"]["center_deflection"]["final"]
    assert r.probes["center_deflection"]["last"] == pytest.approx(expect, rel=1e-12)
    assert r.history["probe:center_deflection"][-1] == pytest.approx(expect, rel=1e-12)
    assert r.summary["dofs"] == summary["dofs"]
    # out= writes the files of `deasim run`
    for name in ["summary.json", "history.csv", "fields.pvd"]:
        assert (tmp_path / "py" / name).is_file(), name
    py_summary = json.loads((tmp_path / "py" / "summary.json").read_text())
    assert py_summary["probe_stats"]["center_deflection"]["final"] == pytest.approx(expect)


def test_history_fields_and_dtypes():
    r = coarse().run(fields="every")
    h = r.history
    n = len(r)
    assert n > 1
    for name in ["time", "voltage", "stored", "probe:center_deflection", "dt"]:
        assert h[name].dtype == np.float64 and h[name].shape == (n,), name
    assert len(h["stage"]) == n and isinstance(h["stage"][0], str)
    assert np.all(np.diff(h["time"]) >= 0)
    assert r.field_steps == list(range(n))
    f = r.fields()
    nodes, cells = f["points"].shape[0], f["cells"].shape[0]
    assert f["points"].shape == (nodes, 3) and f["points"].dtype == np.float64
    assert f["cells"].shape == (cells, 4) and f["cells"].dtype == np.int64
    assert f["cell_type"] == "quad" and f["axisymmetric"]
    assert f["displacement"].shape == (nodes, 3)
    assert f["potential"].shape == (nodes,)
    assert f["electric_field"].shape == (cells, 3)
    assert f["stress"].shape == (cells, 3, 3)
    assert f["volume_ratio"].shape == (cells,)
    assert f["row"] == n - 1
    # the last row's deflection is the history's
    first = r.fields(0)
    assert first["row"] == 0
    with pytest.raises(ValueError):
        coarse().run(fields="none").fields()


def test_overrides_change_the_result():
    soft = coarse().set("materials.vhb.c10", 2.0e4).run(fields="none")
    stiff = coarse().set("materials.vhb.c10", 4.0e4).run(fields="none")
    a = soft.probes["center_deflection"]["last"]
    b = stiff.probes["center_deflection"]["last"]
    assert a != b
    assert coarse().set("materials.vhb.c10", 2e4).overrides[-1] == "materials.vhb.c10=20000.0"


def test_from_toml_and_from_dict_read_the_same_scenario():
    text = deasim.Scenario.from_example("film").text
    a = deasim.Scenario.from_toml(text).run(fields="none")
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    d = tomllib.loads(text)
    b = deasim.Scenario.from_dict(d).run(fields="none")
    assert a.history["stored"][-1] == pytest.approx(b.history["stored"][-1], rel=1e-12)


def test_bad_key_raises_a_scenario_error_naming_it():
    s = coarse().set("materials.vhb.c10x", 1.0)
    problems = s.check()
    assert len(problems) == 1 and "c10x" in problems[0]
    with pytest.raises(deasim.ScenarioError) as e:
        s.run()
    assert e.value.key is not None and "c10x" in e.value.key
    assert isinstance(e.value, deasim.DeasimError) and isinstance(e.value, ValueError)
    assert coarse().check() == []
    with pytest.raises(deasim.ScenarioError):
        deasim.Scenario.from_example("no-such-example")
    with pytest.raises(deasim.DeasimIOError) as io:
        deasim.Scenario.from_file("/no/such/file.toml")
    assert isinstance(io.value, OSError)
    with pytest.raises(deasim.ScenarioError) as e:
        coarse().set("materials.vhb.c10", object())
    assert e.value.key == "materials.vhb.c10"


def test_modes_match_the_command_line(cli, tmp_path):
    args = ["modes", "--count", "4", "--out", "m"]
    for k, v in COARSE.items():
        args += ["--set", f"{k}={v}"]
    cli(args, tmp_path)
    lines = (tmp_path / "m" / "modes.csv").read_text().splitlines()[1:]
    expect = [float(line.split(",")[1]) for line in lines]
    m = coarse().modes(count=4, out=tmp_path / "py")
    assert m.frequencies.shape == (4,) and m.frequencies.dtype == np.float64
    np.testing.assert_allclose(m.frequencies, expect, rtol=1e-6)
    assert m.shapes.shape[0] == 4 and m.shapes.shape[2] == 4
    assert m.note is not None and "axisymmetric" in m.note
    assert (tmp_path / "py" / "modes.csv").is_file()


def test_harmonic_modes_match_the_command_line(cli, tmp_path):
    args = ["modes", "--count", "2", "--harmonic", "0,1,2", "--out", "m"]
    for k, v in COARSE.items():
        args += ["--set", f"{k}={v}"]
    cli(args, tmp_path)
    rows = [line.split(",") for line in (tmp_path / "m" / "modes.csv").read_text().splitlines()[1:]]
    m = coarse().modes(count=2, harmonic=[0, 1, 2])
    np.testing.assert_allclose(m.frequencies, [float(r[1]) for r in rows], rtol=1e-6)
    assert list(m.harmonics) == [int(r[4]) for r in rows] == [0, 0, 1, 1, 2, 2]
    one = coarse().modes(count=2, harmonic=1)
    np.testing.assert_allclose(one.frequencies, m.frequencies[2:4], rtol=1e-12)
    with pytest.raises(deasim.ScenarioError, match="harmonic"):
        coarse().modes(harmonic=-1)


def test_modes_refuse_a_dynamic_start():
    with pytest.raises(deasim.ScenarioError, match="starts with a dynamic stage"):
        deasim.Scenario.from_example("film-vibration").modes()


def test_reduce_gives_state_space_matrices():
    r = coarse().reduce(modes=3, bias=1500.0)
    n = r.A.shape[0]
    p = len(r.outputs)
    assert r.A.shape == (n, n) and n >= 6
    assert r.B.shape == (n, 1)
    assert r.C.shape == (p, n)
    assert r.D.shape == (p, 1)
    assert r.frequencies.shape == (3,)
    # a step of 1 V: the deflection settles where the static gain -C A⁻¹ B + D puts it
    t = np.linspace(0.0, 2.0, 4001)
    y = r.simulate(t, np.full_like(t, r.bias + 1.0))
    k = r.outputs.index("center_deflection")
    gain = (-r.C @ np.linalg.solve(r.A, r.B) + r.D)[k, 0]
    assert y.shape == (t.size, p)
    assert y[-1, k] - r.output_offsets[k] == pytest.approx(gain, rel=1e-3)


def test_frequency_response_is_complex_per_probe():
    f = np.array([1.0, 10.0, 100.0])
    fr = coarse().frequency_response(f, bias=1500.0)
    np.testing.assert_array_equal(fr.frequencies, f)
    h = fr.probes["center_deflection"]
    assert h.dtype == np.complex128 and h.shape == (3,)
    assert fr.electrode and fr.bias == 1500.0


def test_progress_callback_is_called_per_step():
    seen = []
    r = coarse().run(progress=seen.append, fields="none")
    assert len(seen) == len(r)
    assert seen[-1]["steps_done"] == len(r)
    assert seen[-1]["time"] == pytest.approx(r.history["time"][-1])
    assert {"stage", "step", "time", "dt", "voltage"} <= set(seen[0])


def test_a_raising_callback_stops_the_run_cleanly():
    class Stop(Exception):
        pass

    def progress(info):
        if info["steps_done"] == 5:
            raise Stop("enough")

    with pytest.raises(Stop) as e:
        coarse().run(progress=progress)
    r = e.value.results
    assert r.interrupted and len(r) == 5
    # the last accepted state is kept
    assert r.fields()["row"] == 4
    with pytest.raises(deasim.Interrupted) as i:
        coarse().run(progress=lambda info: info["steps_done"] < 3)
    assert len(i.value.results) == 3


def test_ctrl_c_stops_the_run_at_its_last_accepted_step():
    # SIGINT from another thread once the engine runs (the GIL released): the run stops after
    # the step under way and KeyboardInterrupt carries the results of the accepted steps
    started = threading.Event()

    def interrupt():
        started.wait()
        os.kill(os.getpid(), signal.SIGINT)

    thread = threading.Thread(target=interrupt)
    thread.start()
    try:
        with pytest.raises(KeyboardInterrupt) as e:
            deasim.Scenario.from_example("diaphragm").set("mesh.radial", 24).run(
                progress=lambda info: started.set()
            )
    finally:
        started.set()
        thread.join()
    r = e.value.results
    assert r.interrupted and 0 < len(r) < 1006
    assert r.fields()["row"] == len(r) - 1


def test_material_test_matches_the_command_line(cli, tmp_path):
    cli(
        ["material", "vhb4910-wang2016", "--rate", "0.05", "--steps", "20", "--out", "mt"],
        tmp_path,
    )
    rows = [
        line.split(",")
        for line in (tmp_path / "mt" / "uniaxial.csv").read_text().splitlines()
        if line and line[0].isdigit()
    ]
    curves = deasim.material_test("vhb4910-wang2016", "uniaxial", rates=[0.05], steps=20)
    assert len(curves) == 1
    c = curves[0]
    assert c["stretch"].shape == (len(rows),) and c["nominal_stress"].dtype == np.float64
    np.testing.assert_allclose(c["nominal_stress"], [float(r[4]) for r in rows], rtol=1e-9)
    with pytest.raises(deasim.ScenarioError) as e:
        deasim.material_test("vhb4910-wang2016", "torsion")
    assert e.value.key == "test"
    with pytest.raises(deasim.ScenarioError):
        deasim.material_test("no-such-preset")
    # a scenario's material
    s = deasim.material_test(coarse(), "equibiaxial", stretch=1.5, rates=[0.1], steps=20)
    assert s[0]["stretch"][-1] == pytest.approx(1.5)
    assert np.all(np.diff(s[0]["nominal_stress"]) > 0)


def test_lumped_model_matches_the_command_line(cli, tmp_path):
    out = cli(["lumped", "--out", "lp"], tmp_path).stdout
    line = next(x for x in out.splitlines() if "natural frequency" in x)
    expect = float(line.split("natural frequency")[1].split("Hz")[0])
    lumped = deasim.Scenario.from_example("diaphragm").lumped()
    assert lumped["linearised"]["natural_frequency"] == pytest.approx(expect, abs=1e-4)
    h = lumped["history"]
    assert h["time"].shape == h["deflection"].shape
    csv = (tmp_path / "lp" / "lumped.csv").read_text().splitlines()
    assert len(csv) - 1 == h["time"].size
    with pytest.raises(deasim.ScenarioError) as e:
        deasim.Scenario.from_example("film").lumped()
    assert e.value.key == "mesh.generator"


def test_optional_converters_need_their_package():
    r = coarse().run()
    m = coarse().reduce(modes=2, bias=1500.0)
    for call, module in [
        (r.to_pandas, "pandas"),
        (r.to_meshio, "meshio"),
        (m.to_control, "control"),
    ]:
        try:
            __import__(module)
        except ImportError:
            with pytest.raises(ImportError, match=f"pip install {module}"):
                call()
        else:
            assert call() is not None


def test_readme_example_runs_as_written():
    from conftest import REPO

    readme = (REPO / "README.md").read_text()
    section = readme.split("## Python", 1)[1]
    code = section.split("```python", 1)[1].split("```", 1)[0]
    namespace = {}
    exec(compile(code, "README.md", "exec"), namespace)
    assert namespace["A"].shape[0] == namespace["A"].shape[1] == namespace["B"].shape[0]


def test_analyses_report_the_run_to_the_loaded_state():
    seen = []
    m = coarse().modes(count=2, progress=seen.append)
    assert len(m) == 2 and seen and all(info["stage"] != "actuate" for info in seen)
    with pytest.raises(deasim.Interrupted) as e:
        coarse().reduce(modes=2, progress=lambda info: False)
    assert e.value.results.interrupted and len(e.value.results) == 1
