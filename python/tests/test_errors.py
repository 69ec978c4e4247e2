"""Every kind of failure from Python: a clear exception of its kind naming the key, never a
panic (pyo3's PanicException) or a crash."""

import math
import re

import numpy as np
import pytest

import deasim


def diaphragm():
    return deasim.Scenario.from_example("diaphragm")


def test_a_bad_key_names_its_path():
    with pytest.raises(deasim.ScenarioError) as e:
        diaphragm().set("materials.vhb.c10x", 1.0).run()
    assert e.value.key == "materials.vhb.c10x"
    assert "c10x" in str(e.value) and "<embedded diaphragm>" in str(e.value)


def test_a_solve_failure_carries_the_steps_before():
    # one Newton iteration per step and no cut-back below half a step: the first loaded step
    # of the film fails (in milliseconds)
    s = (
        deasim.Scenario.from_example("film")
        .set("solver.newton_max_iterations", 1)
        .set("solver.min_step_fraction", 0.5)
    )
    with pytest.raises(deasim.SolveError) as e:
        s.run()
    assert isinstance(e.value, RuntimeError) and isinstance(e.value, deasim.DeasimError)
    assert "Newton did not converge in 1 iterations" in e.value.reason
    r = e.value.results
    assert not r.converged and not r.interrupted and len(r) >= 1
    assert r.summary["error"] == e.value.reason


def test_a_missing_file_is_an_os_error(tmp_path):
    missing = tmp_path / "no-such-scenario.toml"
    with pytest.raises(deasim.DeasimIOError) as e:
        deasim.Scenario.from_file(missing)
    assert isinstance(e.value, OSError) and str(missing) in str(e.value)
    assert isinstance(e.value, FileNotFoundError)
    assert isinstance(e.value, deasim.DeasimFileNotFoundError)
    # a file the scenario names (a mesh) is the scenario's error, naming the key
    s = deasim.Scenario.from_example("film").set("mesh", {"file": str(tmp_path / "none.msh")})
    with pytest.raises(deasim.ScenarioError) as e:
        s.run()
    assert e.value.key is not None and e.value.key.startswith("mesh")


@pytest.mark.parametrize(
    "key, value, says",
    [
        ("materials.vhb.c10", "soft", "expected a number"),
        ("materials.vhb.c10", [1.0, 2.0], "expected a number"),
        ("materials.vhb.c10", {"a": 1.0}, "expected a number"),
        ("materials.vhb.c10", math.nan, "must be finite"),
        ("materials.vhb.c10", np.float64(np.inf), "must be finite"),
        ("materials.vhb.c10", -1.0e4, "c10"),
        ("mesh.radial", -1, "expected a whole number ≥ 0"),
        ("mesh.radial", 2.5, "expected a whole number"),
        ("stages.0.steps", 0, "must be between 1"),
        ("stages.1.dt", -1e-3, "dt"),
    ],
)
def test_bad_values_name_their_key(key, value, says):
    # checked when the scenario is built, as the command line checks --set
    s = diaphragm().set(key, value)
    problems = s.check()
    assert len(problems) == 1 and says in problems[0], problems
    with pytest.raises(deasim.ScenarioError) as e:
        s.run()
    assert e.value.key == key and says in str(e.value)


@pytest.mark.parametrize(
    "key, value, says",
    [
        ("materials.vhb", {1: 2.0}, "keys must be strings; got the key 1 (int)"),
        ("materials.vhb.c10", object(), "cannot give a object"),
        ("mesh.radial", 2**70, "beyond the range of a 64-bit integer"),
    ],
)
def test_values_without_a_toml_form_are_refused_by_set(key, value, says):
    with pytest.raises(deasim.ScenarioError, match=re.escape(says)) as e:
        diaphragm().set(key, value)
    assert e.value.key == key and isinstance(e.value, ValueError)


def test_bad_tables_and_arguments_name_their_key():
    with pytest.raises(deasim.ScenarioError) as e:
        deasim.Scenario.from_dict({"mesh": {"generator": "disc", 3: 1}})
    assert e.value.key == "mesh"
    with pytest.raises(deasim.ScenarioError) as e:
        deasim.Scenario.from_dict({"stages": [{"name": "a"}, {None: 1}]})
    assert e.value.key == "stages.1"
    for call, key in [
        (lambda: diaphragm().modes(count=-1), "count"),
        (lambda: diaphragm().modes(count=0), "count"),
        (lambda: diaphragm().modes(shift_hz=math.nan), "shift_hz"),
        (lambda: diaphragm().reduce(modes=-2), "modes"),
        (lambda: diaphragm().reduce(bias=math.inf), "bias"),
        (lambda: diaphragm().frequency_response([1.0, math.nan]), "frequencies.1"),
    ]:
        with pytest.raises(deasim.ScenarioError) as e:
            call()
        assert e.value.key == key
    with pytest.raises(ValueError, match="fields"):
        diaphragm().run(fields="some")


def test_check_lists_every_wrong_override():
    s = (
        diaphragm()
        .set("materials.vhb.c10", math.nan)
        .set("mesh.radial", -1)
        .set("mesh.layers", 1)
        .set("stages.0.steps", 0)
    )
    problems = s.check()
    assert len(problems) == 3, problems
    for key in ["materials.vhb.c10", "mesh.radial", "stages.0.steps"]:
        assert sum(f"`{key}`" in p for p in problems) == 1, (key, problems)
    # the text's own first problem ends the list (the library stops there)
    bad = deasim.Scenario.from_toml(diaphragm().text.replace("radial = 12", "radial = -12"))
    problems = bad.set("mesh.radial", -3).set("stages.0.steps", 0).check()
    assert len(problems) == 2, problems
    assert "`-3`" in problems[0] and "`-12`" in problems[1] and "--set" not in problems[1]
    assert diaphragm().check() == []
