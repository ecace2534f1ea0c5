//! A standard's history (`polycal::history`, docs/FORMAT.md §13.2) against independent
//! truth: a hand-derived case (the weighted straight line per face, written out here),
//! and series drawn here with a seeded generator and a known drift — the drift test's
//! false-alarm rate at its stated 5 %, its power against the noncentral χ² law, the fit
//! test's rates, and the prediction one year ahead within 2u of the truth
//! (docs/verdicts.md).

// Hand derivations index faces and calibrations as the formulas do.
#![allow(clippy::needless_range_loop)]

use polycal::history::{Calibration, DriftModel, History, HistoryOptions, evaluate};
use polycal::results::{Quantity, ResultFile, ResultRow};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// A calibration of `date` with these values and standard uncertainties.
fn calibration(date: &str, quantity: Quantity, x: &[f64], u: &[f64]) -> Calibration {
    let first = if quantity == Quantity::EncoderError {
        0
    } else {
        1
    };
    let rows = x
        .iter()
        .zip(u)
        .enumerate()
        .map(|(k, (x, u))| ResultRow::new(quantity, k as u32 + first, *x).with_u(*u))
        .collect();
    let result = ResultFile {
        source: format!("{date}.csv"),
        rows,
        lines: vec![],
        columns: vec![],
    };
    Calibration::new(date, result).expect("a date")
}

/// Days since 1970-01-01 of a date (written out here: the civil calendar by counting).
fn days(date: &str) -> f64 {
    let y: i64 = date[0..4].parse().unwrap();
    let m: i64 = date[5..7].parse().unwrap();
    let d: i64 = date[8..10].parse().unwrap();
    let leap = |y: i64| (y % 4 == 0 && y % 100 != 0) || y % 400 == 0;
    let mut total = 0;
    for year in 1970..y {
        total += if leap(year) { 366 } else { 365 };
    }
    let months = [
        31,
        if leap(y) { 29 } else { 28 },
        31,
        30,
        31,
        30,
        31,
        31,
        30,
        31,
        30,
        31,
    ];
    total += months[..(m - 1) as usize].iter().sum::<i64>();
    (total + d - 1) as f64
}

/// The weighted straight line of one face, by the textbook formulas: (slope, u(slope),
/// prediction at `at`, its u), t in years of 365.25 days.
fn straight_line(t: &[f64], x: &[f64], u: &[f64], at: f64) -> (f64, f64, f64, f64) {
    let w: Vec<f64> = u.iter().map(|u| 1.0 / (u * u)).collect();
    let sw: f64 = w.iter().sum();
    let t_bar = w.iter().zip(t).map(|(w, t)| w * t).sum::<f64>() / sw;
    let x_bar = w.iter().zip(x).map(|(w, x)| w * x).sum::<f64>() / sw;
    let stt: f64 = w.iter().zip(t).map(|(w, t)| w * (t - t_bar).powi(2)).sum();
    let sxt: f64 = (0..t.len()).map(|i| w[i] * (t[i] - t_bar) * x[i]).sum();
    let slope = sxt / stt;
    let predicted = x_bar + slope * (at - t_bar);
    let variance = 1.0 / sw + (at - t_bar).powi(2) / stt;
    (slope, (1.0 / stt).sqrt(), predicted, variance.sqrt())
}

/// Three calibrations of three faces, by hand: face deviations (not closed) with each
/// calibration's own u, and pitch deviations (closed) with one u per calibration, whose
/// GLS is the per-face weighted line and whose drift χ² is S_tt/c·Σb².
#[test]
fn history_three_calibrations_by_hand() {
    let dates = ["2001-01-01", "2002-01-01", "2004-07-01"];
    let at = "2006-01-01";
    let t: Vec<f64> = dates.iter().map(|d| days(d) / 365.25).collect();
    let t_at = days(at) / 365.25;
    let s = [0.1, 0.2, 0.05];
    // Face deviations: three faces, each its own line; u per calibration.
    let phi = [
        [0.30, -0.10, 0.05],
        [0.41, -0.12, 0.02],
        [0.62, -0.09, -0.01],
    ];
    let calibrations: Vec<Calibration> = (0..3)
        .map(|i| calibration(dates[i], Quantity::FaceDeviation, &phi[i], &[s[i]; 3]))
        .collect();
    let options = HistoryOptions::new(at)
        .unwrap()
        .with_quantity(Quantity::FaceDeviation);
    let h = evaluate(&calibrations, &options).unwrap();
    let mut chi2 = 0.0;
    for k in 0..3 {
        let x: Vec<f64> = (0..3).map(|i| phi[i][k]).collect();
        let (b, ub, p, up) = straight_line(&t, &x, &s, t_at);
        assert!(
            (h.drift[k] - b).abs() < 1e-12,
            "face {k}: {} vs {b}",
            h.drift[k]
        );
        assert!(
            (h.drift_u[k] - ub).abs() < 1e-12,
            "{} vs {ub}",
            h.drift_u[k]
        );
        chi2 += (b / ub).powi(2);
        if h.model == DriftModel::Linear {
            assert!(
                (h.predicted[k] - p).abs() < 1e-12,
                "{} vs {p}",
                h.predicted[k]
            );
            assert!(
                (h.predicted_u[k] - up).abs() < 1e-12,
                "{} vs {up}",
                h.predicted_u[k]
            );
        }
    }
    assert!(
        (h.vector.chi2 - chi2).abs() < 1e-9 * chi2,
        "{} vs {chi2}",
        h.vector.chi2
    );
    assert_eq!(h.vector.dof, 3);
    assert_eq!(h.model, DriftModel::Linear, "χ² = {chi2}");
    assert_eq!(h.fit.as_ref().unwrap().test.dof, 3);

    // Pitch deviations of three faces (each calibration closed), one u per calibration.
    let beta = [
        [0.20, -0.05, -0.15],
        [0.24, -0.04, -0.20],
        [0.21, -0.06, -0.15],
    ];
    let calibrations: Vec<Calibration> = (0..3)
        .map(|i| calibration(dates[i], Quantity::PitchDeviation, &beta[i], &[s[i]; 3]))
        .collect();
    let h = evaluate(&calibrations, &HistoryOptions::new(at).unwrap()).unwrap();
    let w: Vec<f64> = s.iter().map(|u| 1.0 / (u * u)).collect();
    let sw: f64 = w.iter().sum();
    let t_bar = w.iter().zip(&t).map(|(w, t)| w * t).sum::<f64>() / sw;
    let stt: f64 = w.iter().zip(&t).map(|(w, t)| w * (t - t_bar).powi(2)).sum();
    let mut sum_b2 = 0.0;
    for k in 0..3 {
        let x: Vec<f64> = (0..3).map(|i| beta[i][k]).collect();
        let (b, ub, _, _) = straight_line(&t, &x, &s, t_at);
        assert!((h.drift[k] - b).abs() < 1e-12, "face {k}");
        // the diagonal of the closed covariance c·P·diag(u²)·P with one u is u²
        assert!(
            (h.drift_u[k] - ub).abs() < 1e-12,
            "{} vs {ub}",
            h.drift_u[k]
        );
        sum_b2 += b * b;
    }
    let c = 3.0 / 2.0;
    let chi2 = stt / c * sum_b2;
    assert!(
        (h.vector.chi2 - chi2).abs() < 1e-9 * chi2,
        "{} vs {chi2}",
        h.vector.chi2
    );
    assert_eq!(h.vector.dof, 2);
    // constant model: the weighted mean of each face, u² = c(1 − 1/N)/Σw = 1/Σw
    if h.model == DriftModel::Constant {
        for k in 0..3 {
            let mean = (0..3).map(|i| w[i] * beta[i][k]).sum::<f64>() / sw;
            assert!((h.predicted[k] - mean).abs() < 1e-12);
            assert!((h.predicted_u[k] - (1.0 / sw).sqrt()).abs() < 1e-12);
        }
    } else {
        panic!("χ² = {chi2}: the hand case is chosen to be constant");
    }
}

/// Yearly calibration dates from 2010-03-01.
fn yearly(n: usize) -> Vec<String> {
    (0..n).map(|i| format!("{}-03-01", 2010 + i)).collect()
}

/// One simulated history of a standard with `faces` pitch deviations: truth `beta0`
/// drifting by `drift` per year, each calibration with closed noise of u per face
/// (u_scale[i]·u_face[k]; closed: e = √(N/(N − 1))·(u·z − mean)). Returns the
/// calibrations and the truth at `at`.
#[allow(clippy::too_many_arguments)]
fn draw(
    rng: &mut ChaCha8Rng,
    dates: &[String],
    beta0: &[f64],
    drift: &[f64],
    u_face: &[f64],
    u_scale: &[f64],
    at: &str,
) -> (Vec<Calibration>, Vec<f64>) {
    let n = beta0.len();
    let t0 = days(&dates[0]);
    let c = (n as f64 / (n as f64 - 1.0)).sqrt();
    let calibrations = dates
        .iter()
        .zip(u_scale)
        .map(|(date, scale)| {
            let years = (days(date) - t0) / 365.25;
            let u: Vec<f64> = u_face.iter().map(|u| u * scale).collect();
            let e: Vec<f64> = u
                .iter()
                .map(|u| {
                    let z: f64 = StandardNormal.sample(rng);
                    u * z
                })
                .collect();
            // noise with covariance c²·P·diag(u²)·P: closed, as a closure calibration's
            let mean = e.iter().sum::<f64>() / n as f64;
            let x: Vec<f64> = (0..n)
                .map(|k| beta0[k] + drift[k] * years + c * (e[k] - mean))
                .collect();
            calibration(date, Quantity::PitchDeviation, &x, &u)
        })
        .collect();
    let years = (days(at) - t0) / 365.25;
    let truth = (0..n).map(|k| beta0[k] + drift[k] * years).collect();
    (calibrations, truth)
}

fn closed_truth(n: usize) -> Vec<f64> {
    let raw: Vec<f64> = (0..n).map(|k| 0.4 * (k as f64 * 0.7).sin() + 0.1).collect();
    let mean = raw.iter().sum::<f64>() / n as f64;
    raw.iter().map(|b| b - mean).collect()
}

/// P(χ'²(ν, λ) > χ²_0.95(ν)): the power of the drift test, by the noncentral law.
fn power(dof: usize, lambda: f64) -> f64 {
    let critical = ChiSquared::new(dof as f64).unwrap().inverse_cdf(0.95);
    polycal::plan::power::noncentral_f_sf(critical / dof as f64, dof, f64::INFINITY, lambda)
}

/// Stable standards (no drift), six yearly calibrations of 24 faces, u differing per
/// face and per calibration: the drift test calls a drift in 5 % ± 1.5 % of 3 000
/// histories (its stated rate); the chosen model's fit test rejects at 5 % ± 1.5 % too;
/// and the prediction one year after the last calibration is within 2u of the truth on
/// ≥ 93 % of faces.
#[test]
fn history_stable_standards_false_alarm_rate() {
    let mut rng = ChaCha8Rng::seed_from_u64(56);
    let n = 24;
    let dates = yearly(6);
    let beta0 = closed_truth(n);
    let u_face: Vec<f64> = (0..n)
        .map(|k| 0.02 * (1.0 + 0.5 * (k % 3) as f64))
        .collect();
    let u_scale = [1.0, 1.3, 0.8, 1.0, 1.6, 1.1];
    let drift = vec![0.0; n];
    let at = "2016-03-01";
    let options = HistoryOptions::new(at).unwrap();
    let draws = 3000;
    let (mut alarms, mut fit_rejects, mut within, mut faces) = (0, 0, 0, 0);
    for _ in 0..draws {
        let (calibrations, truth) = draw(&mut rng, &dates, &beta0, &drift, &u_face, &u_scale, at);
        let h = evaluate(&calibrations, &options).unwrap();
        alarms += usize::from(h.model == DriftModel::Linear);
        fit_rejects += usize::from(!h.fit.as_ref().unwrap().test.consistent);
        (within, faces) = count_within(&h, &truth, within, faces);
    }
    let rate = alarms as f64 / draws as f64;
    let fit_rate = fit_rejects as f64 / draws as f64;
    let coverage = within as f64 / faces as f64;
    eprintln!(
        "stable: drift called {rate:.4}, fit rejected {fit_rate:.4}, 2u coverage {coverage:.4}"
    );
    assert!((rate - 0.05).abs() <= 0.015, "false-alarm rate {rate}");
    assert!(
        (fit_rate - 0.05).abs() <= 0.015,
        "fit test's rate {fit_rate}"
    );
    assert!(coverage >= 0.93, "coverage {coverage}");
}

/// Counts the faces whose prediction is within 2u of the truth.
fn count_within(h: &History, truth: &[f64], within: usize, faces: usize) -> (usize, usize) {
    let hits = (0..truth.len())
        .filter(|&k| (h.predicted[k] - truth[k]).abs() <= 2.0 * h.predicted_u[k])
        .count();
    (within + hits, faces + truth.len())
}

/// Standards drifting 0.03″ a year (δ_k = 0.03·cos(2πk/24), a closed once-per-turn
/// change) over six yearly calibrations: with u = 0.1″ the drift is found as often as the
/// noncentral χ² law says (λ = S_tt·Σδ²/(c·u²), within 3.5 points, three binomial standard
/// deviations of 2 000 draws); with u = 0.02″ (λ ≈ 450) in every one of 500 histories;
/// and then the prediction one year ahead is within 2u of the truth on ≥ 93 % of faces.
#[test]
fn history_drifting_standards_power_and_prediction() {
    let mut rng = ChaCha8Rng::seed_from_u64(57);
    let n = 24;
    let dates = yearly(6);
    let beta0 = closed_truth(n);
    let drift: Vec<f64> = (0..n)
        .map(|k| 0.03 * (2.0 * std::f64::consts::PI * (k + 1) as f64 / n as f64).cos())
        .collect();
    let at = "2016-03-01";
    let options = HistoryOptions::new(at).unwrap();
    let t: Vec<f64> = dates.iter().map(|d| days(d) / 365.25).collect();
    let t_bar = t.iter().sum::<f64>() / t.len() as f64;
    let stt: f64 = t.iter().map(|t| (t - t_bar).powi(2)).sum();
    let c = n as f64 / (n as f64 - 1.0);
    let sum_d2: f64 = drift.iter().map(|d| d * d).sum();
    for (u, draws, tolerance) in [(0.1, 2000, 0.035_f64), (0.02, 500, 0.0)] {
        let lambda = stt * sum_d2 / (c * u * u);
        let expected = power(n - 1, lambda);
        let (mut found, mut within, mut faces, mut fit_rejects) = (0, 0, 0, 0);
        for _ in 0..draws {
            let (calibrations, truth) =
                draw(&mut rng, &dates, &beta0, &drift, &vec![u; n], &[1.0; 6], at);
            let h = evaluate(&calibrations, &options).unwrap();
            if h.model == DriftModel::Linear {
                found += 1;
                fit_rejects += usize::from(!h.fit.as_ref().unwrap().test.consistent);
            }
            (within, faces) = count_within(&h, &truth, within, faces);
        }
        let rate = found as f64 / draws as f64;
        let coverage = within as f64 / faces as f64;
        let fit_rate = fit_rejects as f64 / found.max(1) as f64;
        eprintln!(
            "u = {u}: λ = {lambda:.1}, power {expected:.4}, found {rate:.4}, linear fit \
             rejected {fit_rate:.4}, 2u coverage {coverage:.4}"
        );
        assert!(
            (rate - expected).abs() <= tolerance.max(1e-12) || (tolerance == 0.0 && rate == 1.0),
            "u = {u}: found {rate}, the law says {expected}"
        );
        if u == 0.02 {
            assert!(expected > 0.9999);
            assert!(coverage >= 0.93, "coverage {coverage}");
            assert!(
                (fit_rate - 0.05).abs() <= 0.03,
                "linear fit's rate {fit_rate}"
            );
        }
    }
}

/// The fit test's power: calibrations whose real u is 1.25 times the stated one, of a
/// standard drifting 0.03″ a year (u = 0.02″: the drift is always found, so the linear
/// model's residual χ², independent of the drift's estimate, is 1.25²·χ²(92)): the fit
/// test rejects as often as P(1.25²·χ²(92) > χ²_0.95(92)) says, within three binomial
/// standard deviations.
#[test]
fn history_fit_test_finds_understated_uncertainties() {
    let mut rng = ChaCha8Rng::seed_from_u64(58);
    let n = 24;
    let dates = yearly(6);
    let beta0 = closed_truth(n);
    let drift: Vec<f64> = (0..n)
        .map(|k| 0.03 * (2.0 * std::f64::consts::PI * (k + 1) as f64 / n as f64).cos())
        .collect();
    let options = HistoryOptions::new("2016-03-01").unwrap();
    let draws = 1000;
    let mut rejected = 0;
    for _ in 0..draws {
        let (mut calibrations, _) = draw(
            &mut rng,
            &dates,
            &beta0,
            &drift,
            &vec![0.02; n],
            &[1.0; 6],
            "2016-03-01",
        );
        for c in &mut calibrations {
            for row in &mut c.result.rows {
                row.u = row.u.map(|u| u / 1.25);
            }
        }
        let h = evaluate(&calibrations, &options).unwrap();
        assert_eq!(h.model, DriftModel::Linear);
        let fit = h.fit.as_ref().unwrap();
        assert_eq!(fit.test.dof, 92);
        rejected += usize::from(!fit.test.consistent);
    }
    let law = ChiSquared::new(92.0).unwrap();
    let critical = law.inverse_cdf(0.95);
    let expected = 1.0 - law.cdf(critical / 1.25f64.powi(2));
    let rate = rejected as f64 / draws as f64;
    let sd = (expected * (1.0 - expected) / draws as f64).sqrt();
    eprintln!("u understated 1.25×: fit rejected {rate:.4}, the law says {expected:.4}");
    assert!((rate - expected).abs() <= 3.0 * sd, "{rate} vs {expected}");
}

/// The refusals: one calibration, every calibration on one day, a file twice, a bad date,
/// a row without u, other numbers of faces, setup errors.
#[test]
fn history_refusals() {
    let x = [0.1, -0.1];
    let u = [0.05, 0.05];
    let a = calibration("2020-01-01", Quantity::PitchDeviation, &x, &u);
    let options = HistoryOptions::new("2021-01-01").unwrap();
    let err = |c: &[Calibration]| evaluate(c, &options).unwrap_err().to_string();
    assert!(err(std::slice::from_ref(&a)).contains("at least 2 calibrations"));
    let mut b = calibration("2020-01-01", Quantity::PitchDeviation, &x, &u);
    b.result.source = "other.csv".into();
    assert!(err(&[a.clone(), b.clone()]).contains("at least 2 different days"));
    let same = calibration("2021-01-01", Quantity::PitchDeviation, &x, &u);
    let mut twice = same.clone();
    twice.result.source = a.result.source.clone();
    assert!(err(&[a.clone(), twice]).contains("given twice"));
    assert!(Calibration::new("2021-02-29", a.result.clone()).is_err());
    assert!(HistoryOptions::new("2021-13-01").is_err());
    let mut no_u = same.clone();
    no_u.result.rows[1].u = None;
    let message = err(&[a.clone(), no_u]);
    assert!(
        message.contains("2021-01-01.csv (row 2)") && message.contains("no standard uncertainty"),
        "{message}"
    );
    let three = calibration(
        "2022-01-01",
        Quantity::PitchDeviation,
        &[0.1, 0.0, -0.1],
        &[0.05; 3],
    );
    assert!(err(&[a.clone(), three]).contains("faces"));
    let setup = HistoryOptions::new("2021-01-01")
        .unwrap()
        .with_quantity(Quantity::SetupError);
    assert!(
        evaluate(&[a, same], &setup)
            .unwrap_err()
            .to_string()
            .contains("setup errors")
    );
}

/// Today's run of the standard, drawn as a closure calibration gives it: closed noise of u
/// per face, with U = 2u and k = 2 (as `report` has them from its budget).
fn run_today(rng: &mut ChaCha8Rng, truth: &[f64], u: f64, date: &str) -> ResultFile {
    let n = truth.len();
    let c = (n as f64 / (n as f64 - 1.0)).sqrt();
    let e: Vec<f64> = (0..n)
        .map(|_| {
            let z: f64 = StandardNormal.sample(rng);
            u * z
        })
        .collect();
    let mean = e.iter().sum::<f64>() / n as f64;
    let rows = (0..n)
        .map(|k| {
            ResultRow::new(
                Quantity::PitchDeviation,
                k as u32 + 1,
                truth[k] + c * (e[k] - mean),
            )
            .with_u(u)
            .with_expanded_u(2.0 * u)
            .with_k(2.0)
        })
        .collect();
    ResultFile {
        source: format!("run {date}"),
        rows,
        lines: vec![],
        columns: vec![],
    }
}

/// `report --history`'s one decision (`certificate::agreement_with_prediction`): today's
/// run against what five earlier yearly calibrations predict for its day, compare's vector
/// test at 5 %. A stable standard: disagreement called in 5 % ± 1.5 % of 2 000 runs. A
/// standard knocked since its last calibration (±0.8 u on alternate faces): found as
/// often as the noncentral χ² law of the closed difference says (± 4 points). A standard
/// drifting 0.03″ a year (u = 0.05″): the rate measured and stated (docs/verdicts.md).
#[test]
fn report_history_agreement_rates() {
    let mut rng = ChaCha8Rng::seed_from_u64(1056);
    let n = 24;
    let dates = yearly(6);
    let (earlier_dates, today) = (&dates[..5], dates[5].as_str());
    let beta0 = closed_truth(n);
    let u = 0.05;
    let u_face = vec![u; n];
    let u_scale = [1.0; 5];
    let draws = 2000;
    let mut rate = |drift: &[f64], knock: &[f64], draws: usize| {
        let mut alarms = 0;
        for _ in 0..draws {
            let (earlier, truth) = draw(
                &mut rng,
                earlier_dates,
                &beta0,
                drift,
                &u_face,
                &u_scale,
                today,
            );
            let truth: Vec<f64> = truth.iter().zip(knock).map(|(t, k)| t + k).collect();
            let run = run_today(&mut rng, &truth, u, today);
            let (_, agreement) =
                polycal::certificate::agreement_with_prediction(&earlier, &run, today).unwrap();
            alarms += usize::from(!agreement.verdict_ok());
        }
        alarms as f64 / draws as f64
    };
    let none = vec![0.0; n];
    let stable = rate(&none, &none, draws);
    // a knock of ±0.8u on alternate faces (closed): the difference's covariance is
    // c·(u² + u_pred²)·P with u_pred² = u²/5 (five equal calibrations, the constant
    // model), so λ = Σ knock² / (c·u²·(1 + 1/5)), c = N/(N − 1)
    let knock: Vec<f64> = (0..n)
        .map(|k| if k % 2 == 0 { 0.8 * u } else { -0.8 * u })
        .collect();
    let knocked = rate(&none, &knock, 1000);
    let c = n as f64 / (n as f64 - 1.0);
    let lambda = knock.iter().map(|d| d * d).sum::<f64>() / (c * u * u * 1.2);
    let expected = power(n - 1, lambda);
    let drift: Vec<f64> = (0..n)
        .map(|k| 0.03 * (2.0 * std::f64::consts::PI * k as f64 / n as f64).cos())
        .collect();
    let drifting = rate(&drift, &none, 1000);
    eprintln!(
        "report --history: stable {stable:.4}; knocked ±0.8u {knocked:.4} (law {expected:.4}, \
         λ = {lambda:.1}); drifting 0.03″/year {drifting:.4}"
    );
    assert!((stable - 0.05).abs() <= 0.015, "false-alarm rate {stable}");
    assert!(
        (knocked - expected).abs() <= 0.04,
        "power {knocked} against {expected}"
    );
}
