//! Shifted mountings (docs/FORMAT.md §2 `shift`, §9.1): whole-face shifts solve as the
//! unshifted design with the encoder re-indexed, and sub-pitch shifts recover the encoder
//! errors at every table angle of every coset, each up to its constant.

use std::path::Path;

use polycal::measurement::MeasurementSet;
use polycal::simulate::{Harmonic, SimulationConfig, Truth, simulate, simulate_with_truth};
use polycal::solve::sub_pitch::{
    ShiftGeometry, SubPitchSolution, solve_shifted, solve_shifted_with_progress,
};
use polycal::solve::{self, Method, SolveError, SolveOptions};

const EXAMPLE: &str = "examples/data/polygon24-2ac-6cycles.csv";

fn harmonic(order: usize, amplitude_arcsec: f64, phase_rad: f64) -> Harmonic {
    Harmonic {
        order,
        amplitude_arcsec,
        phase_rad,
    }
}

/// 24 faces (15° apart), five mountings with the polygon turned 5 faces each time and the
/// table at 0°, 5°, 10°, 30° (two faces) and 65° (four faces and 5°) at step 0: three
/// cosets (0°, 5°, 10°). The encoder error has harmonics 24 and 48, which the polygon
/// cannot see and which differ from coset to coset.
fn three_cosets(noise_arcsec: f64, seed: u64) -> SimulationConfig {
    SimulationConfig {
        faces: 24,
        setups: 5,
        setup_shift_faces: 5,
        table_shift_deg: vec![0.0, 5.0, 10.0, 30.0, 65.0],
        cycles: 2,
        closing: true,
        noise_arcsec,
        encoder_harmonics: vec![
            harmonic(1, 0.6, 0.4),
            harmonic(2, 0.35, 1.3),
            harmonic(7, 0.2, 2.2),
            harmonic(24, 0.3, 0.5),
            harmonic(48, 0.1, 1.0),
        ],
        seed,
        ..SimulationConfig::default()
    }
}

/// The truth of each entry minus the mean of its coset (entry q·C + c is coset c).
fn truth_per_coset(truth: &[f64], cosets: usize) -> Vec<f64> {
    let n = truth.len() / cosets;
    let means: Vec<f64> = (0..cosets)
        .map(|c| (0..n).map(|q| truth[q * cosets + c]).sum::<f64>() / n as f64)
        .collect();
    truth
        .iter()
        .enumerate()
        .map(|(i, t)| t - means[i % cosets])
        .collect()
}

fn max_abs_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn sub_pitch_shifts_recover_every_coset_without_noise() {
    let (set, truth) = simulate(&three_cosets(0.0, 1)).unwrap();
    let geometry = ShiftGeometry::of(&set);
    assert_eq!(geometry.coset_shift_deg(), &[0.0, 5.0, 10.0]);
    let solved = solve_shifted(&set, &SolveOptions::default()).unwrap();
    assert!(solved.is_sub_pitch());
    assert_eq!(solved.cosets, [0.0, 5.0, 10.0]);
    assert_eq!(solved.encoder_error.len(), 72);
    let angles = truth
        .encoder_angle_deg
        .clone()
        .expect("a sub-pitch truth has angles");
    assert_eq!(solved.encoder_angle_deg, angles);
    assert_eq!(&angles[..4], &[0.0, 5.0, 10.0, 15.0]);

    // harmonics 24 and 48 make the cosets' constants differ: the test means something
    let coset_mean = |c: usize| (0..24).map(|q| truth.encoder_error[q * 3 + c]).sum::<f64>() / 24.0;
    assert!((coset_mean(1) - coset_mean(0)).abs() > 0.05);
    assert!((coset_mean(2) - coset_mean(1)).abs() > 0.05);

    let expected = truth_per_coset(&truth.encoder_error, 3);
    assert!(
        max_abs_difference(&solved.encoder_error, &expected) < 1e-9,
        "α: {:?}\nexpected {:?}",
        solved.encoder_error,
        expected
    );
    for c in 0..3 {
        let sum: f64 = (0..24).map(|q| solved.encoder_error[q * 3 + c]).sum();
        assert!(sum.abs() < 1e-9, "Σα of coset {c} = {sum}");
    }
    assert!(max_abs_difference(&solved.solution.pitch_deviation, &truth.pitch_deviation) < 1e-9);
    for s in &solved.solution.setup_error {
        let true_u = truth.setup_error_of(s.setup, s.ac).unwrap();
        // the setup errors absorb the constant of their coset's α
        let coset = geometry.mounting(s.setup).unwrap().coset;
        assert!((s.value - (true_u + coset_mean(coset))).abs() < 1e-9);
    }
    assert_eq!(solved.notes.len(), 1);
    assert!(
        solved.notes[0].contains("up to a constant"),
        "{}",
        solved.notes[0]
    );
    assert!(solved.notes[0].contains("Σα = 0 within the coset"));
}

/// (estimate − truth)/u over many noise draws of one truth: the uncertainties are right
/// when its RMS is 1.
#[test]
fn sub_pitch_uncertainties_match_the_scatter() {
    const SEEDS: u64 = 120;
    let truth = Truth::draw(&three_cosets(0.05, 1)).unwrap();
    let expected = truth_per_coset(&truth.encoder_error, 3);
    let (mut alpha, mut beta, mut count_alpha, mut count_beta) = (0.0, 0.0, 0.0, 0.0);
    for seed in 0..SEEDS {
        let set = simulate_with_truth(&three_cosets(0.05, seed + 100), &truth).unwrap();
        let solved = solve_shifted(&set, &SolveOptions::default()).unwrap();
        let u = solved.encoder_error_u.as_ref().unwrap();
        for ((a, t), u) in solved.encoder_error.iter().zip(&expected).zip(u) {
            alpha += ((a - t) / u).powi(2);
            count_alpha += 1.0;
        }
        let u_beta = solved.solution.pitch_deviation_u().unwrap();
        for ((b, t), u) in solved
            .solution
            .pitch_deviation
            .iter()
            .zip(&truth.pitch_deviation)
            .zip(&u_beta)
        {
            beta += ((b - t) / u).powi(2);
            count_beta += 1.0;
        }
    }
    let (alpha, beta) = ((alpha / count_alpha).sqrt(), (beta / count_beta).sqrt());
    eprintln!("RMS of the normalised errors over {SEEDS} seeds: α {alpha:.4}, β {beta:.4}");
    assert!(
        (0.85..=1.15).contains(&alpha),
        "RMS of (α − truth)/u = {alpha}"
    );
    assert!(
        (0.85..=1.15).contains(&beta),
        "RMS of (β − truth)/u = {beta}"
    );
}

/// A sub-pitch set the coset engine cannot take (one reading in seven left out) is fitted
/// by the dense reference; with a progress observer (issue 34) the answer is the same to
/// the bit, and the observer sees a count rising to a total known from its first call.
#[test]
fn the_dense_fallback_with_a_progress_observer_gives_the_same_numbers() {
    let (mut set, _) = simulate(&three_cosets(0.05, 3)).unwrap();
    let mut index = 0;
    set.readings.retain(|_| {
        index += 1;
        index % 7 != 0
    });
    let options = SolveOptions::default();
    let plain = solve_shifted(&set, &options).unwrap();
    assert_eq!(plain.solution.engine, solve::Engine::Dense);
    let seen = std::sync::Mutex::new(Vec::new());
    let observer = |done: u64, total: Option<u64>| seen.lock().unwrap().push((done, total));
    let observed = solve_shifted_with_progress(&set, &options, Some(&observer)).unwrap();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&observed.encoder_error), bits(&plain.encoder_error));
    assert_eq!(
        bits(observed.encoder_error_u.as_ref().unwrap()),
        bits(plain.encoder_error_u.as_ref().unwrap())
    );
    assert_eq!(
        bits(&observed.solution.pitch_deviation),
        bits(&plain.solution.pitch_deviation)
    );
    assert_eq!(
        bits(observed.solution.covariance().unwrap().as_slice()),
        bits(plain.solution.covariance().unwrap().as_slice())
    );
    assert_eq!(observed.solution.residuals, plain.solution.residuals);

    let seen = seen.into_inner().unwrap();
    let total = seen[0].1.expect("a total from the first call");
    assert!(total > 1, "{seen:?}");
    assert!(seen.iter().all(|&(_, t)| t == Some(total)), "{seen:?}");
    assert!(seen.windows(2).all(|w| w[0].0 <= w[1].0), "{seen:?}");
    assert_eq!(seen[0].0, 0);
    assert_eq!(seen.last().unwrap().0, total);
    assert!(
        seen.len() >= 4,
        "the factorisation, the inverse, the mappings: {seen:?}"
    );
}

/// The reparametrisation (α_c = α_0 + δ_c, δ_c as contrast columns) against the model
/// written out: β, every coset's α and the setup errors as unknowns, the closures Σβ = 0
/// and Σα_c = 0 (one per coset) as constraints, solved by the bordered normal equations;
/// the covariance is σ² times the inverse's leading block.
#[test]
fn sub_pitch_solution_is_the_constrained_least_squares() {
    let config = SimulationConfig {
        faces: 6,
        setups: 3,
        table_shift_deg: vec![0.0, 20.0, 100.0],
        cycles: 2,
        closing: true,
        ..SimulationConfig::default()
    };
    let (set, _) = simulate(&config).unwrap();
    let solved = solve_shifted(&set, &SolveOptions::default()).unwrap();
    let dense = solve_shifted(&set, &SolveOptions::new().with_method(Method::Dense)).unwrap();
    assert!(max_abs_difference(&solved.encoder_error, &dense.encoder_error) < 1e-12);
    let closed = solve_shifted(&set, &SolveOptions::new().with_method(Method::ClosedForm));
    assert!(matches!(
        closed,
        Err(SolveError::ClosedFormNotApplicable(_))
    ));

    // shifts 0°, 20° and 100° (= 60° + 40°): cosets 0°, 20°, 40°
    let geometry = ShiftGeometry::of(&set);
    assert_eq!(geometry.coset_shift_deg(), &[0.0, 20.0, 40.0]);
    let (n, c_count) = (6, 3);
    let streams = set.streams();
    let k = streams.len();
    let p = n + c_count * n + k;
    let constraints = 1 + c_count;
    let mut normal = nalgebra::DMatrix::<f64>::zeros(p + constraints, p + constraints);
    let mut rhs = nalgebra::DVector::<f64>::zeros(p + constraints);
    for r in &set.readings {
        let mounting = geometry.mounting(r.setup).unwrap();
        let q = (r.step % n + mounting.whole_positions) % n;
        let mut row = vec![0.0; p];
        for beta in row.iter_mut().take(r.face) {
            *beta = 1.0; // φ[face] = β_1 + … + β_face
        }
        row[n + mounting.coset * n + q] = 1.0;
        row[n + c_count * n + streams.iter().position(|&s| s == (r.setup, r.ac)).unwrap()] = 1.0;
        for i in 0..p {
            rhs[i] += row[i] * r.reading_arcsec;
            for j in 0..p {
                normal[(i, j)] += row[i] * row[j];
            }
        }
    }
    let mut constraint = |index: usize, columns: std::ops::Range<usize>| {
        for j in columns {
            normal[(p + index, j)] = 1.0;
            normal[(j, p + index)] = 1.0;
        }
    };
    constraint(0, 0..n);
    for c in 0..c_count {
        constraint(1 + c, n + c * n..n + (c + 1) * n);
    }
    let inverse = normal
        .try_inverse()
        .expect("the bordered normal matrix is regular");
    let theta = &inverse * &rhs;
    let rss = solved.solution.rss;
    let dof = set.readings.len() - (p - constraints);
    assert_eq!(solved.solution.dof, dof);
    let sigma2 = rss / dof as f64;
    let u = solved.encoder_error_u.as_ref().unwrap();
    for q in 0..n {
        for c in 0..c_count {
            let i = n + c * n + q;
            let entry = q * c_count + c;
            assert!(
                (solved.encoder_error[entry] - theta[i]).abs() < 1e-10,
                "α_{c}[{q}]"
            );
            let u_direct = (sigma2 * inverse[(i, i)]).sqrt();
            assert!(
                (u[entry] - u_direct).abs() < 1e-10,
                "u(α_{c}[{q}]): {} vs {u_direct}",
                u[entry]
            );
        }
    }
    for f in 0..n {
        assert!((solved.solution.pitch_deviation[f] - theta[f]).abs() < 1e-10);
    }
}

/// `solve` holds N encoder errors: a set with sub-pitch mountings is refused, naming the
/// entry point that solves it.
#[test]
fn solve_refuses_sub_pitch_mountings() {
    let (set, _) = simulate(&three_cosets(0.05, 1)).unwrap();
    let err = solve::solve(&set, &SolveOptions::default()).unwrap_err();
    assert_eq!(
        err,
        SolveError::SubPitch {
            faces: 24,
            cosets: 3
        }
    );
    assert!(err.to_string().contains("solve_shifted"), "{err}");
}

/// One coset away from the whole positions (every mounting at 5° + whole faces): no
/// differences to fit, the encoder errors at 5° + q·15°, still up to a constant.
#[test]
fn one_sub_pitch_coset() {
    let config = SimulationConfig {
        setups: 2,
        table_shift_deg: vec![5.0, 20.0],
        noise_arcsec: 0.0,
        encoder_harmonics: vec![harmonic(1, 0.6, 0.4), harmonic(24, 0.3, 0.5)],
        ..SimulationConfig::default()
    };
    let (set, truth) = simulate(&config).unwrap();
    let solved = solve_shifted(&set, &SolveOptions::default()).unwrap();
    assert_eq!(solved.cosets, [5.0]);
    assert_eq!(solved.solution.layout.effects, 0);
    assert_eq!(solved.encoder_angle_deg[1], 20.0);
    let expected = truth_per_coset(&truth.encoder_error, 1);
    assert!(max_abs_difference(&solved.encoder_error, &expected) < 1e-9);
    assert_eq!(solved.notes.len(), 1);
    assert!(solve::solve(&set, &SolveOptions::default()).is_err());
}

/// A whole-face shift, derived by hand: the one mounting of the example run with the
/// table at 45° (3 positions) at step 0 reads α\[(p + 3) mod 24\] at step p, so the same
/// readings give the same β and setup errors and α re-indexed by 3; the `shift` column
/// survives the file.
#[test]
fn a_whole_face_shift_re_indexes_the_encoder() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let plain = MeasurementSet::read_path(&root.join(EXAMPLE), None).unwrap();
    let shifted = plain.clone().with_setup_shifts([(1, 45.0)]).unwrap();
    let mut file = Vec::new();
    shifted.write_to(&mut file, &[]).unwrap();
    let shifted = MeasurementSet::read_from(&file[..], "shifted.csv", None).unwrap();
    assert_eq!(shifted.shift_deg(1), 45.0);

    let options = SolveOptions::default();
    let a = solve::solve(&plain, &options).unwrap();
    let b = solve::solve(&shifted, &options).unwrap();
    assert!(max_abs_difference(&a.pitch_deviation, &b.pitch_deviation) < 1e-12);
    assert!(max_abs_difference(&a.face_deviation, &b.face_deviation) < 1e-12);
    for p in 0..24 {
        assert!((b.encoder_error[(p + 3) % 24] - a.encoder_error[p]).abs() < 1e-12);
    }
    let (ua, ub) = (a.encoder_error_u().unwrap(), b.encoder_error_u().unwrap());
    for p in 0..24 {
        assert!((ub[(p + 3) % 24] - ua[p]).abs() < 1e-12);
    }
    for (x, y) in a.setup_error.iter().zip(&b.setup_error) {
        assert!((x.value - y.value).abs() < 1e-12);
    }
    assert_eq!((a.dof, a.readings), (b.dof, b.readings));

    // solve_shifted says the same, at the N whole positions, without notes
    let c = solve_shifted(&shifted, &options).unwrap();
    assert!(!c.is_sub_pitch() && c.notes.is_empty());
    assert_eq!(c.cosets, [0.0]);
    assert_eq!(c.encoder_error, b.encoder_error);
    assert_eq!(c.encoder_angle_deg[3], 45.0);
}

/// Mountings at different whole-face shifts read the encoder at different positions at
/// the same step: the truth (N values) is recovered exactly, and the result is an
/// ordinary solution.
#[test]
fn whole_face_shifts_recover_the_truth() {
    let config = SimulationConfig {
        setups: 3,
        setup_shift_faces: 7,
        table_shift_deg: vec![0.0, 45.0, 345.0],
        noise_arcsec: 0.0,
        ..SimulationConfig::default()
    };
    let (set, truth) = simulate(&config).unwrap();
    assert!(truth.encoder_angle_deg.is_none());
    assert_eq!(set.shift_deg(3), 345.0);
    // step 1 of setup 2 stands at 60° (position 4), step 23 of setup 3 at 330° (22)
    let r = set
        .readings
        .iter()
        .find(|r| (r.setup, r.step, r.ac) == (2, 1, 1))
        .unwrap();
    assert_eq!(r.encoder_degrees, Some(60.0));
    let expected = truth.encoder_error[4]
        + truth.face_deviation_at(r.face)
        + truth.setup_error_of(2, 1).unwrap();
    assert!((r.reading_arcsec - expected).abs() < 1e-12);

    let solution = solve::solve(&set, &SolveOptions::default()).unwrap();
    assert!(max_abs_difference(&solution.encoder_error, &truth.encoder_error) < 1e-9);
    assert!(max_abs_difference(&solution.pitch_deviation, &truth.pitch_deviation) < 1e-9);
    // without the shifts the same readings are another design, and fit worse
    let mut unshifted = set.clone();
    unshifted.setup_shift_deg.clear();
    let wrong = solve::solve(&unshifted, &SolveOptions::default()).unwrap();
    assert!(wrong.rss > 1.0, "RSS {}", wrong.rss);
}

/// The truth of a sub-pitch run carries the angles of its encoder errors, reads back
/// from its file, and only a truth with a value at every angle of the run simulates it.
#[test]
fn sub_pitch_truth_file() {
    let config = three_cosets(0.05, 1);
    let truth = Truth::draw(&config).unwrap();
    let dir = std::env::temp_dir().join(format!("polycal-sub-pitch-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("truth.json");
    std::fs::write(&path, truth.to_json_pretty()).unwrap();
    let back = Truth::read_path(&path).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(back, truth);
    assert!(truth.to_json_pretty().contains("\"encoder_angle_deg\""));
    assert_eq!(
        truth.encoder_error_at_deg(365.0),
        Some(truth.encoder_error[1])
    );
    assert_eq!(truth.encoder_error_at_deg(2.0), None);

    // a truth of the whole positions has no value at 5°
    let whole = Truth::draw(&SimulationConfig::default()).unwrap();
    let err = simulate_with_truth(&config, &whole).unwrap_err();
    assert!(
        err.to_string()
            .contains("no encoder error at the table angle 5°"),
        "{err}"
    );

    // angles that do not ascend, or do not match the values, are refused
    let mut bad = truth.clone();
    bad.encoder_angle_deg.as_mut().unwrap().swap(0, 1);
    assert!(bad.validate().is_err());
    let mut bad = truth;
    bad.encoder_error.pop();
    assert!(bad.validate().is_err());
}

/// The reports: JSON with angles and notes, CSV rows 0 … C·N − 1 in angle order.
#[test]
fn sub_pitch_reports() {
    let (set, _) = simulate(&three_cosets(0.05, 1)).unwrap();
    let solved: SubPitchSolution = solve_shifted(&set, &SolveOptions::default()).unwrap();
    let json: serde_json::Value = serde_json::from_str(
        &polycal::output::SolveReport::sub_pitch(&solved, None)
            .to_json()
            .unwrap(),
    )
    .unwrap();
    assert_eq!(json["encoder_error"].as_array().unwrap().len(), 72);
    assert_eq!(json["encoder_error_u"].as_array().unwrap().len(), 72);
    assert_eq!(json["encoder_angle_deg"][2], 10.0);
    assert!(
        json["notes"][0]
            .as_str()
            .unwrap()
            .contains("up to a constant")
    );
    assert_eq!(json["pitch_deviation"].as_array().unwrap().len(), 24);
    assert_eq!(json["effects"].as_array().unwrap().len(), 0);

    let rows = polycal::output::sub_pitch_result_rows(&solved);
    let encoder: Vec<_> = rows
        .iter()
        .filter(|r| r.quantity == polycal::results::Quantity::EncoderError)
        .collect();
    assert_eq!(encoder.len(), 72);
    assert!(
        encoder
            .iter()
            .enumerate()
            .all(|(i, r)| r.index as usize == i)
    );
    assert_eq!(encoder[5].value, solved.encoder_error[5]);
    assert_eq!(rows.len(), 24 + 24 + 72 + 10);
    let mut table = String::new();
    polycal::output::write_sub_pitch_table(&mut table, &solved, "run.csv").unwrap();
    assert!(table.contains("   index     angle/°"));
    assert!(table.contains("\nnote: "));
}
