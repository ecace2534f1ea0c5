//! Where a session keeps a run: the [`Store`] trait, what a store holds of a run when a
//! session starts ([`RunSoFar`]), what a session asks it to keep ([`Record`]), and a
//! store in memory ([`MemoryStore`]). The run directory ([`RunDir`](super::RunDir)) is
//! the other store (`dir_store.rs`); a lab's own database can be a third.

use std::collections::BTreeSet;

use super::live::{Remeasured, Suspect};
use super::mounting::{Mounting, MountingRecord};
use super::noise::{NoiseRecord, RepeatNoise};
use super::repeat::LastValue;
use super::{RunError, RunSettings};
use crate::measurement::{Reading, Stop};

/// A reading's place in the run: (setup, cycle, step, autocollimator).
pub(super) type Key = (u32, u32, usize, u32);

/// The place of `reading` in the run.
pub(super) fn key(reading: &Reading) -> Key {
    (reading.setup, reading.cycle, reading.step, reading.ac)
}

/// What a store holds of a run when a session starts: the settings, the mountings, every
/// reading kept so far and what the checks recorded — everything the session's rules
/// decide from.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct RunSoFar {
    /// The run's settings.
    pub settings: RunSettings,
    /// The polygon's mountings in the order measured; the last is the one this session
    /// measures.
    pub mountings: Vec<MountingRecord>,
    /// Every reading kept, all mountings, in the order kept (a reading measured again in
    /// its first one's place).
    pub readings: Vec<Reading>,
    /// The (setup, cycle) pairs whose check after the cycle was done; `None` for a run
    /// that recorded none (every complete cycle counts as checked).
    pub checked_cycles: Option<Vec<(u32, u32)>>,
    /// The noise the run judged each autocollimator by at its latest check.
    pub repeat_noise: Vec<NoiseRecord>,
    /// Each autocollimator's last reply before this session that the store knows of (a
    /// run directory's traffic log), with the table angle commanded before it, degrees:
    /// autocollimator 1 first, `None` where none is known.
    pub last_replies: Vec<Option<(LastValue, f64)>>,
    /// Each autocollimator's port or name, autocollimator 1 first, for messages.
    pub ac_names: Vec<String>,
    /// The table's port or name, for messages.
    pub table_name: String,
}

impl RunSoFar {
    /// A run not begun: `settings`, the first mounting, no reading.
    pub fn new(settings: RunSettings) -> RunSoFar {
        let k = settings.autocollimators();
        RunSoFar {
            settings,
            mountings: vec![MountingRecord::new(Mounting::default())],
            readings: Vec::new(),
            checked_cycles: Some(Vec::new()),
            repeat_noise: Vec::new(),
            last_replies: vec![None; k],
            ac_names: (1..=k).map(|ac| format!("ac{ac}")).collect(),
            table_name: "table".to_string(),
        }
    }

    /// Adds the next mounting of the polygon (docs/FORMAT.md §7.3, *Several mountings*):
    /// the next session asks for the remount before it measures it.
    ///
    /// # Errors
    ///
    /// A mounting out of range ([`RunError::Settings`]), not the next one
    /// ([`RunError::MountingOrder`]) or after one not complete
    /// ([`RunError::MountingIncomplete`]); the paths in them are empty (a run in memory).
    pub fn add_mounting(&mut self, mounting: Mounting) -> Result<(), RunError> {
        let path = std::path::PathBuf::new();
        mounting
            .validate(&self.settings)
            .map_err(|error| RunError::Settings {
                path: path.clone(),
                error,
            })?;
        let last = self.mounting().setup;
        if mounting.setup != last + 1 {
            return Err(RunError::MountingOrder {
                path,
                requested: mounting.setup,
                last,
            });
        }
        let done = self.readings.iter().filter(|r| r.setup == last).count();
        let expected = self.settings.reading_count();
        if done < expected || self.unchecked_cycle().is_some() {
            return Err(RunError::MountingIncomplete {
                path,
                setup: last,
                done,
                expected,
            });
        }
        self.mountings.push(MountingRecord::new(mounting));
        Ok(())
    }

    /// The mounting this session measures (the last).
    pub fn mounting(&self) -> Mounting {
        self.mountings
            .last()
            .map_or_else(Mounting::default, |m| m.mounting)
    }

    /// Whether the polygon is still to be remounted for this session's mounting.
    pub fn awaits_remount(&self) -> bool {
        self.mountings
            .last()
            .is_some_and(MountingRecord::awaits_remount)
    }

    /// Readings of the whole run (every mounting measured).
    pub fn expected_readings(&self) -> usize {
        self.settings.reading_count() * self.mountings.len().max(1)
    }

    fn done(&self) -> BTreeSet<Key> {
        self.readings.iter().map(key).collect()
    }

    /// The stops of this session's mounting still to visit, each with the
    /// autocollimators still to read there, in order.
    pub fn remaining(&self) -> Vec<(Stop, Vec<u32>)> {
        remaining(&self.settings, self.mounting().setup, &self.done())
    }

    /// The latest complete cycle of this session's mounting whose check after the cycle
    /// was not done.
    pub fn unchecked_cycle(&self) -> Option<u32> {
        unchecked_cycle(
            &self.settings,
            self.mounting().setup,
            &self.done(),
            self.checked_cycles.as_deref(),
        )
    }
}

/// The stops of mounting `setup` still to visit when the readings `done` are kept, each
/// with the autocollimators still to read there, in the run's order.
pub(super) fn remaining(
    settings: &RunSettings,
    setup: u32,
    done: &BTreeSet<Key>,
) -> Vec<(Stop, Vec<u32>)> {
    settings
        .plan()
        .into_iter()
        .filter_map(|stop| {
            let acs: Vec<u32> = settings
                .acs()
                .filter(|&ac| !done.contains(&(setup, stop.cycle, stop.step, ac)))
                .collect();
            (!acs.is_empty()).then_some((stop, acs))
        })
        .collect()
}

/// The latest cycle of mounting `setup` whose readings are all in `done`, when it is not
/// among the `checked` ones (`None` checked: every complete cycle counts as checked).
pub(super) fn unchecked_cycle(
    settings: &RunSettings,
    setup: u32,
    done: &BTreeSet<Key>,
    checked: Option<&[(u32, u32)]>,
) -> Option<u32> {
    let checked = checked?;
    let plan = settings.plan();
    let complete = (1..=settings.cycles).rev().find(|&c| {
        plan.iter().filter(|s| s.cycle == c).all(|s| {
            settings
                .acs()
                .all(|ac| done.contains(&(setup, c, s.step, ac)))
        })
    })?;
    (!checked.contains(&(setup, complete))).then_some(complete)
}

/// What a session asks its store to keep (docs/FORMAT.md §7.3).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Record {
    /// A reading, measured at its stop: appended, and kept (synced) before the table
    /// moves again.
    Reading(Reading),
    /// A reading measured again after its cycle's check: `first` is replaced by
    /// `replacement` (same place), and `remeasured` says why.
    Replacement {
        /// The reading kept before.
        first: Reading,
        /// The reading that takes its place.
        replacement: Reading,
        /// The record of it (the manifest's `remeasured`).
        remeasured: Remeasured,
    },
    /// A reading far beyond the run's noise that measuring its stop again confirmed.
    Suspect(Suspect),
    /// The noise each autocollimator's readings were judged by, autocollimator 1 first.
    Noise(Vec<RepeatNoise>),
    /// The readings of this session's mounting do not fit the mountings before it.
    Misfit(String),
    /// The check after this cycle of this session's mounting was done.
    Checked {
        /// The cycle.
        cycle: u32,
    },
    /// The operator confirmed the remount, the table reporting this angle, degrees.
    Remounted {
        /// The table's position, degrees.
        table_deg: f64,
    },
    /// The remount's confirmation is withdrawn: its first stop showed the polygon not
    /// mounted as stated, so the next session asks for it again.
    RemountWithdrawn,
}

/// Why a store could not keep a record.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StoreError {
    /// The run directory could not write.
    #[error(transparent)]
    Run(#[from] RunError),
    /// The traffic log could not be written, so the record that would follow it was not.
    #[error("{}: {source}", path.display())]
    Log {
        /// The traffic log.
        path: std::path::PathBuf,
        /// What failed.
        source: std::io::Error,
    },
    /// A reading was not kept: the error, and the reading as its row would read.
    #[error("{source} ({what} not written: {row})")]
    NotWritten {
        /// Why not.
        source: Box<StoreError>,
        /// `the reading` or `the reading measured again`.
        what: &'static str,
        /// The reading's row.
        row: String,
    },
    /// A store of the caller's own failed.
    #[error("{0}")]
    Own(Box<dyn std::error::Error + Send + Sync>),
}

/// Where a session keeps a run: a run directory ([`RunDir`](super::RunDir)), memory
/// ([`MemoryStore`]) or the caller's own.
pub trait Store {
    /// The run as kept, for a session to start from.
    ///
    /// # Errors
    ///
    /// The store cannot be read.
    fn so_far(&self) -> Result<RunSoFar, StoreError>;

    /// Keeps `record` (whole or not at all: a record that fails leaves the store as it
    /// was before it).
    ///
    /// # Errors
    ///
    /// The record could not be kept; the session then ends with
    /// [`Outcome::FileError`](super::Outcome::FileError) saying so.
    fn keep(&mut self, record: &Record) -> Result<(), StoreError>;
}

/// A store in memory: the run as a [`RunSoFar`] and what the checks recorded, for a run
/// that lab software keeps in a database of its own, and for tests.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct MemoryStore {
    /// The run kept.
    pub run: RunSoFar,
    /// Readings measured again.
    pub remeasured: Vec<Remeasured>,
    /// Readings confirmed far off.
    pub suspect: Vec<Suspect>,
    /// The warnings that a mounting did not fit.
    pub misfits: Vec<String>,
}

impl MemoryStore {
    /// An empty run of `settings`.
    pub fn new(settings: RunSettings) -> MemoryStore {
        MemoryStore {
            run: RunSoFar::new(settings),
            remeasured: Vec::new(),
            suspect: Vec::new(),
            misfits: Vec::new(),
        }
    }
}

impl Store for MemoryStore {
    fn so_far(&self) -> Result<RunSoFar, StoreError> {
        Ok(self.run.clone())
    }

    fn keep(&mut self, record: &Record) -> Result<(), StoreError> {
        let run = &mut self.run;
        match record {
            Record::Reading(r) => run.readings.push(r.clone()),
            Record::Replacement {
                first,
                replacement,
                remeasured,
            } => {
                let place = run.readings.iter().position(|r| key(r) == key(first));
                let Some(i) = place else {
                    return Err(StoreError::Own(
                        format!(
                            "no reading of cycle {}, step {}, autocollimator {} to replace",
                            first.cycle, first.step, first.ac
                        )
                        .into(),
                    ));
                };
                run.readings[i] = replacement.clone();
                self.remeasured.push(remeasured.clone());
            }
            Record::Suspect(s) => self.suspect.push(s.clone()),
            Record::Noise(noise) => {
                let session = 1;
                let stated = run.settings.reading_noise_arcsec;
                run.repeat_noise = noise
                    .iter()
                    .zip(1..)
                    .map(|(n, ac)| NoiseRecord::of(ac, session, n, stated))
                    .collect();
            }
            Record::Misfit(warning) => {
                if let Some(last) = run.mountings.last_mut() {
                    last.misfit = Some(warning.clone());
                }
                self.misfits.push(warning.clone());
            }
            Record::Checked { cycle } => {
                let place = (run.mounting().setup, *cycle);
                if let Some(checked) = run.checked_cycles.as_mut()
                    && !checked.contains(&place)
                {
                    checked.push(place);
                }
            }
            Record::Remounted { table_deg } => {
                if let Some(last) = run.mountings.last_mut() {
                    last.confirmed = Some(super::rfc3339(super::unix_now()));
                    last.table_deg = Some(*table_deg);
                }
            }
            Record::RemountWithdrawn => {
                if let Some(last) = run.mountings.last_mut()
                    && last.mounting.setup > 1
                {
                    last.confirmed = None;
                    last.table_deg = None;
                }
            }
        }
        Ok(())
    }
}
