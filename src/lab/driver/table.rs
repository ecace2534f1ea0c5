//! A rotary table as its profile describes it.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

mod start;

use super::read_reply;
use crate::lab::profile::{
    Captures, Command, Condition, LineSettings, Profile, ProfileError, Query, TableProfile,
    Template, format_degrees,
};
use crate::lab::query::{Resync, query};
use crate::lab::transport::Transport;
use crate::lab::{InstrumentError, QueryOptions, RotaryTable, StopFlag};

/// The largest difference between the reported and the commanded position a move
/// accepts unless set otherwise, degrees.
pub const POSITION_TOLERANCE_DEG: f64 = 0.001;

/// How many errors latched before a session its start reads away at most: the longest
/// error queue of a bundled make (the ESP301 keeps ten).
const LATCHED_ERRORS_READ: usize = 10;

/// How the runner waits for and checks a table: the same for every profile.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct TableOptions {
    /// Reply deadline and retries of queries.
    pub query: QueryOptions,
    /// Time between two state queries while the table moves or homes.
    pub poll_interval: Duration,
    /// Longest a move or a home search may take.
    pub motion_timeout: Duration,
    /// Largest accepted difference between the reported and the commanded position, degrees.
    pub position_tolerance_deg: f64,
}

impl TableOptions {
    /// Options with `query` for the queries, 20 ms polling, 120 s per motion and a
    /// 0.001° tolerance.
    pub fn new(query: QueryOptions) -> TableOptions {
        TableOptions {
            query,
            poll_interval: Duration::from_millis(20),
            motion_timeout: Duration::from_secs(120),
            position_tolerance_deg: POSITION_TOLERANCE_DEG,
        }
    }

    /// Sets the reply deadline and retries of queries.
    pub fn with_query(mut self, query: QueryOptions) -> TableOptions {
        self.query = query;
        self
    }

    /// Sets the time between two state queries while the table moves or homes.
    pub fn with_poll_interval(mut self, poll_interval: Duration) -> TableOptions {
        self.poll_interval = poll_interval;
        self
    }

    /// Sets the longest a move or a home search may take.
    pub fn with_motion_timeout(mut self, motion_timeout: Duration) -> TableOptions {
        self.motion_timeout = motion_timeout;
        self
    }

    /// Sets the largest accepted difference between the reported and the commanded
    /// position, degrees.
    pub fn with_position_tolerance_deg(mut self, position_tolerance_deg: f64) -> TableOptions {
        self.position_tolerance_deg = position_tolerance_deg;
        self
    }
}

impl Default for TableOptions {
    /// Default queries, 20 ms polling, 120 s per motion, 0.001° tolerance.
    fn default() -> Self {
        TableOptions::new(QueryOptions::default())
    }
}

/// What a state reply says, read by the profile's conditions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum TableState {
    /// Ready for a move.
    Ready,
    /// Moving or homing.
    Moving,
    /// Not referenced: a home search is due.
    NotReferenced,
}

/// A rotary table driven through its profile's commands (module
/// [`crate::lab::driver`]).
///
/// A move is: the state (must be ready), the move command sent **once** (its
/// acknowledgement read when the profile has one, never a reason to send it again), the
/// error (must be none), the state every poll interval until ready, the position (must
/// be within tolerance of the target).
///
/// Starting is: pending input thrown away, the errors the controller latched before the
/// session read away (each noted `latched`), the `[[enable]]` commands each sent once and
/// checked, the state, and a home search when the axis is not referenced (or the profile
/// cannot tell), its acknowledgement, when the profile has one, awaited as long as a
/// motion may take.
///
/// ```
/// use polycal::lab::driver::{ProfileTable, TableOptions};
/// use polycal::lab::profile::Profile;
/// use polycal::lab::scripted::ScriptedStream;
/// use polycal::lab::transport::StreamTransport;
/// use polycal::lab::RotaryTable;
///
/// let stream = ScriptedStream::new()
///     .expect("ONT? 1\n", "1=1\n")
///     .expect("MOV 1 45\n", "")
///     .expect("ERR?\n", "0\n")
///     .expect("ONT? 1\n", "1=1\n")
///     .expect("POS? 1\n", "1=45.0000\n");
/// let profile = Profile::load("pi-gcs2")?;
/// let transport = StreamTransport::new("mem:table", stream);
/// let mut table = ProfileTable::new(transport, &profile, TableOptions::default())?;
/// assert_eq!(table.move_to(45.0)?, 45.0);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct ProfileTable<T> {
    transport: T,
    name: String,
    line: LineSettings,
    table: TableProfile,
    options: TableOptions,
    stop: StopFlag,
    /// The last query sent and the reply taken for it.
    last: Option<(String, String)>,
}

impl<T: Transport> ProfileTable<T> {
    /// A driver over `transport` speaking `profile`.
    ///
    /// # Errors
    ///
    /// [`ProfileError::WrongInstrument`] for an autocollimator's profile.
    pub fn new(
        transport: T,
        profile: &Profile,
        options: TableOptions,
    ) -> Result<Self, ProfileError> {
        Ok(ProfileTable {
            transport,
            name: profile.name.clone(),
            line: profile.line.clone(),
            table: profile.table()?.clone(),
            options,
            stop: StopFlag::new(),
            last: None,
        })
    }

    /// An SMC100 (the bundled profile `smc100`).
    pub fn smc100(transport: T, options: TableOptions) -> Self {
        let profile = crate::lab::profile::bundled("smc100");
        ProfileTable {
            transport,
            name: profile.name.clone(),
            line: profile.line.clone(),
            table: match profile.kind {
                crate::lab::profile::ProfileKind::Table(table) => *table,
                crate::lab::profile::ProfileKind::Autocollimator(_) => {
                    unreachable!("the bundled smc100 describes a table")
                }
            },
            options,
            stop: StopFlag::new(),
            last: None,
        }
    }

    /// Makes waits for motion watch `stop`: when it is set, the table is stopped and the
    /// move ends with [`InstrumentError::Interrupted`].
    pub fn with_stop_flag(mut self, stop: StopFlag) -> Self {
        self.stop = stop;
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

    fn wire(&self, command: &str) -> String {
        format!("{command}{}", self.line.command_end)
    }

    /// Asks `q` (retried as a query, resynchronised with the identification) and reads its
    /// reply.
    fn ask(&mut self, q: &Query) -> Result<(Captures, String), InstrumentError> {
        let resync_command = self.wire(&self.table.identify.send);
        let identify = &self.table.identify.reply;
        let is_reply = |line: &str| identify.matches(line).is_some();
        let resync = Resync {
            command: &resync_command,
            is_reply: &is_reply,
        };
        let command = self.wire(&q.send);
        let line = &self.line;
        let mut taken = query(
            &mut self.transport,
            &self.options.query,
            Some(&resync),
            &command,
            |reply| read_reply(line, &q.reply, reply),
        )?;
        // A reply word for word the last one, which answered another query, cannot be
        // told from a stale copy of it where replies look alike (an ESP301's `1` is a
        // move done and an error code): the device is brought back in step and asked
        // again, and the second answer is taken.
        if self
            .last
            .as_ref()
            .is_some_and(|(sent, reply)| *reply == taken.1 && *sent != command)
        {
            self.transport.note("doubtful", &taken.1);
            crate::lab::query::resync(&mut self.transport, &self.options.query, &resync)?;
            taken = query(
                &mut self.transport,
                &self.options.query,
                Some(&resync),
                &command,
                |reply| read_reply(line, &q.reply, reply),
            )?;
        }
        self.last = Some((command, taken.1.clone()));
        Ok(taken)
    }

    fn device_error(&self, sent: &str, received: &str, message: String) -> InstrumentError {
        InstrumentError::Device {
            port: self.transport.port().to_string(),
            sent: self.wire(sent),
            received: received.to_string(),
            message,
        }
    }

    /// `field value (name)` of a condition's field in a reply, for messages.
    fn describe(&self, condition: &Condition, captures: &Captures) -> String {
        let value = captures.get(&condition.field).unwrap_or("");
        let names = &self.table.state.names;
        match names
            .get(&condition.field)
            .and_then(|n| n.iter().find(|(k, _)| k.eq_ignore_ascii_case(value)))
        {
            Some((_, name)) => format!("{} {value} ({name})", condition.field),
            None => format!("{} {value}", condition.field),
        }
    }

    /// The state, as reported.
    ///
    /// # Errors
    ///
    /// A port failure, a query that fails after its retries, a fault the state reports
    /// (with the names of its bits), and a state that is neither ready, moving nor "not
    /// referenced" (a disabled or misconfigured controller).
    pub fn state(&mut self) -> Result<TableState, InstrumentError> {
        let q = self.table.state.query.clone();
        let (captures, line) = self.ask(&q)?;
        let state = &self.table.state;
        let template = &state.query.reply;
        if let Some(fault) = &state.fault
            && fault.holds(template, &captures)
        {
            let value = captures.get(&fault.field).unwrap_or("").to_string();
            let bits = bit_names(template, &fault.field, &value, state.bits.get(&fault.field));
            return Err(self.device_error(
                &q.send,
                &line,
                format!(
                    "the controller reports a fault ({} {value}{})",
                    fault.field,
                    if bits.is_empty() {
                        String::new()
                    } else {
                        format!(": {}", bits.join(", "))
                    }
                ),
            ));
        }
        // A state that is "ready" and "not referenced" at once is not referenced: an axis
        // at rest that has lost (or never had) its reference must be homed before it is
        // moved (an Aerotech AXISSTATUS with Enabled and InPosition set, Homed clear).
        let not_referenced = state
            .not_referenced
            .as_ref()
            .is_some_and(|c| c.holds(template, &captures));
        if state.ready.holds(template, &captures) && !not_referenced {
            return Ok(TableState::Ready);
        }
        if state.moving.holds(template, &captures) {
            return Ok(TableState::Moving);
        }
        if not_referenced {
            return Ok(TableState::NotReferenced);
        }
        let what = self.describe(&state.ready, &captures);
        Err(self.device_error(
            &q.send,
            &line,
            format!("the table is neither ready nor moving: {what}"),
        ))
    }

    /// After a motion command: the controller must not have refused it.
    fn check_accepted(&mut self, motion: &str) -> Result<(), InstrumentError> {
        let Some(error) = self.table.error.clone() else {
            return Ok(());
        };
        let (captures, line) = self.ask(&error.query)?;
        if error.none.holds(&error.query.reply, &captures) {
            return Ok(());
        }
        let code = captures.get(&error.none.field).unwrap_or("").to_string();
        let meaning = error
            .names
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(&code))
            .map(|(_, v)| v.clone())
            .or_else(|| bit_meaning(&error.names, &code))
            .unwrap_or_else(|| "no meaning in the profile".to_string());
        Err(self.device_error(
            &error.query.send,
            &line,
            format!(
                "the controller refused {:?}: error {code} ({meaning})",
                self.wire(motion)
            ),
        ))
    }

    /// Sends a motion (or any command that changes something) exactly once; reads its
    /// acknowledgement when the profile has one. A lost acknowledgement is not a reason
    /// to send it again: the state and position tell what happened.
    fn send_once(&mut self, command: &Command, text: &str) -> Result<(), InstrumentError> {
        self.transport.drain()?;
        self.transport.send(&self.wire(text))?;
        let Some(ack) = &command.ack else {
            return Ok(());
        };
        match self.transport.read_line(self.options.query.reply_timeout)? {
            None => {
                self.transport.note("no acknowledgement", &self.wire(text));
                Ok(())
            }
            Some(reply) if ack.matches(&reply).is_some() => Ok(()),
            Some(reply) => {
                if let Some(refusal) = self
                    .line
                    .refusals
                    .iter()
                    .find(|r| r.matches(&reply).is_some())
                {
                    return Err(self.device_error(
                        text,
                        &reply,
                        format!(
                            "the controller refused the command (a reply of the form `{}`)",
                            refusal.as_str()
                        ),
                    ));
                }
                self.transport.note("discarded", &reply);
                Ok(())
            }
        }
    }

    /// Polls the state until the controller is ready again after `motion`.
    fn wait_ready(&mut self, motion: &str) -> Result<(), InstrumentError> {
        let deadline = Instant::now() + self.options.motion_timeout;
        loop {
            if self.stop.is_set() {
                let _ = self.stop();
                return Err(InstrumentError::Interrupted {
                    port: self.transport.port().to_string(),
                });
            }
            match self.state()? {
                TableState::Ready => return Ok(()),
                TableState::Moving => {}
                TableState::NotReferenced => {
                    let q = self.table.state.query.send.clone();
                    return Err(self.device_error(
                        &q,
                        "",
                        format!(
                            "after {:?} the table is not referenced: it lost its reference",
                            self.wire(motion)
                        ),
                    ));
                }
            }
            if Instant::now() >= deadline {
                let _ = self.stop();
                return Err(self.device_error(
                    motion,
                    "",
                    format!(
                        "the table was not ready {} s after the motion command; stopped it",
                        self.options.motion_timeout.as_secs_f64()
                    ),
                ));
            }
            self.stop.sleep(self.options.poll_interval);
        }
    }
}

/// The meaning of an error code that is a bit mask (Aerotech's AXISFAULT), from the
/// names the profile gives its single bits: `None` unless the code is a number of two
/// bits or more, every one of them named.
fn bit_meaning(names: &BTreeMap<String, String>, code: &str) -> Option<String> {
    let bits: u64 = code.trim().parse().ok()?;
    if bits.count_ones() < 2 {
        return None;
    }
    (0..64)
        .filter(|i| bits & (1 << i) != 0)
        .map(|i| names.get(&(1u64 << i).to_string()).cloned())
        .collect::<Option<Vec<String>>>()
        .map(|named| named.join(", "))
}

/// The names of the bits set in a digit field's value.
fn bit_names(
    template: &Template,
    field: &str,
    value: &str,
    names: Option<&Vec<String>>,
) -> Vec<String> {
    let (Some(names), Some(radix)) = (names, template.field(field).and_then(|f| f.kind.radix()))
    else {
        return Vec::new();
    };
    let Ok(bits) = u64::from_str_radix(value, radix) else {
        return Vec::new();
    };
    (0..64)
        .filter(|i| bits & (1 << i) != 0)
        .map(|i| names.get(i).cloned().unwrap_or_else(|| format!("bit {i}")))
        .collect()
}

impl<T: Transport> RotaryTable for ProfileTable<T> {
    fn port(&self) -> &str {
        self.transport.port()
    }

    fn start(&mut self) -> Result<(), InstrumentError> {
        self.start_axis()
    }

    fn identify(&mut self) -> Result<String, InstrumentError> {
        let command = self.wire(&self.table.identify.send);
        let (line, template) = (&self.line, &self.table.identify.reply);
        query(
            &mut self.transport,
            &self.options.query,
            None,
            &command,
            |reply| {
                read_reply(line, template, reply)
                    .map(|c| c.get("text").unwrap_or(reply.trim()).trim().to_string())
            },
        )
        .map(|(text, _)| text)
    }

    fn move_to(&mut self, degrees: f64) -> Result<f64, InstrumentError> {
        if self.stop.is_set() {
            return Err(InstrumentError::Interrupted {
                port: self.transport.port().to_string(),
            });
        }
        match self.state()? {
            TableState::Ready => {}
            other => {
                let q = self.table.state.query.send.clone();
                return Err(self.device_error(
                    &q,
                    "",
                    format!("the table is not ready for a move ({other:?})"),
                ));
            }
        }
        let command = self.table.motion.clone();
        let motion = command.send.replace("{deg}", &format_degrees(degrees));
        self.send_once(&command, &motion)?;
        self.check_accepted(&motion)?;
        self.wait_ready(&motion)?;
        let q = self.table.position.clone();
        let (captures, line) = self.ask(&q)?;
        let Some(position) = captures.number("deg") else {
            return Err(self.device_error(
                &q.send,
                &line,
                "the position is not a finite number".into(),
            ));
        };
        if (position - degrees).abs() > self.options.position_tolerance_deg {
            return Err(self.device_error(
                &q.send,
                &line,
                format!("the table stopped at {position}°, not at the commanded {degrees}°"),
            ));
        }
        Ok(position)
    }

    fn position(&mut self) -> Result<f64, InstrumentError> {
        let q = self.table.position.clone();
        let (captures, line) = self.ask(&q)?;
        captures.number("deg").ok_or_else(|| {
            self.device_error(&q.send, &line, "the position is not a finite number".into())
        })
    }

    fn stop(&mut self) -> Result<(), InstrumentError> {
        let stop = self.wire(&self.table.stop.send);
        self.transport.send(&stop)
    }
}
