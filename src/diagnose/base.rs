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

use std::borrow::Cow;

use super::geometry::FitGeometry;
use crate::measurement::{MeasurementSet, Sigma};
use crate::solve::sub_pitch::{self, ShiftGeometry, SubPitchSolution};
use crate::solve::{Solution, SolveError, least_squares_with_regressors};

/// The base model of a diagnosis (module documentation).
#[derive(Debug, Clone)]
pub struct Base<'a> {
    /// The readings in encoder positions (the set itself without shifts).
    positions: Cow<'a, MeasurementSet>,
    /// The columns always in the model: the sub-pitch cosets' differences.
    columns: Vec<Vec<f64>>,
    /// Where the mountings put the encoder, with shifted mountings.
    shifts: Option<ShiftGeometry>,
}

impl<'a> Base<'a> {
    /// The base model of `set` (readings as in the file, in time order).
    pub fn of(set: &'a MeasurementSet) -> Base<'a> {
        if !set.has_shifts() {
            return Base {
                positions: Cow::Borrowed(set),
                columns: Vec::new(),
                shifts: None,
            };
        }
        let geometry = ShiftGeometry::of(set);
        let columns = sub_pitch::coset_columns(&geometry, set);
        Base {
            positions: Cow::Owned(geometry.encoder_set(set)),
            columns,
            shifts: Some(geometry),
        }
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

    /// The base columns followed by `terms` (the columns of the diagnosis's terms).
    pub fn with(&self, terms: &[Vec<f64>]) -> Vec<Vec<f64>> {
        if self.columns.is_empty() {
            return terms.to_vec();
        }
        let mut all = self.columns.clone();
        all.extend(terms.iter().cloned());
        all
    }

    /// The fit of the base model with the columns `terms`.
    ///
    /// # Errors
    ///
    /// The solver's, as [`least_squares_with_regressors`].
    pub fn fit(&self, terms: &[Vec<f64>], sigma: Option<Sigma>) -> Result<Solution, SolveError> {
        if self.columns.is_empty() {
            least_squares_with_regressors(&self.positions, terms, sigma)
        } else {
            least_squares_with_regressors(&self.positions, &self.with(terms), sigma)
        }
    }

    /// The fit of the base model to `values` in place of the readings (one per reading).
    ///
    /// # Errors
    ///
    /// The solver's.
    pub fn fit_values(&self, values: &[f64]) -> Result<Solution, SolveError> {
        let mut as_readings = self.positions.clone().into_owned();
        for (r, v) in as_readings.readings.iter_mut().zip(values) {
            r.reading_arcsec = *v;
        }
        least_squares_with_regressors(&as_readings, &self.columns, None)
    }

    /// The hat-matrix geometry of `fit`, a fit with the columns `terms`.
    pub fn geometry(&self, fit: &Solution, terms: &[Vec<f64>]) -> FitGeometry {
        FitGeometry::new(fit, &self.positions, &self.with(terms))
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
