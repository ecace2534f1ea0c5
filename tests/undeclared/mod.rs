//! Designs shared by the tests of issue 21 (undeclared effects).
#![allow(dead_code)]

use polycal::effects::Effect;
use polycal::simulate::{ElevationModel, SimulationConfig};

/// Two mountings (shifted by 5 faces), 4 cycles each, an elevation axis without a
/// mounting tilt: `reading_y` = Y[face] + W[step] + offsets, so that closure determines
/// only the differences of the autocollimators' cross-talk coefficients.
pub fn two_mountings_with_y(seed: u64, effects: Vec<Effect>) -> SimulationConfig {
    SimulationConfig {
        setups: 2,
        setup_shift_faces: 5,
        cycles: 4,
        elevation: Some(ElevationModel {
            mounting_tilt_arcsec: 0.0,
            ..ElevationModel::default()
        }),
        effects,
        seed,
        ..SimulationConfig::default()
    }
}
