//! Rate-dependent pull-in of a viscoelastic film: a free film between two electrodes under a
//! voltage ramp. The homogeneous reference is the material-point history
//! (`material::point_history`, the film mode: equibiaxial, free in plane and in thickness, nominal
//! field V/H) stepped with the same update of the internal variables.
//!
//! - The finite element solution (one hex8 cell, a quasi-static stage) equals that homogeneous
//!   history at the same step times to 1e-8 in both stretches at three ramp rates, up to its
//!   pull-in (the tolerance covers Newton's tolerance; the cell is exactly homogeneous).
//! - The critical voltage rises with the ramp rate, between the relaxed limit (the equilibrium
//!   branch alone) and the instantaneous limit (the instantaneous modulus G_eq + Σgᵢ); for the
//!   neo-Hookean `vhb4910-hossain2012` both limits are the Zhao–Suo field
//!   E_c = 0.6874 √(μ/ε) (incompressible free film, Φ̂ = √(λ⁻² − λ⁻⁸) at λ = 4^(1/6)) with μ the
//!   relaxed or the instantaneous modulus (0.5 % for the compressibility κ = 1000 μ and the
//!   ramp's resolution of 1/4000), and a very slow or fast ramp reaches them. The slow limit is
//!   approached slowly: past the relaxed limit point the film needs time to creep away (a delayed
//!   passage through a saddle-node, the delay shrinking about as (τ·rate)^(2/3)); measured 3.5 %
//!   above it for a ramp of 10⁶ s, 0.9 % for 10⁷ s, 0.02 % for 10⁸ s.

mod common;
use common::{deasim, tempdir};
use deasim::material::homogeneous::Mode;
use deasim::material::point_history::{run, uniform_times, Control};
use deasim::material::registry::{build, preset};
use deasim::material::{Material, EPSILON_0};
use std::sync::Arc;

const H: f64 = 1e-3;

fn material(name: &str) -> Arc<dyn Material> {
    let (model, p) = preset(name).unwrap();
    build(model, &p).unwrap().0
}

/// The critical nominal field (V/m) of a ramp E₀ = rate·t: the last converged field.
fn critical_field(m: &dyn Material, rate: f64, e_max: f64, steps: usize) -> f64 {
    let e = |t: f64| rate * t;
    let times = uniform_times(e_max / rate, steps);
    let f = run(m, Mode::Equibiaxial, &Control::Field(&e), &times)
        .expect_err("the ramp must pass the limit point");
    f.records.last().unwrap().field
}

#[test]
fn critical_field_rises_with_rate_between_the_zhao_suo_limits() {
    let m = material("vhb4910-hossain2012");
    let eps = 4.7 * EPSILON_0;
    let mu_eq = 13.7e3;
    let mu_0 = mu_eq + 56.4e3 + 31.5e3 + 19.8e3;
    let zs = |mu: f64| 0.6874 * (mu / eps).sqrt();
    let e_max = 1.2 * zs(mu_0);
    // ramp durations from 1 µs (instantaneous) to 10⁸ s (relaxed: ≫ the longest τ = 500 s)
    let durations = [1e-6, 1.0, 10.0, 100.0, 1e3, 1e6, 1e8];
    let ec: Vec<f64> = durations
        .iter()
        .map(|d| critical_field(m.as_ref(), e_max / d, e_max, 4000))
        .collect();
    for (d, e) in durations.iter().zip(&ec) {
        eprintln!(
            "ramp to {:.1} MV/m in {d:e} s: pull-in at {:.4} MV/m",
            e_max / 1e6,
            e / 1e6
        );
    }
    assert!(ec.windows(2).all(|w| w[1] < w[0]), "{ec:?}");
    let (fast, slow) = (ec[0], *ec.last().unwrap());
    eprintln!(
        "limits: instantaneous {:.4} MV/m (Zhao–Suo {:.4}), relaxed {:.4} MV/m (Zhao–Suo {:.4})",
        fast / 1e6,
        zs(mu_0) / 1e6,
        slow / 1e6,
        zs(mu_eq) / 1e6
    );
    assert!((fast / zs(mu_0) - 1.0).abs() < 0.005, "{fast} {}", zs(mu_0));
    assert!(
        (slow / zs(mu_eq) - 1.0).abs() < 0.005,
        "{slow} {}",
        zs(mu_eq)
    );
    // intermediate rates lie strictly between
    assert!(ec[1..ec.len() - 1]
        .iter()
        .all(|&e| e < 0.995 * fast && e > 1.005 * slow));
}

/// The FE film (one hex8 cell, `vhb4910-wang2016`) ramped at `volts_per_s` to pull-in: the
/// recorded (time, in-plane stretch, thickness stretch) of its ramp.
fn fe_ramp(dir: &std::path::Path, name: &str, duration: f64) -> (Vec<[f64; 3]>, i32) {
    let text = format!(
        r#"name = "{name}"
[mesh]
generator = "box"
size = [1e-3, 1e-3, 1e-3]
divisions = [1, 1, 1]
element = "hex8"
[materials.vhb]
preset = "vhb4910-wang2016"
[[constraints]]
set = "x0"
fix = ["x"]
[[constraints]]
set = "y0"
fix = ["y"]
[[constraints]]
set = "z0"
fix = ["z"]
[electrodes.bottom]
set = "z0"
voltage = 0.0
[electrodes.top]
set = "z1"
voltage = {{ waveform = "ramp", amplitude = 40e3, rise_time = {duration} }}
[[stages]]
name = "ramp"
kind = "quasi-static"
duration = {duration}
steps = 100
[probes.thickness]
kind = "mean"
quantity = "uz"
set = "z1"
scale = 1000.0
offset = 1.0
[probes.inplane]
kind = "mean"
quantity = "ux"
set = "x1"
scale = 1000.0
offset = 1.0
[output]
fields_every = 0
plots = false
"#
    );
    std::fs::write(dir.join(format!("{name}.toml")), text).unwrap();
    let o = deasim(&["run", &format!("{name}.toml"), "--out", name], dir);
    let h = std::fs::read_to_string(dir.join(name).join("history.csv")).unwrap();
    let mut lines = h.lines();
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| head.iter().position(|h| *h == n).unwrap();
    let (ct, cl, cz) = (col("time"), col("probe:inplane"), col("probe:thickness"));
    let rows = lines
        .map(|l| {
            let v: Vec<f64> = l
                .split(',')
                .map(|x| x.parse().unwrap_or(f64::NAN))
                .collect();
            [v[ct], v[cl], v[cz]]
        })
        .filter(|r| r[0] > 0.0)
        .collect();
    (rows, o.status.code().unwrap_or(-1))
}

#[test]
fn finite_element_film_equals_the_homogeneous_history_at_every_rate() {
    let dir = tempdir("rate-pull-in");
    let m = material("vhb4910-wang2016");
    let mut critical = Vec::new();
    for (i, duration) in [0.1f64, 3.0, 100.0].into_iter().enumerate() {
        let (rows, code) = fe_ramp(&dir, &format!("r{i}"), duration);
        assert_eq!(code, 1, "the ramp to 40 kV must end in pull-in");
        let times: Vec<f64> = rows.iter().map(|r| r[0]).collect();
        let e = |t: f64| 40e3 * (t / duration).min(1.0) / H;
        let point = run(m.as_ref(), Mode::Equibiaxial, &Control::Field(&e), &times)
            .expect("the point converges where the FE did");
        let mut worst = 0.0f64;
        for (r, p) in rows.iter().zip(&point) {
            worst = worst
                .max((r[1] - p.stretch).abs())
                .max((r[2] - p.lateral).abs());
        }
        let v_c = e(*times.last().unwrap()) * H;
        eprintln!(
            "ramp 40 kV in {duration} s: {} steps, pull-in after {v_c:.1} V, FE vs point {worst:.2e}",
            rows.len()
        );
        assert!(worst < 1e-8, "{worst}");
        critical.push(v_c);
    }
    // faster ramps pull in later, between the relaxed (~13 kV) and instantaneous (~30 kV) limits
    let relaxed = critical_field(material("vhb4910-ab-wang").as_ref(), 1e6, 40e6, 4000) * H;
    let instantaneous = critical_field(m.as_ref(), 40e6 / 1e-6, 40e6, 4000) * H;
    eprintln!(
        "limits: relaxed {relaxed:.1} V, instantaneous {instantaneous:.1} V; FE {critical:?}"
    );
    assert!(critical.windows(2).all(|w| w[1] < w[0]), "{critical:?}");
    assert!(critical.iter().all(|&v| v > relaxed && v < instantaneous));
}
