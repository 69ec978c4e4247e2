//! The frequency response of the diaphragm (coarse mesh, Kelvin–Voigt and pad damping as in the
//! example) to a small voltage about a 1.5 kV bias (`deasim response`) against time-domain runs
//! (`deasim run`: the mass hung, the bias ramped, then 1.5 kV + 20 V sin ωt with the midpoint
//! integrator, Δt = 0.2 ms) below, at and above the pad resonance (≈ 30.6 Hz). The steady
//! amplitude and phase of the pad deflection are fitted by least squares over whole periods after
//! the transient has decayed (its envelope falls by e⁻⁷ before the fit window); the complex
//! response must agree within 1 % of its magnitude (measured: 4.8e-6, 1.1e-3, 1.1e-3 at 5, 30,
//! 100 Hz). The residual difference is the drive's
//! nonlinearity (V² has a 2ω part, orthogonal to the fit) and the integrator's phase error
//! ((ωΔt)²/12 ≤ 1.3e-3).

mod common;
use common::{deasim, tempdir};

const SETS: [&str; 2] = ["mesh.radial=8", "mesh.layers=1"];

/// The example with a static bias stage and a small sine about it at `f` Hz for `duration` s.
fn scenario(f: f64, duration: f64) -> String {
    let text = deasim::io::examples::example("diaphragm").unwrap();
    let text = text.replace(
        r#"voltage = { waveform = "square", amplitude = 3000.0, frequency = 2.0 }   # unipolar 0..3 kV"#,
        &format!(
            r#"voltage = {{ waveform = "sine", polarity = "bipolar", offset = 1500.0, amplitude = 20.0, frequency = {f} }}"#
        ),
    );
    assert!(
        text.contains("offset = 1500.0"),
        "the example's drive line changed"
    );
    let text = text.replace(
        "[[stages]]\nname = \"actuate\"",
        "[[stages]]\nname = \"bias\"\nkind = \"static\"\nsteps = 4\n\n[[stages]]\nname = \"actuate\"",
    );
    text.replace(
        "duration = 1.0                # s: two periods",
        &format!("duration = {duration}                # s: two periods"),
    )
    .replace("dt = 1e-3                     # s", "dt = 2e-4")
}

#[test]
fn response_equals_the_steady_state_of_time_domain_runs() {
    let dir = tempdir("frequency-response");
    let freqs: [f64; 3] = [5.0, 30.0, 100.0];
    std::fs::write(dir.join("d.toml"), scenario(5.0, 1.0)).unwrap();
    let mut args = vec![
        "response",
        "d.toml",
        "--bias",
        "1500",
        "--frequencies",
        "5,30,100",
        "--out",
        "frf",
    ];
    for s in SETS {
        args.extend(["--set", s]);
    }
    let o = deasim(&args, &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = std::fs::read_to_string(dir.join("frf/frequency_response.csv")).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let head: Vec<&str> = lines.next().unwrap().split(',').collect();
    let (cr, ci) = (
        head.iter()
            .position(|h| *h == "center_deflection:real")
            .unwrap(),
        head.iter()
            .position(|h| *h == "center_deflection:imag")
            .unwrap(),
    );
    let frf: Vec<(f64, f64)> = lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (v[cr], v[ci])
        })
        .collect();
    assert_eq!(frf.len(), 3);
    for (k, &f) in freqs.iter().enumerate() {
        // transient 0.35 s (e⁻⁷ of it left), then whole periods over ≥ 0.2 s
        let periods = (0.2 * f).ceil();
        let duration = 0.35 + periods / f;
        let name = format!("t{k}");
        std::fs::write(dir.join(format!("{name}.toml")), scenario(f, duration)).unwrap();
        let mut args = vec![
            "run".to_string(),
            format!("{name}.toml"),
            "--out".into(),
            name.clone(),
            "--set".into(),
            "output.fields_every=0".into(),
            "--set".into(),
            "output.plots=false".into(),
        ];
        for s in SETS {
            args.extend(["--set".into(), s.to_string()]);
        }
        let a: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        let o = deasim(&a, &dir);
        assert_eq!(
            o.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
        let h = std::fs::read_to_string(dir.join(&name).join("history.csv")).unwrap();
        let mut lines = h.lines();
        let head: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = |n: &str| head.iter().position(|h| *h == n).unwrap();
        let (ct, cs, cd, cdt) = (
            col("time"),
            col("stage"),
            col("probe:center_deflection"),
            col("dt"),
        );
        let rows: Vec<(f64, f64, f64)> = lines
            .map(|l| l.split(',').collect::<Vec<&str>>())
            .filter(|v| v[cs] == "actuate" && v[2] != "0")
            .map(|v| {
                (
                    v[ct].parse().unwrap(),
                    v[cdt].parse().unwrap(),
                    v[cd].parse().unwrap(),
                )
            })
            .collect();
        let t0 = rows[0].0 - rows[0].1;
        let w = 2.0 * std::f64::consts::PI * f;
        // least squares y = a + b sin ωt + c cos ωt over the window
        let window: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| (r.0 - t0, r.2))
            .filter(|(t, _)| *t > duration - periods / f - 1e-9)
            .collect();
        let mut ata = nalgebra::Matrix3::<f64>::zeros();
        let mut aty = nalgebra::Vector3::<f64>::zeros();
        for (t, y) in &window {
            let row = nalgebra::Vector3::new(1.0, (w * t).sin(), (w * t).cos());
            ata += row * row.transpose();
            aty += row * *y;
        }
        let coef = ata.lu().solve(&aty).unwrap();
        // input 20 sin ωt: output 20 (H_r sin ωt + H_i cos ωt)
        let (tr, ti) = (coef[1] / 20.0, coef[2] / 20.0);
        let (fr, fi) = frf[k];
        let diff = (tr - fr).hypot(ti - fi) / fr.hypot(fi);
        println!(
            "{f} Hz: response |H| = {:.4e} m/V at {:.2}°, time domain {:.4e} m/V at {:.2}° \
             ({} samples): difference {diff:.2e} of |H|",
            fr.hypot(fi),
            fi.atan2(fr).to_degrees(),
            tr.hypot(ti),
            ti.atan2(tr).to_degrees(),
            window.len()
        );
        assert!(diff < 0.01, "{f} Hz: {diff}");
    }
}

/// The coarse diaphragm linearised about 1.5 kV (as `deasim response --bias 1500`), in a new
/// directory named after `label`.
fn biased(label: &str) -> deasim::cli::response::Prepared {
    let sets: Vec<String> = SETS.iter().map(|s| s.to_string()).collect();
    let dir = tempdir(label);
    std::fs::write(dir.join("d.toml"), scenario(5.0, 1.0)).unwrap();
    deasim::cli::response::prepare(Some(&dir.join("d.toml")), &sets, None, Some(1500.0)).unwrap()
}

/// The reduced model (4 modes and the static Ritz vector) reproduces the direct frequency response
/// of the pad deflection: exact at ω → 0 (7e-10), within 2 % up to 100 Hz (measured 6.8e-4 at
/// 5 Hz, 7.8e-3 at the 30.6 Hz resonance, 1.5e-2 at 100 Hz: one static vector stands for the
/// overdamped truncated modes, exactly only at ω → 0).
#[test]
fn reduced_model_matches_the_direct_response() {
    use deasim::time::reduced::{Outputs, ReducedModel};
    let mut p = biased("reduced-direct");
    let names = p.names();
    let k = names.iter().position(|n| n == "center_deflection").unwrap();
    let offsets = p.offsets().unwrap();
    let grad = |dq: &[f64]| p.gradient(dq);
    let rom = ReducedModel::build(
        &p.lin,
        4,
        &Default::default(),
        &Outputs {
            names: names.clone(),
            offsets,
            gradient: &grad,
        },
        &p.electrode,
        p.bias,
    )
    .unwrap();
    for f in [1e-3, 5.0, 30.0, 100.0] {
        let w = 2.0 * std::f64::consts::PI * f;
        let (xr, xi) = p.lin.response(w).unwrap();
        let (gr, gi) = (p.gradient(&xr).unwrap(), p.gradient(&xi).unwrap());
        let (rr, ri) = rom.response(w)[k];
        let diff = (rr - gr[k]).hypot(ri - gi[k]) / gr[k].hypot(gi[k]);
        println!(
            "{f} Hz: direct ({:.5e}, {:.5e}), reduced ({rr:.5e}, {ri:.5e}): {diff:.2e}",
            gr[k], gi[k]
        );
        assert!(diff < if f < 1.0 { 1e-8 } else { 2e-2 }, "{f} Hz: {diff}");
    }
}

/// A sweep (`responses`) takes the frequencies in parallel, one complex LU per thread, reusing
/// each LU's storage: on one thread and on two it gives the same bits as the frequencies solved
/// one by one, in the order asked, and a failing frequency is reported by the sweep.
#[test]
fn a_sweep_in_parallel_gives_the_bits_of_single_frequencies() {
    let mut p = biased("sweep");
    let omegas: Vec<f64> = [1e-3, 5.0, 30.6, 100.0, 1000.0, 7.0, 1e4]
        .iter()
        .map(|f| 2.0 * std::f64::consts::PI * f)
        .collect();
    let single: Vec<(Vec<f64>, Vec<f64>)> =
        omegas.iter().map(|&w| p.lin.response(w).unwrap()).collect();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let swept = pool
            .install(|| {
                p.lin
                    .responses(&omegas, |xr, xi| Ok((xr.to_vec(), xi.to_vec())))
            })
            .unwrap();
        assert_eq!(swept.len(), omegas.len());
        for (k, ((sr, si), (xr, xi))) in swept.iter().zip(&single).enumerate() {
            assert!(sr == xr && si == xi, "{threads} threads, frequency {k}");
        }
        // the error of the first frequency that fails, whichever thread met it
        let failed = pool.install(|| {
            p.lin.responses(&omegas, |xr, _| {
                if xr == single[2].0.as_slice() || xr == single[5].0.as_slice() {
                    Err(format!(
                        "frequency {}",
                        if xr == single[2].0.as_slice() { 2 } else { 5 }
                    ))
                } else {
                    Ok(())
                }
            })
        });
        assert_eq!(failed.unwrap_err(), "frequency 2", "{threads} threads");
    }
}

/// The real form [[A, B], [B, −A]] of (A + iB) x = f, which distributed runs hand to their
/// solver, here solved by the serial LDLᵀ on the whole matrices, gives the complex LU's response
/// of the coarse diaphragm (Kelvin–Voigt and the pad's dashpot) below, at and above the pad
/// resonance: displacements and potentials each to 1e-9 of their largest value.
#[test]
fn the_real_form_gives_the_complex_response() {
    use deasim::job::linear::device_mass;
    use deasim::solve::linear::FaerLdlt;
    use deasim::time::frequency::linearise;
    let mut p = biased("real-form");
    let driven = p
        .plan
        .electrodes
        .iter()
        .position(|e| e.name == p.electrode)
        .unwrap();
    let mass = device_mass(&p.plan, &p.model);
    let mut real = linearise(
        &p.model,
        &p.state,
        &mass,
        &p.plan.viscosities,
        &p.plan.electrodes[driven].nodes,
        Some(Box::new(FaerLdlt::new())),
    )
    .unwrap();
    // the largest difference of each field (displacements, potential) over its largest value
    let differences = |a: &[f64], b: &[f64]| {
        let mut out = [(0.0f64, 0.0f64); 2];
        for (d, (x, y)) in a.iter().zip(b).enumerate() {
            let o = &mut out[usize::from(d % 4 == 3)];
            o.0 = o.0.max((x - y).abs());
            o.1 = o.1.max(x.abs());
        }
        out.map(|(diff, scale)| diff / scale)
    };
    for f in [1e-3, 5.0, 30.6, 100.0, 1000.0] {
        let w = 2.0 * std::f64::consts::PI * f;
        let (cr, ci) = p.lin.response(w).unwrap();
        let (rr, ri) = real.response(w).unwrap();
        let (dr, di) = (differences(&cr, &rr), differences(&ci, &ri));
        println!(
            "{f} Hz: real part {:.2e} {:.2e}, imaginary part {:.2e} {:.2e} (u, Φ)",
            dr[0], dr[1], di[0], di[1]
        );
        for d in dr.into_iter().chain(di) {
            assert!(d < 1e-9, "{f} Hz: {dr:?} {di:?}");
        }
    }
}

/// `deasim reduce --compare`: the reduced model (4 modes and the static Ritz vector) of the coarse
/// diaphragm about its loaded state at 1520 V, driven by the scenario's square wave 1500 ± 20 V at
/// 5 Hz, against the finite element run of the same scenario: the pad deflection within 2 % of
/// its peak-to-peak (measured 1.0 %, of which ≈ 1.3 % at most is expected from V² linearised at
/// the top of a 40 V swing; 0.26 % with a 2 V square), the charge within 0.1 %. The model's JSON
/// and CSV matrices are consistent (2N + 2 states).
#[test]
fn reduced_model_follows_a_square_wave() {
    let dir = tempdir("reduced-square");
    let text = scenario(5.0, 0.4).replace(
        r#"waveform = "sine", polarity = "bipolar""#,
        r#"waveform = "square", polarity = "bipolar""#,
    );
    std::fs::write(dir.join("sq.toml"), text).unwrap();
    let mut run = vec![
        "run",
        "sq.toml",
        "--out",
        "fe",
        "--set",
        "output.fields_every=0",
        "--set",
        "output.plots=false",
    ];
    for s in SETS {
        run.extend(["--set", s]);
    }
    let o = deasim(&run, &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let mut args = vec![
        "reduce",
        "sq.toml",
        "--modes",
        "4",
        "--compare",
        "fe",
        "--out",
        "rom",
    ];
    for s in SETS {
        args.extend(["--set", s]);
    }
    let o = deasim(&args, &dir);
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    println!("{out}");
    let fraction = |probe: &str| -> f64 {
        let line = out
            .lines()
            .find(|l| l.starts_with(&format!("{probe}:")))
            .unwrap();
        line.split(" = ")
            .nth(1)
            .unwrap()
            .split_whitespace()
            .next()
            .unwrap()
            .parse()
            .unwrap()
    };
    assert!(fraction("center_deflection") < 0.02, "{out}");
    assert!(fraction("charge") < 1e-3, "{out}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("rom/reduced_model.json")).unwrap())
            .unwrap();
    let states = json["a"].as_array().unwrap().len();
    assert_eq!(states, 2 * (4 + 1));
    assert_eq!(json["b"].as_array().unwrap().len(), states);
    assert_eq!(
        json["c"].as_array().unwrap().len(),
        json["outputs"].as_array().unwrap().len()
    );
    let a_csv = std::fs::read_to_string(dir.join("rom/A.csv")).unwrap();
    assert_eq!(a_csv.lines().count(), states);
    assert!(dir.join("rom/compare_center_deflection.png").exists());
}
