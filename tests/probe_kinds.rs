//! Every probe kind on every kind of geometry (a 3-D box film, an axisymmetric diaphragm and
//! balloon, a 3-D stack): `check` refuses it with a clear message (exit 2), or the run records
//! finite values; never a panic. And the area strain of an axisymmetric electrode is that of its
//! ring surface.

mod common;

use common::{deasim, tempdir};
use deasim::job::probes::{Probe, ProbeInput, ProbeKind, Share};

fn text(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned() + &String::from_utf8_lossy(&o.stdout)
}

/// A geometry: its example, the overrides that make it small and short, a face set, an
/// electrode and a point of the mesh.
struct Geometry {
    example: &'static str,
    sets: &'static [&'static str],
    faces: &'static str,
    electrode: &'static str,
    at: &'static str,
}

const GEOMETRIES: [Geometry; 4] = [
    Geometry {
        example: "film",
        sets: &["stages.0.steps=2"],
        faces: "z1",
        electrode: "top",
        at: "[0.0, 0.0, 0.001]",
    },
    Geometry {
        example: "diaphragm",
        sets: &[
            "mesh.radial=4",
            "mesh.layers=1",
            "prestretch.steps=1",
            "stages.0.steps=1",
            "stages.1.duration=0.003",
        ],
        faces: "electrode_top",
        electrode: "top",
        at: "[0.0, 0.0, 0.0]",
    },
    Geometry {
        example: "balloon",
        sets: &[
            "mesh.radial=6",
            "mesh.layers=1",
            "stages.0.steps=1",
            "stages.1.target.value=1.2",
        ],
        faces: "inner",
        electrode: "outside",
        at: "[10e-3, 0.0, 0.0]",
    },
    Geometry {
        example: "stack",
        sets: &[
            "mesh.layers_per_film=1",
            "mesh.active_cells=2",
            "stages.0.steps=1",
        ],
        faces: "top",
        electrode: "hv",
        at: "[0.0, 0.0, 200e-6]",
    },
];

/// The probe kinds, each with the keys it needs on geometry `g`.
fn kinds(g: &Geometry) -> Vec<(&'static str, String)> {
    let (f, e, at) = (g.faces, g.electrode, g.at);
    vec![
        ("mean", format!("kind=\"mean\",quantity=\"u\",set=\"{f}\"")),
        ("max", format!("kind=\"max\",quantity=\"uz\",set=\"{f}\"")),
        ("min", format!("kind=\"min\",quantity=\"phi\",set=\"{f}\"")),
        ("point", format!("kind=\"point\",quantity=\"u\",at={at}")),
        ("charge", format!("kind=\"charge\",electrode=\"{e}\"")),
        (
            "capacitance",
            format!("kind=\"capacitance\",electrode=\"{e}\""),
        ),
        (
            "reaction",
            format!("kind=\"reaction\",quantity=\"z\",set=\"{f}\""),
        ),
        ("energy", "kind=\"energy\",quantity=\"stored\"".to_string()),
        (
            "center_deflection",
            format!("kind=\"center_deflection\",set=\"{f}\""),
        ),
        ("max_electric_field", "kind=\"max_electric_field\"".into()),
        ("current", format!("kind=\"current\",electrode=\"{e}\"")),
        ("power", format!("kind=\"power\",electrode=\"{e}\"")),
        (
            "source_energy",
            format!("kind=\"source_energy\",electrode=\"{e}\""),
        ),
        (
            "resistor_loss",
            format!("kind=\"resistor_loss\",electrode=\"{e}\""),
        ),
        (
            "area_strain",
            format!("kind=\"area_strain\",electrode=\"{e}\""),
        ),
        (
            "area_strain_set",
            format!("kind=\"area_strain\",set=\"{f}\""),
        ),
        ("volume", format!("kind=\"volume\",set=\"{f}\"")),
        ("pressure", format!("kind=\"pressure\",set=\"{f}\"")),
    ]
}

fn with_sets(base: &[&str], g: &Geometry, extra: &[String]) -> Vec<String> {
    let mut args: Vec<String> = base.iter().map(|s| s.to_string()).collect();
    args.push(format!("{}.toml", g.example));
    for s in g
        .sets
        .iter()
        .map(|s| s.to_string())
        .chain(extra.iter().cloned())
    {
        args.push("--set".into());
        args.push(s);
    }
    args
}

#[test]
fn every_probe_kind_on_every_geometry_is_refused_or_finite() {
    let dir = tempdir("probe-kinds");
    for g in &GEOMETRIES {
        let toml = deasim(&["example", g.example], &dir).stdout;
        std::fs::write(dir.join(format!("{}.toml", g.example)), toml).unwrap();
        let mut accepted = Vec::new();
        for (name, keys) in kinds(g) {
            let set = format!("probes.p_{name}={{{keys}}}");
            let args = with_sets(&["check", "--no-trial"], g, std::slice::from_ref(&set));
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let out = deasim(&args, &dir);
            let t = text(&out);
            assert!(!t.contains("panicked"), "{} {name}: {t}", g.example);
            match out.status.code() {
                Some(0) => accepted.push((name, set)),
                Some(2) => assert!(
                    t.contains(&format!("probes.p_{name}")),
                    "{} {name}: the refusal names no key: {t}",
                    g.example
                ),
                c => panic!("{} {name}: check ended with {c:?}: {t}", g.example),
            }
        }
        let names: Vec<&str> = accepted.iter().map(|a| a.0).collect();
        // the area strain of a surface, on every geometry; of an electrode where the electrode
        // is a face set (the stack's inner electrodes are node sets)
        assert!(
            names.contains(&"area_strain_set")
                && (names.contains(&"area_strain") || g.example == "stack"),
            "{}: {names:?}",
            g.example
        );
        let sets: Vec<String> = accepted.iter().map(|a| a.1.clone()).collect();
        let mut args = with_sets(&["run"], g, &sets);
        args.extend(["--out".into(), g.example.into()]);
        args.extend(["--set".into(), "output.plots=false".into()]);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = deasim(&args, &dir);
        let t = text(&out);
        assert_eq!(out.status.code(), Some(0), "{} {names:?}: {t}", g.example);
        let summary: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.join(g.example).join("summary.json")).unwrap(),
        )
        .unwrap();
        for name in &names {
            let v = &summary["probes"][format!("p_{name}")];
            assert!(
                v.as_f64().is_some_and(f64::is_finite),
                "{} {name}: {v} in {}",
                g.example,
                summary["probes"]
            );
        }
    }
}

/// The area strain of the diaphragm's top electrode (a set of meridian sides): its reference
/// area is the disc π r_e² its ring surfaces sweep, and a radial stretch λ (u_r = (λ − 1) R)
/// makes the strain λ² − 1 exactly (a rigid lift u_z changes nothing). Quadratic cells (3-node
/// sides) too.
#[test]
fn area_strain_of_an_axisymmetric_electrode_is_its_ring_area() {
    for element in ["quad4", "quad8", "tri6"] {
        let plan = deasim::cli::app::load(
            None,
            &[
                "probes.area={kind=\"area_strain\",electrode=\"top\"}".into(),
                format!("mesh.element=\"{element}\""),
                "mesh.formulation=\"displacement\"".into(),
            ],
        )
        .unwrap_or_else(|e| panic!("{element}: {e}"));
        let probe = &plan.probes.iter().find(|p| p.0 == "area").unwrap().1;
        let ProbeKind::AreaStrain(faces) = &probe.kind else {
            panic!("{:?}", probe.kind)
        };
        assert!(faces
            .iter()
            .all(|f| f.ring && f.nodes.len() == 2 + (element != "quad4") as usize));
        let mesh = &plan.model.mesh;
        let reference = vec![0.0; mesh.n_nodes() * 4];
        let lambda = 1.3;
        let mut state = reference.clone();
        for (n, x) in mesh.nodes.iter().enumerate() {
            state[n * 4] = (lambda - 1.0) * x[0];
            state[n * 4 + 1] = 1e-4;
        }
        let (Share::Sum([_, area]), zero) = evaluate(probe, &reference, &reference) else {
            panic!("a sum")
        };
        let disc = std::f64::consts::PI * 7.5e-3 * 7.5e-3;
        assert!(
            (area - disc).abs() < 1e-12 * disc,
            "{element}: {area} vs {disc}"
        );
        assert_eq!(zero, 0.0);
        let (_, strain) = evaluate(probe, &state, &reference);
        let exact = lambda * lambda - 1.0;
        assert!(
            (strain - exact).abs() < 1e-12,
            "{element}: {strain} vs {exact}"
        );
    }
}

/// The probe's share and value at `state` against `reference`.
fn evaluate(probe: &Probe, state: &[f64], reference: &[f64]) -> (Share, f64) {
    let input = ProbeInput {
        state,
        reactions: reference,
        electrodes: &[],
        stored: 0.0,
        electric: 0.0,
        reference,
        max_field: 0.0,
        symmetry: 1.0,
        previous: (&[], 0.0),
        circuit_energy: &[],
        pressures: &[],
        charges: &[],
    };
    (probe.share(&input), probe.evaluate(&input))
}
