//! Table controllers written by hand from their makers' manuals, not from polycal's
//! profiles (issue 54, "Every make homed"): a Newport SMC100, a PI C-863 speaking GCS 2,
//! an Aerotech Ensemble's ASCII command interface and a Newport ESP301. Each starts in
//! one of its controller's power-on states — not referenced with its position counter
//! wherever it came up, the motor disabled or the servo off, a fault latched — answers
//! and refuses as its manual says, and records what it was sent and where the table
//! physically went, so that a test can tell a move made before the home search from one
//! made after it.
//!
//! The table they drive is the same for all four ([`Stage`]): a physical angle, a
//! position counter whose zero is wherever the controller came up until a home search
//! puts it on the home mark (physical 0°), moves and home searches that take time. They
//! are served over a pseudo-terminal or TCP by the simulated lab's own serving loop
//! ([`serve`]), one command line at a time.

#![allow(dead_code)]

pub mod aerotech;
pub mod esp301;
pub mod pi_gcs2;
pub mod smc100;

use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use polycal::lab::sim::{Devices, Endpoint, Lab, LabConfig, SimDevice};
use polycal::simulate::SimulationConfig;

/// How long a home search takes: longer than a query's deadline and its retries in the
/// tests, as a real one (seconds) is longer than the driver's (one second).
pub const HOME_TIME: Duration = Duration::from_millis(600);
/// How fast a move turns the table, degrees a second.
const SPEED_DEG_PER_S: f64 = 3000.0;
/// How long a move takes at least (acceleration and settling).
const SETTLE: Duration = Duration::from_millis(15);
/// The home mark's physical angle, degrees: where the counter reads 0 once homed.
pub const HOME_MARK_DEG: f64 = 0.0;

/// A motion under way.
#[derive(Debug, Clone, Copy)]
struct Motion {
    from: f64,
    to: f64,
    start: Instant,
    end: Instant,
    home: bool,
}

/// The rotary table behind a controller: its physical angle, the controller's position
/// counter (physical − `offset`), and whether the counter has been referenced to the
/// home mark.
#[derive(Debug, Clone)]
pub struct Stage {
    rest: f64,
    motion: Option<Motion>,
    offset: f64,
    referenced: bool,
}

impl Stage {
    /// A table at `physical` degrees whose counter reads `counter` there.
    pub fn new(physical: f64, counter: f64, referenced: bool) -> Stage {
        Stage {
            rest: physical,
            motion: None,
            offset: physical - counter,
            referenced,
        }
    }

    /// A table that came up at `physical` degrees, not referenced, its counter at 0: the
    /// power-on state of an incremental encoder.
    pub fn unknown(physical: f64) -> Stage {
        Stage::new(physical, 0.0, false)
    }

    /// A table referenced by an earlier session and left at `counter` degrees.
    pub fn referenced_at(counter: f64) -> Stage {
        Stage::new(counter + HOME_MARK_DEG, counter, true)
    }

    /// The physical angle at `now`.
    pub fn physical(&self, now: Instant) -> f64 {
        match self.motion {
            Some(m) if now < m.end => {
                let span = (m.end - m.start).as_secs_f64();
                let done = (now - m.start).as_secs_f64() / span;
                m.from + (m.to - m.from) * done.clamp(0.0, 1.0)
            }
            Some(m) => m.to,
            None => self.rest,
        }
    }

    /// The position counter at `now`, degrees.
    pub fn counter(&self, now: Instant) -> f64 {
        self.physical(now) - self.offset
    }

    /// Whether the counter is referenced to the home mark.
    pub fn referenced(&self) -> bool {
        self.referenced
    }

    /// Ends a motion whose time is up; `Some(home)` when one ended (a home search when
    /// `home`), with the physical angle it ended at.
    pub fn update(&mut self, now: Instant) -> Option<(bool, f64)> {
        let m = self.motion?;
        if now < m.end {
            return None;
        }
        self.motion = None;
        self.rest = m.to;
        if m.home {
            self.offset = HOME_MARK_DEG;
            self.referenced = true;
        }
        Some((m.home, m.to))
    }

    /// Whether a move or a home search is under way (after [`Stage::update`]).
    pub fn busy(&self) -> bool {
        self.motion.is_some()
    }

    /// Whether a home search is under way.
    pub fn homing(&self) -> bool {
        self.motion.is_some_and(|m| m.home)
    }

    /// Starts a move to counter reading `target`.
    pub fn start_move(&mut self, target: f64, now: Instant) {
        let from = self.physical(now);
        let to = target + self.offset;
        let time = SETTLE + Duration::from_secs_f64((to - from).abs() / SPEED_DEG_PER_S);
        self.motion = Some(Motion {
            from,
            to,
            start: now,
            end: now + time,
            home: false,
        });
    }

    /// Starts a home search: the table turns to the home mark and the counter is set to 0
    /// there.
    pub fn start_home(&mut self, now: Instant) {
        let from = self.physical(now);
        self.referenced = false;
        self.motion = Some(Motion {
            from,
            to: HOME_MARK_DEG,
            start: now,
            end: now + HOME_TIME,
            home: true,
        });
    }

    /// Stops where the table is; a home search stopped leaves the axis not referenced.
    pub fn stop(&mut self, now: Instant) {
        if self.motion.is_some() {
            self.rest = self.physical(now);
            self.motion = None;
        }
    }

    /// The time left of the motion under way.
    pub fn left(&self, now: Instant) -> Duration {
        self.motion
            .map_or(Duration::ZERO, |m| m.end.saturating_duration_since(now))
    }
}

/// A motion command as the controller received it.
#[derive(Debug, Clone)]
pub struct MotionCommand {
    /// The command line.
    pub command: String,
    /// Whether the axis was referenced when it came.
    pub referenced: bool,
    /// How many home searches had ended before it came.
    pub homes_before: usize,
    /// Whether the controller took it (false: refused, nothing moved).
    pub accepted: bool,
}

/// What an emulator was sent and what its table did.
#[derive(Debug, Clone, Default)]
pub struct Record {
    /// Every command line, in order.
    pub received: Vec<String>,
    /// Home searches started.
    pub homes_started: usize,
    /// Home searches that ended on the home mark.
    pub homes_done: usize,
    /// Every motion command (a move, not a home search).
    pub motions: Vec<MotionCommand>,
    /// Where each move ended, physical degrees.
    pub landings: Vec<f64>,
    /// Commands the controller does not know.
    pub unknown: Vec<String>,
}

/// The record an emulator keeps and a test reads.
#[derive(Debug, Clone, Default)]
pub struct Log(Arc<Mutex<Record>>);

impl Log {
    fn lock(&self) -> MutexGuard<'_, Record> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A copy of the record so far.
    pub fn record(&self) -> Record {
        self.lock().clone()
    }

    fn received(&self, line: &str) {
        self.lock().received.push(line.to_string());
    }

    fn home_started(&self) {
        self.lock().homes_started += 1;
    }

    fn motion(&self, command: &str, referenced: bool, accepted: bool) {
        let mut record = self.lock();
        let homes_before = record.homes_done;
        record.motions.push(MotionCommand {
            command: command.to_string(),
            referenced,
            homes_before,
            accepted,
        });
    }

    fn unknown(&self, line: &str) {
        self.lock().unknown.push(line.to_string());
    }

    /// Records what [`Stage::update`] reports.
    fn ended(&self, ended: Option<(bool, f64)>) {
        match ended {
            Some((true, _)) => self.lock().homes_done += 1,
            Some((false, at)) => self.lock().landings.push(at),
            None => {}
        }
    }
}

/// Serves `device` alone on a pseudo-terminal, or on a TCP port of 127.0.0.1 when
/// `tcp`, with the simulated lab's serving loop (no faults of its own); the lab and the
/// path to open.
pub fn serve(device: Box<dyn SimDevice>, tcp: bool) -> (Lab, String) {
    let config = LabConfig::new(SimulationConfig {
        faces: 4,
        ..SimulationConfig::default()
    })
    .with_time_scale(0.0);
    let mut devices = Devices::new(config).expect("a lab of four faces");
    devices.autocollimators.clear();
    devices.table = Endpoint::new(device, &[]);
    let lab = if tcp {
        Lab::start_tcp(devices)
    } else {
        Lab::start(devices)
    }
    .expect("the emulator is served");
    let path = lab.paths().table.clone();
    (lab, path)
}
