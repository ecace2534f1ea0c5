//! Realistic runs with an undeclared fault, each beside its clean twin (issue 53).
//!
//! Written for these tests apart from polycal's `simulate` module (it shares no code with
//! it, and nothing of the effects catalogue): a truth (β closed, α closed, a setup error
//! per autocollimator), the readings of the paper's model with Gaussian noise, and one
//! fault of a real lab applied to a copy. The twin has the same truth and the same noise
//! draws without the fault, so that "2× the twin's error" compares like with like.
//!
//! The design is the paper's: autocollimator j (1-based) reads face (p + d_j) mod N + 1 at
//! step p, d_j = `face_offsets[j − 1]`; steps 0 … N−1 and, with `closing`, step N; cycles
//! clockwise unless `bidirectional` (then even cycles counter-clockwise, their stops taken
//! in reverse order in time). One stop every `seconds_per_stop` seconds, in time order.
#![allow(dead_code)]

use polycal::measurement::{Direction, MeasurementSet, Reading, face_at};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_xoshiro::Xoshiro256PlusPlus;

/// The shape of a run.
#[derive(Debug, Clone)]
pub struct Run {
    /// N.
    pub faces: usize,
    /// Face offset d_j of each autocollimator (its length is the number of autocollimators).
    pub face_offsets: Vec<usize>,
    /// Cycles.
    pub cycles: u32,
    /// With the closing reading (step N).
    pub closing: bool,
    /// Even cycles counter-clockwise.
    pub bidirectional: bool,
    /// Noise σ of one reading, arcsec (every autocollimator).
    pub sigma: f64,
    /// Seconds between stops.
    pub seconds_per_stop: f64,
}

impl Run {
    /// 24 faces, two adjacent autocollimators, `cycles` cycles with closing readings,
    /// noise `sigma`, one stop every 30 s.
    pub fn typical(cycles: u32, sigma: f64) -> Self {
        Run {
            faces: 24,
            face_offsets: vec![0, 1],
            cycles,
            closing: true,
            bidirectional: false,
            sigma,
            seconds_per_stop: 30.0,
        }
    }

    /// The steps of one cycle in time order.
    fn steps(&self, cycle: u32) -> Vec<usize> {
        let last = if self.closing {
            self.faces
        } else {
            self.faces - 1
        };
        let mut steps: Vec<usize> = (0..=last).collect();
        if self.bidirectional && cycle.is_multiple_of(2) {
            steps.reverse();
        }
        steps
    }

    fn direction(&self, cycle: u32) -> Direction {
        if self.bidirectional && cycle.is_multiple_of(2) {
            Direction::Ccw
        } else {
            Direction::Cw
        }
    }
}

/// A fault nobody declares.
#[derive(Debug, Clone, PartialEq)]
pub enum Fault {
    /// None: the faulty set equals the twin.
    None,
    /// In `cycle`, the readings of autocollimators `a` and `b` exchanged at every stop (the
    /// log pasted the wrong way round).
    SwappedAcs { cycle: u32, a: u32, b: u32 },
    /// In `cycle`, every reading stored against a stop is the reading of the stop before it
    /// in time (the logger latched before the table settled); the first stop's is the
    /// reading of the stop before the cycle (the previous cycle's last stop, or the table
    /// at rest at step 0 before the first).
    OneStopLate { cycle: u32 },
    /// In `cycle`, every reading stored against a stop is the reading of the stop after it
    /// in time; the last stop's is the reading of the stop after the cycle (the next
    /// cycle's first, or the table at rest where it ended).
    OneStopEarly { cycle: u32 },
    /// In `cycle`, every autocollimator read the face `by` (±1) after the one the design
    /// (and the file) says: the polygon sat a pitch round for that cycle.
    FacesShifted { cycle: u32, by: i64 },
    /// `cycle` was run counter-clockwise but logged as clockwise with its stops in the
    /// order of a clockwise cycle (the reading of step N − p stored against step p).
    Reversed { cycle: u32 },
    /// Autocollimator `ac`'s noise multiplied by `factor` from `from_cycle` on.
    NoiseRise {
        ac: u32,
        from_cycle: u32,
        factor: f64,
    },
    /// Autocollimator `ac`'s zero drifts `rate_before` ″/h until `kink_seconds`, then
    /// `rate_after` ″/h (continuous at the kink).
    KinkedDrift {
        ac: u32,
        rate_before: f64,
        rate_after: f64,
        kink_seconds: f64,
    },
    /// An encoder interpolation error `amplitude`·sin(2π θ/`period_arcsec` + phase) on top of
    /// the smooth α, and a table that stops within ±`stop_within_arcsec` of each nominal
    /// angle: each stop samples the interpolation error at another phase. The readings are
    /// referred to the nominal angle by the position the table reported (the `encoder`
    /// column), so the stop's offset itself does not enter them; the truth's α is the
    /// encoder error at the nominal angle.
    Interpolation {
        period_arcsec: f64,
        amplitude: f64,
        stop_within_arcsec: f64,
    },
}

/// What the generator knows.
#[derive(Debug, Clone)]
pub struct Truth {
    /// β[k − 1], closed.
    pub pitch_deviation: Vec<f64>,
    /// α[p] at the nominal angles, closed.
    pub encoder_error: Vec<f64>,
    /// Setup error of each autocollimator (in the reading).
    pub setup_error: Vec<f64>,
}

/// A faulty run, its clean twin and their truth.
#[derive(Debug, Clone)]
pub struct Pair {
    /// The readings with the fault, as the file would hold them.
    pub faulty: MeasurementSet,
    /// The same truth and noise without the fault.
    pub twin: MeasurementSet,
    /// The truth.
    pub truth: Truth,
}

fn closed(mut v: Vec<f64>) -> Vec<f64> {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    for x in &mut v {
        *x -= mean;
    }
    v
}

/// A truth for `run`: β of 0.3″ RMS, α a few harmonics of about 0.5″ plus 0.1″ of white
/// detail, setup errors within ±2″.
pub fn truth(run: &Run, rng: &mut impl Rng) -> Truth {
    let n = run.faces;
    let pitch = Normal::new(0.0, 0.3).expect("σ > 0");
    let detail = Normal::new(0.0, 0.1).expect("σ > 0");
    let pitch_deviation = closed((0..n).map(|_| pitch.sample(rng)).collect());
    let harmonics: Vec<(f64, f64)> = (1..=3)
        .map(|_| {
            (
                rng.random_range(0.1..0.5),
                rng.random_range(0.0..std::f64::consts::TAU),
            )
        })
        .collect();
    let encoder_error = closed(
        (0..n)
            .map(|p| {
                let theta = std::f64::consts::TAU * p as f64 / n as f64;
                harmonics
                    .iter()
                    .enumerate()
                    .map(|(h, (a, phase))| a * ((h + 1) as f64 * theta + phase).sin())
                    .sum::<f64>()
                    + detail.sample(rng)
            })
            .collect(),
    );
    let setup_error = run
        .face_offsets
        .iter()
        .map(|_| rng.random_range(-2.0..2.0))
        .collect();
    Truth {
        pitch_deviation,
        encoder_error,
        setup_error,
    }
}

/// φ[face] (face 1 … N) of the truth.
pub fn face_deviation(truth: &Truth, face: usize) -> f64 {
    if face == truth.pitch_deviation.len() {
        return 0.0;
    }
    truth.pitch_deviation[..face].iter().sum()
}

/// One stop of the run in time order.
#[derive(Debug, Clone, Copy)]
struct Slot {
    cycle: u32,
    step: usize,
    time: f64,
}

/// `run` with `fault`, drawn from `seed`. The random draws do not depend on the fault:
/// the same seed gives the same truth and noise whatever the fault.
pub fn generate(run: &Run, fault: &Fault, seed: u64) -> Pair {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let mut truth = truth(run, &mut rng);
    let n = run.faces;
    let acs = run.face_offsets.len();
    let unit = Normal::new(0.0, 1.0).expect("σ > 0");

    // the stops in time order
    let mut slots = Vec::new();
    for cycle in 1..=run.cycles {
        for step in run.steps(cycle) {
            let time = slots.len() as f64 * run.seconds_per_stop;
            slots.push(Slot { cycle, step, time });
        }
    }
    // each stop's offset from its nominal angle (as a fraction of the stated bound), the
    // interpolation's phase, the unit noise per (slot, ac), and the noise of a reading
    // before the first and after the last stop (the late / early faults' stray readings)
    let interp_phase = rng.random_range(0.0..std::f64::consts::TAU);
    let unit_offsets: Vec<f64> = slots.iter().map(|_| rng.random_range(-1.0..=1.0)).collect();
    let noise: Vec<Vec<f64>> = slots
        .iter()
        .map(|_| (0..acs).map(|_| unit.sample(&mut rng)).collect())
        .collect();
    let stray: Vec<f64> = (0..acs).map(|_| unit.sample(&mut rng)).collect();

    let nominal_arcsec = |step: usize| step as f64 * 1_296_000.0 / n as f64;
    let (stop_offsets, interpolation_at): (Vec<f64>, Box<dyn Fn(f64) -> f64>) = match fault {
        Fault::Interpolation {
            period_arcsec,
            amplitude,
            stop_within_arcsec,
        } => {
            let (period, amplitude) = (*period_arcsec, *amplitude);
            (
                unit_offsets
                    .iter()
                    .map(|u| u * stop_within_arcsec)
                    .collect(),
                Box::new(move |theta: f64| {
                    amplitude * (std::f64::consts::TAU * theta / period + interp_phase).sin()
                }),
            )
        }
        _ => (vec![0.0; slots.len()], Box::new(|_| 0.0)),
    };
    // the truth's α is the encoder error at the nominal angle (closed; the mean of the
    // interpolation part is a constant the setup errors take)
    let at_nominal: Vec<f64> = (0..n)
        .map(|p| interpolation_at(nominal_arcsec(p)))
        .collect();
    let mean_at_nominal = at_nominal.iter().sum::<f64>() / n as f64;
    for (alpha, i) in truth.encoder_error.iter_mut().zip(&at_nominal) {
        *alpha += i - mean_at_nominal;
    }
    let truth = truth;

    // the true reading of autocollimator `ac` (0-based) at slot `s` with noise draw `e`:
    // `faulty` with the fault's effects on the instruments (a stop off its nominal angle,
    // a noise rise, a drift), else the twin's; `face_shift` for a polygon a pitch round
    let value = |s: usize, ac: usize, e: f64, face_shift: i64, faulty: bool| -> f64 {
        let slot = slots[s];
        let face = face_at(slot.step, run.face_offsets[ac], n);
        let face = ((face as i64 - 1 + face_shift).rem_euclid(n as i64) + 1) as usize;
        let position = slot.step % n;
        let mut v = truth.encoder_error[position]
            + face_deviation(&truth, face)
            + truth.setup_error[ac]
            + run.sigma * e;
        if !faulty {
            return v;
        }
        let theta = nominal_arcsec(slot.step);
        v += interpolation_at(theta + stop_offsets[s]) - interpolation_at(theta);
        match fault {
            Fault::NoiseRise {
                ac: a,
                from_cycle,
                factor,
            } if *a as usize == ac + 1 && slot.cycle >= *from_cycle => {
                v += run.sigma * (factor - 1.0) * e;
            }
            Fault::KinkedDrift {
                ac: a,
                rate_before,
                rate_after,
                kink_seconds,
            } if *a as usize == ac + 1 => {
                let hours = |seconds: f64| seconds / 3600.0;
                v += if slot.time <= *kink_seconds {
                    rate_before * hours(slot.time)
                } else {
                    rate_before * hours(*kink_seconds)
                        + rate_after * hours(slot.time - kink_seconds)
                };
            }
            _ => {}
        }
        v
    };

    let mut twin = Vec::new();
    let mut faulty = Vec::new();
    for (s, slot) in slots.iter().enumerate() {
        for ac in 0..acs {
            let clean = value(s, ac, noise[s][ac], 0, false);
            let stored = if Some(slot.cycle) == fault_cycle(fault) {
                faulty_value(run, fault, &slots, s, ac, &noise, &stray, &value)
            } else {
                value(s, ac, noise[s][ac], 0, true)
            };
            let line = 2 + faulty.len() as u64;
            let reading = |v: f64, offset: f64| Reading {
                setup: 1,
                cycle: slot.cycle,
                step: slot.step,
                ac: ac as u32 + 1,
                face: face_at(slot.step, run.face_offsets[ac], n),
                reading_arcsec: v,
                direction: run.direction(slot.cycle),
                time_seconds: Some(slot.time),
                reading_y_arcsec: None,
                temperature_celsius: None,
                encoder_degrees: matches!(fault, Fault::Interpolation { .. })
                    .then(|| slot.step as f64 * 360.0 / n as f64 + offset / 3600.0),
                line,
            };
            twin.push(reading(clean, 0.0));
            faulty.push(reading(stored, stop_offsets[s]));
        }
    }
    let twin =
        MeasurementSet::from_readings(twin, Some(n), "twin.csv").expect("the twin is a valid set");
    let faulty = MeasurementSet::from_readings(faulty, Some(n), "faulty.csv")
        .expect("the faulty run is a valid set");
    Pair {
        faulty,
        twin,
        truth,
    }
}

/// The cycle a logging fault acts on.
pub fn fault_cycle(fault: &Fault) -> Option<u32> {
    match fault {
        Fault::SwappedAcs { cycle, .. }
        | Fault::OneStopLate { cycle }
        | Fault::OneStopEarly { cycle }
        | Fault::FacesShifted { cycle, .. }
        | Fault::Reversed { cycle } => Some(*cycle),
        _ => None,
    }
}

/// The value a logging fault stores for autocollimator `ac` at slot `s` of its cycle.
#[allow(clippy::too_many_arguments)]
fn faulty_value(
    run: &Run,
    fault: &Fault,
    slots: &[Slot],
    s: usize,
    ac: usize,
    noise: &[Vec<f64>],
    stray: &[f64],
    value: &dyn Fn(usize, usize, f64, i64, bool) -> f64,
) -> f64 {
    let last = slots.len() - 1;
    match fault {
        Fault::SwappedAcs { a, b, .. } => {
            let other = if ac + 1 == *a as usize {
                *b as usize - 1
            } else if ac + 1 == *b as usize {
                *a as usize - 1
            } else {
                ac
            };
            value(s, other, noise[s][other], 0, true)
        }
        Fault::OneStopLate { .. } => {
            if s == 0 {
                // the table at rest at step 0 before the run
                value(0, ac, stray[ac], 0, true)
            } else {
                value(s - 1, ac, noise[s - 1][ac], 0, true)
            }
        }
        Fault::OneStopEarly { .. } => {
            if s == last {
                // the table at rest where it ended
                value(last, ac, stray[ac], 0, true)
            } else {
                value(s + 1, ac, noise[s + 1][ac], 0, true)
            }
        }
        Fault::FacesShifted { by, .. } => value(s, ac, noise[s][ac], *by, true),
        Fault::Reversed { cycle } => {
            // the cycle's slots in time order; slot k of them holds, in truth, the stop a
            // counter-clockwise cycle visits k-th: the k-th from the end of the clockwise order
            let first = slots
                .iter()
                .position(|slot| slot.cycle == *cycle)
                .expect("the cycle is in the run");
            let len = run.steps(*cycle).len();
            let k = s - first;
            let mirrored = first + (len - 1 - k);
            value(mirrored, ac, noise[s][ac], 0, true)
        }
        _ => value(s, ac, noise[s][ac], 0, true),
    }
}

/// RMS and largest |difference| of `estimate` against `truth`.
pub fn error(estimate: &[f64], truth: &[f64]) -> (f64, f64) {
    let d: Vec<f64> = estimate.iter().zip(truth).map(|(a, b)| a - b).collect();
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    let max = d.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    (rms, max)
}
