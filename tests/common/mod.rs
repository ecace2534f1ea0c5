//! An independent, minimal generator of readings from the model of docs/FORMAT.md §1:
//! reading = α[step mod N] + φ[face] + U[setup, ac] + noise, written out here without
//! the library's simulator so that the solver is checked against separate code.
#![allow(dead_code)]

use polycal::measurement::{Direction, MeasurementSet, Reading};

/// A truth: β (closed), α (closed), and one U per stream.
#[derive(Debug, Clone)]
pub struct Truth {
    pub beta: Vec<f64>,
    pub alpha: Vec<f64>,
}

impl Truth {
    /// Makes β and α close exactly by removing their means.
    pub fn closed(beta: &[f64], alpha: &[f64]) -> Self {
        let centre = |v: &[f64]| {
            let m = v.iter().sum::<f64>() / v.len() as f64;
            v.iter().map(|x| x - m).collect::<Vec<_>>()
        };
        Self {
            beta: centre(beta),
            alpha: centre(alpha),
        }
    }

    /// φ[f] = β[1] + … + β[f].
    pub fn phi(&self) -> Vec<f64> {
        let mut acc = 0.0;
        self.beta
            .iter()
            .map(|b| {
                acc += b;
                acc
            })
            .collect()
    }
}

/// One stream: (setup, ac, face offset d, setup error U): reads face (step + d) mod N + 1.
pub type Stream = (u32, u32, usize, f64);

/// Readings of every stream at every step of every cycle (step N too when `closing`),
/// plus `noise(i)` on reading i.
pub fn readings(
    truth: &Truth,
    streams: &[Stream],
    cycles: u32,
    closing: bool,
    mut noise: impl FnMut() -> f64,
) -> MeasurementSet {
    let n = truth.beta.len();
    let phi = truth.phi();
    let mut out = Vec::new();
    for cycle in 1..=cycles {
        for step in 0..(if closing { n + 1 } else { n }) {
            for &(setup, ac, d, u) in streams {
                let face = (step + d) % n + 1;
                out.push(Reading {
                    setup,
                    cycle,
                    step,
                    ac,
                    face,
                    reading_arcsec: truth.alpha[step % n] + phi[face - 1] + u + noise(),
                    direction: Direction::Cw,
                    time_seconds: None,
                    reading_y_arcsec: None,
                    temperature_celsius: None,
                    encoder_degrees: None,
                    line: 0,
                });
            }
        }
    }
    MeasurementSet {
        faces: n,
        readings: out,
        source: "test".into(),
        setup_shift_deg: Default::default(),
    }
}

/// Largest absolute difference.
pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}
