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
    let text = std::fs::read_to_string(dir.join("frf/response.csv")).unwrap();
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
