//! Which positions results share, and how results closed over different positions are
//! compared at one (docs/FORMAT.md §12, "Encoder errors at different positions"): the groups
//! that positions connect (one reference is possible only within a group) and the results
//! put on one level for per-position estimates.

/// Results closed each over its own positions, put on one level for per-position
/// estimates: each less its mean difference from `reference` over the positions it reports
/// (`reports(r, k)`) where the reference is given — the constant its closure over other
/// positions put in. Without it the spread at a position would count the laboratories'
/// different closures (the truth's mean over different positions) as disagreement.
pub(crate) fn levelled(
    values: &[Vec<f64>],
    reports: impl Fn(usize, usize) -> bool,
    reference: &[f64],
) -> Vec<Vec<f64>> {
    values
        .iter()
        .enumerate()
        .map(|(r, x)| {
            let at: Vec<usize> = (0..x.len())
                .filter(|&k| reports(r, k) && reference[k].is_finite())
                .collect();
            let offset = if at.is_empty() {
                0.0
            } else {
                at.iter().map(|&k| x[k] - reference[k]).sum::<f64>() / at.len() as f64
            };
            x.iter().map(|x| x - offset).collect()
        })
        .collect()
}

/// The results that report positions `reports[r][k]`, named `names[r]`, in the groups
/// connected by the positions they share, each as `{A, B}`, joined by " and "; `None` when
/// they are one group.
pub(crate) fn groups_apart(reports: &[Vec<bool>], names: &[&str]) -> Option<String> {
    let u: Vec<Vec<f64>> = reports
        .iter()
        .map(|r| {
            r.iter()
                .map(|&m| if m { 1.0 } else { f64::INFINITY })
                .collect()
        })
        .collect();
    let rows: Vec<&[f64]> = u.iter().map(Vec::as_slice).collect();
    let found = groups(&rows);
    (found.len() > 1).then(|| {
        found
            .iter()
            .map(|g| {
                let named: Vec<&str> = g.iter().map(|&r| names[r]).collect();
                format!("{{{}}}", named.join(", "))
            })
            .collect::<Vec<_>>()
            .join(" and ")
    })
}

/// The results (by their standard uncertainties `u`, +∞ where one does not report a
/// position) in groups connected by the positions they share: one group when a closed fit
/// of them all can put them on one reference, each group's results ascending.
pub(crate) fn groups(u: &[&[f64]]) -> Vec<Vec<usize>> {
    let n = u.len();
    let mut group: Vec<usize> = (0..n).collect();
    fn root(group: &mut [usize], mut i: usize) -> usize {
        while group[i] != i {
            group[i] = group[group[i]];
            i = group[i];
        }
        i
    }
    let faces = u.first().map_or(0, |u| u.len());
    for k in 0..faces {
        let mut first: Option<usize> = None;
        for (i, u) in u.iter().enumerate() {
            if !u[k].is_finite() {
                continue;
            }
            match first {
                None => first = Some(i),
                Some(f) => {
                    let (a, b) = (root(&mut group, f), root(&mut group, i));
                    group[a.max(b)] = a.min(b);
                }
            }
        }
    }
    let mut out: Vec<Vec<usize>> = Vec::new();
    let mut at: Vec<Option<usize>> = vec![None; n];
    for i in 0..n {
        let r = root(&mut group, i);
        match at[r] {
            Some(g) => out[g].push(i),
            None => {
                at[r] = Some(out.len());
                out.push(vec![i]);
            }
        }
    }
    out
}
