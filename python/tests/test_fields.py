"""The fields of a step: shapes and units as docs/output.md gives them for the field files, the
same numbers as the run's own VTU file, and to_meshio() through a VTU file and back."""

import re

import numpy as np
import pytest

import deasim

meshio = pytest.importorskip("meshio")


def run(out, name="diaphragm", **more):
    s = deasim.Scenario.from_example(name)
    for k, v in {"output.fields_every": 0, "output.plots": False, **more}.items():
        s.set(k, v)
    return s.run(out=out)


def last_vtu(out):
    """The last field file of fields.pvd and its time."""
    pvd = (out / "fields.pvd").read_text()
    t, f = re.findall(r'timestep="([^"]+)"[^>]*file="([^"]+)"', pvd)[-1]
    return float(t), meshio.read(out / f)


@pytest.mark.parametrize(
    "name, more",
    [
        ("diaphragm", {"mesh.radial": 8, "mesh.layers": 1}),  # axisymmetric quads
        ("film", {"mesh.divisions": [2, 2, 1]}),  # 3-D hexahedra
    ],
)
def test_fields_are_those_of_the_vtu_file(tmp_path, name, more):
    r = run(tmp_path / "out", name, **more)
    f = r.fields()
    t, vtu = last_vtu(tmp_path / "out")
    assert t == r.history["time"][f["row"]]
    n, c = f["points"].shape[0], f["cells"].shape[0]
    # shapes: n×3 points and displacements (m), n potentials (V), c×3 fields (V/m), c×3×3
    # stresses (Pa, row-major), c volume ratios
    assert vtu.points.shape == f["points"].shape == (n, 3)
    assert f["displacement"].shape == (n, 3) and f["potential"].shape == (n,)
    assert f["electric_field"].shape == (c, 3) and f["stress"].shape == (c, 3, 3)
    assert f["volume_ratio"].shape == (c,) and f["max_electric_field"].shape == (c,)
    # the same numbers (the file holds Float64 values exactly)
    assert np.array_equal(vtu.points, f["points"])
    (block,) = vtu.cells
    assert block.type == f["cell_type"] and np.array_equal(block.data, f["cells"])
    assert np.array_equal(vtu.point_data["displacement"], f["displacement"])
    assert np.array_equal(vtu.point_data["potential"].ravel(), f["potential"])
    cd = {k: v[0] for k, v in vtu.cell_data.items()}
    assert np.array_equal(cd["electric_field"], f["electric_field"])
    assert np.array_equal(cd["cauchy_stress"], f["stress"].reshape(c, 9))
    assert np.array_equal(cd["mechanical_stress"], f["mechanical_stress"].reshape(c, 9))
    assert np.array_equal(cd["J"].ravel(), f["volume_ratio"])
    # units: the potential reaches the voltage of the history (V); the stresses are symmetric
    v = r.history["voltage"][f["row"]]
    assert np.max(np.abs(f["potential"])) == pytest.approx(abs(v), rel=1e-12)
    assert np.allclose(f["stress"], np.swapaxes(f["stress"], 1, 2), rtol=0, atol=1e-9 * np.abs(f["stress"]).max())
    assert np.all(f["volume_ratio"] > 0.9) and np.all(f["volume_ratio"] < 1.1)


def test_diaphragm_fields_in_si_units(tmp_path):
    r = run(tmp_path / "out", **{"mesh.radial": 8, "mesh.layers": 1})
    f = r.fields()
    assert f["axisymmetric"] and f["cell_type"] == "quad"
    # reference points (R, Z, 0) in m: the 17.5 mm radius, the 1 mm thickness
    p = f["points"]
    assert p[:, 0].min() == 0.0 and p[:, 0].max() == pytest.approx(17.5e-3)
    assert np.ptp(p[:, 1]) == pytest.approx(1e-3) and np.all(p[:, 2] == 0.0)
    # the pad's downward deflection (probe, m) is the axial displacement on the axis
    on_axis = p[:, 0] == 0.0
    w = -f["displacement"][on_axis, 1]
    deflection = r.history["probe:center_deflection"][f["row"]]
    # the probe and the field agree to about 2e-12 of the deflection, not bit for bit
    tol = 1e-9 * deflection
    assert w.min() - tol <= deflection <= w.max() + tol and 1e-4 < deflection < 1e-2
    # V/m: the true field through the film under the electrode, of the order of V / thickness
    v = r.history["voltage"][f["row"]]
    e = np.abs(f["electric_field"][:, 1]).max()
    assert v > 0 and 0.1 * v / 1e-3 < e < 100 * v / 1e-3
    assert f["max_electric_field"].max() >= e * (1 - 1e-12)


def test_to_meshio_round_trips_through_a_vtu_file(tmp_path):
    r = run(tmp_path / "out", **{"mesh.radial": 8, "mesh.layers": 1})
    m = r.to_meshio()
    meshio.write(tmp_path / "step.vtu", m)
    back = meshio.read(tmp_path / "step.vtu")
    f = r.fields()
    assert np.array_equal(back.points, f["points"])
    assert np.array_equal(back.cells[0].data, f["cells"])
    assert np.array_equal(back.point_data["displacement"], f["displacement"])
    assert np.array_equal(back.point_data["potential"].ravel(), f["potential"])
    assert np.array_equal(back.cell_data["stress"][0], f["stress"].reshape(-1, 9))
    assert np.array_equal(back.cell_data["volume_ratio"][0].ravel(), f["volume_ratio"])
