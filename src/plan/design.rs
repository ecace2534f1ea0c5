//! A design without readings: what a metrologist decides before the polygon is on the
//! table, and its written form (docs/FORMAT.md §5.6).

use std::str::FromStr;

use serde::Deserialize;

use crate::measurement::MeasurementSet;
use crate::simulate::{SimulationConfig, TemperatureModel, simulate};

use super::PlanError;

/// A measuring design: the polygon, the autocollimators, the cycles, the closing
/// reading, the direction, the mountings and the time per stop. Its readings are not
/// needed to predict what it gives: the cofactor of a design does not depend on them.
///
/// ```
/// use polycal::plan::Design;
///
/// let paper = Design::default();
/// assert_eq!((paper.faces, paper.cycles, paper.ac_faces.as_slice()), (24, 6, &[1, 2][..]));
/// // the written form overrides a base design key by key
/// let d = paper.with_spec("name=three;ac-faces=1,2,5;cycles=3;bidirectional")?;
/// assert_eq!(d.name.as_deref(), Some("three"));
/// assert_eq!((d.ac_faces.len(), d.cycles, d.bidirectional), (3, 3, true));
/// assert_eq!(d.reading_count(), 3 * 25 * 3);
/// # Ok::<(), polycal::plan::PlanError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Design {
    /// A name for tables and JSON (`design 1`, … when none is given).
    pub name: Option<String>,
    /// Faces of the polygon N (= encoder positions), ≥ 3.
    pub faces: usize,
    /// The face each autocollimator reads at step 0 of mounting 1.
    pub ac_faces: Vec<usize>,
    /// Cycles per mounting, ≥ 1.
    pub cycles: u32,
    /// Whether clockwise cycles end with the closing reading at step N.
    pub closing: bool,
    /// Whether every second cycle runs counter-clockwise (with the closing reading).
    pub bidirectional: bool,
    /// Mountings of the polygon, ≥ 1.
    pub setups: u32,
    /// Whole faces the polygon is turned between mountings.
    pub setup_shift_faces: usize,
    /// The table's angle at step 0 of each mounting, degrees (empty: all at 0).
    pub table_shift_deg: Vec<f64>,
    /// Seconds per table stop, > 0.
    pub step_seconds: f64,
    /// The lab's temperature profile, when the run records it (the `temperature` column):
    /// a diagnosis can then test the autocollimators' temperature coefficients.
    pub temperature: Option<TemperatureModel>,
}

impl Default for Design {
    /// The paper's design: 24 faces, autocollimators on faces 1 and 2, 6 clockwise cycles
    /// with the closing reading, one mounting, 20 s per stop.
    fn default() -> Self {
        Design::from_config(&SimulationConfig::default())
    }
}

/// The keys of a design's written form, as they appear in a spec and a designs file.
pub const DESIGN_KEYS: [&str; 11] = [
    "name",
    "faces",
    "ac-faces",
    "cycles",
    "closing",
    "bidirectional",
    "setups",
    "setup-shift",
    "shift-deg",
    "step-seconds",
    "temperature",
];

impl Design {
    /// The design part of simulation settings (faces, autocollimators, cycles, closing,
    /// direction, mountings, time per stop).
    pub fn from_config(config: &SimulationConfig) -> Self {
        Design {
            name: None,
            faces: config.faces,
            ac_faces: config.ac_faces.clone(),
            cycles: config.cycles,
            closing: config.closing,
            bidirectional: config.bidirectional,
            setups: config.setups,
            setup_shift_faces: config.setup_shift_faces,
            table_shift_deg: config.table_shift_deg.clone(),
            step_seconds: config.step_seconds,
            temperature: config.temperature.clone(),
        }
    }

    /// Simulation settings of this design without truth, noise or effects: every reading
    /// of the run is 0.
    pub fn simulation_config(&self) -> SimulationConfig {
        SimulationConfig {
            faces: self.faces,
            ac_faces: self.ac_faces.clone(),
            cycles: self.cycles,
            closing: self.closing,
            bidirectional: self.bidirectional,
            setups: self.setups,
            setup_shift_faces: self.setup_shift_faces,
            table_shift_deg: self.table_shift_deg.clone(),
            step_seconds: self.step_seconds,
            noise_arcsec: 0.0,
            pitch_spread_arcsec: 0.0,
            encoder_harmonics: Vec::new(),
            setup_error_spread_arcsec: 0.0,
            temperature: self.temperature.clone(),
            ..SimulationConfig::default()
        }
    }

    /// The number of readings a run of this design takes.
    pub fn reading_count(&self) -> usize {
        self.simulation_config().reading_count()
    }

    /// The design with the same settings and another number of cycles.
    pub fn with_cycles(&self, cycles: u32) -> Self {
        Design {
            cycles,
            ..self.clone()
        }
    }

    /// Checks the design (the rules of `simulate`'s settings).
    ///
    /// # Errors
    ///
    /// [`PlanError::Design`] naming the first problem.
    pub fn validate(&self) -> Result<(), PlanError> {
        self.simulation_config().validate().map_err(design_error)
    }

    /// The design's readings, all 0, with their times (a run's readings do not change
    /// what the design gives). Refused up front when the readings alone would not fit in
    /// the memory available.
    ///
    /// # Errors
    ///
    /// [`PlanError::Design`] for an invalid design; [`PlanError::TooLarge`] for one whose
    /// readings would not fit.
    pub fn measurement_set(&self) -> Result<MeasurementSet, PlanError> {
        self.measurement_set_within(None)
    }

    /// [`Design::measurement_set`] held to a memory limit (bytes) instead of the
    /// machine's available memory.
    ///
    /// # Errors
    ///
    /// As [`Design::measurement_set`].
    pub fn measurement_set_within(
        &self,
        memory_limit_bytes: Option<u64>,
    ) -> Result<MeasurementSet, PlanError> {
        self.validate()?;
        super::check_memory(
            self.reading_count() as u128 * super::BYTES_PER_READING,
            "the readings of the design",
            memory_limit_bytes,
        )?;
        let (mut set, _) = simulate(&self.simulation_config()).map_err(design_error)?;
        set.source = format!("design {}", self.label());
        Ok(set)
    }

    /// The name, or a description of the design when it has none.
    pub fn label(&self) -> String {
        self.name.clone().unwrap_or_else(|| {
            format!(
                "{} faces, autocollimators at {}, {} cycle{}{}{}{}",
                self.faces,
                self.ac_faces
                    .iter()
                    .map(usize::to_string)
                    .collect::<Vec<_>>()
                    .join(","),
                self.cycles,
                if self.cycles == 1 { "" } else { "s" },
                if self.closing || self.bidirectional {
                    ", closing"
                } else {
                    ""
                },
                if self.bidirectional {
                    ", bidirectional"
                } else {
                    ""
                },
                if self.setups > 1 {
                    format!(", {} mountings", self.setups)
                } else {
                    String::new()
                }
            )
        })
    }

    /// This design with the keys of `spec` changed: `KEY=VALUE` pairs separated by `;`
    /// (keys [`DESIGN_KEYS`]; `closing` and `bidirectional` alone mean `=true`; lists are
    /// separated by `,`; `temperature` takes `simulate`'s profile
    /// `START:WARMUP:WARMUP_SECONDS:AMPLITUDE:PERIOD_SECONDS[:PHASE[:NOISE]]`, alone its
    /// default, `none` for no temperature column), e.g.
    /// `name=B;cycles=4;ac-faces=1,2,5;bidirectional`.
    ///
    /// # Errors
    ///
    /// [`PlanError::Spec`] naming the key and what is wrong with it.
    pub fn with_spec(&self, spec: &str) -> Result<Design, PlanError> {
        let mut design = self.clone();
        for part in spec.split(';').map(str::trim).filter(|p| !p.is_empty()) {
            let (key, value) = match part.split_once('=') {
                Some((k, v)) => (k.trim(), Some(v.trim())),
                None => (part, None),
            };
            design.set(key, value, spec)?;
        }
        Ok(design)
    }

    fn set(&mut self, key: &str, value: Option<&str>, spec: &str) -> Result<(), PlanError> {
        self.set_key(key, value).map_err(|problem| PlanError::Spec {
            spec: spec.to_string(),
            problem,
        })
    }

    fn set_key<'a>(&mut self, key: &str, value: Option<&'a str>) -> Result<(), DesignSpecError> {
        use DesignSpecError as E;
        let need = |v: Option<&'a str>| {
            v.ok_or_else(|| E::NeedsValue {
                key: key.to_string(),
            })
        };
        fn number<T: FromStr>(key: &str, text: &str) -> Result<T, DesignSpecError> {
            text.parse::<T>().map_err(|_| DesignSpecError::NotANumber {
                key: key.to_string(),
                text: text.to_string(),
            })
        }
        let flag = |v: Option<&str>| match v {
            None | Some("true") | Some("yes") => Ok(true),
            Some("false") | Some("no") => Ok(false),
            Some(other) => Err(E::NotAFlag {
                key: key.to_string(),
                text: other.to_string(),
            }),
        };
        match key.replace('_', "-").as_str() {
            "name" => {
                let name = need(value)?;
                if name.contains(char::is_control) {
                    return Err(E::ControlCharacter {
                        key: key.to_string(),
                        name: name.to_string(),
                    });
                }
                self.name = Some(name.to_string())
            }
            "faces" => self.faces = number(key, need(value)?)?,
            "cycles" => self.cycles = number(key, need(value)?)?,
            "setups" => self.setups = number(key, need(value)?)?,
            "setup-shift" => self.setup_shift_faces = number(key, need(value)?)?,
            "step-seconds" => {
                let seconds: f64 = number(key, need(value)?)?;
                if !(seconds.is_finite() && seconds > 0.0) {
                    return Err(E::StepNotPositive {
                        key: key.to_string(),
                        seconds,
                    });
                }
                self.step_seconds = seconds;
            }
            "temperature" => {
                self.temperature =
                    match value {
                        None | Some("default") => Some(TemperatureModel::default()),
                        Some("none") => None,
                        Some(text) => Some(text.parse::<TemperatureModel>().map_err(|error| {
                            E::Temperature {
                                key: key.to_string(),
                                text: text.to_string(),
                                error: Box::new(error),
                            }
                        })?),
                    }
            }
            "closing" => self.closing = flag(value)?,
            "bidirectional" => self.bidirectional = flag(value)?,
            "ac-faces" => {
                self.ac_faces = need(value)?
                    .split(',')
                    .map(|t| number(key, t.trim()))
                    .collect::<Result<_, _>>()?
            }
            "shift-deg" => {
                self.table_shift_deg = need(value)?
                    .split(',')
                    .map(|t| number::<f64>(key, t.trim()))
                    .collect::<Result<_, _>>()?
            }
            other => {
                return Err(E::UnknownKey {
                    key: other.to_string(),
                });
            }
        }
        Ok(())
    }

    /// Reads a designs file (`-`: standard input) and its designs ([`Design::parse_designs_file`]).
    ///
    /// # Errors
    ///
    /// [`PlanError::Io`] naming the file; [`PlanError::File`] with the line and column of
    /// bytes that are not UTF-8, a TOML error or a bad key.
    pub fn read_designs_file(
        path: &std::path::Path,
        base: &Design,
    ) -> Result<Vec<Design>, PlanError> {
        let (bytes, name) = crate::input::read_bytes(path)
            .map_err(|(file, source)| PlanError::Io { file, source })?;
        let text = crate::input::text::utf8(&bytes).map_err(|((line, column), message)| {
            PlanError::File {
                location: crate::input::Location::new(name.clone(), line, column),
                message,
            }
        })?;
        Design::parse_designs_file(text, &name, base)
    }

    /// The designs of a designs file (TOML, docs/FORMAT.md §5.6): `[[design]]` tables
    /// with the keys of [`DESIGN_KEYS`] (`ac-faces` and `shift-deg` as arrays), each
    /// changing `base`.
    ///
    /// # Errors
    ///
    /// [`PlanError::File`] with the file, line and column of a TOML error or a bad key.
    pub fn parse_designs_file(
        text: &str,
        source: &str,
        base: &Design,
    ) -> Result<Vec<Design>, PlanError> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct File {
            design: Vec<toml::Table>,
        }
        let located = |span: Option<std::ops::Range<usize>>, message: String| {
            let location = match span {
                Some(span) => crate::uncertainty::budget_file::location(source, text, span.start),
                None => crate::input::Location::file_only(source),
            };
            PlanError::File { location, message }
        };
        let file: File =
            toml::from_str(text).map_err(|e| located(e.span(), e.message().to_string()))?;
        let mut designs = Vec::with_capacity(file.design.len());
        for (index, table) in file.design.iter().enumerate() {
            let mut design = base.clone();
            for (key, value) in table {
                if let Some(wanted) = toml_type_mismatch(key, value) {
                    return Err(located(
                        key_span(text, index, key),
                        format!(
                            "design {}: `{key}` must be {wanted}, not {} {value}",
                            index + 1,
                            value.type_str()
                        ),
                    ));
                }
                let text_value = match value {
                    toml::Value::String(s) => s.clone(),
                    toml::Value::Integer(i) => i.to_string(),
                    toml::Value::Float(f) => f.to_string(),
                    toml::Value::Boolean(b) => b.to_string(),
                    toml::Value::Array(items) => items
                        .iter()
                        .map(|v| match v {
                            toml::Value::String(s) => s.clone(),
                            other => other.to_string(),
                        })
                        .collect::<Vec<_>>()
                        .join(","),
                    other => other.to_string(),
                };
                design
                    .set(key, Some(&text_value), &format!("[[design]] {}", index + 1))
                    .map_err(|e| {
                        located(
                            key_span(text, index, key),
                            match e {
                                PlanError::Spec { problem, .. } => {
                                    format!("design {}: {problem}", index + 1)
                                }
                                other => other.to_string(),
                            },
                        )
                    })?;
            }
            // a design whose values are each well formed but do not make a design
            // together (0 faces, an autocollimator twice, a shift not a number) is
            // refused at its table's header
            if let Err(e) = design.validate() {
                let header = text
                    .match_indices("[[design]]")
                    .nth(index)
                    .map(|(i, _)| i..i + "[[design]]".len());
                return Err(located(
                    header,
                    format!(
                        "design {}: {}",
                        index + 1,
                        match e {
                            PlanError::Design(reason) => reason,
                            other => other.to_string(),
                        }
                    ),
                ));
            }
            designs.push(design);
        }
        if designs.is_empty() {
            return Err(located(None, "no [[design]] table".into()));
        }
        Ok(designs)
    }
}

/// What a designs file's `key` must be in TOML when `value` is not that (docs/FORMAT.md
/// §5.6): a count is an integer (`faces = "24"` is refused), a flag a boolean, a list an
/// array; `None` when the type fits (or the key is unknown, refused by its name later).
fn toml_type_mismatch(key: &str, value: &toml::Value) -> Option<&'static str> {
    use toml::Value::{Array, Boolean, Float, Integer, String};
    let all = |items: &[toml::Value], ok: fn(&toml::Value) -> bool| items.iter().all(ok);
    let (fits, wanted) = match key.replace('_', "-").as_str() {
        "name" => (matches!(value, String(_)), "a string"),
        "faces" | "cycles" | "setups" | "setup-shift" => {
            (matches!(value, Integer(_)), "an integer")
        }
        "step-seconds" => (matches!(value, Integer(_) | Float(_)), "a number"),
        "closing" | "bidirectional" => (matches!(value, Boolean(_)), "true or false"),
        "temperature" => (
            matches!(value, String(_)),
            "a string (a profile, \"default\" or \"none\")",
        ),
        "ac-faces" => (
            matches!(value, Array(items) if all(items, |v| matches!(v, Integer(_)))),
            "an array of integers",
        ),
        "shift-deg" => (
            matches!(value, Array(items) if all(items, |v| matches!(v, Integer(_) | Float(_)))),
            "an array of numbers",
        ),
        _ => (true, ""),
    };
    (!fits).then_some(wanted)
}

/// Why one `KEY=VALUE` of a design's written form ([`Design::with_spec`], a designs
/// file's `[[design]]` table) is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum DesignSpecError {
    /// A key that needs a value without one.
    #[error("`{key}` needs a value")]
    NeedsValue {
        /// The key.
        key: String,
    },
    /// A value that is not a number of the key's kind.
    #[error("`{key}={text}`: not a valid number")]
    NotANumber {
        /// The key.
        key: String,
        /// The value (one item of a list).
        text: String,
    },
    /// A flag's value other than true, yes, false or no.
    #[error("`{key}={text}`: want true or false")]
    NotAFlag {
        /// The key.
        key: String,
        /// The value.
        text: String,
    },
    /// A name with a control character.
    #[error(
        "`{key}`: {name:?} holds a control character; a name is printed in tables and messages"
    )]
    ControlCharacter {
        /// The key.
        key: String,
        /// The name given.
        name: String,
    },
    /// A step time that is not a finite number > 0.
    #[error("`{key}`: {seconds} is not a time > 0")]
    StepNotPositive {
        /// The key.
        key: String,
        /// The step time, seconds.
        seconds: f64,
    },
    /// A temperature profile that cannot be read.
    #[error("`{key}={text}`: {error}")]
    Temperature {
        /// The key.
        key: String,
        /// The profile given.
        text: String,
        /// Why it cannot be read.
        error: Box<crate::simulate::ModelSpecError>,
    },
    /// A key that is not one of [`DESIGN_KEYS`].
    #[error("unknown key `{key}` (keys: {})", DESIGN_KEYS.join(", "))]
    UnknownKey {
        /// The key, `_` written `-`.
        key: String,
    },
}

/// A design the simulation settings refuse: their reason, without their prefix.
fn design_error(e: crate::simulate::SimulateError) -> PlanError {
    PlanError::Design(match e {
        crate::simulate::SimulateError::Config(reason) => reason.to_string(),
        other => other.to_string(),
    })
}

/// The byte range of `key` in the `index`-th `[[design]]` table of `text`, for the error's
/// line and column (the first occurrence after that table's header).
fn key_span(text: &str, index: usize, key: &str) -> Option<std::ops::Range<usize>> {
    let mut headers = text.match_indices("[[design]]").map(|(i, _)| i);
    let start = headers.nth(index)?;
    let rest = &text[start..];
    let at = rest
        .lines()
        .scan(0usize, |offset, line| {
            let here = *offset;
            *offset += line.len() + 1;
            Some((here, line))
        })
        .find(|(_, line)| {
            let t = line.trim_start();
            t.starts_with(key) && t[key.len()..].trim_start().starts_with('=')
        })
        .map(|(offset, line)| offset + (line.len() - line.trim_start().len()))?;
    Some(start + at..start + at + key.len())
}
