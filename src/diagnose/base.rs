//! The base model a diagnosis fits: `solve`'s closure model in encoder positions.
//!
//! Without shifted mountings the readings are fitted as they are. With shifted mountings
//! (a `shift` column) the one place that knows where a shift puts the encoder,
//! [`crate::solve::sub_pitch`], gives the set in encoder positions
//! ([`ShiftGeometry::encoder_set`]) and, for sub-pitch mountings, the differences of the
//! cosets' encoder errors as columns that are always in the model
//! ([`sub_pitch::coset_columns`]). The candidate terms keep the readings as the file has
//! them (its steps, in time order), so that every effect found names the stop the file
//! names; only the fits and the hat-matrix geometry see the encoder positions. A term j
//! of the diagnosis is then effect column `offset() + j` of every fit.
//!
//! A self-calibration ([`Base::self_calibration`]) is diagnosed on its closure model
//! (the disc as the polygon, the heads as the autocollimators: `selfcal`'s
//! `closure_set`). Its table error is a nuisance at every stop of every cycle: the
//! closure model holds one per step, and the rest is taken out exactly by fitting the
//! readings and the terms minus their stop's mean ([`StopNuisance`]).
//! The harmonics the head layout cannot see are set to zero, as `selfcal::solve` does,
//! and a term is judged by what a self-calibration certifies: the disc's encoder error
//! e = φ − φ̄ and the heads' errors c_j − c_1 ([`Base::calibrated`]), not the table's
//! nuisance. When some head sits between the positions
//! (`Base::self_calibration_off_grid`) the closure model is the band-limited one
//! `selfcal` solves such heads with (`OffGridDesign`): its fits and its geometry go
//! through that design, the rest of the diagnosis is the same.

use std::borrow::Cow;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use super::geometry::FitGeometry;
use super::lack_of_fit::{LackOfFit, PureError};
use super::nuisance::StopNuisance;
use crate::measurement::{MeasurementSet, Sigma};
use crate::progress::Progress;
use crate::selfcal::OffGridDesign;
use crate::solve::circulant::Prepared;
use crate::solve::least_squares::{least_squares_prepared, least_squares_zeroing_lost_with};
use crate::solve::sub_pitch::{self, ShiftGeometry, SubPitchSolution};
use crate::solve::{Solution, SolveError, SolveOptions};

/// The progress of a diagnosis as its observer is told it ([`super::DiagnoseOptions::progress`]):
/// the rounds of the forward selection done, with no total (the search ends when nothing
/// significant remains), told again after every fit and geometry so that a spinner moves
/// while a round, the doubt and the identifiability checks run.
#[derive(Clone, Default)]
pub(crate) struct Ticker {
    observer: Option<Arc<dyn Progress + Send>>,
    rounds: Arc<AtomicU64>,
}

impl std::fmt::Debug for Ticker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ticker")
            .field("observer", &self.observer.as_ref().map(|_| "observer"))
            .field("rounds", &self.rounds.load(Ordering::Relaxed))
            .finish()
    }
}

impl Ticker {
    /// Tells the observer, if any, the rounds done so far.
    pub(crate) fn tick(&self) {
        if let Some(observer) = &self.observer {
            observer.update(self.rounds.load(Ordering::Relaxed), None);
        }
    }

    /// One more round of the forward selection done.
    pub(crate) fn round_done(&self) {
        self.rounds.fetch_add(1, Ordering::Relaxed);
        self.tick();
    }
}

/// The most encoder positions of a design a diagnosis fits by weighted least squares
/// ([`Base::with_weights`]): beyond, the dense path's cost at every fit of the search is
/// too high, and the fits stay unweighted (with a note).
pub const WEIGHTED_MAX_POSITIONS: usize = 360;

/// The base model of a diagnosis (module documentation).
#[derive(Debug, Clone)]
pub struct Base<'a> {
    /// The readings in encoder positions (the set itself without shifts).
    positions: Cow<'a, MeasurementSet>,
    /// The columns always in the model: the sub-pitch cosets' differences.
    columns: Vec<Vec<f64>>,
    /// Where the mountings put the encoder, with shifted mountings.
    shifts: Option<ShiftGeometry>,
    /// A self-calibration's table error at every stop, taken out of the readings and the
    /// terms (the lost harmonics set to zero, e and the heads' errors certified).
    nuisance: Option<StopNuisance>,
    /// A self-calibration's band-limited closure design, when some head sits between the
    /// positions (the fits and the geometry go through it).
    off_grid: Option<Arc<OffGridDesign>>,
    /// Whether the geometry is the dense reference's whatever the fit's cofactor.
    dense_geometry: bool,
    /// A weighted diagnosis's whitening factors, one per reading ([`Base::with_weights`]).
    weights: Option<Arc<[f64]>>,
    /// Told after every fit and geometry.
    ticker: Ticker,
    /// The lack-of-fit test's cells and centred readings, formed at its first test (the
    /// same for every fit of one diagnosis).
    pure_error: OnceLock<Option<PureError>>,
    /// The geometry of the base fit, formed at its first use: every geometry of the
    /// diagnosis adds its terms to it.
    base_geometry: OnceLock<FitGeometry>,
    /// The design planned for the circulant engine once, with its regular cofactor,
    /// for every fit of the base model with terms (plain and whole-face runs).
    prepared: OnceLock<Option<Prepared>>,
}

impl<'a> Base<'a> {
    /// The base model of `set` (readings as in the file, in time order).
    pub fn of(set: &'a MeasurementSet) -> Base<'a> {
        if !set.has_shifts() {
            return Base {
                positions: Cow::Borrowed(set),
                columns: Vec::new(),
                shifts: None,
                nuisance: None,
                off_grid: None,
                dense_geometry: false,
                weights: None,
                ticker: Ticker::default(),
                pure_error: OnceLock::new(),
                base_geometry: OnceLock::new(),
                prepared: OnceLock::new(),
            };
        }
        let geometry = ShiftGeometry::of(set);
        let columns = sub_pitch::coset_columns(&geometry, set);
        Base {
            positions: Cow::Owned(geometry.encoder_set(set)),
            columns,
            shifts: Some(geometry),
            nuisance: None,
            off_grid: None,
            dense_geometry: false,
            weights: None,
            ticker: Ticker::default(),
            pure_error: OnceLock::new(),
            base_geometry: OnceLock::new(),
            prepared: OnceLock::new(),
        }
    }

    /// The base model of a self-calibration's closure set (module documentation): the
    /// table's error at every stop taken out exactly ([`StopNuisance`]): the readings and
    /// every term's column are fitted minus their stop's mean.
    pub fn self_calibration(closure: &'a MeasurementSet) -> Base<'a> {
        let nuisance = StopNuisance::of(closure);
        let values: Vec<f64> = closure.readings.iter().map(|r| r.reading_arcsec).collect();
        let mut projected = closure.clone();
        for (r, v) in projected.readings.iter_mut().zip(nuisance.project(&values)) {
            r.reading_arcsec = v;
        }
        Base {
            positions: Cow::Owned(projected),
            columns: Vec::new(),
            shifts: None,
            nuisance: Some(nuisance),
            off_grid: None,
            dense_geometry: false,
            weights: None,
            ticker: Ticker::default(),
            pure_error: OnceLock::new(),
            base_geometry: OnceLock::new(),
            prepared: OnceLock::new(),
        }
    }

    /// The base model of a self-calibration whose heads are not all on the position grid:
    /// as [`Base::self_calibration`], with `design` (the band-limited closure design of
    /// `closure`'s readings) in place of the closure engine. The dense geometry is not
    /// offered for it.
    pub(crate) fn self_calibration_off_grid(
        closure: &'a MeasurementSet,
        design: OffGridDesign,
    ) -> Base<'a> {
        let mut base = Self::self_calibration(closure);
        base.off_grid = Some(Arc::new(design));
        base
    }

    /// This base model with the dense geometry ([`FitGeometry::dense`]) whatever the
    /// fits' cofactors: the reference the structured geometry is tested against.
    pub fn with_dense_geometry(mut self, dense: bool) -> Self {
        self.dense_geometry = dense;
        self
    }

    /// This base model with a progress observer, told the forward selection's rounds done
    /// after every fit and geometry ([`super::DiagnoseOptions::progress`]).
    pub fn with_progress(mut self, observer: Option<Arc<dyn Progress + Send>>) -> Self {
        self.ticker = Ticker {
            observer,
            rounds: Arc::default(),
        };
        self
    }

    /// This base model fitted by weighted least squares: reading i weighs `weights[i]`²
    /// (`weights[i]` = σ_ref/σ of its noise group), every fit and geometry in whitened
    /// quantities (the readings, the base columns and the residuals times wᵢ; the terms'
    /// columns come whitened from an [`crate::effects::EffectContext`] with the same
    /// weights). The fits go through the dense reference solver
    /// ([`crate::solve::dense::dense_weighted_least_squares`]). `None` when the weights do
    /// not fit the readings, for a self-calibration (its stop nuisance is unweighted), and
    /// for designs of more than [`WEIGHTED_MAX_POSITIONS`] positions (the dense path's
    /// cost at every fit of a search).
    pub fn with_weights(&self, weights: Arc<[f64]>) -> Option<Base<'a>> {
        if weights.len() != self.positions.readings.len()
            || weights.iter().any(|w| !(w.is_finite() && *w > 0.0))
            || self.nuisance.is_some()
            || self.off_grid.is_some()
            || self.positions.faces > WEIGHTED_MAX_POSITIONS
        {
            return None;
        }
        let columns = self
            .columns
            .iter()
            .map(|x| x.iter().zip(weights.iter()).map(|(x, w)| x * w).collect())
            .collect();
        Some(Base {
            positions: self.positions.clone(),
            columns,
            shifts: self.shifts.clone(),
            nuisance: None,
            off_grid: None,
            dense_geometry: self.dense_geometry,
            weights: Some(weights),
            ticker: self.ticker.clone(),
            pure_error: OnceLock::new(),
            base_geometry: OnceLock::new(),
            prepared: OnceLock::new(),
        })
    }

    /// The whitening factors of a weighted base model ([`Base::with_weights`]).
    pub fn weights(&self) -> Option<&Arc<[f64]>> {
        self.weights.as_ref()
    }

    /// The progress of the diagnosis fitted with this base model.
    pub(crate) fn ticker(&self) -> &Ticker {
        &self.ticker
    }

    /// Whether this is a self-calibration's band-limited closure model (some head between
    /// the positions).
    pub fn is_off_grid(&self) -> bool {
        self.off_grid.is_some()
    }

    /// Whether this is a self-calibration's closure model.
    pub fn is_self_calibration(&self) -> bool {
        self.nuisance.is_some()
    }

    /// The two families a term is judged by (docs/FORMAT.md §5.2 `changes_calibration`):
    /// β and α of a polygon run; for a self-calibration, the disc's encoder error
    /// e = φ − φ̄ and the heads' errors c_j − c_1 (j = 2 … M).
    pub fn calibrated(&self, fit: &Solution) -> [Vec<f64>; 2] {
        if !self.is_self_calibration() {
            return [fit.pitch_deviation.clone(), fit.encoder_error.clone()];
        }
        let mean = fit.face_deviation.iter().sum::<f64>() / fit.face_deviation.len() as f64;
        let e = fit.face_deviation.iter().map(|phi| phi - mean).collect();
        let heads = match fit.setup_error.split_first() {
            Some((first, rest)) => rest.iter().map(|s| s.value - first.value).collect(),
            None => Vec::new(),
        };
        [e, heads]
    }

    /// The standard uncertainties of [`Base::calibrated`], when σ is known.
    pub fn calibrated_u(&self, fit: &Solution) -> [Option<Vec<f64>>; 2] {
        if !self.is_self_calibration() {
            return [fit.pitch_deviation_u(), fit.encoder_error_u()];
        }
        let Some((sigma, _)) = fit.sigma else {
            return [None, None];
        };
        let q = &fit.cofactor;
        let e = q
            .centered_face_deviation_diagonal()
            .into_iter()
            .map(|v| sigma * v.max(0.0).sqrt())
            .collect();
        let first = fit.layout.setup(0);
        let heads = (1..fit.layout.setups)
            .map(|j| {
                let a = fit.layout.setup(j);
                let var = q.entry(a, a) + q.entry(first, first) - 2.0 * q.entry(a, first);
                sigma * var.max(0.0).sqrt()
            })
            .collect();
        [Some(e), Some(heads)]
    }

    /// The readings in encoder positions.
    pub fn positions(&self) -> &MeasurementSet {
        &self.positions
    }

    /// The number of columns always in the model before the diagnosis's terms.
    pub fn offset(&self) -> usize {
        self.columns.len()
    }

    /// Whether the mountings are shifted.
    pub fn shifted(&self) -> bool {
        self.shifts.is_some()
    }

    /// Whether some mounting stands between the positions (sub-pitch cosets).
    pub fn sub_pitch(&self) -> bool {
        self.shifts
            .as_ref()
            .is_some_and(ShiftGeometry::is_sub_pitch)
    }

    /// The columns a fit holds: the base columns followed by `terms` (the columns of the
    /// diagnosis's terms; for a self-calibration, each minus its stop's mean).
    /// `terms` themselves when that is all a fit holds (no copy).
    pub fn with<'t>(&self, terms: &'t [Vec<f64>]) -> Cow<'t, [Vec<f64>]> {
        if let Some(n) = &self.nuisance {
            return Cow::Owned(terms.iter().map(|x| n.project(x)).collect());
        }
        if self.columns.is_empty() {
            return Cow::Borrowed(terms);
        }
        let mut all = self.columns.clone();
        all.extend(terms.iter().cloned());
        Cow::Owned(all)
    }

    /// A fit of the positions' readings with the columns `all` (of [`Base::with`]); for a
    /// self-calibration the lost harmonics set to zero and the stop nuisance's degrees of
    /// freedom taken off.
    fn fit_columns(&self, all: &[Vec<f64>], sigma: Option<Sigma>) -> Result<Solution, SolveError> {
        if let Some(weights) = &self.weights {
            return crate::solve::dense::dense_weighted_least_squares(
                &self.positions,
                all,
                weights,
                sigma,
            );
        }
        let Some(n) = &self.nuisance else {
            let prepared = self
                .prepared
                .get_or_init(|| Prepared::of(&self.positions))
                .as_ref();
            let options = SolveOptions::new().with_sigma_opt(sigma);
            return least_squares_prepared(&self.positions, prepared, all, &options);
        };
        let mut fit = match &self.off_grid {
            Some(design) => {
                let values: Vec<f64> = self
                    .positions
                    .readings
                    .iter()
                    .map(|r| r.reading_arcsec)
                    .collect();
                design.fit(&values, all, sigma)?
            }
            None => {
                let options = SolveOptions::new().with_sigma_opt(sigma);
                least_squares_zeroing_lost_with(&self.positions, all, &options)?.0
            }
        };
        fit.dof = fit.dof.saturating_sub(n.parameters());
        fit.sigma = crate::solve::choose_sigma(fit.rss, fit.dof, sigma);
        Ok(fit)
    }

    /// The lack-of-fit test of `fit`, a fit of the base model with the columns `terms`,
    /// at false-alarm probability `alpha` ([`lack_of_fit`](super::lack_of_fit::lack_of_fit); for a
    /// self-calibration the pure error is the scatter within cells beyond the table's
    /// error at every stop). `set` is the diagnosis's readings, the same at every call:
    /// its cells are formed at the first.
    pub fn lack_of_fit(
        &self,
        set: &MeasurementSet,
        fit: &Solution,
        terms: &[Vec<f64>],
        alpha: f64,
    ) -> Option<LackOfFit> {
        let nuisance = self.nuisance.as_ref();
        self.pure_error
            .get_or_init(|| PureError::of_weighted(set, nuisance, self.weights.clone()))
            .as_ref()?
            .test(set, fit, &self.with(terms), alpha, nuisance)
    }

    /// The fit of the base model with the columns `terms`.
    ///
    /// # Errors
    ///
    /// The solver's, as [`least_squares_with_regressors`](crate::solve::least_squares_with_regressors).
    pub fn fit(&self, terms: &[Vec<f64>], sigma: Option<Sigma>) -> Result<Solution, SolveError> {
        let fit = self.fit_columns(&self.with(terms), sigma);
        self.ticker.tick();
        fit
    }

    /// The fit of the base model to `values` in place of the readings (one per reading).
    ///
    /// # Errors
    ///
    /// The solver's.
    pub fn fit_values(&self, values: &[f64]) -> Result<Solution, SolveError> {
        let values = match &self.nuisance {
            Some(n) => n.project(values),
            None => values.to_vec(),
        };
        let mut as_readings = self.positions.clone().into_owned();
        for (r, v) in as_readings.readings.iter_mut().zip(values) {
            r.reading_arcsec = v;
        }
        let base = Base {
            positions: Cow::Owned(as_readings),
            columns: self.columns.clone(),
            shifts: None,
            nuisance: self.nuisance.clone(),
            off_grid: self.off_grid.clone(),
            dense_geometry: self.dense_geometry,
            weights: self.weights.clone(),
            ticker: Ticker::default(),
            pure_error: OnceLock::new(),
            base_geometry: OnceLock::new(),
            // the same design: only the readings' values differ
            prepared: self.prepared.clone(),
        };
        let fit = base.fit_columns(&self.columns, None);
        self.ticker.tick();
        fit
    }

    /// The hat-matrix geometry of `fit`, a fit with the columns `terms`: the geometry of
    /// the base fit (formed at the first call, from `fit` when `terms` is empty, else from
    /// a fit of the base model) with the terms' columns added
    /// ([`FitGeometry::with_columns`]), which is the geometry of `fit` to the round-off.
    /// With the dense reference geometry ([`Base::with_dense_geometry`]) it is formed
    /// from `fit` itself, every time.
    pub fn geometry(&self, fit: &Solution, terms: &[Vec<f64>]) -> FitGeometry {
        let geometry = if self.dense_geometry {
            self.geometry_of_fit(fit, terms)
        } else if terms.is_empty() {
            self.base_geometry
                .get_or_init(|| self.geometry_of_fit(fit, terms))
                .clone()
        } else {
            let base = match self.base_geometry.get() {
                Some(base) => Some(base),
                None => self.fit(&[], None).ok().map(|base_fit| {
                    self.base_geometry
                        .get_or_init(|| self.geometry_of_fit(&base_fit, &[]))
                }),
            };
            match base {
                Some(base) => base.with_columns(&self.with_terms_only(terms)),
                None => self.geometry_of_fit(fit, terms),
            }
        };
        self.ticker.tick();
        geometry
    }

    /// The geometry of the base model with the columns `terms`, from the geometry of the
    /// base fit without a fit ([`FitGeometry::with_columns`]; what [`Base::geometry`]
    /// gives for a fit with them). `None` before the base fit's geometry is formed
    /// ([`Base::geometry`] with no terms) or with the dense reference geometry (which
    /// forms every geometry from a fit).
    pub fn geometry_without_fit(&self, terms: &[Vec<f64>]) -> Option<FitGeometry> {
        if self.dense_geometry {
            return None;
        }
        Some(
            self.base_geometry
                .get()?
                .with_columns(&self.with_terms_only(terms)),
        )
    }

    /// `geometry` (of [`Base::geometry_without_fit`]) with the columns `terms` added.
    pub fn add_terms(&self, geometry: &FitGeometry, terms: &[Vec<f64>]) -> FitGeometry {
        geometry.with_columns(&self.with_terms_only(terms))
    }

    /// The residual sum of squares a fit of the base model would leave whose geometry is
    /// `geometry` (of [`Base::geometry_without_fit`]): |(I − H)·y|², equal to the fit's
    /// to the round-off.
    pub fn rss_without_fit(&self, geometry: &FitGeometry) -> f64 {
        let weight = |i: usize| self.weights.as_ref().map_or(1.0, |w| w[i]);
        let readings: Vec<f64> = self
            .positions
            .readings
            .iter()
            .enumerate()
            .map(|(i, r)| weight(i) * r.reading_arcsec)
            .collect();
        geometry
            .residual_of_kept(&readings)
            .iter()
            .map(|e| e * e)
            .sum()
    }

    /// The columns `terms` as the geometry adds them to the base fit's: a
    /// self-calibration's taken within stops, as its fits take them (the same span with
    /// the stop nuisance: the stop means are in the base model).
    fn with_terms_only(&self, terms: &[Vec<f64>]) -> Vec<Vec<f64>> {
        match &self.nuisance {
            Some(n) => terms.iter().map(|x| n.project(x)).collect(),
            None => terms.to_vec(),
        }
    }

    /// The geometry formed from `fit` itself, a fit with the columns `terms`.
    fn geometry_of_fit(&self, fit: &Solution, terms: &[Vec<f64>]) -> FitGeometry {
        let columns = self.with(terms);
        if let Some(weights) = &self.weights {
            return FitGeometry::weighted(fit, &self.positions, &columns, Arc::clone(weights));
        }
        let off_grid = self
            .off_grid
            .as_ref()
            .and_then(|design| FitGeometry::off_grid(fit, Arc::clone(design), &columns));
        off_grid
            .unwrap_or_else(|| FitGeometry::new(fit, &self.positions, &columns))
            .with_nuisance(self.nuisance.clone())
    }

    /// The values of the diagnosis's terms in `fit`.
    pub fn term_values<'s>(&self, fit: &'s Solution) -> &'s [f64] {
        fit.effect_values.get(self.offset()..).unwrap_or(&[])
    }

    /// The standard uncertainties of the diagnosis's terms in `fit`.
    pub fn term_u(&self, fit: &Solution) -> Option<Vec<f64>> {
        fit.effect_u()
            .map(|u| u.get(self.offset()..).unwrap_or(&[]).to_vec())
    }

    /// For sub-pitch mountings: `fit` with the encoder errors at every table angle of
    /// every coset, as `solve` reports them.
    pub fn sub_pitch_solution(&self, fit: &Solution) -> Option<SubPitchSolution> {
        let geometry = self.shifts.as_ref().filter(|g| g.is_sub_pitch())?;
        Some(sub_pitch::from_engine_solution(fit.clone(), geometry))
    }
}
