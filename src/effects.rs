//! Effects: terms the base model lacks (docs/FORMAT.md §6).
//!
//! Every effect is *linear in its value*: it adds `value * x(reading)` to a reading, where
//! the regressor `x` ([`Effect::regressor`]) depends only on the reading's bookkeeping
//! (autocollimator, cycle, step, direction, time), never on the true angles. The simulator
//! uses this to put effects into simulated data, and a least-squares diagnosis can use the
//! same regressor as an extra column of its design matrix.
//!
//! In JSON an effect is an object with a `kind` and a `value`, plus the fields its kind
//! needs, exactly as in docs/FORMAT.md §6:
//!
//! ```text
//! {"kind": "drift", "ac": 1, "value": 0.3}
//! {"kind": "drift", "ac": 1, "value": 0.3, "quadratic": -0.05}
//! {"kind": "offset-step", "ac": 2, "cycle": 4, "value": 0.5}
//! {"kind": "offset-step", "ac": 2, "cycle": 4, "step": 7, "setup": 1, "value": 0.5}
//! {"kind": "direction", "value": 0.2}                (or with "ac")
//! {"kind": "outlier", "cycle": 3, "step": 7, "ac": 1, "value": 2.0}   (optional "setup")
//! {"kind": "temperature", "ac": 1, "value": 0.2}
//! {"kind": "cross-talk", "ac": 1, "value": 0.01}
//! {"kind": "rezero", "ac": 1, "offsets": [0.0, 0.12, -0.3], "value": 0.3}   (optional "setup", "offsets_u")
//! ```
//!
//! Extra fields (such as a fit's `u`) are ignored when reading.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::measurement::{Direction, Reading};

/// One effect term, with its value in arcseconds (per hour for a drift, per °C for a
/// temperature coefficient, dimensionless for cross-talk).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Effect {
    /// Zero drift of autocollimator `ac`: `value` arcseconds per hour, linear in the
    /// reading's `time` (zero at time 0), plus `quadratic`·t² (arcsec/h²) when curved.
    Drift {
        /// Autocollimator number (≥ 1).
        ac: u32,
        /// Drift rate at time 0, arcsec per hour.
        value: f64,
        /// Curvature of the drift, arcsec per hour², when the drift accelerates or settles.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        quadratic: Option<f64>,
    },
    /// A jump of autocollimator `ac`'s zero by `value` arcseconds, from cycle `cycle` on
    /// (that cycle included) or, with `step`, from that stop of the cycle on in time order
    /// (a clockwise cycle runs steps 0 … N, a counter-clockwise one N … 0). With `setup`
    /// the jump acts in that mounting only; without it, cycle numbers restart in every
    /// setup, so the jump applies from that cycle on in each of them.
    OffsetStep {
        /// Autocollimator number (≥ 1).
        ac: u32,
        /// First cycle with the new zero (≥ 1).
        cycle: u32,
        /// First stop of `cycle` with the new zero, in time order; `None` for the whole cycle.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        step: Option<usize>,
        /// The mounting the jump acts in; `None` for every mounting.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        setup: Option<u32>,
        /// Size of the jump, arcsec.
        value: f64,
    },
    /// Offset of counter-clockwise readings against clockwise ones (ccw minus cw), of one
    /// autocollimator when `ac` is given, else of all.
    Direction {
        /// Autocollimator number, or `None` for every autocollimator.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        ac: Option<u32>,
        /// ccw minus cw offset, arcsec.
        value: f64,
    },
    /// One bad reading: reading minus model is `value` arcseconds. With `setup` `None` it
    /// matches the reading of that cycle, step and autocollimator in any setup.
    Outlier {
        /// Cycle number (≥ 1).
        cycle: u32,
        /// Table stop 0 … N.
        step: usize,
        /// Autocollimator number (≥ 1).
        ac: u32,
        /// Setup number, or `None` for any setup.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        setup: Option<u32>,
        /// Reading minus model, arcsec.
        value: f64,
    },
    /// Temperature coefficient of autocollimator `ac`: the reading changes by `value`
    /// arcseconds per °C of the `temperature` column, measured from the column's mean over
    /// the run ([`EffectContext`]).
    Temperature {
        /// Autocollimator number (≥ 1).
        ac: u32,
        /// Coefficient, arcsec per °C.
        value: f64,
    },
    /// Cross-talk of the elevation axis into the measuring axis of autocollimator `ac`:
    /// the reading changes by `value` times its `reading_y` (dimensionless).
    CrossTalk {
        /// Autocollimator number (≥ 1).
        ac: u32,
        /// Coefficient, arcsec of reading per arcsec of `reading_y`.
        value: f64,
    },
    /// The zero of autocollimator `ac` set anew at the start of every cycle: in cycle c
    /// its readings are offset by `offsets[c − 1]` arcseconds (in mounting `setup` only,
    /// when given; without it in every mounting, cycle numbers restarting in each). A
    /// fit reports the offsets against the first cycle (`offsets[0]` = 0: a constant
    /// offset is the setup error's); `value` is the largest |offset|.
    Rezero {
        /// Autocollimator number (≥ 1).
        ac: u32,
        /// The mounting the offsets act in; `None` for every mounting.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        setup: Option<u32>,
        /// Offset of the zero in each cycle, arcsec, cycle 1 first (a cycle beyond the
        /// list has none).
        offsets: Vec<f64>,
        /// Standard uncertainty of each offset, when a fit gives one.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        offsets_u: Option<Vec<f64>>,
        /// The largest |offset|, arcsec.
        value: f64,
    },
}

/// The effect kinds, as spelled in files and on the command line.
pub const KINDS: [&str; 7] = [
    "drift",
    "offset-step",
    "direction",
    "outlier",
    "temperature",
    "cross-talk",
    "rezero",
];

/// What an effect's regressor needs to know about the whole run: the mean of the
/// `temperature` column, against which a temperature coefficient acts.
#[derive(Debug, Clone, Default, PartialEq)]
#[non_exhaustive]
pub struct EffectContext {
    /// Mean of the readings' `temperature` values, °C (0 when none has one).
    pub mean_temperature_celsius: f64,
    /// A weighted diagnosis's whitening factors, one per reading (σ_ref/σ of the reading's
    /// noise group): the diagnosis's term columns are formed whitened, each value times
    /// its reading's factor (`diagnose`'s noise groups). `None`: unweighted. An effect's
    /// own regressor ([`Effect::regressor`]) never uses them.
    pub weights: Option<std::sync::Arc<[f64]>>,
}

impl EffectContext {
    /// The context of a run: the mean temperature over the readings that have one.
    pub fn of(readings: &[Reading]) -> Self {
        let (sum, count) = readings
            .iter()
            .filter_map(|r| r.temperature_celsius)
            .fold((0.0, 0usize), |(s, c), t| (s + t, c + 1));
        Self {
            mean_temperature_celsius: if count > 0 { sum / count as f64 } else { 0.0 },
            weights: None,
        }
    }

    /// A context with a given mean temperature, °C.
    pub fn with_mean_temperature(mean_temperature_celsius: f64) -> Self {
        Self {
            mean_temperature_celsius,
            weights: None,
        }
    }

    /// This context with the whitening factors `weights` (one per reading) for the
    /// diagnosis's term columns ([`EffectContext::weights`]).
    pub fn with_weights(mut self, weights: Option<std::sync::Arc<[f64]>>) -> Self {
        self.weights = weights;
        self
    }
}

/// Whether `reading` is taken at or after stop `step` of cycle `cycle` in time order:
/// a later cycle, or the same cycle at that stop or later in the cycle's direction
/// (clockwise cycles run steps 0 … N, counter-clockwise ones N … 0).
pub fn at_or_after(reading: &Reading, cycle: u32, step: Option<usize>) -> bool {
    if reading.cycle != cycle {
        return reading.cycle > cycle;
    }
    match (step, reading.direction) {
        (None, _) => true,
        (Some(s), Direction::Cw) => reading.step >= s,
        (Some(s), Direction::Ccw) => reading.step <= s,
    }
}

impl Effect {
    /// The regressor x(reading) of the effect's `value`: the effect adds `value * x` (plus,
    /// for a curved drift, `quadratic * t²`, see [`Effect::contribution`]) to that reading.
    ///
    /// - drift: the reading's time in hours for that autocollimator (0 when the reading
    ///   has no time, and for other autocollimators);
    /// - offset-step: 1 for that autocollimator (and setup, if given) at or after the
    ///   step's cycle and stop in time order ([`at_or_after`]), else 0;
    /// - direction: 1 for `ccw` readings (of that autocollimator if given), else 0;
    /// - outlier: 1 for that one reading, else 0;
    /// - temperature: the reading's temperature minus the run's mean (0 without one);
    /// - cross-talk: the reading's `reading_y` (0 without one).
    pub fn regressor(&self, reading: &Reading, context: &EffectContext) -> f64 {
        let hit = |b: bool| if b { 1.0 } else { 0.0 };
        match *self {
            Effect::Drift { ac, .. } => {
                if reading.ac == ac {
                    reading.time_seconds.map_or(0.0, |t| t / 3600.0)
                } else {
                    0.0
                }
            }
            Effect::OffsetStep {
                ac,
                cycle,
                step,
                setup,
                ..
            } => hit(reading.ac == ac
                && setup.is_none_or(|s| reading.setup == s)
                && at_or_after(reading, cycle, step)),
            Effect::Direction { ac, .. } => {
                hit(reading.direction == Direction::Ccw && ac.is_none_or(|ac| reading.ac == ac))
            }
            Effect::Outlier {
                cycle,
                step,
                ac,
                setup,
                ..
            } => hit(reading.cycle == cycle
                && reading.step == step
                && reading.ac == ac
                && setup.is_none_or(|s| reading.setup == s)),
            Effect::Temperature { ac, .. } => {
                if reading.ac == ac {
                    reading
                        .temperature_celsius
                        .map_or(0.0, |t| t - context.mean_temperature_celsius)
                } else {
                    0.0
                }
            }
            Effect::CrossTalk { ac, .. } => {
                if reading.ac == ac {
                    reading.reading_y_arcsec.unwrap_or(0.0)
                } else {
                    0.0
                }
            }
            Effect::Rezero { value, .. } => {
                if value == 0.0 {
                    0.0
                } else {
                    self.rezero_offset(reading) / value
                }
            }
        }
    }

    /// For a `rezero`: the offset of `reading`'s cycle when the reading is of that
    /// autocollimator (and mounting, if given), else 0; 0 for every other effect.
    pub fn rezero_offset(&self, reading: &Reading) -> f64 {
        match self {
            Effect::Rezero {
                ac, setup, offsets, ..
            } if reading.ac == *ac && setup.is_none_or(|s| reading.setup == s) => (reading.cycle
                as usize)
                .checked_sub(1)
                .and_then(|c| offsets.get(c))
                .copied()
                .unwrap_or(0.0),
            _ => 0.0,
        }
    }

    /// A `rezero` of autocollimator `ac` (in `setup`, if given) with these offsets, one
    /// per cycle; its `value` is the largest |offset|.
    pub fn rezero(ac: u32, setup: Option<u32>, offsets: Vec<f64>) -> Effect {
        let value = offsets.iter().fold(0.0_f64, |m, o| m.max(o.abs()));
        Effect::Rezero {
            ac,
            setup,
            offsets,
            offsets_u: None,
            value,
        }
    }

    /// The regressor of a drift's `quadratic` term: the reading's time in hours, squared,
    /// for that autocollimator; 0 for every other effect and reading.
    pub fn quadratic_regressor(&self, reading: &Reading) -> f64 {
        match *self {
            Effect::Drift { ac, .. } if reading.ac == ac => {
                reading.time_seconds.map_or(0.0, |t| (t / 3600.0).powi(2))
            }
            _ => 0.0,
        }
    }

    /// What the effect adds to `reading`, arcsec: `value · regressor`, plus
    /// `quadratic · t²` for a curved drift.
    pub fn contribution(&self, reading: &Reading, context: &EffectContext) -> f64 {
        let quadratic = match *self {
            Effect::Drift {
                quadratic: Some(q), ..
            } => q * self.quadratic_regressor(reading),
            Effect::Rezero { .. } => return self.rezero_offset(reading),
            _ => 0.0,
        };
        self.value() * self.regressor(reading, context) + quadratic
    }

    /// The effect's value: arcsec per hour for a drift, arcsec otherwise.
    pub fn value(&self) -> f64 {
        match *self {
            Effect::Drift { value, .. }
            | Effect::OffsetStep { value, .. }
            | Effect::Direction { value, .. }
            | Effect::Outlier { value, .. }
            | Effect::Temperature { value, .. }
            | Effect::CrossTalk { value, .. }
            | Effect::Rezero { value, .. } => value,
        }
    }

    /// The same effect with another value (e.g. a fitted one). A `rezero`'s offsets are
    /// scaled with it (they are zero when its value was).
    pub fn with_value(mut self, new_value: f64) -> Effect {
        if let Effect::Rezero { offsets, value, .. } = &mut self {
            let scale = if *value == 0.0 {
                0.0
            } else {
                new_value / *value
            };
            offsets.iter_mut().for_each(|o| *o *= scale);
        }
        match &mut self {
            Effect::Drift { value, .. }
            | Effect::OffsetStep { value, .. }
            | Effect::Direction { value, .. }
            | Effect::Outlier { value, .. }
            | Effect::Temperature { value, .. }
            | Effect::CrossTalk { value, .. }
            | Effect::Rezero { value, .. } => *value = new_value,
        }
        self
    }

    /// The kind as spelled in files: one of [`KINDS`] (`drift`, `offset-step`,
    /// `direction`, `outlier`, `temperature`, `cross-talk`).
    pub fn kind(&self) -> &'static str {
        match self {
            Effect::Drift { .. } => KINDS[0],
            Effect::OffsetStep { .. } => KINDS[1],
            Effect::Direction { .. } => KINDS[2],
            Effect::Outlier { .. } => KINDS[3],
            Effect::Temperature { .. } => KINDS[4],
            Effect::CrossTalk { .. } => KINDS[5],
            Effect::Rezero { .. } => KINDS[6],
        }
    }

    /// The effect's name without its value, in the words every report uses, e.g.
    /// `drift of autocollimator 2` or `offset-step of autocollimator 1 from cycle 3`.
    pub fn label(&self) -> String {
        match self {
            Effect::Drift { ac, .. } => format!("drift of autocollimator {ac}"),
            Effect::OffsetStep {
                ac,
                cycle,
                step,
                setup,
                ..
            } => format!(
                "offset-step of autocollimator {ac} from {}cycle {cycle}{}",
                setup.map_or(String::new(), |s| format!("setup {s}, ")),
                step.map_or(String::new(), |s| format!(", step {s}"))
            ),
            Effect::Temperature { ac, .. } => {
                format!("temperature coefficient of autocollimator {ac}")
            }
            Effect::CrossTalk { ac, .. } => format!("cross-talk of autocollimator {ac}"),
            Effect::Rezero { ac, setup, .. } => format!(
                "zero of autocollimator {ac}{} set anew every cycle",
                setup.map_or(String::new(), |s| format!(" in setup {s}"))
            ),
            Effect::Direction { ac: None, .. } => "direction (ccw − cw)".into(),
            Effect::Direction { ac: Some(ac), .. } => {
                format!("direction (ccw − cw) of autocollimator {ac}")
            }
            Effect::Outlier {
                cycle,
                step,
                ac,
                setup,
                ..
            } => format!(
                "outlier at {}cycle {cycle}, step {step}, autocollimator {ac}",
                setup.map_or(String::new(), |s| format!("setup {s}, "))
            ),
        }
    }

    /// Parses a command-line spec of an effect of kind `kind` (one of [`KINDS`]):
    ///
    /// | kind | spec | example |
    /// |---|---|---|
    /// | `drift` | `AC:RATE` or `AC:RATE:QUADRATIC` (arcsec per hour, per hour²) | `1:0.3`, `1:0.3:-0.05` |
    /// | `offset-step` | `AC:CYCLE:VALUE`, `AC:CYCLE:STEP:VALUE` or `SETUP:AC:CYCLE:STEP:VALUE` | `2:4:0.5`, `2:4:7:0.5`, `1:2:4:7:0.5` |
    /// | `direction` | `VALUE` or `AC:VALUE` | `0.2`, `1:0.2` |
    /// | `outlier` | `CYCLE:STEP:AC:VALUE` or `SETUP:CYCLE:STEP:AC:VALUE` | `3:7:1:2.0` |
    /// | `temperature` | `AC:COEFF` (arcsec per °C) | `1:0.2` |
    /// | `cross-talk` | `AC:COEFF` (dimensionless) | `1:0.01` |
    ///
    /// Autocollimator, cycle and setup numbers start at 1, steps at 0 (a step is a stop of
    /// the cycle, counted as in the `step` column); values must be finite numbers. Whether
    /// a step, setup or cycle exists in a run is checked by the run, not here.
    /// Bad input gives an error text naming the kind, the spec and the faulty part.
    ///
    /// ```
    /// use polycal::effects::Effect;
    /// let e = Effect::parse_spec("offset-step", "2:4:0.5").unwrap();
    /// assert_eq!(e, Effect::OffsetStep { ac: 2, cycle: 4, step: None, setup: None, value: 0.5 });
    /// assert!(Effect::parse_spec("drift", "1").is_err());
    /// ```
    ///
    /// # Errors
    ///
    /// A [`SpecError`] naming the kind, the spec and the faulty part.
    pub fn parse_spec(kind: &str, spec: &str) -> Result<Effect, SpecError> {
        let parts: Vec<&str> = spec.split(':').map(str::trim).collect();
        let n = parts.len();
        let what = || format!("{kind} effect");
        let bad =
            |problem: SpecProblem, form: &'static str| SpecError::part(what(), spec, problem, form);
        match kind {
            "drift" => {
                let form = "AC:RATE or AC:RATE:QUADRATIC, e.g. 1:0.3 or 1:0.3:-0.05";
                let at = |problem| bad(problem, form);
                if !(2..=3).contains(&n) {
                    return Err(at(SpecProblem::part_count(n, "2 or 3")));
                }
                Ok(Effect::Drift {
                    ac: number_from_1("AC", parts[0]).map_err(at)?,
                    value: finite("RATE", parts[1]).map_err(at)?,
                    quadratic: match parts.get(2) {
                        Some(text) => Some(finite("QUADRATIC", text).map_err(at)?),
                        None => None,
                    },
                })
            }
            "offset-step" => {
                let form = "AC:CYCLE:VALUE, AC:CYCLE:STEP:VALUE or SETUP:AC:CYCLE:STEP:VALUE, \
                            e.g. 2:4:0.5, 2:4:7:0.5 or 1:2:4:7:0.5";
                let at = |problem| bad(problem, form);
                let (setup, rest) = match n {
                    3 | 4 => (None, &parts[..]),
                    5 => (
                        Some(number_from_1("SETUP", parts[0]).map_err(at)?),
                        &parts[1..],
                    ),
                    _ => return Err(at(SpecProblem::part_count(n, "3, 4 or 5"))),
                };
                let step = if rest.len() == 4 {
                    Some(whole("STEP", rest[2]).map_err(at)?)
                } else {
                    None
                };
                Ok(Effect::OffsetStep {
                    ac: number_from_1("AC", rest[0]).map_err(at)?,
                    cycle: number_from_1("CYCLE", rest[1]).map_err(at)?,
                    step,
                    setup,
                    value: finite("VALUE", rest[rest.len() - 1]).map_err(at)?,
                })
            }
            "temperature" | "cross-talk" => {
                let form = if kind == "temperature" {
                    "AC:COEFF (arcsec per °C), e.g. 1:0.2"
                } else {
                    "AC:COEFF (arcsec of reading per arcsec of reading_y), e.g. 1:0.01"
                };
                let at = |problem| bad(problem, form);
                if n != 2 {
                    return Err(at(SpecProblem::part_count(n, "2")));
                }
                let ac = number_from_1("AC", parts[0]).map_err(at)?;
                let value = finite("COEFF", parts[1]).map_err(at)?;
                Ok(if kind == "temperature" {
                    Effect::Temperature { ac, value }
                } else {
                    Effect::CrossTalk { ac, value }
                })
            }
            "direction" => {
                let form = "VALUE or AC:VALUE, e.g. 0.2 or 1:0.2";
                let at = |problem| bad(problem, form);
                match n {
                    1 => Ok(Effect::Direction {
                        ac: None,
                        value: finite("VALUE", parts[0]).map_err(at)?,
                    }),
                    2 => Ok(Effect::Direction {
                        ac: Some(number_from_1("AC", parts[0]).map_err(at)?),
                        value: finite("VALUE", parts[1]).map_err(at)?,
                    }),
                    _ => Err(at(SpecProblem::PartsCount {
                        found: n,
                        wanted: "1 or 2",
                    })),
                }
            }
            "outlier" => {
                let form = "CYCLE:STEP:AC:VALUE or SETUP:CYCLE:STEP:AC:VALUE, e.g. 3:7:1:2.0";
                let at = |problem| bad(problem, form);
                let (setup, rest) = match n {
                    4 => (None, &parts[..]),
                    5 => (
                        Some(number_from_1("SETUP", parts[0]).map_err(at)?),
                        &parts[1..],
                    ),
                    _ => {
                        return Err(at(SpecProblem::PartsCount {
                            found: n,
                            wanted: "4 or 5",
                        }));
                    }
                };
                Ok(Effect::Outlier {
                    cycle: number_from_1("CYCLE", rest[0]).map_err(at)?,
                    step: whole("STEP", rest[1]).map_err(at)?,
                    ac: number_from_1("AC", rest[2]).map_err(at)?,
                    setup,
                    value: finite("VALUE", rest[3]).map_err(at)?,
                })
            }
            "rezero" => Err(SpecError::RezeroGiven {
                spec: spec.to_string(),
            }),
            _ => Err(SpecError::UnknownKind {
                kind: kind.to_string(),
            }),
        }
    }
}

impl fmt::Display for Effect {
    /// A one-line description for people, e.g. `offset-step of ac 2 from cycle 4: 0.5"`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Effect::Drift {
                ac,
                value,
                quadratic,
            } => {
                write!(f, "drift of ac {ac}: {value}\"/h")?;
                if let Some(q) = quadratic {
                    write!(f, " + {q}\"/h² · t²")?;
                }
                Ok(())
            }
            Effect::OffsetStep {
                ac,
                cycle,
                step,
                setup,
                value,
            } => {
                write!(f, "offset-step of ac {ac} from ")?;
                if let Some(s) = setup {
                    write!(f, "setup {s}, ")?;
                }
                write!(f, "cycle {cycle}")?;
                if let Some(s) = step {
                    write!(f, ", step {s}")?;
                }
                write!(f, ": {value}\"")
            }
            Effect::Temperature { ac, value } => {
                write!(f, "temperature coefficient of ac {ac}: {value}\"/°C")
            }
            Effect::CrossTalk { ac, value } => write!(f, "cross-talk of ac {ac}: {value}"),
            Effect::Rezero {
                ac, setup, offsets, ..
            } => {
                write!(f, "rezero of ac {ac}")?;
                if let Some(s) = setup {
                    write!(f, " in setup {s}")?;
                }
                let list: Vec<String> = offsets.iter().map(|o| format!("{o}")).collect();
                write!(f, ": offsets [{}]\"", list.join(", "))
            }
            Effect::Direction {
                ac: Some(ac),
                value,
            } => {
                write!(f, "direction (ccw − cw) of ac {ac}: {value}\"")
            }
            Effect::Direction { ac: None, value } => write!(f, "direction (ccw − cw): {value}\""),
            Effect::Outlier {
                cycle,
                step,
                ac,
                setup,
                value,
            } => {
                write!(f, "outlier at ")?;
                if let Some(s) = setup {
                    write!(f, "setup {s}, ")?;
                }
                write!(f, "cycle {cycle}, step {step}, ac {ac}: {value}\"")
            }
        }
    }
}

/// A command-line form of an effect, a harmonic, a model or a habit (e.g. `AC:RATE`) that
/// cannot be read; the message names the kind, the spec, the faulty part and the expected
/// form.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SpecError {
    /// A spec of a known form with a faulty part.
    #[error("{what} \"{spec}\": {problem} (expected {form})")]
    Part {
        /// What the spec describes: `drift effect`, `harmonic`, `temperature model`,
        /// `rezero`, …
        what: String,
        /// The spec as given.
        spec: String,
        /// What is wrong with it.
        problem: SpecProblem,
        /// The form expected, with an example.
        form: &'static str,
    },
    /// A `rezero` effect given by hand: its offsets are drawn by the simulation.
    #[error(
        "rezero effect \"{spec}\": the offsets of a zero set anew every cycle are drawn by \
         the simulation (simulate --rezero AC:SIGMA), not given one by one"
    )]
    RezeroGiven {
        /// The spec as given.
        spec: String,
    },
    /// An effect kind that is not one of [`KINDS`].
    #[error("unknown effect kind \"{kind}\" (known kinds: {})", KINDS.join(", "))]
    UnknownKind {
        /// The kind as given.
        kind: String,
    },
}

impl SpecError {
    /// A spec of `what` whose faulty part is `problem`; `form` is the form expected.
    pub(crate) fn part(
        what: impl Into<String>,
        spec: &str,
        problem: SpecProblem,
        form: &'static str,
    ) -> SpecError {
        SpecError::Part {
            what: what.into(),
            spec: spec.to_string(),
            problem,
            form,
        }
    }

    /// What is wrong, as one line (the error's message).
    pub fn message(&self) -> String {
        self.to_string()
    }
}

/// The faulty part of a command-line spec ([`SpecError::Part`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SpecProblem {
    /// Not as many `:`-separated parts as the form has.
    #[error("{found} part(s) separated by ':', want {wanted}")]
    PartCount {
        /// The number of parts given.
        found: usize,
        /// The numbers the form allows, e.g. `2 or 3`.
        wanted: String,
    },
    /// The same as [`SpecProblem::PartCount`], worded `parts` (the direction and outlier
    /// effects' wording).
    #[error("{found} parts separated by ':', want {wanted}")]
    PartsCount {
        /// The number of parts given.
        found: usize,
        /// The numbers the form allows, e.g. `1 or 2`.
        wanted: &'static str,
    },
    /// A part that is not a whole number ≥ 1.
    #[error("{part} \"{text}\" is not a whole number ≥ 1")]
    NotFromOne {
        /// The part's name in the form: `AC`, `CYCLE`, `ORDER`, …
        part: &'static str,
        /// Its text.
        text: String,
    },
    /// A part that is not a whole number ≥ 0.
    #[error("{part} \"{text}\" is not a whole number ≥ 0")]
    NotWhole {
        /// The part's name in the form: `STEP`.
        part: &'static str,
        /// Its text.
        text: String,
    },
    /// A part that is not a finite number.
    #[error("{}\"{text}\" is not a finite number", named(*part))]
    NotFinite {
        /// The part's name in the form (`RATE`, `VALUE`, …), if the message names it.
        part: Option<&'static str>,
        /// Its text.
        text: String,
    },
    /// A part that is not a finite number ≥ 0.
    #[error("\"{text}\" is not a finite number ≥ 0")]
    NotNonNegative {
        /// Its text.
        text: String,
    },
}

impl SpecProblem {
    /// [`SpecProblem::PartCount`].
    pub(crate) fn part_count(found: usize, wanted: impl Into<String>) -> SpecProblem {
        SpecProblem::PartCount {
            found,
            wanted: wanted.into(),
        }
    }
}

/// `NAME ` before a quoted part, or nothing.
fn named(part: Option<&str>) -> String {
    part.map_or(String::new(), |p| format!("{p} "))
}

/// A part that must be a whole number ≥ 1.
pub(crate) fn number_from_1(part: &'static str, text: &str) -> Result<u32, SpecProblem> {
    match text.parse::<u32>() {
        Ok(v) if v >= 1 => Ok(v),
        _ => Err(SpecProblem::NotFromOne {
            part,
            text: text.to_string(),
        }),
    }
}

fn whole(part: &'static str, text: &str) -> Result<usize, SpecProblem> {
    text.parse::<usize>().map_err(|_| SpecProblem::NotWhole {
        part,
        text: text.to_string(),
    })
}

/// A part that must be a finite number.
pub(crate) fn finite(part: &'static str, text: &str) -> Result<f64, SpecProblem> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(SpecProblem::NotFinite {
            part: Some(part),
            text: text.to_string(),
        }),
    }
}
