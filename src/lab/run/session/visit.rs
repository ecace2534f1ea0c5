//! The visit of one stop: the table moved there (approached from the cycle's direction
//! when the visit measures), settled, and each autocollimator read until its readings
//! agree (`repeat.rs`); then what the visit was for — a reading kept, a check before the
//! first reading decided, a reading measured again judged.
//!
//! Every stop is approached from its cycle's direction (a re-measured reading from its
//! own): the last move onto it increases the angle in a clockwise cycle and decreases it
//! in a counter-clockwise one, from a pre-position
//! [`approach_overshoot_deg`](super::super::approach_overshoot_deg) past the stop when the
//! table is not already on that side.

use super::super::live::Fit;
use super::super::repeat::{Offered, StopReading, StopReads};
use super::super::store::Record;
use super::super::verify;
use super::cycle::CycleChecking;
use super::{Action, Event, LogRecord, Outcome, Session, Step, TABLE, role};
use crate::lab::run::approach_overshoot_deg;
use crate::measurement::{Direction, Reading, Stop};

/// What a stop is visited for.
#[derive(Debug, Clone)]
pub(in crate::lab::run) enum Purpose {
    /// A resumed mounting's last stop read again (nothing kept).
    LastStop,
    /// A new mounting's first stop against the mountings before (nothing kept);
    /// `remounted_at`: the table's position when the remount was confirmed, to keep once
    /// the stop agrees.
    NewMounting { remounted_at: Option<f64> },
    /// The stop's readings measured and kept.
    Measure,
    /// A reading far beyond the run's noise measured again after its cycle.
    Again(Box<Again>),
}

/// A reading measured again: the check it belongs to, the fit that flagged it.
#[derive(Debug, Clone)]
pub(in crate::lab::run) struct Again {
    pub(super) check: CycleChecking,
    pub(super) fit: Fit,
    pub(super) flagged: Reading,
    pub(super) residual: f64,
}

/// Where a visit is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase {
    /// The table to move (`pre`: the move asked is to the pre-position).
    Moving { pre: bool },
    /// The table to settle.
    Settling,
    /// The autocollimators to read.
    Reading,
}

/// One stop visited.
#[derive(Debug, Clone)]
pub(in crate::lab::run) struct Visit {
    purpose: Purpose,
    stop: Stop,
    acs: Vec<u32>,
    phase: Phase,
    /// The position the table reported at the stop, degrees.
    encoder_deg: f64,
    /// The autocollimator being read (index into `acs`).
    next: usize,
    reads: Option<StopReads>,
    got: Vec<StopReading>,
}

impl Visit {
    /// A visit of `stop` for `purpose`, reading `acs` in order.
    pub(in crate::lab::run) fn new(purpose: Purpose, stop: Stop, acs: Vec<u32>) -> Visit {
        Visit {
            purpose,
            stop,
            acs,
            phase: Phase::Moving { pre: false },
            encoder_deg: f64::NAN,
            next: 0,
            reads: None,
            got: Vec::new(),
        }
    }

    /// Whether the table approaches the stop from the cycle's direction (a measuring
    /// visit), or is sent straight there (a check before the first reading).
    fn approaches(&self) -> bool {
        matches!(self.purpose, Purpose::Measure | Purpose::Again(_))
    }
}

impl Session {
    /// Starts a visit.
    pub(super) fn start_visit(&mut self, visit: Visit) -> Step {
        self.visit_next(visit)
    }

    /// The stop's table angle, degrees.
    fn target_deg(&self, visit: &Visit) -> f64 {
        self.mounting.table_deg(&visit.stop, self.settings.faces)
    }

    /// What the visit asks next.
    pub(super) fn visit_next(&mut self, mut v: Visit) -> Step {
        let target = self.target_deg(&v);
        match v.phase {
            Phase::Moving { .. } => {
                let from_its_side = v.approaches()
                    && self.commanded.is_some_and(|at| match v.stop.direction {
                        Direction::Cw => at < target,
                        Direction::Ccw => at > target,
                    });
                // A move that fails leaves the table somewhere unknown.
                self.commanded = None;
                if v.approaches() && !from_its_side {
                    let overshoot = approach_overshoot_deg(self.settings.faces);
                    let pre_deg = match v.stop.direction {
                        Direction::Cw => target - overshoot,
                        Direction::Ccw => target + overshoot,
                    };
                    v.phase = Phase::Moving { pre: true };
                    return self.ask(Action::Move { to_deg: pre_deg }, Step::Visit(Box::new(v)));
                }
                v.phase = Phase::Moving { pre: false };
                self.ask(Action::Move { to_deg: target }, Step::Visit(Box::new(v)))
            }
            Phase::Settling => {
                v.phase = Phase::Reading;
                let settle = self.settings.settle_seconds;
                if settle > 0.0 && settle.is_finite() {
                    let until_seconds = self.now_seconds + settle;
                    return self.ask(Action::Wait { until_seconds }, Step::Visit(Box::new(v)));
                }
                Step::Visit(Box::new(v))
            }
            Phase::Reading => {
                let Some(&ac) = v.acs.get(v.next) else {
                    return self.visit_done(v);
                };
                if v.reads.is_none() {
                    let Some(memory) = self.memory.get(ac as usize - 1) else {
                        return self.end(Outcome::InstrumentError(format!(
                            "{} is not connected",
                            role(ac)
                        )));
                    };
                    v.reads = Some(StopReads::new(memory, &self.settings, target));
                }
                self.ask(Action::Read { ac }, Step::Visit(Box::new(v)))
            }
        }
    }

    /// What the visit makes of the event answering its action.
    pub(super) fn visit_told(&mut self, mut v: Visit, event: Event) -> Step {
        match (v.phase, event) {
            (Phase::Moving { pre }, Event::Moved { at_deg }) => {
                let target = self.target_deg(&v);
                if pre {
                    let overshoot = approach_overshoot_deg(self.settings.faces);
                    self.commanded = Some(match v.stop.direction {
                        Direction::Cw => target - overshoot,
                        Direction::Ccw => target + overshoot,
                    });
                    v.phase = Phase::Moving { pre: false };
                } else {
                    v.encoder_deg = at_deg;
                    // A check's straight move leaves the approach to the measuring.
                    self.commanded = v.approaches().then_some(target);
                    v.phase = Phase::Settling;
                }
                Step::Visit(Box::new(v))
            }
            (Phase::Moving { .. }, Event::Failed(e)) => {
                self.end(Outcome::from_instrument(TABLE, &e))
            }
            (Phase::Reading, Event::Waited) | (Phase::Settling, Event::Waited) => {
                Step::Visit(Box::new(v))
            }
            (Phase::Reading, Event::Read(reply)) => self.offered(v, reply),
            (Phase::Reading, Event::Failed(e)) => {
                let ac = v.acs.get(v.next).copied().unwrap_or(1);
                self.end(Outcome::from_instrument(&role(ac), &e))
            }
            (_, _) => Step::Visit(Box::new(v)),
        }
    }

    /// A reply of the autocollimator being read, offered to its reads at the stop.
    fn offered(&mut self, mut v: Visit, reply: crate::lab::AcReading) -> Step {
        let Some(&ac) = v.acs.get(v.next) else {
            return Step::Visit(Box::new(v));
        };
        let i = ac as usize - 1;
        let port = self.kept.run.ac_names.get(i).cloned().unwrap_or_default();
        let at = verify::place(self.mounting, &v.stop);
        let (Some(reads), Some(memory)) = (v.reads.as_mut(), self.memory.get_mut(i)) else {
            return Step::Visit(Box::new(v));
        };
        let offered = reads.offer(reply, memory, &self.settings, (&role(ac), &port, &at));
        for text in reads.take_refused() {
            self.notes.push_back(Action::Log(LogRecord {
                device: format!("ac{ac}"),
                port: port.clone(),
                event: "refused".to_string(),
                text,
            }));
        }
        match offered {
            Offered::Again => Step::Visit(Box::new(v)),
            Offered::NoAgreement(message) => self.end(Outcome::InstrumentError(message)),
            Offered::Accepted(read) => {
                self.refused += read.refused;
                v.reads = None;
                v.next += 1;
                let reading = self.reading(&v, ac, &read);
                match v.purpose {
                    Purpose::Measure => Step::Keeping {
                        records: [Record::Reading(reading)].into(),
                        notes: Vec::new(),
                        then: Box::new(Step::Visit(Box::new(v))),
                    },
                    Purpose::Again(again) => self.judge_again(*again, reading),
                    Purpose::LastStop | Purpose::NewMounting { .. } => {
                        v.got.push(read);
                        Step::Visit(Box::new(v))
                    }
                }
            }
        }
    }

    /// The reading of autocollimator `ac` at the visit's stop.
    fn reading(&self, v: &Visit, ac: u32, read: &StopReading) -> Reading {
        Reading {
            setup: self.mounting.setup,
            cycle: v.stop.cycle,
            step: v.stop.step,
            ac,
            face: self.mounting.face(&self.settings, ac, v.stop.step),
            reading_arcsec: read.x_arcsec,
            direction: v.stop.direction,
            time_seconds: Some(self.now_seconds),
            reading_y_arcsec: read.y_arcsec,
            temperature_celsius: None,
            encoder_degrees: Some(v.encoder_deg),
            line: 0,
        }
    }

    /// Every autocollimator read: what the visit was for.
    fn visit_done(&mut self, v: Visit) -> Step {
        match v.purpose {
            Purpose::Measure | Purpose::Again(_) => Step::NextWork,
            Purpose::LastStop => {
                let verdict = verify::last_stop_verdict(&self.kept.run, v.stop, &v.got);
                self.log("compared", verdict.compared);
                match verdict.refused {
                    Some(outcome) => self.end(outcome),
                    None => Step::NextWork,
                }
            }
            Purpose::NewMounting { remounted_at } => {
                let verdict = verify::new_mounting_verdict(&self.kept.run, v.stop, &v.got);
                self.log("compared", verdict.compared);
                match (verdict.refused, remounted_at) {
                    // Not yet confirmed: nothing to withdraw.
                    (Some(outcome), Some(_)) => self.end(outcome),
                    // The polygon is to be mounted again: its remount is asked for again.
                    (Some(outcome), None) => Step::Keeping {
                        records: [Record::RemountWithdrawn].into(),
                        notes: Vec::new(),
                        then: Box::new(Step::End(outcome)),
                    },
                    (None, Some(table_deg)) => {
                        self.log(
                            "remounted",
                            format!("{}: confirmed, the table at {table_deg}°", self.mounting),
                        );
                        Step::Keeping {
                            records: [Record::Remounted { table_deg }].into(),
                            notes: Vec::new(),
                            then: Box::new(Step::NextWork),
                        }
                    }
                    (None, None) => Step::NextWork,
                }
            }
        }
    }
}
