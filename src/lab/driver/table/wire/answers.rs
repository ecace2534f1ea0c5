//! What a query's reply decides in a table's operation: the next steps, or its end.

use super::{Purpose, StateUse, Step, TableOutcome, TableWire};
use crate::lab::driver::table::TableState;
use crate::lab::driver::table::reading::{accepted, classify_state};
use crate::lab::profile::{Captures, format_degrees};
use crate::lab::query::note;

impl TableWire {
    /// A query's reply `line` (read as `captures`) for `purpose`.
    pub(super) fn answered(&mut self, q: &str, purpose: Purpose, captures: &Captures, line: &str) {
        match purpose {
            Purpose::Identify => {
                let text = captures
                    .get("text")
                    .unwrap_or(line.trim())
                    .trim()
                    .to_string();
                self.end(Ok(TableOutcome::Identified(text)));
            }
            Purpose::State(state_use) => match classify_state(self, captures, line) {
                Err(e) => self.end(Err(e)),
                Ok(state) => self.state_answered(state_use, state),
            },
            Purpose::Error { motion } => {
                if let Err(e) = accepted(self, &motion, captures, line) {
                    self.end(Err(e));
                }
            }
            Purpose::Latched { left, previous } => {
                let Some(error) = &self.table.error else {
                    return;
                };
                if error.none.holds(&error.query.reply, captures) {
                    return;
                }
                self.notes.push_back(note("latched", line.to_string()));
                if previous.as_deref() != Some(line) && left > 1 {
                    let q = error.query.clone();
                    self.steps.push_front(Step::Ask(
                        Box::new(q),
                        Purpose::Latched {
                            left: left - 1,
                            previous: Some(line.to_string()),
                        },
                    ));
                }
            }
            Purpose::Referenced { after_home } => {
                let Some((query, when)) = &self.table.referenced else {
                    return;
                };
                let referenced = when.holds(&query.reply, captures);
                if !after_home {
                    self.start_referenced = Some(referenced);
                } else if !referenced {
                    let e = self.device_error(
                        q,
                        "",
                        "the home search ended but the axis does not report itself referenced"
                            .into(),
                    );
                    self.end(Err(e));
                }
            }
            Purpose::Position { target } => {
                let Some(position) = captures.number("deg") else {
                    let e =
                        self.device_error(q, line, "the position is not a finite number".into());
                    return self.end(Err(e));
                };
                if let Some(target) = target
                    && (position - target).abs() > self.options.position_tolerance_deg
                {
                    let e = self.device_error(
                        q,
                        line,
                        format!("the table stopped at {position}°, not at the commanded {target}°"),
                    );
                    return self.end(Err(e));
                }
                self.end(Ok(TableOutcome::At(position)));
            }
        }
    }

    fn state_answered(&mut self, state_use: StateUse, state: TableState) {
        let state_query = self.table.state.query.send.clone();
        match state_use {
            StateUse::Report => self.end(Ok(TableOutcome::State(state))),
            StateUse::AtStart => self.start_state = Some(state),
            StateUse::BeforeMove(target) => {
                if state != TableState::Ready {
                    let e = self.device_error(
                        &state_query,
                        "",
                        format!("the table is not ready for a move ({state:?})"),
                    );
                    return self.end(Err(e));
                }
                let command = self.table.motion.clone();
                let motion = command.send.replace("{deg}", &format_degrees(target));
                let position = self.table.position.clone();
                let steps = [
                    Step::SendOnce(Box::new(command), motion.clone()),
                    Step::CheckAccepted(motion.clone()),
                    Step::WaitReady(motion),
                    Step::Ask(
                        Box::new(position),
                        Purpose::Position {
                            target: Some(target),
                        },
                    ),
                ];
                for step in steps.into_iter().rev() {
                    self.steps.push_front(step);
                }
            }
            StateUse::Ready { motion, deadline } => match state {
                TableState::Ready => {}
                TableState::NotReferenced => {
                    let e = self.device_error(
                        &state_query,
                        "",
                        format!(
                            "after {:?} the table is not referenced: it lost its reference",
                            self.wire(&motion)
                        ),
                    );
                    self.end(Err(e));
                }
                TableState::Moving if self.now_seconds >= deadline => {
                    let e = self.device_error(
                        &motion,
                        "",
                        format!(
                            "the table was not ready {} s after the motion command; stopped it",
                            self.options.motion_timeout.as_secs_f64()
                        ),
                    );
                    self.stop_then(e);
                }
                TableState::Moving => {
                    let q = self.table.state.query.clone();
                    self.steps.push_front(Step::Ask(
                        Box::new(q),
                        Purpose::State(StateUse::Ready { motion, deadline }),
                    ));
                    self.steps
                        .push_front(Step::Wait(self.options.poll_interval));
                }
            },
        }
    }
}
