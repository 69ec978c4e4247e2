"""Every embedded example by name: the command's text, a valid scenario, and a short run of the
cheap ones (a second in all)."""

import numpy as np
import pytest

import deasim

# runs in well under a second each (the others take seconds: 3-D meshes, long dynamic stages)
CHEAP = ["film", "film-arc", "film-charge", "film-vibration", "film-modes", "diaphragm", "balloon"]
# examples that stop on purpose
FAILS = {"film-pull-in": "pull-in", "membrane-wrinkling": "circumferential harmonic n = 19"}


def test_every_example_is_valid_and_the_command_lines(cli, tmp_path):
    names = deasim.examples()
    assert len(names) == len(set(names)) >= 14
    assert set(CHEAP) | set(FAILS) <= set(names)
    for name in names:
        s = deasim.Scenario.from_example(name)
        assert s.check() == [], name
        assert isinstance(s.warnings(), list)
        assert s.text == cli(["example", name], tmp_path).stdout, name


@pytest.mark.parametrize("name", CHEAP)
def test_cheap_examples_run(name):
    r = deasim.Scenario.from_example(name).run()
    assert r.converged and len(r) > 1, name
    h = r.history
    # (an arc-length stage's pseudo-time may turn back at a limit point)
    assert np.all(np.isfinite(h["time"])) and h["time"][-1] > 0.0
    assert r.fields()["row"] == len(r) - 1


def test_the_pull_in_example_stops_at_pull_in():
    with pytest.raises(deasim.SolveError) as e:
        deasim.Scenario.from_example("film-pull-in").run(fields="none")
    assert FAILS["film-pull-in"] in e.value.reason
    assert len(e.value.results) > 1


def test_the_wrinkling_example_stops_at_its_onset():
    with pytest.raises(deasim.SolveError) as e:
        deasim.Scenario.from_example("membrane-wrinkling").run(fields="none")
    assert FAILS["membrane-wrinkling"] in e.value.reason
    onset = e.value.results.summary["stages"][0]["instability"]
    assert onset["harmonic"] == 19 and onset["stopped"]
    assert onset["stable_load_factor"] < onset["load_factor"]
    assert 2600.0 < dict(onset["voltages"])["top"] < 2630.0
