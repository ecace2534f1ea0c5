//! The instruments a run needs, as traits: an autocollimator that gives one measurement on
//! request, and a rotary table that moves to absolute positions.

use super::InstrumentError;

/// One autocollimator measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct AcReading {
    /// The device's three-digit status, e.g. 3 for `003`.
    pub status: u16,
    /// Measuring axis (X), arcsec; always valid in a returned reading.
    pub x_arcsec: f64,
    /// Second axis (Y), arcsec, when the status says it is valid.
    pub y_arcsec: Option<f64>,
}

impl AcReading {
    /// A measurement: the device's status, X and, when valid, Y, arcsec.
    pub fn new(status: u16, x_arcsec: f64, y_arcsec: Option<f64>) -> AcReading {
        AcReading {
            status,
            x_arcsec,
            y_arcsec,
        }
    }
}

/// An autocollimator that gives one absolute two-axis measurement on request.
pub trait Autocollimator {
    /// The port it is connected to (for messages).
    fn port(&self) -> &str;
    /// Puts the device into a known state (stops any stream, clears pending input).
    fn start(&mut self) -> Result<(), InstrumentError>;
    /// The device's identification.
    fn identify(&mut self) -> Result<String, InstrumentError>;
    /// One absolute measurement whose X axis is valid (retried as a query).
    fn measure(&mut self) -> Result<AcReading, InstrumentError>;
}

/// A rotary table that moves to absolute positions in degrees.
pub trait RotaryTable {
    /// The port it is connected to (for messages).
    fn port(&self) -> &str;
    /// Makes the table ready to move: clears pending input, checks the state, homes it
    /// when it is not referenced, and waits until it is ready.
    fn start(&mut self) -> Result<(), InstrumentError>;
    /// The controller's identification.
    fn identify(&mut self) -> Result<String, InstrumentError>;
    /// Moves to `degrees` (the motion command is sent exactly once), waits until the
    /// table is ready, and returns the position it reports.
    fn move_to(&mut self, degrees: f64) -> Result<f64, InstrumentError>;
    /// The position the table reports, degrees.
    fn position(&mut self) -> Result<f64, InstrumentError>;
    /// Stops any motion at once.
    fn stop(&mut self) -> Result<(), InstrumentError>;
}
