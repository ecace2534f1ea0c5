//! The Welch–Satterthwaite degrees of freedom of each degree of equivalence, when the
//! laboratories state the degrees of freedom of their u (a result file's `dof` column;
//! docs/FORMAT.md §12, "Degrees of freedom"). Per quantity, with v_j = u_j² + u_stab² + τ²
//! and the weights w'_j = (1/v_j)/Σ_{l in the reference} 1/v_l of the laboratories in the
//! reference, d_i = Σ_j c_j x_j with c_j = δ_ij − w'_j (c_i = 1 for a result out of the
//! reference). Its variance has three kinds of component: each result's u_j² (ν_j, as
//! stated), the pilot's u_stab² in every result (one estimate with ν = m − 1, so its
//! parts add before they are squared) and τ² (ν = ∞):
//!
//! ```text
//! ν_eff = u_c⁴ / ( Σ_j (c_j² u_j²)²/ν_j + (Σ_j c_j² · u_stab²)²/(m − 1) ),
//! u_c² = Σ_j c_j² (u_j² + u_stab² + τ²),   k = t_95.45(ν_eff),   U = k · u(d_i)
//! ```
//!
//! (JCGM 100:2008, G.4.1). The coefficients are the per-quantity weighted mean's, which
//! the closed reference is when each laboratory has one u on every quantity; u(d_i) is the
//! closed reference's own.

use statrs::distribution::{ContinuousCDF, StudentsT};

use super::KeyComparison;

/// k = t_95.45(ν): the two-sided 95.45 % quantile of Student's t with ν degrees of freedom
/// (statrs), 2 for ν = ∞ (the formulas' k).
pub(crate) fn coverage_factor(dof: f64) -> f64 {
    if !dof.is_finite() {
        return 2.0;
    }
    StudentsT::new(0.0, 1.0, dof).map_or(f64::NAN, |t| t.inverse_cdf(0.5 + 0.9545 / 2.0))
}

/// What ν_eff is worked out from, in the comparison's scaled units.
pub(crate) struct Sources<'a> {
    /// Every result's stated u per quantity (laboratories, then the pilot's repeats).
    pub u: &'a [Vec<f64>],
    /// Their degrees of freedom (∞ where none is stated).
    pub dof: &'a [Vec<f64>],
    /// u_stab per quantity (0 when the pilot's repeats agree).
    pub stability: &'a [f64],
    /// The degrees of freedom of u_stab: m − 1 for m repeats.
    pub stability_dof: f64,
    /// τ per quantity (0 for the weighted mean).
    pub tau: &'a [f64],
    /// The laboratories in the reference.
    pub inside: &'a [usize],
    /// Whether each result reports each quantity (`None`: all of them; angle blocks may
    /// not be).
    pub measured: Option<&'a [Vec<bool>]>,
}

impl Sources<'_> {
    /// Whether result `r` reports quantity `k`.
    fn reports(&self, r: usize, k: usize) -> bool {
        self.measured
            .is_none_or(|m| m.get(r).and_then(|m| m.get(k)).copied().unwrap_or(false))
    }
}

/// ν_eff of result `r`'s degree of equivalence at quantity `k` (∞ when every component
/// has infinitely many degrees of freedom; NaN where `r` does not report `k`). The
/// reference of `k` is that of the laboratories in it that report `k`.
pub(crate) fn effective(sources: &Sources, r: usize, k: usize) -> f64 {
    if !sources.reports(r, k) {
        return f64::NAN;
    }
    let inside: Vec<usize> = sources
        .inside
        .iter()
        .copied()
        .filter(|&j| sources.reports(j, k))
        .collect();
    let (s2, t2) = (
        sources.stability[k] * sources.stability[k],
        sources.tau[k] * sources.tau[k],
    );
    let v = |j: usize| sources.u[j][k] * sources.u[j][k] + s2 + t2;
    let total: f64 = inside.iter().map(|&j| 1.0 / v(j)).sum();
    let coefficient = |j: usize| {
        let weight = if inside.contains(&j) {
            (1.0 / v(j)) / total
        } else {
            0.0
        };
        f64::from(u8::from(j == r)) - weight
    };
    let (mut combined, mut own, mut c2_sum) = (0.0, 0.0, 0.0);
    for j in 0..sources.u.len() {
        let c2 = coefficient(j).powi(2);
        if c2 == 0.0 {
            continue;
        }
        let uj2 = sources.u[j][k] * sources.u[j][k];
        combined += c2 * (uj2 + s2 + t2);
        c2_sum += c2;
        let dof = sources.dof[j][k];
        if dof.is_finite() {
            own += (c2 * uj2).powi(2) / dof;
        }
    }
    let stability = if s2 > 0.0 && sources.stability_dof.is_finite() {
        (c2_sum * s2).powi(2) / sources.stability_dof
    } else {
        0.0
    };
    let denominator = own + stability;
    if denominator > 0.0 {
        combined * combined / denominator
    } else {
        f64::INFINITY
    }
}

/// Every degree of equivalence's U (the pilot's repeats' too) with k = t_95.45(ν_eff), the
/// Welch–Satterthwaite ν from `sources` ([`effective`]), each ν_eff and k stated, and a note.
pub(crate) fn apply(comparison: &mut KeyComparison, sources: &Sources) {
    let degrees = comparison.degrees_of_equivalence.iter_mut().chain(
        comparison
            .pilot
            .iter_mut()
            .flat_map(|p| p.degrees_of_equivalence.iter_mut()),
    );
    for (r, doe) in degrees.enumerate() {
        let (mut nu, mut k) = (Vec::new(), Vec::new());
        for (position, expanded_u) in doe.expanded_u.iter_mut().enumerate() {
            let effective = effective(sources, r, position);
            if effective.is_nan() {
                // not reported: no U, no ν, no k
                nu.push(None);
                k.push(f64::NAN);
                continue;
            }
            let factor = coverage_factor(effective);
            *expanded_u *= factor / 2.0;
            nu.push(effective.is_finite().then_some(effective));
            k.push(factor);
        }
        doe.dof_effective = Some(nu);
        doe.k = Some(k);
    }
    comparison.notes.push(
        "every U(d_i) is k·u(d_i) with k = t_95.45(ν_eff), ν_eff by Welch–Satterthwaite from \
         the degrees of freedom the laboratories state for their u (column dof; none stated: \
         infinitely many), the pilot's u_stab with m − 1 and τ with infinitely many \
         (dof_effective and k in the JSON)"
            .to_string(),
    );
}
