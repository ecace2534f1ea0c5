//! The paper's verification reproduced from simulated truth (issue 11, part 4): the three
//! methods agree with each other and with the truth within their uncertainties, and the
//! comparison fails where it should (a harmonic the self-calibration cannot see, left out
//! of its uncertainty).

use polycal::simulate::Harmonic;
use polycal::uncertainty::calibration::InstrumentBudget;
use polycal::verification::{VerificationConfig, verify};

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, count) = values.fold((0.0, 0usize), |(s, c), v| (s + v * v, c + 1));
    (sum / count as f64).sqrt()
}

/// With type A uncertainties (k from Student's t), the normalised differences between the
/// methods and the normalised errors against the truth have unit RMS over many seeds.
#[test]
fn normalised_differences_and_errors_have_unit_rms() {
    let mut beta = Vec::new();
    let mut alpha = Vec::new();
    let mut truth: Vec<Vec<f64>> = vec![Vec::new(); 4];
    for seed in 0..200 {
        let mut config = VerificationConfig::default();
        config.seed = seed;
        let outcome = verify(&config).unwrap();
        assert_eq!(outcome.pitch_deviation.comparison.rows.len(), 24);
        assert_eq!(outcome.encoder_error.comparison.rows.len(), 24);
        beta.extend(
            outcome
                .pitch_deviation
                .normalised_differences
                .iter()
                .copied(),
        );
        alpha.extend(outcome.encoder_error.normalised_differences.iter().copied());
        for (all, check) in truth.iter_mut().zip(&outcome.truth) {
            all.extend(check.normalised_errors.iter().copied());
        }
    }
    let (rms_beta, rms_alpha) = (rms(beta.into_iter()), rms(alpha.into_iter()));
    eprintln!("RMS β {rms_beta:.3}, α {rms_alpha:.3}");
    assert!((0.85..=1.15).contains(&rms_beta), "β: {rms_beta}");
    assert!((0.85..=1.15).contains(&rms_alpha), "α: {rms_alpha}");
    for (i, all) in truth.into_iter().enumerate() {
        let r = rms(all.into_iter());
        eprintln!("RMS against the truth, check {i}: {r:.3}");
        assert!((0.85..=1.15).contains(&r), "truth check {i}: {r}");
    }
}

fn instrument_budget() -> InstrumentBudget {
    InstrumentBudget::read_path(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/budgets/instrument.toml"
    ))
    .unwrap()
}

/// With the paper's instrument budget on the polygon methods (as its Figs. 4–7 are), every
/// En of the comparisons and against the truth is below 1, seed after seed.
#[test]
fn with_the_instrument_budget_every_en_is_below_one() {
    for seed in 1..=10 {
        let mut config = VerificationConfig::default();
        config.seed = seed;
        config.budget = Some(instrument_budget());
        let outcome = verify(&config).unwrap();
        assert!(
            outcome.all_agree(),
            "seed {seed}: β {:.2}, α {:.2}, truth {:?}",
            outcome.pitch_deviation.comparison.max_abs_en,
            outcome.encoder_error.comparison.max_abs_en,
            outcome
                .truth
                .iter()
                .map(|t| t.max_abs_en)
                .collect::<Vec<_>>()
        );
    }
}

/// An encoder with a large harmonic of order 84 — invisible to SelfA, seen by the
/// 24-faced polygon — makes the α comparison fail when the self-calibration's
/// uncertainty leaves it out, and pass when a bound on it is given.
#[test]
fn a_harmonic_selfa_cannot_see_fails_the_comparison_unless_bounded() {
    let mut harmonics: Vec<Harmonic> = (1..=60)
        .map(|k| Harmonic {
            order: k,
            amplitude_arcsec: 0.3 / (k as f64).sqrt(),
            phase_rad: 0.37 * k as f64,
        })
        .collect();
    harmonics.push(Harmonic {
        order: 84,
        amplitude_arcsec: 1.0,
        phase_rad: 0.2,
    });
    let mut config = VerificationConfig::default();
    config.budget = Some(instrument_budget());
    config.lost_harmonic_bound_arcsec = None;
    config.selfcal.encoder_harmonics = harmonics;
    let unbounded = verify(&config).unwrap();
    assert_eq!(unbounded.lost_harmonics, [84]);
    // at the angles k·15° the order 84 alternates: ±cos(0.2)
    assert!((unbounded.encoder_error.max_abs_difference_arcsec - 0.2f64.cos()).abs() < 0.1);
    assert!(unbounded.encoder_error.comparison.max_abs_en > 1.0);
    assert!(!unbounded.all_agree());
    config.lost_harmonic_bound_arcsec = Some(1.0);
    let bounded = verify(&config).unwrap();
    assert!(bounded.encoder_error.comparison.max_abs_en <= 1.0);
}
