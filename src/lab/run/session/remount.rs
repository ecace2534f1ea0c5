//! A mounting that awaits its remount: the table to the mounting's first stop, the
//! operator's confirmation, the table's position checked (not moved while the polygon
//! was remounted: within [`REMOUNT_TOLERANCE_DEG`]), every autocollimator seeing a face,
//! then the first stop against the mountings before (`verify.rs`, through a visit) and
//! the confirmation kept.

use super::super::REMOUNT_TOLERANCE_DEG;
use super::super::mounting::Remount;
use super::visit::{Purpose, Visit};
use super::{Action, Event, Outcome, Session, Step, TABLE, role};
use crate::lab::InstrumentError;
use crate::measurement::Stop;

/// Where a remount is; each state that asks names what it waits for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(in crate::lab::run) enum RemountStep {
    /// The table to send to the mounting's first stop.
    Start { stop: Stop },
    /// Waiting for the table at `commanded_deg`.
    Moving { stop: Stop, commanded_deg: f64 },
    /// Waiting for the operator.
    Asking { stop: Stop, commanded_deg: f64 },
    /// Waiting for the table's position.
    Positioning { stop: Stop, commanded_deg: f64 },
    /// Autocollimator `ac` to read once (does it see a face?); `reported_deg` the
    /// table's position.
    Probe {
        stop: Stop,
        commanded_deg: f64,
        reported_deg: f64,
        ac: u32,
    },
    /// Waiting for autocollimator `ac`'s reply.
    Probing {
        stop: Stop,
        commanded_deg: f64,
        reported_deg: f64,
        ac: u32,
    },
}

impl Session {
    /// What the remount asks next.
    pub(super) fn remount_next(&mut self, r: RemountStep) -> Step {
        match r {
            RemountStep::Start { stop } => {
                let commanded_deg = self.mounting.table_deg(&stop, self.settings.faces);
                self.commanded = None;
                self.ask(
                    Action::Move {
                        to_deg: commanded_deg,
                    },
                    Step::Remount(RemountStep::Moving {
                        stop,
                        commanded_deg,
                    }),
                )
            }
            RemountStep::Probe {
                stop,
                commanded_deg,
                reported_deg,
                ac,
            } => {
                if ac as usize > self.settings.autocollimators() {
                    // The faces the autocollimators see are those the mounting says.
                    let acs = self.settings.acs().collect();
                    return self.start_visit(Visit::new(
                        Purpose::NewMounting {
                            remounted_at: Some(reported_deg),
                        },
                        stop,
                        acs,
                    ));
                }
                self.ask(
                    Action::Read { ac },
                    Step::Remount(RemountStep::Probing {
                        stop,
                        commanded_deg,
                        reported_deg,
                        ac,
                    }),
                )
            }
            // The others wait for their event.
            waiting => Step::Remount(waiting),
        }
    }

    /// What the remount makes of the event answering its action.
    pub(super) fn remount_told(&mut self, r: RemountStep, event: Event) -> Step {
        match (r, event) {
            (RemountStep::Moving { .. } | RemountStep::Positioning { .. }, Event::Failed(e)) => {
                self.end(Outcome::from_instrument(TABLE, &e))
            }
            (
                RemountStep::Moving {
                    stop,
                    commanded_deg,
                },
                Event::Moved { at_deg },
            ) => self.ask_remount(stop, commanded_deg, at_deg),
            (RemountStep::Asking { .. }, Event::Remounted { confirmed: false }) => {
                self.end(Outcome::Interrupted)
            }
            (
                RemountStep::Asking {
                    stop,
                    commanded_deg,
                },
                Event::Remounted { confirmed: true },
            ) => self.ask(
                Action::Position,
                Step::Remount(RemountStep::Positioning {
                    stop,
                    commanded_deg,
                }),
            ),
            (
                RemountStep::Positioning {
                    stop,
                    commanded_deg,
                },
                Event::Position { deg },
            ) => self.table_after_remount(stop, commanded_deg, deg),
            (
                RemountStep::Probing {
                    stop,
                    commanded_deg,
                    reported_deg,
                    ac,
                },
                Event::Read(_),
            ) => Step::Remount(RemountStep::Probe {
                stop,
                commanded_deg,
                reported_deg,
                ac: ac + 1,
            }),
            (
                RemountStep::Probing {
                    stop,
                    commanded_deg,
                    ac,
                    ..
                },
                Event::Failed(e),
            ) => self.no_face_seen(stop, commanded_deg, ac, &e),
            (other, _) => Step::Remount(other),
        }
    }

    /// The table at the mounting's first stop, reporting `at_deg` degrees: the operator
    /// is asked to remount the polygon there, each autocollimator facing the face the
    /// mounting puts before it at `stop`.
    fn ask_remount(&mut self, stop: Stop, commanded_deg: f64, at_deg: f64) -> Step {
        let mounting = self.mounting;
        let settings = &self.settings;
        let remount = Remount {
            mounting,
            table_deg: at_deg,
            faces: settings
                .acs()
                .map(|ac| (ac, mounting.face(settings, ac, stop.step)))
                .collect(),
        };
        self.ask(
            Action::Remount(remount),
            Step::Remount(RemountStep::Asking {
                stop,
                commanded_deg,
            }),
        )
    }

    /// The table's position `deg` after the remount against `commanded_deg`, where the
    /// polygon was to be mounted: more than [`REMOUNT_TOLERANCE_DEG`] apart (or no
    /// number), the table was moved while the polygon was remounted and the session
    /// ends; otherwise autocollimator 1 is read first to see a face.
    fn table_after_remount(&mut self, stop: Stop, commanded_deg: f64, deg: f64) -> Step {
        let mounting = self.mounting;
        let off_deg = (deg - commanded_deg).abs();
        if off_deg.is_nan() || off_deg > REMOUNT_TOLERANCE_DEG {
            return self.end(Outcome::InstrumentError(format!(
                "{TABLE}: after the remount of {mounting} it reports {deg}°, not \
                 {commanded_deg}° where the polygon was to be mounted: the table was \
                 moved while the polygon was remounted; mount it again with the table \
                 at {commanded_deg}°"
            )));
        }
        Step::Remount(RemountStep::Probe {
            stop,
            commanded_deg,
            reported_deg: deg,
            ac: 1,
        })
    }

    /// Autocollimator `ac` failed to read after the remount (`e`): every autocollimator
    /// must see a face, and a polygon mounted off the faces' directions leaves them
    /// without light (whole faces off: the first stop's check). The session ends,
    /// interrupted or naming the face to mount before `ac`, the table at
    /// `commanded_deg` degrees.
    fn no_face_seen(
        &mut self,
        stop: Stop,
        commanded_deg: f64,
        ac: u32,
        e: &InstrumentError,
    ) -> Step {
        if e.is_interrupted() {
            return self.end(Outcome::Interrupted);
        }
        let mounting = self.mounting;
        let face = mounting.face(&self.settings, ac, stop.step);
        self.end(Outcome::InstrumentError(format!(
            "{} sees no face after the remount of {mounting} ({e}): mount the polygon \
             with face {face} facing it, the table at {commanded_deg}°",
            role(ac)
        )))
    }
}
