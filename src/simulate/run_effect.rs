//! Why an effect does not fit a simulated run, and an effect as it is named in messages:
//! shared by the run's settings (`config.rs`) and the truth file's reader
//! (`truth_file.rs`), and importing neither.

use crate::effects::Effect;

/// Why an effect does not fit a simulated run: not finite, naming something the run does
/// not have, or lacking the model it acts through.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RunEffectError {
    /// The effect's value is not finite.
    #[error("value is not finite")]
    ValueNotFinite,
    /// A re-zeroing offset that is not finite.
    #[error("an offset is not finite")]
    OffsetNotFinite,
    /// A drift's `quadratic` that is not finite.
    #[error("quadratic is not finite")]
    QuadraticNotFinite,
    /// An autocollimator the run does not have.
    #[error("no autocollimator {ac}; the run has 1 … {acs}")]
    NoAutocollimator {
        /// The autocollimator named.
        ac: u32,
        /// The run's number of autocollimators.
        acs: usize,
    },
    /// A cycle the run does not have.
    #[error("no cycle {cycle}; the run has 1 … {cycles}")]
    NoCycle {
        /// The cycle named.
        cycle: u32,
        /// The run's number of cycles.
        cycles: u32,
    },
    /// A step the run's cycles do not have.
    #[error("no step {step}; the run has 0 … {last}")]
    NoStep {
        /// The step named.
        step: usize,
        /// The last step of a cycle.
        last: usize,
    },
    /// A setup the run does not have.
    #[error("no setup {setup}; the run has 1 … {setups}")]
    NoSetup {
        /// The setup named.
        setup: u32,
        /// The run's number of setups.
        setups: u32,
    },
    /// A temperature effect in a run without a temperature model.
    #[error("a temperature effect needs a temperature model (the run has no temperature column)")]
    NoTemperatureModel,
    /// A cross-talk effect in a run without an elevation model.
    #[error("a cross-talk effect needs an elevation model (the run has no reading_y column)")]
    NoElevationModel,
    /// A direction effect in a run without a counter-clockwise cycle.
    #[error("no counter-clockwise cycle in this run (needs bidirectional and at least 2 cycles)")]
    NoCounterClockwiseCycle,
    /// An outlier without a setup in a run of several setups.
    #[error("the run has {setups} setups; say which one the outlier is in")]
    OutlierSetupUnnamed {
        /// The run's number of setups.
        setups: u32,
    },
}

/// An effect as compact JSON, for messages.
pub(super) fn effect_json(e: &Effect) -> String {
    serde_json::to_string(e).unwrap_or_else(|_| format!("{e:?}"))
}
