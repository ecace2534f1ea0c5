//! The systematic blocks of a round scored against its fit: a drift's nested orders
//! share their Gram matrices off the base fit's span, every term's column is read once.

use nalgebra::DMatrix;
use rayon::prelude::*;

use super::columns::Columns;
use crate::diagnose::base::Ticker;
use crate::diagnose::candidates::{Candidate, Family, Term};
use crate::diagnose::geometry::{BlockScore, ColumnScore, FitGeometry, dot};
use crate::effects::Effect;

/// A term's column against a round's fit: xᵀe, xᵀx and its coordinates on the basis of
/// the columns added to the base fit (Uᵀx).
struct TermStats {
    projection: f64,
    length_squared: f64,
    coordinates: Vec<f64>,
}

/// What the systematic blocks of a round are scored with.
pub(super) struct Systematic<'r> {
    pub geometry: &'r FitGeometry,
    /// Every block's columns, formed.
    pub known: &'r Columns<'r>,
    pub residuals: &'r [f64],
    /// The terms of the model.
    pub terms: &'r [Term],
    pub ticker: &'r Ticker,
}

impl Systematic<'_> {
    /// The candidates of the systematic `blocks`, in their order, and the autocollimators
    /// whose cross-talk is untestable against the base model, in the blocks' order (none
    /// when another autocollimator's cross-talk is in the model: it is that term's
    /// alternative then).
    /// A drift's orders are nested blocks: each one's Gram matrix is the leading part of
    /// the longest block it begins; its part off the base fit's span is the same in every
    /// round (formed once, side by side, into `core_grams`), the terms found take theirs
    /// off.
    pub fn candidates(
        &self,
        blocks: &[Vec<Term>],
        core_grams: &mut Vec<(Vec<Term>, DMatrix<f64>)>,
    ) -> (Vec<Candidate>, Vec<u32>) {
        let longest_of = |block: &Vec<Term>| -> Vec<Term> {
            blocks
                .iter()
                .filter(|o| o.len() >= block.len() && o.starts_with(block))
                .max_by_key(|o| o.len())
                .unwrap_or(block)
                .clone()
        };
        let mut missing: Vec<Vec<Term>> = Vec::new();
        for block in blocks {
            let longest = longest_of(block);
            if !core_grams.iter().any(|(terms, _)| *terms == longest) && !missing.contains(&longest)
            {
                missing.push(longest);
            }
        }
        let grams: Vec<DMatrix<f64>> = missing
            .par_iter()
            .map(|block| {
                self.geometry
                    .core_projected_gram(&self.known.columns(block))
            })
            .collect();
        core_grams.extend(missing.into_iter().zip(grams));
        // every term's xᵀe, xᵀx and Uᵀx once (a term is in several nested blocks)
        let mut stats: Vec<(&Term, TermStats)> = Vec::new();
        for term in blocks.iter().flatten() {
            if stats.iter().any(|(t, _)| *t == term) {
                continue;
            }
            let Some((x, length_squared)) = self.known.with_length(term) else {
                continue;
            };
            stats.push((
                term,
                TermStats {
                    projection: dot(x, self.residuals),
                    length_squared,
                    coordinates: self.geometry.added_coordinates(x),
                },
            ));
        }
        let stats_of = |term: &Term| stats.iter().find(|(t, _)| *t == term).map(|(_, s)| s);
        let mut out = Vec::new();
        let mut untestable = Vec::new();
        for block in blocks {
            self.ticker.tick();
            let longest = longest_of(block);
            let Some((_, core_gram)) = core_grams.iter().find(|(terms, _)| *terms == longest)
            else {
                continue;
            };
            let Some(block_stats) = block.iter().map(stats_of).collect::<Option<Vec<_>>>() else {
                continue;
            };
            let m = block.len();
            let coordinates: Vec<&[f64]> = block_stats
                .iter()
                .map(|s| s.coordinates.as_slice())
                .collect();
            let gram = FitGeometry::projected_gram_from_coordinates(
                core_gram.view((0, 0), (m, m)).into_owned(),
                &coordinates,
            );
            if let [term] = block.as_slice() {
                let score = ColumnScore {
                    projection: block_stats[0].projection,
                    new_length_squared: gram[(0, 0)],
                    length_squared: block_stats[0].length_squared,
                };
                if let Term::Effect(Effect::CrossTalk { ac, .. }) = term
                    && score.new_fraction() < 0.1
                {
                    let other_in_model = self
                        .terms
                        .iter()
                        .any(|t| matches!(t, Term::Effect(Effect::CrossTalk { .. })));
                    if !other_in_model {
                        untestable.push(*ac);
                    }
                    continue;
                }
                if score.is_new() {
                    out.push(Candidate::single(term.clone(), Family::Systematic, &score));
                }
            } else {
                let projection =
                    nalgebra::DVector::from_iterator(m, block_stats.iter().map(|s| s.projection));
                let scale = block_stats
                    .iter()
                    .map(|s| s.length_squared)
                    .fold(0.0, f64::max);
                let score = BlockScore::of(projection, scale, gram);
                if score.rank > 0
                    && let Some(c) = Candidate::block(block.clone(), Family::Systematic, &score)
                {
                    out.push(c);
                }
            }
        }
        (out, untestable)
    }
}
