//! A simulated instrument of any profile: it answers the profile's commands with the
//! profile's replies, written from the shared [`World`] (what `sim-lab --ac-profile` /
//! `--table-profile` serves).
//!
//! The profile's conditions say which field values to send: a ready table's state
//! reply holds `ready` and none of `moving`, `not_referenced` and `fault`; a valid
//! measurement's holds `x_valid` (and `y_valid`); an error reply holds `none` until a
//! command is refused. A command the device refuses sets a non-`none` error (the first
//! code of the profile's `error.names`) and, when the command has an acknowledgement
//! and the line has refusals, is answered by the last refusal (e.g. Aerotech's `#`). A
//! command the profile does not have is answered by the first refusal, if any, else not
//! at all.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use super::fault::ValueFaults;
use super::world::{Refused, Stalls};
use super::{Fault, FaultKind, SimDevice, World, lock};
use crate::lab::profile::{
    AcProfile, Condition, Field, FieldKind, LineSettings, Profile, TableProfile, Template,
    format_degrees,
};

/// What the simulated table's state query reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Shown {
    Ready,
    Moving,
    NotReferenced,
    Disabled,
}

/// A simulated instrument speaking a profile.
pub struct ProfileSim {
    world: Arc<Mutex<World>>,
    line: LineSettings,
    name: String,
    device: Kind,
    events: u64,
}

enum Kind {
    Ac {
        number: u32,
        profile: Box<AcProfile>,
        /// Status field values by (X valid, Y valid).
        status: BTreeMap<(bool, bool), Option<String>>,
        x_invalid: Vec<(u64, u64)>,
        values: ValueFaults,
        last: (f64, f64),
    },
    Table {
        profile: Box<TableProfile>,
        /// State field values by what is shown: field → value.
        state: BTreeMap<Shown, Vec<(String, String)>>,
        error_code: Option<String>,
        error_none: Option<String>,
        pending_error: bool,
        disable_after: Option<u64>,
        stalls: Stalls,
    },
}

impl std::fmt::Debug for ProfileSim {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProfileSim")
            .field("profile", &self.name)
            .finish_non_exhaustive()
    }
}

/// Values for every field of `template` such that every condition of `hold` holds and
/// none of `not` does; `None` when the profile's conditions allow no such reply.
fn values_for(
    template: &Template,
    hold: &[&Condition],
    not: &[&Condition],
) -> Option<Vec<(String, String)>> {
    let mut out = Vec::new();
    for field in template.fields() {
        let all: Vec<&Condition> = hold
            .iter()
            .copied()
            .filter(|c| c.field == field.name)
            .collect();
        let none: Vec<&Condition> = not
            .iter()
            .copied()
            .filter(|c| c.field == field.name)
            .collect();
        let value = if all.is_empty() && none.is_empty() {
            placeholder(field)
        } else {
            Condition::example(template, &field.name, &all, &none)?
        };
        out.push((field.name.clone(), value));
    }
    Some(out)
}

fn placeholder(field: &Field) -> String {
    match field.kind {
        FieldKind::Float => "0".into(),
        FieldKind::Decimal | FieldKind::Hex => "0".repeat(field.width.unwrap_or(1)),
        FieldKind::Char => "@".into(),
        FieldKind::Word => "X".into(),
        FieldKind::Text => "polycal".into(),
    }
}

fn render(template: &Template, values: &[(String, String)]) -> String {
    template.render(&|f| {
        values
            .iter()
            .find(|(n, _)| *n == f.name)
            .map_or_else(|| placeholder(f), |(_, v)| v.clone())
    })
}

impl ProfileSim {
    /// Autocollimator `number` of `world` speaking `profile`, with its `x-invalid`
    /// faults; `None` for a table's profile.
    pub fn autocollimator(
        world: Arc<Mutex<World>>,
        profile: &Profile,
        number: u32,
        faults: &[Fault],
    ) -> Option<ProfileSim> {
        let ac = profile.autocollimator().ok()?.clone();
        let template = &ac.measure.reply;
        let mut status = BTreeMap::new();
        for x in [false, true] {
            for y in [false, true] {
                let mut hold = Vec::new();
                let mut not = Vec::new();
                if x {
                    hold.push(&ac.x_valid)
                } else {
                    not.push(&ac.x_valid)
                }
                if let Some(yv) = &ac.y_valid {
                    if y { hold.push(yv) } else { not.push(yv) }
                }
                let value = ac
                    .measure
                    .reply
                    .field("status")
                    .and_then(|_| values_for(template, &hold, &not))
                    .and_then(|v| v.into_iter().find(|(n, _)| n == "status").map(|(_, v)| v));
                status.insert((x, y), value);
            }
        }
        Some(ProfileSim {
            world,
            line: profile.line.clone(),
            name: profile.name.clone(),
            device: Kind::Ac {
                number,
                profile: Box::new(ac),
                status,
                x_invalid: faults
                    .iter()
                    .filter(|f| f.kind == FaultKind::XInvalid)
                    .map(|f| (f.after, f.count))
                    .collect(),
                values: ValueFaults::of(faults),
                last: (0.0, 0.0),
            },
            events: 0,
        })
    }

    /// The table of `world` speaking `profile`, with its `disable` fault; `None` for an
    /// autocollimator's profile.
    pub fn table(
        world: Arc<Mutex<World>>,
        profile: &Profile,
        faults: &[Fault],
    ) -> Option<ProfileSim> {
        let table = profile.table().ok()?.clone();
        let s = &table.state;
        let t = &s.query.reply;
        let optional: Vec<&Condition> = s.not_referenced.iter().chain(s.fault.iter()).collect();
        let mut state = BTreeMap::new();
        let without = |keep: &Condition| -> Vec<&Condition> {
            [&s.ready, &s.moving]
                .into_iter()
                .chain(optional.iter().copied())
                .filter(|c| !std::ptr::eq(*c, keep))
                .collect()
        };
        if let Some(v) = values_for(t, &[&s.ready], &without(&s.ready)) {
            state.insert(Shown::Ready, v);
        }
        if let Some(v) = values_for(t, &[&s.moving], &without(&s.moving)) {
            state.insert(Shown::Moving, v);
        }
        if let Some(nr) = &s.not_referenced
            && let Some(v) = values_for(t, &[nr], &without(nr))
        {
            state.insert(Shown::NotReferenced, v);
        }
        let disabled = match &s.fault {
            Some(fault) => values_for(t, &[fault], &[]),
            None => {
                let all: Vec<&Condition> = [&s.ready, &s.moving]
                    .into_iter()
                    .chain(optional.iter().copied())
                    .collect();
                values_for(t, &[], &all)
            }
        };
        if let Some(v) = disabled {
            state.insert(Shown::Disabled, v);
        }
        let (error_code, error_none) = match &table.error {
            Some(e) => {
                let none =
                    values_for(&e.query.reply, &[&e.none], &[]).map(|v| render(&e.query.reply, &v));
                let code = e
                    .names
                    .keys()
                    .find(|k| {
                        let v = vec![(e.none.field.clone(), (*k).clone())];
                        let line = render(&e.query.reply, &v);
                        e.query
                            .reply
                            .matches(&line)
                            .is_some_and(|c| !e.none.holds(&e.query.reply, &c))
                    })
                    .map(|k| render(&e.query.reply, &[(e.none.field.clone(), k.clone())]))
                    .or_else(|| {
                        values_for(&e.query.reply, &[], &[&e.none])
                            .map(|v| render(&e.query.reply, &v))
                    });
                (code, none)
            }
            None => (None, None),
        };
        Some(ProfileSim {
            world,
            line: profile.line.clone(),
            name: profile.name.clone(),
            device: Kind::Table {
                profile: Box::new(table),
                state,
                error_code,
                error_none,
                pending_error: false,
                disable_after: faults
                    .iter()
                    .find(|f| f.kind == FaultKind::Disable)
                    .map(|f| f.after),
                stalls: Stalls::of(faults),
            },
            events: 0,
        })
    }

    fn reply(&self, text: String) -> Option<String> {
        Some(format!("{text}{}", self.line.reply_end))
    }

    fn identification(&self, template: &Template) -> String {
        let who = match &self.device {
            Kind::Ac { number, .. } => format!("polycal simulated {} SIM-{number}", self.name),
            Kind::Table { .. } => format!("polycal simulated {}", self.name),
        };
        // A text field glued to a literal word (`ESP301{version:s}`) is written apart
        // from it, as a device would (`ESP301 Version …`).
        let text = template.as_str();
        template.render(&|f| match f.kind {
            FieldKind::Text => {
                let glued = text
                    .find(&format!("{{{}:", f.name))
                    .and_then(|i| text[..i].chars().last())
                    .is_some_and(|c| c.is_alphanumeric());
                if glued {
                    format!(" {who}")
                } else {
                    who.clone()
                }
            }
            _ => placeholder(f),
        })
    }

    fn measurement(&mut self, now: Instant) -> String {
        let before = self.events;
        self.events += 1;
        let Kind::Ac {
            number,
            profile,
            status,
            x_invalid,
            values,
            last,
        } = &mut self.device
        else {
            return String::new();
        };
        let (mut axes, x, y) = lock(&self.world).measure(*number, now);
        for (after, left) in x_invalid.iter_mut() {
            if before >= *after && *left > 0 {
                *left -= 1;
                axes = 2;
            }
        }
        *last = (x, y);
        let (x, y) = values.apply(before, x, y);
        let valid = (axes & 1 != 0, axes & 2 != 0);
        let status_value = status.get(&valid).cloned().flatten();
        profile.measure.reply.render(&|f| match f.name.as_str() {
            "x" => format!("{x:.6}"),
            "y" => format!("{y:.6}"),
            "status" => status_value.clone().unwrap_or_else(|| placeholder(f)),
            _ => placeholder(f),
        })
    }

    fn handle_ac(&mut self, command: &str, now: Instant) -> Option<String> {
        let Kind::Ac { profile, .. } = &self.device else {
            return None;
        };
        if command == profile.measure.send {
            let line = self.measurement(now);
            return self.reply(line);
        }
        if command == profile.identify.send {
            let template = profile.identify.reply.clone();
            let line = self.identification(&template);
            return self.reply(line);
        }
        if profile.start.iter().any(|c| c == command) {
            return None;
        }
        self.unknown()
    }

    fn unknown(&self) -> Option<String> {
        let refusal = self.line.refusals.first()?;
        let line = refusal.render(&|f| placeholder(f));
        self.reply(line)
    }

    fn state_line(&self, now: Instant) -> Option<String> {
        let Kind::Table { profile, state, .. } = &self.device else {
            return None;
        };
        let code = lock(&self.world).table_state(now);
        let shown = match code {
            0x0A..=0x11 if state.contains_key(&Shown::NotReferenced) => Shown::NotReferenced,
            0x0A..=0x11 => Shown::Ready,
            0x1E | 0x1F | 0x28 => Shown::Moving,
            0x32..=0x34 => Shown::Ready,
            _ => Shown::Disabled,
        };
        let values = state.get(&shown).or_else(|| state.get(&Shown::Ready))?;
        Some(render(&profile.state.query.reply, values))
    }

    /// A table command: the reply line (without terminator), if any.
    fn handle_table(&mut self, command: &str, now: Instant) -> Option<String> {
        let Kind::Table {
            profile,
            error_code,
            error_none,
            pending_error,
            disable_after,
            stalls,
            ..
        } = &mut self.device
        else {
            return None;
        };
        let profile = profile.clone();
        let ack = |c: &crate::lab::profile::Command| {
            c.ack.as_ref().map(|t| t.render(&|f| placeholder(f)))
        };
        let refusal = self
            .line
            .refusals
            .last()
            .map(|r| r.render(&|f| placeholder(f)));
        if command == profile.state.query.send {
            return self.state_line(now);
        }
        if command == profile.position.send {
            let mut world = lock(&self.world);
            world.touch(now);
            let deg = format_degrees(world.encoder_position(now));
            return Some(profile.position.reply.render(&|f| {
                if f.name == "deg" {
                    deg.clone()
                } else {
                    placeholder(f)
                }
            }));
        }
        if command == profile.identify.send {
            return Some(self.identification(&profile.identify.reply));
        }
        if let Some(e) = &profile.error
            && command == e.query.send
        {
            let line = if std::mem::take(pending_error) {
                error_code.clone()
            } else {
                error_none.clone()
            };
            return line;
        }
        if let Some((q, when)) = &profile.referenced
            && command == q.send
        {
            let referenced = lock(&self.world).table.referenced;
            let values = if referenced {
                values_for(&q.reply, &[when], &[])
            } else {
                values_for(&q.reply, &[], &[when])
            }?;
            return Some(render(&q.reply, &values));
        }
        if let Some(c) = profile.enable.iter().find(|c| c.send == command) {
            return ack(c);
        }
        if command == profile.stop.send {
            lock(&self.world).stop_motion(now);
            return ack(&profile.stop);
        }
        if command == profile.home.send {
            // A controller homes on request (the runner asks only when it must).
            let refused = lock(&self.world).start_home(true, now).is_err();
            if refused {
                *pending_error = true;
                return if profile.home.ack.is_some() {
                    refusal
                } else {
                    None
                };
            }
            return ack(&profile.home);
        }
        if let Some((before, after)) = profile.motion.send.split_once("{deg}")
            && let Some(number) = command
                .strip_prefix(before)
                .and_then(|rest| rest.strip_suffix(after))
        {
            let moves_before = self.events;
            self.events += 1;
            let fails = disable_after.is_some_and(|k| moves_before >= k);
            let short_deg = stalls.shortfall_deg(moves_before);
            let refused = match number.trim().parse::<f64>() {
                Ok(target) if target.is_finite() => lock(&self.world)
                    .start_move(target, fails, short_deg, now)
                    .err(),
                _ => Some(Refused::OutOfTravel),
            };
            if refused.is_some() {
                *pending_error = true;
                return if profile.motion.ack.is_some() {
                    refusal
                } else {
                    None
                };
            }
            return ack(&profile.motion);
        }
        *pending_error = true;
        self.line
            .refusals
            .first()
            .map(|r| r.render(&|f| placeholder(f)))
    }
}

impl SimDevice for ProfileSim {
    fn handle(&mut self, command: &str, now: Instant) -> Option<String> {
        match self.device {
            Kind::Ac { .. } => self.handle_ac(command, now),
            Kind::Table { .. } => {
                let line = self.handle_table(command, now)?;
                self.reply(line)
            }
        }
    }

    fn tick(&mut self, _now: Instant) -> Option<String> {
        None
    }

    fn events(&self) -> u64 {
        self.events
    }

    /// An autocollimator: a measurement 99″ beyond the last in X; a table: a position
    /// reply 1° beyond where it is.
    fn unsolicited(&mut self, now: Instant) -> String {
        let line = match &self.device {
            Kind::Ac {
                profile,
                status,
                last,
                ..
            } => {
                let (x, y) = *last;
                let s = status.get(&(true, true)).cloned().flatten();
                profile.measure.reply.render(&|f| match f.name.as_str() {
                    "x" => format!("{:.6}", x + 99.0),
                    "y" => format!("{y:.6}"),
                    "status" => s.clone().unwrap_or_else(|| placeholder(f)),
                    _ => placeholder(f),
                })
            }
            Kind::Table { profile, .. } => {
                let deg = format_degrees(lock(&self.world).encoder_position(now) + 1.0);
                profile.position.reply.render(&|f| {
                    if f.name == "deg" {
                        deg.clone()
                    } else {
                        placeholder(f)
                    }
                })
            }
        };
        format!("{line}{}", self.line.reply_end)
    }
}
