//! `[solver]`: the linear solver of every stage.

use super::Ctx;
use crate::io::scenario::{InputError, Scenario};
use crate::solve::linear::{FactorPrecision, Ordering, SolverKind, SolverSettings};
use crate::solve::newton::NewtonSettings;
use crate::solve::stepping::StepControl;

/// `[solver]`'s Newton and step-control keys → the settings of every nonlinear solve of the run
/// (the defaults without them).
pub(super) fn build_newton(
    ctx: &Ctx,
    s: &Scenario,
) -> Result<(NewtonSettings, StepControl), InputError> {
    let mut newton = NewtonSettings::default();
    let mut control = StepControl::default();
    let Some(spec) = &s.solver else {
        return Ok((newton, control));
    };
    if let Some(r) = spec.newton_rtol {
        if !(r > 0.0 && r < 1.0) {
            return Err(ctx.err(
                "solver.newton_rtol",
                format!("{r} is outside (0, 1): expected Newton's relative residual tolerance, e.g. 1e-10"),
            ));
        }
        newton.rtol = r;
    }
    let count = |key: &str, v: i64, least: i64| {
        usize::try_from(v)
            .ok()
            .filter(|&n| n as i64 >= least)
            .ok_or_else(|| ctx.err(key, format!("{v}: expected a whole number ≥ {least}")))
    };
    if let Some(n) = spec.newton_max_iterations {
        newton.max_iterations = count("solver.newton_max_iterations", n, 1)?;
    }
    if let Some(n) = spec.line_search_halvings {
        newton.max_backtracks = count("solver.line_search_halvings", n, 0)?;
    }
    if let Some(t) = &spec.newton_tangent {
        newton.lag_tangent = choice(
            ctx,
            "newton_tangent",
            t,
            [("lagged", true), ("every-iteration", false)],
        )?;
    }
    if let Some(f) = spec.min_step_fraction {
        if !(f > 0.0 && f <= 1.0) {
            return Err(ctx.err(
                "solver.min_step_fraction",
                format!("{f} is outside (0, 1]: expected the smallest increment as a fraction of a nominal step, e.g. 0.000244"),
            ));
        }
        control.min_fraction = f;
    }
    Ok((newton, control))
}

/// `[solver]` → the solver settings (the defaults without the table).
pub(super) fn build_solver(ctx: &Ctx, s: &Scenario) -> Result<SolverSettings, InputError> {
    let mut out = SolverSettings::default();
    let Some(spec) = &s.solver else {
        return Ok(out);
    };
    if let Some(k) = &spec.kind {
        out.kind = SolverKind::from_name(k).ok_or_else(|| {
            let message = match SolverKind::OPTIONAL.iter().find(|(name, _)| name == k) {
                Some((name, feature)) => {
                    format!("kind = \"{name}\" needs a build with --features {feature}")
                }
                None => format!(
                    "unknown solver `{k}`; expected one of: {}",
                    SolverKind::NAMES.join(", ")
                ),
            };
            ctx.err("solver.kind", message)
        })?;
    }
    if let Some(o) = &spec.petsc_options {
        if out.kind.name() != "petsc" {
            return Err(ctx.err(
                "solver.petsc_options",
                "petsc_options applies to kind = \"petsc\" only",
            ));
        }
        out.petsc_options = o.clone();
    }
    #[cfg(feature = "petsc")]
    if out.kind == SolverKind::Petsc {
        crate::solve::petsc::initialize()
            .map_err(|e| ctx.err("solver.kind", format!("PETSc could not start: {e}")))?;
        crate::solve::petsc::check_options(&out.petsc_options).map_err(|e| {
            let mut sources = vec![format!("\"{}\"", out.petsc_options)];
            if let Ok(v) = std::env::var("PETSC_OPTIONS") {
                sources.push(format!("then PETSC_OPTIONS = \"{v}\" from the environment"));
            }
            ctx.err(
                "solver.petsc_options",
                format!(
                    "PETSc refuses the solver these options choose ({}): {e}",
                    sources.join(", ")
                ),
            )
        })?;
    }
    if let Some(o) = &spec.ordering {
        out.ordering = Ordering::from_name(o).ok_or_else(|| {
            ctx.err(
                "solver.ordering",
                format!(
                    "unknown ordering `{o}`; expected one of: {}",
                    Ordering::NAMES.join(", ")
                ),
            )
        })?;
    }
    if let Some(n) = spec.reuse_from {
        if out.kind != SolverKind::Auto {
            return Err(ctx.err(
                "solver.reuse_from",
                "applies to kind = \"auto\" only (the direct kind factors every tangent)",
            ));
        }
        out.reuse_from = usize::try_from(n).map_err(|_| {
            ctx.err(
                "solver.reuse_from",
                format!("expected a number of unknowns ≥ 0, got {n}"),
            )
        })?;
    }
    if let Some(m) = spec.memory_limit {
        if !matches!(out.kind, SolverKind::Auto | SolverKind::Direct) {
            return Err(ctx.err(
                "solver.memory_limit",
                "applies to kind = \"auto\" or \"direct\" only (the kinds that factor)",
            ));
        }
        if !(m.is_finite() && m >= 1.0) {
            return Err(ctx.err(
                "solver.memory_limit",
                format!("expected a number of bytes ≥ 1, e.g. 8e9, got {m}"),
            ));
        }
        out.memory_limit = Some(m as usize);
    }
    if let Some(r) = spec.rtol {
        if !matches!(out.kind, SolverKind::Iterative | SolverKind::Auto) {
            return Err(ctx.err(
                "solver.rtol",
                "applies to kind = \"iterative\" or \"auto\" only (the direct kind solves exactly)",
            ));
        }
        if !(r > 0.0 && r < 1.0) {
            return Err(ctx.err(
                "solver.rtol",
                format!("expected a relative tolerance in (0, 1), got {r}"),
            ));
        }
        out.rtol = r;
    }
    if let Some(f) = &spec.forcing {
        if !matches!(out.kind, SolverKind::Iterative | SolverKind::Auto) && !petsc(out.kind) {
            return Err(ctx.err(
                "solver.forcing",
                "applies to kind = \"iterative\", \"auto\" or \"petsc\" only (the direct kind \
                 solves exactly)",
            ));
        }
        out.adaptive = choice(ctx, "forcing", f, [("adaptive", true), ("fixed", false)])?;
    } else if petsc(out.kind) {
        // in one large step to a strongly nonlinear state, loose first directions can leave
        // Newton creeping until it fails and the step is cut back (docs/petsc.md)
        out.adaptive = false;
    }
    if let Some(p) = &spec.preconditioner {
        if !petsc(out.kind) {
            return Err(ctx.err(
                "solver.preconditioner",
                "applies to kind = \"petsc\" only (deasim's own kinds renew theirs by their \
                 own measures)",
            ));
        }
        out.keep_preconditioner = choice(
            ctx,
            "preconditioner",
            p,
            [("kept", true), ("renewed", false)],
        )?;
    } else {
        // a set-up of algebraic multigrid costs several Krylov iterations' worth, and the
        // preconditioner of a nearby tangent still serves
        out.keep_preconditioner = petsc(out.kind);
    }
    if let Some(p) = &spec.precision {
        if out.kind != SolverKind::Auto {
            return Err(ctx.err(
                "solver.precision",
                "applies to kind = \"auto\" only (the direct kind factors in double precision)",
            ));
        }
        out.precision = choice(
            ctx,
            "precision",
            p,
            [
                ("auto", FactorPrecision::Auto),
                ("double", FactorPrecision::Double),
                ("single", FactorPrecision::Single),
            ],
        )?;
    }
    if let Some(j) = &spec.jacobian {
        let exact = choice(ctx, "jacobian", j, [("exact", true), ("symmetric", false)])?;
        if exact && !matches!(out.kind, SolverKind::Auto | SolverKind::Direct) {
            return Err(ctx.err(
                "solver.jacobian",
                format!(
                    "jacobian = \"exact\" needs kind = \"auto\" or \"direct\" (a factor of its \
                     symmetric part preconditions it), not \"{}\"",
                    out.kind.name()
                ),
            ));
        }
        out.jacobian = if exact {
            crate::solve::linear::StepJacobian::Exact
        } else {
            crate::solve::linear::StepJacobian::Symmetric
        };
    }
    Ok(out)
}

/// Whether `kind` is PETSc's (never in a build without the `petsc` feature).
fn petsc(kind: SolverKind) -> bool {
    #[cfg(feature = "petsc")]
    return kind == SolverKind::Petsc;
    #[cfg(not(feature = "petsc"))]
    {
        let _ = kind;
        false
    }
}

/// The setting of one of the named choices of `solver.<key>`, or an error listing them.
fn choice<T: Copy, const N: usize>(
    ctx: &Ctx,
    key: &str,
    value: &str,
    names: [(&str, T); N],
) -> Result<T, InputError> {
    names
        .iter()
        .find(|(name, _)| *name == value)
        .map(|&(_, on)| on)
        .ok_or_else(|| {
            let listed: Vec<&str> = names.iter().map(|(name, _)| *name).collect();
            ctx.err(
                format!("solver.{key}"),
                format!(
                    "unknown {key} `{value}`; expected one of: {}",
                    listed.join(", ")
                ),
            )
        })
}

#[cfg(test)]
mod tests {
    use super::super::testing::{assert_names, assert_rejected, plan, scenario, CTX};
    use super::*;

    fn solver(text: &str) -> Result<SolverSettings, InputError> {
        build_solver(&CTX, &scenario(&[("solver", text)]))
    }

    #[test]
    fn without_the_table_the_defaults() {
        let s = plan(&[]).solver;
        assert_eq!(s.kind, SolverKind::Auto);
        assert_eq!(s.ordering, Ordering::NestedDissection);
        assert_eq!(solver("[solver]").unwrap(), SolverSettings::default());
    }

    #[test]
    fn the_amd_ordering() {
        let s = plan(&[("solver", "[solver]\nkind = \"direct\"\nordering = \"amd\"")]).solver;
        assert_eq!((s.kind, s.ordering), (SolverKind::Direct, Ordering::Amd));
    }

    #[test]
    fn nested_dissection_by_name_and_by_its_alias() {
        let s = solver("[solver]\nordering = \"nested-dissection\"").unwrap();
        assert_eq!(s.ordering, Ordering::NestedDissection);
        let s = solver("[solver]\nordering = \"metis\"").unwrap();
        assert_eq!(s.ordering, Ordering::NestedDissection);
    }

    #[test]
    fn an_unknown_solver_kind_is_rejected() {
        assert_rejected(
            &[("solver", "[solver]\nkind = \"cg\"")],
            "solver.kind",
            "unknown solver `cg`; expected one of: auto, direct, iterative",
        );
    }

    #[test]
    fn reuse_from_is_a_count_of_unknowns_for_auto_only() {
        let s = solver("[solver]\nreuse_from = 0").unwrap();
        assert_eq!((s.kind, s.reuse_from), (SolverKind::Auto, 0));
        assert_rejected(
            &[("solver", "[solver]\nreuse_from = -3")],
            "solver.reuse_from",
            "expected a number of unknowns ≥ 0, got -3",
        );
        assert_rejected(
            &[("solver", "[solver]\nkind = \"direct\"\nreuse_from = 10")],
            "solver.reuse_from",
            "applies to kind = \"auto\" only",
        );
    }

    /// `newton_tangent`: lagged by default, a tangent at every iteration on request, and an
    /// unknown value named with the accepted ones.
    #[test]
    fn newton_tangent_lagged_or_every_iteration() {
        let newton = |text: &str| build_newton(&CTX, &scenario(&[("solver", text)])).map(|n| n.0);
        assert!(newton("[solver]").unwrap().lag_tangent);
        for (value, lagged) in [("lagged", true), ("every-iteration", false)] {
            let text = format!("[solver]\nnewton_tangent = \"{value}\"");
            assert_eq!(newton(&text).unwrap().lag_tangent, lagged, "{value}");
        }
        assert_rejected(
            &[("solver", "[solver]\nnewton_tangent = \"always\"")],
            "solver.newton_tangent",
            "unknown newton_tangent `always`; expected one of: lagged, every-iteration",
        );
    }

    #[test]
    fn precision_auto_double_or_single_for_auto_only() {
        let precision = |text: &str| solver(text).unwrap().precision;
        assert_eq!(precision("[solver]"), FactorPrecision::Auto);
        assert_eq!(
            precision("[solver]\nprecision = \"auto\""),
            FactorPrecision::Auto
        );
        assert_eq!(
            precision("[solver]\nprecision = \"single\""),
            FactorPrecision::Single
        );
        assert_eq!(
            precision("[solver]\nprecision = \"double\""),
            FactorPrecision::Double
        );
        assert_rejected(
            &[("solver", "[solver]\nprecision = \"half\"")],
            "solver.precision",
            "unknown precision `half`; expected one of: auto, double, single",
        );
        assert_rejected(
            &[(
                "solver",
                "[solver]\nkind = \"direct\"\nprecision = \"single\"",
            )],
            "solver.precision",
            "applies to kind = \"auto\" only",
        );
    }

    #[test]
    fn the_iterative_kind_and_its_tolerance() {
        let s = solver("[solver]\nkind = \"iterative\"\nrtol = 1e-6").unwrap();
        assert_eq!((s.kind, s.rtol), (SolverKind::Iterative, 1e-6));
        assert_eq!(
            solver("[solver]\nkind = \"iterative\"").unwrap().rtol,
            crate::solve::iterative::DEFAULT_RTOL
        );
        assert_rejected(
            &[("solver", "[solver]\nkind = \"iterative\"\nrtol = 2.0")],
            "solver.rtol",
            "expected a relative tolerance in (0, 1), got 2",
        );
        assert_rejected(
            &[("solver", "[solver]\nkind = \"direct\"\nrtol = 1e-6")],
            "solver.rtol",
            "applies to kind = \"iterative\" or \"auto\" only",
        );
    }

    #[test]
    fn memory_limit_in_bytes_for_the_kinds_that_factor() {
        let s = solver("[solver]\nmemory_limit = 8e9").unwrap();
        assert_eq!(s.memory_limit, Some(8_000_000_000));
        assert_rejected(
            &[("solver", "[solver]\nmemory_limit = -1")],
            "solver.memory_limit",
            "expected a number of bytes ≥ 1, e.g. 8e9, got -1",
        );
        assert_rejected(
            &[(
                "solver",
                "[solver]\nkind = \"iterative\"\nmemory_limit = 8e9",
            )],
            "solver.memory_limit",
            "applies to kind = \"auto\" or \"direct\" only",
        );
    }

    #[cfg(not(feature = "petsc"))]
    #[test]
    fn the_petsc_kind_names_the_feature_it_needs() {
        assert_rejected(
            &[("solver", "[solver]\nkind = \"petsc\"")],
            "solver.kind",
            "kind = \"petsc\" needs a build with --features petsc",
        );
    }

    #[cfg(feature = "petsc")]
    #[test]
    fn the_petsc_kind_with_its_options() {
        let s = solver("[solver]\nkind = \"petsc\"\npetsc_options = \"-ksp_type minres\"").unwrap();
        assert_eq!(s.kind, SolverKind::Petsc);
        assert_eq!(s.petsc_options, "-ksp_type minres");
        assert!(s.describe(0).starts_with("PETSc"), "{}", s.describe(0));
        // every solve to PETSc's own tolerance unless told otherwise, and the solver line says
        // which
        assert!(!s.adaptive);
        assert!(!s.describe(0).contains("forcing"), "{}", s.describe(0));
        // the forcing term acts on a Krylov method only: the direct default does not mention it
        let s = solver("[solver]\nkind = \"petsc\"\nforcing = \"adaptive\"").unwrap();
        assert!(s.adaptive);
        assert!(!s.describe(0).contains("forcing"), "{}", s.describe(0));
        let s = solver(
            "[solver]\nkind = \"petsc\"\nforcing = \"adaptive\"\npetsc_options = \"-ksp_type gmres\"",
        )
        .unwrap();
        assert!(
            s.describe(0).contains("Newton's forcing term"),
            "{}",
            s.describe(0)
        );
    }

    #[cfg(feature = "petsc")]
    #[test]
    fn a_petsc_krylov_method_keeps_its_preconditioner_unless_renewed() {
        let gmres = "[solver]\nkind = \"petsc\"\npetsc_options = \"-ksp_type gmres\"";
        let s = solver(gmres).unwrap();
        assert!(s.keep_preconditioner);
        assert!(
            s.describe(0).contains("keeps its preconditioner"),
            "{}",
            s.describe(0)
        );
        let s = solver(&format!("{gmres}\npreconditioner = \"renewed\"")).unwrap();
        assert!(!s.keep_preconditioner);
        assert!(
            !s.describe(0).contains("preconditioner"),
            "{}",
            s.describe(0)
        );
        // the direct default has nothing to keep, and its line does not say it keeps anything
        let s = solver("[solver]\nkind = \"petsc\"").unwrap();
        assert!(!s.describe(0).contains("keeps"), "{}", s.describe(0));
        assert_rejected(
            &[(
                "solver",
                format!("{gmres}\npreconditioner = \"stale\"").as_str(),
            )],
            "solver.preconditioner",
            "unknown preconditioner `stale`; expected one of: kept, renewed",
        );
    }

    #[test]
    fn the_preconditioner_key_needs_the_petsc_kind() {
        assert_rejected(
            &[(
                "solver",
                "[solver]\nkind = \"iterative\"\npreconditioner = \"kept\"",
            )],
            "solver.preconditioner",
            "applies to kind = \"petsc\" only",
        );
    }

    #[test]
    fn petsc_options_need_the_petsc_kind() {
        assert_rejected(
            &[("solver", "[solver]\npetsc_options = \"-ksp_type cg\"")],
            "solver.petsc_options",
            "petsc_options applies to kind = \"petsc\" only",
        );
    }

    #[test]
    fn the_forcing_is_adaptive_unless_fixed() {
        assert!(solver("[solver]\nkind = \"iterative\"").unwrap().adaptive);
        let s = solver("[solver]\nkind = \"iterative\"\nforcing = \"fixed\"").unwrap();
        assert!(!s.adaptive);
        assert!(s.describe(10).starts_with("FGMRES to 1e-8 preconditioned"));
        assert_rejected(
            &[(
                "solver",
                "[solver]\nkind = \"iterative\"\nforcing = \"loose\"",
            )],
            "solver.forcing",
            "unknown forcing `loose`; expected one of: adaptive, fixed",
        );
        assert_rejected(
            &[("solver", "[solver]\nkind = \"direct\"\nforcing = \"fixed\"")],
            "solver.forcing",
            "applies to kind = \"iterative\", \"auto\" or \"petsc\" only",
        );
    }

    #[test]
    fn an_unknown_ordering_is_rejected() {
        assert_rejected(
            &[("solver", "[solver]\nordering = \"rcm\"")],
            "solver.ordering",
            "unknown ordering `rcm`; expected one of: nested-dissection, amd",
        );
    }

    #[test]
    fn the_kind_is_checked_before_the_ordering() {
        let e = solver("[solver]\nkind = \"cg\"\nordering = \"rcm\"").unwrap_err();
        assert_names(&e, "solver.kind", "unknown solver `cg`");
        let e = solver("[solver]\nkind = \"direct\"\nordering = \"AMD\"").unwrap_err();
        assert_names(&e, "solver.ordering", "unknown ordering `AMD`");
    }
}
