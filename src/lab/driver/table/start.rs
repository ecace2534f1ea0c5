//! Starting a table: the errors latched before the session, the `[[enable]]` commands,
//! the state, and the home search when the axis is not referenced.

use std::time::{Duration, Instant};

use super::{LATCHED_ERRORS_READ, ProfileTable, TableState};
use crate::lab::profile::Command;
use crate::lab::transport::Transport;
use crate::lab::{InstrumentError, RotaryTable};

impl<T: Transport> ProfileTable<T> {
    /// Reads away the errors the controller latched before this session (a fault of an
    /// earlier session, a command of another program), each noted as `latched` in the
    /// traffic log, so that none is taken for a refusal of this session's first command.
    /// The error query is asked until it reports none, gives the same line twice in a row
    /// (a fault register that reading does not clear, as Aerotech's AXISFAULT: a command
    /// of `[[enable]]` acknowledges it, or the start is refused naming it), or
    /// [`LATCHED_ERRORS_READ`] times.
    fn read_latched_errors(&mut self) -> Result<(), InstrumentError> {
        let Some(error) = self.table.error.clone() else {
            return Ok(());
        };
        let mut previous: Option<String> = None;
        for _ in 0..LATCHED_ERRORS_READ {
            let (captures, line) = self.ask(&error.query)?;
            if error.none.holds(&error.query.reply, &captures) {
                break;
            }
            self.transport.note("latched", &line);
            if previous.as_deref() == Some(line.as_str()) {
                break;
            }
            previous = Some(line);
        }
        Ok(())
    }

    /// Sends the home search once and, when the profile has an acknowledgement for it,
    /// waits for that as long as a motion may take: a controller that answers the home
    /// command only once the search has ended (Aerotech's `HOME`, which holds the
    /// controller's interpreter meanwhile) must not have the next query timed out and
    /// retried into a search still under way. Lines other than the acknowledgement are
    /// discarded; a refusal ends the start.
    fn send_home(&mut self, home: &Command) -> Result<(), InstrumentError> {
        let Some(ack) = &home.ack else {
            return self.send_once(home, &home.send);
        };
        self.transport.drain()?;
        self.transport.send(&self.wire(&home.send))?;
        let deadline = Instant::now() + self.options.motion_timeout;
        loop {
            if self.stop.is_set() {
                let _ = self.stop();
                return Err(InstrumentError::Interrupted {
                    port: self.transport.port().to_string(),
                });
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                let _ = self.stop();
                return Err(self.device_error(
                    &home.send,
                    "",
                    format!(
                        "no acknowledgement of the home search within {} s; stopped it",
                        self.options.motion_timeout.as_secs_f64()
                    ),
                ));
            }
            let wait = left.min(self.options.poll_interval.max(Duration::from_millis(1)));
            let Some(reply) = self.transport.read_line(wait)? else {
                continue;
            };
            if ack.matches(&reply).is_some() {
                return Ok(());
            }
            if let Some(refusal) = self
                .line
                .refusals
                .iter()
                .find(|r| r.matches(&reply).is_some())
            {
                return Err(self.device_error(
                    &home.send,
                    &reply,
                    format!(
                        "the controller refused the command (a reply of the form `{}`)",
                        refusal.as_str()
                    ),
                ));
            }
            self.transport.note("discarded", &reply);
        }
    }

    /// Whether the axis is referenced, by the profile's `referenced` query; `None` when
    /// the profile has none.
    fn referenced(&mut self) -> Result<Option<bool>, InstrumentError> {
        let Some((q, when)) = self.table.referenced.clone() else {
            return Ok(None);
        };
        let (captures, _) = self.ask(&q)?;
        Ok(Some(when.holds(&q.reply, &captures)))
    }

    fn home(&mut self) -> Result<(), InstrumentError> {
        let home = self.table.home.clone();
        self.send_home(&home)?;
        self.check_accepted(&home.send)?;
        self.wait_ready(&home.send)?;
        if self.referenced()? == Some(false) {
            let q = self
                .table
                .referenced
                .as_ref()
                .map_or(String::new(), |(q, _)| q.send.clone());
            return Err(self.device_error(
                &q,
                "",
                "the home search ended but the axis does not report itself referenced".into(),
            ));
        }
        Ok(())
    }

    /// Makes the axis ready to move (the struct's *Starting*): what
    /// [`RotaryTable::start`] does.
    pub(super) fn start_axis(&mut self) -> Result<(), InstrumentError> {
        self.transport.clear_input()?;
        self.read_latched_errors()?;
        for enable in self.table.enable.clone() {
            self.send_once(&enable, &enable.send)?;
            self.check_accepted(&enable.send)?;
        }
        let state = self.state()?;
        let can_tell = self.table.referenced.is_some() || self.table.state.not_referenced.is_some();
        let referenced = match self.referenced()? {
            Some(r) => r,
            None => state != TableState::NotReferenced,
        };
        match state {
            TableState::Moving => self.wait_ready("(motion in progress at start)")?,
            TableState::Ready | TableState::NotReferenced => {}
        }
        if !referenced || !can_tell {
            // A profile that cannot tell whether the axis is referenced homes it on every
            // start: the encoder's zero must be the same in every session of a run.
            self.home()?;
        }
        Ok(())
    }
}
