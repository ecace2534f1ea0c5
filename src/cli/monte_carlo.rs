//! The Monte Carlo options every evaluation with a budget takes (`solve`, `diagnose`,
//! `selfcal`): `--monte-carlo N|adaptive`, `--seed`, `--mc-digits`, `--mc-max-trials`
//! (docs/FORMAT.md §5.1, §5.2, §9).

use anyhow::{Result, bail};
use clap::Args;
use polycal::uncertainty::calibration::{McOptions, McSolver};
use polycal::uncertainty::monte_carlo::Trials;

/// The Monte Carlo arguments, flattened into each command that takes `--budget`.
#[derive(Args, Debug, Clone)]
pub struct McArgs {
    /// Monte Carlo through the solver (JCGM 101): a number of trials (e.g. 1000000 or
    /// 1e6) or `adaptive` (JCGM 101 §7.9). Needs --budget.
    #[arg(
        long,
        value_name = "N|adaptive",
        value_parser = parse_trials,
        allow_negative_numbers = true
    )]
    monte_carlo: Option<McTrials>,
    /// Seed of the Monte Carlo (same seed, same numbers, whatever the threads).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Significant digits of u_c for the Monte Carlo validation of the GUM result and
    /// for the adaptive procedure.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=6))]
    mc_digits: u32,
    /// Largest number of trials of the adaptive procedure (e.g. 10000000 or 1e7; at
    /// least two of its sequences, 20000 at p = 0.95).
    #[arg(long, default_value = "10000000", value_parser = parse_count, allow_negative_numbers = true)]
    mc_max_trials: usize,
}

/// `--monte-carlo`: a number of trials or the adaptive procedure.
#[derive(Debug, Clone, Copy)]
enum McTrials {
    Fixed(usize),
    Adaptive,
}

fn parse_trials(text: &str) -> Result<McTrials, TrialsError> {
    if text == "adaptive" {
        return Ok(McTrials::Adaptive);
    }
    count(text, " or `adaptive`").map(McTrials::Fixed)
}

/// `--mc-max-trials`.
fn parse_count(text: &str) -> Result<usize, TrialsError> {
    count(text, "")
}

/// A number of trials, written whole (`1000000`) or as a whole number in E notation
/// (`1e6`), up to the largest count this machine holds (18446744073709551615 on 64 bits):
/// what is too many for the memory is refused by the Monte Carlo itself, with the memory
/// it would need. `or` names what else the option takes.
fn count(text: &str, or: &'static str) -> Result<usize, TrialsError> {
    if let Ok(n) = text.parse::<usize>() {
        return Ok(n);
    }
    let value = text.parse::<f64>().ok().filter(|v| v.is_finite());
    let why = match value {
        // below 2^64 exactly (usize::MAX as f64 rounds up to 2^64)
        Some(v) if v >= 0.0 && v.fract() == 0.0 && v < usize::MAX as f64 => return Ok(v as usize),
        Some(v) if v < 0.0 => Some(NotTrials::Negative),
        Some(v) if v.fract() != 0.0 => Some(NotTrials::NotWhole),
        Some(_) => Some(NotTrials::TooMany),
        None => None,
    };
    Err(TrialsError {
        text: text.to_string(),
        or,
        why,
    })
}

/// A number of trials that cannot be read (`--monte-carlo`, `--mc-max-trials`).
#[derive(Debug, thiserror::Error)]
#[error(
    "expected a number of trials (e.g. 1000000 or 1e6){or}, got {text:?}{}",
    why.map_or(String::new(), |why| format!(": {why}"))
)]
struct TrialsError {
    /// The text given.
    text: String,
    /// What else the option takes (` or `adaptive``), or nothing.
    or: &'static str,
    /// Why a number is not a number of trials; `None`: not a number.
    why: Option<NotTrials>,
}

/// Why a number is not a number of trials.
#[derive(Debug, Clone, Copy, thiserror::Error)]
enum NotTrials {
    /// Below 0.
    #[error("a number of trials is not negative")]
    Negative,
    /// With a fraction.
    #[error("not a whole number")]
    NotWhole,
    /// More than this machine counts.
    #[error("more than {} trials", usize::MAX)]
    TooMany,
}

impl McArgs {
    /// The library's options, or `None` without `--monte-carlo`; refused without a
    /// budget, which is what the Monte Carlo propagates.
    pub fn options(&self, has_budget: bool) -> Result<Option<McOptions<'static>>> {
        let Some(trials) = self.monte_carlo else {
            return Ok(None);
        };
        if !has_budget {
            bail!(
                "--monte-carlo needs --budget: the Monte Carlo propagates the instrument \
                 budget with the reading noise (see examples/budgets/instrument.toml)"
            );
        }
        Ok(Some(
            McOptions::new(match trials {
                McTrials::Fixed(m) => Trials::Fixed(m),
                McTrials::Adaptive => Trials::Adaptive {
                    significant_digits: self.mc_digits,
                    max_trials: self.mc_max_trials,
                },
            })
            .with_seed(self.seed)
            .with_significant_digits(self.mc_digits)
            .with_solver(McSolver::Auto),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trials_are_a_count_or_adaptive() {
        assert!(matches!(
            parse_trials("1e6"),
            Ok(McTrials::Fixed(1_000_000))
        ));
        assert!(matches!(parse_trials("20000"), Ok(McTrials::Fixed(20_000))));
        assert!(matches!(parse_trials("adaptive"), Ok(McTrials::Adaptive)));
        assert!(matches!(
            parse_trials("1e13"),
            Ok(McTrials::Fixed(10_000_000_000_000))
        ));
        assert!(matches!(
            parse_trials("18446744073709551615"),
            Ok(McTrials::Fixed(usize::MAX))
        ));
        for bad in ["1.5", "-3", "-1", "many", "1e20", "2e19", "inf", "nan"] {
            assert!(parse_trials(bad).is_err(), "{bad}");
        }
        assert!(parse_trials("-1").err().is_some_and(|e| {
            e.to_string()
                .ends_with("got \"-1\": a number of trials is not negative")
        }),);
    }
}
