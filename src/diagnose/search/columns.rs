//! The column cache of a search: a term's column is the same in every round, so it is
//! formed once.

use rayon::prelude::*;

use crate::diagnose::candidates::Term;
use crate::diagnose::geometry::dot;
use crate::effects::EffectContext;
use crate::measurement::MeasurementSet;

/// Terms whose columns one task forms ([`Columns::form`]): enough that a task reads the
/// readings for several columns at once, few enough that a round's columns (tens of
/// terms) keep both threads busy.
const FORMED_TOGETHER: usize = 4;

/// The columns of the terms met so far in a search: a term's column is the same in every
/// round, so it is formed once.
pub(super) struct Columns<'s> {
    pub set: &'s MeasurementSet,
    pub context: &'s EffectContext,
    /// (term, its column, xᵀx).
    pub known: Vec<(Term, Vec<f64>, f64)>,
}

impl Columns<'_> {
    /// The column of `term`.
    pub fn column(&mut self, term: &Term) -> &[f64] {
        let index = match self.known.iter().position(|(t, ..)| t == term) {
            Some(index) => index,
            None => {
                let column = term.column(self.set, self.context);
                let length_squared = dot(&column, &column);
                self.known.push((term.clone(), column, length_squared));
                self.known.len() - 1
            }
        };
        &self.known[index].1
    }

    /// Forms the columns of `terms` not formed yet, in one pass over the readings
    /// ([`Term::columns`]).
    pub fn form<'t>(&mut self, terms: impl Iterator<Item = &'t Term>) {
        let mut missing: Vec<Term> = Vec::new();
        for term in terms {
            if !self.known.iter().any(|(t, ..)| t == term) && !missing.contains(term) {
                missing.push(term.clone());
            }
        }
        // a few terms to a task, side by side (each task reads the readings once for its
        // terms: [`Term::columns`])
        let columns: Vec<(Vec<f64>, f64)> = missing
            .par_chunks(FORMED_TOGETHER)
            .flat_map_iter(|terms| Term::columns(terms, self.set, self.context))
            .map(|column| {
                let length_squared = dot(&column, &column);
                (column, length_squared)
            })
            .collect();
        self.known.extend(
            missing
                .into_iter()
                .zip(columns)
                .map(|(term, (column, length_squared))| (term, column, length_squared)),
        );
    }

    /// The columns of `terms`, formed before ([`Columns::column`]), in their order
    /// (none for a term not formed).
    pub fn columns(&self, terms: &[Term]) -> Vec<&[f64]> {
        terms
            .iter()
            .filter_map(|t| {
                self.known
                    .iter()
                    .find(|(k, ..)| k == t)
                    .map(|(_, c, _)| c.as_slice())
            })
            .collect()
    }

    /// The column of `term` and its xᵀx, formed before.
    pub fn with_length(&self, term: &Term) -> Option<(&[f64], f64)> {
        self.known
            .iter()
            .find(|(k, ..)| k == term)
            .map(|(_, c, l)| (c.as_slice(), *l))
    }

    /// The columns of `terms`, in their order.
    pub fn of(&mut self, terms: &[Term]) -> Vec<Vec<f64>> {
        terms.iter().map(|t| self.column(t).to_vec()).collect()
    }
}
