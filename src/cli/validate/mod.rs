//! `deasim validate`: the verification manual. Every family of the code (materials, Cook's
//! membrane, the film, time integration, viscoelasticity, axisymmetry, small-signal) is run
//! against closed forms and published values and printed as one table: family, case, reference,
//! expected, computed, relative error, tolerance and pass/FAIL (docs/validation.md).

pub mod axisymmetric;
pub mod cook;
pub mod dynamics;
pub mod film;
pub mod materials;
pub mod small_signal;
pub mod viscoelastic;

use super::app::{EXIT_BAD_INPUT, EXIT_OK, EXIT_SOLVE_FAILED};

/// One verification result.
#[derive(Debug, Clone)]
pub struct Case {
    /// The family's name (set by [`cases_of`]).
    pub family: &'static str,
    pub name: String,
    /// Where the expected value comes from.
    pub reference: String,
    pub expected: f64,
    pub computed: f64,
    /// The absolute deviation when it is not |computed − expected|: for a vector or tensor the
    /// norm of the difference (expected and computed are then norms), for a run the largest
    /// deviation over its steps.
    pub deviation: Option<f64>,
    /// Largest accepted relative error.
    pub tolerance: f64,
}

impl Case {
    pub fn new(
        name: String,
        reference: String,
        expected: f64,
        computed: f64,
        tolerance: f64,
    ) -> Self {
        Case {
            family: "",
            name,
            reference,
            expected,
            computed,
            deviation: None,
            tolerance,
        }
    }

    /// The same case with the deviation given (see [`Case::deviation`]).
    pub fn with_deviation(self, deviation: f64) -> Self {
        Case {
            deviation: Some(deviation),
            ..self
        }
    }

    /// Deviation relative to |expected|; NaN when a value is not finite.
    pub fn rel_error(&self) -> f64 {
        let d = self
            .deviation
            .unwrap_or((self.computed - self.expected).abs());
        if self.computed.is_finite() && self.expected.is_finite() {
            d / self.expected.abs()
        } else {
            f64::NAN
        }
    }

    /// Within tolerance (false for a NaN error).
    pub fn passed(&self) -> bool {
        self.rel_error() <= self.tolerance
    }
}

/// A family of cases.
pub struct Family {
    /// Name for `--family`.
    pub name: &'static str,
    /// Heading of its group in the table.
    pub title: &'static str,
    /// Runs the family's cases.
    pub run: fn() -> Result<Vec<Case>, String>,
}

/// Every family, in the order of the table.
pub const FAMILIES: &[Family] = &[
    Family {
        name: "materials",
        title: "hyperelastic models and the dielectric at homogeneous states",
        run: materials::cases,
    },
    Family {
        name: "cook",
        title: "Cook's membrane, tip deflection",
        run: cook::cases,
    },
    Family {
        name: "film",
        title: "homogeneous film: closed form and pull-in",
        run: film::cases,
    },
    Family {
        name: "dynamics",
        title: "time integration: midpoint rule without damping",
        run: dynamics::cases,
    },
    Family {
        name: "viscoelasticity",
        title: "Maxwell branches, one hex8 cell in uniaxial stress",
        run: viscoelastic::cases,
    },
    Family {
        name: "axisymmetric",
        title: "film disc, meridian kernel",
        run: axisymmetric::cases,
    },
    Family {
        name: "small-signal",
        title: "natural frequencies of a pre-stretched membrane",
        run: small_signal::cases,
    },
];

/// The cases of one family; a family that cannot be run gives one failing row with the reason.
pub fn cases_of(family: &Family) -> Vec<Case> {
    match (family.run)() {
        Ok(mut cases) => {
            cases.iter_mut().for_each(|c| c.family = family.name);
            cases
        }
        Err(e) => vec![Case {
            family: family.name,
            ..Case::new(
                format!("could not run: {e}"),
                String::new(),
                f64::NAN,
                f64::NAN,
                0.0,
            )
        }],
    }
}

/// Runs every case.
pub fn cases() -> Vec<Case> {
    FAMILIES.iter().flat_map(cases_of).collect()
}

/// The table, grouped by family, and the closing "N passed, M failed" line.
pub fn render(cases: &[Case]) -> String {
    let width = |f: fn(&Case) -> usize, title: usize| cases.iter().map(f).fold(title, usize::max);
    let wn = width(|c| c.name.chars().count(), 4);
    let wr = width(|c| c.reference.chars().count(), 9);
    let mut out = format!(
        "{:<wn$}  {:<wr$}  {:>14} {:>14} {:>10} {:>9}  result\n",
        "case", "reference", "expected", "computed", "rel_error", "tolerance"
    );
    let mut family = None;
    for c in cases {
        if family != Some(c.family) {
            family = Some(c.family);
            let title = FAMILIES
                .iter()
                .find(|f| f.name == c.family)
                .map_or("", |f| f.title);
            out += &format!("-- {}: {title}\n", c.family);
        }
        out += &format!(
            "{:<wn$}  {:<wr$}  {:>14.8e} {:>14.8e} {:>10.2e} {:>9.1e}  {}\n",
            c.name,
            c.reference,
            c.expected,
            c.computed,
            c.rel_error(),
            c.tolerance,
            if c.passed() { "pass" } else { "FAIL" }
        );
    }
    let passed = cases.iter().filter(|c| c.passed()).count();
    out += &format!("{passed} passed, {} failed\n", cases.len() - passed);
    out
}

/// Prints the table of every family (or of the one named); exit status 0 when every case
/// passes, 1 when one fails, 2 for an unknown family.
pub fn cmd_validate(family: Option<&str>) -> i32 {
    let selected: Vec<&Family> = match family {
        None => FAMILIES.iter().collect(),
        Some(name) => match FAMILIES.iter().find(|f| f.name == name) {
            Some(f) => vec![f],
            None => {
                let names: Vec<&str> = FAMILIES.iter().map(|f| f.name).collect();
                eprintln!(
                    "error: unknown family `{name}`; expected one of: {}",
                    names.join(", ")
                );
                return EXIT_BAD_INPUT;
            }
        },
    };
    let cases: Vec<Case> = selected.into_iter().flat_map(cases_of).collect();
    print!("{}", render(&cases));
    if cases.iter().all(Case::passed) {
        EXIT_OK
    } else {
        EXIT_SOLVE_FAILED
    }
}
