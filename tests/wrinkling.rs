//! Stability of static stages against circumferential harmonics (`stability_harmonics`).
//!
//! References:
//! - a thin pre-stretched membrane (h/a = 1/100) clamped on its rim face with electrodes on both
//!   faces: under voltage its in-plane stretch is held, the film thins and the Maxwell stress
//!   eats its tension. Where the total in-plane Cauchy stress vanishes, σ_rr(λ, λ_t(V), V) = 0
//!   with λ_t from σ_zz = 0 (computed here from the material itself), the flat state loses
//!   stability against every out-of-plane harmonic at once (the bending stiffness of a film
//!   h/a = 1/100 thick moves the onset by a fraction (h/a)² of the stress);
//! - a central electrode on a larger membrane: the same discretisation as a full 3-D disc, whose
//!   ramp loses stability (one more negative pivot, of any pattern) at the same voltage.

mod common;

use deasim::api::{Error, RunOptions, Simulation};
use deasim::job::linear::held_model;
use deasim::job::state::InstabilityRecord;
use deasim::material::{ElectroNeoHooke, Mat3, Material, Vec3};
use deasim::time::harmonic::harmonic_inertia;

const RADIUS: f64 = 10e-3;
const THICKNESS: f64 = 0.1e-3;
const STRETCH: f64 = 1.5;
const MU: f64 = 1e5;
const LAMBDA: f64 = 1e7;
const EPS_R: f64 = 4.7;

/// The clamped membrane with full electrodes, ramped to `voltage` in `steps` static steps,
/// tested against harmonics 1…`harmonics` (none when 0).
fn full_membrane(voltage: f64, steps: usize, harmonics: u32, extra: &str) -> String {
    let test = if harmonics > 0 {
        format!("stability_harmonics = {harmonics}\n")
    } else {
        String::new()
    };
    format!(
        r#"
name = "membrane"
[mesh]
geometry = "axisymmetric"
generator = "rectangle"
radius = {RADIUS:e}
thickness = {THICKNESS:e}
radial = 40
layers = 1
element = "quad8"
[materials.film]
model = "neo-hooke"
mu = {MU:e}
lambda = {LAMBDA:e}
permittivity = {EPS_R}
density = 1000.0
[prestretch]
stretch = {STRETCH}
set = "outer"
clamp = "face"
steps = 2
[electrodes.bottom]
set = "bottom"
voltage = 0.0
[electrodes.top]
set = "top"
voltage = {{ waveform = "ramp", amplitude = {voltage:e}, rise_time = 1.0 }}
[output]
fields_every = 0
plots = false
{extra}
[[stages]]
name = "ramp"
kind = "static"
steps = {steps}
{test}"#
    )
}

/// The total in-plane Cauchy stress of the homogeneous film at thickness stretch `t` and
/// voltage `v`, and its through-thickness stress (meridian order: R, Z, Θ).
fn stresses(m: &ElectroNeoHooke, t: f64, v: f64) -> (f64, f64) {
    let f = Mat3::from_diagonal(&Vec3::new(STRETCH, t, STRETCH));
    let e0 = Vec3::new(0.0, -v / THICKNESS, 0.0);
    let p = m.stress(&f, &e0).unwrap().p;
    let j = f.determinant();
    (p[(0, 0)] * STRETCH / j, p[(1, 1)] * t / j)
}

/// Bisection of a sign change of `g` on [a, b].
fn root(mut a: f64, mut b: f64, g: impl Fn(f64) -> f64) -> f64 {
    let ga = g(a);
    assert!(ga * g(b) < 0.0, "no sign change on [{a}, {b}]");
    for _ in 0..200 {
        let c = 0.5 * (a + b);
        if (g(c) > 0.0) == (ga > 0.0) {
            a = c;
        } else {
            b = c;
        }
    }
    0.5 * (a + b)
}

/// The voltage at which the homogeneous film's total in-plane stress vanishes.
fn zero_stress_voltage() -> f64 {
    let m = ElectroNeoHooke::new(MU, LAMBDA, EPS_R);
    let thickness = |v: f64| root(0.05, 1.0, |t| stresses(&m, t, v).1);
    root(0.0, 10e3, |v| stresses(&m, thickness(v), v).0)
}

/// The instability the run reported (it stops there), with the run's error.
fn stopped_at(text: &str) -> (InstabilityRecord, String) {
    match Simulation::from_toml(text, None).run(RunOptions::default()) {
        Err(Error::Solve { reason, results }) => (
            results
                .summary
                .stages
                .iter()
                .find_map(|s| s.instability.clone())
                .expect("an instability record"),
            reason,
        ),
        Err(e) => panic!("unexpected error: {e}"),
        Ok(_) => panic!("the ramp should lose stability"),
    }
}

/// The clamped thin membrane loses stability within 1 % of the voltage that makes its total
/// in-plane stress vanish, and there every harmonic 0…30 goes together: stable at 0.995 V₀,
/// unstable at 1.01 V₀.
#[test]
fn a_clamped_membrane_loses_stability_where_its_tension_vanishes() {
    let v0 = zero_stress_voltage();
    let (onset, reason) = stopped_at(&full_membrane(1.3 * v0, 26, 30, ""));
    let v = onset.voltages.iter().find(|(n, _)| n == "top").unwrap().1;
    println!(
        "zero-stress voltage {v0:.2} V; onset harmonic {} at {v:.2} V ({:+.3e}); {reason}",
        onset.harmonic,
        v / v0 - 1.0
    );
    assert!((v / v0 - 1.0).abs() < 1e-2);
    assert!(onset.stopped);
    assert!(
        reason.contains("circumferential harmonic n = 0"),
        "{reason}"
    );
    // the flat states on both sides, reached without the stability test (an iterative solver
    // gives no inertia), tested harmonic by harmonic
    let states = |voltage: f64| {
        let sim = Simulation::from_toml(
            &full_membrane(voltage, 10, 0, "[solver]\nkind = \"iterative\"\n"),
            None,
        );
        let plan = sim.plan().unwrap();
        let results = sim
            .run(RunOptions {
                fields: deasim::api::FieldsKept::Last,
                ..Default::default()
            })
            .unwrap();
        let state = results.fields.last().unwrap().nodal.clone();
        (held_model(&plan, &state, None), state)
    };
    let (below, at_below) = states(0.995 * v0);
    let (above, at_above) = states(1.01 * v0);
    for n in [1, 2, 3, 5, 10, 20, 30] {
        let (stable, expected) = harmonic_inertia(&below, &at_below, n).unwrap();
        let (unstable, _) = harmonic_inertia(&above, &at_above, n).unwrap();
        println!(
            "n = {n}: negative pivots {} at 0.995 V0, {} at 1.01 V0 ({expected} potentials)",
            stable.negative, unstable.negative
        );
        assert_eq!(stable.negative, expected, "harmonic {n} below");
        assert!(unstable.negative > expected, "harmonic {n} above");
    }
}

/// A pre-stretched membrane of radius 20 mm with a central electrode (radius 8 mm in the
/// reference state), neo-Hooke, `mesh` keys for the axisymmetric or the 3-D disc.
fn central(mesh: &str, test: &str) -> String {
    central_of(
        mesh,
        &format!("model = \"neo-hooke\"\nlambda = {LAMBDA:e}"),
        2500.0,
        test,
    )
}

/// [`central`] of the material keys `material` (beside μ, εᵣ and the density), ramped to
/// `voltage`.
fn central_of(mesh: &str, material: &str, voltage: f64, test: &str) -> String {
    format!(
        r#"
name = "central"
[mesh]
generator = "disc"
radius = 20e-3
thickness = 0.1e-3
pad_radius = 1e-3
electrode_radius = 8e-3
layers = 1
{mesh}
[materials.film]
{material}
mu = {MU:e}
permittivity = {EPS_R}
density = 1000.0
[prestretch]
stretch = {STRETCH}
set = "rim"
clamp = "face"
steps = 2
[electrodes.bottom]
set = "electrode_bottom"
voltage = 0.0
[electrodes.top]
set = "electrode_top"
voltage = {{ waveform = "ramp", amplitude = {voltage:e}, rise_time = 1.0 }}
[output]
fields_every = 0
plots = false
[[stages]]
name = "ramp"
kind = "static"
steps = 25
{test}"#
    )
}

/// A continuation stage tests every point of its path: on the clamped membrane the first point
/// unstable against a harmonic n ≥ 1 follows the voltage at which the tension vanishes, and the
/// run stops there.
#[test]
fn a_continuation_stops_at_the_first_point_unstable_against_a_harmonic() {
    let v0 = zero_stress_voltage();
    let text = full_membrane(1.3 * v0, 26, 0, "").replace(
        "kind = \"static\"\nsteps = 26\n",
        "kind = \"continuation\"\nparameter = \"voltage\"\nsteps = 26\n\
         target = { load = 1.0 }\nstability_harmonics = 8\n",
    );
    assert!(text.contains("continuation"));
    let (onset, reason) = stopped_at(&text);
    let below = onset.stable_load_factor * 1.3 * v0;
    let above = onset.load_factor * 1.3 * v0;
    println!(
        "continuation: harmonic {} between {below:.2} and {above:.2} V (V0 {v0:.2} V); {reason}",
        onset.harmonic
    );
    assert!(onset.harmonic >= 1 && onset.stopped);
    assert!(below < v0 * 1.01 && above > v0 * 0.99, "{below} {above}");
    assert!(reason.contains("circumferential harmonic n = "), "{reason}");
}

/// The axisymmetric mesh keys of the central electrode's membrane, and those of the same cells as
/// a full 3-D disc.
const AXI_Q4: &str =
    "geometry = \"axisymmetric\"\nelement = \"quad4\"\nradial = 20\nformulation = \"mean-dilatation\"";
const FULL_HEX8: &str =
    "quarter = false\nelement = \"hex8\"\nradial = 20\nformulation = \"mean-dilatation\"";

/// The central electrode's membrane loses stability against a circumferential harmonic n ≥ 1;
/// the same discretisation as a full 3-D disc (hex8 for quad4, the same cells across the radius
/// and through the thickness) loses stability at the same voltage within 1 %.
#[test]
fn a_central_electrode_loses_stability_as_the_full_3d_disc() {
    let (onset, _) = stopped_at(&central(AXI_Q4, "stability_harmonics = 12"));
    let v_axi = onset.voltages.iter().find(|(n, _)| n == "top").unwrap().1;
    let reason =
        match Simulation::from_toml(&central(FULL_HEX8, ""), None).run(RunOptions::default()) {
            Err(Error::Solve { reason, .. }) => reason,
            Err(e) => panic!("unexpected error: {e}"),
            Ok(_) => panic!("the 3-D ramp should lose stability"),
        };
    // "… last converged voltage X V, failed at Y V …"
    let volts = |key: &str| -> f64 {
        let rest = &reason[reason.find(key).expect(key) + key.len()..];
        rest.split_whitespace().next().unwrap().parse().unwrap()
    };
    let v_3d = volts("last converged voltage ");
    println!(
        "axisymmetric: harmonic {} (unstable {:?}, axial share {:.3}) at {v_axi:.2} V; 3-D: \
         {v_3d:.2} V ({:+.3e})",
        onset.harmonic,
        onset.unstable,
        onset.axial_share,
        v_axi / v_3d - 1.0
    );
    assert!(onset.harmonic >= 1);
    assert!(onset.unstable.contains(&onset.harmonic));
    assert!((v_axi / v_3d - 1.0).abs() < 1e-2);
}

/// `after_instability = "continue"` reports the loss and goes on to the stage's end; the
/// command line prints it, `summary.json` holds it and `instability.csv` the critical mode. A
/// strain-stiffening (Gent) film on quad8 cells wrinkles out of plane at the electrode's edge
/// (about 2565 V on this mesh) and its axisymmetric path holds to about 2574 V.
#[test]
fn the_run_reports_the_onset_and_goes_on_when_asked() {
    let dir = common::tempdir("wrinkling-continue");
    let text = central_of(
        "geometry = \"axisymmetric\"\nelement = \"quad8\"\nradial = 24",
        "model = \"gent\"\njm = 8\nkappa = 1e7",
        2570.0,
        "stability_harmonics = 24\nafter_instability = \"continue\"",
    );
    std::fs::write(dir.join("s.toml"), text).unwrap();
    let o = common::deasim(&["run", "s.toml", "--out", "out"], &dir);
    let said = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{said}");
    assert!(said.contains("wrinkling (out of plane), n = "), "{said}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/summary.json")).unwrap())
            .unwrap();
    let i = &summary["instability"];
    assert_eq!(summary["converged"], true);
    assert_eq!(i["stopped"], false);
    assert_eq!(i["stage"], "ramp");
    let n = i["harmonic"].as_u64().unwrap();
    assert!(n >= 1);
    let load = i["load_factor"].as_f64().unwrap();
    let stable = i["stable_load_factor"].as_f64().unwrap();
    assert!(stable < load && load - stable < 2.0 / 25.0 / 4096.0 * 1.0001);
    let top = i["voltages"]["top"].as_f64().unwrap();
    assert!((top - 2570.0 * load).abs() < 1e-6 * 2570.0);
    assert!(i["axial_share"].as_f64().unwrap() > 0.5);
    let csv = std::fs::read_to_string(dir.join("out/instability.csv")).unwrap();
    let row: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    assert_eq!(row[4].parse::<u64>().unwrap(), n);
    assert!(
        row[2].parse::<f64>().unwrap() < 0.0,
        "the critical eigenvalue: {csv}"
    );
    assert!(dir.join("out/instability/mode_01.vtu").exists());
    // the revolved view shows the mode with its n waves around the axis
    assert!(dir.join("out/instability/mode_01_revolved.vtu").exists());
    assert!(dir.join("out/instability_revolved.pvd").exists());
    // the stage went on to its end
    let history = std::fs::read_to_string(dir.join("out/history.csv")).unwrap();
    let last = history.lines().last().unwrap();
    let time: f64 = last.split(',').next().unwrap().parse().unwrap();
    assert_eq!(time, 1.0, "{last}");
}

/// The keys are refused where they do not apply, each error naming its key.
#[test]
fn stability_keys_name_what_is_wrong() {
    let axi = AXI_Q4;
    for (mesh, test, key) in [
        (
            axi,
            "stability_harmonics = 0",
            "stages.0.stability_harmonics",
        ),
        (
            axi,
            "after_instability = \"stop\"",
            "stages.0.after_instability",
        ),
        (
            axi,
            "stability_harmonics = 3\nafter_instability = \"halt\"",
            "stages.0.after_instability",
        ),
        (
            FULL_HEX8,
            "stability_harmonics = 3",
            "stages.0.stability_harmonics",
        ),
    ] {
        match Simulation::from_toml(&central(mesh, test), None).plan() {
            Err(Error::Input(e)) => {
                let said = e.to_string();
                assert!(said.contains(key), "{test}: {said}");
            }
            Err(e) => panic!("{test}: unexpected error {e}"),
            Ok(_) => panic!("{test}: accepted"),
        }
    }
    let dynamic = central(axi, "").replace(
        "kind = \"static\"\nsteps = 25",
        "kind = \"dynamic\"\nduration = 1e-3\ndt = 1e-4\nstability_harmonics = 3",
    );
    match Simulation::from_toml(&dynamic, None).plan() {
        Err(Error::Input(e)) => assert!(
            e.to_string().contains("stages.0.stability_harmonics"),
            "{e}"
        ),
        other => panic!("dynamic: {:?}", other.err()),
    }
}
