//! GUM uncertainty: Student's t, budgets, and Monte Carlo.
//!
//! - [`student`]: Student's t quantile and distribution function (coverage factors);
//! - [`distribution`]: the distributions of input quantities (normal, rectangular,
//!   triangular, arcsine, t);
//! - [`budget`]: GUM budgets (law of propagation, Welch–Satterthwaite, coverage factor);
//! - [`budget_file`]: the budget TOML file of docs/FORMAT.md §5;
//! - [`calibration`]: the uncertainty of the calibration results, per quantity: the fit's
//!   covariance with the instrument's budget (GUM), and Monte Carlo through the solver;
//! - [`monte_carlo`]: propagation of distributions (GUM Supplement 1, JCGM 101:2008): one
//!   engine, generic over the trial, with the adaptive procedure, a progress hook and the
//!   validation of the GUM result; the calibration's Monte Carlo runs on it;
//! - `format` (private): number formatting and the budget table ([`render_table`]).

pub mod budget;
pub mod budget_file;
pub mod calibration;
pub mod distribution;
pub(crate) mod format;
pub mod monte_carlo;
pub mod student;

pub use budget::{
    Budget, BudgetError, BudgetResult, Component, ComponentError, ComponentResult, DofPolicy,
    EvaluationType,
};
pub use budget_file::{BudgetFile, read_budget_path};
pub use distribution::{Distribution, DistributionError};
pub use format::{budget_table, render_table};
pub use student::{normal_cdf, normal_quantile, t_cdf, t_coverage, t_quantile};
