//! Carrying a table's steps out: the actions each asks, and what the port's events do.

use std::time::Duration;

use super::{Asking, Running, SendPhase, TableOutcome, TableWire};
use crate::lab::InstrumentError;
use crate::lab::query::{Resynchronising, note};
use crate::lab::wire::{Wire, WireAction, WireError, WireEvent, check};

impl TableWire {
    /// The next action of the query under way; `None` once its reply is handled (or it
    /// failed), the step then over.
    fn poll_ask(&mut self) -> Option<WireAction> {
        let Some(Running::Ask(asking, _)) = &mut self.running else {
            return None;
        };
        let action = match asking.as_mut() {
            Asking::First(ex, _) | Asking::Second(ex) => ex.poll(),
            Asking::Doubtful(r, _) => r.poll(),
        };
        if action != WireAction::Done {
            return Some(action);
        }
        let Some(Running::Ask(asking, purpose)) = self.running.take() else {
            return None;
        };
        let (mut ex, first) = match *asking {
            Asking::Doubtful(mut r, q) => {
                match r.outcome() {
                    Some(Err(e)) => self.end(Err(e)),
                    // Back in step or not, the query is asked again and its answer taken.
                    _ => {
                        let second = Asking::Second(self.exchange(&q));
                        self.running = Some(Running::Ask(Box::new(second), purpose));
                    }
                }
                return None;
            }
            Asking::First(ex, q) => (ex, Some(q)),
            Asking::Second(ex) => (ex, None),
        };
        let (captures, line) = match ex.outcome() {
            Some(Ok(taken)) => taken,
            Some(Err(e)) => {
                self.end(Err(e));
                return None;
            }
            None => {
                self.end(Err(InstrumentError::Reported {
                    port: self.port.clone(),
                    message: "a query ended without an outcome".into(),
                }));
                return None;
            }
        };
        let command = ex.command().to_string();
        // A reply word for word the last one, which answered another query, cannot be
        // told from a stale copy of it where replies look alike (an ESP301's `1` is a
        // move done and an error code): the device is brought back in step and asked
        // again, and the second answer is taken.
        if let Some(q) = first
            && self
                .last
                .as_ref()
                .is_some_and(|(sent, reply)| *reply == line && *sent != command)
        {
            self.notes.push_back(note("doubtful", line));
            let resync = Resynchronising::new(self.resync(), self.options.query.reply_timeout);
            self.running = Some(Running::Ask(Box::new(Asking::Doubtful(resync, q)), purpose));
            return None;
        }
        self.last = Some((command.clone(), line.clone()));
        let sent = command
            .strip_suffix(self.line.command_end.as_str())
            .unwrap_or(&command)
            .to_string();
        self.answered(&sent, purpose, &captures, &line);
        None
    }

    /// The action of the step under way that is not a query's.
    fn step_action(&mut self) -> Option<WireAction> {
        let reply_timeout = self.options.query.reply_timeout;
        let action = match self.running.as_ref()? {
            Running::Ask(..) => return None,
            Running::ClearInput => WireAction::ClearInput,
            Running::Wait(d) => WireAction::Wait(*d),
            Running::Stop(_) => WireAction::Send(self.wire(&self.table.stop.send)),
            Running::Send { text, phase, .. } => match phase {
                SendPhase::Drain => WireAction::Drain,
                SendPhase::Send => WireAction::Send(self.wire(text)),
                SendPhase::Ack => WireAction::ReadLine(reply_timeout),
            },
            Running::Home { phase, deadline } => match phase {
                SendPhase::Drain => WireAction::Drain,
                SendPhase::Send => WireAction::Send(self.wire(&self.table.home.send)),
                SendPhase::Ack => {
                    let left = deadline - self.now_seconds;
                    if self.interrupted {
                        self.stop_then(self.interrupted_error());
                        return None;
                    }
                    if left <= 0.0 {
                        let e = self.device_error(
                            &self.table.home.send,
                            "",
                            format!(
                                "no acknowledgement of the home search within {} s; stopped it",
                                self.options.motion_timeout.as_secs_f64()
                            ),
                        );
                        self.stop_then(e);
                        return None;
                    }
                    let poll = self.options.poll_interval.max(Duration::from_millis(1));
                    WireAction::ReadLine(Duration::from_secs_f64(left).min(poll))
                }
            },
        };
        Some(action)
    }

    /// A reply to a command sent once that is not its acknowledgement: a refusal ends the
    /// operation; anything else is noted as discarded.
    fn not_acknowledged(&mut self, sent: &str, reply: String) {
        if let Some(refusal) = self
            .line
            .refusals
            .iter()
            .find(|r| r.matches(&reply).is_some())
        {
            let e = self.device_error(
                sent,
                &reply,
                format!(
                    "the controller refused the command (a reply of the form `{}`)",
                    refusal.as_str()
                ),
            );
            self.end(Err(e));
        } else {
            self.notes.push_back(note("discarded", reply));
        }
    }

    /// What the port did for the step under way (not a query's).
    fn step_told(&mut self, event: WireEvent) {
        let Some(running) = self.running.take() else {
            return;
        };
        if let Running::Stop(then) = running {
            match (then, event) {
                (Some(e), _) => self.end(Err(*e)),
                (None, WireEvent::Failed(e)) => self.end(Err(e)),
                (None, _) => {}
            }
            return;
        }
        if let WireEvent::Failed(e) = event {
            return self.end(Err(e));
        }
        match running {
            Running::Send {
                command,
                text,
                phase,
            } => match (phase, event) {
                (SendPhase::Drain, _) => {
                    self.running = Some(Running::Send {
                        command,
                        text,
                        phase: SendPhase::Send,
                    })
                }
                (SendPhase::Send, _) if command.ack.is_some() => {
                    self.running = Some(Running::Send {
                        command,
                        text,
                        phase: SendPhase::Ack,
                    })
                }
                (SendPhase::Ack, WireEvent::Line(None)) => {
                    let sent = self.wire(&text);
                    self.notes.push_back(note("no acknowledgement", sent));
                }
                (SendPhase::Ack, WireEvent::Line(Some(reply)))
                    if command
                        .ack
                        .as_ref()
                        .is_none_or(|a| a.matches(&reply).is_none()) =>
                {
                    self.not_acknowledged(&text, reply);
                }
                _ => {}
            },
            Running::Home { phase, deadline } => match (phase, event) {
                (SendPhase::Drain, _) => {
                    self.running = Some(Running::Home {
                        phase: SendPhase::Send,
                        deadline,
                    })
                }
                (SendPhase::Send, _) => {
                    self.running = Some(Running::Home {
                        phase: SendPhase::Ack,
                        deadline: self.now_seconds + self.options.motion_timeout.as_secs_f64(),
                    })
                }
                (SendPhase::Ack, WireEvent::Line(Some(reply))) => {
                    let acknowledged =
                        (self.table.home.ack.as_ref()).is_some_and(|a| a.matches(&reply).is_some());
                    if !acknowledged {
                        let sent = self.table.home.send.clone();
                        self.not_acknowledged(&sent, reply);
                        if self.outcome.is_none() {
                            self.running = Some(Running::Home { phase, deadline });
                        }
                    }
                }
                (SendPhase::Ack, _) => self.running = Some(Running::Home { phase, deadline }),
            },
            Running::Ask(..) | Running::ClearInput | Running::Wait(_) | Running::Stop(_) => {}
        }
    }
}

impl Wire for TableWire {
    type Output = TableOutcome;

    fn poll(&mut self) -> WireAction {
        loop {
            if let Some(n) = self.notes.pop_front() {
                return n;
            }
            if self.outcome.is_some() {
                return WireAction::Done;
            }
            if self.running.is_none() {
                if !self.start_next() {
                    return WireAction::Done;
                }
                continue;
            }
            if let Some(action) = self.poll_ask() {
                return action;
            }
            if let Some(action) = self.step_action() {
                self.asked = Some(action.clone());
                return action;
            }
        }
    }

    fn tell(&mut self, now_seconds: f64, event: WireEvent) -> Result<(), WireError> {
        if let Some(Running::Ask(asking, _)) = &mut self.running {
            let told = match asking.as_mut() {
                Asking::First(ex, _) | Asking::Second(ex) => ex.tell(now_seconds, event),
                Asking::Doubtful(r, _) => r.tell(now_seconds, event),
            };
            if told.is_ok() {
                self.now_seconds = self.now_seconds.max(now_seconds);
            }
            return told;
        }
        check(self.asked.as_ref(), now_seconds, &event)?;
        // The clock told never goes back, and a wait or a read that timed out took at
        // least its time: a driver whose clock stands still (or a Python driver that
        // passes the same `now`) still reaches the motion's and the home search's
        // time-outs instead of polling for ever.
        let took = match (self.asked.take(), &event) {
            (Some(WireAction::Wait(d)), _) => d.as_secs_f64(),
            (Some(WireAction::ReadLine(t)), WireEvent::Line(None)) => t.as_secs_f64(),
            _ => 0.0,
        };
        self.now_seconds = now_seconds.max(self.now_seconds + took);
        self.step_told(event);
        Ok(())
    }

    fn outcome(&mut self) -> Option<Result<TableOutcome, InstrumentError>> {
        self.outcome.take()
    }

    fn interrupt(&mut self) {
        self.interrupted = true;
    }
}
