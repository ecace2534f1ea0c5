//! Simulated instruments: an ELCOMAT 3000 pair and an SMC100 rotary table sharing one
//! simulated world, fed by the simulator's truth model.
//!
//! # The physical model
//!
//! The polygon sits on the table; the table's encoder reads θ (degrees, the position
//! `1TP` reports), and its true angle is θ + α(θ)/3600, where α\[p\] is the truth's
//! encoder error at the nominal stop p·360°/N nearest to θ. So α is *true minus
//! indicated* angle, the sign that makes the autocollimator reading follow FORMAT.md §1:
//! with the table at rest at θ and p the nearest stop (δ = θ − p·360/N, in arcsec),
//! autocollimator j reads
//!
//! ```text
//! x = Truth::model_reading(reading) + δ + noise     (= α[p mod N] + φ[face] + U[1, j] + effects + δ + noise)
//! ```
//!
//! where `reading` has step p (N for 360°), face `((ac_faces[j-1] − 1) + p) mod N + 1`,
//! setup 1, and the cycle and direction of the run's stop the table is at (see
//! *Cycles* below); its `time` is the real time since the lab's first command. The
//! noise is drawn from stream 1 of `ChaCha8Rng::seed_from_u64(seed)`, one standard
//! normal for X and one for Y per measurement, in the order the measurements are asked.
//! Y is the face's pyramidal error (spread 2″, stream 2) plus noise.
//!
//! While the table moves or homes, when it is disabled midway, or when |x| exceeds the
//! measuring range (±1000″: the face is not in front of the autocollimator), the reply
//! is `4 000 0.000000 0.000000`: no axis valid. Motion takes |Δθ|/speed seconds, a home
//! search |θ|/speed + `home_seconds`, all multiplied by `time_scale` (0: instantaneous).
//!
//! # Cycles
//!
//! The protocols do not carry the cycle number, which effects such as `offset-step` and
//! `outlier` need. The world follows the run design of its [`SimulationConfig`]
//! (cycles, closing, bidirectional): each arrival of the table at a stop advances to the
//! next planned stop with that step, unless the current one has not been read by both
//! autocollimators yet (a resumed run comes back to it). Give `sim-lab` the run's
//! `--cycles`, `--closing` and `--bidirectional` when you simulate such effects.
//!
//! # Faults
//!
//! [`Fault`]s are injected per device: `KIND:DEVICE[:after=K][:count=M]`. The device
//! counts *events*, measurements for an autocollimator and move commands (`1PA`) for
//! the table; a fault is armed once K events happened, and then:
//!
//! | kind | devices | effect |
//! |---|---|---|
//! | `lost-reply` | all | the next M replies are not sent |
//! | `garbled` | all | the next M replies are garbled (every third character `?`) |
//! | `x-invalid` | ac1, ac2 | the next M measurements have status `002` (X not valid) |
//! | `disable` | table | the next move stops midway in state `3D` (DISABLE from MOVING) and stays disabled |
//! | `close` | all | at the next command the device closes its port |

mod elcomat;
#[cfg(unix)]
mod lab;
mod smc100;

use std::fmt;
use std::io::{self, Read, Write};
use std::str::FromStr;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

pub use elcomat::ElcomatSim;
#[cfg(unix)]
pub use lab::{Lab, LabPaths};
pub use smc100::Smc100Sim;

use crate::measurement::{Direction, Reading, run_stops};
use crate::simulate::{SimulateError, SimulationConfig, Truth};

/// Measuring range of the simulated autocollimators, arcsec (beyond it X is not valid).
pub const AC_RANGE_ARCSEC: f64 = 1000.0;
/// Spread of the simulated pyramidal errors (the Y axis), arcsec.
pub const PYRAMIDAL_SPREAD_ARCSEC: f64 = 2.0;
/// Period of the simulated autocollimators' continuous streams.
pub const STREAM_PERIOD: Duration = Duration::from_millis(50);

/// Which simulated device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DeviceId {
    /// Autocollimator 1.
    Ac1,
    /// Autocollimator 2.
    Ac2,
    /// The rotary table.
    Table,
}

impl DeviceId {
    /// `ac1`, `ac2` or `table`.
    pub fn as_str(self) -> &'static str {
        match self {
            DeviceId::Ac1 => "ac1",
            DeviceId::Ac2 => "ac2",
            DeviceId::Table => "table",
        }
    }
}

impl fmt::Display for DeviceId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What a fault does (see the [module documentation](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultKind {
    /// Replies are not sent.
    LostReply,
    /// Replies are garbled.
    Garbled,
    /// Measurements report X not valid.
    XInvalid,
    /// The table stops midway and stays disabled.
    Disable,
    /// The device closes its port.
    Close,
}

impl FaultKind {
    /// The spelling on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            FaultKind::LostReply => "lost-reply",
            FaultKind::Garbled => "garbled",
            FaultKind::XInvalid => "x-invalid",
            FaultKind::Disable => "disable",
            FaultKind::Close => "close",
        }
    }
}

/// One injected fault: `KIND:DEVICE[:after=K][:count=M]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fault {
    /// What happens.
    pub kind: FaultKind,
    /// To which device.
    pub device: DeviceId,
    /// Events (measurements or moves) before the fault is armed.
    pub after: u64,
    /// How many replies or measurements it hits (lost-reply, garbled, x-invalid).
    pub count: u64,
}

impl FromStr for Fault {
    type Err = String;

    /// Parses `KIND:DEVICE[:after=K][:count=M]`, e.g. `lost-reply:ac1:after=10`.
    ///
    /// ```
    /// use polycal::instrument::sim::{DeviceId, Fault, FaultKind};
    /// let f: Fault = "garbled:table:after=3:count=2".parse().unwrap();
    /// assert_eq!((f.kind, f.device, f.after, f.count), (FaultKind::Garbled, DeviceId::Table, 3, 2));
    /// assert!("x-invalid:table".parse::<Fault>().is_err());
    /// ```
    fn from_str(spec: &str) -> Result<Fault, String> {
        let form = "KIND:DEVICE[:after=K][:count=M], e.g. lost-reply:ac1:after=10";
        let bad = |m: String| format!("fault \"{spec}\": {m} (expected {form})");
        let parts: Vec<&str> = spec.split(':').map(str::trim).collect();
        if parts.len() < 2 {
            return Err(bad("too few parts".into()));
        }
        let kind = match parts[0] {
            "lost-reply" => FaultKind::LostReply,
            "garbled" => FaultKind::Garbled,
            "x-invalid" => FaultKind::XInvalid,
            "disable" => FaultKind::Disable,
            "close" => FaultKind::Close,
            other => {
                return Err(bad(format!(
                    "unknown kind \"{other}\" (kinds: lost-reply, garbled, x-invalid, disable, close)"
                )));
            }
        };
        let device = match parts[1] {
            "ac1" => DeviceId::Ac1,
            "ac2" => DeviceId::Ac2,
            "table" => DeviceId::Table,
            other => return Err(bad(format!("unknown device \"{other}\" (ac1, ac2, table)"))),
        };
        match (kind, device) {
            (FaultKind::XInvalid, DeviceId::Table) => {
                return Err(bad("x-invalid is a fault of an autocollimator".into()));
            }
            (FaultKind::Disable, DeviceId::Ac1 | DeviceId::Ac2) => {
                return Err(bad("disable is a fault of the table".into()));
            }
            _ => {}
        }
        let mut fault = Fault {
            kind,
            device,
            after: 0,
            count: 1,
        };
        for part in &parts[2..] {
            let (key, value) = part
                .split_once('=')
                .ok_or_else(|| bad(format!("\"{part}\" is not after=K or count=M")))?;
            let n: u64 = value
                .parse()
                .map_err(|_| bad(format!("\"{value}\" is not a whole number")))?;
            match key {
                "after" => fault.after = n,
                "count" if n >= 1 => fault.count = n,
                "count" => return Err(bad("count must be at least 1".into())),
                _ => return Err(bad(format!("unknown option \"{key}\""))),
            }
        }
        Ok(fault)
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:after={}:count={}",
            self.kind.as_str(),
            self.device,
            self.after,
            self.count
        )
    }
}

/// Settings of a simulated lab.
#[derive(Debug, Clone, PartialEq)]
pub struct LabConfig {
    /// The truth, noise, seed and run design (its `ac_faces` must have two entries).
    pub simulation: SimulationConfig,
    /// Table speed, degrees per second.
    pub speed_deg_per_s: f64,
    /// Extra time of a home search, seconds.
    pub home_seconds: f64,
    /// Factor on every simulated duration (0: instantaneous motion).
    pub time_scale: f64,
    /// Injected faults.
    pub faults: Vec<Fault>,
}

impl Default for LabConfig {
    /// The simulator's defaults, 20°/s, 2 s home search, real time, no faults.
    fn default() -> Self {
        LabConfig {
            simulation: SimulationConfig::default(),
            speed_deg_per_s: 20.0,
            home_seconds: 2.0,
            time_scale: 1.0,
            faults: Vec::new(),
        }
    }
}

impl LabConfig {
    /// Checks the settings.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Config`] naming the first bad setting.
    pub fn validate(&self) -> Result<(), SimulateError> {
        self.simulation.validate()?;
        let bad = |m: String| Err(SimulateError::Config(m));
        if self.simulation.ac_faces.len() != 2 {
            return bad(format!(
                "the lab has two autocollimators; ac faces {:?} name {}",
                self.simulation.ac_faces,
                self.simulation.ac_faces.len()
            ));
        }
        if self.simulation.setups != 1 {
            return bad("the lab simulates one polygon mounting (setup 1)".into());
        }
        if !(self.speed_deg_per_s.is_finite() && self.speed_deg_per_s > 0.0) {
            return bad(format!(
                "speed {} °/s must be a finite number > 0",
                self.speed_deg_per_s
            ));
        }
        for (name, v) in [
            ("home time", self.home_seconds),
            ("time scale", self.time_scale),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} {v} must be a finite number ≥ 0"));
            }
        }
        Ok(())
    }

    fn faults_of(&self, device: DeviceId) -> Vec<Fault> {
        self.faults
            .iter()
            .copied()
            .filter(|f| f.device == device)
            .collect()
    }
}

/// A planned stop of the run design the world follows.
#[derive(Debug, Clone, Copy)]
struct PlannedStop {
    cycle: u32,
    step: usize,
    direction: Direction,
    read: [bool; 2],
}

/// Which planned stop the table is at.
#[derive(Debug)]
struct Tracker {
    plan: Vec<PlannedStop>,
    current: Option<usize>,
}

impl Tracker {
    fn new(config: &SimulationConfig) -> Tracker {
        let plan = run_stops(
            config.faces,
            config.cycles,
            config.closing,
            config.bidirectional,
        )
        .into_iter()
        .map(|stop| PlannedStop {
            cycle: stop.cycle,
            step: stop.step,
            direction: stop.direction,
            read: [false; 2],
        })
        .collect();
        Tracker {
            plan,
            current: None,
        }
    }

    fn arrive(&mut self, step: usize) {
        if let Some(c) = self.current {
            let stop = &self.plan[c];
            if stop.step == step && !stop.read.iter().all(|&r| r) {
                return;
            }
        }
        let from = self.current.map_or(0, |c| c + 1);
        self.current = (from..self.plan.len())
            .find(|&i| self.plan[i].step == step)
            .or(self.current.filter(|&c| self.plan[c].step == step));
    }

    /// (cycle, direction) of the current stop if it has `step`, else of cycle 1, cw.
    fn context(&mut self, step: usize, ac: u32) -> (u32, Direction) {
        match self.current {
            Some(c) if self.plan[c].step == step => {
                let stop = &mut self.plan[c];
                if let Some(r) = stop.read.get_mut(ac as usize - 1) {
                    *r = true;
                }
                (stop.cycle, stop.direction)
            }
            _ => (1, Direction::Cw),
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Motion {
    from: f64,
    to: f64,
    start: Instant,
    duration: Duration,
    homing: bool,
    /// Disable fault: the motion stops at its middle in state 3D.
    fails: bool,
}

/// The simulated rotary table's mechanics and controller state.
#[derive(Debug)]
struct Table {
    position: f64,
    motion: Option<Motion>,
    referenced: bool,
    ready_code: u8,
    disabled: Option<u8>,
    stuck: bool,
}

/// The world the simulated devices share: the truth, the table and the noise.
#[derive(Debug)]
pub struct World {
    config: LabConfig,
    truth: Truth,
    pyramidal: Vec<f64>,
    noise: ChaCha8Rng,
    table: Table,
    tracker: Tracker,
    first_command: Option<Instant>,
}

/// What the table is doing, as the autocollimators see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TableView {
    /// Moving, homing, or disabled midway: no face in front of the autocollimators.
    InMotion,
    /// At rest at this encoder position, degrees.
    AtRest(f64),
}

impl World {
    /// A world for `config`, its truth drawn with [`Truth::draw`].
    ///
    /// # Errors
    ///
    /// Invalid settings ([`LabConfig::validate`]).
    pub fn new(config: LabConfig) -> Result<World, SimulateError> {
        config.validate()?;
        let truth = Truth::draw(&config.simulation)?;
        Ok(World::with_truth(config, truth))
    }

    fn with_truth(config: LabConfig, truth: Truth) -> World {
        let mut noise = ChaCha8Rng::seed_from_u64(config.simulation.seed);
        noise.set_stream(1);
        let mut shape = ChaCha8Rng::seed_from_u64(config.simulation.seed);
        shape.set_stream(2);
        let pyramidal = (0..truth.faces)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut shape);
                PYRAMIDAL_SPREAD_ARCSEC * z
            })
            .collect();
        World {
            tracker: Tracker::new(&config.simulation),
            config,
            truth,
            pyramidal,
            noise,
            table: Table {
                position: 0.0,
                motion: None,
                referenced: false,
                ready_code: 0x32,
                disabled: None,
                stuck: false,
            },
            first_command: None,
        }
    }

    /// The truth the readings are drawn from.
    pub fn truth(&self) -> &Truth {
        &self.truth
    }

    /// The settings.
    pub fn config(&self) -> &LabConfig {
        &self.config
    }

    fn touch(&mut self, now: Instant) {
        if self.first_command.is_none() {
            self.first_command = Some(now);
        }
        self.update(now);
    }

    /// Completes a motion whose time is over.
    fn update(&mut self, now: Instant) {
        let Some(m) = self.table.motion else { return };
        if m.fails {
            if now >= m.start + m.duration / 2 {
                self.table.position = (m.from + m.to) / 2.0;
                self.table.motion = None;
                self.table.disabled = Some(0x3D);
                self.table.stuck = true;
            }
            return;
        }
        if now < m.start + m.duration {
            return;
        }
        self.table.position = m.to;
        self.table.motion = None;
        if m.homing {
            self.table.referenced = true;
            self.table.ready_code = 0x32;
        } else {
            self.table.ready_code = 0x33;
            if let Some(step) = self.nominal_step(m.to) {
                self.tracker.arrive(step);
            }
        }
    }

    /// The stop index nearest to `degrees` (0 … N for 0° … 360°), if it is in that range.
    fn nominal_step(&self, degrees: f64) -> Option<usize> {
        let n = self.truth.faces as f64;
        let p = (degrees * n / 360.0).round();
        (p >= 0.0 && p <= n).then_some(p as usize)
    }

    fn encoder_position(&self, now: Instant) -> f64 {
        match self.table.motion {
            Some(m) => {
                let total = m.duration.as_secs_f64();
                let done = if total > 0.0 {
                    (now.saturating_duration_since(m.start).as_secs_f64() / total).min(1.0)
                } else {
                    1.0
                };
                m.from + (m.to - m.from) * done
            }
            None => self.table.position,
        }
    }

    /// What the autocollimators see.
    pub fn table_view(&mut self, now: Instant) -> TableView {
        self.touch(now);
        if self.table.motion.is_some() || self.table.stuck {
            TableView::InMotion
        } else {
            TableView::AtRest(self.table.position)
        }
    }

    /// One measurement of autocollimator `ac` (1 or 2): (status axis digit, x, y).
    fn measure(&mut self, ac: u32, now: Instant) -> (u16, f64, f64) {
        let z_x: f64 = StandardNormal.sample(&mut self.noise);
        let z_y: f64 = StandardNormal.sample(&mut self.noise);
        let TableView::AtRest(theta) = self.table_view(now) else {
            return (0, 0.0, 0.0);
        };
        let n = self.truth.faces;
        let p = (theta * n as f64 / 360.0).round();
        let delta_arcsec = (theta - p * 360.0 / n as f64) * 3600.0;
        let p = p as i64;
        let step = if (0..=n as i64).contains(&p) {
            p as usize
        } else {
            p.rem_euclid(n as i64) as usize
        };
        let ac_face = self.config.simulation.ac_faces[ac as usize - 1];
        let face = (ac_face - 1 + step) % n + 1;
        let (cycle, direction) = self.tracker.context(step, ac);
        let time = self
            .first_command
            .map_or(0.0, |t| now.saturating_duration_since(t).as_secs_f64());
        let reading = Reading {
            setup: 1,
            cycle,
            step,
            ac,
            face,
            reading_arcsec: 0.0,
            direction,
            time_seconds: Some(time),
            reading_y_arcsec: None,
            temperature_celsius: None,
            encoder_degrees: Some(theta),
            line: 0,
        };
        let sigma = self.config.simulation.noise_arcsec;
        let x = self.truth.model_reading(&reading) + delta_arcsec + sigma * z_x;
        let y = self.pyramidal[face - 1] + sigma * z_y;
        if !x.is_finite() || x.abs() > AC_RANGE_ARCSEC {
            return (0, 0.0, 0.0);
        }
        (3, x, y)
    }

    fn table_state(&mut self, now: Instant) -> u8 {
        self.touch(now);
        if let Some(code) = self.table.disabled {
            return code;
        }
        match self.table.motion {
            Some(m) if m.homing => 0x1E,
            Some(_) => 0x28,
            None if !self.table.referenced => 0x0A,
            None => self.table.ready_code,
        }
    }

    fn duration(&self, distance_deg: f64, extra_s: f64) -> Duration {
        let s =
            (distance_deg.abs() / self.config.speed_deg_per_s + extra_s) * self.config.time_scale;
        Duration::try_from_secs_f64(s).unwrap_or(Duration::ZERO)
    }
}

/// Locks the world, recovering from a poisoned lock (a panicked device thread must not
/// take the others down).
fn lock(world: &Mutex<World>) -> MutexGuard<'_, World> {
    world.lock().unwrap_or_else(|p| p.into_inner())
}

/// A simulated device: answers command lines.
pub trait SimDevice: Send {
    /// The reply to one command line (terminator removed), terminator included; `None`
    /// when the protocol gives none.
    fn handle(&mut self, command: &str, now: Instant) -> Option<String>;
    /// Output the device sends by itself (a continuous stream), if due.
    fn tick(&mut self, now: Instant) -> Option<String>;
    /// Events so far (measurements, or move commands), which arm faults.
    fn events(&self) -> u64;
}

#[derive(Debug, Clone, Copy)]
struct Armed {
    fault: Fault,
    left: u64,
}

/// A device with its reply faults and its input line buffer: the part shared by the
/// pseudo-terminal lab and the in-memory [`SimStream`].
pub struct Endpoint {
    device: Box<dyn SimDevice>,
    faults: Vec<Armed>,
    input: Vec<u8>,
    closed: bool,
}

impl fmt::Debug for Endpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Endpoint")
            .field("faults", &self.faults)
            .field("closed", &self.closed)
            .finish_non_exhaustive()
    }
}

impl Endpoint {
    /// A device with the faults that act on its replies (`lost-reply`, `garbled`,
    /// `close`); the others are the device's own.
    pub fn new(device: Box<dyn SimDevice>, faults: &[Fault]) -> Endpoint {
        Endpoint {
            device,
            faults: faults
                .iter()
                .filter(|f| {
                    matches!(
                        f.kind,
                        FaultKind::LostReply | FaultKind::Garbled | FaultKind::Close
                    )
                })
                .map(|&fault| Armed {
                    fault,
                    left: fault.count,
                })
                .collect(),
            input: Vec::new(),
            closed: false,
        }
    }

    /// Whether a `close` fault closed the device.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Feeds bytes from the host; returns the bytes to send back.
    pub fn input(&mut self, bytes: &[u8], now: Instant) -> Vec<u8> {
        let mut out = Vec::new();
        if self.closed {
            return out;
        }
        self.input.extend_from_slice(bytes);
        while let Some(i) = self.input.iter().position(|&b| b == b'\r' || b == b'\n') {
            let line: Vec<u8> = self.input.drain(..=i).collect();
            let command = String::from_utf8_lossy(&line[..i]).trim().to_string();
            if command.is_empty() {
                continue;
            }
            let events = self.device.events();
            if self
                .faults
                .iter()
                .any(|a| a.fault.kind == FaultKind::Close && events >= a.fault.after)
            {
                self.closed = true;
                return out;
            }
            let Some(reply) = self.device.handle(&command, now) else {
                continue;
            };
            out.extend(self.apply_faults(reply, events).into_bytes());
        }
        if self.input.len() > 4096 {
            self.input.clear();
        }
        out
    }

    fn apply_faults(&mut self, reply: String, events: u64) -> String {
        for armed in &mut self.faults {
            if armed.left == 0 || events < armed.fault.after {
                continue;
            }
            match armed.fault.kind {
                FaultKind::LostReply => {
                    armed.left -= 1;
                    return String::new();
                }
                FaultKind::Garbled => {
                    armed.left -= 1;
                    return garble(&reply);
                }
                _ => {}
            }
        }
        reply
    }

    /// Output the device sends by itself, if due.
    pub fn tick(&mut self, now: Instant) -> Vec<u8> {
        if self.closed {
            return Vec::new();
        }
        self.device
            .tick(now)
            .map(String::into_bytes)
            .unwrap_or_default()
    }
}

/// Every third character (from the first) replaced by `?`, terminators kept.
fn garble(reply: &str) -> String {
    let body = reply.trim_end_matches(['\r', '\n']);
    let end = &reply[body.len()..];
    let garbled: String = body
        .chars()
        .enumerate()
        .map(|(i, c)| if i % 3 == 0 { '?' } else { c })
        .collect();
    garbled + end
}

/// The three simulated devices of one world, ready to serve.
pub struct Devices {
    /// The shared world.
    pub world: Arc<Mutex<World>>,
    /// Autocollimator 1.
    pub ac1: Endpoint,
    /// Autocollimator 2.
    pub ac2: Endpoint,
    /// The table.
    pub table: Endpoint,
}

impl fmt::Debug for Devices {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Devices").finish_non_exhaustive()
    }
}

impl Devices {
    /// A world for `config` and its three devices, with their faults.
    ///
    /// # Errors
    ///
    /// Invalid settings ([`LabConfig::validate`]).
    pub fn new(config: LabConfig) -> Result<Devices, SimulateError> {
        let world = World::new(config)?;
        Ok(Devices::from_world(world))
    }

    /// The devices of a world built with a given truth (e.g. one read from a file).
    ///
    /// # Errors
    ///
    /// Invalid settings, or a truth whose number of faces differs from the settings'.
    pub fn with_truth(config: LabConfig, truth: Truth) -> Result<Devices, SimulateError> {
        config.validate()?;
        truth.validate()?;
        if truth.faces != config.simulation.faces {
            return Err(SimulateError::Truth {
                origin: "truth".into(),
                message: format!(
                    "it has {} faces, the lab {}",
                    truth.faces, config.simulation.faces
                ),
            });
        }
        Ok(Devices::from_world(World::with_truth(config, truth)))
    }

    fn from_world(world: World) -> Devices {
        let config = world.config.clone();
        let world = Arc::new(Mutex::new(world));
        let ac = |id: DeviceId, number: u32| {
            let faults = config.faults_of(id);
            Endpoint::new(
                Box::new(ElcomatSim::new(Arc::clone(&world), number, &faults)),
                &faults,
            )
        };
        let table_faults = config.faults_of(DeviceId::Table);
        Devices {
            ac1: ac(DeviceId::Ac1, 1),
            ac2: ac(DeviceId::Ac2, 2),
            table: Endpoint::new(
                Box::new(Smc100Sim::new(Arc::clone(&world), &table_faults)),
                &table_faults,
            ),
            world,
        }
    }

    /// A copy of the truth.
    pub fn truth(&self) -> Truth {
        lock(&self.world).truth.clone()
    }
}

/// An in-memory `Read + Write` connected to a simulated device, for driving the drivers
/// (through a [`super::StreamTransport`]) without pseudo-terminals.
///
/// Writing feeds the device; reading returns its replies, `WouldBlock` when there are
/// none yet, and end of input once a `close` fault closed it.
#[derive(Debug)]
pub struct SimStream {
    endpoint: Endpoint,
    output: Vec<u8>,
}

impl SimStream {
    /// A stream to `endpoint`.
    pub fn new(endpoint: Endpoint) -> SimStream {
        SimStream {
            endpoint,
            output: Vec::new(),
        }
    }
}

impl Read for SimStream {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.output.is_empty() {
            let tick = self.endpoint.tick(Instant::now());
            self.output.extend(tick);
        }
        if self.output.is_empty() {
            if self.endpoint.is_closed() {
                return Ok(0);
            }
            return Err(io::Error::new(io::ErrorKind::WouldBlock, "no reply yet"));
        }
        let n = buf.len().min(self.output.len());
        buf[..n].copy_from_slice(&self.output[..n]);
        self.output.drain(..n);
        Ok(n)
    }
}

impl Write for SimStream {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.endpoint.is_closed() {
            return Err(io::Error::new(io::ErrorKind::BrokenPipe, "device closed"));
        }
        let reply = self.endpoint.input(buf, Instant::now());
        self.output.extend(reply);
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}
