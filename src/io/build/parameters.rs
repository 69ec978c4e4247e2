//! Key paths of material parameters: which material and which entry of its parameter vector θ
//! ([`crate::material::parameters`]) a scenario key names, in the one style of `--set`
//! (`materials.vhb.c10`, `materials.vhb.branches.1.tau`, `materials.gel.mu.0`). What a gradient,
//! a calibration or an optimal control addresses.

use super::materials::build_material;
use super::Ctx;
use crate::io::scenario::{closest, InputError, Scenario, VoltageSpec};
use crate::waveform::WaveformScalar;

/// A material parameter named by a key path.
#[derive(Debug, Clone, PartialEq)]
pub struct ParameterKey {
    /// The material's name.
    pub material: String,
    /// Its index in name order: the order of [`super::materials`] and of the plan's materials.
    pub material_index: usize,
    /// The entry of the material's θ.
    pub entry: usize,
    /// The entry's name (the key below `materials.<name>.`).
    pub name: String,
    /// Its value in the scenario (a preset's unless overridden), SI units as the scenario's.
    pub value: f64,
}

/// The keys a material table takes ([`crate::io::scenario::MaterialSpec`]): an unknown key is
/// suggested the closest of these or of the material's parameters.
const MATERIAL_KEYS: &[&str] = &[
    "model",
    "preset",
    "mu",
    "lambda",
    "kappa",
    "c10",
    "c20",
    "c30",
    "c01",
    "d1",
    "d2",
    "d3",
    "jm",
    "lambda_m",
    "alpha",
    "permittivity",
    "c1",
    "c2",
    "density",
    "viscosity",
    "breakdown_field",
    "stop_at_breakdown",
    "branches",
];

/// The material parameter that `key` names in scenario `s` (from file `file`): its material, the
/// entry of that material's θ and its value. A key of the scenario that is no differentiable
/// material parameter (`mesh.divisions`, `materials.vhb.model`, `materials.vhb.density`, a Yeoh
/// D₂ of 0) is refused naming the key and listing the material's parameters; an unknown key gets
/// the "did you mean" of the scenario's errors.
pub fn material_parameter(s: &Scenario, file: &str, key: &str) -> Result<ParameterKey, InputError> {
    let ctx = Ctx::plain(file);
    let parts: Vec<&str> = key.split('.').collect();
    let hint = |word: &str, candidates: &[&str]| {
        closest(word, candidates.iter().copied())
            .map(|c| format!("; did you mean `{c}`?"))
            .unwrap_or_default()
    };
    let names: Vec<&str> = s.materials.keys().map(|n| n.as_str()).collect();
    if parts.first() != Some(&"materials") {
        if let Some(unknown) = unknown_part(s, &parts) {
            return Err(ctx.err(key, unknown));
        }
        return Err(ctx.err(
            key,
            format!(
                "not a material parameter: only the parameters of a material's model are \
                 differentiable; expected `materials.<name>.<parameter>` (materials: {})",
                names.join(", ")
            ),
        ));
    }
    let Some(&name) = parts.get(1) else {
        return Err(ctx.err(key, "expected `materials.<name>.<parameter>`"));
    };
    let Some(index) = names.iter().position(|n| *n == name) else {
        return Err(ctx.err(
            key,
            format!(
                "unknown material `{name}` (materials: {}){}",
                names.join(", "),
                hint(name, &names)
            ),
        ));
    };
    let (mat, _) = build_material(&ctx, name, &s.materials[name], &mut Vec::new())?;
    let theta = mat.parameters().ok_or_else(|| {
        ctx.err(
            format!("materials.{name}"),
            "this material has no parameter vector",
        )
    })?;
    let list = theta.names.join(", ");
    let rest = parts[2..].join(".");
    if rest.is_empty() {
        return Err(ctx.err(
            key,
            format!(
                "a material, not a parameter: expected `materials.{name}.<parameter>` with one of \
                 the parameters of `{name}` (model `{}`): {list}",
                theta.model
            ),
        ));
    }
    if let Some(entry) = theta.index(&rest) {
        return Ok(ParameterKey {
            material: name.to_string(),
            material_index: index,
            entry,
            name: rest,
            value: theta.values[entry],
        });
    }
    let given = toml::Value::try_from(&s.materials[name]).ok();
    let exists = MATERIAL_KEYS.contains(&parts[2])
        && given
            .as_ref()
            .is_none_or(|v| parts.len() == 3 || lookup(v, &parts[3..]).is_some());
    if !exists {
        let mut candidates: Vec<&str> = theta.names.iter().map(|n| n.as_str()).collect();
        candidates.extend(MATERIAL_KEYS);
        return Err(ctx.err(
            key,
            format!(
                "unknown parameter `{rest}` of material `{name}` (its parameters: {list}){}",
                hint(&rest, &candidates)
            ),
        ));
    }
    let why = match rest.as_str() {
        "model" | "preset" => " (it chooses the model, not a number)".to_string(),
        "density" | "viscosity" | "breakdown_field" | "stop_at_breakdown" => {
            " (not a parameter of the material's energy)".to_string()
        }
        "d2" | "d3" if theta.model == "yeoh" => {
            format!(" (a Yeoh {rest} of 0 switches its term off: no derivative there)")
        }
        "mu" | "alpha" if theta.model == "ogden" => {
            format!(" (Ogden's lists by index: {rest}.0, {rest}.1, …)")
        }
        _ => format!(" (not a parameter of model `{}`)", theta.model),
    };
    Err(ctx.err(
        key,
        format!(
            "not a differentiable parameter{why}: expected one of the parameters of material \
             `{name}` (model `{}`): {list}",
            theta.model
        ),
    ))
}

/// A differentiable scalar of a scenario, named by its key path.
#[derive(Debug, Clone, PartialEq)]
pub enum Parameter {
    /// An entry of a material's parameter vector θ.
    Material(ParameterKey),
    /// A scalar of an electrode's voltage (`source`: of its circuit's source): the waveform's
    /// amplitude (V; a constant voltage is one), offset (V) or frequency (Hz).
    Voltage {
        electrode: String,
        source: bool,
        scalar: WaveformScalar,
        value: f64,
    },
    /// The charge of a charge-controlled electrode: a constant charge (C), or its waveform's
    /// amplitude, offset (C) or frequency (Hz).
    Charge {
        electrode: String,
        scalar: WaveformScalar,
        value: f64,
    },
    /// The series resistance of an electrode's circuit (Ω).
    Resistance { electrode: String, value: f64 },
    /// The mass of a rigid pad (kg), by its index in `loads.rigid`.
    RigidMass { index: usize, value: f64 },
    /// The Kelvin–Voigt viscosity η of a material (Pa·s), by its index in the plan.
    Viscosity {
        material: String,
        material_index: usize,
        value: f64,
    },
    /// The density ρ₀ of a material (kg/m³, per reference volume), by its index in the plan:
    /// its mass and its weight.
    Density {
        material: String,
        material_index: usize,
        value: f64,
    },
    /// The pre-stretch λ.
    Prestretch { value: f64 },
    /// The value (Pa) of a follower pressure, by its index in `loads.pressure`.
    Pressure { index: usize, value: f64 },
}

impl Parameter {
    /// Its value in the scenario (SI).
    pub fn value(&self) -> f64 {
        match self {
            Parameter::Material(k) => k.value,
            Parameter::Voltage { value, .. }
            | Parameter::Charge { value, .. }
            | Parameter::Resistance { value, .. }
            | Parameter::RigidMass { value, .. }
            | Parameter::Viscosity { value, .. }
            | Parameter::Density { value, .. }
            | Parameter::Prestretch { value }
            | Parameter::Pressure { value, .. } => *value,
        }
    }
}

/// The differentiable parameter that `key` names in scenario `s` (from file `file`): a
/// material's (see [`material_parameter`]), an electrode's voltage amplitude, offset or frequency,
/// charge, or circuit source and resistance, a pressure's value, a rigid pad's mass, or the
/// pre-stretch. Any other key of the scenario (`mesh.divisions`, a square wave's frequency) is
/// refused naming the key and what is differentiable; an unknown key gets the "did you mean" of
/// the scenario's errors.
pub fn parameter(s: &Scenario, file: &str, key: &str) -> Result<Parameter, InputError> {
    let ctx = Ctx::plain(file);
    let parts: Vec<&str> = key.split('.').collect();
    // a material's viscosity and density: scalars of the plan beside its energy, each
    // differentiable where it is positive
    if let ["materials", name, which @ ("viscosity" | "density")] = parts.as_slice() {
        if let Some(material_index) = s.materials.keys().position(|n| n == name) {
            let m = &s.materials[*name];
            let (value, what) = match *which {
                "viscosity" => (m.viscosity.unwrap_or(0.0), "Kelvin–Voigt viscosity"),
                _ => (m.density.unwrap_or(0.0), "density"),
            };
            if value > 0.0 {
                let material = name.to_string();
                return Ok(match *which {
                    "viscosity" => Parameter::Viscosity {
                        material,
                        material_index,
                        value,
                    },
                    _ => Parameter::Density {
                        material,
                        material_index,
                        value,
                    },
                });
            }
            return Err(ctx.err(
                key,
                format!(
                    "material `{name}` has no {what} to differentiate: give \
                     `materials.{name}.{which}` a value > 0"
                ),
            ));
        }
    }
    if parts.first() == Some(&"materials") {
        return material_parameter(s, file, key).map(Parameter::Material);
    }
    if let Some(unknown) = unknown_part(s, &parts) {
        return Err(ctx.err(key, unknown));
    }
    // a waveform's frequency where its values change smoothly with it: a square wave's values
    // at the steps jump as its frequency moves, so its frequency is refused (with the reason)
    let mut refused = None;
    let mut voltage = |electrode: &str, spec: &VoltageSpec, rest: &[&str], source: bool| {
        let (scalar, value) = match (spec, rest) {
            (VoltageSpec::Constant(v), []) => (WaveformScalar::Amplitude, *v),
            (VoltageSpec::Waveform(w), ["amplitude"]) => (WaveformScalar::Amplitude, w.amplitude),
            (VoltageSpec::Waveform(w), ["offset"]) => (WaveformScalar::Offset, w.offset),
            (VoltageSpec::Waveform(w), ["frequency"]) => {
                let f = w.frequency?;
                if w.waveform == "square" {
                    refused = Some(
                        "a square wave's values at the steps jump as its frequency moves: its \
                         frequency has no derivative (a `sine`, `triangle` or `fourier` \
                         waveform's has)",
                    );
                    return None;
                }
                (WaveformScalar::Frequency, f)
            }
            _ => return None,
        };
        Some(Parameter::Voltage {
            electrode: electrode.to_string(),
            source,
            scalar,
            value,
        })
    };
    let found = match parts.as_slice() {
        ["electrodes", name, rest @ ..] => s.electrodes.get(*name).and_then(|e| match rest {
            ["voltage", tail @ ..] => voltage(name, &e.voltage, tail, false),
            // a constant charge, or a charge waveform's amplitude or offset
            ["charge", tail @ ..] => {
                e.charge
                    .as_ref()
                    .and_then(|spec| match voltage(name, spec, tail, false)? {
                        Parameter::Voltage { scalar, value, .. } => Some(Parameter::Charge {
                            electrode: name.to_string(),
                            scalar,
                            value,
                        }),
                        _ => None,
                    })
            }
            ["circuit", "resistance"] => e.circuit.as_ref().map(|c| Parameter::Resistance {
                electrode: name.to_string(),
                value: c.resistance,
            }),
            ["circuit", "source", tail @ ..] => e
                .circuit
                .as_ref()
                .and_then(|c| voltage(name, &c.source, tail, true)),
            _ => None,
        }),
        ["loads", "rigid", index, "mass"] => {
            let rigid = s.loads.as_ref().map(|l| l.rigid.as_slice()).unwrap_or(&[]);
            index.parse::<usize>().ok().and_then(|i| {
                rigid.get(i).map(|r| Parameter::RigidMass {
                    index: i,
                    value: r.mass,
                })
            })
        }
        ["loads", "pressure", index, "value"] => {
            let pressures = s.loads.as_ref().map_or(&[][..], |l| l.pressure.as_slice());
            index.parse::<usize>().ok().and_then(|i| {
                let value = pressures.get(i)?.value?;
                Some(Parameter::Pressure { index: i, value })
            })
        }
        ["prestretch", "stretch"] => s
            .prestretch
            .as_ref()
            .map(|p| Parameter::Prestretch { value: p.stretch }),
        _ => None,
    };
    if let Some(why) = refused {
        return Err(ctx.err(key, why));
    }
    found.ok_or_else(|| {
        ctx.err(
            key,
            "not a differentiable parameter: expected a material's \
             (`materials.<name>.<parameter>`, `materials.<name>.viscosity`), an electrode's \
             voltage amplitude, offset or frequency (`electrodes.<name>.voltage`, \
             `electrodes.<name>.voltage.amplitude`, `.offset`, `.frequency`, the same below \
             `electrodes.<name>.circuit.source` and `electrodes.<name>.charge`), \
             `electrodes.<name>.circuit.resistance`, `loads.pressure.<i>.value`, \
             `loads.rigid.<i>.mass` or `prestretch.stretch`",
        )
    })
}

/// The value at `path` below `v` (tables by key, arrays by index).
fn lookup<'a>(v: &'a toml::Value, path: &[&str]) -> Option<&'a toml::Value> {
    path.iter().try_fold(v, |cur, part| match cur {
        toml::Value::Table(t) => t.get(*part),
        toml::Value::Array(a) => a.get(part.parse::<usize>().ok()?),
        _ => None,
    })
}

/// The message for a key outside `materials` that the scenario does not hold, with the closest
/// key at the level where it leaves the scenario; `None` when the scenario holds it.
fn unknown_part(s: &Scenario, parts: &[&str]) -> Option<String> {
    let root = toml::Value::try_from(s).ok()?;
    let mut cur = &root;
    for (i, part) in parts.iter().enumerate() {
        match lookup(cur, &parts[i..=i]) {
            Some(next) => cur = next,
            None => {
                let so_far = parts[..=i].join(".");
                let candidates: Vec<&str> = match cur {
                    toml::Value::Table(t) => t.keys().map(|k| k.as_str()).collect(),
                    _ => Vec::new(),
                };
                let parent = parts[..i]
                    .iter()
                    .map(|p| format!("{p}."))
                    .collect::<String>();
                let hint = closest(part, candidates.iter().copied())
                    .map(|c| format!("; did you mean `{parent}{c}`?"))
                    .unwrap_or_default();
                return Some(format!(
                    "unknown key `{so_far}` (not in the scenario){hint}"
                ));
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::super::testing::{scenario, text, FILE};
    use super::*;
    use crate::io::scenario::{parse, MaterialSpec};

    fn at(materials: &str, key: &str) -> Result<ParameterKey, InputError> {
        material_parameter(&scenario(&[("materials", materials)]), FILE, key)
    }

    /// Asserts that `key` is refused, naming it, with a message containing each of `says`.
    fn refused(materials: &str, key: &str, says: &[&str]) {
        let e = at(materials, key).expect_err(key);
        let msg = e.to_string();
        assert_eq!(e.key.as_deref(), Some(key), "{msg}");
        assert!(msg.starts_with(&format!("{FILE}: key `{key}`: ")), "{msg}");
        for s in says {
            assert!(msg.contains(s), "`{s}` not in: {msg}");
        }
    }

    const TWO: &str = "[materials.vhb]\npreset = \"vhb4910-wang2016\"\n\
                       [materials.gel]\nmodel = \"ogden\"\nmu = [1e5, 2e3]\nalpha = [1.5, 4.0]\n\
                       kappa = 1e7\npermittivity = 4.7\ndensity = 1000.0";

    const YEOH: &str = "[materials.y]\nmodel = \"yeoh\"\nc10 = 5e4\nd1 = 2e-8\nd2 = 0.0\n\
                        permittivity = 4.7";

    #[test]
    fn a_parameter_key_names_its_material_entry_and_value() {
        // the base scenario's neo-Hooke material
        let base = "[materials.gel]\nmodel = \"neo-hooke\"\nmu = 1e5\nlambda = 1e7\n\
                    permittivity = 4.7";
        let k = at(base, "materials.gel.lambda").unwrap();
        assert_eq!(
            k,
            ParameterKey {
                material: "gel".into(),
                material_index: 0,
                entry: 1,
                name: "lambda".into(),
                value: 1e7,
            }
        );
        assert_eq!(at(base, "materials.gel.c2").unwrap().value, 0.0);
        // a preset's parameters by the model's names; materials in name order (gel, vhb)
        let k = at(TWO, "materials.vhb.lambda_m").unwrap();
        assert_eq!((k.material_index, k.entry, k.value), (1, 1, 5.99));
        let k = at(TWO, "materials.vhb.branches.1.tau").unwrap();
        assert_eq!((k.entry, k.value), (9, 6.56));
        assert_eq!(
            at(TWO, "materials.vhb.branches.2.mu").unwrap().value,
            10.83e3
        );
        assert!((at(TWO, "materials.vhb.permittivity").unwrap().value - 4.8).abs() < 1e-14);
        // Ogden's lists by index
        let k = at(TWO, "materials.gel.alpha.1").unwrap();
        assert_eq!((k.material_index, k.entry, k.value), (0, 3, 4.0));
        // a density is a parameter of its own (the mass and the weight, not the energy)
        let s = scenario(&[("materials", TWO)]);
        assert_eq!(
            parameter(&s, FILE, "materials.gel.density").unwrap(),
            Parameter::Density {
                material: "gel".into(),
                material_index: 0,
                value: 1000.0
            }
        );
        let e = parameter(&s, FILE, "materials.vhb.density").unwrap_err();
        assert!(e.to_string().contains("no density to differentiate"), "{e}");
        // the entry is the material's θ entry
        let mats = super::super::materials(&scenario(&[("materials", TWO)]), FILE).unwrap();
        let theta = mats[1].parameters().unwrap();
        assert_eq!(theta.names[9], "branches.1.tau");
    }

    #[test]
    fn keys_that_are_no_differentiable_parameter_are_refused() {
        refused(
            TWO,
            "mesh.divisions",
            &["not a material parameter", "materials.<name>.<parameter>"],
        );
        refused(
            TWO,
            "materials.vhb.preset",
            &[
                "not a differentiable parameter (it chooses the model",
                "model `arruda-boyce`): mu, lambda_m, kappa, permittivity, c1, c2, branches.0.mu",
            ],
        );
        refused(
            TWO,
            "materials.gel.model",
            &["not a differentiable parameter", "mu.0, mu.1, alpha.0"],
        );
        refused(
            TWO,
            "materials.gel.density",
            &["not a parameter of the material's energy"],
        );
        refused(TWO, "materials.gel.mu", &["Ogden's lists by index: mu.0"]);
        refused(
            TWO,
            "materials.vhb.c10",
            &["not a parameter of model `arruda-boyce`"],
        );
        refused(TWO, "materials.vhb", &["a material, not a parameter"]);
        refused(
            YEOH,
            "materials.y.d2",
            &[
                "switches its term off",
                "c10, c20, c30, d1, permittivity, c1, c2",
            ],
        );
    }

    #[test]
    fn unknown_keys_get_a_suggestion() {
        refused(
            TWO,
            "materials.vhb.lamda_m",
            &[
                "unknown parameter `lamda_m` of material `vhb`",
                "did you mean `lambda_m`?",
            ],
        );
        refused(
            TWO,
            "materials.vhx.kappa",
            &["unknown material `vhx`", "did you mean `vhb`?"],
        );
        refused(
            TWO,
            "materials.gel.mu.5",
            &["unknown parameter `mu.5`", "did you mean `mu.0`?"],
        );
        refused(
            TWO,
            "materials.vhb.branches.7.tau",
            &["unknown parameter `branches.7.tau`"],
        );
        refused(
            TWO,
            "mesh.divisons",
            &[
                "unknown key `mesh.divisons`",
                "did you mean `mesh.divisions`?",
            ],
        );
    }

    /// The key of a parameter is the one `--set` takes: an override changes the value it names.
    #[test]
    fn a_set_override_changes_the_value_the_key_names() {
        let m = "[materials.gel]\nmodel = \"ogden\"\nmu = [1e5, 2e3]\nalpha = [1.5, 4.0]\n\
                 kappa = 1e7\npermittivity = 4.7\nbranches = [{ mu = 1e4, tau = 2.0 }]";
        let text = text(&[("materials", m)]);
        for (key, v) in [
            ("materials.gel.alpha.1", 4.5),
            ("materials.gel.mu.0", 1.2e5),
            ("materials.gel.branches.0.tau", 3.0),
            ("materials.gel.kappa", 2e7),
            ("materials.gel.c1", 1e-12),
        ] {
            let s = parse(&text, FILE, &[format!("{key}={v:e}")]).unwrap();
            assert_eq!(material_parameter(&s, FILE, key).unwrap().value, v, "{key}");
        }
    }

    /// Every key of the list is one a material table takes.
    #[test]
    fn the_material_keys_are_the_material_tables() {
        let e = toml::from_str::<MaterialSpec>("nonsense = 1").unwrap_err();
        let msg = e.to_string();
        for k in MATERIAL_KEYS {
            assert!(msg.contains(&format!("`{k}`")), "{k}: {msg}");
        }
        assert_eq!(
            msg.matches('`').count(),
            2 * (MATERIAL_KEYS.len() + 1),
            "{msg}"
        );
    }

    /// Every kind of parameter outside the materials is named by its key path, with its value;
    /// keys that hold no differentiable number are refused naming the key.
    #[test]
    fn device_parameters_are_named_by_their_key_paths() {
        let example =
            |name: &str| parse(crate::io::examples::example(name).unwrap(), FILE, &[]).unwrap();
        let film = example("film-vibration");
        let p = |s: &Scenario, key: &str| parameter(s, FILE, key).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            p(&film, "electrodes.top.voltage.amplitude"),
            Parameter::Voltage {
                electrode: "top".into(),
                source: false,
                scalar: WaveformScalar::Amplitude,
                value: 20e3
            }
        );
        assert_eq!(p(&film, "electrodes.top.voltage.offset").value(), 0.0);
        assert_eq!(p(&film, "electrodes.bottom.voltage").value(), 0.0);
        let disc = example("diaphragm");
        assert_eq!(
            p(&disc, "loads.rigid.0.mass"),
            Parameter::RigidMass {
                index: 0,
                value: 0.04622
            }
        );
        assert!(
            matches!(p(&disc, "prestretch.stretch"), Parameter::Prestretch { value } if value > 1.0)
        );
        assert!(matches!(
            p(&film, "materials.elastomer.mu"),
            Parameter::Material(ParameterKey { entry: 0, .. })
        ));
        let circuit = parse(
            &crate::io::examples::example("film-vibration")
                .unwrap()
                .replace(
                    "voltage = { waveform = \"step\", amplitude = 20e3, at = 0.0 }",
                    "circuit = { source = 1e3, resistance = 1e6 }",
                ),
            FILE,
            &[],
        )
        .unwrap();
        assert_eq!(
            p(&circuit, "electrodes.top.circuit.resistance"),
            Parameter::Resistance {
                electrode: "top".into(),
                value: 1e6
            }
        );
        assert_eq!(p(&circuit, "electrodes.top.circuit.source").value(), 1e3);
        for key in [
            "mesh.divisions",
            "electrodes.top.voltage.at",
            "electrodes.top.voltage.waveform",
            "electrodes.top.set",
            "loads.rigid.0.damping",
        ] {
            let s = if key.starts_with("loads") {
                &disc
            } else {
                &film
            };
            let e = parameter(s, FILE, key).expect_err(key);
            let msg = e.to_string();
            assert_eq!(e.key.as_deref(), Some(key), "{msg}");
            assert!(msg.contains("not a differentiable parameter"), "{msg}");
        }
        let e = parameter(&film, FILE, "electrodes.top.voltage.amplitud").unwrap_err();
        assert!(e.to_string().contains("did you mean"), "{e}");
        // a pressure's value; a smooth waveform's frequency, not a square wave's
        let balloon = example("balloon");
        assert_eq!(
            p(&balloon, "loads.pressure.0.value"),
            Parameter::Pressure {
                index: 0,
                value: balloon.loads.as_ref().unwrap().pressure[0].value.unwrap()
            }
        );
        let e = parameter(&disc, FILE, "electrodes.top.voltage.frequency").unwrap_err();
        assert_eq!(e.key.as_deref(), Some("electrodes.top.voltage.frequency"));
        assert!(e.to_string().contains("square wave"), "{e}");
        let sine = parse(
            &crate::io::examples::example("diaphragm")
                .unwrap()
                .replace("waveform = \"square\"", "waveform = \"sine\""),
            FILE,
            &[],
        )
        .unwrap();
        assert_eq!(
            p(&sine, "electrodes.top.voltage.frequency"),
            Parameter::Voltage {
                electrode: "top".into(),
                source: false,
                scalar: WaveformScalar::Frequency,
                value: 2.0
            }
        );
    }
}
