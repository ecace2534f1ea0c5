//! Why a search ended: nothing more significant, or a limit (docs/FORMAT.md §5,
//! `search_stopped`). A search a limit ended is never certified adequate: something
//! significant may be left that the model does not hold.

/// The limit that ended a diagnosis's search while something more was significant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SearchStop {
    /// The model holds the most effects a diagnosis adds
    /// ([`crate::diagnose::DiagnoseOptions::max_effects`]) and a further candidate is
    /// significant.
    MaxEffects {
        /// The limit, effects.
        limit: usize,
    },
    /// The fit with the effects found has fewer than two residual degrees of freedom: no
    /// further term can be tested.
    TooFewDegreesOfFreedom {
        /// The residual degrees of freedom left.
        dof: usize,
    },
    /// The only significant candidates left are further jumps of a zero that already
    /// jumped as often as a diagnosis accepts as events ([`crate::diagnose::MAX_JUMPS_PER_STREAM`]).
    JumpsPerZero {
        /// The most jumps of one zero, per stream.
        limit: usize,
    },
    /// A round refitted as many significant candidates as a round tries, each refused,
    /// and further significant candidates were left untried.
    AttemptsPerRound {
        /// The most refits of one round.
        attempts: usize,
    },
}

impl SearchStop {
    /// The limit as spelled in the JSON's `search_stopped`: `max-effects`,
    /// `too-few-degrees-of-freedom`, `jumps-per-zero`, `attempts-per-round`.
    pub fn as_str(self) -> &'static str {
        match self {
            SearchStop::MaxEffects { .. } => "max-effects",
            SearchStop::TooFewDegreesOfFreedom { .. } => "too-few-degrees-of-freedom",
            SearchStop::JumpsPerZero { .. } => "jumps-per-zero",
            SearchStop::AttemptsPerRound { .. } => "attempts-per-round",
        }
    }

    /// The limit in words, for the table and the notes.
    pub fn describe(self) -> String {
        match self {
            SearchStop::MaxEffects { limit } => format!(
                "the search stopped at its limit of {limit} effect{} while a further term was significant",
                if limit == 1 { "" } else { "s" }
            ),
            SearchStop::TooFewDegreesOfFreedom { dof } => format!(
                "the search stopped with {dof} residual degree{} of freedom left, too few to test a further term",
                if dof == 1 { "" } else { "s" }
            ),
            SearchStop::JumpsPerZero { limit } => format!(
                "the search stopped at a further significant jump of a zero that already jumped {limit} times, the most a run explains as events"
            ),
            SearchStop::AttemptsPerRound { attempts } => format!(
                "the search stopped after {attempts} significant terms of one round were each refused, with further significant terms untried"
            ),
        }
    }
}
