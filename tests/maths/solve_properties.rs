//! Property tests of the closure solvers on noise-free data with a known truth:
//! random N in 3…72, random β, α, U and random valid designs are solved back to the
//! truth; closure holds; Const and Dyn agree; the closed form equals least squares.

use crate::common::{Stream, Truth, max_abs_diff, readings};
use nalgebra::{DVector, SVector};
use polycal::measurement::Sigma;
use polycal::solve::{self, Method, SolveOptions, closed_form, lost_harmonics};
use proptest::prelude::*;

fn options(method: Method) -> SolveOptions {
    SolveOptions::new().with_method(method)
}

/// A random design: 1–3 mountings, 1–3 autocollimators per mounting at random face
/// offsets, 1–3 cycles, with or without closing readings; random β, α, U.
fn design() -> impl Strategy<Value = (Truth, Vec<Stream>, u32, bool)> {
    (3usize..=72).prop_flat_map(|n| {
        (
            prop::collection::vec(-2.0..2.0f64, n),
            prop::collection::vec(-2.0..2.0f64, n),
            prop::collection::vec((1u32..=3, 1u32..=3, 0..n, -5.0..5.0f64), 1..=6),
            1u32..=3,
            any::<bool>(),
        )
            .prop_map(|(beta, alpha, raw_streams, cycles, closing)| {
                let mut streams: Vec<Stream> = Vec::new();
                for (setup, ac, d, u) in raw_streams {
                    if !streams.iter().any(|s| (s.0, s.1) == (setup, ac)) {
                        streams.push((setup, ac, d, u));
                    }
                }
                (Truth::closed(&beta, &alpha), streams, cycles, closing)
            })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Observable designs are solved back to the truth within 1e-9″ with Σβ = Σα = 0;
    /// unobservable ones are refused, naming exactly the harmonics the rule predicts.
    #[test]
    fn noise_free_designs_recover_the_truth((truth, streams, cycles, closing) in design()) {
        let n = truth.beta.len();
        let set = readings(&truth, &streams, cycles, closing, || 0.0);
        let offsets: Vec<usize> = streams.iter().map(|s| s.2).collect();
        let lost = lost_harmonics(n, &offsets);
        match solve::solve(&set, &options(Method::LeastSquares)) {
            Ok(solution) => {
                prop_assert!(lost.is_empty(), "solved a design that loses {lost:?}");
                prop_assert!(max_abs_diff(&solution.pitch_deviation, &truth.beta) < 1e-9);
                prop_assert!(max_abs_diff(&solution.encoder_error, &truth.alpha) < 1e-9);
                prop_assert!(max_abs_diff(&solution.face_deviation, &truth.phi()) < 1e-9);
                prop_assert!(solution.pitch_deviation.iter().sum::<f64>().abs() < 1e-9);
                prop_assert!(solution.encoder_error.iter().sum::<f64>().abs() < 1e-9);
                let mut sorted = streams.clone();
                sorted.sort_by_key(|s| (s.0, s.1));
                for (estimate, s) in solution.setup_error.iter().zip(&sorted) {
                    prop_assert_eq!((estimate.setup, estimate.ac), (s.0, s.1));
                    prop_assert!((estimate.value - s.3).abs() < 1e-9);
                }
                prop_assert!(solution.rss < 1e-15 * set.readings.len() as f64);
            }
            Err(solve::SolveError::Unobservable(e)) => {
                prop_assert_eq!(&e.harmonics, &lost, "{}", e.message);
            }
            Err(other) => prop_assert!(false, "unexpected error {other}"),
        }
    }

    /// On the paper's design (two autocollimators on adjacent faces, equal repeats, no
    /// closing readings) the closed form and least squares agree to 1e-9″ in the
    /// estimates and in the covariance.
    #[test]
    fn closed_form_equals_least_squares(
        n in 3usize..=72,
        offset in 0usize..72,
        repeats in 1u32..=3,
        swap in any::<bool>(),
        seed in any::<u64>(),
    ) {
        let mut state = seed | 1;
        let mut next = move || {
            state ^= state << 13; state ^= state >> 7; state ^= state << 17;
            (state % 2_000_001) as f64 / 1e6 - 1.0
        };
        let beta: Vec<f64> = (0..n).map(|_| next()).collect();
        let alpha: Vec<f64> = (0..n).map(|_| next()).collect();
        let truth = Truth::closed(&beta, &alpha);
        let d = offset % n;
        let (d1, d2) = if swap { ((d + 1) % n, d) } else { (d, (d + 1) % n) };
        let streams = [(1, 1, d1, 0.7), (1, 2, d2, -0.4)];
        let set = readings(&truth, &streams, repeats, false, || 0.3 * next());
        let cf = solve::solve(&set, &SolveOptions::new().with_method(Method::ClosedForm).with_sigma(Sigma::new(0.05).unwrap())).unwrap();
        let ls = solve::solve(&set, &SolveOptions::new().with_method(Method::LeastSquares).with_sigma(Sigma::new(0.05).unwrap())).unwrap();
        prop_assert_eq!(cf.method, Method::ClosedForm);
        prop_assert!(max_abs_diff(&cf.pitch_deviation, &ls.pitch_deviation) < 1e-9);
        prop_assert!(max_abs_diff(&cf.encoder_error, &ls.encoder_error) < 1e-9);
        prop_assert!(max_abs_diff(&cf.face_deviation, &ls.face_deviation) < 1e-9);
        for (a, b) in cf.setup_error.iter().zip(&ls.setup_error) {
            prop_assert_eq!((a.setup, a.ac), (b.setup, b.ac));
            prop_assert!((a.value - b.value).abs() < 1e-9);
        }
        prop_assert!(max_abs_diff(&cf.residuals, &ls.residuals) < 1e-9);
        prop_assert_eq!(cf.dof, ls.dof);
        prop_assert!((cf.cofactor.to_dense() - ls.cofactor.to_dense()).abs().max() < 1e-9);
        let auto = solve::solve(&set, &options(Method::Auto)).unwrap();
        prop_assert_eq!(auto.method, Method::ClosedForm);
    }

    /// The closed form gives bit-identical results for a compile-time and a run-time N.
    #[test]
    fn const_and_dyn_are_identical(
        m1 in prop::array::uniform24(-500.0..500.0f64),
        m2 in prop::array::uniform24(-500.0..500.0f64),
    ) {
        let s = closed_form(&SVector::<f64, 24>::from(m1), &SVector::<f64, 24>::from(m2)).unwrap();
        let d = closed_form(&DVector::from_column_slice(&m1), &DVector::from_column_slice(&m2)).unwrap();
        prop_assert_eq!(s.polygon.pitch_deviation_arcsec().as_slice(), d.polygon.pitch_deviation_arcsec().as_slice());
        prop_assert_eq!(s.polygon.face_deviation_arcsec().as_slice(), d.polygon.face_deviation_arcsec().as_slice());
        prop_assert_eq!(s.encoder_error.as_slice(), d.encoder_error.as_slice());
        prop_assert_eq!(s.setup_error, d.setup_error);
    }
}

/// The paper's design on exact data: the closed form reproduces the truth and the paper's
/// gauge relation (paper U₂ = generic U₂ + β[1]), checked on a hand-sized 5-faced case.
#[test]
fn closed_form_on_a_hand_sized_case() {
    let truth = Truth::closed(&[0.4, -0.2, 0.1, -0.5, 0.2], &[0.3, -0.1, 0.0, 0.2, -0.4]);
    let phi = truth.phi();
    let (u1, u2) = (0.25, -0.75);
    // eqs. (4), (5): ac 1 at step p reads α[p] + φ[p+1] + U1; ac 2 reads α[p] + φ[p+2] + U2
    let m1 = SVector::<f64, 5>::from_fn(|p, _| truth.alpha[p] + phi[p] + u1);
    let m2 = SVector::<f64, 5>::from_fn(|p, _| truth.alpha[p] + phi[(p + 1) % 5] + u2);
    let s = closed_form(&m1, &m2).unwrap();
    assert!(max_abs_diff(s.polygon.pitch_deviation_arcsec().as_slice(), &truth.beta) < 1e-12);
    assert!(max_abs_diff(s.encoder_error.as_slice(), &truth.alpha) < 1e-12);
    assert!((s.setup_error[0] - u1).abs() < 1e-12);
    assert!((s.setup_error[1] - u2).abs() < 1e-12);
    // the paper's eq. (6) last line: ε₂₄,₂ − ε₂₄,₁ = U₂(paper) − U₁ with U₂(paper) = U₂ + β₁
    let last = m2[4] - m1[4];
    assert!((last - (u2 + truth.beta[0] - u1)).abs() < 1e-12);
}

/// Observability refusals for designs that cannot determine everything, against the
/// rule derived in `solve::observability` (harmonic k lost when N/gcd(N, offsets) | k).
#[test]
fn refusals_name_the_lost_harmonics() {
    let cases: &[(usize, &[usize], &[usize])] = &[
        (24, &[0, 3], &[8, 16]),
        (24, &[0, 2], &[12]),
        (24, &[0, 8], &[3, 6, 9, 12, 15, 18, 21]),
        (24, &[0, 12], &[2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22]),
        (12, &[0, 4, 8], &[3, 6, 9]),
        (36, &[5, 14], &[4, 8, 12, 16, 20, 24, 28, 32]),
        (6, &[1], &[1, 2, 3, 4, 5]),
        (10, &[0, 5], &[2, 4, 6, 8]),
    ];
    for &(n, offsets, expected) in cases {
        assert_eq!(
            lost_harmonics(n, offsets),
            expected,
            "rule for N={n} {offsets:?}"
        );
        let truth = Truth::closed(&vec![0.0; n], &vec![0.0; n]);
        let streams: Vec<Stream> = offsets
            .iter()
            .enumerate()
            .map(|(i, &d)| (1, i as u32 + 1, d, 0.0))
            .collect();
        let set = readings(&truth, &streams, 2, true, || 0.0);
        let error = solve::solve(&set, &SolveOptions::default()).unwrap_err();
        match error {
            solve::SolveError::Unobservable(e) => {
                assert_eq!(e.harmonics, expected, "N={n} {offsets:?}: {}", e.message);
                let listed = expected.iter().map(|k| k.to_string()).collect::<Vec<_>>();
                for k in listed {
                    assert!(e.message.contains(&k), "{}", e.message);
                }
            }
            other => panic!("expected a refusal, got {other}"),
        }
    }
    // Designs that do determine everything: coprime offsets, or a third autocollimator.
    for (n, offsets) in [
        (24usize, vec![0usize, 1]),
        (24, vec![0, 5]),
        (24, vec![0, 3, 8]),
        (7, vec![0, 3]),
    ] {
        assert!(lost_harmonics(n, &offsets).is_empty());
        let truth = Truth::closed(&vec![0.1; n], &vec![0.0; n]);
        let streams: Vec<Stream> = offsets
            .iter()
            .enumerate()
            .map(|(i, &d)| (1, i as u32 + 1, d, 0.0))
            .collect();
        assert!(
            solve::solve(
                &readings(&truth, &streams, 1, false, || 0.0),
                &SolveOptions::default()
            )
            .is_ok()
        );
    }
}
