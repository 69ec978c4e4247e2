"""deasim: finite-strain electro-mechanical simulation of dielectric elastomer actuators.

The engine is the Rust library; this package only converts. Build a :class:`Scenario`, run it
and read its :class:`Results`, or take its small-signal models (:meth:`Scenario.modes`,
:meth:`Scenario.frequency_response`, :meth:`Scenario.reduce`), its gradient
(:meth:`Scenario.gradient`), or fit a material to measured curves (:func:`calibrate`). See
docs/python.md.
"""

from typing import Any, Dict

from ._deasim import (
    FrequencyResponse,
    Modes,
    ReducedModel,
    Results,
    Scenario,
    __version__,
    calibrate,
    default_example,
    examples,
    material_test,
)
from ._errors import (
    DeasimError,
    DeasimFileNotFoundError,
    DeasimIOError,
    Interrupted,
    ScenarioError,
    SolveError,
)

__all__ = [
    "Scenario",
    "Results",
    "Modes",
    "FrequencyResponse",
    "ReducedModel",
    "examples",
    "material_test",
    "calibrate",
    "default_example",
    "DeasimError",
    "ScenarioError",
    "SolveError",
    "DeasimIOError",
    "DeasimFileNotFoundError",
    "Interrupted",
    "__version__",
]


def _to_pandas(self: Results) -> Any:
    """The history as a pandas DataFrame (one column per quantity, `stage` included)."""
    try:
        import pandas
    except ImportError as e:
        raise ImportError("Results.to_pandas() needs pandas: pip install pandas") from e
    return pandas.DataFrame(self.history)


def _to_meshio(self: Results, step: Any = None) -> Any:
    """The fields of a kept step as a meshio Mesh (point data: displacement, potential; cell
    data: the cell fields)."""
    try:
        import meshio
    except ImportError as e:
        raise ImportError("Results.to_meshio() needs meshio: pip install meshio") from e
    f = self.fields(step)
    point_data = {"displacement": f["displacement"], "potential": f["potential"]}
    cell_names = [
        "electric_field",
        "stress",
        "mechanical_stress",
        "volume_ratio",
        "max_electric_field",
    ]
    cell_data: Dict[str, Any] = {}
    for n in cell_names:
        v = f[n]
        cell_data[n] = [v.reshape(v.shape[0], -1) if v.ndim > 2 else v]
    return meshio.Mesh(
        f["points"], [(f["cell_type"], f["cells"])], point_data=point_data, cell_data=cell_data
    )


def _to_control(self: ReducedModel) -> Any:
    """The model as a python-control StateSpace (input: the voltage change; outputs: the
    probes)."""
    try:
        import control
    except ImportError as e:
        raise ImportError("ReducedModel.to_control() needs python-control: pip install control") from e
    return control.ss(self.A, self.B, self.C, self.D)


Results.to_pandas = _to_pandas  # type: ignore[attr-defined]
Results.to_meshio = _to_meshio  # type: ignore[attr-defined]
ReducedModel.to_control = _to_control  # type: ignore[attr-defined]
