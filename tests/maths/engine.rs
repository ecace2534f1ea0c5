//! The circulant engine against the dense reference, on random designs: N 3…200, 1–3
//! mountings, 1–4 autocollimators per mounting at random face offsets, 1–3 cycles,
//! closing readings, missing readings and effect columns. Estimates, u and the whole
//! covariance agree to 1e-9; designs one refuses, the other refuses naming the same
//! harmonics. Readings come from the independent generator of `tests/common`.

use crate::common::{Stream, Truth, max_abs_diff, readings};
use polycal::measurement::Sigma;
use polycal::solve::{
    self, Engine, Method, SolveError, SolveOptions, dense_least_squares,
    least_squares_with_regressors, lost_harmonics,
};
use proptest::prelude::*;

/// xorshift in [−1, 1).
fn generator(seed: u64) -> impl FnMut() -> f64 {
    let mut state = seed | 1;
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % 2_000_001) as f64 / 1e6 - 1.0
    }
}

#[derive(Debug, Clone)]
struct Design {
    truth: Truth,
    streams: Vec<Stream>,
    cycles: u32,
    closing: bool,
    /// Readings to drop: every `missing_every`-th from `missing_from` (0: none).
    missing: (usize, usize),
    effects: usize,
    seed: u64,
}

fn design() -> impl Strategy<Value = Design> {
    (3usize..=200).prop_flat_map(|n| {
        (
            prop::collection::vec(-2.0..2.0f64, n),
            prop::collection::vec(-2.0..2.0f64, n),
            prop::collection::vec((1u32..=3, 1u32..=4, 0..n, -5.0..5.0f64), 1..=8),
            1u32..=3,
            any::<bool>(),
            prop_oneof![Just((0usize, 0usize)), (0usize..50, 7usize..400)],
            0usize..=3,
            any::<u64>(),
        )
            .prop_map(
                |(beta, alpha, raw, cycles, closing, missing, effects, seed)| {
                    let mut streams: Vec<Stream> = Vec::new();
                    for (setup, ac, d, u) in raw {
                        if !streams.iter().any(|s| (s.0, s.1) == (setup, ac)) {
                            streams.push((setup, ac, d, u));
                        }
                    }
                    Design {
                        truth: Truth::closed(&beta, &alpha),
                        streams,
                        cycles,
                        closing,
                        missing,
                        effects,
                        seed,
                    }
                },
            )
    })
}

/// The design's readings (noisy) and its effect columns: a ramp on one stream, an
/// indicator of one reading (an outlier term) and a random column.
fn build(d: &Design) -> (polycal::measurement::MeasurementSet, Vec<Vec<f64>>) {
    let mut noise = generator(d.seed);
    let mut set = readings(&d.truth, &d.streams, d.cycles, d.closing, || 0.05 * noise());
    if d.missing.1 > 0 {
        let (from, every) = d.missing;
        let mut i = 0;
        set.readings.retain(|_| {
            i += 1;
            i <= from || (i - from) % every != 0
        });
    }
    let count = set.readings.len();
    let mut random = generator(d.seed ^ 0x9e37_79b9);
    let first = (d.streams[0].0, d.streams[0].1);
    let columns: Vec<Vec<f64>> = (0..d.effects)
        .map(|e| match e {
            0 => set
                .readings
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    if (r.setup, r.ac) == first {
                        i as f64 / count as f64
                    } else {
                        0.0
                    }
                })
                .collect(),
            1 => (0..count)
                .map(|i| if i == count / 2 { 1.0 } else { 0.0 })
                .collect(),
            _ => (0..count).map(|_| random()).collect(),
        })
        .collect();
    (set, columns)
}

fn all_u(s: &solve::Solution) -> Vec<f64> {
    let mut u = s.pitch_deviation_u().unwrap_or_default();
    u.extend(s.face_deviation_u().unwrap_or_default());
    u.extend(s.encoder_error_u().unwrap_or_default());
    u.extend(s.setup_error_u().unwrap_or_default());
    u.extend(s.effect_u().unwrap_or_default());
    u
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn circulant_equals_dense(d in design()) {
        let (set, columns) = build(&d);
        let sigma = Some(Sigma::new(0.05).unwrap());
        let fast = least_squares_with_regressors(&set, &columns, sigma);
        let dense = dense_least_squares(&set, &columns, sigma);
        match (fast, dense) {
            (Ok(fast), Ok(dense)) => {
                prop_assert_eq!(dense.engine, Engine::Dense);
                prop_assert!(max_abs_diff(&fast.pitch_deviation, &dense.pitch_deviation) < 1e-9);
                prop_assert!(max_abs_diff(&fast.face_deviation, &dense.face_deviation) < 1e-9);
                prop_assert!(max_abs_diff(&fast.encoder_error, &dense.encoder_error) < 1e-9);
                let values = |s: &solve::Solution| s.setup_error.iter().map(|e| e.value).collect::<Vec<_>>();
                prop_assert!(max_abs_diff(&values(&fast), &values(&dense)) < 1e-9);
                prop_assert!(max_abs_diff(&fast.effect_values, &dense.effect_values) < 1e-9);
                prop_assert!(max_abs_diff(&fast.residuals, &dense.residuals) < 1e-9);
                prop_assert_eq!(fast.dof, dense.dof);
                prop_assert!(max_abs_diff(&all_u(&fast), &all_u(&dense)) < 1e-9);
                let difference = (fast.cofactor.to_dense() - dense.cofactor.to_dense()).abs().max();
                prop_assert!(difference < 1e-9, "cofactor differs by {difference}");
                // Q·x by the operator equals the dense product
                let x: Vec<f64> = (0..fast.cofactor.len()).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
                let dense_product = dense.cofactor.apply(&x);
                prop_assert!(max_abs_diff(&fast.cofactor.apply(&x), &dense_product) < 1e-8);
            }
            (Err(SolveError::Unobservable(a)), Err(SolveError::Unobservable(b))) => {
                prop_assert_eq!(&a.harmonics, &b.harmonics);
                prop_assert_eq!(&a.effects, &b.effects);
                prop_assert_eq!(a.message, b.message);
            }
            (fast, dense) => prop_assert!(false, "the engines disagree: {:?} vs {:?}", fast.map(|s| s.engine), dense.map(|s| s.engine)),
        }
    }
}

/// Designs the circulant engine serves, and the rank of their correction: the paper's
/// cycle with closing readings (one cell per stream), shift-angle mountings, missing
/// readings and effect columns; a design with lost harmonics is refused by the rule,
/// naming the harmonics, without the dense path.
#[test]
fn the_engine_is_chosen_where_it_serves() {
    let n = 36;
    let mut random = generator(5);
    let beta: Vec<f64> = (0..n).map(|_| random()).collect();
    let alpha: Vec<f64> = (0..n).map(|_| random()).collect();
    let truth = Truth::closed(&beta, &alpha);
    let paper = [(1, 1, 0, 0.3), (1, 2, 1, -0.2)];
    let closing = readings(&truth, &paper, 6, true, || 0.0);
    let s = least_squares_with_regressors(&closing, &[], None).unwrap();
    assert_eq!(s.engine, Engine::Circulant { low_rank: 2 });
    assert!(max_abs_diff(&s.encoder_error, &truth.alpha) < 1e-10);

    let shift: Vec<Stream> = (0..6).map(|m| (m + 1, 1, 6 * m as usize, 0.1)).collect();
    let mut shift = shift;
    shift.push((1, 2, 1, 0.0));
    let set = readings(&truth, &shift, 1, false, || 0.0);
    let s = least_squares_with_regressors(&set, &[], None).unwrap();
    assert_eq!(s.engine, Engine::Circulant { low_rank: 0 });
    assert!(max_abs_diff(&s.pitch_deviation, &truth.beta) < 1e-10);

    let mut missing = readings(&truth, &paper, 6, false, || 0.0);
    missing.readings.remove(100);
    missing.readings.remove(7);
    let s = least_squares_with_regressors(&missing, &[], None).unwrap();
    assert_eq!(s.engine, Engine::Circulant { low_rank: 2 });

    let lost = readings(&truth, &[(1, 1, 0, 0.0), (1, 2, 4, 0.0)], 2, false, || 0.0);
    match least_squares_with_regressors(&lost, &[], None) {
        Err(SolveError::Unobservable(e)) => {
            assert_eq!(e.harmonics, lost_harmonics(n, &[0, 4]));
            assert_eq!(e.harmonics, vec![9, 18, 27]);
        }
        other => panic!("{other:?}"),
    }
    // auto on the paper's bare design is the closed form, with its analytic covariance
    let bare = readings(&truth, &paper, 2, false, || 0.0);
    let s = solve::solve(&bare, &SolveOptions::new().with_method(Method::Auto)).unwrap();
    assert_eq!(s.engine, Engine::ClosedForm);
}

/// (estimate − truth)/u over a whole solution: RMS and largest.
fn normalised_errors(estimates: &[f64], truth: &[f64], u: &[f64]) -> (f64, f64) {
    let z: Vec<f64> = estimates
        .iter()
        .zip(truth)
        .zip(u)
        .filter(|(_, u)| **u > 0.0)
        .map(|((e, t), u)| (e - t) / u)
        .collect();
    let rms = (z.iter().map(|z| z * z).sum::<f64>() / z.len() as f64).sqrt();
    (rms, z.iter().fold(0.0_f64, |a, b| a.max(b.abs())))
}

/// 65 536 positions: the bare cycle (closed form, σ stated) and the same with closing
/// readings and two cycles (the circulant engine) are solved back to their simulated
/// truth within their own u: (estimate − truth)/u has an RMS near 1 over 65 536 values and
/// no value beyond 5.5; the closed form's analytic u equals the circulant engine's.
#[test]
fn sixty_five_thousand_positions() {
    use polycal::simulate::{SimulationConfig, simulate};
    let sigma = Sigma::new(0.05).unwrap();
    for (cycles, closing) in [(1, false), (2, true)] {
        let config = SimulationConfig {
            faces: 65_536,
            cycles,
            closing,
            noise_arcsec: 0.05,
            seed: 17,
            ..SimulationConfig::default()
        };
        let (set, truth) = simulate(&config).unwrap();
        let solution = solve::solve(&set, &SolveOptions::new().with_sigma(sigma)).unwrap();
        let expected = if closing {
            Engine::Circulant { low_rank: 2 }
        } else {
            Engine::ClosedForm
        };
        assert_eq!(solution.engine, expected);
        let u_alpha = solution.encoder_error_u().unwrap();
        let u_beta = solution.pitch_deviation_u().unwrap();
        // α's errors are strongly correlated (a bridge over the circle): judge each one
        // by its u, and their successive differences — nearly independent — by the
        // variance the cofactor gives them, over 65 535 values.
        let (_, max) = normalised_errors(&solution.encoder_error, &truth.encoder_error, &u_alpha);
        assert!(max < 5.5, "α: max {max}");
        let (s, _) = solution.sigma.unwrap();
        let q = &solution.cofactor;
        let n = solution.faces;
        let step = |v: &[f64]| (1..n).map(|p| v[p] - v[p - 1]).collect::<Vec<_>>();
        let u_step: Vec<f64> = (1..n)
            .map(|p| {
                let (a, b) = (n + p, n + p - 1);
                s * (q.entry(a, a) + q.entry(b, b) - 2.0 * q.entry(a, b)).sqrt()
            })
            .collect();
        let (rms, max) = normalised_errors(
            &step(&solution.encoder_error),
            &step(&truth.encoder_error),
            &u_step,
        );
        assert!(
            (0.97..1.03).contains(&rms) && max < 5.5,
            "Δα: RMS {rms}, max {max}"
        );
        let (rms, max) =
            normalised_errors(&solution.pitch_deviation, &truth.pitch_deviation, &u_beta);
        assert!(
            (0.97..1.03).contains(&rms) && max < 5.5,
            "β: RMS {rms}, max {max}"
        );
        if !closing {
            // the analytic covariance against the FFT engine on the same data
            let lsq = solve::solve(
                &set,
                &SolveOptions::new()
                    .with_method(Method::LeastSquares)
                    .with_sigma(sigma),
            )
            .unwrap();
            assert_eq!(lsq.engine, Engine::Circulant { low_rank: 0 });
            assert!(max_abs_diff(&lsq.encoder_error_u().unwrap(), &u_alpha) < 1e-9);
            assert!(
                max_abs_diff(
                    &lsq.face_deviation_u().unwrap(),
                    &solution.face_deviation_u().unwrap()
                ) < 1e-9
            );
            // u(α) = σ √((N² − 1)/(6N)) for one cycle (hand-derived, docs/FORMAT.md §5)
            let n = 65_536.0_f64;
            let by_hand = 0.05 * ((n * n - 1.0) / (6.0 * n)).sqrt();
            assert!((u_alpha[12_345] - by_hand).abs() < 1e-9 * by_hand);
            // two ways of rounding sums over 65 536 positions: agree to 1e-10 of u(α)
            let difference = max_abs_diff(&lsq.encoder_error, &solution.encoder_error);
            assert!(difference < 1e-10 * by_hand, "{difference}");
        }
    }
}

/// The closed form's covariance is the analytic one and equals the dense propagation:
/// β: 2σ²(δ_jk − 1/N)/R; α: σ²[(N² − 1)/6 − j(N − j)]/(N·R), j = |p − q|; U₁, U₂:
/// σ²/(N·R) + the φ′_N variance σ²(N² − 1)/(6N·R) each, that variance between them.
#[test]
fn closed_form_covariance_is_analytic_and_equals_the_dense_propagation() {
    for (n, repeats, offset) in [(7usize, 1u32, 0usize), (24, 3, 5), (60, 2, 59)] {
        let mut random = generator(n as u64);
        let beta: Vec<f64> = (0..n).map(|_| random()).collect();
        let alpha: Vec<f64> = (0..n).map(|_| random()).collect();
        let truth = Truth::closed(&beta, &alpha);
        let streams = [(1, 1, offset, 0.2), (1, 2, (offset + 1) % n, -0.1)];
        let set = readings(&truth, &streams, repeats, false, || 0.0);
        let options = SolveOptions::new().with_sigma(Sigma::new(1.0).unwrap());
        let cf = solve::solve(&set, &options.with_method(Method::ClosedForm)).unwrap();
        let dense = dense_least_squares(&set, &[], Some(Sigma::new(1.0).unwrap())).unwrap();
        assert_eq!(cf.engine, Engine::ClosedForm);
        let (q, qd) = (cf.cofactor.to_dense(), dense.cofactor.to_dense());
        assert!((&q - &qd).abs().max() < 1e-10, "N = {n}");
        let (nf, r) = (n as f64, f64::from(repeats));
        for j in 0..n {
            for k in 0..n {
                let delta = if j == k { 1.0 } else { 0.0 };
                assert!((q[(j, k)] - 2.0 * (delta - 1.0 / nf) / r).abs() < 1e-12);
                let lag = j.abs_diff(k) as f64;
                let alpha = ((nf * nf - 1.0) / 6.0 - lag * (nf - lag)) / (nf * r);
                assert!((q[(n + j, n + k)] - alpha).abs() < 1e-12);
            }
        }
        let phi_last = (nf * nf - 1.0) / (6.0 * nf * r);
        assert!((q[(2 * n, 2 * n)] - (1.0 / (nf * r) + phi_last)).abs() < 1e-12);
        assert!((q[(2 * n, 2 * n + 1)] - phi_last).abs() < 1e-12);
    }
}

/// A design whose engine would need more memory than allowed is refused before anything
/// is allocated, naming its size, the engine and both amounts.
#[test]
fn designs_too_large_are_refused_up_front() {
    use polycal::simulate::{SimulationConfig, simulate};
    let config = SimulationConfig {
        faces: 1440,
        closing: true,
        ..SimulationConfig::default()
    };
    let (set, _) = simulate(&config).unwrap();
    let limited = SolveOptions::new()
        .with_method(Method::LeastSquares)
        .with_memory_limit(64 << 10);
    match solve::solve(&set, &limited) {
        Err(e @ SolveError::TooLarge { .. }) => {
            let text = e.to_string();
            assert!(text.contains("1440 positions"), "{text}");
            assert!(text.contains("circulant solver"), "{text}");
            assert!(text.contains("64.0 KiB is the limit set"), "{text}");
        }
        other => panic!("{:?}", other.map(|s| s.engine)),
    }
    match solve::solve(&set, &limited.with_method(Method::Dense)) {
        Err(e @ SolveError::TooLarge { .. }) => {
            assert!(e.to_string().contains("dense solver"), "{e}");
            // 7 matrices of (2·1440 + 2)² values
            assert!(e.to_string().contains("443.6 MiB"), "{e}");
        }
        other => panic!("{:?}", other.map(|s| s.engine)),
    }
    let roomy = limited.with_memory_limit(4 << 20);
    assert_eq!(
        solve::solve(&set, &roomy).unwrap().engine,
        Engine::Circulant { low_rank: 2 }
    );
}
