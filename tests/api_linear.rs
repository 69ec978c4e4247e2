//! The small-signal analyses of the library interface (`deasim::api`): the modes about the
//! loaded state, the biased linearisation with its frequency response and reduced model, their
//! refusals and a cancelled run to the loaded state.

use deasim::api::{self, Cancel, Error, RunOptions, Simulation};
use deasim::job::plan::StageKind;
use deasim::time::modal::ModeSettings;

/// The coarse diaphragm (8 radial cells, 1 layer).
fn coarse() -> Simulation {
    Simulation::from_example("diaphragm")
        .unwrap()
        .set("mesh.radial", "8")
        .set("mesh.layers", "1")
}

/// The modes are those of the state after the static stages, with every electrode's voltage
/// there, and the run to that state is in the results.
#[test]
fn loaded_modes_are_taken_after_the_static_stages() {
    let settings = ModeSettings {
        count: 3,
        ..Default::default()
    };
    let plan = api::modes_plan(coarse().plan().unwrap(), &settings).unwrap();
    assert!(plan
        .stages
        .iter()
        .all(|s| !matches!(s.kind, StageKind::Dynamic { .. })));
    let m = api::loaded_modes(&plan, &settings, RunOptions::default()).unwrap();
    assert_eq!(m.modes.len(), 3);
    assert_eq!(m.stage, plan.stages.last().unwrap().name);
    assert_eq!(m.bias.len(), plan.electrodes.len());
    assert!(!m.results.records.is_empty());
    let direct = deasim::job::linear::modes_at(&plan, &m.state, &settings).unwrap();
    for (a, b) in m.modes.iter().zip(&direct) {
        assert!((a.frequency - b.frequency).abs() <= 1e-9 * b.frequency);
    }
    assert!(m.note.unwrap().contains("axisymmetric"));
}

/// A scenario that starts dynamic, a negative shift and a driven electrode that does not exist
/// are refused with what is expected.
#[test]
fn bad_requests_are_refused() {
    let film = Simulation::from_example("film-vibration").unwrap();
    let e = api::modes_plan(film.plan().unwrap(), &ModeSettings::default()).unwrap_err();
    assert!(
        matches!(&e, Error::Refused(m) if m.contains("starts with a dynamic stage")),
        "{e}"
    );
    let shift = ModeSettings {
        shift_hz: -1.0,
        ..Default::default()
    };
    let e = api::modes_plan(coarse().plan().unwrap(), &shift).unwrap_err();
    assert!(
        matches!(&e, Error::Refused(m) if m.contains("shift")),
        "{e}"
    );
    let e = api::prepare(
        coarse().plan().unwrap(),
        Some("nowhere"),
        None,
        RunOptions::default(),
    )
    .err()
    .unwrap();
    assert!(
        matches!(&e, Error::Refused(m) if m.contains("no electrode `nowhere`")),
        "{e}"
    );
}

/// The biased linearisation gives the response per probe at each frequency and a reduced model
/// whose matrices fit together.
#[test]
fn response_and_reduced_model_of_the_biased_state() {
    let mut p = api::prepare(
        coarse().plan().unwrap(),
        None,
        Some(1500.0),
        RunOptions::default(),
    )
    .unwrap();
    assert_eq!(p.bias, 1500.0);
    assert!(p.warning.is_none());
    let r = p.frequency_response(&[1.0, 10.0]).unwrap();
    assert_eq!(r.probes.len(), p.names().len());
    assert!(r.probes.iter().all(|(_, v)| v.len() == 2));
    assert!(matches!(
        p.frequency_response(&[0.0]),
        Err(Error::Refused(_))
    ));
    let m = p.reduced_model(2).unwrap();
    let n = m.a.len();
    assert!(m.a.iter().all(|row| row.len() == n));
    assert_eq!(m.b.len(), n);
    assert_eq!(m.c.len(), p.names().len());
    assert_eq!(m.d.len(), p.names().len());
    assert!(matches!(p.reduced_model(0), Err(Error::Refused(_))));
}

/// A cancelled token stops the run to the loaded state: the error keeps its kind.
#[test]
fn a_cancelled_run_to_the_loaded_state_is_interrupted() {
    let cancel = Cancel::new();
    cancel.cancel();
    let e = api::prepare(
        coarse().plan().unwrap(),
        None,
        None,
        RunOptions {
            cancel: Some(cancel),
            ..Default::default()
        },
    )
    .err()
    .unwrap();
    assert!(matches!(e, Error::Interrupted { .. }), "{e}");
}
