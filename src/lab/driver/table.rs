//! A rotary table as its profile describes it.

use std::time::Duration;

mod reading;
mod wire;

pub use wire::{TableOp, TableOutcome, TableWire};

use crate::lab::profile::{Profile, ProfileError};
use crate::lab::transport::Transport;
use crate::lab::wire::drive;
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
/// [`crate::lab::driver`]): the machine [`TableWire`] driven over a [`Transport`].
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
    wire: TableWire,
    stop: StopFlag,
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
        let wire = TableWire::new(transport.port(), profile, options)?;
        Ok(ProfileTable {
            transport,
            name: profile.name.clone(),
            wire,
            stop: StopFlag::new(),
        })
    }

    /// An SMC100 (the bundled profile `smc100`).
    pub fn smc100(transport: T, options: TableOptions) -> Self {
        let profile = crate::lab::profile::bundled("smc100");
        let table = match profile.kind {
            crate::lab::profile::ProfileKind::Table(table) => *table,
            crate::lab::profile::ProfileKind::Autocollimator(_) => {
                unreachable!("the bundled smc100 describes a table")
            }
        };
        let port = transport.port().to_string();
        ProfileTable {
            transport,
            name: profile.name.clone(),
            wire: TableWire::of(port, profile.line.clone(), table, options),
            stop: StopFlag::new(),
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

    /// `op` carried out over the transport.
    fn run(&mut self, op: TableOp) -> Result<TableOutcome, InstrumentError> {
        self.wire.begin(op);
        drive(&mut self.wire, &mut self.transport, Some(&self.stop))
    }

    /// The state, as reported.
    ///
    /// # Errors
    ///
    /// A port failure, a query that fails after its retries, a fault the state reports
    /// (with the names of its bits), and a state that is neither ready, moving nor "not
    /// referenced" (a disabled or misconfigured controller).
    pub fn state(&mut self) -> Result<TableState, InstrumentError> {
        match self.run(TableOp::State)? {
            TableOutcome::State(state) => Ok(state),
            other => Err(self.unexpected(other)),
        }
    }

    /// An outcome of the machine that is not its operation's: a bug of polycal's,
    /// reported rather than trusted.
    fn unexpected(&self, outcome: TableOutcome) -> InstrumentError {
        InstrumentError::Reported {
            port: self.transport.port().to_string(),
            message: format!("the table's wire rules gave {outcome:?}"),
        }
    }

    fn at(&mut self, op: TableOp) -> Result<f64, InstrumentError> {
        match self.run(op)? {
            TableOutcome::At(deg) => Ok(deg),
            other => Err(self.unexpected(other)),
        }
    }
}

impl<T: Transport> RotaryTable for ProfileTable<T> {
    fn port(&self) -> &str {
        self.transport.port()
    }

    fn start(&mut self) -> Result<(), InstrumentError> {
        self.run(TableOp::Start).map(|_| ())
    }

    fn identify(&mut self) -> Result<String, InstrumentError> {
        match self.run(TableOp::Identify)? {
            TableOutcome::Identified(text) => Ok(text),
            other => Err(self.unexpected(other)),
        }
    }

    fn move_to(&mut self, degrees: f64) -> Result<f64, InstrumentError> {
        self.at(TableOp::MoveTo(degrees))
    }

    fn position(&mut self) -> Result<f64, InstrumentError> {
        self.at(TableOp::Position)
    }

    fn stop(&mut self) -> Result<(), InstrumentError> {
        // a stop is sent whatever the stop flag says
        self.wire.begin(TableOp::Stop);
        drive(&mut self.wire, &mut self.transport, None).map(|_| ())
    }
}
