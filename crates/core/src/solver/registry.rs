//! The solvers, one row each: name, aliases, what the row's solver reads beyond the common
//! settings, and how it is checked and built. [`SolverKind`], its names, parsing, checks,
//! construction and the refusal of settings a solver ignores all come from the one table
//! in `solver_table!` at the end of this file: adding a solver is its own file and one
//! row there (the compiler checks the rest: every `match` over [`SolverKind`] is generated
//! from the table).

use super::gathering::{self, GatherMethod};
use super::{
    CgSolver, GatheringSolver, HierarchicalSolver, Problem, ProgressiveSolver, RowCache, Solver,
    SolverError, hierarchical, matrix,
};

/// A setting that only some solvers read. Given for a solver that does not read it, the
/// command line and scene file refuse it ([`SolverKind::refuse_unread`]) instead of
/// silently ignoring it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SolverOption {
    /// `--formfactor`: how form-factor rows are computed (solvers that store rows).
    FormFactor,
    /// `--no-overshoot`: overshooting by the ambient estimate (shooting).
    Overshoot,
    /// `--ambient`: the display correction while unconverged (shooting).
    Ambient,
    /// `--omega`: the relaxation factor (SOR).
    Omega,
    /// `--link-tolerance`: the BF refinement threshold (hierarchical and wavelet).
    LinkTolerance,
}

impl SolverOption {
    /// Every option, in declaration order.
    pub const ALL: [SolverOption; 5] = [
        SolverOption::FormFactor,
        SolverOption::Overshoot,
        SolverOption::Ambient,
        SolverOption::Omega,
        SolverOption::LinkTolerance,
    ];

    /// The command-line flag that sets it.
    pub fn flag(self) -> &'static str {
        match self {
            SolverOption::FormFactor => "--formfactor",
            SolverOption::Overshoot => "--no-overshoot",
            SolverOption::Ambient => "--ambient",
            SolverOption::Omega => "--omega",
            SolverOption::LinkTolerance => "--link-tolerance",
        }
    }
}

/// A set of [`SolverOption`]s: the ones a run was given.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OptionSet(u8);

impl OptionSet {
    /// The set of `options`.
    pub fn of(options: &[SolverOption]) -> Self {
        let mut set = Self::default();
        for &o in options {
            set.insert(o);
        }
        set
    }
    pub fn insert(&mut self, option: SolverOption) {
        self.0 |= 1 << option as u8;
    }
    pub fn contains(self, option: SolverOption) -> bool {
        self.0 & (1 << option as u8) != 0
    }
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// The options in the set, in declaration order.
    pub fn iter(self) -> impl Iterator<Item = SolverOption> {
        SolverOption::ALL
            .into_iter()
            .filter(move |o| self.contains(*o))
    }
}

/// One solver's row of the registry.
pub struct SolverRow {
    /// The name as the command line, the scene file and the viewer spell it.
    pub name: &'static str,
    /// Other accepted spellings.
    pub aliases: &'static [&'static str],
    /// One line for help texts and the viewer's solver menu.
    pub summary: &'static str,
    /// The kind [`SolverKind::parse`] returns for the name (SOR: ω estimated).
    pub parsed: SolverKind,
    /// The settings beyond the common ones that this solver reads.
    pub reads: &'static [SolverOption],
    /// Refuses a problem the solver cannot take (ω out of range, a matrix over the memory
    /// budget), before any work.
    pub check: fn(SolverKind, &Problem) -> Result<(), SolverError>,
    /// The solver on `problem`, starting dark, reusing the rows when it stores rows.
    pub build: BuildFn,
}

/// How a row builds its solver: the kind (with its payload), the problem and the rows to
/// reuse.
pub type BuildFn = fn(SolverKind, Problem, RowCache) -> Result<Box<dyn Solver>, SolverError>;

/// Generates [`SolverKind`] and the matches over it from the rows, so that a new solver is
/// one row (a variant, possibly with a payload, and its [`SolverRow`]).
macro_rules! solver_table {
    ($( $(#[$doc:meta])* $variant:ident $(($payload:ty))? => $row:expr ),+ $(,)?) => {
        /// Which solver (`--solver`): one per row of the registry ([`SolverRow`]).
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub enum SolverKind {
            $( $(#[$doc])* $variant $(($payload))? ),+
        }

        impl SolverKind {
            /// Every solver's row, in the order help texts and menus list them.
            pub const ROWS: &'static [SolverRow] = &[$($row),+];

            /// This solver's row of the registry.
            pub fn row(self) -> &'static SolverRow {
                const ROWS: &[SolverRow] = SolverKind::ROWS;
                let mut i = 0;
                $(
                    if solver_table!(@is self, $variant $(($payload))?) {
                        return &ROWS[i];
                    }
                    i += 1;
                )+
                unreachable!("every variant has a row (generated from the same list): {i}")
            }
        }
    };
    (@is $e:expr, $variant:ident ($payload:ty)) => { matches!($e, SolverKind::$variant(_)) };
    (@is $e:expr, $variant:ident) => { matches!($e, SolverKind::$variant) };
}

fn no_check(_: SolverKind, _: &Problem) -> Result<(), SolverError> {
    Ok(())
}

fn matrix_check(kind: SolverKind, problem: &Problem) -> Result<(), SolverError> {
    if let SolverKind::Sor(omega) = kind {
        gathering::check_omega(GatherMethod::Sor(omega))?;
    }
    matrix::PatchMatrix::check(problem, kind.name())
}

fn build_gathering(
    kind: SolverKind,
    problem: Problem,
    rows: RowCache,
) -> Result<Box<dyn Solver>, SolverError> {
    let method = match kind {
        SolverKind::Jacobi => GatherMethod::Jacobi,
        SolverKind::GaussSeidel => GatherMethod::GaussSeidel,
        SolverKind::Sor(omega) => GatherMethod::Sor(omega),
        other => unreachable!("{} is not a gathering solver", other.name()),
    };
    Ok(Box::new(GatheringSolver::with_rows(problem, method, rows)?))
}

const ROW_SETTINGS: &[SolverOption] = &[SolverOption::FormFactor];

solver_table! {
    Shooting => SolverRow {
        name: "shooting",
        aliases: &[],
        summary: "progressive refinement with overshooting: an image after a few shots",
        parsed: SolverKind::Shooting,
        reads: &[SolverOption::FormFactor, SolverOption::Overshoot, SolverOption::Ambient],
        check: no_check,
        build: |_, problem, rows| Ok(Box::new(ProgressiveSolver::with_rows(problem, rows))),
    },
    Jacobi => SolverRow {
        name: "jacobi",
        aliases: &[],
        summary: "Jacobi sweeps on the stored patch matrix",
        parsed: SolverKind::Jacobi,
        reads: ROW_SETTINGS,
        check: matrix_check,
        build: build_gathering,
    },
    GaussSeidel => SolverRow {
        name: "gauss-seidel",
        aliases: &["gs"],
        summary: "Gauss-Seidel sweeps on the stored patch matrix",
        parsed: SolverKind::GaussSeidel,
        reads: ROW_SETTINGS,
        check: matrix_check,
        build: build_gathering,
    },
    /// Successive over-relaxation; `None` = ω estimated from the first sweeps.
    Sor(Option<f64>) => SolverRow {
        name: "sor",
        aliases: &[],
        summary: "successive over-relaxation on the stored patch matrix (ω given or estimated)",
        parsed: SolverKind::Sor(None),
        reads: &[SolverOption::FormFactor, SolverOption::Omega],
        check: matrix_check,
        build: build_gathering,
    },
    Cg => SolverRow {
        name: "cg",
        aliases: &[],
        summary: "BiCGSTAB (a Krylov method) on the stored patch matrix",
        parsed: SolverKind::Cg,
        reads: ROW_SETTINGS,
        check: matrix_check,
        build: |_, problem, rows| Ok(Box::new(CgSolver::with_rows(problem, rows)?)),
    },
    /// Hierarchical radiosity with clustering ([`hierarchical`]).
    Hierarchical => SolverRow {
        name: "hierarchical",
        aliases: &["hr"],
        summary: "hierarchical radiosity with clustering: links that follow the light",
        parsed: SolverKind::Hierarchical,
        reads: &[SolverOption::LinkTolerance],
        check: no_check,
        // Links, not rows: cached rows are dropped.
        build: |_, problem, _| Ok(Box::new(HierarchicalSolver::new(problem))),
    },
    /// Wavelet radiosity with flatlets F2 ([`hierarchical::flatlet`]).
    Wavelet => SolverRow {
        name: "wavelet",
        aliases: &["flatlet"],
        summary: "wavelet radiosity with flatlets F2 (piecewise-constant within an element)",
        parsed: SolverKind::Wavelet,
        reads: &[SolverOption::LinkTolerance],
        check: no_check,
        build: |_, problem, _| {
            Ok(Box::new(HierarchicalSolver::with_basis(
                problem,
                hierarchical::Basis::Flatlet,
            )))
        },
    },
}

impl SolverKind {
    /// Names as the command line spells them, in the registry's order.
    pub fn names() -> impl Iterator<Item = &'static str> {
        Self::ROWS.iter().map(|r| r.name)
    }

    /// The names joined by `", "`, for messages.
    pub fn names_joined() -> String {
        Self::names().collect::<Vec<_>>().join(", ")
    }

    /// Parses a `--solver` name or alias; `omega` applies to `sor`.
    pub fn parse(name: &str, omega: Option<f64>) -> Option<SolverKind> {
        let row = Self::ROWS
            .iter()
            .find(|r| r.name == name || r.aliases.contains(&name))?;
        Some(match row.parsed {
            SolverKind::Sor(_) => SolverKind::Sor(omega),
            kind => kind,
        })
    }

    /// The name as the command line spells it.
    pub fn name(self) -> &'static str {
        self.row().name
    }

    /// Whether this solver reads `option`.
    pub fn reads(self, option: SolverOption) -> bool {
        self.row().reads.contains(&option)
    }

    /// Whether this solver reads every option of `given`.
    pub fn reads_all(self, given: OptionSet) -> bool {
        given.iter().all(|o| self.reads(o))
    }

    /// Refuses settings this solver would ignore: the first of `given` it does not read,
    /// as a message naming the flag and the solvers that read it.
    pub fn refuse_unread(self, given: OptionSet) -> Result<(), String> {
        match given.iter().find(|o| !self.reads(*o)) {
            None => Ok(()),
            Some(option) => Err(unread_message(option, self.name())),
        }
    }

    /// Whether [`build`](Self::build) would refuse `problem` (ω out of range, a matrix over
    /// the memory budget), without taking it.
    pub fn check(self, problem: &Problem) -> Result<(), SolverError> {
        (self.row().check)(self, problem)
    }

    /// A solver of this kind on `problem`, starting dark.
    pub fn build(self, problem: Problem) -> Result<Box<dyn Solver>, SolverError> {
        self.build_with_rows(problem, None)
    }

    /// As [`build`](Self::build), reusing form-factor rows cached on the same problem (by
    /// [`Solver::into_parts`] of another solver): switching solvers keeps the mesh and the
    /// rows.
    pub fn build_with_rows(
        self,
        problem: Problem,
        rows: Option<RowCache>,
    ) -> Result<Box<dyn Solver>, SolverError> {
        (self.row().build)(self, problem, rows.unwrap_or_default())
    }
}

/// "`--flag` is a setting of --solver a and b; --solver `solver` does not use it".
pub fn unread_message(option: SolverOption, solver: &str) -> String {
    let readers: Vec<&str> = SolverKind::ROWS
        .iter()
        .filter(|r| r.reads.contains(&option))
        .map(|r| r.name)
        .collect();
    format!(
        "{} is a setting of --solver {}; --solver {solver} does not use it",
        option.flag(),
        readers.join(" and "),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_row_parses_back_to_its_kind_and_names_are_unique() {
        for (i, row) in SolverKind::ROWS.iter().enumerate() {
            let kind = SolverKind::parse(row.name, None).expect(row.name);
            assert_eq!(kind, row.parsed);
            assert_eq!(kind.row().name, row.name);
            for alias in row.aliases {
                assert_eq!(SolverKind::parse(alias, None), Some(kind));
            }
            for other in &SolverKind::ROWS[i + 1..] {
                assert_ne!(row.name, other.name);
            }
        }
        assert_eq!(
            SolverKind::parse("sor", Some(1.5)),
            Some(SolverKind::Sor(Some(1.5)))
        );
        assert_eq!(SolverKind::parse("magic", None), None);
    }

    #[test]
    fn a_setting_the_solver_ignores_is_refused_by_its_flag() {
        let err = SolverKind::Hierarchical
            .refuse_unread(OptionSet::of(&[SolverOption::FormFactor]))
            .unwrap_err();
        assert!(err.contains("--formfactor"), "{err}");
        assert!(err.contains("--solver hierarchical"), "{err}");
        assert!(err.contains("shooting"), "{err}");
        let err = SolverKind::Shooting
            .refuse_unread(OptionSet::of(&[SolverOption::Omega]))
            .unwrap_err();
        assert!(
            err.contains("--omega is a setting of --solver sor"),
            "{err}"
        );
        assert!(
            SolverKind::Sor(None)
                .refuse_unread(OptionSet::of(&[
                    SolverOption::Omega,
                    SolverOption::FormFactor
                ]))
                .is_ok()
        );
        assert!(
            SolverKind::Wavelet
                .refuse_unread(OptionSet::default())
                .is_ok()
        );
    }
}
