//! The coset engine: least squares for sub-pitch mountings in near-linear time.
//!
//! Mountings between the positions put the encoder at C cosets of N table angles
//! ([`super::sub_pitch`]), each with encoder errors α_c of its own (Σα_c = 0); the
//! polygon and the setup errors are shared:
//!
//! ```text
//! reading = α_{c(s)}[q] + φ′[(q + d_s) mod N] + U′_s + noise,
//! ```
//!
//! q the reading's position in its coset and d_s its stream's face offset. In its own
//! positions every coset is a closure design with the circular structure of the regular
//! one, so the unknowns g = [α_0, …, α_{C−1}, φ′, U′] have a block-circulant normal
//! matrix wherever every stream reads every position of its coset equally often (w_s
//! times): harmonic k ≠ 0 couples only α̂_0(k), …, α̂_{C−1}(k) and φ̂′(k), a (C + 1) ×
//! (C + 1) Hermitian block whose inverse is written out in `base`; the setup errors live
//! at k = 0 alone. That is the regular part's cofactor B, in the gauge Σα_c = 0 (every
//! c), Σφ′ = 0.
//!
//! What breaks the symmetry is the circulant engine's ([`super::circulant`]) low-rank
//! correction: a (stream, position) cell read n_sp ≠ w_s times (closing readings, missing
//! or repeated readings) adds (n_sp − w_s)·x xᵀ to the normal matrix, x its design row,
//! and by Woodbury in the constrained parametrisation
//!
//! ```text
//! Q_g = B − B V (D⁻¹ + Vᵀ B V)⁻¹ Vᵀ B = B + W M Wᵀ,   W = B V,   M = −(D⁻¹ + Vᵀ B V)⁻¹,
//! ```
//!
//! g = Q_g Xᵀy, refined by one step on the residuals. The cofactor stays an operator
//! ([`super::Cofactor`]: entries, diagonal, products; `operator`), reported in the
//! effect-column path's θ — β, α_0, U and the differences δ_c = α_c − α_0 — so that
//! [`super::sub_pitch::SubPitchSolution`] is the same whichever engine ran. The work is
//! O((C + 1)² N + (C + 1) N log N) for the regular part and O(L·r + r³) for r
//! corrections (L = (C + 1)·N + K), against O(((C − 1)·N)³) for the differences as
//! effect columns.
//!
//! The engine does not serve a design whose structure breaks — a stream that reads most
//! positions of its coset zero times, a position of a coset nobody reads, harmonics no
//! coset can see, more corrections than a quarter of the unknowns (the circulant
//! engine's rule), a singular capacitance — nor a reading whose face contradicts its
//! stream's offset; the caller then fits the differences as effect columns, which name
//! what is lost.

mod base;
pub(crate) mod operator;

use self::base::{CosetBase, CosetStream};
use self::operator::CosetStructured;
use super::shift_geometry::ShiftGeometry;
use super::{
    Cofactor, Engine, Method, ParameterLayout, SetupError, Solution, SolveError, woodbury,
};
use crate::measurement::{MeasurementSet, Reading, Sigma};
use crate::polygon::face_deviation_from_pitch;

/// A sub-pitch design the coset engine serves: its regular part and the cells that
/// differ.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CosetPlan {
    faces: usize,
    cosets: usize,
    /// The regular part of each stream (coset, face offset, readings per position).
    streams: Vec<CosetStream>,
    /// (stream, position, n_sp − w_s) for every cell read a different number of times.
    corrections: Vec<(usize, usize, f64)>,
}

impl CosetPlan {
    /// The length L = (C + 1)·N + K of g.
    fn len(&self) -> usize {
        (self.cosets + 1) * self.faces + self.streams.len()
    }

    /// The rank r of the low-rank part: the corrections.
    pub(crate) fn rank(&self) -> usize {
        self.corrections.len()
    }

    /// The circulant engine's rule: at most a quarter of the unknowns (or 16) corrected.
    pub(crate) fn is_cheaper_than_dense(&self) -> bool {
        self.rank() <= (self.len() / 4).max(16)
    }

    /// Bytes the engine and `solve_shifted` need beyond the set they are given: the set
    /// in encoder positions and, per reading, its design row, stream, coset and residual
    /// (twice); the plan's counts; B ([`CosetBase::bytes_needed`]) and a product's FFT
    /// buffers; W, W·M and B·V (L·r each), the capacitance, its LU and inverse (r² each);
    /// g, Xᵀy, the gradient and a product (L each); the solution and the encoder errors
    /// at every table angle with their u (a few C·N), and θ-long vectors for u(α) of the
    /// last position of every coset.
    pub(crate) fn bytes_needed(&self, readings: usize) -> u128 {
        let n = self.faces as u128;
        let c = self.cosets as u128;
        let k = self.streams.len() as u128;
        let len = self.len() as u128;
        let r = self.rank() as u128;
        let theta = 2 * n + k + c.saturating_sub(1) * n;
        let per_reading = std::mem::size_of::<Reading>() as u128 + 8 * (3 + 1 + 1 + 2);
        per_reading * readings as u128
            + 4 * k * n
            + 24 * k * n
            + CosetBase::bytes_needed(self.faces, self.cosets, self.streams.len())
            + 2 * 16 * (c + 1) * n
            + 8 * (3 * len * r + 5 * r * r + 6 * len + 8 * (c + 1) * n + 6 * theta)
    }
}

/// Plans the coset engine for the set in encoder positions ([`ShiftGeometry::encoder_set`])
/// and its `streams`: `None` when the structure breaks (module documentation).
pub(crate) fn plan(
    positions: &MeasurementSet,
    geometry: &ShiftGeometry,
    streams: &[(u32, u32)],
) -> Option<CosetPlan> {
    let n = positions.faces;
    let k = streams.len();
    let cosets = geometry.cosets();
    if n < 2 || k == 0 {
        return None;
    }
    let offsets: Vec<usize> = positions
        .face_offsets()
        .into_iter()
        .map(|(_, d)| d)
        .collect();
    if offsets.len() != k {
        return None;
    }
    let stream_coset: Vec<usize> = streams
        .iter()
        .map(|&(setup, _)| geometry.mounting(setup).map_or(0, |m| m.coset))
        .collect();
    let mut count = vec![0u32; k * n];
    for r in &positions.readings {
        let s = streams.binary_search(&(r.setup, r.ac)).ok()?;
        let p = r.position(n);
        if r.face == 0 || r.face > n || (p + offsets[s]) % n != r.face - 1 {
            return None;
        }
        count[s * n + p] += 1;
    }
    // every position of every coset read by one of its streams
    for c in 0..cosets {
        let unread = (0..n).any(|p| {
            (0..k)
                .filter(|&s| stream_coset[s] == c)
                .all(|s| count[s * n + p] == 0)
        });
        if unread {
            return None;
        }
    }
    // a harmonic k is lost when every coset sees it in one phase: when the period
    // N/gcd(N, its offset differences) of every coset divides k
    let mut common_period = 1usize;
    for c in 0..cosets {
        let mut offsets_of = (0..k).filter(|&s| stream_coset[s] == c).map(|s| offsets[s]);
        let first = offsets_of.next()?;
        let g = offsets_of.fold(n, |g, d| gcd(g, (d + n - first) % n));
        let period = n / g;
        common_period = common_period / gcd(common_period, period) * period;
    }
    if common_period < n {
        return None;
    }
    let mut plan_streams = Vec::with_capacity(k);
    let mut corrections = Vec::new();
    for s in 0..k {
        // the regular weight as the circulant engine's plan
        let mode = woodbury::regular_weight(s, &count[s * n..(s + 1) * n], &mut corrections);
        if mode == 0 {
            return None;
        }
        plan_streams.push(CosetStream {
            coset: stream_coset[s],
            offset: offsets[s],
            weight: f64::from(mode),
        });
    }
    Some(CosetPlan {
        faces: n,
        cosets,
        streams: plan_streams,
        corrections,
    })
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// Solves the planned sub-pitch design: the set in encoder positions, its `streams` and
/// the `plan`. `Ok(None)` when the corrections make the system singular (missing
/// readings): the caller then fits the differences as effect columns, which name what is
/// lost. The solution is in the effect-column path's θ (module documentation): its
/// effect values are δ_c\[q\], q = 0 … N−2, of cosets 1 … C−1, whose columns it never
/// forms (`effect_regressors` is empty).
pub(crate) fn solve(
    positions: &MeasurementSet,
    streams: &[(u32, u32)],
    plan: &CosetPlan,
    stated_sigma: Option<Sigma>,
) -> Result<Option<Solution>, SolveError> {
    let n = plan.faces;
    let cosets = plan.cosets;
    let k = streams.len();
    let len = plan.len();
    let (phi, setup) = (cosets * n, (cosets + 1) * n);
    let Some(base) = CosetBase::new(n, cosets, &plan.streams) else {
        return Ok(None);
    };

    // each stream's mean out of its readings first (U′ absorbs it exactly)
    let mut stream_sum = vec![0.0; k];
    let mut stream_count = vec![0usize; k];
    let mut reading_stream = Vec::with_capacity(positions.readings.len());
    for r in &positions.readings {
        let Ok(s) = streams.binary_search(&(r.setup, r.ac)) else {
            return Ok(None);
        };
        stream_sum[s] += r.reading_arcsec;
        stream_count[s] += 1;
        reading_stream.push(s);
    }
    let stream_mean: Vec<f64> = stream_sum
        .iter()
        .zip(&stream_count)
        .map(|(sum, &count)| sum / count.max(1) as f64)
        .collect();

    // Xᵀy and the design rows
    let mut b = vec![0.0; len];
    let mut rows = Vec::with_capacity(positions.readings.len());
    for (r, &s) in positions.readings.iter().zip(&reading_stream) {
        let row = [
            plan.streams[s].coset * n + r.position(n),
            phi + r.face - 1,
            setup + s,
        ];
        rows.push(row);
        let y = r.reading_arcsec - stream_mean[s];
        for &a in &row {
            b[a] += y;
        }
    }

    // Woodbury: W = B V, C1 = D⁻¹ + Vᵀ B V
    let cells: Vec<([usize; 3], f64)> = plan
        .corrections
        .iter()
        .map(|&(s, p, d)| {
            let stream = plan.streams[s];
            (
                [
                    stream.coset * n + p,
                    phi + (p + stream.offset) % n,
                    setup + s,
                ],
                d,
            )
        })
        .collect();
    let Some((w, capacitance_inverse)) =
        woodbury::cell_correction(len, &cells, |a, b| base.entry(a, b))
    else {
        return Ok(None);
    };
    let structured = CosetStructured::new(base, w, &(-capacitance_inverse));

    // g = Q_g Xᵀy, and one step of iterative refinement on the residuals' gradient
    let mut g = structured.apply(&b);
    let model_residual = |g: &[f64], out: &mut Vec<f64>| {
        out.clear();
        out.extend(
            positions
                .readings
                .iter()
                .zip(&rows)
                .zip(&reading_stream)
                .map(|((reading, row), &s)| {
                    let model: f64 = row.iter().map(|&a| g[a]).sum();
                    (reading.reading_arcsec - stream_mean[s]) - model
                }),
        );
    };
    let mut residuals = Vec::with_capacity(positions.readings.len());
    model_residual(&g, &mut residuals);
    let mut gradient = vec![0.0; len];
    for (e, row) in residuals.iter().zip(&rows) {
        for &a in row {
            gradient[a] += e;
        }
    }
    for (g, d) in g.iter_mut().zip(structured.apply(&gradient)) {
        *g += d;
    }
    model_residual(&g, &mut residuals);

    // θ in the reported gauge: φ = φ′ − φ′_N, U = U′ + mean + φ′_N, δ_c = α_c − α_0
    let phi_last = g[phi + n - 1];
    let pitch_deviation: Vec<f64> = (0..n)
        .map(|i| g[phi + i] - g[phi + (i + n - 1) % n])
        .collect();
    let face_deviation = face_deviation_from_pitch(&pitch_deviation);
    let encoder_error = g[..n].to_vec();
    let effect_values: Vec<f64> = (1..cosets)
        .flat_map(|c| (0..n - 1).map(move |q| (c, q)))
        .map(|(c, q)| g[c * n + q] - g[q])
        .collect();
    let setup_values: Vec<f64> = (0..k)
        .map(|s| g[setup + s] + stream_mean[s] + phi_last)
        .collect();
    let rss: f64 = residuals.iter().map(|v| v * v).sum();
    let e = effect_values.len();
    let dof = positions.readings.len().saturating_sub(2 * n - 2 + k + e);
    let layout = ParameterLayout {
        faces: n,
        setups: k,
        effects: e,
    };
    Ok(Some(Solution {
        faces: n,
        method: Method::LeastSquares,
        engine: Engine::CosetCirculant {
            cosets,
            low_rank: plan.corrections.len(),
        },
        pitch_deviation,
        face_deviation,
        encoder_error,
        setup_error: streams
            .iter()
            .zip(setup_values)
            .map(|(&(setup, ac), value)| SetupError { setup, ac, value })
            .collect(),
        effect_values,
        effect_regressors: Vec::new(),
        residuals,
        readings: positions.readings.len(),
        dof,
        rss,
        sigma: super::choose_sigma(rss, dof, stated_sigma),
        cofactor: Cofactor::cosets(layout, structured),
        layout,
        incomplete_cycles: Vec::new(),
    }))
}
