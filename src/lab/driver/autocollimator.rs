//! An autocollimator as its profile describes it.

use std::time::Duration;

use super::read_reply;
use crate::lab::profile::{AcProfile, LineSettings, Profile, ProfileError};
use crate::lab::query::{Resync, query};
use crate::lab::transport::Transport;
use crate::lab::{AcReading, Autocollimator, InstrumentError, QueryOptions};

/// An autocollimator driven through its profile's commands (module
/// [`crate::lab::driver`]).
///
/// ```
/// use std::sync::Arc;
/// use polycal::lab::driver::ProfileAutocollimator;
/// use polycal::lab::profile::Profile;
/// use polycal::lab::scripted::ScriptedStream;
/// use polycal::lab::transport::StreamTransport;
/// use polycal::lab::{Autocollimator, QueryOptions};
///
/// let stream = ScriptedStream::new()
///     .expect("s\n", "")
///     .expect("a\n", "4 003 12.345000 -1.234000\r");
/// let profile = Profile::load("elcomat3000")?;
/// let transport = StreamTransport::new("mem:ac1", stream);
/// let mut ac = ProfileAutocollimator::new(transport, &profile, QueryOptions::default())?;
/// ac.start()?;
/// let reading = ac.measure()?;
/// assert_eq!((reading.x_arcsec, reading.y_arcsec), (12.345, Some(-1.234)));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct ProfileAutocollimator<T> {
    transport: T,
    name: String,
    line: LineSettings,
    ac: AcProfile,
    options: QueryOptions,
    drain: Duration,
}

impl<T: Transport> ProfileAutocollimator<T> {
    /// A driver over `transport` speaking `profile`. On [`Autocollimator::start`] it
    /// waits 50 ms after the profile's start commands for lines still on their way
    /// before it clears the input ([`ProfileAutocollimator::with_drain`] changes that).
    ///
    /// # Errors
    ///
    /// [`ProfileError::WrongInstrument`] for a table's profile.
    pub fn new(
        transport: T,
        profile: &Profile,
        options: QueryOptions,
    ) -> Result<Self, ProfileError> {
        Ok(ProfileAutocollimator {
            transport,
            name: profile.name.clone(),
            line: profile.line.clone(),
            ac: profile.autocollimator()?.clone(),
            options,
            drain: Duration::from_millis(50),
        })
    }

    /// An ELCOMAT 3000 (the bundled profile `elcomat3000`).
    pub fn elcomat3000(transport: T, options: QueryOptions) -> Self {
        let profile = crate::lab::profile::bundled("elcomat3000");
        ProfileAutocollimator {
            transport,
            name: profile.name.clone(),
            line: profile.line.clone(),
            ac: match profile.kind {
                crate::lab::profile::ProfileKind::Autocollimator(ac) => *ac,
                crate::lab::profile::ProfileKind::Table(_) => {
                    unreachable!("the bundled elcomat3000 describes an autocollimator")
                }
            },
            options,
            drain: Duration::from_millis(50),
        }
    }

    /// Sets the wait between the start commands and clearing the input on start.
    pub fn with_drain(mut self, drain: Duration) -> Self {
        self.drain = drain;
        self
    }

    /// The profile's name.
    pub fn profile_name(&self) -> &str {
        &self.name
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// The transport, mutably.
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }

    fn wire(&self, command: &str) -> String {
        format!("{command}{}", self.line.command_end)
    }
}

impl<T: Transport> Autocollimator for ProfileAutocollimator<T> {
    fn port(&self) -> &str {
        self.transport.port()
    }

    fn start(&mut self) -> Result<(), InstrumentError> {
        for command in self.ac.start.clone() {
            self.transport.send(&self.wire(&command))?;
        }
        if !self.ac.start.is_empty() && !self.drain.is_zero() {
            std::thread::sleep(self.drain);
        }
        self.transport.clear_input()
    }

    fn identify(&mut self) -> Result<String, InstrumentError> {
        let command = self.wire(&self.ac.identify.send);
        let (line, template) = (&self.line, &self.ac.identify.reply);
        query(
            &mut self.transport,
            &self.options,
            None,
            &command,
            |reply| {
                read_reply(line, template, reply)
                    .map(|c| c.get("text").unwrap_or(reply.trim()).trim().to_string())
            },
        )
        .map(|(text, _)| text)
    }

    fn measure(&mut self) -> Result<AcReading, InstrumentError> {
        let resync_command = self.wire(&self.ac.identify.send);
        let identify = &self.ac.identify.reply;
        let is_reply = |line: &str| identify.matches(line).is_some();
        let resync = Resync {
            command: &resync_command,
            is_reply: &is_reply,
        };
        let command = self.wire(&self.ac.measure.send);
        let (line, ac) = (&self.line, &self.ac);
        query(
            &mut self.transport,
            &self.options,
            Some(&resync),
            &command,
            |reply| {
                // A refusal of the line's is named as such; the rest is the profile's.
                read_reply(line, &ac.measure.reply, reply)?;
                ac.reading(reply)
            },
        )
        .map(|(reading, _)| reading)
    }
}
