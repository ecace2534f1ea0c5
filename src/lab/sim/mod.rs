//! Simulated instruments: an ELCOMAT 3000 pair and an SMC100 rotary table sharing one
//! simulated world, fed by the simulator's truth model.
//!
//! # The physical model
//!
//! The polygon sits on the table; the table's encoder reads θ (degrees, the position
//! `1TP` reports), and its true angle is θ + α(θ)/3600, where α\[p\] is the truth's
//! encoder error at the nominal stop p·360°/N nearest to θ. So α is *true minus
//! indicated* angle, the sign that makes the autocollimator reading follow docs/FORMAT.md §1:
//! with the table at rest at θ and p the nearest stop (δ = θ − p·360/N, in arcsec),
//! autocollimator j reads
//!
//! ```text
//! x = Truth::model_reading(reading) + δ + noise     (= α[p mod N] + φ[face] + U[1, j] + effects + δ + noise)
//! ```
//!
//! where `reading` has step p (N for 360°), face `((ac_faces[j-1] − 1) + p) mod N + 1`,
//! setup 1, and the cycle and direction of the run's stop the table is at (see
//! *Cycles* below); its `time` is the real time since the lab's first command.
//!
//! # Mountings
//!
//! The polygon starts in the simulation's setup 1; each [`Devices::remount`] (`sim-lab`:
//! a `remount` line on its standard input) mounts it as the next setup, the operator's
//! part of a run in several mountings. In setup s the stops are at `table_shift_deg[s-1]`
//! (0 without shifts) + p·360°/N: p and δ are taken against that shift, the face is
//! [`SimulationConfig::face_at`](crate::simulate::SimulationConfig::face_at)`(s, j, p)`
//! (the setup's face shift included), α the truth's encoder error at the table's angle
//! ([`Truth::model_reading_shifted`]) and U the setup's. A run that goes on to the next
//! setup's stops without the remount finds the faces where the old mounting put them: off
//! its range by a sub-pitch shift (no axis valid), or other faces. The
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
//! `outlier` need. The world follows the run design of its [`SimulationConfig`](crate::simulate::SimulationConfig)
//! (cycles, closing, bidirectional): each arrival of the table at a stop advances to the
//! next planned stop with that step, unless the current one has not been read by both
//! autocollimators yet (a resumed run comes back to it). A visit to another step (a
//! stop measured again at the end of a cycle) is off the plan: it reads with the cycle
//! and direction of the run's current stop, without the truth's outliers (an outlier is
//! one reading's), and does not move the run's place in the plan. Give `sim-lab` the run's
//! `--cycles`, `--closing` and `--bidirectional` when you simulate such effects.
//!
//! # Faults
//!
//! [`Fault`]s are injected per device: `KIND:DEVICE[:after=K][:count=M][:seconds=S][:fraction=F]` (S of
//! `late` and `xoff`). The device
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
//! | `late` | all | the next M replies are sent `seconds=S` late (default 1.5 s); later replies wait behind them. With `commands=C`: each is held until C more commands have come and sent just inside the C-th's reply window, ahead of its reply (later replies do not wait) |
//! | `duplicated` | all | the next M replies are sent twice |
//! | `unsolicited` | all | before each of the next M replies, a line in the form of a reply that nothing asked for (an autocollimator: its last measurement + 99″; the table: its position + 1°) |
//! | `swapped` | all | each of the next M replies is held back and sent after the reply that follows it |
//! | `stale` | all | the next M replies are the previous reply again |
//! | `stall` | table | the next M moves end `fraction=F` (default 0.5) of the position tolerance (0.001°) short of their target, where the encoder then reads |
//! | `sign-flip` | autocollimators | the next M measurements have X negated, in the reply's right form |
//! | `swap-xy` | autocollimators | the next M measurements have X and Y exchanged |
//! | `drop-digit` | autocollimators | the next M measurements have X's units digit dropped (`12.345678` → `1.345678`) |
//! | `nul-padding` | all | every reply (M ignored) is padded with NUL bytes, three before it and three after its terminator |
//! | `xoff` | table | after each of the next M replies, the device sends XOFF and holds the host's output `seconds=S` (default 1.5 s), then sends XON: a flow-control pause, on the pseudo-terminal lab only (the table's line has XON/XOFF) |

mod config;
mod elcomat;
mod endpoint;
mod fault;
#[cfg(unix)]
mod lab;
mod profiled;
mod smc100;
mod world;

use std::fmt;
use std::sync::{Arc, Mutex};
use std::time::Duration;

pub use config::{LabConfig, LabConfigError, LabSimError};
pub use elcomat::ElcomatSim;
pub use endpoint::{Endpoint, SimDevice, SimStream};
pub use fault::{
    DEFAULT_LATE, DEFAULT_STALL_FRACTION, DeviceId, FAULT_KINDS, Fault, FaultError, FaultKind,
    FaultProblem, NUL_PADDING,
};
#[cfg(unix)]
pub use lab::{Lab, LabPaths};
pub use profiled::ProfileSim;
pub use smc100::Smc100Sim;
pub use world::{RemountError, TableView, World};

use crate::simulate::{SimulateError, Truth, TruthError};
use world::lock;

/// Measuring range of the simulated autocollimators, arcsec (beyond it X is not valid).
pub const AC_RANGE_ARCSEC: f64 = 1000.0;
/// Spread of the simulated pyramidal errors (the Y axis), arcsec.
pub const PYRAMIDAL_SPREAD_ARCSEC: f64 = 2.0;
/// Period of the simulated autocollimators' continuous streams.
pub const STREAM_PERIOD: Duration = Duration::from_millis(50);

/// The simulated devices of one world, ready to serve: one autocollimator per face of
/// the simulation's `ac_faces` (two by default) and the table.
pub struct Devices {
    /// The shared world.
    pub world: Arc<Mutex<World>>,
    /// Autocollimators 1 … K, in order.
    pub autocollimators: Vec<Endpoint>,
    /// The table.
    pub table: Endpoint,
}

impl fmt::Debug for Devices {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Devices").finish_non_exhaustive()
    }
}

impl Devices {
    /// A world for `config` and its devices, with their faults.
    ///
    /// # Errors
    ///
    /// Invalid settings ([`LabConfig::validate`]).
    pub fn new(config: LabConfig) -> Result<Devices, LabSimError> {
        let world = World::new(config)?;
        Ok(Devices::from_world(world))
    }

    /// The devices of a world built with a given truth (e.g. one read from a file).
    ///
    /// # Errors
    ///
    /// Invalid settings, or a truth whose number of faces differs from the settings'.
    pub fn with_truth(config: LabConfig, truth: Truth) -> Result<Devices, LabSimError> {
        config.validate()?;
        truth.validate()?;
        if truth.faces != config.simulation.faces {
            return Err(SimulateError::Truth {
                origin: "truth".into(),
                problem: TruthError::FacesDiffer {
                    truth_faces: truth.faces,
                    run: "the lab",
                    run_faces: config.simulation.faces,
                },
            }
            .into());
        }
        Ok(Devices::from_world(World::with_truth(config, truth)))
    }

    fn from_world(world: World) -> Devices {
        let config = world.config.clone();
        let world = Arc::new(Mutex::new(world));
        let ac = |number: u32| {
            let faults = config.faults_of(DeviceId::Ac(number));
            let device: Box<dyn SimDevice> =
                match config.ac_profile.as_ref().and_then(|p| {
                    ProfileSim::autocollimator(Arc::clone(&world), p, number, &faults)
                }) {
                    Some(sim) => Box::new(sim),
                    None => Box::new(ElcomatSim::new(Arc::clone(&world), number, &faults)),
                };
            Endpoint::new(device, &faults)
        };
        let k = config.simulation.ac_faces.len().max(2) as u32;
        let table_faults = config.faults_of(DeviceId::Table);
        let table: Box<dyn SimDevice> = match config
            .table_profile
            .as_ref()
            .and_then(|p| ProfileSim::table(Arc::clone(&world), p, &table_faults))
        {
            Some(sim) => Box::new(sim),
            None => Box::new(Smc100Sim::new(Arc::clone(&world), &table_faults)),
        };
        Devices {
            autocollimators: (1..=k).map(ac).collect(),
            table: Endpoint::new(table, &table_faults),
            world,
        }
    }

    /// The face each autocollimator reads at step 0, autocollimator 1 first.
    pub fn ac_faces(&self) -> Vec<usize> {
        lock(&self.world).config.simulation.ac_faces.clone()
    }

    /// A copy of the truth.
    pub fn truth(&self) -> Truth {
        lock(&self.world).truth.clone()
    }

    /// Every setup of the simulation as the run states its mounting (`run --setup S
    /// --shift DEG --face-shift K`), setup 1 first.
    pub fn mountings(&self) -> Vec<crate::lab::run::Mounting> {
        let world = lock(&self.world);
        let simulation = &world.config.simulation;
        let n = simulation.faces.max(1);
        (1..=simulation.setups)
            .map(|s| {
                crate::lab::run::Mounting::new(s)
                    .with_shift_deg(simulation.table_shift_of(s))
                    .with_face_shift((s as usize - 1) % n * (simulation.setup_shift_faces % n) % n)
            })
            .collect()
    }

    /// The operator remounts the polygon for the simulation's next setup
    /// ([`World::remount`]).
    ///
    /// # Errors
    ///
    /// [`RemountError::LastMounting`]: the last setup is mounted already.
    pub fn remount(&self) -> Result<u32, RemountError> {
        lock(&self.world).remount()
    }
}
