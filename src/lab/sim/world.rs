//! The world the simulated devices share: the truth, the table's mechanics and state, the
//! noise, and the stop of the run the table is at.

use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::{AC_RANGE_ARCSEC, LabConfig, LabSimError, PYRAMIDAL_SPREAD_ARCSEC};
use crate::measurement::{Direction, Reading, run_stops};
use crate::simulate::{SimulationConfig, Truth};

/// Why the simulated lab could not remount the polygon.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum RemountError {
    /// The simulation's last setup is on the table already: there is no next mounting.
    #[error("the lab simulates {setups} mounting(s), and mounting {mounting} is on the table")]
    LastMounting {
        /// The setups the simulation has.
        setups: u32,
        /// The mounting on the table.
        mounting: u32,
    },
}

/// A planned stop of the run design the world follows.
#[derive(Debug, Clone)]
struct PlannedStop {
    cycle: u32,
    step: usize,
    direction: Direction,
    read: Vec<bool>,
}

/// Which planned stop the table is at.
#[derive(Debug)]
struct Tracker {
    plan: Vec<PlannedStop>,
    current: Option<usize>,
    /// The step of a visit off the plan (a stop measured again at the end of a cycle):
    /// the run's place in the plan stays where it was.
    off_plan: Option<usize>,
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
            read: vec![false; config.ac_faces.len()],
        })
        .collect();
        Tracker {
            plan,
            current: None,
            off_plan: None,
        }
    }

    /// The table arrived at `step`: the current stop again (while not read by both
    /// autocollimators, as when a resumed run comes back to it), the next planned stop,
    /// or — at another step — a visit off the plan, which does not move the run's place.
    fn arrive(&mut self, step: usize) {
        self.off_plan = None;
        let Some(c) = self.current else {
            self.current = self.plan.iter().position(|s| s.step == step);
            return;
        };
        let stop = &self.plan[c];
        if stop.step == step && !stop.read.iter().all(|&r| r) {
            return;
        }
        match self.plan.get(c + 1) {
            Some(next) if next.step == step => self.current = Some(c + 1),
            _ if stop.step == step => {}
            _ => self.off_plan = Some(step),
        }
    }

    /// (cycle, direction) of the current stop if the table is at it; at a visit off the
    /// plan those of the current stop (the cycle the run is in); else cycle 1, cw.
    fn context(&mut self, step: usize, ac: u32) -> (u32, Direction) {
        if let (Some(c), Some(visit)) = (self.current, self.off_plan)
            && visit == step
        {
            let stop = &self.plan[c];
            return (stop.cycle, stop.direction);
        }
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
pub(super) struct Motion {
    pub(super) from: f64,
    pub(super) to: f64,
    pub(super) start: Instant,
    pub(super) duration: Duration,
    pub(super) homing: bool,
    /// Disable fault: the motion stops at its middle in state 3D.
    pub(super) fails: bool,
}

impl Motion {
    /// Where the motion is at `now`, degrees: linear from `from` to `to` over `duration`.
    pub(super) fn position_at(&self, now: Instant) -> f64 {
        let total = self.duration.as_secs_f64();
        let done = if total > 0.0 {
            (now.saturating_duration_since(self.start).as_secs_f64() / total).min(1.0)
        } else {
            1.0
        };
        self.from + (self.to - self.from) * done
    }
}

/// The simulated rotary table's mechanics and controller state.
#[derive(Debug)]
pub(super) struct Table {
    pub(super) position: f64,
    pub(super) motion: Option<Motion>,
    pub(super) referenced: bool,
    pub(super) ready_code: u8,
    pub(super) disabled: Option<u8>,
    pub(super) stuck: bool,
}

/// The world the simulated devices share: the truth, the table and the noise.
#[derive(Debug)]
pub struct World {
    pub(super) config: LabConfig,
    pub(super) truth: Truth,
    /// The truth without its outliers: what a visit off the plan reads (an outlier is
    /// one reading's, at its planned stop).
    without_outliers: Truth,
    pyramidal: Vec<f64>,
    noise: ChaCha8Rng,
    pub(super) table: Table,
    tracker: Tracker,
    first_command: Option<Instant>,
    /// The mounting of the polygon on the table (the simulation's setup), from 1.
    mounting: u32,
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
    pub fn new(config: LabConfig) -> Result<World, LabSimError> {
        config.validate()?;
        let truth = Truth::draw(&config.simulation)?;
        Ok(World::with_truth(config, truth))
    }

    pub(super) fn with_truth(config: LabConfig, truth: Truth) -> World {
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
        let mut without_outliers = truth.clone();
        without_outliers
            .effects
            .retain(|e| !matches!(e, crate::effects::Effect::Outlier { .. }));
        World {
            tracker: Tracker::new(&config.simulation),
            config,
            without_outliers,
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
            mounting: 1,
        }
    }

    /// The polygon's mounting on the table now (the simulation's setup, from 1).
    pub fn mounting(&self) -> u32 {
        self.mounting
    }

    /// The operator remounts the polygon for the next setup of the simulation: at step p
    /// of setup s the table stands at the setup's table shift + p·360°/N and
    /// autocollimator j faces the face [`SimulationConfig::face_at`] gives. The run's
    /// place in the plan starts anew (the setup's cycles). Returns the new mounting.
    ///
    /// # Errors
    ///
    /// [`RemountError::LastMounting`]: the simulation's last setup is mounted already.
    pub fn remount(&mut self) -> Result<u32, RemountError> {
        let setups = self.config.simulation.setups;
        if self.mounting >= setups {
            return Err(RemountError::LastMounting {
                setups,
                mounting: self.mounting,
            });
        }
        self.mounting += 1;
        self.tracker = Tracker::new(&self.config.simulation);
        Ok(self.mounting)
    }

    /// Someone turns the table by hand by `degrees` while it is at rest, as can happen
    /// while the polygon is remounted: the encoder follows, the controller stays ready.
    pub fn turn_table_by_hand(&mut self, degrees: f64) {
        if self.table.motion.is_none() && degrees.is_finite() {
            self.table.position += degrees;
        }
    }

    /// The table's angle at step 0 of the mounting now, degrees.
    fn shift_deg(&self) -> f64 {
        self.config.simulation.table_shift_of(self.mounting)
    }

    /// The truth the readings are drawn from.
    pub fn truth(&self) -> &Truth {
        &self.truth
    }

    /// The settings.
    pub fn config(&self) -> &LabConfig {
        &self.config
    }

    pub(super) fn touch(&mut self, now: Instant) {
        if self.first_command.is_none() {
            self.first_command = Some(now);
        }
        self.update(now);
    }

    /// Completes a motion whose time is over.
    pub(super) fn update(&mut self, now: Instant) {
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

    /// The stop index nearest to `degrees` in the mounting now (0 … N for the shift …
    /// the shift + 360°), if it is in that range.
    fn nominal_step(&self, degrees: f64) -> Option<usize> {
        let n = self.truth.faces as f64;
        let p = ((degrees - self.shift_deg()) * n / 360.0).round();
        (p >= 0.0 && p <= n).then_some(p as usize)
    }

    /// The position the table's encoder reads, degrees (moving: where the motion is).
    pub(super) fn encoder_position(&self, now: Instant) -> f64 {
        match self.table.motion {
            Some(m) => m.position_at(now),
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
    pub(super) fn measure(&mut self, ac: u32, now: Instant) -> (u16, f64, f64) {
        let z_x: f64 = StandardNormal.sample(&mut self.noise);
        let z_y: f64 = StandardNormal.sample(&mut self.noise);
        let TableView::AtRest(theta) = self.table_view(now) else {
            return (0, 0.0, 0.0);
        };
        let n = self.truth.faces;
        let shift = self.shift_deg();
        let p = ((theta - shift) * n as f64 / 360.0).round();
        let delta_arcsec = (theta - shift - p * 360.0 / n as f64) * 3600.0;
        let p = p as i64;
        let step = if (0..=n as i64).contains(&p) {
            p as usize
        } else {
            p.rem_euclid(n as i64) as usize
        };
        let face = self.config.simulation.face_at(self.mounting, ac, step);
        let off_plan = self.tracker.off_plan == Some(step);
        let (cycle, direction) = self.tracker.context(step, ac);
        let time = self
            .first_command
            .map_or(0.0, |t| now.saturating_duration_since(t).as_secs_f64());
        let reading = Reading {
            setup: self.mounting,
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
        let truth = if off_plan {
            &self.without_outliers
        } else {
            &self.truth
        };
        let x = truth.model_reading_shifted(&reading, shift) + delta_arcsec + sigma * z_x;
        let y = self.pyramidal[face - 1] + sigma * z_y;
        if !x.is_finite() || x.abs() > AC_RANGE_ARCSEC {
            return (0, 0.0, 0.0);
        }
        (3, x, y)
    }

    pub(super) fn table_state(&mut self, now: Instant) -> u8 {
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

    pub(super) fn duration(&self, distance_deg: f64, extra_s: f64) -> Duration {
        let s =
            (distance_deg.abs() / self.config.speed_deg_per_s + extra_s) * self.config.time_scale;
        Duration::try_from_secs_f64(s).unwrap_or(Duration::ZERO)
    }
}

/// Why the simulated controller refuses a motion command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Refused {
    /// Not referenced: a move needs a home search first.
    NotReferenced,
    /// A home search is under way.
    Homing,
    /// A move is under way.
    Moving,
    /// The controller is disabled.
    Disabled,
    /// The target is beyond the travel.
    OutOfTravel,
    /// A home search asked of a referenced, ready table.
    AlreadyReferenced,
}

/// The `stall` faults of a table: (armed after, moves left, shortfall as a fraction of
/// the position tolerance).
#[derive(Debug, Clone)]
pub(super) struct Stalls(Vec<(u64, u64, f64)>);

impl Stalls {
    /// The `stall` faults among `faults`.
    pub(super) fn of(faults: &[super::Fault]) -> Stalls {
        Stalls(
            faults
                .iter()
                .filter(|f| f.kind == super::FaultKind::Stall)
                .map(|f| (f.after, f.count, f.stall_fraction))
                .collect(),
        )
    }

    /// How far short the move after `moves_before` moves ends, degrees (0: no stall).
    pub(super) fn shortfall_deg(&mut self, moves_before: u64) -> f64 {
        for (after, left, fraction) in &mut self.0 {
            if moves_before >= *after && *left > 0 {
                *left -= 1;
                return *fraction * crate::lab::driver::POSITION_TOLERANCE_DEG;
            }
        }
        0.0
    }
}

/// Travel limits of the simulated table, degrees.
pub const TRAVEL_DEG: (f64, f64) = (-720.0, 720.0);

impl World {
    /// Starts a move to `target` (the controller's part of a move command); `fails`: the
    /// `disable` fault stops it midway.
    /// `short_deg`: a `stall` fault's shortfall — the move ends that far short of its
    /// target, where the encoder then reads.
    pub(super) fn start_move(
        &mut self,
        target: f64,
        fails: bool,
        short_deg: f64,
        now: Instant,
    ) -> Result<(), Refused> {
        match self.table_state(now) {
            0x0A..=0x11 => return Err(Refused::NotReferenced),
            0x1E | 0x1F => return Err(Refused::Homing),
            0x28 => return Err(Refused::Moving),
            0x32..=0x34 => {}
            _ => return Err(Refused::Disabled),
        }
        if !(TRAVEL_DEG.0..=TRAVEL_DEG.1).contains(&target) {
            return Err(Refused::OutOfTravel);
        }
        let from = self.table.position;
        let target = if target != from {
            target - (target - from).signum() * short_deg
        } else {
            target
        };
        let duration = self.duration(target - from, 0.0);
        self.table.motion = Some(Motion {
            from,
            to: target,
            start: now,
            duration,
            homing: false,
            fails,
        });
        self.update(now);
        Ok(())
    }

    /// Starts a home search; `always`: also when the table is referenced already (a
    /// controller that homes on request whatever its state).
    pub(super) fn start_home(&mut self, always: bool, now: Instant) -> Result<(), Refused> {
        match self.table_state(now) {
            0x0A..=0x11 => {}
            0x32..=0x34 if always => {}
            0x1E | 0x1F => return Err(Refused::Homing),
            0x3C..=0x3E => return Err(Refused::Disabled),
            0x28 => return Err(Refused::Moving),
            _ => return Err(Refused::AlreadyReferenced),
        }
        let from = self.table.position;
        let home_seconds = self.config.home_seconds;
        let duration = self.duration(from, home_seconds);
        self.table.referenced = false;
        self.table.motion = Some(Motion {
            from,
            to: 0.0,
            start: now,
            duration,
            homing: true,
            fails: false,
        });
        self.update(now);
        Ok(())
    }

    /// Stops any motion where it is.
    pub(super) fn stop_motion(&mut self, now: Instant) {
        self.touch(now);
        if let Some(m) = self.table.motion.take() {
            self.table.position = m.position_at(now);
            if m.homing {
                self.table.referenced = false;
            } else {
                self.table.ready_code = 0x33;
            }
        }
    }
}

/// Locks the world, recovering from a poisoned lock (a panicked device thread must not
/// take the others down).
pub(super) fn lock(world: &Mutex<World>) -> MutexGuard<'_, World> {
    world.lock().unwrap_or_else(|p| p.into_inner())
}
