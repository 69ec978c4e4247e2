//! The Python module `deasim._deasim`: scenarios, runs and their results, the small-signal
//! analyses (modes, frequency response, reduced model), the gradient and the material
//! calibration over the library interface [`deasim::api`]. The engine runs with the GIL
//! released; a progress callback and Ctrl-C are served between the steps of a run, and either
//! stops it cleanly at its last accepted state. The Python layer (`deasim/__init__.py`) adds
//! only conveniences (pandas, meshio, python-control).

use deasim::api::{self, Cancel, Error, FieldsKept, RunOptions, Simulation};
use deasim::element::CellFields;
use deasim::io::build::Plan;
use deasim::io::scenario::InputError;
use deasim::job::observer::Observer;
use deasim::job::state::{RunSummary, StepRecord};
use deasim::mesh::{ElementKind, MeridianKind};
use deasim::time::modal::ModeSettings;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use std::path::{Path, PathBuf};

/// The exception class `name` of `deasim._errors`.
fn error_class<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("deasim._errors")?.getattr(name)
}

/// The Python exception of a library error, keeping its kind: `ScenarioError` (with `.key`),
/// `SolveError` (with `.reason`), `DeasimIOError`, `Interrupted` (with `.reason`), the others
/// `DeasimError`; those of a run that started carry its `.results`.
fn to_py(py: Python<'_>, e: Error) -> PyErr {
    let message = e.to_string();
    let build = || -> PyResult<PyErr> {
        let (class, key, reason, results) = match e {
            Error::Input(i) => ("ScenarioError", i.key.clone(), None, None),
            Error::Solve { reason, results } => ("SolveError", None, Some(reason), Some(*results)),
            Error::Interrupted { reason, results } => {
                ("Interrupted", None, Some(reason), Some(*results))
            }
            // a file to read that does not exist: also a FileNotFoundError
            Error::Io { path, message }
                if message.starts_with("cannot read")
                    && std::fs::metadata(&path)
                        .is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound) =>
            {
                ("DeasimFileNotFoundError", None, None, None)
            }
            Error::Io { .. } => ("DeasimIOError", None, None, None),
            Error::Output { results, .. } => ("DeasimIOError", None, None, Some(*results)),
            Error::Refused(_) => ("ScenarioError", None, None, None),
            _ => ("DeasimError", None, None, None),
        };
        let value = error_class(py, class)?.call1((message.clone(),))?;
        value.setattr("key", key)?;
        if let Some(r) = reason {
            value.setattr("reason", r)?;
        }
        let results = match results {
            Some(r) => Some(Py::new(py, Results::new(r))?),
            None => None,
        };
        value.setattr("results", results)?;
        Ok(PyErr::from_value(value))
    };
    build().unwrap_or_else(|err| err)
}

/// A `ScenarioError` about `key` of `file` (a front end's name: `Scenario.set`, …).
fn input_error(py: Python<'_>, file: &str, key: &str, message: String) -> PyErr {
    let e = InputError {
        file: file.to_string(),
        position: None,
        key: (!key.is_empty()).then(|| key.to_string()),
        message,
    };
    to_py(py, Error::Input(e))
}

/// A Python value as a TOML value (bool, int, float, str, list, tuple, dict, numpy scalars);
/// `Err` says what is wrong and where below the value (`path`, a dotted key path).
fn to_toml(value: &Bound<'_, PyAny>, path: &str) -> Result<toml::Value, (String, String)> {
    let wrong = |message: String| (path.to_string(), message);
    let extracted = |e: PyErr| wrong(e.to_string());
    if value.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(value.extract().map_err(extracted)?));
    }
    if value.is_instance_of::<PyInt>() {
        return value
            .extract::<i64>()
            .map(toml::Value::Integer)
            .map_err(|_| {
                wrong(format!(
                    "the integer {value} is beyond the range of a 64-bit integer"
                ))
            });
    }
    if value.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(value.extract().map_err(extracted)?));
    }
    if value.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(value.extract().map_err(extracted)?));
    }
    if let Ok(d) = value.cast::<PyDict>() {
        let mut table = toml::map::Map::new();
        for (k, v) in d.iter() {
            let key: String = k.extract().map_err(|_| {
                wrong(format!(
                    "a table's keys must be strings; got the key {} ({})",
                    k.repr().map_or_else(|_| "?".into(), |r| r.to_string()),
                    k.get_type()
                        .name()
                        .map_or_else(|_| "?".into(), |n| n.to_string())
                ))
            })?;
            let below = if path.is_empty() {
                key.clone()
            } else {
                format!("{path}.{key}")
            };
            table.insert(key, to_toml(&v, &below)?);
        }
        return Ok(toml::Value::Table(table));
    }
    if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        let items: Vec<Bound<'_, PyAny>> = value.extract().map_err(extracted)?;
        return Ok(toml::Value::Array(
            items
                .iter()
                .enumerate()
                .map(|(i, v)| to_toml(v, &format!("{path}.{i}")))
                .collect::<Result<_, _>>()?,
        ));
    }
    // numpy arrays and scalars
    if value.hasattr("tolist").unwrap_or(false) {
        let plain = value.call_method0("tolist").map_err(extracted)?;
        return to_toml(&plain, path);
    }
    Err(wrong(format!(
        "cannot give a {} as a scenario value: expected bool, int, float, str, list or dict",
        value
            .get_type()
            .name()
            .map_or_else(|_| "?".into(), |n| n.to_string())
    )))
}

/// A JSON document as Python objects (`json.loads`).
fn json_to_py<'py>(py: Python<'py>, doc: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(doc).map_err(|e| PyValueError::new_err(e.to_string()))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A `SolveError` with its `reason` (no results: nothing ran as a scenario).
fn solve_error(py: Python<'_>, reason: String) -> PyErr {
    error_class(py, "SolveError")
        .and_then(|c| c.call1((reason.clone(),)))
        .and_then(|v| v.setattr("reason", reason).map(|_| v))
        .map(PyErr::from_value)
        .unwrap_or_else(|e| e)
}

/// A count argument `name` of at least `min`, else a `ScenarioError` naming it.
fn count(py: Python<'_>, file: &str, name: &str, value: i64, min: i64) -> PyResult<usize> {
    if value < min {
        return Err(input_error(
            py,
            file,
            name,
            format!("expected a whole number ≥ {min}; got {value}"),
        ));
    }
    Ok(value as usize)
}

/// A number argument `name` that must be finite, else a `ScenarioError` naming it.
fn finite(py: Python<'_>, file: &str, name: &str, value: f64) -> PyResult<f64> {
    if !value.is_finite() {
        return Err(input_error(
            py,
            file,
            name,
            format!("must be finite; got {value}"),
        ));
    }
    Ok(value)
}

/// A column as a numpy array.
fn column<'py>(py: Python<'py>, v: &[f64]) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_slice(py, v)
}

/// Row-major rows as a 2-D numpy array (`cols` columns when there are no rows).
fn matrix<'py>(
    py: Python<'py>,
    rows: &[Vec<f64>],
    cols: usize,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = rows.len();
    let m = rows.first().map_or(cols, Vec::len);
    let flat: Vec<f64> = rows.iter().flatten().copied().collect();
    PyArray1::from_vec(py, flat).reshape([n, m])
}

/// Calls the progress callback after each accepted step and serves Ctrl-C: an exception of
/// either (or a callback returning `False`) cancels the run, which stops after that step.
struct Progress {
    callback: Option<Py<PyAny>>,
    cancel: Cancel,
    /// The exception that stopped the run.
    error: Option<PyErr>,
    stage: (usize, String),
    done: usize,
}

impl Progress {
    fn new(callback: Option<Py<PyAny>>) -> Self {
        Progress {
            callback,
            cancel: Cancel::new(),
            error: None,
            stage: (0, String::new()),
            done: 0,
        }
    }

    fn options(&mut self) -> RunOptions<'_> {
        let cancel = Some(self.cancel.clone());
        RunOptions {
            observers: vec![self],
            cancel,
            ..Default::default()
        }
    }

    /// The error of a run: the exception that stopped it (carrying the run's results), else the
    /// library's.
    fn error(&mut self, py: Python<'_>, e: Error) -> PyErr {
        match self.error.take() {
            Some(err) => {
                let results = e.results().cloned();
                if let Some(r) = results {
                    if let Ok(r) = Py::new(py, Results::new(r)) {
                        let _ = err.value(py).setattr("results", r);
                    }
                }
                err
            }
            None => to_py(py, e),
        }
    }
}

impl Observer for Progress {
    fn stage_started(&mut self, index: usize, name: &str) {
        self.stage = (index, name.to_string());
    }

    fn step(&mut self, _plan: &Plan, record: &StepRecord, _state: &[f64], _: &[CellFields]) {
        self.done += 1;
        if self.error.is_some() {
            return;
        }
        let outcome = Python::attach(|py| -> PyResult<bool> {
            py.check_signals()?;
            let Some(cb) = &self.callback else {
                return Ok(true);
            };
            let info = PyDict::new(py);
            info.set_item("stage", &record.stage)?;
            info.set_item("stage_index", self.stage.0)?;
            info.set_item("step", record.step)?;
            info.set_item("steps_done", self.done)?;
            info.set_item("time", record.time)?;
            info.set_item("dt", record.dt)?;
            info.set_item("voltage", record.voltage)?;
            info.set_item("newton_iterations", record.newton_iterations)?;
            let answer = cb.call1(py, (info,))?;
            // `False` asks to stop; anything else (None) goes on
            Ok(!answer.bind(py).is(PyBool::new(py, false)))
        });
        match outcome {
            Ok(true) => {}
            Ok(false) => {
                Python::attach(|py| {
                    self.error = Some(
                        error_class(py, "Interrupted")
                            .and_then(|c| c.call1(("stopped by the progress callback",)))
                            .map(PyErr::from_value)
                            .unwrap_or_else(|e| e),
                    )
                });
                self.cancel.cancel();
            }
            Err(e) => {
                self.error = Some(e);
                self.cancel.cancel();
            }
        }
    }

    fn finished(&mut self, _plan: &Plan, _summary: &RunSummary) {}
}

/// A scenario and its overrides.
#[pyclass(module = "deasim._deasim", name = "Scenario")]
#[derive(Clone)]
struct Scenario {
    sim: Simulation,
}

#[pymethods]
impl Scenario {
    /// The embedded example `name` (see `deasim.examples()`).
    #[staticmethod]
    fn from_example(py: Python<'_>, name: &str) -> PyResult<Self> {
        Simulation::from_example(name)
            .map(|sim| Scenario { sim })
            .map_err(|e| to_py(py, e))
    }

    /// The scenario file `path` (TOML); its relative paths are read from its directory.
    #[staticmethod]
    fn from_file(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        Simulation::from_file(&path)
            .map(|sim| Scenario { sim })
            .map_err(|e| to_py(py, e))
    }

    /// A scenario given as TOML text; relative paths are read from `base` (default: the working
    /// directory).
    #[staticmethod]
    #[pyo3(signature = (text, base=None))]
    fn from_toml(text: &str, base: Option<PathBuf>) -> Self {
        Scenario {
            sim: Simulation::from_toml(text, base.as_deref()),
        }
    }

    /// A scenario given as nested dictionaries (the tables of the TOML file).
    #[staticmethod]
    #[pyo3(signature = (d, base=None))]
    fn from_dict(py: Python<'_>, d: &Bound<'_, PyDict>, base: Option<PathBuf>) -> PyResult<Self> {
        let value = to_toml(d.as_any(), "")
            .map_err(|(key, message)| input_error(py, "Scenario.from_dict", &key, message))?;
        let text = toml::to_string(&value)
            .map_err(|e| PyValueError::new_err(format!("cannot write the scenario: {e}")))?;
        Ok(Self::from_toml(&text, base))
    }

    /// Sets `key` (a dotted key path, as `--set` takes) to `value`; returns the scenario.
    fn set<'py>(
        mut slf: PyRefMut<'py, Self>,
        key: &str,
        value: &Bound<'py, PyAny>,
    ) -> PyResult<PyRefMut<'py, Self>> {
        let v = to_toml(value, key)
            .map_err(|(k, message)| input_error(slf.py(), "Scenario.set", &k, message))?;
        slf.sim = slf.sim.clone().set(key, &v.to_string());
        Ok(slf)
    }

    /// The overrides `key=value`, in the order they apply.
    #[getter]
    fn overrides(&self) -> Vec<String> {
        self.sim.overrides().to_vec()
    }

    /// The scenario's TOML text, before the overrides.
    #[getter]
    fn text(&self) -> String {
        self.sim.text().to_string()
    }

    /// The problems that stop the scenario from running: empty when it is valid. The library
    /// stops at the first problem; an override it blames is dropped and the rest checked again,
    /// so every wrong override is listed, and then the first problem of the text.
    fn check(&self, py: Python<'_>) -> Vec<String> {
        let sim = self.sim.clone();
        py.detach(move || problems(&sim))
    }

    /// The warnings of a valid scenario's plan.
    fn warnings(&self, py: Python<'_>) -> PyResult<Vec<String>> {
        let sim = self.sim.clone();
        py.detach(move || sim.plan().map(|p| p.warnings))
            .map_err(|e| to_py(py, e))
    }

    /// Runs the scenario.
    #[pyo3(signature = (out=None, progress=None, fields="last", overwrite=false))]
    fn run(
        &self,
        py: Python<'_>,
        out: Option<PathBuf>,
        progress: Option<Py<PyAny>>,
        fields: &str,
        overwrite: bool,
    ) -> PyResult<Results> {
        let keep = match fields {
            "none" => FieldsKept::None,
            "last" => FieldsKept::Last,
            "every" => FieldsKept::Every,
            o => {
                return Err(PyValueError::new_err(format!(
                    "fields: expected \"none\", \"last\" or \"every\"; got {o:?}"
                )))
            }
        };
        let sim = self.sim.clone();
        let mut p = Progress::new(progress);
        let ran = py.detach(|| {
            let mut options = p.options();
            options.fields = keep;
            options.out = out;
            options.overwrite = overwrite;
            let plan = sim.plan()?;
            let mesh = Mesh::of(&plan);
            options.overrides = sim.overrides().to_vec();
            api::run_plan(&plan, options).map(|r| (r, mesh))
        });
        match ran {
            Ok((r, mesh)) => {
                let mut results = Results::new(r);
                results.mesh = Some(mesh);
                Ok(results)
            }
            Err(e) => Err(p.error(py, e)),
        }
    }

    /// The natural modes about the loaded state (the end of the static stages before the first
    /// dynamic one), `count` of them nearest `shift_hz` of each circumferential harmonic of
    /// `harmonic` (a whole number or a list; axisymmetric models, 0 the axisymmetric modes).
    #[pyo3(signature = (count=6, shift_hz=0.0, harmonic=None, out=None, progress=None, overwrite=false))]
    #[allow(clippy::too_many_arguments)]
    fn modes(
        &self,
        py: Python<'_>,
        count: i64,
        shift_hz: f64,
        harmonic: Option<Bound<'_, PyAny>>,
        out: Option<PathBuf>,
        progress: Option<Py<PyAny>>,
        overwrite: bool,
    ) -> PyResult<Modes> {
        let count = self::count(py, "Scenario.modes", "count", count, 1)?;
        let shift_hz = finite(py, "Scenario.modes", "shift_hz", shift_hz)?;
        let harmonics: Vec<u32> = match harmonic {
            None => vec![0],
            Some(h) => {
                let list: Vec<i64> = match h.extract::<i64>() {
                    Ok(n) => vec![n],
                    Err(_) => h.extract::<Vec<i64>>().map_err(|_| {
                        input_error(
                            py,
                            "Scenario.modes",
                            "harmonic",
                            "expected a whole number ≥ 0 or a list of them".to_string(),
                        )
                    })?,
                };
                let mut out = Vec::with_capacity(list.len());
                for n in list {
                    out.push(self::count(py, "Scenario.modes", "harmonic", n, 0)? as u32);
                }
                if out.is_empty() {
                    return Err(input_error(
                        py,
                        "Scenario.modes",
                        "harmonic",
                        "expected at least one harmonic".to_string(),
                    ));
                }
                out
            }
        };
        let sim = self.sim.clone();
        let mut p = Progress::new(progress);
        let settings = ModeSettings {
            count,
            shift_hz,
            ..Default::default()
        };
        let ran = py.detach(|| {
            let plan = api::modes_plan(sim.plan()?, &settings)?;
            let mut dir = match &out {
                Some(d) => Some(open_dir(d, "modes", &plan, overwrite)?),
                None => None,
            };
            let m = api::loaded_modes_of_harmonics(&plan, &settings, &harmonics, p.options())?;
            if let (Some(results), Some(d)) = (dir.as_mut(), &out) {
                deasim::io::linear::write_modes(&plan, d, "modes", &m.state, &m.modes)
                    .and(results.record())
                    .map_err(|message| Error::Io {
                        path: d.clone(),
                        message,
                    })?;
            }
            Ok(m)
        });
        match ran {
            Ok(m) => Ok(Modes { m }),
            Err(e) => Err(p.error(py, e)),
        }
    }

    /// The frequency response of the probes per volt on `electrode` (default: the first with a
    /// voltage) about `bias` V (default: its voltage in the loaded state) at `frequencies` (Hz).
    #[pyo3(signature = (frequencies, electrode=None, bias=None, progress=None))]
    fn frequency_response(
        &self,
        py: Python<'_>,
        frequencies: Vec<f64>,
        electrode: Option<String>,
        bias: Option<f64>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<FrequencyResponse> {
        let file = "Scenario.frequency_response";
        if let Some(b) = bias {
            finite(py, file, "bias", b)?;
        }
        for (i, &f) in frequencies.iter().enumerate() {
            finite(py, file, &format!("frequencies.{i}"), f)?;
        }
        let sim = self.sim.clone();
        let mut p = Progress::new(progress);
        let ran = py.detach(|| {
            let mut prepared = api::prepare(sim.plan()?, electrode.as_deref(), bias, p.options())?;
            let r = prepared.frequency_response(&frequencies)?;
            Ok((r, prepared.warning))
        });
        match ran {
            Ok((r, warning)) => Ok(FrequencyResponse { r, warning }),
            Err(e) => Err(p.error(py, e)),
        }
    }

    /// The reduced state-space model of `modes` modes from the voltage of `electrode` about
    /// `bias` to the probes.
    #[pyo3(signature = (modes=4, electrode=None, bias=None, progress=None))]
    fn reduce(
        &self,
        py: Python<'_>,
        modes: i64,
        electrode: Option<String>,
        bias: Option<f64>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<ReducedModel> {
        let modes = count(py, "Scenario.reduce", "modes", modes, 1)?;
        if let Some(b) = bias {
            finite(py, "Scenario.reduce", "bias", b)?;
        }
        let sim = self.sim.clone();
        let mut p = Progress::new(progress);
        let ran = py.detach(|| {
            let prepared = api::prepare(sim.plan()?, electrode.as_deref(), bias, p.options())?;
            let m = prepared.reduced_model(modes)?;
            Ok((m, prepared.warning))
        });
        match ran {
            Ok((m, warning)) => Ok(ReducedModel { m, warning }),
            Err(e) => Err(p.error(py, e)),
        }
    }

    /// The gradient of the scenario's `[[objective]]` in its `[[parameters]]` by the discrete
    /// adjoint (as `deasim gradient`): the document of `gradient.json` (`objective`,
    /// `gradient` per key path, `forward_s`, `adjoint_s`, `peak_memory`; with `check` the
    /// central finite differences `check` and the Taylor test `taylor`) and `values`, each
    /// parameter's value. `out` receives the forward run's files and `gradient.json`.
    #[pyo3(signature = (check=false, out=None, overwrite=false))]
    fn gradient<'py>(
        &self,
        py: Python<'py>,
        check: bool,
        out: Option<PathBuf>,
        overwrite: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let sim = self.sim.clone();
        #[allow(clippy::needless_update)]
        let options = api::GradientOptions {
            out: out.clone(),
            overwrite,
            check,
            ..Default::default()
        };
        let report = py
            .detach(move || sim.gradient(&options))
            .map_err(|e| to_py(py, e))?;
        let doc = report.to_json();
        if let Some(dir) = &out {
            report.write(dir, None).map_err(|e| to_py(py, e))?;
        }
        // in the order of the parameters (JSON objects are sorted by key)
        let d = json_to_py(py, &doc)?.cast_into::<PyDict>()?;
        let ordered = |f: &dyn Fn(&api::ParameterGradient) -> Option<Py<PyAny>>| {
            let m = PyDict::new(py);
            for p in &report.parameters {
                if let Some(v) = f(p) {
                    m.set_item(&p.path, v)?;
                }
            }
            PyResult::Ok(m)
        };
        let float = |x: f64| Some(PyFloat::new(py, x).into_any().unbind());
        d.set_item("gradient", ordered(&|p| float(p.gradient))?)?;
        d.set_item("values", ordered(&|p| float(p.value))?)?;
        if report.taylor.is_some() {
            let check = ordered(&|p| {
                let (fd, h) = p.finite_difference?;
                let c = PyDict::new(py);
                c.set_item("finite_difference", fd).ok()?;
                c.set_item("h", h).ok()?;
                Some(c.into_any().unbind())
            })?;
            d.set_item("check", check)?;
        }
        Ok(d.into_any())
    }

    /// The drive of the scenario's `[[controls]]` that minimises its `[[objective]]` (as
    /// `deasim control`): the document of `control.json` (`objective` per iteration,
    /// `gradient_norm`, `iterations`, `evaluations`, `converged`, `reason`, `final_objective`,
    /// `wall_s`, `controls`), `drives` (per control: `electrode`, `stage`, `quantity`, `time` on
    /// the run's clock and the optimised knots under the quantity's name, `voltage` in V or
    /// `charge` in C, numpy arrays) and `controlled`, the text of
    /// `controlled.toml`. `out` receives the optimised run's files and those of the command.
    /// `response_model=False` starts the quasi-Newton recursion from a scalar (`--no-model`).
    #[pyo3(signature = (max_iterations=200, gradient_tolerance=1e-6, objective_tolerance=1e-10, out=None, overwrite=false, response_model=true))]
    #[allow(clippy::too_many_arguments)]
    fn control<'py>(
        &self,
        py: Python<'py>,
        max_iterations: usize,
        gradient_tolerance: f64,
        objective_tolerance: f64,
        out: Option<PathBuf>,
        overwrite: bool,
        response_model: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let sim = self.sim.clone();
        let options = api::ControlOptions {
            out: out.clone(),
            overwrite,
            max_iterations,
            gradient_tolerance,
            objective_tolerance,
            response_model,
        };
        let o = py
            .detach(move || sim.control(&options, |_| {}))
            .map_err(|e| to_py(py, e))?;
        if let Some(dir) = &out {
            o.write(dir, None).map_err(|e| to_py(py, e))?;
        }
        let d = json_to_py(py, &o.to_json())?.cast_into::<PyDict>()?;
        let drives = PyList::empty(py);
        for dr in &o.drives {
            let x = PyDict::new(py);
            x.set_item("electrode", &dr.electrode)?;
            x.set_item("stage", &dr.stage)?;
            let t: Vec<f64> = dr.times.iter().map(|t| dr.stage_start + t).collect();
            x.set_item("time", column(py, &t))?;
            // the knots under their quantity's name: `voltage` (V) or `charge` (C)
            x.set_item("quantity", dr.quantity.name())?;
            x.set_item(dr.quantity.name(), column(py, &dr.values))?;
            drives.append(x)?;
        }
        d.set_item("drives", drives)?;
        d.set_item("controlled", &o.controlled)?;
        Ok(d)
    }

    /// Fits the scenario's `[[parameters]]` to its `[[objective]]` probe terms with the finite
    /// element run in the loop (as `deasim calibrate SCENARIO.toml`): the document of
    /// `calibration.json` (`parameters` with `initial`, `fitted`, `std_error`, `ci95`; `rms`,
    /// `rms_by_experiment`, `correlation`, `iterations`, `converged`, `reason`, `warnings`),
    /// `fitted`, the text of `fitted.toml`, and `curves`: per probe term its `term`, `probe`
    /// and numpy columns `time`, `measured`, `fitted` (what the plots of the fit draw).
    fn calibrate<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let sim = self.sim.clone();
        let c = py
            .detach(move || sim.calibrate_device())
            .map_err(|e| to_py(py, e))?;
        let d = json_to_py(py, &c.to_json())?.cast_into::<PyDict>()?;
        d.set_item("fitted", &c.fitted)?;
        let curves = PyList::empty(py);
        for cv in &c.curves {
            let x = PyDict::new(py);
            x.set_item("term", &cv.term)?;
            x.set_item("probe", &cv.probe)?;
            x.set_item("time", column(py, &cv.time))?;
            x.set_item("measured", column(py, &cv.measured))?;
            x.set_item("fitted", column(py, &cv.fitted))?;
            curves.append(x)?;
        }
        d.set_item("curves", curves)?;
        Ok(d)
    }

    /// The lumped diaphragm model of a `disc` scenario: its linearisation about the rest state
    /// at 0 V (`linearised`: equilibrium, mass, damping, stiffness, natural_frequency,
    /// damping_ratio, ...) and its simulation of the first dynamic stage (`history`: numpy
    /// columns on the run's clock, the probes as the command's `lumped.csv` names them).
    fn lumped<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let sim = self.sim.clone();
        let file = "<scenario>".to_string();
        let ran = py.detach(move || -> Result<_, Error> {
            let scenario = sim.scenario()?;
            let plan = sim.plan()?;
            let setup = deasim::lumped::setup::from_scenario(&scenario, &plan, &file)?;
            let (lin, history, dt) = setup.simulate().map_err(|e| {
                Error::Refused(format!("the lumped model cannot be simulated: {e}"))
            })?;
            Ok((setup.start, setup.pad_capacitance, lin, history, dt))
        });
        let (start, pad, lin, history, dt) = ran.map_err(|e| to_py(py, e))?;
        let d = PyDict::new(py);
        let l = PyDict::new(py);
        l.set_item("equilibrium", lin.equilibrium)?;
        l.set_item("mass", lin.mass)?;
        l.set_item("damping", lin.damping)?;
        l.set_item("stiffness", lin.stiffness)?;
        l.set_item("force_per_volt2", lin.force_per_volt2)?;
        l.set_item("capacitance", lin.capacitance)?;
        l.set_item("min_thickness", lin.min_thickness)?;
        l.set_item("natural_frequency", lin.natural_frequency())?;
        l.set_item("damping_ratio", lin.damping_ratio())?;
        d.set_item("linearised", l)?;
        d.set_item("dt", dt)?;
        let h = PyDict::new(py);
        let samples = &history.samples;
        let col = |f: &dyn Fn(&deasim::lumped::Sample) -> f64| {
            PyArray1::from_vec(py, samples.iter().map(f).collect())
        };
        h.set_item("time", col(&|s| start + s.time))?;
        h.set_item("voltage", col(&|s| s.voltage))?;
        h.set_item("deflection", col(&|s| s.deflection))?;
        h.set_item("velocity", col(&|s| s.velocity))?;
        h.set_item("capacitance", col(&|s| s.capacitance + pad))?;
        h.set_item("charge", col(&|s| (s.capacitance + pad) * s.voltage))?;
        h.set_item("max_field", col(&|s| s.max_field))?;
        h.set_item("energy", col(&|s| s.energy))?;
        d.set_item("history", h)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "Scenario({}, {} override(s))",
            self.sim.text().lines().next().unwrap_or(""),
            self.sim.overrides().len()
        )
    }
}

/// The problems of `sim`: its first, then, while that one is blamed on an override, the first
/// of the scenario without that override (one plan build per wrong override); each once.
fn problems(sim: &Simulation) -> Vec<String> {
    let mut found: Vec<String> = Vec::new();
    let mut overrides = sim.overrides().to_vec();
    let mut current = sim.clone();
    loop {
        let e = match current.plan() {
            Ok(_) => return found,
            Err(e) => e,
        };
        let message = e.to_string();
        // the same problem again, once blamed on an override that did not cause it
        let plain = |m: &str| {
            m.split(" (the value comes from `--set ")
                .next()
                .unwrap_or("")
                .to_string()
        };
        if !found.iter().any(|f| plain(f) == plain(&message)) {
            found.push(message);
        }
        let Error::Input(InputError { key: Some(k), .. }) = &e else {
            return found;
        };
        // the override that gave the key (or a table above or below it), as the library blames
        let Some(i) = overrides.iter().position(|o| {
            let path = o.split_once('=').map_or(o.as_str(), |(p, _)| p).trim();
            path == k || k.starts_with(&format!("{path}.")) || path.starts_with(&format!("{k}."))
        }) else {
            return found;
        };
        overrides.remove(i);
        current = sim.without_overrides().with_overrides(&overrides);
    }
}

/// Opens (and locks) the results directory `dir` of command `command` on `plan`.
fn open_dir(
    dir: &Path,
    command: &str,
    plan: &Plan,
    overwrite: bool,
) -> Result<deasim::io::results::ResultsDir, Error> {
    let hash = format!("{:016x}", plan.fingerprint());
    deasim::io::results::ResultsDir::open(dir, command, &plan.name, &hash, overwrite)
        .map_err(Error::Refused)
}

/// The mesh a run's fields live on: reference coordinates, connectivity and its cell type.
#[derive(Clone)]
struct Mesh {
    points: Vec<[f64; 3]>,
    cells: Vec<usize>,
    per_cell: usize,
    cell_type: &'static str,
    axisymmetric: bool,
}

impl Mesh {
    fn of(plan: &Plan) -> Mesh {
        let m = &plan.model.mesh;
        let cell_type = match m.kind {
            ElementKind::Hex8 => "hexahedron",
            ElementKind::Tet4 => "tetra",
            ElementKind::Tet10 => "tetra10",
            ElementKind::Meridian(MeridianKind::Quad4) => "quad",
            ElementKind::Meridian(MeridianKind::Quad8) => "quad8",
            ElementKind::Meridian(MeridianKind::Quad9) => "quad9",
            ElementKind::Meridian(MeridianKind::Tri3) => "triangle",
            ElementKind::Meridian(MeridianKind::Tri6) => "triangle6",
        };
        Mesh {
            points: m.nodes.clone(),
            cells: m.connectivity.clone(),
            per_cell: m.kind.nodes_per_cell(),
            cell_type,
            axisymmetric: plan.model.is_axisymmetric(),
        }
    }
}

/// The results of a run: its history, summary, probe statistics and kept fields.
#[pyclass(module = "deasim._deasim", name = "Results")]
struct Results {
    r: api::Results,
    mesh: Option<Mesh>,
}

impl Results {
    fn new(r: api::Results) -> Self {
        Results { r, mesh: None }
    }
}

#[pymethods]
impl Results {
    /// The history: one numpy column (float64) per quantity of `history.csv`, and `stage` (a
    /// list of str).
    #[getter]
    fn history<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let h = &self.r.history;
        for (name, values) in &h.columns {
            d.set_item(name, column(py, values))?;
        }
        d.set_item("stage", h.stage.clone())?;
        Ok(d)
    }

    /// The summary of the run (as `summary.json` has it): converged, error, interrupted,
    /// wall_s, dofs, warnings, stages.
    #[getter]
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.r.summary;
        let d = PyDict::new(py);
        d.set_item("converged", s.converged)?;
        d.set_item("error", s.error.clone())?;
        d.set_item("interrupted", s.interrupted)?;
        d.set_item("wall_s", s.wall_s)?;
        d.set_item("dofs", s.dofs)?;
        d.set_item("warnings", s.warnings.clone())?;
        let json = py.import("json")?;
        let stages =
            serde_json::to_string(&s.stages).map_err(|e| PyValueError::new_err(e.to_string()))?;
        d.set_item("stages", json.call_method1("loads", (stages,))?)?;
        d.set_item("steps", self.r.records.len())?;
        Ok(d)
    }

    /// Per probe: its first, last, smallest and largest value.
    #[getter]
    fn probes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for p in &self.r.probes {
            let s = PyDict::new(py);
            s.set_item("first", p.first)?;
            s.set_item("last", p.last)?;
            s.set_item("min", p.min)?;
            s.set_item("max", p.max)?;
            d.set_item(&p.name, s)?;
        }
        Ok(d)
    }

    /// Whether the run was stopped on request before its end.
    #[getter]
    fn interrupted(&self) -> bool {
        self.r.summary.interrupted
    }

    /// Whether every stage converged.
    #[getter]
    fn converged(&self) -> bool {
        self.r.summary.converged
    }

    /// The indices (into the history's rows) of the steps whose fields were kept.
    #[getter]
    fn field_steps(&self) -> Vec<usize> {
        self.r.fields.iter().map(|f| f.record).collect()
    }

    /// The nodal values and cell fields of a kept step (default: the last kept): `points`
    /// (n×3, m), `cells` (c×k node indices), `cell_type` (meshio's name), `displacement` (n×3,
    /// m), `potential` (n, V), `electric_field` (c×3, V/m), `stress` and `mechanical_stress`
    /// (c×3×3, Pa, Cauchy), `volume_ratio` (c), `max_electric_field` (c, V/m).
    #[pyo3(signature = (step=None))]
    fn fields<'py>(&self, py: Python<'py>, step: Option<i64>) -> PyResult<Bound<'py, PyDict>> {
        let kept = &self.r.fields;
        if kept.is_empty() {
            return Err(PyValueError::new_err(
                "no fields were kept: run with fields=\"last\" or fields=\"every\"",
            ));
        }
        let f = match step {
            None => kept.last().expect("kept fields"),
            Some(s) => {
                let row = if s < 0 {
                    self.r.records.len() as i64 + s
                } else {
                    s
                };
                kept.iter()
                    .find(|f| f.record as i64 == row)
                    .ok_or_else(|| {
                        PyValueError::new_err(format!(
                            "step {s}: its fields were not kept; kept rows: {:?}",
                            self.field_steps()
                        ))
                    })?
            }
        };
        let d = PyDict::new(py);
        let n = f.nodal.len() / 4;
        let mut u = Vec::with_capacity(3 * n);
        let mut phi = Vec::with_capacity(n);
        for a in 0..n {
            u.extend_from_slice(&f.nodal[4 * a..4 * a + 3]);
            phi.push(f.nodal[4 * a + 3]);
        }
        if let Some(m) = &self.mesh {
            let pts: Vec<f64> = m.points.iter().flatten().copied().collect();
            d.set_item("points", PyArray1::from_vec(py, pts).reshape([n, 3])?)?;
            let cells: Vec<i64> = m.cells.iter().map(|&c| c as i64).collect();
            let nc = cells.len() / m.per_cell;
            d.set_item(
                "cells",
                PyArray1::from_vec(py, cells).reshape([nc, m.per_cell])?,
            )?;
            d.set_item("cell_type", m.cell_type)?;
            d.set_item("axisymmetric", m.axisymmetric)?;
        }
        d.set_item("displacement", PyArray1::from_vec(py, u).reshape([n, 3])?)?;
        d.set_item("potential", PyArray1::from_vec(py, phi))?;
        let c = f.cells.len();
        let e: Vec<f64> = f.cells.iter().flat_map(|x| x.e).collect();
        let s: Vec<f64> = f.cells.iter().flat_map(|x| x.sigma).collect();
        let sm: Vec<f64> = f.cells.iter().flat_map(|x| x.sigma_mech).collect();
        d.set_item("electric_field", PyArray1::from_vec(py, e).reshape([c, 3])?)?;
        d.set_item("stress", PyArray1::from_vec(py, s).reshape([c, 3, 3])?)?;
        d.set_item(
            "mechanical_stress",
            PyArray1::from_vec(py, sm).reshape([c, 3, 3])?,
        )?;
        d.set_item(
            "volume_ratio",
            PyArray1::from_vec(py, f.cells.iter().map(|x| x.j).collect()),
        )?;
        d.set_item(
            "max_electric_field",
            PyArray1::from_vec(py, f.cells.iter().map(|x| x.e_max).collect()),
        )?;
        d.set_item("row", f.record)?;
        Ok(d)
    }

    fn __len__(&self) -> usize {
        self.r.records.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "Results({} steps, {})",
            self.r.records.len(),
            if self.r.summary.interrupted {
                "interrupted"
            } else if self.r.summary.converged {
                "converged"
            } else {
                "failed"
            }
        )
    }
}

/// Natural modes about a loaded state.
#[pyclass(module = "deasim._deasim", name = "Modes")]
struct Modes {
    m: api::LoadedModes,
}

#[pymethods]
impl Modes {
    /// Natural frequencies (Hz).
    #[getter]
    fn frequencies<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.m.modes.iter().map(|m| m.frequency).collect())
    }

    /// ω² (rad²/s²) of each mode: negative for an unstable state.
    #[getter]
    fn eigenvalues<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.m.modes.iter().map(|m| m.eigenvalue).collect())
    }

    /// Relative residual of each mode.
    #[getter]
    fn residuals<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.m.modes.iter().map(|m| m.residual).collect())
    }

    /// The circumferential harmonic n of each mode (0 for a 3-D model); its shape holds the
    /// amplitudes of cos nθ (u_r, u_z, Φ) and sin nθ (u_θ, the third slot).
    #[getter]
    fn harmonics<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        PyArray1::from_vec(
            py,
            self.m.modes.iter().map(|m| i64::from(m.harmonic)).collect(),
        )
    }

    /// Mode shapes: modes × nodes × 4 (u in m, Φ in V), unit modal mass.
    #[getter]
    fn shapes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray3<f64>>> {
        let k = self.m.modes.len();
        let n = self.m.state.len() / 4;
        let flat: Vec<f64> = self
            .m
            .modes
            .iter()
            .flat_map(|m| m.shape.iter().copied())
            .collect();
        PyArray1::from_vec(py, flat).reshape([k, n, 4])
    }

    /// The stage whose end state the modes are taken about.
    #[getter]
    fn stage(&self) -> String {
        self.m.stage.clone()
    }

    /// Each electrode's voltage (V) in that state.
    #[getter]
    fn bias(&self) -> Vec<(String, f64)> {
        self.m.bias.clone()
    }

    /// What the model's symmetry hides, if anything.
    #[getter]
    fn note(&self) -> Option<String> {
        self.m.note.clone()
    }

    fn __len__(&self) -> usize {
        self.m.modes.len()
    }

    fn __repr__(&self) -> String {
        let f: Vec<String> = self
            .m
            .modes
            .iter()
            .map(|m| format!("{:.4}", m.frequency))
            .collect();
        format!("Modes([{}] Hz)", f.join(", "))
    }
}

/// The complex response of the probes per volt at each frequency.
#[pyclass(module = "deasim._deasim", name = "FrequencyResponse")]
struct FrequencyResponse {
    r: deasim::job::state::FrequencyResponse,
    warning: Option<String>,
}

#[pymethods]
impl FrequencyResponse {
    /// Frequencies (Hz).
    #[getter]
    fn frequencies<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        column(py, &self.r.frequencies)
    }

    /// Per probe: its complex response per volt (complex128 array over the frequencies).
    #[getter]
    fn probes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (name, v) in &self.r.probes {
            let c: Vec<numpy::Complex64> = v
                .iter()
                .map(|&(re, im)| numpy::Complex64::new(re, im))
                .collect();
            d.set_item(name, PyArray1::from_vec(py, c))?;
        }
        Ok(d)
    }

    /// The driven electrode.
    #[getter]
    fn electrode(&self) -> String {
        self.r.electrode.clone()
    }

    /// Its DC bias (V).
    #[getter]
    fn bias(&self) -> f64 {
        self.r.bias
    }

    /// Set when the drive moves nothing to first order (zero bias).
    #[getter]
    fn warning(&self) -> Option<String> {
        self.warning.clone()
    }
}

/// A reduced state-space model ẋ = A x + B v, y = C x + D v from the driven electrode's voltage
/// change v (V) to the probes' changes y about their values at the bias.
#[pyclass(module = "deasim._deasim", name = "ReducedModel")]
struct ReducedModel {
    m: deasim::time::reduced::ReducedModel,
    warning: Option<String>,
}

#[pymethods]
impl ReducedModel {
    /// A (2N+… × same).
    #[getter(A)]
    fn a<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let n = self.m.a.len();
        matrix(py, &self.m.a, n)
    }
    /// B (states × 1).
    #[getter(B)]
    fn b<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix(py, &self.m.b, 1)
    }
    /// C (outputs × states).
    #[getter(C)]
    fn c<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix(py, &self.m.c, self.m.a.len())
    }
    /// D (outputs × 1).
    #[getter(D)]
    fn d<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        matrix(py, &self.m.d, 1)
    }
    /// Natural frequencies (Hz) of the kept modes.
    #[getter]
    fn frequencies<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        column(py, &self.m.frequencies_hz)
    }
    /// Names of the outputs (probes), the rows of C and D.
    #[getter]
    fn outputs(&self) -> Vec<String> {
        self.m.outputs.clone()
    }
    /// The outputs' values at the bias (y is the change about them).
    #[getter]
    fn output_offsets<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        column(py, &self.m.output_offsets)
    }
    /// The driven electrode.
    #[getter]
    fn electrode(&self) -> String {
        self.m.electrode.clone()
    }
    /// Its DC bias (V).
    #[getter]
    fn bias(&self) -> f64 {
        self.m.bias_v
    }
    /// Set when the drive moves nothing to first order (zero bias).
    #[getter]
    fn warning(&self) -> Option<String> {
        self.warning.clone()
    }
    /// The outputs (absolute: offsets included; times × outputs) for the driven electrode's
    /// voltages `voltages` (V, absolute, one per time, linear between them) at `times` (s,
    /// increasing), from rest at the bias.
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        times: Vec<f64>,
        voltages: Vec<f64>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        if times.len() != voltages.len() || times.is_empty() {
            return Err(PyValueError::new_err(format!(
                "times and voltages: expected arrays of one length (at least 1); got {} and {}",
                times.len(),
                voltages.len()
            )));
        }
        if times.windows(2).any(|w| w[1] < w[0]) {
            return Err(PyValueError::new_err("times: expected increasing values"));
        }
        // the voltage between the given times: linear
        let v = |t: f64| {
            let k = times.partition_point(|&x| x <= t);
            if k == 0 {
                return voltages[0];
            }
            if k >= times.len() {
                return voltages[times.len() - 1];
            }
            let (t0, t1) = (times[k - 1], times[k]);
            let w = if t1 > t0 { (t - t0) / (t1 - t0) } else { 0.0 };
            voltages[k - 1] + w * (voltages[k] - voltages[k - 1])
        };
        let y = py.detach(|| self.m.simulate(&v, &times));
        matrix(py, &y, self.m.outputs.len())
    }
}

/// Homogeneous material-point tests of a preset (`material` a name of `deasim materials`) or of
/// a scenario's material (`material` a `Scenario`, `name` the material, default its first):
/// one record set per curve (per stretch rate), as numpy columns.
#[pyfunction]
#[pyo3(signature = (material, test="uniaxial", *, name=None, mode="uniaxial", stretch=2.5,
    rates=vec![0.01, 0.03, 0.05], stress=None, ramp_time=0.1, hold=60.0, cycles=1, steps=200))]
#[allow(clippy::too_many_arguments)]
fn material_test<'py>(
    py: Python<'py>,
    material: &Bound<'py, PyAny>,
    test: &str,
    name: Option<String>,
    mode: &str,
    stretch: f64,
    rates: Vec<f64>,
    stress: Option<f64>,
    ramp_time: f64,
    hold: f64,
    cycles: usize,
    steps: usize,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    use deasim::material::registry::{build, preset, PRESETS};
    let scenario_error = |message: String, key: Option<&str>| -> PyErr {
        let e = deasim::io::scenario::InputError {
            file: "<material_test>".into(),
            position: None,
            key: key.map(str::to_string),
            message,
        };
        to_py(py, Error::Input(e))
    };
    let mat: std::sync::Arc<dyn deasim::material::Material> =
        if let Ok(s) = material.extract::<PyRef<'_, Scenario>>() {
            let sim = s.sim.clone();
            let plan = py.detach(move || sim.plan()).map_err(|e| to_py(py, e))?;
            let i = match &name {
                Some(n) => plan
                    .material_names
                    .iter()
                    .position(|m| m == n)
                    .ok_or_else(|| {
                        scenario_error(
                            format!(
                                "no material `{n}`; the scenario has {}",
                                plan.material_names.join(", ")
                            ),
                            Some("name"),
                        )
                    })?,
                None => 0,
            };
            plan.model.materials[i].clone()
        } else {
            let label: String = material.extract().map_err(|_| {
                PyTypeError::new_err("material: expected a preset name (str) or a Scenario")
            })?;
            let Some((model, p)) = preset(&label) else {
                return Err(scenario_error(
                    format!(
                        "`{label}` is not a preset; the presets are {}",
                        PRESETS.join(", ")
                    ),
                    Some("material"),
                ));
            };
            build(model, &p)
                .map_err(|e| scenario_error(format!("preset `{label}`: {e}"), Some("material")))?
                .0
        };
    let spec = deasim::material::lab::TestSpec {
        test: test.to_string(),
        mode: mode.to_string(),
        stretch,
        rates,
        stress,
        ramp_time,
        hold,
        cycles,
        steps,
    };
    spec.check().map_err(|e| {
        let key = e.split(':').next().map(str::to_string);
        scenario_error(e, key.as_deref())
    })?;
    let curves = py
        .detach(|| spec.curves(mat.as_ref()))
        .map_err(|reason| solve_error(py, reason))?;
    curves
        .iter()
        .map(|c| {
            let d = PyDict::new(py);
            d.set_item("label", &c.label)?;
            d.set_item("rate", c.rate)?;
            let col = |f: fn(&deasim::material::point_history::PointRecord) -> f64| {
                PyArray1::from_vec(py, c.records.iter().map(f).collect())
            };
            d.set_item("time", col(|r| r.t))?;
            d.set_item("stretch", col(|r| r.stretch))?;
            d.set_item("lateral_stretch", col(|r| r.lateral))?;
            d.set_item("nominal_stress", col(|r| r.nominal))?;
            d.set_item("cauchy_stress", col(|r| r.cauchy))?;
            d.set_item("dissipated", col(|r| r.dissipated))?;
            Ok(d)
        })
        .collect()
}

/// Fits a material's parameters to measured homogeneous test curves (as `deasim calibrate`):
/// `spec` a calibration spec (a path, its TOML text or its tables as a dict; relative data
/// paths from the spec's directory, else from `base` or the working directory).
#[pyfunction]
#[pyo3(signature = (spec, out=None, overwrite=false, starts=None, base=None))]
fn calibrate<'py>(
    py: Python<'py>,
    spec: &Bound<'py, PyAny>,
    out: Option<PathBuf>,
    overwrite: bool,
    starts: Option<i64>,
    base: Option<PathBuf>,
) -> PyResult<Bound<'py, PyDict>> {
    use deasim::calibrate::{output, read_problem, spec as cspec, CalibrationError};
    let file = "calibrate";
    let starts = match starts {
        Some(s) => Some(count(py, file, "starts", s, 1)?),
        None => None,
    };
    // the spec's text (with the name its errors give) or its path
    let text: Option<(String, String)> = if let Ok(d) = spec.cast::<PyDict>() {
        let value = to_toml(d.as_any(), "")
            .map_err(|(key, message)| input_error(py, "<spec dict>", &key, message))?;
        let text = toml::to_string(&value)
            .map_err(|e| input_error(py, "<spec dict>", "", format!("cannot write it: {e}")))?;
        Some((text, "<spec dict>".into()))
    } else if let Ok(t) = spec.extract::<String>() {
        (t.contains('\n') || t.contains('[')).then(|| (t, "<spec text>".into()))
    } else {
        None
    };
    let (what, problem) = match text {
        Some((text, name)) => {
            if cspec::has_objectives(&text) {
                return Err(to_py(
                    py,
                    Error::Refused(format!("{name}: {}", cspec::DEVICE_OBJECTIVES)),
                ));
            }
            let base = match base {
                Some(b) => b,
                None => std::env::current_dir().unwrap_or_default(),
            };
            let p = cspec::parse(&text, &name, &base).map_err(|e| to_py(py, Error::Input(e)))?;
            (name, p)
        }
        None => {
            let path: PathBuf = spec.extract().map_err(|_| {
                PyTypeError::new_err(
                    "spec: expected a path, the spec's TOML text or its tables as a dict",
                )
            })?;
            if let Err(e) = std::fs::metadata(&path) {
                return Err(to_py(
                    py,
                    Error::Io {
                        path: path.clone(),
                        message: format!("cannot read the calibration spec: {e}"),
                    },
                ));
            }
            let p = read_problem(&path).map_err(|e| match e {
                CalibrationError::Input(i) => to_py(py, Error::Input(i)),
                other => to_py(py, Error::Refused(other.to_string())),
            })?;
            (path.display().to_string(), p)
        }
    };
    let options = deasim::api::CalibrateOptions { starts };
    let cal = py
        .detach(|| deasim::calibrate::calibrate(&problem, &options))
        .map_err(|e| match e {
            CalibrationError::Input(i) => to_py(py, Error::Input(i)),
            CalibrationError::Unsupported(m) => to_py(py, Error::Refused(m)),
            CalibrationError::Failed(m) => solve_error(py, m),
        })?;
    if let Some(dir) = &out {
        let mut results =
            deasim::io::results::ResultsDir::open(dir, "calibrate", &what, "", overwrite)
                .map_err(|e| to_py(py, Error::Refused(e)))?;
        output::write(&cal, dir)
            .and_then(|()| results.record())
            .map_err(|message| {
                to_py(
                    py,
                    Error::Io {
                        path: dir.clone(),
                        message,
                    },
                )
            })?;
    }
    let d = json_to_py(py, &output::json(&cal))?.cast_into::<PyDict>()?;
    // in the order of the spec (JSON objects are sorted by key)
    let fitted = PyDict::new(py);
    let parameters = PyDict::new(py);
    let by_path = d.get_item("parameters")?;
    for p in &cal.parameters {
        fitted.set_item(&p.path, p.fitted)?;
        if let Some(all) = &by_path {
            parameters.set_item(&p.path, all.get_item(&p.path)?)?;
        }
    }
    d.set_item("parameters", parameters)?;
    d.set_item("fitted", fitted)?;
    d.set_item("model", &cal.model)?;
    d.set_item(
        "fitted_toml",
        output::fitted_toml(&cal).map_err(PyValueError::new_err)?,
    )?;
    let experiments = PyList::empty(py);
    for e in &cal.experiments {
        let x = PyDict::new(py);
        x.set_item("name", &e.name)?;
        x.set_item("rms", e.rms)?;
        x.set_item("rms_initial", e.rms_initial)?;
        x.set_item("stretch", column(py, &e.stretch))?;
        x.set_item("time", e.time.as_ref().map(|t| column(py, t)))?;
        x.set_item("measured", column(py, &e.measured))?;
        x.set_item("model", column(py, &e.model))?;
        experiments.append(x)?;
    }
    d.set_item("experiments", experiments)?;
    Ok(d)
}

/// The names of the embedded examples.
#[pyfunction]
fn examples() -> Vec<String> {
    deasim::io::examples::EXAMPLES
        .iter()
        .map(|(n, _)| n.to_string())
        .collect()
}

/// The name of the default example.
#[pyfunction]
fn default_example() -> &'static str {
    deasim::io::examples::DEFAULT
}

#[pymodule]
fn _deasim(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Scenario>()?;
    m.add_class::<Results>()?;
    m.add_class::<Modes>()?;
    m.add_class::<FrequencyResponse>()?;
    m.add_class::<ReducedModel>()?;
    m.add_function(wrap_pyfunction!(examples, m)?)?;
    m.add_function(wrap_pyfunction!(material_test, m)?)?;
    m.add_function(wrap_pyfunction!(default_example, m)?)?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
