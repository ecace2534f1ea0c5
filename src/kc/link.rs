//! Linking a comparison to another (docs/FORMAT.md §12, "Linking"): an RMO comparison to
//! the CIPM one through the laboratories that took part in both. Per quantity k, each
//! linking laboratory j gives the offset between the two references as the difference of
//! its degrees of equivalence, Δ_jk = d_jk(linked) − d_jk(this); the correction Δ_k is
//! their GLS mean with the covariance of the Δ_jk,
//!
//! ```text
//! C = Cov_linked(d) + Cov_this(d),   Cov(d_j, d_l) = u²(d_j)   (j = l)
//!                                                  = −u_ref²   (both in the reference)
//!                                                  = +u_ref²   (both out of it)
//!                                                  = 0         (one in, one out)
//! Δ_k = aᵀΔ,  a = C⁻¹1 / 1ᵀC⁻¹1,   u²(Δ_k) = 1 / 1ᵀC⁻¹1,
//! χ²_k = (Δ − Δ_k 1)ᵀ C⁻¹ (Δ − Δ_k 1)
//! ```
//!
//! (the covariances of degrees of equivalence against one weighted-mean reference: with
//! v_j the variance of x_j, Cov(x_j − x_ref, x_l − x_ref) = −w'_j v_j − w'_l v_l + u_ref² and
//! w'_j v_j = u_ref² for a laboratory in it; u²(d) and u_ref from each JSON). The link's
//! one test at 5 % is χ² = (N − 1)/N · Σ_k χ²_k with ν = (N − 1)(L − 1) for L linking
//! laboratories — the degrees of equivalence are closed vectors (Σ_k d_jk = 0), and with
//! one u per laboratory that scaling makes the sum over the N quantities exactly the
//! closed vector's χ². Every laboratory i of this comparison is then also given against
//! the linked reference: d_i,linked = d_i + Δ_k, with
//! u² = u²(d_i) + u²(Δ_k) − 2 Σ_j a_j Cov_this(d_i, d_j) (its correlation with the
//! linking laboratories' degrees of equivalence counted), U at k = 2.
//!
//! Angle blocks are not closed: at each block the linking laboratories are those that
//! report it in both comparisons (L_k of them), the link's test is χ² = Σ_k χ²_k with
//! ν = Σ_k (L_k − 1), and a block no laboratory links has no correction (NaN, `null`).
//!
//! Encoder errors that some laboratory reports at only some positions (in this comparison,
//! or a linking laboratory in the other) are linked by `link_positions`: each linking
//! laboratory's offsets with a constant of its own, every d_linked closed over its
//! laboratory's own positions.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use super::{DegreeOfEquivalence, KcError, KeyComparison, VectorTest};

/// The link of a comparison to another: the laboratories in both, the correction per
/// quantity (the linked reference less this one) with its u, and the link's one test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Link {
    /// The linking laboratories (in both comparisons), in this comparison's order.
    pub labs: Vec<String>,
    /// Δ per quantity: what is added to a degree of equivalence of this comparison to
    /// give it against the linked reference, arcseconds.
    pub correction: Vec<f64>,
    /// u(Δ) per quantity, arcseconds.
    pub correction_u: Vec<f64>,
    /// The link's one test at 5 %: whether the linking laboratories agree on the offset
    /// (`None` with one linking laboratory: nothing to test).
    pub vector: Option<VectorTest>,
}

impl Link {
    /// Why the link has no test (`vector` is `None`): one linking laboratory, or linking
    /// laboratories that share too few encoder positions to leave a degree of freedom.
    pub fn untested_reason(&self) -> &'static str {
        untested_reason(self.labs.len())
    }
}

/// Says in `kc`'s notes that it is not linked: the comparisons it was to be linked to hold
/// none of its quantity (its degrees of equivalence are against its own reference only).
pub fn note_not_linked(kc: &mut KeyComparison) {
    kc.notes.push(format!(
        "not linked: the linked comparisons hold none of {}; the degrees of equivalence are \
         against this comparison's own reference only",
        kc.quantity
    ));
}

/// Why a link through `linking` laboratories has no test.
fn untested_reason(linking: usize) -> &'static str {
    if linking == 1 {
        "one linking laboratory: the link is not tested"
    } else {
        "the linking laboratories share too few positions to test the link (no degree of \
         freedom left)"
    }
}

impl KeyComparison {
    /// Whether the degrees of equivalence against the linked reference are closed over
    /// each laboratory's own positions, d + Δ less Δ's mean there: linked encoder errors
    /// that some laboratory (or a pilot's repeat) does not report at every position.
    pub fn linked_over_own_positions(&self) -> bool {
        self.link.is_some()
            && self.wording().is_closed()
            && self
                .degrees_of_equivalence
                .iter()
                .chain(self.pilot.iter().flat_map(|p| &p.degrees_of_equivalence))
                .any(|d| d.d.iter().any(|x| !x.is_finite()))
    }
}

/// One comparison's covariance of the degrees of equivalence of laboratories `a` and `b`
/// at quantity `k` (see the module's documentation).
pub(super) fn doe_covariance(
    kc: &KeyComparison,
    a: &DegreeOfEquivalence,
    b: &DegreeOfEquivalence,
    k: usize,
) -> f64 {
    let u_ref2 = kc.reference_u[k] * kc.reference_u[k];
    if a.lab == b.lab {
        let u = standard_u(a, k);
        return u * u;
    }
    match (a.in_reference, b.in_reference) {
        (true, true) => -u_ref2,
        (false, false) => u_ref2,
        _ => 0.0,
    }
}

/// u(d) of a degree of equivalence at quantity `k`: U/k, k its Welch–Satterthwaite
/// coverage factor where it has one, else 2.
pub(super) fn standard_u(d: &DegreeOfEquivalence, k: usize) -> f64 {
    let factor =
        d.k.as_ref()
            .and_then(|k_of| k_of.get(k))
            .copied()
            .unwrap_or(2.0);
    d.expanded_u[k] / factor
}

/// The degree of equivalence of `lab` in `kc`.
pub(super) fn doe<'a>(kc: &'a KeyComparison, lab: &str) -> Option<&'a DegreeOfEquivalence> {
    kc.degrees_of_equivalence.iter().find(|d| d.lab == lab)
}

/// The link at one quantity: the GLS mean of the offsets and what goes with it.
struct Offset {
    /// Δ_k.
    correction: f64,
    /// u(Δ_k).
    correction_u: f64,
    /// χ²_k of the offsets about Δ_k.
    chi2: f64,
    /// The GLS weights a of the linking laboratories.
    weights: DVector<f64>,
}

/// The offsets d_j(linked) − d_j(this) of the linking laboratories `labs` at quantity `k`,
/// and their GLS mean with the covariance C of the module's documentation.
fn offset_at(
    this: &KeyComparison,
    linked: &KeyComparison,
    labs: &[String],
    k: usize,
) -> Result<Offset, KcError> {
    let l = labs.len();
    let here: Vec<&DegreeOfEquivalence> = labs.iter().filter_map(|n| doe(this, n)).collect();
    let there: Vec<&DegreeOfEquivalence> = labs.iter().filter_map(|n| doe(linked, n)).collect();
    if l == 0 || here.len() != l || there.len() != l {
        return Ok(Offset {
            correction: f64::NAN,
            correction_u: f64::NAN,
            chi2: 0.0,
            weights: DVector::zeros(0),
        });
    }
    let c = DMatrix::from_fn(l, l, |i, j| {
        doe_covariance(linked, there[i], there[j], k) + doe_covariance(this, here[i], here[j], k)
    });
    let offsets = DVector::from_fn(l, |j, _| there[j].d[k] - here[j].d[k]);
    let inverse = c.cholesky().map(|ch| ch.inverse()).ok_or_else(|| {
        KcError::Link(format!(
            "the covariance of the linking laboratories' offsets at position {} cannot be \
             inverted",
            this.index[k]
        ))
    })?;
    let ones = DVector::from_element(l, 1.0);
    let c_ones = &inverse * &ones;
    let total = ones.dot(&c_ones);
    let weights = &c_ones / total;
    let correction = weights.dot(&offsets);
    let residual = &offsets - &ones * correction;
    Ok(Offset {
        correction,
        correction_u: (1.0 / total).sqrt(),
        chi2: residual.dot(&(&inverse * &residual)),
        weights,
    })
}

/// The laboratories in both comparisons `this` and `linked`, in this one's order: refused
/// for another quantity, other positions, or none in both.
fn linking_labs(this: &KeyComparison, linked: &KeyComparison) -> Result<Vec<String>, KcError> {
    if this.quantity != linked.quantity {
        return Err(KcError::Link(format!(
            "the linked comparison is of {}, this one of {}",
            linked.quantity, this.quantity
        )));
    }
    let same_positions = match (&this.angle_deg, &linked.angle_deg) {
        (Some(a), Some(b)) => {
            a.len() == b.len()
                && a.iter().zip(b).all(|(a, b)| {
                    let apart = (a - b).rem_euclid(360.0);
                    apart.min(360.0 - apart) <= crate::results::ANGLE_TOLERANCE_DEG
                })
        }
        // blocks (or faces) by number, and a block's nominal angle where both state it
        (None, None) => {
            this.index == linked.index
                && match (&this.nominal_deg, &linked.nominal_deg) {
                    (Some(a), Some(b)) => a.iter().zip(b).all(|(a, b)| match (a, b) {
                        (Some(a), Some(b)) => (a - b).abs() <= 1e-9,
                        _ => true,
                    }),
                    _ => true,
                }
        }
        _ => false,
    };
    if !same_positions {
        return Err(KcError::Link(
            "the two comparisons are not of the same positions (faces, table angles, or angle \
             blocks and their nominal angles)"
                .into(),
        ));
    }
    let labs: Vec<String> = this
        .labs
        .iter()
        .filter(|name| doe(linked, name).is_some() && doe(this, name).is_some())
        .cloned()
        .collect();
    if labs.is_empty() {
        return Err(KcError::Link(
            "no laboratory is in both comparisons: nothing links them".into(),
        ));
    }
    Ok(labs)
}

/// Links `this` comparison to `linked` (e.g. the CIPM comparison, read back from its JSON
/// by [`super::read_json`]) through the laboratories in both: sets `this.link` and every
/// degree of equivalence's `d_linked` and `U_linked`, and adds a note.
///
/// # Errors
///
/// [`KcError::Link`]: another quantity, other positions (faces or angles), no laboratory
/// in both, an encoder position no linking laboratory reports in both, linking
/// laboratories in groups that share no position, or a covariance of the offsets that
/// cannot be inverted.
///
/// # Examples
///
/// ```
/// use polycal::kc::{evaluate, link, KcOptions, LabResult};
/// use polycal::results::{Quantity, ResultRow};
///
/// let lab = |name: &str, beta: [f64; 3]| {
///     let rows = (1..=3)
///         .map(|f| ResultRow::new(Quantity::PitchDeviation, f, beta[f as usize - 1]).with_u(0.1))
///         .collect();
///     LabResult::from_rows(name, rows)
/// };
/// let cipm = evaluate(
///     &[lab("A", [0.2, -0.1, -0.1]), lab("B", [0.1, 0.0, -0.1]), lab("X", [0.15, -0.05, -0.1])],
///     &[],
///     &KcOptions::new(),
/// )?;
/// let mut rmo = evaluate(
///     &[lab("A", [0.25, -0.15, -0.1]), lab("Y", [0.2, -0.1, -0.1])],
///     &[],
///     &KcOptions::new(),
/// )?;
/// link(&mut rmo, &cipm)?;
/// let linked = rmo.link.as_ref().expect("linked through A");
/// assert_eq!(linked.labs, ["A"]);
/// // A's degree of equivalence against the linked reference is its CIPM one
/// let a = &rmo.degrees_of_equivalence[0];
/// let d = a.d_linked.as_ref().expect("given");
/// assert!((d[0] - cipm.degrees_of_equivalence[0].d[0]).abs() < 1e-12);
/// # Ok::<(), polycal::kc::KcError>(())
/// ```
pub fn link(this: &mut KeyComparison, linked: &KeyComparison) -> Result<(), KcError> {
    let labs = linking_labs(this, linked)?;
    if this.wording().is_closed() && reports_different_positions(this, linked, &labs) {
        return link_over_positions(this, linked, labs);
    }
    let positions = this.index.len();
    let l = labs.len();
    let closed = this.wording().is_closed();
    let (mut correction, mut correction_u, mut weights) = (Vec::new(), Vec::new(), Vec::new());
    // per quantity, the linking laboratories that report it in both (every one of them
    // for closed vectors)
    let mut linking_at: Vec<Vec<String>> = Vec::with_capacity(positions);
    let (mut chi2, mut block_dof) = (0.0, 0usize);
    for k in 0..positions {
        let reporting: Vec<String> = labs
            .iter()
            .filter(|name| {
                closed
                    || [doe(this, name), doe(linked, name)]
                        .iter()
                        .all(|d| d.is_some_and(|d| d.d[k].is_finite()))
            })
            .cloned()
            .collect();
        let at = offset_at(this, linked, &reporting, k)?;
        chi2 += at.chi2;
        block_dof += reporting.len().saturating_sub(1);
        correction.push(at.correction);
        correction_u.push(at.correction_u);
        weights.push(at.weights);
        linking_at.push(reporting);
    }
    let faces = positions as f64;
    let tested = if closed { l > 1 } else { block_dof > 0 };
    let vector = tested.then(|| {
        let (chi2, dof) = if closed {
            (chi2 * (faces - 1.0) / faces, (positions - 1) * (l - 1))
        } else {
            (chi2, block_dof)
        };
        VectorTest::at_five_percent(chi2, dof)
    });
    // every degree of equivalence (the pilot's repeats' too) against the linked reference
    let snapshot = this.clone();
    let linking: Vec<Vec<&DegreeOfEquivalence>> = linking_at
        .iter()
        .map(|names| names.iter().filter_map(|n| doe(&snapshot, n)).collect())
        .collect();
    let all = this.degrees_of_equivalence.iter_mut().chain(
        this.pilot
            .iter_mut()
            .flat_map(|p| p.degrees_of_equivalence.iter_mut()),
    );
    for d in all {
        let mut d_linked = Vec::with_capacity(positions);
        let mut u_linked = Vec::with_capacity(positions);
        for k in 0..positions {
            let u_d = standard_u(d, k);
            let covariance: f64 = linking[k]
                .iter()
                .zip(weights[k].iter())
                .map(|(j, a)| a * doe_covariance(&snapshot, d, j, k))
                .sum();
            let variance = u_d * u_d + correction_u[k] * correction_u[k] - 2.0 * covariance;
            let value = d.d[k] + correction[k];
            d_linked.push(value);
            // (a block not reported, or not linked: neither d nor U)
            u_linked.push(if value.is_finite() && variance.is_finite() {
                2.0 * variance.max(0.0).sqrt()
            } else {
                f64::NAN
            });
        }
        d.d_linked = Some(d_linked);
        d.expanded_u_linked = Some(u_linked);
    }
    this.notes.push(link_note(&labs, vector.as_ref()));
    this.link = Some(Link {
        labs,
        correction,
        correction_u,
        vector,
    });
    Ok(())
}

/// Whether some laboratory of `this` (a pilot's repeat included), or a linking one in
/// `linked`, does not report every position: closed vectors over different positions.
fn reports_different_positions(
    this: &KeyComparison,
    linked: &KeyComparison,
    labs: &[String],
) -> bool {
    let gapped = |d: &DegreeOfEquivalence| d.d.iter().any(|x| !x.is_finite());
    this.degrees_of_equivalence
        .iter()
        .chain(this.pilot.iter().flat_map(|p| &p.degrees_of_equivalence))
        .any(gapped)
        || labs
            .iter()
            .any(|name| doe(linked, name).is_some_and(gapped))
}

/// [`link`] when laboratories report different encoder positions
/// ([`super::link_positions`]): each linking laboratory's offsets with a constant of its
/// own, every degree of equivalence closed over its own positions against the linked
/// reference.
fn link_over_positions(
    this: &mut KeyComparison,
    linked: &KeyComparison,
    labs: Vec<String>,
) -> Result<(), KcError> {
    let solved = super::link_positions::solve(this, linked, &labs)?;
    let snapshot = this.clone();
    let all = this.degrees_of_equivalence.iter_mut().chain(
        this.pilot
            .iter_mut()
            .flat_map(|p| p.degrees_of_equivalence.iter_mut()),
    );
    for d in all {
        let (value, expanded) = solved.linked(&snapshot, d);
        d.d_linked = Some(value);
        d.expanded_u_linked = Some(expanded);
    }
    let mut note = link_note(&labs, solved.vector.as_ref());
    note.push_str(
        "; the laboratories report different positions: each linking laboratory's offsets \
         are taken over the positions it reports in both, with a constant of its own, and \
         every degree of equivalence against the linked reference is closed over the \
         laboratory's own positions, as in this comparison",
    );
    this.notes.push(note);
    this.link = Some(Link {
        labs,
        correction: solved.correction,
        correction_u: solved.correction_u,
        vector: solved.vector,
    });
    Ok(())
}

/// The note on the link through `labs`, with its test (`None`: one linking laboratory).
fn link_note(labs: &[String], vector: Option<&VectorTest>) -> String {
    let l = labs.len();
    format!(
        "linked to another comparison through {} ({} laboratory(ies) in both): every degree \
         of equivalence is also given against the linked reference (d_linked, U_linked), \
         d + Δ with Δ the GLS mean of the linking laboratories' offsets d(linked) − d(this), \
         their correlations counted{}",
        labs.join(", "),
        l,
        match vector {
            Some(v) => format!(
                "; the link's test: χ² = {:.2} {} χ²_0.95({}) = {:.2}: the linking laboratories \
                 {} on the offset",
                v.chi2,
                if v.consistent { "≤" } else { ">" },
                v.dof,
                v.chi2_critical,
                if v.consistent { "agree" } else { "DISAGREE" }
            ),
            None => format!("; {}", untested_reason(l)),
        }
    )
}
