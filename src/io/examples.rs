//! The example scenarios embedded in the binary (`deasim example NAME`). Each is a file under
//! `scenarios/` and runs as printed.

/// (name, TOML text) of every example.
pub const EXAMPLES: &[(&str, &str)] = &[
    ("film", include_str!("../../scenarios/film.toml")),
    ("film-arc", include_str!("../../scenarios/film-arc.toml")),
    (
        "film-charge",
        include_str!("../../scenarios/film-charge.toml"),
    ),
    (
        "film-pull-in",
        include_str!("../../scenarios/film-pull-in.toml"),
    ),
    (
        "film-vibration",
        include_str!("../../scenarios/film-vibration.toml"),
    ),
    (
        "film-modes",
        include_str!("../../scenarios/film-modes.toml"),
    ),
    ("diaphragm", include_str!("../../scenarios/diaphragm.toml")),
    (
        "diaphragm-3d",
        include_str!("../../scenarios/diaphragm-3d.toml"),
    ),
    (
        "diaphragm-modes",
        include_str!("../../scenarios/diaphragm-modes.toml"),
    ),
    (
        "diaphragm-response",
        include_str!("../../scenarios/diaphragm-response.toml"),
    ),
    (
        "diaphragm-control",
        include_str!("../../scenarios/diaphragm-control.toml"),
    ),
    (
        "diaphragm-visco",
        include_str!("../../scenarios/diaphragm-visco.toml"),
    ),
    (
        "diaphragm-track",
        include_str!("../../scenarios/diaphragm-track.toml"),
    ),
    (
        "diaphragm-pid",
        include_str!("../../scenarios/diaphragm-pid.toml"),
    ),
    (
        "diaphragm-creep-hold",
        include_str!("../../scenarios/diaphragm-creep-hold.toml"),
    ),
    (
        "diaphragm-creep-pi",
        include_str!("../../scenarios/diaphragm-creep-pi.toml"),
    ),
    (
        "membrane-wrinkling",
        include_str!("../../scenarios/membrane-wrinkling.toml"),
    ),
    ("balloon", include_str!("../../scenarios/balloon.toml")),
    (
        "balloon-volume",
        include_str!("../../scenarios/balloon-volume.toml"),
    ),
    ("stack", include_str!("../../scenarios/stack.toml")),
    (
        "stack-blocked",
        include_str!("../../scenarios/stack-blocked.toml"),
    ),
];

/// The scenario `deasim run` uses without a file.
pub const DEFAULT: &str = "diaphragm";

/// The text of an example.
pub fn example(name: &str) -> Option<&'static str> {
    EXAMPLES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}
