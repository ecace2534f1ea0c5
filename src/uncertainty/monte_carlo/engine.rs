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
//! # Exact intervals in bounded memory
//!
//! The probabilistically symmetric coverage interval (JCGM 101 §7.7) is the pair of order
//! statistics a full sort of all `M` values would give, but the trials are not stored: a
//! pilot of the first trials ([`pilot_len`]: `min(M, J)`, `J` the sequence length of the
//! adaptive procedure, fewer when `J` trials of every output would take more than 64 MiB,
//! but at least one block per thread) brackets each interval end; later trials only count
//! the values below a bracket and keep the few inside it, and a bracket that missed is
//! widened and the later trials re-run (module `statistics`). At every doubling of the
//! trials run the brackets are refined from the values kept (a bracket then holds about
//! `2·(6√(sπ(1−π)) + 10)/s` of the `s` trials, π the end's probability), so that the
//! values kept grow like √M per output, not like M: 10⁵ trials of 4 319 outputs keep
//! about 1.8 % of their values. [`memory_needed`] bounds what a run holds, and a run that
//! would not fit is refused before it starts ([`McError::TooLarge`]). The per-output work
//! is branch-free but for the values inside a bracket. The mean and the standard
//! deviation come from sums of the deviations from [`Trial::centre`], added block by
//! block in block order whatever the stages and the threads. With
//! [`EngineOptions::keep_samples`] every trial's outputs are kept as well, which adds the
//! shortest coverage interval (JCGM 101 §7.7.2) and the samples to the result without
//! changing any other number.
//!
//! The adaptive procedure (JCGM 101 §7.9) summarizes each sequence of `J` trials the same
//! way, and once its results are stable runs the `h·J` trials again (the same draws) for
//! the exact order statistics of all of them.

use std::fmt;
use std::ops::Range;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use rand::Rng;
use rayon::prelude::*;

use super::statistics::{
    Acc, Brackets, Moments, ROWS, brackets_from_raw, columns, finish, rank_margin,
    shortest_interval, standard_deviation_of_mean,
};
use super::stream::block_rng;
use super::{McError, McResult, OutputSummary, Trials, numerical_tolerance};
use crate::progress::Progress;

/// Bytes of trial outputs the pilot may hold: a run of many outputs brackets its interval
/// ends from fewer trials (at least one block), with wider brackets that later
/// refinements narrow.
const PILOT_BYTES: usize = 64 << 20;

/// The pilot of a run of `m` trials of `outputs` outputs at coverage probability `p`:
/// `min(m, J)` trials (`J` the adaptive sequence length), fewer when `J` trials'
/// outputs would take more than [`PILOT_BYTES`], but whole blocks and at least one per
/// thread.
pub(crate) fn pilot_len(m: usize, outputs: usize, p: f64) -> usize {
    let fit = (PILOT_BYTES / (8 * outputs.max(1))) / BLOCK_SIZE * BLOCK_SIZE;
    // One block per thread at least, so that no thread waits for the pilot; the
    // results do not depend on the pilot's length, only the memory and the time do.
    let threads = rayon::current_num_threads().max(1) * BLOCK_SIZE;
    m.min(adaptive_sequence_length(p).min(fit.max(threads)))
}

/// The trial counts at which the brackets are refined in a run of `m` trials with a
/// pilot of `pilot` trials: the pilot doubled, again and again, below `m`. After the
/// refinement at `s` trials a bracket holds about `2·rank_margin(s)/s` of the trials.
fn refinements(pilot: usize, m: usize) -> Vec<usize> {
    let mut at = Vec::new();
    // (doubled without overflow: a run of up to usize::MAX trials is planned, and then
    // refused on its memory, never wrapped to 0)
    let mut s = pilot.max(1).saturating_mul(2);
    while s < m {
        at.push(s);
        match s.checked_mul(2) {
            Some(next) => s = next,
            None => break,
        }
    }
    at
}

/// An upper bound of the memory a run of `trials` trials of `outputs` outputs at coverage
/// probability `p` needs, bytes: the pilot's outputs (8 bytes each) and the columns
/// bracketed at a time, and twice (while they are sorted into buckets) the values inside
/// the coverage interval's brackets (16 bytes each: after the last refinement at `s`
/// trials, each of the two brackets of an output spans about `2·rank_margin(s) + 1` of
/// `s` ranks; counted with half as much again for the scatter of the values and the
/// stores' slack); with `keep_samples` every output of every trial as well (8 bytes
/// each).
pub(crate) fn memory_needed(trials: usize, outputs: usize, keep_samples: bool, p: f64) -> u128 {
    let pilot = pilot_len(trials, outputs, p);
    let pilot_bytes = 8 * pilot as u128 * outputs as u128;
    let last = refinements(pilot, trials)
        .last()
        .copied()
        .unwrap_or(pilot)
        .max(1);
    let pi = (1.0 - p.clamp(0.0, 1.0)) / 2.0;
    let per_bracket = ((2.0 * rank_margin(last, pi, 1.0) + 1.0) / last as f64).min(1.0);
    let kept = 1.5 * 2.0 * per_bracket * trials as f64 * outputs as f64;
    let bracket_bytes = 2 * 16 * kept.ceil() as u128;
    let values = trials as u128 * outputs as u128;
    pilot_bytes
        + super::statistics::COLUMN_BYTES as u128
        + bracket_bytes
        + if keep_samples { values * 8 } else { 0 }
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
        Trials::Adaptive { max_trials, .. } => {
            // two sequences are the fewest with which stability can be judged
            let fewest = 2 * adaptive_sequence_length(p);
            if max_trials < fewest {
                return Err(McError::AdaptiveLimitTooLow { max_trials, fewest });
            }
            max_trials
        }
    };
    let needed_bytes = memory_needed(planned, outputs, options.keep_samples, p);
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
        peak_kept: AtomicUsize::new(0),
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
    /// The most values kept inside brackets at once (what the memory estimate bounds).
    peak_kept: AtomicUsize,
}

/// The outputs of some trials, trial-major (`outputs` values per trial).
type Raw = Vec<f64>;

impl<T: Trial> Engine<'_, T> {
    /// Runs trials `range` (its start a multiple of [`BLOCK_SIZE`]) in parallel blocks.
    /// With `brackets` (and the share of the values they are expected to hold), merges
    /// each block's sums and bracket contents into `into`, block
    /// by block in block order (so that the sums are added in the same order however
    /// the trials are split into stages, and whatever the number of threads); returns
    /// every trial's outputs (trial-major) without brackets, or when all are kept.
    fn blocks(
        &self,
        range: Range<usize>,
        brackets: Option<(&Brackets, &mut Acc, f64)>,
    ) -> Result<Raw, McError> {
        debug_assert_eq!(range.start % BLOCK_SIZE, 0);
        let trial = self.trial;
        let outputs = trial.outputs();
        let centre = trial.centre();
        let keep = self.keep || brackets.is_none();
        // The share of all values the brackets are expected to hold.
        let (brackets, into, share) = match brackets {
            Some((b, into, share)) => (Some(b), Some(into), share.clamp(0.0, 2.0)),
            None => (None, None, 0.0),
        };
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
                // Room for the share of the values the brackets are expected to hold
                // (and a fifth more): more is made as needed, and a store left more than
                // half empty is given back at the end of the block.
                let mut acc = brackets.map(|_| {
                    let expected = share * (outputs * (to - from)) as f64 * 1.2;
                    Acc::with_capacity(outputs, expected.ceil() as usize + 64)
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
                        if let (Some(acc), Some(b)) = (&mut acc, brackets) {
                            acc.record_rows(&rows[..filled * outputs], centre, b);
                        }
                        filled = 0;
                    }
                }
                if let Some(acc) = &mut acc {
                    acc.shrink();
                }
                self.counter.add_done(to - from);
                Ok((acc, raw))
            })
            .collect::<Vec<Result<_, McError>>>()
            .into_iter()
            .collect::<Result<_, McError>>()?;
        let mut raw = Vec::new();
        let mut into = into;
        for (acc, values) in blocks {
            if let (Some(total), Some(acc)) = (&mut into, acc) {
                total.merge(acc);
            }
            raw.extend(values);
        }
        Ok(raw)
    }

    /// Merges the pilot's outputs (trial-major, from trial 0 of a block) into `acc`
    /// block by block, as [`Engine::blocks`] merges the trials it runs.
    fn feed_pilot(&self, pilot_raw: &[f64], brackets: &Brackets, acc: &mut Acc) {
        let outputs = self.trial.outputs();
        let centre = self.trial.centre();
        for block in pilot_raw.chunks(BLOCK_SIZE * outputs) {
            let mut one = Acc::new(outputs);
            one.feed(block, centre, brackets);
            acc.merge(one);
        }
    }

    /// The exact summary (mean, u, the ends of the probabilistically symmetric interval)
    /// of the trials `range` (its start a multiple of [`BLOCK_SIZE`]) in bounded memory:
    /// its first trials ([`pilot_len`] of them) are the pilot, whose order statistics
    /// bracket each interval end; the rest are counted against the brackets, refined at
    /// every doubling of the trials run ([`refinements`]); a bracket that missed is
    /// widened and the trials after the pilot run again. Returns also the sums Σ(x − c)
    /// and Σ(x − c)² of the range, and its outputs, trial-major, when all are kept.
    fn exact(&self, range: Range<usize>) -> Result<(Moments, [Vec<f64>; 2], Raw), McError> {
        let outputs = self.trial.outputs();
        let centre = self.trial.centre();
        let m = range.len();
        let pilot_len = pilot_len(m, outputs, self.p);
        let pilot_end = range.start + pilot_len;
        let pilot_raw = self.blocks(range.start..pilot_end, None)?;
        let mut factor = 1.0;
        let mut rerun = false;
        loop {
            let wide = factor > 1000.0;
            let mut brackets = if wide {
                Brackets::everything(outputs)
            } else {
                brackets_from_raw(&pilot_raw, outputs, m, self.p, factor)
            };
            let mut acc = Acc::new(outputs);
            self.feed_pilot(&pilot_raw, &brackets, &mut acc);
            let mut raw = if self.keep {
                pilot_raw.clone()
            } else {
                Vec::new()
            };
            if m > pilot_len && rerun {
                self.counter.add_total(m - pilot_len);
            }
            // Stages: from the pilot to twice as many trials, to four times as many, …
            // each with brackets refined from every trial before it.
            let mut starts = vec![pilot_len];
            if !wide {
                starts.extend(refinements(pilot_len, m));
            }
            for (k, &from) in starts.iter().enumerate() {
                let to = starts.get(k + 1).copied().unwrap_or(m);
                if from >= to {
                    continue;
                }
                if k > 0 {
                    brackets = acc.refine(from, m, self.p, factor, &brackets);
                }
                let stage = range.start + from..range.start + to;
                // Each bracket holds about 2·margin + 1 of the ranks of the trials it
                // was set from (the pilot's, or the trials before the stage).
                let set_from = if k == 0 { pilot_len } else { from };
                let pi = (1.0 - self.p) / 2.0;
                let share = if wide {
                    2.0
                } else {
                    2.0 * (2.0 * rank_margin(set_from, pi, factor) + 1.0) / set_from as f64
                };
                let values = self.blocks(stage, Some((&brackets, &mut acc, share)))?;
                self.note_kept(acc.kept());
                raw.extend(values);
            }
            let sums = [acc.s1.clone(), acc.s2.clone()];
            if let Some(result) = finish(acc, m, self.p, centre) {
                return Ok((result, sums, raw));
            }
            factor *= 16.0;
            rerun = true;
        }
    }

    /// Records the number of values kept inside brackets, for [`Engine::peak_kept`].
    fn note_kept(&self, kept: usize) {
        self.peak_kept.fetch_max(kept, Ordering::Relaxed);
    }

    /// `m` trials, summarized exactly ([`Engine::exact`]).
    fn fixed(&self, m: usize) -> Result<(Moments, Option<Raw>), McError> {
        let (moments, _, raw) = self.exact(0..m)?;
        Ok((moments, self.keep.then_some(raw)))
    }

    /// The adaptive procedure of JCGM 101 §7.9: sequences of `J` trials (§7.9.4 b) until
    /// twice the standard deviation of the sequence means of the mean, the standard
    /// uncertainty and both interval ends of every output is within the numerical
    /// tolerance `δ` of the standard uncertainty (§7.9.4 f–i). Returns the number of
    /// sequences.
    ///
    /// Each sequence is summarized exactly and in bounded memory ([`Engine::exact`]);
    /// once the results are stable, the `h·J` trials are summarized together (§7.9.4 j)
    /// by running them again: the same draws (each block's random stream depends only on
    /// the seed and its index), so the interval ends are the order statistics of all
    /// `h·J` values, without keeping them.
    fn adaptive(
        &self,
        digits: u32,
        max_trials: usize,
    ) -> Result<(usize, Moments, Option<Raw>), McError> {
        let outputs = self.trial.outputs();
        let j = adaptive_sequence_length(self.p);
        // Per output, per sequence: mean, u, low, high.
        let mut estimates: Vec<Vec<[f64; 4]>> = vec![Vec::new(); outputs];
        // Σ(x − c) and Σ(x − c)² of all sequences so far.
        let mut s1 = vec![0.0; outputs];
        let mut s2 = vec![0.0; outputs];
        let mut kept = Vec::new();
        let mut h = 0;
        loop {
            if (h + 1) * j > max_trials.max(2 * j) {
                return Err(McError::NotStabilized {
                    trials: h * j,
                    digits,
                });
            }
            let ((mean, u, low, high), [a, b], raw) = self.exact(h * j..(h + 1) * j)?;
            for o in 0..outputs {
                estimates[o].push([mean[o], u[o], low[o], high[o]]);
                s1[o] += a[o];
                s2[o] += b[o];
            }
            kept.extend(raw);
            h += 1;
            if h < 2 {
                continue;
            }
            let m = (h * j) as f64;
            let stable = (0..outputs).all(|o| {
                let u_all = ((s2[o] - s1[o] * s1[o] / m).max(0.0) / (m - 1.0)).sqrt();
                let delta = numerical_tolerance(u_all, digits);
                (0..4).all(|q| {
                    let xs: Vec<f64> = estimates[o].iter().map(|e| e[q]).collect();
                    2.0 * standard_deviation_of_mean(&xs) <= delta
                })
            });
            if stable {
                // The second pass keeps nothing it need not: the samples, if asked
                // for, were kept sequence by sequence.
                let all = Engine {
                    keep: false,
                    ..self.share()
                };
                let (moments, _, _) = all.exact(0..h * j)?;
                self.note_kept(all.peak_kept.load(Ordering::Relaxed));
                return Ok((h, moments, self.keep.then_some(kept)));
            }
        }
    }

    /// An engine of the same trial, seed, coverage and progress observer.
    fn share(&self) -> Engine<'_, T> {
        Engine {
            trial: self.trial,
            seed: self.seed,
            p: self.p,
            keep: self.keep,
            counter: Counter {
                progress: self.counter.progress,
                state: Mutex::new(*self.counter.state.lock().unwrap_or_else(|e| e.into_inner())),
            },
            peak_kept: AtomicUsize::new(0),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_distr::{Distribution as _, StandardNormal};

    /// `outputs` independent normal outputs around 0.
    struct Normals(Vec<f64>);

    impl Trial for Normals {
        type Scratch = ();
        fn outputs(&self) -> usize {
            self.0.len()
        }
        fn centre(&self) -> &[f64] {
            &self.0
        }
        fn scratch(&self) {}
        fn draw<R: Rng + ?Sized>(
            &self,
            rng: &mut R,
            _: &mut (),
            out: &mut [f64],
        ) -> Result<(), TrialFailure> {
            for o in out.iter_mut() {
                *o = StandardNormal.sample(rng);
            }
            Ok(())
        }
        fn inputs(&self, _: &()) -> Vec<f64> {
            Vec::new()
        }
    }

    /// The values kept inside the brackets never exceed what [`memory_needed`] counts for
    /// them, and the estimate grows with the trials far slower than trials × outputs.
    #[test]
    fn the_memory_estimate_bounds_the_values_kept() {
        for (outputs, m) in [(2_000, 60_000), (40, 250_000), (3, 7_000)] {
            let trial = Normals(vec![0.0; outputs]);
            let engine = Engine {
                trial: &trial,
                seed: 9,
                p: 0.95,
                keep: false,
                counter: Counter::new(None),
                peak_kept: AtomicUsize::new(0),
            };
            engine.fixed(m).unwrap();
            let kept_bytes = 16 * engine.peak_kept.load(Ordering::Relaxed) as u128;
            let pilot = pilot_len(m, outputs, 0.95);
            let estimate = memory_needed(m, outputs, false, 0.95);
            let bracket_bytes = estimate
                - 8 * pilot as u128 * outputs as u128
                - super::super::statistics::COLUMN_BYTES as u128;
            // the estimate counts the values twice (while they are bucketed)
            assert!(
                2 * kept_bytes <= bracket_bytes,
                "{outputs} outputs, {m} trials: kept {kept_bytes} B, estimated {bracket_bytes} B"
            );
            if outputs == 2_000 {
                // a quarter of every value's 8 bytes, pilot included
                assert!(estimate < (8 * m * outputs / 4) as u128, "{estimate}");
            }
        }
    }
}
