//! What a table's state and error replies say, read by its profile's conditions.

use std::collections::BTreeMap;

use super::TableState;
use super::wire::TableWire;
use crate::lab::InstrumentError;
use crate::lab::profile::{Captures, Condition, Template};

/// `field value (name)` of a condition's field in a reply, for messages.
fn describe(wire: &TableWire, condition: &Condition, captures: &Captures) -> String {
    let value = captures.get(&condition.field).unwrap_or("");
    let names = &wire.table().state.names;
    match names
        .get(&condition.field)
        .and_then(|n| n.iter().find(|(k, _)| k.eq_ignore_ascii_case(value)))
    {
        Some((_, name)) => format!("{} {value} ({name})", condition.field),
        None => format!("{} {value}", condition.field),
    }
}

/// The state a reply `line` (read as `captures`) reports.
///
/// # Errors
///
/// A fault the state reports (with the names of its bits), and a state that is neither
/// ready, moving nor "not referenced" (a disabled or misconfigured controller).
pub(super) fn classify_state(
    wire: &TableWire,
    captures: &Captures,
    line: &str,
) -> Result<TableState, InstrumentError> {
    let state = &wire.table().state;
    let sent = &state.query.send;
    let template = &state.query.reply;
    if let Some(fault) = &state.fault
        && fault.holds(template, captures)
    {
        let value = captures.get(&fault.field).unwrap_or("").to_string();
        let bits = bit_names(template, &fault.field, &value, state.bits.get(&fault.field));
        return Err(wire.device_error(
            sent,
            line,
            format!(
                "the controller reports a fault ({} {value}{})",
                fault.field,
                if bits.is_empty() {
                    String::new()
                } else {
                    format!(": {}", bits.join(", "))
                }
            ),
        ));
    }
    // A state that is "ready" and "not referenced" at once is not referenced: an axis
    // at rest that has lost (or never had) its reference must be homed before it is
    // moved (an Aerotech AXISSTATUS with Enabled and InPosition set, Homed clear).
    let not_referenced = state
        .not_referenced
        .as_ref()
        .is_some_and(|c| c.holds(template, captures));
    if state.ready.holds(template, captures) && !not_referenced {
        return Ok(TableState::Ready);
    }
    if state.moving.holds(template, captures) {
        return Ok(TableState::Moving);
    }
    if not_referenced {
        return Ok(TableState::NotReferenced);
    }
    let what = describe(wire, &state.ready, captures);
    Err(wire.device_error(
        sent,
        line,
        format!("the table is neither ready nor moving: {what}"),
    ))
}

/// After a motion command, the error reply `line`: the controller must not have refused
/// `motion`.
pub(super) fn accepted(
    wire: &TableWire,
    motion: &str,
    captures: &Captures,
    line: &str,
) -> Result<(), InstrumentError> {
    let Some(error) = &wire.table().error else {
        return Ok(());
    };
    if error.none.holds(&error.query.reply, captures) {
        return Ok(());
    }
    let code = captures.get(&error.none.field).unwrap_or("").to_string();
    let meaning = error
        .names
        .iter()
        .find(|(k, _)| k.eq_ignore_ascii_case(&code))
        .map(|(_, v)| v.clone())
        .or_else(|| bit_meaning(&error.names, &code))
        .unwrap_or_else(|| "no meaning in the profile".to_string());
    Err(wire.device_error(
        &error.query.send,
        line,
        format!(
            "the controller refused {:?}: error {code} ({meaning})",
            wire.wire(motion)
        ),
    ))
}

/// The meaning of an error code that is a bit mask (Aerotech's AXISFAULT), from the
/// names the profile gives its single bits: `None` unless the code is a number of two
/// bits or more, every one of them named.
fn bit_meaning(names: &BTreeMap<String, String>, code: &str) -> Option<String> {
    let bits: u64 = code.trim().parse().ok()?;
    if bits.count_ones() < 2 {
        return None;
    }
    (0..64)
        .filter(|i| bits & (1 << i) != 0)
        .map(|i| names.get(&(1u64 << i).to_string()).cloned())
        .collect::<Option<Vec<String>>>()
        .map(|named| named.join(", "))
}

/// The names of the bits set in a digit field's value.
fn bit_names(
    template: &Template,
    field: &str,
    value: &str,
    names: Option<&Vec<String>>,
) -> Vec<String> {
    let (Some(names), Some(radix)) = (names, template.field(field).and_then(|f| f.kind.radix()))
    else {
        return Vec::new();
    };
    let Ok(bits) = u64::from_str_radix(value, radix) else {
        return Vec::new();
    };
    (0..64)
        .filter(|i| bits & (1 << i) != 0)
        .map(|i| names.get(i).cloned().unwrap_or_else(|| format!("bit {i}")))
        .collect()
}
