//! Cycles with fewer steps than the others (docs/FORMAT.md §2.1): a run interrupted in
//! its last cycle, a cycle cut short. Such a file is valid — the closure model uses every
//! reading it has — but the user should know: the result is evaluated with fewer readings
//! in that cycle than the design planned.

use super::MeasurementSet;
use std::collections::{BTreeMap, BTreeSet};
use std::fmt;

/// A cycle of one mounting that read only some of the steps every other cycle of that
/// mounting read alike (a run interrupted in its last cycle, a cycle cut short); cycles
/// of a design in which the cycles read different steps are not incomplete.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
#[non_exhaustive]
pub struct IncompleteCycle {
    /// The mounting (`setup`).
    pub setup: u32,
    /// The cycle.
    pub cycle: u32,
    /// The number of distinct steps the cycle read.
    pub steps: usize,
    /// The number of steps a whole cycle of its mounting reads: what every other cycle
    /// read.
    pub expected_steps: usize,
    /// The steps of a whole cycle it did not read, ascending.
    pub missing_steps: Vec<usize>,
    /// Whether the set has several mountings (the message then names the setup).
    #[serde(skip)]
    several_setups: bool,
}

impl fmt::Display for IncompleteCycle {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.several_setups {
            write!(f, "setup {}, ", self.setup)?;
        }
        let missing = ranges(&self.missing_steps);
        write!(
            f,
            "cycle {} is incomplete: it read {} of the {} steps of a whole cycle (step{} {} \
             missing); it is evaluated with the readings it has",
            self.cycle,
            self.steps,
            self.expected_steps,
            if self.missing_steps.len() == 1 {
                ""
            } else {
                "s"
            },
            missing
        )
    }
}

/// The most runs a message lists; the rest are counted.
const RUNS_SHOWN: usize = 8;

/// Ascending numbers as runs: `5–23`, `1, 3–4`; beyond [`RUNS_SHOWN`] runs, the first ones
/// and how many numbers in all.
fn ranges(numbers: &[usize]) -> String {
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for &n in numbers {
        match runs.last_mut() {
            Some((_, end)) if *end + 1 == n => *end = n,
            _ => runs.push((n, n)),
        }
    }
    let shown = runs
        .iter()
        .take(RUNS_SHOWN)
        .map(|&(a, b)| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}–{b}")
            }
        })
        .collect::<Vec<_>>()
        .join(", ");
    if runs.len() > RUNS_SHOWN {
        format!("{shown}, … ({} in all)", numbers.len())
    } else {
        shown
    }
}

impl MeasurementSet {
    /// The cycles with fewer steps than a whole cycle of their mounting, in (setup, cycle)
    /// order. A whole cycle is what every other cycle of the mounting read, all alike (step
    /// N, the closing reading, counting when they have it); a cycle that read only part of
    /// it is incomplete. A mounting of one cycle, or whose other cycles read different
    /// steps (a design that skips steps on purpose), has none. A step counts as read when
    /// any autocollimator read it.
    ///
    /// ```
    /// use polycal::measurement::MeasurementSet;
    /// // Two cycles of a 3-faced polygon; the second stopped after step 1.
    /// let csv = b"cycle,step,ac,face,reading\n\
    ///             1,0,1,1,0.5\n1,1,1,2,0.1\n1,2,1,3,-0.6\n\
    ///             2,0,1,1,0.4\n2,1,1,2,0.2\n";
    /// let set = MeasurementSet::read_from(&csv[..], "run.csv", None).unwrap();
    /// let incomplete = set.incomplete_cycles();
    /// assert_eq!(incomplete.len(), 1);
    /// assert_eq!((incomplete[0].cycle, incomplete[0].steps, incomplete[0].expected_steps), (2, 2, 3));
    /// assert_eq!(
    ///     incomplete[0].to_string(),
    ///     "cycle 2 is incomplete: it read 2 of the 3 steps of a whole cycle (step 2 \
    ///      missing); it is evaluated with the readings it has"
    /// );
    /// ```
    pub fn incomplete_cycles(&self) -> Vec<IncompleteCycle> {
        let mut steps: BTreeMap<(u32, u32), BTreeSet<usize>> = BTreeMap::new();
        for r in &self.readings {
            steps.entry((r.setup, r.cycle)).or_default().insert(r.step);
        }
        let setups: BTreeSet<u32> = steps.keys().map(|&(setup, _)| setup).collect();
        let several_setups = setups.len() > 1;
        let mut found = Vec::new();
        for &setup in &setups {
            let cycles: Vec<(u32, &BTreeSet<usize>)> = steps
                .iter()
                .filter(|((s, _), _)| *s == setup)
                .map(|(&(_, cycle), read)| (cycle, read))
                .collect();
            for (i, &(cycle, read)) in cycles.iter().enumerate() {
                // The other cycles of the mounting, all alike: what a whole cycle reads.
                let mut others = cycles
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| j != i)
                    .map(|(_, &(_, other))| other);
                let Some(whole) = others.next() else {
                    continue;
                };
                if !others.all(|other| other == whole)
                    || read.len() >= whole.len()
                    || !read.is_subset(whole)
                {
                    continue;
                }
                found.push(IncompleteCycle {
                    setup,
                    cycle,
                    steps: read.len(),
                    expected_steps: whole.len(),
                    missing_steps: whole.difference(read).copied().collect(),
                    several_setups,
                });
            }
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(rows: &str) -> MeasurementSet {
        let header = if rows.lines().all(|l| l.split(',').count() == 6) {
            "cycle,step,ac,face,reading,setup"
        } else {
            "cycle,step,ac,face,reading"
        };
        let csv = format!("{header}\n{rows}");
        MeasurementSet::read_from(csv.as_bytes(), "t.csv", None).unwrap()
    }

    #[test]
    fn whole_cycles_are_not_incomplete() {
        let s = set("1,0,1,1,0\n1,1,1,2,0\n1,2,1,3,0\n2,0,1,1,0\n2,1,1,2,0\n2,2,1,3,0\n");
        assert!(s.incomplete_cycles().is_empty());
    }

    #[test]
    fn a_missing_closing_reading_counts_when_other_cycles_have_it() {
        // cycle 1 has steps 0..=3 (the closing step 3), cycle 2 lacks step 3
        let s =
            set("1,0,1,1,0\n1,1,1,2,0\n1,2,1,3,0\n1,3,1,1,0\n2,0,1,1,0\n2,1,1,2,0\n2,2,1,3,0\n");
        let found = s.incomplete_cycles();
        assert_eq!(found.len(), 1);
        assert_eq!(
            (found[0].cycle, found[0].steps, found[0].expected_steps),
            (2, 3, 4)
        );
        assert_eq!(found[0].missing_steps, [3]);
    }

    #[test]
    fn cycles_are_judged_within_their_mounting_and_named_with_it() {
        // setup 1: whole; setup 2: cycle 1 whole, cycle 2 lacks step 1 (a gap, not the end)
        let s = set("1,0,1,1,0,1\n1,1,1,2,0,1\n1,2,1,3,0,1\n\
             1,0,1,1,0,2\n1,1,1,2,0,2\n1,2,1,3,0,2\n2,0,1,1,0,2\n2,2,1,3,0,2\n");
        let found = s.incomplete_cycles();
        assert_eq!(found.len(), 1);
        assert_eq!((found[0].setup, found[0].cycle), (2, 2));
        assert_eq!(found[0].missing_steps, [1]);
        assert!(
            found[0]
                .to_string()
                .starts_with("setup 2, cycle 2 is incomplete: it read 2 of the 3 steps of a whole cycle (step 1 missing)"),
            "{}",
            found[0]
        );
    }

    #[test]
    fn missing_steps_are_shown_as_runs() {
        assert_eq!(ranges(&[5, 6, 7, 8]), "5–8");
        assert_eq!(ranges(&[1, 3, 4, 9]), "1, 3–4, 9");
        assert_eq!(ranges(&[2]), "2");
        let every_other: Vec<usize> = (0..20).map(|i| 2 * i).collect();
        assert_eq!(
            ranges(&every_other),
            "0, 2, 4, 6, 8, 10, 12, 14, … (20 in all)"
        );
    }

    #[test]
    fn a_design_whose_cycles_read_different_steps_has_no_incomplete_cycle() {
        // three cycles of a 4-faced polygon, each skipping another step on purpose
        let s = set("1,0,1,1,0\n1,1,1,2,0\n1,2,1,3,0\n\
             2,1,1,2,0\n2,2,1,3,0\n2,3,1,4,0\n\
             3,0,1,1,0\n3,2,1,3,0\n3,3,1,4,0\n");
        assert!(s.incomplete_cycles().is_empty());
    }
}
