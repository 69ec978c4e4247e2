//! `deasim validate`, the verification manual: every row of every family passes, every model of
//! the material registry has its rows, `--family` selects one family, and the table reports FAIL
//! (with exit status 1) for a case outside its tolerance or a family that cannot run.

mod common;

use deasim::cli::validate::{cases_of, render, Case, Family, FAMILIES};
use deasim::material::registry::MODELS;

/// The whole table: exit 0, a group per family, every row "pass", the count line consistent.
#[test]
fn every_row_of_every_family_passes() {
    let dir = common::tempdir("validate-all");
    let started = std::time::Instant::now();
    let o = common::deasim(&["validate"], &dir);
    let out = String::from_utf8_lossy(&o.stdout);
    eprintln!(
        "{out}deasim validate: {:.1} s",
        started.elapsed().as_secs_f64()
    );
    assert_eq!(
        o.status.code(),
        Some(0),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    for f in FAMILIES {
        assert!(
            out.contains(&format!("-- {}: {}\n", f.name, f.title)),
            "family {} missing",
            f.name
        );
    }
    for model in MODELS {
        assert!(out.contains(&format!("{model}: uniaxial")), "{model}");
        assert!(out.contains(&format!("{model}: equibiaxial")), "{model}");
    }
    let rows: Vec<&str> = out
        .lines()
        .filter(|l| l.ends_with("  pass") || l.ends_with("  FAIL"))
        .collect();
    assert!(rows.len() >= 40, "{} rows", rows.len());
    assert!(rows.iter().all(|l| l.ends_with("  pass")));
    assert!(
        out.ends_with(&format!("{} passed, 0 failed\n", rows.len())),
        "{out}"
    );
}

/// `--family` prints one group; an unknown name is refused with exit 2 and the list.
#[test]
fn family_filter() {
    let dir = common::tempdir("validate-family");
    let o = common::deasim(&["validate", "--family", "small-signal"], &dir);
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0), "{out}");
    assert_eq!(out.matches("\n-- ").count(), 1, "{out}");
    assert!(out.contains("-- small-signal:"), "{out}");
    let o = common::deasim(&["validate", "--family", "nope"], &dir);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("unknown family `nope`") && err.contains("materials, cook"));
}

/// A computed value outside its tolerance, a vector deviation beyond it, a non-finite value and a
/// family that cannot run are all FAIL, and the count line says so.
#[test]
fn a_case_outside_its_tolerance_fails() {
    let row = |computed: f64| Case {
        family: "materials",
        ..Case::new("c".into(), "r".into(), 2.0, computed, 1e-3)
    };
    assert!(row(2.001).passed());
    let bad = [
        row(2.01),
        row(2.0).with_deviation(0.01),
        row(f64::NAN),
        row(f64::INFINITY),
    ];
    for c in &bad {
        assert!(!c.passed(), "{c:?}");
    }
    assert!((bad[0].rel_error() - 5e-3).abs() < 1e-12);
    let table = render(&[row(2.0), bad[0].clone()]);
    let lines: Vec<&str> = table.lines().collect();
    assert!(
        lines[2].ends_with("  pass") && lines[3].ends_with("  FAIL"),
        "{table}"
    );
    assert!(table.ends_with("1 passed, 1 failed\n"), "{table}");
    let broken = Family {
        name: "broken",
        title: "a family whose setup fails",
        run: || Err("no mesh".into()),
    };
    let rows = cases_of(&broken);
    assert_eq!(rows.len(), 1);
    assert!(!rows[0].passed() && rows[0].name.contains("no mesh"));
    assert!(render(&rows).ends_with("0 passed, 1 failed\n"));
}
