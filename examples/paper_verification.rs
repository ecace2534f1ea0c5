//! The paper's verification (Hsieh et al. 2023, section 3.1, Figs. 4–7) reproduced from a
//! simulated truth: a 24-faced polygon and an encoder whose error has harmonics up to
//! order 150, measured three ways — two autocollimators (6 cycles), the shift-angle
//! method (24 mountings) and SelfA self-calibration (12 heads, 168 positions) — each
//! evaluated with its uncertainty and compared by En (ISO 13528).
//!
//! ```text
//! cargo run --release --example paper_verification -- 1 examples/budgets/instrument.toml
//! cargo run --release --example paper_verification [-- SEED [BUDGET.toml]]
//! ```
//!
//! With BUDGET.toml (e.g. examples/budgets/instrument.toml, the paper's Table 1) the
//! polygon methods carry the instrument's budget, as the paper's do; without it, their
//! type A with k from Student's t at 95 %. The self-calibration carries its type A and a
//! bound on the harmonics SelfA cannot see (order 84). Exit status 0 when every |En| ≤ 1
//! (the methods agree with each other and with the truth), 1 otherwise, 2 on an error.

use std::process::ExitCode;

use polycal::uncertainty::calibration::InstrumentBudget;
use polycal::verification::{Agreement, VerificationConfig, verify};

fn main() -> ExitCode {
    match run() {
        Ok(true) => ExitCode::SUCCESS,
        Ok(false) => ExitCode::from(1),
        Err(error) => {
            eprintln!("error: {error}");
            ExitCode::from(2)
        }
    }
}

fn run() -> Result<bool, Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mut config = VerificationConfig::default();
    if let Some(seed) = args.next() {
        config.seed = seed
            .parse()
            .map_err(|_| format!("SEED must be a whole number, not {seed:?}"))?;
    }
    if let Some(path) = args.next() {
        config.budget = Some(InstrumentBudget::read_path(&path)?);
    }
    let outcome = verify(&config)?;
    println!(
        "truth: a {}-faced polygon (pitch spread {}″) and an encoder with harmonics up to order {} (seed {})",
        config.faces, config.pitch_spread_arcsec, outcome.max_order, config.seed
    );
    println!(
        "methods: two autocollimators ({} cycles); shift-angle ({} mountings × {} cycles, one autocollimator); \
         self-calibration ({} heads, {} positions, {} cycles)",
        config.cycles,
        config.faces,
        config.mounting_cycles,
        config.selfcal.head_angles_deg.len(),
        config.selfcal.positions,
        config.selfcal.cycles
    );
    println!(
        "uncertainties: polygon methods {}; self-calibration type A{}",
        match &config.budget {
            Some(budget) => format!("with the budget {}", budget.source),
            None => "type A, k = t(95 %, dof)".to_string(),
        },
        match config.lost_harmonic_bound_arcsec {
            Some(a) => format!(
                " and a bound of {a:.4}″ on the harmonics it cannot see ({:?})",
                outcome.lost_harmonics
            ),
            None => String::new(),
        }
    );
    println!();
    println!("comparisons (En = (a − b)/√(U_a² + U_b²)):");
    for agreement in [&outcome.pitch_deviation, &outcome.encoder_error] {
        print_agreement(agreement);
    }
    println!();
    println!("against the truth (En = (estimate − truth)/U):");
    for check in &outcome.truth {
        println!(
            "  {:<22} {:<16} max |error| {:.4}″   max |En| {:.2}   |En| > 1: {:>2}   {}",
            check.method,
            check.quantity.name(),
            check.max_abs_error_arcsec,
            check.max_abs_en,
            check.beyond_one,
            if check.max_abs_en <= 1.0 {
                "agrees within U"
            } else {
                "DOES NOT agree within U"
            }
        );
    }
    let agree = outcome.all_agree();
    println!();
    println!(
        "{}",
        if agree {
            "every |En| ≤ 1: the three methods agree with each other and with the truth"
        } else {
            "some |En| > 1 (with U at 95 % coverage about one value in twenty exceeds 1 by chance; \
             the instrument budget's U, as in the paper, covers more)"
        }
    );
    Ok(agree)
}

fn print_agreement(agreement: &Agreement) {
    println!(
        "  {:<58} {} values   max |Δ| {:.4}″   max |En| {:.2}   |En| > 1: {}",
        agreement.label,
        agreement.comparison.rows.len(),
        agreement.max_abs_difference_arcsec,
        agreement.comparison.max_abs_en,
        agreement
            .comparison
            .rows
            .iter()
            .filter(|r| r.en.abs() > 1.0)
            .count()
    );
}
