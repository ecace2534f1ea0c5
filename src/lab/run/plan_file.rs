//! A run that executes a planned design: the design of a `polycal plan --format json`
//! output (docs/FORMAT.md §5.6) as run settings (docs/FORMAT.md §7.3, `--plan`).

use serde::Deserialize;

use super::{Mounting, RunSettings, SettingsError};
use crate::input::Location;

/// Why a plan file cannot be run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PlanFileError {
    /// A line that is not a `plan --format json` object with its `design`.
    #[error("{location}: not a design of `plan --format json`: {message}")]
    Form {
        /// Where.
        location: Location,
        /// What the JSON reader said.
        message: String,
    },
    /// No design in the file.
    #[error("{file}: holds no design")]
    Empty {
        /// The file.
        file: String,
    },
    /// Several designs and none chosen.
    #[error("{file}: holds {} designs ({}): choose one by its name", names.len(), names.join(", "))]
    Several {
        /// The file.
        file: String,
        /// Their names.
        names: Vec<String>,
    },
    /// The chosen design is not in the file.
    #[error("{file}: no design named {name:?} (it holds {})", names.join(", "))]
    NotFound {
        /// The file.
        file: String,
        /// The name asked for.
        name: String,
        /// The names it holds.
        names: Vec<String>,
    },
    /// A mounting the design does not have.
    #[error("{location}: design {name:?} has {setups} mounting(s), not a mounting {setup}")]
    Mountings {
        /// Where the design is.
        location: Location,
        /// Its name.
        name: String,
        /// Its mountings.
        setups: u32,
        /// The mounting asked for.
        setup: u32,
    },
    /// A design whose mountings a run cannot take (a table shift out of range, or not one
    /// per mounting).
    #[error("{location}: design {name:?}: {error}")]
    Mounting {
        /// Where the design is.
        location: Location,
        /// Its name.
        name: String,
        /// What is wrong.
        error: String,
    },
    /// A design whose settings a run refuses.
    #[error("{location}: design {name:?}: {error}")]
    Settings {
        /// Where the design is.
        location: Location,
        /// Its name.
        name: String,
        /// The setting out of range.
        error: SettingsError,
    },
}

#[derive(Deserialize)]
struct PlanLine {
    name: String,
    design: PlannedDesign,
}

#[derive(Deserialize)]
struct PlannedDesign {
    faces: usize,
    ac_faces: Vec<usize>,
    cycles: u32,
    closing: bool,
    bidirectional: bool,
    setups: u32,
    #[serde(default)]
    setup_shift: usize,
    #[serde(default)]
    shift_deg: Vec<f64>,
}

/// A planned design as a run executes it: the settings of every mounting, and the
/// mountings (docs/FORMAT.md §7.3, *Several mountings*).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct PlannedRun {
    /// The settings of each mounting.
    pub settings: RunSettings,
    /// The mountings, setup 1 first: setup s at the design's table shift of s (0 without
    /// shifts), the polygon turned (s − 1)·`setup_shift` faces (modulo N).
    pub mountings: Vec<Mounting>,
    /// The design's name.
    pub name: String,
    /// Where the design is in its file.
    pub location: Location,
}

impl PlannedRun {
    /// Mounting `setup` of the design.
    ///
    /// # Errors
    ///
    /// [`PlanFileError::Mountings`] for a mounting the design does not have.
    pub fn mounting(&self, setup: u32) -> Result<Mounting, PlanFileError> {
        (setup as usize)
            .checked_sub(1)
            .and_then(|i| self.mountings.get(i))
            .copied()
            .ok_or_else(|| PlanFileError::Mountings {
                location: self.location.clone(),
                name: self.name.clone(),
                setups: self.mountings.len() as u32,
                setup,
            })
    }
}

/// The run of the design named `name` (the only one when `None`) of the
/// `plan --format json` output `bytes` (UTF-8, one JSON object per line, as `plan`
/// writes it for one design or several), read from `file`: faces, the autocollimators'
/// faces, cycles, the closing step and the direction of the cycles, and its mountings;
/// `base` gives the rest (settle time, readings per stop, noise).
///
/// # Errors
///
/// [`PlanFileError`]: bytes that are not UTF-8 or a line that is not a plan's JSON (at
/// their line and column), no design, several without a choice, an unknown name,
/// settings or mountings a run refuses.
pub fn run_from_plan(
    bytes: &[u8],
    file: &str,
    name: Option<&str>,
    base: &RunSettings,
) -> Result<PlannedRun, PlanFileError> {
    let text = crate::input::text::utf8(bytes).map_err(|((line, column), message)| {
        PlanFileError::Form {
            location: Location::new(file, line, column),
            message,
        }
    })?;
    let mut designs = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let parsed: PlanLine = serde_json::from_str(line).map_err(|e| PlanFileError::Form {
            location: Location::new(file, i as u64 + 1, e.column() as u64),
            message: e.to_string(),
        })?;
        designs.push((i as u64 + 1, parsed));
    }
    let names: Vec<String> = designs.iter().map(|(_, d)| d.name.clone()).collect();
    let chosen = match name {
        Some(wanted) => designs
            .into_iter()
            .find(|(_, d)| d.name == wanted)
            .ok_or_else(|| PlanFileError::NotFound {
                file: file.to_string(),
                name: wanted.to_string(),
                names: names.clone(),
            })?,
        None if designs.len() > 1 => {
            return Err(PlanFileError::Several {
                file: file.to_string(),
                names,
            });
        }
        None => designs.pop().ok_or_else(|| PlanFileError::Empty {
            file: file.to_string(),
        })?,
    };
    let (line, PlanLine { name, design }) = chosen;
    let location = Location::new(file, line, 1);
    let mut settings = base.clone();
    settings.faces = design.faces;
    settings.cycles = design.cycles;
    settings.closing = design.closing || design.bidirectional;
    settings.bidirectional = design.bidirectional;
    settings.ac_faces = design.ac_faces;
    settings
        .validate()
        .map_err(|error| PlanFileError::Settings {
            location: location.clone(),
            name: name.clone(),
            error,
        })?;
    let refused = |error: String| PlanFileError::Mounting {
        location: location.clone(),
        name: name.clone(),
        error,
    };
    if !design.shift_deg.is_empty() && design.shift_deg.len() != design.setups as usize {
        return Err(refused(format!(
            "{} table shift(s) for {} mounting(s)",
            design.shift_deg.len(),
            design.setups
        )));
    }
    if design.setups == 0 || design.setups > super::MAX_MOUNTINGS {
        return Err(refused(format!("{} mountings", design.setups)));
    }
    let n = settings.faces;
    let mut mountings = Vec::with_capacity(design.setups as usize);
    for s in 1..=design.setups {
        let m = Mounting::new(s)
            .with_shift_deg(design.shift_deg.get(s as usize - 1).copied().unwrap_or(0.0))
            .with_face_shift((s as usize - 1) % n * (design.setup_shift % n) % n);
        m.validate(&settings)
            .map_err(|e| refused(format!("mounting {s}: {e}")))?;
        mountings.push(m);
    }
    Ok(PlannedRun {
        settings,
        mountings,
        name,
        location,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: &str = r#"{"version":"0.1.0","name":"A","design":{"faces":8,"ac_faces":[1,2,5],"cycles":3,"closing":true,"bidirectional":false,"setups":1,"setup_shift":1,"shift_deg":[],"step_seconds":20.0},"faces":8}"#;
    const B: &str = r#"{"version":"0.1.0","name":"B","design":{"faces":12,"ac_faces":[1,2],"cycles":2,"closing":true,"bidirectional":true,"setups":1,"setup_shift":1,"shift_deg":[],"step_seconds":20.0},"faces":12}"#;
    const TWO: &str = r#"{"version":"0.1.0","name":"M","design":{"faces":8,"ac_faces":[1,2],"cycles":2,"closing":true,"bidirectional":false,"setups":2,"setup_shift":1,"shift_deg":[],"step_seconds":20.0},"faces":8}"#;

    fn base() -> RunSettings {
        RunSettings::new(3, 1).with_settle_seconds(0.5)
    }

    #[test]
    fn the_planned_design_becomes_the_runs_settings() {
        let s = run_from_plan(A.as_bytes(), "p.json", None, &base())
            .unwrap()
            .settings;
        assert_eq!(
            (
                s.faces,
                s.cycles,
                s.closing,
                s.bidirectional,
                s.ac_faces.clone()
            ),
            (8, 3, true, false, vec![1, 2, 5])
        );
        assert_eq!(s.settle_seconds, 0.5, "the rest from the command");
        let both = format!("{A}\n{B}\n");
        let s = run_from_plan(both.as_bytes(), "p.json", Some("B"), &base()).unwrap();
        assert_eq!((s.settings.faces, s.settings.bidirectional), (12, true));
        assert_eq!(s.mountings, [Mounting::default()]);
        // Two mountings, the polygon turned one face in the second.
        let two = run_from_plan(TWO.as_bytes(), "p.json", None, &base()).unwrap();
        assert_eq!(
            two.mountings,
            [Mounting::new(1), Mounting::new(2).with_face_shift(1)]
        );
        assert_eq!(two.mounting(2), Ok(Mounting::new(2).with_face_shift(1)));
        assert_eq!(
            two.mounting(3).unwrap_err().to_string(),
            "p.json:1:1: design \"M\" has 2 mounting(s), not a mounting 3"
        );
    }

    #[test]
    fn what_a_run_cannot_take_is_refused_at_its_place() {
        let both = format!("{A}\n{B}\n");
        let e = run_from_plan(both.as_bytes(), "p.json", None, &base()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "p.json: holds 2 designs (A, B): choose one by its name"
        );
        let e = run_from_plan(both.as_bytes(), "p.json", Some("C"), &base()).unwrap_err();
        assert!(e.to_string().contains("no design named \"C\""), "{e}");
        let shifts = TWO.replace(r#""shift_deg":[]"#, r#""shift_deg":[0,400]"#);
        let e = run_from_plan(shifts.as_bytes(), "p.json", None, &base()).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("p.json:1:1: design \"M\": mounting 2: shift 400"),
            "{e}"
        );
        let e = run_from_plan(b"{\"name\": 3}", "p.json", None, &base()).unwrap_err();
        assert!(e.to_string().starts_with("p.json:1:"), "{e}");
        let e = run_from_plan(b"{}\n\xff", "p.json", None, &base()).unwrap_err();
        assert!(e.to_string().starts_with("p.json:2:1: "), "{e}");
        let e = run_from_plan(b"", "p.json", None, &base()).unwrap_err();
        assert_eq!(
            e,
            PlanFileError::Empty {
                file: "p.json".into()
            }
        );
    }
}
