//! Helpers of the in-process instrument tests: the simulated lab over in-memory streams
//! (no pseudo-terminals), its drivers, and scratch run directories.

#![allow(dead_code)]

use std::path::PathBuf;
use std::time::Duration;

use polycal::lab::driver::ProfileAutocollimator;
use polycal::lab::driver::{ProfileTable, TableOptions};
use polycal::lab::run::Ports;
use polycal::lab::sim::{Devices, Endpoint, Fault, LabConfig, SimStream};
use polycal::lab::transport::StreamTransport;
use polycal::lab::{QueryOptions, StopFlag};
use polycal::simulate::{SimulationConfig, Truth};

/// A simulated autocollimator's driver.
pub type Ac = ProfileAutocollimator<StreamTransport<SimStream>>;
/// The simulated table's driver.
pub type Table = ProfileTable<StreamTransport<SimStream>>;

/// A lab of `faces` faces (two cycles with the closing step, seed 7), instantaneous.
pub fn lab(faces: usize, noise: f64, faults: Vec<Fault>) -> LabConfig {
    LabConfig::new(SimulationConfig {
        faces,
        noise_arcsec: noise,
        cycles: 2,
        closing: true,
        seed: 7,
        ..SimulationConfig::default()
    })
    .with_time_scale(0.0)
    .with_faults(faults)
}

/// Short deadlines: the lab answers at once.
pub fn query() -> QueryOptions {
    QueryOptions::new(Duration::from_millis(20), 3)
}

/// The three drivers over the lab's devices, and its truth.
pub fn drivers(devices: Devices, stop: &StopFlag) -> (Ac, Ac, Table, Truth) {
    let truth = devices.truth();
    let Devices {
        autocollimators,
        table,
        ..
    } = devices;
    let Ok([ac1, ac2]) = <[_; 2]>::try_from(autocollimators) else {
        panic!("two autocollimators")
    };
    let ac = |name: &str, e: Endpoint| {
        ProfileAutocollimator::elcomat3000(StreamTransport::new(name, SimStream::new(e)), query())
            .with_drain(Duration::ZERO)
    };
    let table = ProfileTable::smc100(
        StreamTransport::new("mem:table", SimStream::new(table)),
        TableOptions::new(query()).with_poll_interval(Duration::from_millis(1)),
    )
    .with_stop_flag(stop.clone());
    (ac("mem:ac1", ac1), ac("mem:ac2", ac2), table, truth)
}

/// The run's instruments: the two autocollimators and the table of `d`.
pub fn instruments(d: &mut (Ac, Ac, Table, Truth)) -> polycal::lab::run::Instruments<'_> {
    polycal::lab::run::Instruments::new(vec![&mut d.0, &mut d.1], &mut d.2)
}

/// What autocollimator `ac` reads at `step` without noise: α + φ of its face + its
/// setup error (docs/FORMAT.md §1).
pub fn expected(truth: &Truth, step: usize, ac: u32) -> f64 {
    let n = truth.faces;
    let face = (step + ac as usize - 1) % n + 1;
    truth.encoder_error[step % n]
        + truth.face_deviation_at(face)
        + truth.setup_error_of(1, ac).unwrap_or(0.0)
}

/// What autocollimator `ac` reads at `step` with the table at `encoder_deg` (its offset
/// from the nominal stop added), without noise.
pub fn expected_at(truth: &Truth, step: usize, ac: u32, encoder_deg: f64) -> f64 {
    let nominal = step as f64 * 360.0 / truth.faces as f64;
    expected(truth, step, ac) + (encoder_deg - nominal) * 3600.0
}

/// A path for a run directory of this test (removed if it exists).
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-inst-run-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// The in-memory ports.
pub fn ports() -> Ports {
    Ports::new(["mem:ac1", "mem:ac2"], "mem:table")
}
