//! Driving a run with instruments of your own: the lab's software owns the table and the
//! autocollimators (here a few lines of physics in memory), and polycal's session
//! (`polycal::lab::Session`) decides everything else — the approach from the cycle's
//! direction, readings until they agree, stale and stray replies refused, the check
//! after every cycle and the re-measurements. The session does no input or output: it
//! asks for actions and is told what happened (docs/FORMAT.md §7.6).
//!
//! ```text
//! cargo run --example own_instruments
//! ```
//!
//! A 12-face polygon, two autocollimators at faces 1 and 2, two cycles with the closing
//! step; one reply of autocollimator 2 is disturbed by 1″ of air turbulence. The run is
//! kept in memory ([`MemoryStore`]), then solved, and the pitch deviations are printed
//! beside the truth the instruments were built from.

use std::f64::consts::PI;
use std::process::ExitCode;

use polycal::lab::run::{MemoryStore, RunSettings, RunSoFar, Store};
use polycal::lab::{AcReading, Action, Event, Outcome, Session};
use polycal::measurement::MeasurementSet;
use polycal::solve::{SolveOptions, solve};

const FACES: usize = 12;

/// The lab's instruments: a polygon on a rotary table, two autocollimators.
struct Bench {
    /// Where the table stands, degrees.
    table_deg: f64,
    /// The encoder's error at each step, arcsec (Σ = 0).
    encoder_error: Vec<f64>,
    /// The polygon's pitch deviations, arcsec (Σ = 0).
    pitch_deviation: Vec<f64>,
    /// Each autocollimator's setup error, arcsec.
    setup_error: [f64; 2],
    /// A noise source (xorshift), and the replies autocollimator 2 gave so far.
    state: u64,
    replies_ac2: usize,
}

impl Bench {
    fn new() -> Bench {
        let n = FACES as f64;
        let encoder_error = (0..FACES)
            .map(|p| 0.8 * (2.0 * PI * p as f64 / n).sin() + 0.3 * (4.0 * PI * p as f64 / n).cos())
            .collect();
        let raw: Vec<f64> = (0..FACES)
            .map(|k| 0.5 * ((k * 7 % 5) as f64 - 2.0))
            .collect();
        let mean = raw.iter().sum::<f64>() / n;
        Bench {
            table_deg: 0.0,
            encoder_error,
            pitch_deviation: raw.iter().map(|b| b - mean).collect(),
            setup_error: [1.2, -0.7],
            state: 0x9e37_79b9_7f4a_7c15,
            replies_ac2: 0,
        }
    }

    /// Gaussian noise of standard deviation `sigma` (Box–Muller).
    fn noise(&mut self, sigma: f64) -> f64 {
        let mut uniform = || {
            self.state ^= self.state << 13;
            self.state ^= self.state >> 7;
            self.state ^= self.state << 17;
            ((self.state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let (u1, u2) = (uniform(), uniform());
        sigma * (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }

    /// Autocollimator `ac` (1 or 2) reads the face in front of it: encoder error at the
    /// step, face angle deviation, its setup error, noise (paper eq. (2)).
    fn read(&mut self, ac: u32) -> AcReading {
        let step = (self.table_deg * FACES as f64 / 360.0).round() as usize % FACES;
        let face = (step + ac as usize - 1) % FACES + 1; // faces 1 … N
        let face_deviation: f64 = self.pitch_deviation[..face].iter().sum();
        let mut x = self.encoder_error[step]
            + face_deviation
            + self.setup_error[ac as usize - 1]
            + self.noise(0.02);
        if ac == 2 {
            self.replies_ac2 += 1;
            if self.replies_ac2 == 21 {
                x += 1.0; // a gust of air on one reply
            }
        }
        AcReading::new(3, x, Some(0.1 * face as f64))
    }
}

/// What the run gave.
pub struct Ran {
    /// Readings kept.
    pub readings: usize,
    /// Replies refused by the rules, each as the log gives it.
    pub refused: Vec<String>,
    /// Moves of the table.
    pub moves: usize,
    /// The solved pitch deviations and the truth, arcsec, face 1 first.
    pub pitch_deviation: Vec<f64>,
    /// The truth the instruments were built from.
    pub truth: Vec<f64>,
}

/// Drives the run through the session and solves it.
pub fn run() -> Result<Ran, String> {
    let settings = RunSettings::new(FACES, 2)
        .with_closing(true)
        .with_reading_noise_arcsec(0.05);
    let mut store = MemoryStore::new(settings.clone());
    let mut bench = Bench::new();
    let mut session = Session::new(RunSoFar::new(settings), 0.0);
    let mut clock_seconds = 0.0;
    let mut moves = 0;
    let mut refused = Vec::new();
    let outcome = loop {
        let event = match session.poll() {
            Action::Move { to_deg } => {
                moves += 1;
                clock_seconds += 2.0;
                bench.table_deg = to_deg;
                Event::Moved { at_deg: to_deg }
            }
            Action::Position => Event::Position {
                deg: bench.table_deg,
            },
            Action::Read { ac } => {
                clock_seconds += 0.2;
                Event::Read(bench.read(ac))
            }
            Action::Wait { until_seconds } => {
                clock_seconds = until_seconds;
                Event::Waited
            }
            // One mounting: no remount is asked for.
            Action::Remount(_) => Event::Remounted { confirmed: false },
            Action::Keep(record) => match store.keep(&record) {
                Ok(()) => Event::Kept,
                Err(e) => Event::NotKept(e.to_string()),
            },
            Action::Log(line) => {
                if line.event == "refused" {
                    refused.push(format!("{}: {}", line.device, line.text));
                }
                continue;
            }
            Action::Finished(outcome) => break outcome,
            // Progress, and a halt (none in a run that completes).
            _ => continue,
        };
        session
            .tell(clock_seconds, event)
            .map_err(|e| e.to_string())?;
    };
    if outcome != Outcome::Completed {
        return Err(format!("the run ended {outcome}"));
    }
    let readings = store.run.readings.clone();
    let count = readings.len();
    let set = MeasurementSet::from_readings(readings, Some(FACES), "own instruments")
        .map_err(|e| e.to_string())?;
    let solution = solve(&set, &SolveOptions::default()).map_err(|e| e.to_string())?;
    Ok(Ran {
        readings: count,
        refused,
        moves,
        pitch_deviation: solution.pitch_deviation.clone(),
        truth: bench.pitch_deviation,
    })
}

fn main() -> ExitCode {
    let ran = match run() {
        Ok(ran) => ran,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    for line in &ran.refused {
        println!("refused on {line}");
    }
    println!(
        "{} readings kept, {} replies refused, {} moves",
        ran.readings,
        ran.refused.len(),
        ran.moves
    );
    println!("face  pitch deviation/arcsec  truth/arcsec");
    let mut worst: f64 = 0.0;
    for (k, (beta, truth)) in ran.pitch_deviation.iter().zip(&ran.truth).enumerate() {
        worst = worst.max((beta - truth).abs());
        println!("{:>4}  {beta:>22.4}  {truth:>12.4}", k + 1);
    }
    println!("largest error of β: {worst:.4}″");
    ExitCode::SUCCESS
}
