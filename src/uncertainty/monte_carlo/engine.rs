//! The Monte Carlo engine: trials in seeded blocks over rayon's threads, the fixed and the
//! adaptive number of trials (JCGM 101 §7.2, §7.9), and a progress hook.
//!
//! A [`Trial`] draws one trial's inputs and computes its outputs; [`run`] runs it and
//! returns the summary of every output ([`McResult`]).
//!
//! # Random streams
//!
//! Trials are grouped in blocks of [`BLOCK_SIZE`]; block `b` draws from its own stream
//! ([`block_rng`]: xoshiro256++ lanes seeded from ChaCha8 stream `b` of the seed) with a fresh
//! [`Trial::scratch`], and the blocks, spread over rayon's threads, are combined in block
//! order. Trial `t` therefore gets the same draws whatever `M` and however many threads
//! run, and the same seed gives the same numbers to the last bit.
//!
//! # Exact intervals without storing every trial
//!
//! The probabilistically symmetric coverage interval (JCGM 101 §7.7) is the pair of order
//! statistics a full sort of all `M` values would give, but the trials are not stored: the
//! first `min(M, J)` trials (`J` the sequence length of the adaptive procedure) bracket
//! each interval end, later trials only count the values below a bracket and keep the few
//! inside it, and a bracket that missed is widened and the later trials re-run (module
//! `statistics`). After `10 J` and again after `50 J` trials the brackets are refined
//! from the trials run so far (a third, then a sixth as wide), which keeps fewer values. The per-output work is
//! branch-free but for the values inside a bracket. The mean and the standard deviation come from sums of the deviations
//! from [`Trial::centre`]. With [`EngineOptions::keep_samples`] every trial's outputs are
//! kept as well, which adds the shortest coverage interval (JCGM 101 §7.7.2) and the
//! samples to the result without changing any other number.

use std::fmt;
use std::ops::Range;
use std::sync::Mutex;

use rand::Rng;
use rayon::prelude::*;

use super::statistics::{
    Acc, Brackets, Moments, ROWS, brackets_from, columns, finish, order_statistic,
    shortest_interval, standard_deviation_of_mean, symmetric_interval_positions,
};
use super::stream::block_rng;
use super::{McError, McResult, OutputSummary, Trials, numerical_tolerance};

/// An upper bound of the memory a run of `trials` trials of `outputs` outputs keeps,
/// bytes: the values inside the coverage interval's brackets (at most about 2 % of the
/// trials at each end, 16 bytes each, module `statistics`), and with `keep_samples` every
/// output of every trial (8 bytes each).
pub(crate) fn memory_needed(trials: usize, outputs: usize, keep_samples: bool) -> u128 {
    let values = trials as u128 * outputs as u128;
    let brackets = values * 16 / 20; // 2 ends × 2.5 % × 16 bytes
    brackets + if keep_samples { values * 8 } else { 0 }
}

/// Number of trials drawn from one random stream: the unit of parallel work and of
/// progress reports.
pub const BLOCK_SIZE: usize = 1000;

/// The number of trials per sequence of the adaptive procedure at coverage probability
/// `p`: `max(10⁴, ⌈100/(1 − p)⌉)` (JCGM 101 §7.9.4 b), rounded up to whole blocks of
/// [`BLOCK_SIZE`]. A fixed run of more trials takes this many as its pilot.
///
/// ```
/// use polycal::uncertainty::monte_carlo::adaptive_sequence_length;
/// assert_eq!(adaptive_sequence_length(0.95), 10_000);
/// assert_eq!(adaptive_sequence_length(0.999), 100_000);
/// ```
pub fn adaptive_sequence_length(p: f64) -> usize {
    let j = (100.0 / (1.0 - p)).ceil().max(10_000.0) as usize;
    j.div_ceil(BLOCK_SIZE) * BLOCK_SIZE
}

/// The fewest trials for which the coverage interval at `p` has both ends:
/// `⌈1/(1 − p)⌉` (JCGM 101 §7.2.1 asks for far more: `M ≥ 10⁴/(1 − p)`).
pub(crate) fn minimum_trials(p: f64) -> usize {
    (1.0 / (1.0 - p)).ceil() as usize
}

/// One Monte Carlo trial: draw the inputs, evaluate the model (JCGM 101 §7.2, §7.4).
///
/// The engine calls [`Trial::draw`] once per trial with the random stream of the trial's
/// block and a scratch space of that block ([`Trial::scratch`]); a trial must take all its
/// randomness from `rng`, so that its outputs depend only on the seed and its index.
pub trait Trial: Sync {
    /// Working space of one block of trials (buffers reused from trial to trial).
    type Scratch: Send;

    /// Number of outputs of every trial (at least one).
    fn outputs(&self) -> usize;

    /// Values near the expectations of the outputs (for example the outputs at the
    /// estimates of the inputs), [`Trial::outputs`] of them. The engine sums deviations
    /// from them, which keeps the digits of the mean and the standard deviation when
    /// these are small against the values; any finite values give the same results up
    /// to rounding.
    fn centre(&self) -> &[f64];

    /// A fresh scratch space.
    fn scratch(&self) -> Self::Scratch;

    /// Draws one trial from `rng` and writes its [`Trial::outputs`] values into `out`.
    ///
    /// # Errors
    ///
    /// [`TrialFailure`] when the model cannot give this trial's outputs; the engine stops
    /// with [`McError::NonFinite`] or [`McError::OutputCount`]. A non-finite output is
    /// caught by the engine as well.
    fn draw<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        scratch: &mut Self::Scratch,
        out: &mut [f64],
    ) -> Result<(), TrialFailure>;

    /// The inputs of the last trial drawn into `scratch`, for the message of a failed
    /// trial ([`McError::NonFinite`]).
    fn inputs(&self, scratch: &Self::Scratch) -> Vec<f64>;
}

/// Why a [`Trial`] gave no outputs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum TrialFailure {
    /// The model could not be evaluated for these inputs (a singular system, say).
    Failed,
    /// The model gave this many outputs instead of [`Trial::outputs`].
    OutputCount(usize),
}

/// An observer of the progress of a run, told after every block of [`BLOCK_SIZE`] trials
/// (so that a command can draw a progress bar; the library draws nothing).
///
/// Calls come from rayon's threads but never at the same time, and `done` grows from call
/// to call. Any `Fn(u64, Option<u64>) + Sync` closure is a `Progress`:
///
/// ```
/// use std::sync::atomic::{AtomicU64, Ordering};
/// use polycal::uncertainty::monte_carlo::{EngineOptions, Progress, Trials};
///
/// let last = AtomicU64::new(0);
/// let report = |done: u64, _total: Option<u64>| last.store(done, Ordering::Relaxed);
/// let options = EngineOptions::new(Trials::Fixed(20_000)).with_progress(&report);
/// # let _ = options;
/// ```
pub trait Progress: Sync {
    /// `done` trials have run so far; `total` is the number the run will make if known:
    /// `M` for a fixed number of trials (raised if trials are re-run to widen a bracket),
    /// `None` for the adaptive procedure, which stops when the results are stable.
    fn update(&self, done: u64, total: Option<u64>);
}

impl<F: Fn(u64, Option<u64>) + Sync> Progress for F {
    fn update(&self, done: u64, total: Option<u64>) {
        self(done, total);
    }
}

/// How the engine runs: number of trials, coverage probability, seed, whether to keep
/// every trial's outputs, and the progress observer.
#[derive(Clone, Copy)]
#[non_exhaustive]
pub struct EngineOptions<'a> {
    /// Fixed `M`, or the adaptive procedure of JCGM 101 §7.9.
    pub trials: Trials,
    /// Coverage probability of the intervals (default 0.95).
    pub p: f64,
    /// Seed of the random streams (default 1).
    pub seed: u64,
    /// Whether to keep every trial's outputs (default no): adds the samples and the
    /// shortest coverage intervals to the result.
    pub keep_samples: bool,
    /// Told after every block of trials (default none).
    pub progress: Option<&'a dyn Progress>,
}

impl<'a> EngineOptions<'a> {
    /// `trials` trials at `p = 0.95`, seed 1, no samples kept, no progress observer.
    pub fn new(trials: Trials) -> Self {
        EngineOptions {
            trials,
            p: 0.95,
            seed: 1,
            keep_samples: false,
            progress: None,
        }
    }

    /// The same options with coverage probability `p`.
    pub fn with_coverage(mut self, p: f64) -> Self {
        self.p = p;
        self
    }

    /// The same options with another seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// The same options, keeping (or not) every trial's outputs.
    pub fn with_samples(mut self, keep: bool) -> Self {
        self.keep_samples = keep;
        self
    }

    /// The same options with a progress observer ([`Progress`]).
    pub fn with_progress(mut self, progress: &'a dyn Progress) -> Self {
        self.progress = Some(progress);
        self
    }
}

impl fmt::Debug for EngineOptions<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("EngineOptions")
            .field("trials", &self.trials)
            .field("p", &self.p)
            .field("seed", &self.seed)
            .field("keep_samples", &self.keep_samples)
            .field("progress", &self.progress.map(|_| "observer"))
            .finish()
    }
}

/// Runs `trial`: a fixed number of trials or the adaptive procedure of JCGM 101 §7.9,
/// with the statistics of every output (mean, standard uncertainty, probabilistically
/// symmetric coverage interval from the exact order statistics; with
/// [`EngineOptions::keep_samples`] also the shortest interval and the samples).
///
/// # Errors
///
/// [`McError::Coverage`] for `p` outside (0, 1), [`McError::NoOutputs`] for a trial
/// without outputs, [`McError::TooFewTrials`], [`McError::NonFinite`] or
/// [`McError::OutputCount`] for a failed trial, [`McError::NotStabilized`] for an adaptive
/// run that reaches its trial limit.
///
/// # Panics
///
/// If [`Trial::centre`] does not give [`Trial::outputs`] values (a broken `Trial`).
pub fn run<T: Trial>(trial: &T, options: &EngineOptions<'_>) -> Result<McResult, McError> {
    let p = options.p;
    if !(p > 0.0 && p < 1.0) {
        return Err(McError::Coverage(p));
    }
    let outputs = trial.outputs();
    if outputs == 0 {
        return Err(McError::NoOutputs);
    }
    assert_eq!(
        trial.centre().len(),
        outputs,
        "Trial::centre must give one value per output"
    );
    let planned = match options.trials {
        Trials::Fixed(m) => m,
        Trials::Adaptive { max_trials, .. } => max_trials,
    };
    let needed_bytes = memory_needed(planned, outputs, options.keep_samples);
    if let Some((limit_bytes, limit_source)) = crate::solve::memory::limit_for(needed_bytes, None)
        && needed_bytes > u128::from(limit_bytes)
    {
        return Err(McError::TooLarge {
            trials: planned,
            outputs,
            needed_bytes,
            limit_bytes,
            limit_source,
        });
    }
    let engine = Engine {
        trial,
        seed: options.seed,
        p,
        keep: options.keep_samples,
        counter: Counter::new(options.progress),
    };
    let (trials, sequences, moments, raw) = match options.trials {
        Trials::Fixed(m) => {
            let needed = minimum_trials(p);
            if m < needed {
                return Err(McError::TooFewTrials {
                    trials: m,
                    p,
                    needed,
                });
            }
            engine.counter.add_total(m);
            let (moments, raw) = engine.fixed(m)?;
            (m, None, moments, raw)
        }
        Trials::Adaptive {
            significant_digits,
            max_trials,
        } => {
            let (h, moments, raw) = engine.adaptive(significant_digits.max(1), max_trials)?;
            (h * adaptive_sequence_length(p), Some(h), moments, raw)
        }
    };
    let (mean, u, low, high) = moments;
    let columns = raw.map(|raw| columns(&raw, outputs));
    let shortest: Vec<Option<(f64, f64)>> = match &columns {
        Some(columns) => columns
            .par_iter()
            .map(|column| {
                let mut sorted = column.clone();
                sorted.sort_unstable_by(f64::total_cmp);
                Some(shortest_interval(&sorted, p))
            })
            .collect(),
        None => vec![None; outputs],
    };
    let summaries = (0..outputs)
        .map(|j| OutputSummary {
            mean: mean[j],
            u: u[j],
            p,
            low: low[j],
            high: high[j],
            shortest: shortest[j],
        })
        .collect();
    Ok(McResult {
        trials,
        sequences,
        outputs: summaries,
        samples: columns,
    })
}

/// Tells the progress observer, one call at a time.
struct Counter<'a> {
    progress: Option<&'a dyn Progress>,
    /// Trials done, and the total if known.
    state: Mutex<(u64, Option<u64>)>,
}

impl<'a> Counter<'a> {
    fn new(progress: Option<&'a dyn Progress>) -> Self {
        Counter {
            progress,
            state: Mutex::new((0, None)),
        }
    }

    /// `n` more trials will run.
    fn add_total(&self, n: usize) {
        if self.progress.is_some() {
            let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
            state.1 = Some(state.1.unwrap_or(0) + n as u64);
        }
    }

    /// `n` more trials have run.
    fn add_done(&self, n: usize) {
        if let Some(progress) = self.progress {
            let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
            state.0 += n as u64;
            progress.update(state.0, state.1);
        }
    }
}

/// A run in progress: the trial, its seed and coverage probability.
struct Engine<'a, T> {
    trial: &'a T,
    seed: u64,
    p: f64,
    /// Whether to keep every trial's outputs.
    keep: bool,
    counter: Counter<'a>,
}

/// The outputs of some trials, trial-major (`outputs` values per trial).
type Raw = Vec<f64>;

impl<T: Trial> Engine<'_, T> {
    /// Runs trials `range` (its start a multiple of [`BLOCK_SIZE`]) in parallel blocks.
    /// With `brackets` (and the fraction 1/room of the trials expected inside each),
    /// returns the accumulated sums and bracket contents; every trial's outputs
    /// (trial-major) without, or when all are kept.
    fn blocks(
        &self,
        range: Range<usize>,
        brackets: Option<(&Brackets, usize)>,
    ) -> Result<(Option<Acc>, Raw), McError> {
        debug_assert_eq!(range.start % BLOCK_SIZE, 0);
        let trial = self.trial;
        let outputs = trial.outputs();
        let centre = trial.centre();
        let keep = self.keep || brackets.is_none();
        let first = range.start / BLOCK_SIZE;
        let last = range.end.div_ceil(BLOCK_SIZE);
        let blocks: Vec<(Option<Acc>, Raw)> = (first..last)
            .into_par_iter()
            .map(|b| {
                let from = b * BLOCK_SIZE;
                let to = ((b + 1) * BLOCK_SIZE).min(range.end);
                let mut rng = block_rng(self.seed, b as u64);
                let mut scratch = trial.scratch();
                // The outputs of the last few trials, trial-major, recorded together.
                let mut rows = vec![0.0; ROWS * outputs];
                let mut filled = 0;
                // Room for about 1/`room` of the values inside a bracket.
                let mut acc = brackets.map(|(_, room)| {
                    Acc::with_capacity(outputs, 2 * outputs * (to - from) / room + 64)
                });
                let mut raw = Vec::new();
                if keep {
                    raw.reserve((to - from) * outputs);
                }
                for t in from..to {
                    let out = &mut rows[filled * outputs..(filled + 1) * outputs];
                    let solved = match trial.draw(&mut rng, &mut scratch, out) {
                        Ok(()) => true,
                        Err(TrialFailure::Failed) => false,
                        Err(TrialFailure::OutputCount(got)) => {
                            return Err(McError::OutputCount {
                                trial: t,
                                expected: outputs,
                                got,
                            });
                        }
                    };
                    // One pass without a branch per output; the culprit only on failure.
                    let finite = out.iter().fold(true, |all, v| all & v.is_finite());
                    if let Some((output, &value)) = (!solved || !finite)
                        .then(|| {
                            out.iter()
                                .enumerate()
                                .find(|(_, v)| !solved || !v.is_finite())
                        })
                        .flatten()
                    {
                        return Err(McError::NonFinite {
                            trial: t,
                            output,
                            value,
                            inputs: trial.inputs(&scratch),
                        });
                    }
                    if keep {
                        raw.extend_from_slice(out);
                    }
                    filled += 1;
                    if filled == ROWS || t + 1 == to {
                        if let (Some(acc), Some((b, _))) = (&mut acc, brackets) {
                            acc.record_rows(&rows[..filled * outputs], centre, b);
                        }
                        filled = 0;
                    }
                }
                self.counter.add_done(to - from);
                Ok((acc, raw))
            })
            .collect::<Vec<Result<_, McError>>>()
            .into_iter()
            .collect::<Result<_, McError>>()?;
        let mut total = brackets.map(|_| Acc::new(outputs));
        let mut raw = Vec::new();
        for (acc, values) in blocks {
            if let (Some(total), Some(acc)) = (&mut total, acc) {
                total.merge(acc);
            }
            raw.extend(values);
        }
        Ok((total, raw))
    }

    /// The exact summary of trials `0..m` from the pilot (trials `0..pilot_len`, already
    /// run) and brackets around the interval ends, re-running the trials after the pilot
    /// with wider brackets if one missed. Returns the outputs of the trials after the
    /// pilot when all are kept.
    fn bracketed(
        &self,
        m: usize,
        pilot_raw: &[f64],
        pilot_len: usize,
    ) -> Result<(Moments, Raw), McError> {
        let outputs = self.trial.outputs();
        let centre = self.trial.centre();
        let mut pilot = columns(pilot_raw, outputs);
        let mut factor = 1.0;
        let mut rerun = false;
        loop {
            let wide = factor > 1000.0;
            let brackets = if wide {
                Brackets::everything(outputs)
            } else {
                brackets_from(&mut pilot, m, self.p, factor)
            };
            let mut acc = Acc::new(outputs);
            acc.feed(pilot_raw, centre, &brackets);
            let mut rest_raw = Vec::new();
            if m > pilot_len && rerun {
                self.counter.add_total(m - pilot_len);
            }
            // Stages after the pilot: up to ten pilots' worth of trials with the pilot's
            // brackets, then up to fifty with brackets refined from those trials (about a
            // third as wide), the rest with brackets refined again (half as wide again):
            // fewer values to keep, fewer branches mispredicted.
            let (second, third) = if wide {
                (m, m)
            } else {
                (m.min(10 * pilot_len), m.min(50 * pilot_len))
            };
            let mut brackets = brackets;
            let stages = [
                (pilot_len..second, 32),
                (second..third, 128),
                (third..m, 256),
            ];
            for (range, room) in stages {
                if range.is_empty() {
                    continue;
                }
                if range.start > pilot_len {
                    brackets = acc.refine(range.start, m, self.p, factor, &brackets);
                }
                let (rest, raw) = self.blocks(range, Some((&brackets, room)))?;
                acc.merge(rest.unwrap_or_else(|| unreachable!("brackets were given")));
                rest_raw.extend(raw);
            }
            if let Some(result) = finish(acc, m, self.p, centre) {
                return Ok((result, rest_raw));
            }
            factor *= 16.0;
            rerun = true;
        }
    }

    /// `m` trials: the first `min(m, J)` as the pilot, the rest bracketed.
    fn fixed(&self, m: usize) -> Result<(Moments, Option<Raw>), McError> {
        let pilot_len = m.min(adaptive_sequence_length(self.p));
        let (_, pilot_raw) = self.blocks(0..pilot_len, None)?;
        let (moments, rest_raw) = self.bracketed(m, &pilot_raw, pilot_len)?;
        let raw = self.keep.then(|| {
            let mut raw = pilot_raw;
            raw.extend(rest_raw);
            raw
        });
        Ok((moments, raw))
    }

    /// The adaptive procedure of JCGM 101 §7.9: sequences of `J` trials (§7.9.4 b) until
    /// twice the standard deviation of the sequence means of the mean, the standard
    /// uncertainty and both interval ends of every output is within the numerical
    /// tolerance `δ` of the standard uncertainty (§7.9.4 f–i). Returns the number of
    /// sequences.
    fn adaptive(
        &self,
        digits: u32,
        max_trials: usize,
    ) -> Result<(usize, Moments, Option<Raw>), McError> {
        let outputs = self.trial.outputs();
        let centre = self.trial.centre();
        let p = self.p;
        let j = adaptive_sequence_length(p);
        let (r_low, r_high) = symmetric_interval_positions(j, p);
        // Per output, per sequence: mean, u, low, high.
        let mut estimates: Vec<Vec<[f64; 4]>> = vec![Vec::new(); outputs];
        // All sequences so far, bracketed around the interval ends of the first.
        let mut first_raw = Vec::new();
        let mut kept = Vec::new();
        let mut brackets = Brackets::everything(outputs);
        let mut acc = Acc::new(outputs);
        let mut h = 0;
        loop {
            if (h + 1) * j > max_trials.max(2 * j) {
                return Err(McError::NotStabilized {
                    trials: h * j,
                    digits,
                });
            }
            let (_, raw) = self.blocks(h * j..(h + 1) * j, None)?;
            let per_sequence: Vec<[f64; 4]> = (0..outputs)
                .into_par_iter()
                .map(|o| {
                    let mut column: Vec<f64> =
                        raw.iter().skip(o).step_by(outputs).copied().collect();
                    let jf = column.len() as f64;
                    let (a, b) = column.iter().fold((0.0, 0.0), |(a, b), &x| {
                        let d = x - centre[o];
                        (a + d, b + d * d)
                    });
                    let mean = centre[o] + a / jf;
                    let u = ((b - a * a / jf).max(0.0) / (jf - 1.0)).sqrt();
                    let low = order_statistic(&mut column, r_low);
                    let high = order_statistic(&mut column, r_high);
                    [mean, u, low, high]
                })
                .collect();
            for (o, e) in per_sequence.into_iter().enumerate() {
                estimates[o].push(e);
            }
            if h == 0 {
                brackets = brackets_from(&mut columns(&raw, outputs), j, p, 1.0);
            }
            acc.feed(&raw, centre, &brackets);
            if self.keep {
                kept.extend_from_slice(&raw);
            }
            if h == 0 {
                first_raw = raw;
            }
            h += 1;
            if h < 2 {
                continue;
            }
            let m = (h * j) as f64;
            let stable = (0..outputs).all(|o| {
                let (s1, s2) = (acc.s1[o], acc.s2[o]);
                let u_all = ((s2 - s1 * s1 / m).max(0.0) / (m - 1.0)).sqrt();
                let delta = numerical_tolerance(u_all, digits);
                (0..4).all(|q| {
                    let xs: Vec<f64> = estimates[o].iter().map(|e| e[q]).collect();
                    2.0 * standard_deviation_of_mean(&xs) <= delta
                })
            });
            if stable {
                let m = h * j;
                // The brackets were set for J trials; if one missed for m, re-run.
                let moments = match finish(acc, m, p, centre) {
                    Some(result) => result,
                    None => self.bracketed(m, &first_raw, j)?.0,
                };
                return Ok((h, moments, self.keep.then_some(kept)));
            }
        }
    }
}
