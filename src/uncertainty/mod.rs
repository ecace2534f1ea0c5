//! GUM uncertainty (placeholder until the uncertainty branch lands).

pub mod student;
