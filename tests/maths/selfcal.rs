//! Self-calibration of a rotary encoder with several read heads (docs/FORMAT.md §9),
//! checked against truths drawn here (independently of the crate's simulator), the
//! equal-division-averaging (EDA) formula derived by hand, and between the two solvers
//! (heads on the grid: the closure engine; off the grid: the band-limited solver).

use polycal::measurement::{Direction, Sigma};
use polycal::selfcal::{self, HeadGrid, HeadReading, SelfcalOptions, SelfcalSet};
use polycal::solve::Engine;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// A disc error as a sum of harmonics (order, amplitude, phase), a function of angle.
#[derive(Clone)]
struct Disc(Vec<(usize, f64, f64)>);

impl Disc {
    fn at_deg(&self, angle_deg: f64) -> f64 {
        let x = angle_deg.to_radians();
        self.0
            .iter()
            .map(|&(k, a, ph)| a * (k as f64 * x + ph).cos())
            .sum()
    }

    /// The truth the fit can see at the P positions: the harmonics not in `lost`, each
    /// position's value (harmonics of order < P/2 have zero mean over the positions).
    fn visible_at(&self, p: usize, lost: &[usize]) -> Vec<f64> {
        let visible = Disc(
            self.0
                .iter()
                .copied()
                .filter(|(k, _, _)| !lost.contains(k))
                .collect(),
        );
        (0..p)
            .map(|x| visible.at_deg(x as f64 * 360.0 / p as f64))
            .collect()
    }

    fn random(rng: &mut ChaCha8Rng, orders: impl Iterator<Item = usize>) -> Disc {
        Disc(
            orders
                .map(|k| {
                    (
                        k,
                        rng.random_range(0.05..0.5) / (k as f64).sqrt(),
                        rng.random_range(0.0..std::f64::consts::TAU),
                    )
                })
                .collect(),
        )
    }
}

fn selfa_angles() -> Vec<f64> {
    let mut angles = vec![0.0, 120.0, 240.0, 90.0, 180.0, 270.0];
    angles.extend((1..7).map(|k| k as f64 * 360.0 / 7.0));
    angles
}

struct Run {
    positions: usize,
    cycles: u32,
    angles: Vec<f64>,
    table_sigma: f64,
    noise: f64,
    head_errors: Vec<f64>,
}

/// Readings t[c,p] + e(θ_p + ψ_j) + c_j + noise, cycle 2 counter-clockwise.
fn measure(run: &Run, disc: &Disc, rng: &mut ChaCha8Rng) -> SelfcalSet {
    let noise = Normal::new(0.0, run.noise.max(1e-300)).unwrap();
    let table = Normal::new(0.0, run.table_sigma.max(1e-300)).unwrap();
    let mut readings = Vec::new();
    for cycle in 1..=run.cycles {
        let direction = if cycle % 2 == 0 {
            Direction::Ccw
        } else {
            Direction::Cw
        };
        for i in 0..run.positions {
            let step = match direction {
                Direction::Cw => i,
                Direction::Ccw => run.positions - 1 - i,
            };
            let t = if run.table_sigma > 0.0 {
                table.sample(rng)
            } else {
                0.0
            };
            for (j, &psi) in run.angles.iter().enumerate() {
                let angle = step as f64 * 360.0 / run.positions as f64 + psi;
                let e = if run.noise > 0.0 {
                    noise.sample(rng)
                } else {
                    0.0
                };
                readings.push(HeadReading {
                    cycle,
                    step,
                    head: j as u32 + 1,
                    head_angle_deg: psi,
                    reading_arcsec: t + disc.at_deg(angle) + run.head_errors[j] + e,
                    direction,
                    time_seconds: None,
                    line: 0,
                });
            }
        }
    }
    SelfcalSet::from_readings(readings, Some(run.positions)).unwrap()
}

fn head_errors(rng: &mut ChaCha8Rng, m: usize) -> Vec<f64> {
    let mut c: Vec<f64> = (0..m).map(|_| rng.random_range(-2.0..2.0)).collect();
    c[0] = 0.0;
    c
}

fn max_abs_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn selfa_without_noise_recovers_the_disc_except_the_multiples_of_84() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let p = 168;
    // every order up to 83, and the two the SelfA layout cannot see below P/2 = 84
    let mut disc = Disc::random(&mut rng, 1..=83);
    disc.0.push((84, 0.3, 0.7));
    let angles = selfa_angles();
    let run = Run {
        positions: p,
        cycles: 2,
        head_errors: head_errors(&mut rng, angles.len()),
        angles,
        table_sigma: 1.0,
        noise: 0.0,
    };
    let set = measure(&run, &disc, &mut rng);
    let solution = selfcal::solve(&set, &SelfcalOptions::new()).unwrap();
    assert_eq!(solution.grid, HeadGrid::OnGrid);
    assert!(matches!(solution.engine, Engine::Circulant { .. }));
    assert_eq!(solution.lost_harmonics, [84]);
    let truth = disc.visible_at(p, &[84]);
    assert!(max_abs_difference(&solution.encoder_error, &truth) < 1e-9);
    for h in &solution.head_error {
        assert!((h.value - run.head_errors[h.head as usize - 1]).abs() < 1e-9);
    }
    assert!(solution.rss < 1e-15);
    assert!(solution.notes.iter().any(|n| n.contains("order 84")));
    // the angles of the positions
    assert_eq!(solution.encoder_angle_deg[1], 360.0 / 168.0);
}

#[test]
fn one_group_of_m_heads_loses_the_multiples_of_m() {
    for (m, p, expected) in [
        (3usize, 24usize, vec![3usize, 6, 9, 12]),
        (4, 24, vec![4, 8, 12]),
        (7, 28, vec![7, 14]),
    ] {
        let mut rng = ChaCha8Rng::seed_from_u64(m as u64);
        let angles: Vec<f64> = (0..m).map(|j| j as f64 * 360.0 / m as f64).collect();
        let disc = Disc::random(&mut rng, 1..p / 2);
        let run = Run {
            positions: p,
            cycles: 1,
            head_errors: head_errors(&mut rng, m),
            angles,
            table_sigma: 0.5,
            noise: 0.0,
        };
        let set = measure(&run, &disc, &mut rng);
        let solution = selfcal::solve(&set, &SelfcalOptions::new()).unwrap();
        assert_eq!(solution.lost_harmonics, expected, "{m} heads");
        let truth = disc.visible_at(p, &expected);
        assert!(
            max_abs_difference(&solution.encoder_error, &truth) < 1e-9,
            "{m} heads"
        );
    }
}

/// EDA of one group of M equally spaced heads, by hand: the mean of the heads removes
/// the table and every harmonic that is not a multiple of M; head j minus that mean,
/// moved back by its j·P/M positions and averaged over the heads, is the disc's error
/// without its multiples of M. It equals the least-squares answer reading for reading,
/// noise included.
#[test]
fn eda_of_one_equally_spaced_group_equals_least_squares() {
    let (m, p) = (4usize, 32usize);
    let mut rng = ChaCha8Rng::seed_from_u64(44);
    let angles: Vec<f64> = (0..m).map(|j| j as f64 * 360.0 / m as f64).collect();
    let disc = Disc::random(&mut rng, 1..p / 2);
    let run = Run {
        positions: p,
        cycles: 3,
        head_errors: head_errors(&mut rng, m),
        angles,
        table_sigma: 1.0,
        noise: 0.05,
    };
    let set = measure(&run, &disc, &mut rng);
    let solution = selfcal::solve(&set, &SelfcalOptions::new()).unwrap();

    // cycle means per head and step
    let mut y = vec![vec![0.0; p]; m];
    for r in &set.readings {
        y[r.head as usize - 1][r.step] += r.reading_arcsec / run.cycles as f64;
    }
    let shift = p / m;
    let mut eda = vec![0.0; p];
    for (x, value) in eda.iter_mut().enumerate() {
        for (j, head) in y.iter().enumerate() {
            let step = (x + p - j * shift) % p;
            let mean: f64 = (0..m).map(|l| y[l][step]).sum::<f64>() / m as f64;
            *value += (head[step] - mean) / m as f64;
        }
    }
    let eda_mean = eda.iter().sum::<f64>() / p as f64;
    for v in &mut eda {
        *v -= eda_mean;
    }
    assert!(max_abs_difference(&solution.encoder_error, &eda) < 1e-12);
    assert_eq!(solution.lost_harmonics, [4, 8, 12, 16]);
}

/// (estimate − truth)/u over many seeds: RMS within 0.85 … 1.15, for e and for c, for
/// SelfA on the grid (P = 168) and off the grid (P = 24: the group of 7 falls between
/// the positions).
#[test]
fn normalised_errors_have_unit_rms_over_200_seeds() {
    for (p, cycles, seeds) in [(168usize, 2u32, 200u64), (24, 3, 400)] {
        let mut sum_e = 0.0;
        let mut count_e = 0usize;
        let mut sum_c = 0.0;
        let mut count_c = 0usize;
        let mut grid = None;
        for seed in 0..seeds {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
            let angles = selfa_angles();
            let orders = if p == 168 { 1..84 } else { 1..12 };
            let disc = Disc::random(&mut rng, orders);
            let run = Run {
                positions: p,
                cycles,
                head_errors: head_errors(&mut rng, angles.len()),
                angles,
                table_sigma: 1.0,
                noise: 0.03,
            };
            let set = measure(&run, &disc, &mut rng);
            let solution = selfcal::solve(&set, &SelfcalOptions::new()).unwrap();
            grid = Some(solution.grid);
            let truth = disc.visible_at(p, &solution.lost_harmonics);
            let u = solution.encoder_error_u.clone().unwrap();
            for ((estimate, true_value), u) in solution.encoder_error.iter().zip(&truth).zip(&u) {
                sum_e += ((estimate - true_value) / u).powi(2);
                count_e += 1;
            }
            for h in &solution.head_error {
                let z = (h.value - run.head_errors[h.head as usize - 1]) / h.u.unwrap();
                sum_c += z * z;
                count_c += 1;
            }
        }
        let rms_e = (sum_e / count_e as f64).sqrt();
        let rms_c = (sum_c / count_c as f64).sqrt();
        eprintln!("P = {p}: RMS e {rms_e:.4}, c {rms_c:.4}");
        assert!((0.85..=1.15).contains(&rms_e), "P = {p}: RMS of e {rms_e}");
        assert!((0.85..=1.15).contains(&rms_c), "P = {p}: RMS of c {rms_c}");
        let expected = if p == 168 {
            HeadGrid::OnGrid
        } else {
            HeadGrid::OffGrid
        };
        assert_eq!(grid, Some(expected));
    }
}

#[test]
fn heads_off_the_grid_recover_a_band_limited_disc_exactly() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let p = 24;
    // band-limited: orders 1 … 11, and the order 12 (= P/2) as a cosine on the grid
    let mut disc = Disc::random(&mut rng, 1..12);
    disc.0.push((12, 0.2, 0.0));
    let angles = selfa_angles();
    let run = Run {
        positions: p,
        cycles: 2,
        head_errors: head_errors(&mut rng, angles.len()),
        angles,
        table_sigma: 1.0,
        noise: 0.0,
    };
    let set = measure(&run, &disc, &mut rng);
    let solution = selfcal::solve(&set, &SelfcalOptions::new()).unwrap();
    assert_eq!(solution.grid, HeadGrid::OffGrid);
    assert!(solution.lost_harmonics.is_empty());
    let truth = disc.visible_at(p, &[]);
    assert!(
        max_abs_difference(&solution.encoder_error, &truth) < 1e-9,
        "{:?}",
        max_abs_difference(&solution.encoder_error, &truth)
    );
    for h in &solution.head_error {
        assert!((h.value - run.head_errors[h.head as usize - 1]).abs() < 1e-9);
    }
    assert!(solution.notes.iter().any(|n| n.contains("band-limited")));
}

/// The band-limited solver on heads a hair off the grid and the closure engine on the
/// same heads on it: the same equations, so the same estimates and uncertainties.
#[test]
fn the_two_solvers_agree_on_heads_at_the_grid() {
    let p = 36;
    let on = vec![0.0, 10.0, 30.0, 130.0];
    let off: Vec<f64> = on
        .iter()
        .map(|a| if *a == 0.0 { 0.0 } else { a + 3e-5 })
        .collect();
    let mut results = Vec::new();
    for angles in [on, off] {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let disc = Disc::random(&mut rng, 1..18);
        let run = Run {
            positions: p,
            cycles: 2,
            head_errors: head_errors(&mut rng, angles.len()),
            angles,
            table_sigma: 1.0,
            noise: 0.02,
        };
        let set = measure(&run, &disc, &mut rng);
        results.push(selfcal::solve(&set, &SelfcalOptions::new()).unwrap());
    }
    let (grid, band) = (&results[0], &results[1]);
    assert_eq!(
        (grid.grid, band.grid),
        (HeadGrid::OnGrid, HeadGrid::OffGrid)
    );
    assert!(grid.lost_harmonics.is_empty() && band.lost_harmonics.is_empty());
    assert!(max_abs_difference(&grid.encoder_error, &band.encoder_error) < 1e-4);
    let (ug, ub) = (
        grid.encoder_error_u.clone().unwrap(),
        band.encoder_error_u.clone().unwrap(),
    );
    for (a, b) in ug.iter().zip(&ub) {
        assert!((a / b - 1.0).abs() < 1e-3, "{a} {b}");
    }
    for (a, b) in grid.head_error.iter().zip(&band.head_error) {
        assert!((a.value - b.value).abs() < 1e-4);
        assert!((a.u.unwrap() / b.u.unwrap() - 1.0).abs() < 1e-3);
    }
    assert_eq!(grid.dof, band.dof);
}

#[test]
fn a_fine_calibration_of_8400_positions_runs_on_the_structured_engine() {
    let mut rng = ChaCha8Rng::seed_from_u64(8400);
    let p = 8400;
    let disc = Disc::random(&mut rng, (1..=400).chain([84, 168, 1000, 2519]));
    let angles = selfa_angles();
    let run = Run {
        positions: p,
        cycles: 1,
        head_errors: head_errors(&mut rng, angles.len()),
        angles,
        table_sigma: 1.0,
        noise: 0.0,
    };
    let set = measure(&run, &disc, &mut rng);
    let solution = selfcal::solve(&set, &SelfcalOptions::new()).unwrap();
    assert_eq!(solution.engine, Engine::Circulant { low_rank: 0 });
    let expected: Vec<usize> = (1..=50).map(|k| 84 * k).collect();
    assert_eq!(solution.lost_harmonics, expected);
    // the disc's orders 84 and 168 (twice: drawn in 1 … 400 and again) are not seen
    let truth = disc.visible_at(p, &expected);
    assert!(max_abs_difference(&solution.encoder_error, &truth) < 1e-8);
}

#[test]
fn a_bound_on_the_lost_harmonics_adds_to_every_u() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let angles: Vec<f64> = vec![0.0, 120.0, 240.0];
    let disc = Disc::random(&mut rng, 1..12);
    let run = Run {
        positions: 24,
        cycles: 2,
        head_errors: head_errors(&mut rng, 3),
        angles,
        table_sigma: 1.0,
        noise: 0.02,
    };
    let set = measure(&run, &disc, &mut rng);
    let plain = selfcal::solve(&set, &SelfcalOptions::new()).unwrap();
    let bounded = selfcal::solve(
        &set,
        &SelfcalOptions::new().with_lost_harmonic_bound(0.1).unwrap(),
    )
    .unwrap();
    // orders 3, 6, 9, 12 lost: u² = 4 · 0.1²/2
    let expected = (4.0f64 * 0.01 / 2.0).sqrt();
    assert!((bounded.lost_harmonic_u.unwrap() - expected).abs() < 1e-15);
    for (a, b) in plain
        .encoder_error_u
        .unwrap()
        .iter()
        .zip(bounded.encoder_error_u.unwrap())
    {
        assert!((a.hypot(expected) - b).abs() < 1e-15);
    }
    assert_eq!(plain.encoder_error, bounded.encoder_error);
}

#[test]
fn one_cycle_of_two_heads_with_a_stated_sigma() {
    // two heads, one cycle: readings P·2, parameters P + (P − 1 − lost) + 1
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let disc = Disc::random(&mut rng, 1..6);
    let run = Run {
        positions: 12,
        cycles: 1,
        head_errors: vec![0.0, 0.3],
        angles: vec![0.0, 30.0],
        table_sigma: 1.0,
        noise: 0.0,
    };
    let set = measure(&run, &disc, &mut rng);
    let none = selfcal::solve(&set, &SelfcalOptions::new()).unwrap();
    assert_eq!(none.dof, 0);
    assert!(none.encoder_error_u.is_none());
    let stated = selfcal::solve(
        &set,
        &SelfcalOptions::new().with_sigma_opt(Some(Sigma::new(0.05).unwrap())),
    )
    .unwrap();
    // heads 30° apart on 12 positions are the paper's design (offsets 0 and 1, one
    // reading per step): e is φ′ of the closure model, whose cofactor is the Green's
    // function of the cycle's second difference, Cφ(0) = (N² − 1)/(6·N·r)
    let expected = 0.05 * ((144.0f64 - 1.0) / (6.0 * 12.0)).sqrt();
    for u in stated.encoder_error_u.unwrap() {
        assert!((u - expected).abs() < 1e-12, "{u} {expected}");
    }
}

/// A set built field by field (its fields are public) is checked by the file's rules
/// before it is solved: a step beyond P is refused, not an index out of range (heads off
/// the grid, so the band-limited solver would have run).
#[test]
fn a_set_built_by_hand_is_checked_before_it_is_solved() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let disc = Disc::random(&mut rng, 1..6);
    let run = Run {
        positions: 12,
        cycles: 1,
        head_errors: vec![0.0, 0.1, 0.2],
        angles: vec![0.0, 100.0, 250.0],
        table_sigma: 0.0,
        noise: 0.0,
    };
    let mut set = measure(&run, &disc, &mut rng);
    set.readings[5].step = 40;
    let refused = selfcal::solve(&set, &SelfcalOptions::new()).unwrap_err();
    assert!(
        matches!(refused, selfcal::SelfcalSolveError::Invalid(_)),
        "{refused}"
    );
    set.positions = 2;
    assert!(selfcal::solve(&set, &SelfcalOptions::new()).is_err());
}

/// The scopes' gains are structural: an error shared by a head's readings moves only the
/// head errors, one shared by a stop or a position only the table. Solved here, not
/// assumed: readings that are 1 on the group and 0 elsewhere.
#[test]
fn errors_shared_by_a_head_a_stop_or_a_position_are_absorbed() {
    let angles = selfa_angles();
    let (p, cycles) = (168usize, 2u32);
    let template = |value: &dyn Fn(u32, usize, u32) -> f64| {
        let mut readings = Vec::new();
        for cycle in 1..=cycles {
            for step in 0..p {
                for (j, &psi) in angles.iter().enumerate() {
                    let head = j as u32 + 1;
                    readings.push(HeadReading {
                        cycle,
                        step,
                        head,
                        head_angle_deg: psi,
                        reading_arcsec: value(cycle, step, head),
                        direction: Direction::Cw,
                        time_seconds: None,
                        line: 0,
                    });
                }
            }
        }
        let set = SelfcalSet::from_readings(readings, Some(p)).unwrap();
        selfcal::solve(&set, &SelfcalOptions::new()).unwrap()
    };
    let largest = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    // head 5's offset: e untouched, c[5] − c[1] = 1
    let head = template(&|_, _, head| if head == 5 { 1.0 } else { 0.0 });
    assert!(largest(&head.encoder_error) < 1e-12);
    for h in &head.head_error {
        let expected = if h.head == 5 { 1.0 } else { 0.0 };
        assert!((h.value - expected).abs() < 1e-12);
    }
    // head 1's offset moves every c[j] − c[1] by −1: with head j's own, gain 2
    let first = template(&|_, _, head| if head == 1 { 1.0 } else { 0.0 });
    assert!(
        first
            .head_error
            .iter()
            .all(|h| (h.value + 1.0).abs() < 1e-12)
    );
    // a stop, and a position in every cycle: nothing reaches e or c
    for solution in [
        template(&|cycle, step, _| if (cycle, step) == (2, 17) { 1.0 } else { 0.0 }),
        template(&|_, step, _| if step == 17 { 1.0 } else { 0.0 }),
    ] {
        assert!(largest(&solution.encoder_error) < 1e-12);
        assert!(solution.head_error.iter().all(|h| h.value.abs() < 1e-12));
    }
}

/// A budget's combination by hand (JCGM 100 eq. (10), G.2b, t at 95 %): a rectangular
/// error of each reading, an offset of each head, a normal term on the result with 10
/// dof, and an error shared by each stop.
#[test]
fn a_budget_combines_as_derived_by_hand() {
    use polycal::uncertainty::calibration::{InstrumentBudget, Scope, ScopedComponent};
    use polycal::uncertainty::distribution::Distribution;
    use polycal::uncertainty::student::t_quantile;

    let mut rng = ChaCha8Rng::seed_from_u64(77);
    let angles = selfa_angles();
    let disc = Disc::random(&mut rng, 1..84);
    let run = Run {
        positions: 168,
        cycles: 2,
        head_errors: head_errors(&mut rng, angles.len()),
        angles,
        table_sigma: 1.0,
        noise: 0.03,
    };
    let set = measure(&run, &disc, &mut rng);
    let solution = selfcal::solve(&set, &SelfcalOptions::new()).unwrap();
    let (a, u_head, u_result, u_stop) = (0.02, 0.2, 0.1, 0.5);
    let budget = InstrumentBudget::new(vec![
        ScopedComponent::type_b(
            "resolution",
            Distribution::Rectangular { half_width: a },
            Scope::EachReading,
        ),
        ScopedComponent::type_b(
            "head offset",
            Distribution::Normal { u: u_head },
            Scope::EachAutocollimator,
        ),
        ScopedComponent::type_b(
            "reference",
            Distribution::Normal { u: u_result },
            Scope::Result,
        )
        .with_dof(Some(10.0)),
        ScopedComponent::type_b("table", Distribution::Normal { u: u_stop }, Scope::EachStop),
    ]);
    let result = selfcal::evaluate_budget(&solution, &budget).unwrap();
    let (sigma, _) = solution.sigma.unwrap();
    let nu_a = solution.dof as f64;
    let u_r = a / 3f64.sqrt();
    for (x, u_a) in solution
        .encoder_error_u_type_a
        .as_ref()
        .unwrap()
        .iter()
        .enumerate()
    {
        let q = (u_a / sigma).powi(2);
        let variance = u_a * u_a + u_r * u_r * q + u_result * u_result;
        let nu = variance.powi(2) / (u_a.powi(4) / nu_a + u_result.powi(4) / 10.0);
        let k = t_quantile(0.95, Some(nu));
        assert!((result.encoder_error.u[x] - variance.sqrt()).abs() < 1e-12);
        assert!((result.encoder_error.k[x].unwrap() - k).abs() < 1e-9);
        assert!((result.encoder_error.expanded_u[x] - k * variance.sqrt()).abs() < 1e-9);
    }
    for (j, h) in solution.head_error.iter().enumerate() {
        let u_a = h.u.unwrap();
        let q = (u_a / sigma).powi(2);
        let variance = u_a * u_a + u_r * u_r * q + 2.0 * u_head * u_head + u_result * u_result;
        assert!((result.head_error.u[j] - variance.sqrt()).abs() < 1e-12);
    }
    // the stop's error reaches nothing
    assert!(result.components[3].encoder_error.iter().all(|v| *v == 0.0));
}

/// e in the gauge of a 24-faced polygon's encoder errors (Σ = 0 over the angles k·15°):
/// the values moved by their mean over those angles, and u checked against the whole
/// covariance matrix of the closure model formed densely (vᵀ Q v by brute force).
#[test]
fn the_gauge_of_24_angles_references_e_to_a_polygons_positions() {
    let mut rng = ChaCha8Rng::seed_from_u64(24);
    let angles = selfa_angles();
    let disc = Disc::random(&mut rng, (1..84).chain([96, 120]));
    let run = Run {
        positions: 168,
        cycles: 2,
        head_errors: head_errors(&mut rng, angles.len()),
        angles,
        table_sigma: 1.0,
        noise: 0.03,
    };
    let set = measure(&run, &disc, &mut rng);
    let plain = selfcal::solve(&set, &SelfcalOptions::new()).unwrap();
    let gauged = selfcal::solve(&set, &SelfcalOptions::new().with_gauge_positions(24)).unwrap();
    let shared: Vec<usize> = (0..168).step_by(7).collect();
    let mean = shared.iter().map(|&x| plain.encoder_error[x]).sum::<f64>() / 24.0;
    for (a, b) in plain.encoder_error.iter().zip(&gauged.encoder_error) {
        assert!((a - mean - b).abs() < 1e-12);
    }
    assert!(
        shared
            .iter()
            .map(|&x| gauged.encoder_error[x])
            .sum::<f64>()
            .abs()
            < 1e-10
    );
    // brute force: e_x − ē_S = φ_{x+1} − mean_S φ_{s+1}, φ_f = Σ_{i ≤ f} β_i
    let q = gauged.cofactor.to_dense();
    let (sigma, _) = gauged.sigma.unwrap();
    let u = gauged.encoder_error_u_type_a.as_ref().unwrap();
    for x in [0usize, 3, 7, 100, 167] {
        let mut v = vec![0.0; q.nrows()];
        for (i, vi) in v.iter_mut().enumerate().take(168) {
            // β_{i+1} enters φ_{x+1} when i ≤ x, and m_S by the share of S with s ≥ i
            let share = shared.iter().filter(|&&s| s >= i).count() as f64 / 24.0;
            *vi = if i <= x { 1.0 } else { 0.0 } - share;
        }
        let mut variance = 0.0;
        for a in 0..v.len() {
            for b in 0..v.len() {
                variance += v[a] * q[(a, b)] * v[b];
            }
        }
        let expected = sigma * variance.sqrt();
        assert!(
            (u[x] / expected - 1.0).abs() < 1e-9,
            "{x}: {} {expected}",
            u[x]
        );
    }
    assert!(gauged.notes.iter().any(|n| n.contains("24 angles")));
    assert!(matches!(
        selfcal::solve(&set, &SelfcalOptions::new().with_gauge_positions(25)),
        Err(selfcal::SelfcalSolveError::InvalidGauge { .. })
    ));
}

/// The heads' angle uncertainty, checked by brute force: heads actually placed δ away from
/// their nominal angles move e by what the propagation says, to first order (each head
/// in turn, its reading built from the true disc at the displaced angle).
#[test]
fn the_head_angle_uncertainty_is_the_response_to_displaced_heads() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let angles = selfa_angles();
    let disc = Disc::random(&mut rng, 1..40);
    let base = Run {
        positions: 168,
        cycles: 1,
        head_errors: vec![0.0; angles.len()],
        angles: angles.clone(),
        table_sigma: 0.0,
        noise: 0.0,
    };
    let nominal = measure(&base, &disc, &mut rng);
    let u_angle = 2.0; // arcsec
    let solved = selfcal::solve(
        &nominal,
        &SelfcalOptions::new()
            .with_sigma_opt(Some(Sigma::new(0.01).unwrap()))
            .with_head_angle_u(u_angle)
            .unwrap(),
    )
    .unwrap();
    let added = solved.head_angle_u.clone().unwrap();
    let plain = selfcal::solve(
        &nominal,
        &SelfcalOptions::new().with_sigma_opt(Some(Sigma::new(0.01).unwrap())),
    )
    .unwrap();
    // brute force: displace head j by u_angle, solve with the nominal angles, Σ_j Δe²
    let mut var = vec![0.0; 168];
    for j in 1..angles.len() {
        let readings = nominal
            .readings
            .iter()
            .map(|r| {
                let mut r = r.clone();
                if r.head as usize == j + 1 {
                    let angle = r.step as f64 * 360.0 / 168.0 + r.head_angle_deg + u_angle / 3600.0;
                    r.reading_arcsec = disc.at_deg(angle);
                }
                r
            })
            .collect();
        let displaced = SelfcalSet::from_readings(readings, Some(168)).unwrap();
        let moved = selfcal::solve(&displaced, &SelfcalOptions::new()).unwrap();
        for (v, (a, b)) in var
            .iter_mut()
            .zip(moved.encoder_error.iter().zip(&plain.encoder_error))
        {
            *v += (a - b).powi(2);
        }
    }
    for (x, (a, v)) in added.iter().zip(&var).enumerate() {
        assert!(
            (a - v.sqrt()).abs() < 1e-3 * v.sqrt().max(1e-6),
            "{x}: {a} {}",
            v.sqrt()
        );
    }
    for ((u, u0), b) in solved
        .encoder_error_u
        .unwrap()
        .iter()
        .zip(plain.encoder_error_u.unwrap())
        .zip(&added)
    {
        assert!((u - u0.hypot(*b)).abs() < 1e-15);
    }
    assert!(
        selfcal::SelfcalOptions::new()
            .with_head_angle_u(-1.0)
            .is_err()
    );
}
