//! The drivers: any instrument a [`Profile`](crate::lab::profile::Profile) describes,
//! driven by the runner's rules (module [`crate::lab`], *Retries and motion*).
//!
//! [`ProfileAutocollimator`] and [`ProfileTable`] take what to send and how to read the
//! replies from the profile; everything else is theirs and the same for every profile:
//! the drain before every query, the reply deadline, a reply taken only when it comes
//! alone, resynchronisation with the identification after a late or doubtful reply, a
//! query retried, a motion never sent twice, the error asked after every motion
//! command, the state polled until the motion is done within its timeout, and the
//! position checked against the command.

mod autocollimator;
mod table;

pub use autocollimator::{AcOp, AcOutcome, AcWire, ProfileAutocollimator};
pub use table::{
    POSITION_TOLERANCE_DEG, ProfileTable, TableOp, TableOptions, TableOutcome, TableState,
    TableWire,
};

use super::ReplyError;
use super::profile::{Captures, LineSettings, Template};

/// Reads a reply line against `template`: a refusal of the line's, or a line not of the
/// template's form, is a [`ReplyError`].
pub(crate) fn read_reply(
    line: &LineSettings,
    template: &Template,
    reply: &str,
) -> Result<Captures, ReplyError> {
    if let Some(captures) = template.matches(reply) {
        return Ok(captures);
    }
    if let Some(refusal) = line.refusals.iter().find(|r| r.matches(reply).is_some()) {
        return Err(ReplyError::Refused {
            form: refusal.as_str().to_string(),
        });
    }
    Err(ReplyError::NotTheForm {
        form: template.as_str().to_string(),
    })
}
