//! The structured geometry of a fit (the hat matrix from the engine's cofactor, never
//! formed) against the dense reference (the cofactor formed in ψ): leverages, single
//! columns' scores, every suffix of every stream (a change-point search), blocks'
//! projected Gram matrices — to 1e-9 on random designs: regular ones, closing readings,
//! both directions, whole-face mountings, sub-pitch mountings, missing and repeated
//! readings (where the engine falls back to dense, both forms are the reference), with
//! effect columns in the fit. And the whole diagnosis with either geometry picks the same
//! terms and gives the same estimates.

use polycal::diagnose::base::Base;
use polycal::diagnose::geometry::FitGeometry;
use polycal::effects::Effect;
use polycal::measurement::MeasurementSet;
use polycal::simulate::{SimulationConfig, simulate};
use rand_xoshiro::Xoshiro256PlusPlus;
use rand_xoshiro::rand_core::{RngCore, SeedableRng};

struct Random(Xoshiro256PlusPlus);

impl Random {
    fn below(&mut self, n: u64) -> u64 {
        self.0.next_u64() % n
    }
    fn unit(&mut self) -> f64 {
        (self.0.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A random design (module documentation) with one drift and one jump injected.
fn design(random: &mut Random, seed: u64) -> Option<MeasurementSet> {
    let faces = 5 + random.below(36) as usize;
    let acs = 1 + random.below(3) as usize;
    let mut ac_faces = vec![1];
    for _ in 1..acs {
        let f = 2 + random.below(faces as u64 - 1) as usize;
        if !ac_faces.contains(&f) {
            ac_faces.push(f);
        }
    }
    let setups = 1 + random.below(2) as u32;
    let sub_pitch = setups == 2 && random.below(3) == 0;
    let mut config = SimulationConfig {
        faces,
        ac_faces,
        setups,
        setup_shift_faces: 1 + random.below(faces as u64 - 1) as usize,
        cycles: 1 + random.below(4) as u32,
        closing: random.below(2) == 0,
        bidirectional: random.below(3) == 0,
        effects: vec![Effect::Drift {
            ac: 1,
            value: 0.3,
            quadratic: None,
        }],
        seed,
        ..SimulationConfig::default()
    };
    if sub_pitch {
        config.table_shift_deg = vec![0.0, 360.0 / faces as f64 * 0.4];
    }
    let (mut set, _) = simulate(&config).ok()?;
    // missing and repeated readings
    match random.below(4) {
        0 => {
            let k = random.below(set.readings.len() as u64) as usize;
            set.readings.remove(k);
        }
        1 => {
            let k = random.below(set.readings.len() as u64) as usize;
            let mut again = set.readings[k].clone();
            again.reading_arcsec += 0.01;
            set.readings.push(again);
        }
        _ => {}
    }
    Some(set)
}

fn close(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= 1e-9 * scale.max(1.0)
}

#[test]
fn the_structured_geometry_equals_the_dense_one_on_random_designs() {
    let mut random = Random(Xoshiro256PlusPlus::seed_from_u64(22));
    let (mut checked, mut structured) = (0, 0);
    let mut seed = 0;
    while checked < 200 {
        seed += 1;
        let Some(set) = design(&mut random, seed) else {
            continue;
        };
        let base = Base::of(&set);
        // effect columns in the fit: a drift of ac 1 on the clock and a jump of ac 1
        let n = set.readings.len();
        let times: Vec<f64> = set
            .readings
            .iter()
            .map(|r| r.time_seconds.unwrap_or(0.0) / 3600.0)
            .collect();
        let drift: Vec<f64> = set
            .readings
            .iter()
            .zip(&times)
            .map(|(r, t)| if r.ac == 1 { *t } else { 0.0 })
            .collect();
        let jump: Vec<f64> = (0..n)
            .map(|i| f64::from(u8::from(set.readings[i].ac == 1 && i > n / 2)))
            .collect();
        let terms = vec![drift, jump];
        let Ok(fit) = base.fit(&terms, None) else {
            continue;
        };
        checked += 1;
        let fast = base.geometry(&fit, &terms);
        let reference = FitGeometry::dense(&fit, base.positions(), &base.with(&terms));
        structured += usize::from(fast.is_structured());
        // leverages
        for (i, (a, b)) in fast.leverage().iter().zip(reference.leverage()).enumerate() {
            assert!(
                close(*a, b, 1.0),
                "design {seed}: leverage {i}: {a} against {b}"
            );
        }
        // random columns
        let residuals = &fit.residuals;
        for _ in 0..3 {
            let x: Vec<f64> = (0..n).map(|_| random.unit() - 0.5).collect();
            let (a, b) = (fast.score(&x, residuals), reference.score(&x, residuals));
            assert!(
                close(a.new_length_squared, b.new_length_squared, b.length_squared),
                "design {seed}: score {} against {}",
                a.new_length_squared,
                b.new_length_squared
            );
        }
        // every suffix of every stream
        let mut streams: Vec<(u32, u32)> = set.readings.iter().map(|r| (r.setup, r.ac)).collect();
        streams.sort_unstable();
        streams.dedup();
        for (setup, ac) in streams {
            let order: Vec<usize> = (0..n)
                .filter(|&i| (set.readings[i].setup, set.readings[i].ac) == (setup, ac))
                .collect();
            let a = fast.suffix_scores(&order, residuals);
            let b = reference.suffix_scores(&order, residuals);
            for (k, (a, b)) in a.iter().zip(&b).enumerate() {
                assert!(
                    close(a.new_length_squared, b.new_length_squared, b.length_squared),
                    "design {seed}: stream ({setup}, {ac}) suffix {k}: {} against {}",
                    a.new_length_squared,
                    b.new_length_squared
                );
            }
        }
        // a block's projected Gram matrix
        let block: Vec<Vec<f64>> = (0..2)
            .map(|_| (0..n).map(|_| random.unit()).collect())
            .collect();
        let (a, b) = (
            fast.projected_gram(&block),
            reference.projected_gram(&block),
        );
        let scale = b.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        for (x, y) in a.iter().zip(b.iter()) {
            assert!(close(*x, *y, scale), "design {seed}: Gram {x} against {y}");
        }
        // (I − H)z: the same in both forms, a projection (applied twice, the same), its
        // inner products those of the projected Gram matrix, and nothing left of a column
        // the model spans (the fit's own drift term)
        let z: Vec<f64> = (0..n).map(|_| random.unit() - 0.5).collect();
        let (e, e_reference) = (fast.residual_of(&z), reference.residual_of(&z));
        let length: f64 = z.iter().map(|v| v * v).sum::<f64>();
        for (a, b) in e.iter().zip(&e_reference) {
            assert!(
                close(*a, *b, length.sqrt()),
                "design {seed}: (I − H)z {a} against {b}"
            );
        }
        for (a, b) in fast.residual_of(&e).iter().zip(&e) {
            assert!(
                close(*a, *b, length.sqrt()),
                "design {seed}: (I − H)²z {a} against {b}"
            );
        }
        let cross: f64 = block[0]
            .iter()
            .zip(fast.residual_of(&block[1]))
            .map(|(x, y)| x * y)
            .sum();
        assert!(
            close(cross, b[(0, 1)], scale),
            "design {seed}: x̃ᵀỹ {cross} against the Gram matrix's {}",
            b[(0, 1)]
        );
        let drift_norm = terms[0].iter().map(|v| v * v).sum::<f64>().sqrt();
        for v in fast.residual_of(&terms[0]) {
            assert!(
                close(v, 0.0, drift_norm),
                "design {seed}: a spanned column leaves {v}"
            );
        }
    }
    println!("{checked} designs, {structured} with the structured geometry");
    assert!(structured >= 100, "only {structured} structured");
}

#[test]
fn long_streams_take_the_blocked_convolution_and_agree() {
    // streams of more than 2 048 readings on 64 positions or more: the suffix sums go
    // through blocks and FFT convolutions
    for (faces, cycles, closing, bidirectional, seed) in [
        (360, 6, true, false, 1),
        (500, 5, false, true, 2),
        (97, 30, true, true, 3),
    ] {
        let config = SimulationConfig {
            faces,
            cycles,
            closing,
            bidirectional,
            seed,
            ..SimulationConfig::default()
        };
        let (set, _) = simulate(&config).unwrap();
        let base = Base::of(&set);
        let n = set.readings.len();
        let jump: Vec<f64> = (0..n)
            .map(|i| f64::from(u8::from(set.readings[i].ac == 2 && i > n / 3)))
            .collect();
        let terms = vec![jump];
        let fit = base.fit(&terms, None).unwrap();
        let fast = base.geometry(&fit, &terms);
        assert!(fast.is_structured());
        let reference = FitGeometry::dense(&fit, base.positions(), &base.with(&terms));
        for ac in [1, 2] {
            let order: Vec<usize> = (0..n).filter(|&i| set.readings[i].ac == ac).collect();
            assert!(order.len() > 2048);
            let a = fast.suffix_scores(&order, &fit.residuals);
            let b = reference.suffix_scores(&order, &fit.residuals);
            for (k, (a, b)) in a.iter().zip(&b).enumerate() {
                assert!(
                    close(a.new_length_squared, b.new_length_squared, b.length_squared),
                    "{faces} faces, ac {ac}, suffix {k}: {} against {}",
                    a.new_length_squared,
                    b.new_length_squared
                );
            }
        }
    }
}

#[test]
fn the_whole_diagnosis_is_the_same_with_either_geometry() {
    use polycal::diagnose::{DiagnoseOptions, diagnose};
    let mut random = Random(Xoshiro256PlusPlus::seed_from_u64(2022));
    let (mut checked, mut with_effects) = (0, 0);
    let mut seed = 1000;
    while checked < 200 {
        seed += 1;
        let Some(mut set) = design(&mut random, seed) else {
            continue;
        };
        // a jump of ac 1 after the middle and one bad reading
        let n = set.readings.len();
        for (i, r) in set.readings.iter_mut().enumerate() {
            if r.ac == 1 && i > n / 2 {
                r.reading_arcsec += 0.4;
            }
        }
        let bad = random.below(n as u64) as usize;
        set.readings[bad].reading_arcsec += 1.5;
        let options = DiagnoseOptions::default();
        let (Ok(fast), Ok(reference)) = (
            diagnose(&set, &options),
            diagnose(&set, &options.clone().with_dense_geometry(true)),
        ) else {
            continue;
        };
        checked += 1;
        with_effects += usize::from(!fast.effects.is_empty());
        assert_eq!(fast.effects.len(), reference.effects.len(), "design {seed}");
        for (a, b) in fast.effects.iter().zip(&reference.effects) {
            assert_eq!(
                a.effect.clone().with_value(0.0),
                b.effect.clone().with_value(0.0),
                "design {seed}"
            );
            assert!(
                close(a.effect.value(), b.effect.value(), 1.0),
                "design {seed}"
            );
        }
        assert_eq!(
            fast.adequacy.adequate, reference.adequacy.adequate,
            "design {seed}"
        );
        assert_eq!(fast.tried.len(), reference.tried.len(), "design {seed}");
        for (a, b) in fast
            .after
            .encoder_error
            .iter()
            .chain(&fast.after.pitch_deviation)
            .zip(
                reference
                    .after
                    .encoder_error
                    .iter()
                    .chain(&reference.after.pitch_deviation),
            )
        {
            assert!(close(*a, *b, 1.0), "design {seed}: {a} against {b}");
        }
    }
    println!("{checked} designs diagnosed alike, {with_effects} with effects found");
    assert!(with_effects >= 100);
}
