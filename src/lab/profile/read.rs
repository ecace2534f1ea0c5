//! Reading a profile file: the TOML, checked key by key, every refusal at its line and
//! column.

use std::collections::BTreeMap;

use serde::Deserialize;
use toml::Spanned;

use super::{
    AcProfile, Command, Condition, ErrorQuery, FlowControl, LineSettings, Parity, Profile,
    ProfileError, ProfileKind, Query, StateQuery, TableProfile, Template,
};
use crate::uncertainty::budget_file::location;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawProfile {
    profile: Spanned<String>,
    instrument: Spanned<String>,
    #[serde(default)]
    description: String,
    #[serde(default)]
    source: String,
    line: RawLine,
    axis: Option<Spanned<String>>,
    identify: RawQuery,
    // An autocollimator's.
    start: Option<RawStart>,
    measure: Option<RawMeasure>,
    // A table's.
    #[serde(default)]
    enable: Vec<RawCommand>,
    home: Option<RawCommand>,
    referenced: Option<RawReferenced>,
    state: Option<RawState>,
    #[serde(rename = "move")]
    motion: Option<RawCommand>,
    position: Option<RawQuery>,
    error: Option<RawError>,
    stop: Option<RawCommand>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLine {
    baud: Spanned<u32>,
    #[serde(default = "eight")]
    data_bits: Spanned<u8>,
    #[serde(default = "none")]
    parity: Spanned<String>,
    #[serde(default = "one")]
    stop_bits: Spanned<u8>,
    #[serde(default = "none")]
    flow_control: Spanned<String>,
    command_end: Spanned<String>,
    reply_end: Spanned<String>,
    #[serde(default)]
    refusal: Vec<Spanned<String>>,
}

fn eight() -> Spanned<u8> {
    Spanned::new(0..0, 8)
}
fn one() -> Spanned<u8> {
    Spanned::new(0..0, 1)
}
fn none() -> Spanned<String> {
    Spanned::new(0..0, "none".to_string())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawQuery {
    send: Spanned<String>,
    reply: Spanned<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCommand {
    send: Spanned<String>,
    reply: Option<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStart {
    send: Vec<Spanned<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMeasure {
    send: Spanned<String>,
    reply: Spanned<String>,
    x_valid: Spanned<Condition>,
    y_valid: Option<Spanned<Condition>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawReferenced {
    send: Spanned<String>,
    reply: Spanned<String>,
    when: Spanned<Condition>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawState {
    send: Spanned<String>,
    reply: Spanned<String>,
    ready: Spanned<Condition>,
    moving: Spanned<Condition>,
    not_referenced: Option<Spanned<Condition>>,
    fault: Option<Spanned<Condition>>,
    #[serde(default)]
    names: BTreeMap<String, BTreeMap<String, String>>,
    #[serde(default)]
    bits: BTreeMap<String, Vec<String>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawError {
    send: Spanned<String>,
    reply: Spanned<String>,
    none: Spanned<Condition>,
    #[serde(default)]
    names: BTreeMap<String, String>,
}

/// Where errors point: the source's name and text.
struct At<'a> {
    source: &'a str,
    text: &'a str,
}

impl At<'_> {
    fn error(&self, offset: usize, message: impl Into<String>) -> ProfileError {
        ProfileError::File {
            location: location(self.source, self.text, offset),
            message: message.into(),
        }
    }

    /// The offset of character `chars` inside a quoted string value starting at `start`.
    fn inside(&self, start: usize, chars: usize) -> usize {
        let value = &self.text[start.min(self.text.len())..];
        let skip = usize::from(value.starts_with(['"', '\'']));
        value
            .char_indices()
            .nth(skip + chars)
            .map_or(start, |(i, _)| start + i)
    }
}

/// Reads the text of a profile.
pub(super) fn parse(text: &str, source: &str) -> Result<Profile, ProfileError> {
    let at = At { source, text };
    let raw: RawProfile = toml::from_str(text).map_err(|e| {
        let offset = e.span().map_or(0, |s| s.start);
        at.error(offset, e.message().trim().to_string())
    })?;
    let values = Values {
        at: &at,
        axis: raw.axis.as_ref().map(|a| a.get_ref().clone()),
    };
    let line = line_settings(&raw.line, &at, &|s| values.template(s))?;
    let identify = values.query(&raw.identify)?;
    let name = raw.profile.get_ref().trim().to_string();
    if name.is_empty() {
        return Err(at.error(raw.profile.span().start, "the profile needs a name"));
    }
    let kind = match raw.instrument.get_ref().as_str() {
        "autocollimator" => values.autocollimator(&raw, identify)?,
        "table" => values.table(&raw, identify)?,
        other => {
            return Err(at.error(
                raw.instrument.span().start,
                format!("instrument {other:?}: it is \"autocollimator\" or \"table\""),
            ));
        }
    };
    Ok(Profile {
        name,
        description: raw.description,
        source: raw.source,
        line,
        kind,
        sha256: text_sha256(text),
    })
}

/// The SHA-256 of a profile's text, lower-case hex.
fn text_sha256(text: &str) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(text.as_bytes())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The profile's values read into commands, replies and conditions: `{axis}` expanded,
/// every refusal at its line and column.
struct Values<'a> {
    at: &'a At<'a>,
    /// The profile's `axis`, for `{axis}`.
    axis: Option<String>,
}

impl Values<'_> {
    /// A command or query string with `{axis}` expanded; `{deg}` only where
    /// `allow_deg` (the move command).
    fn expand(&self, s: &Spanned<String>, allow_deg: bool) -> Result<String, ProfileError> {
        let at = self.at;
        let value = s.get_ref();
        if let Some(i) = value.find(['\r', '\n']) {
            return Err(at.error(
                at.inside(s.span().start, value[..i].chars().count()),
                "a command or reply holds no line end: the line's command_end and reply_end add them",
            ));
        }
        let mut out = value.clone();
        if out.contains("{axis}") {
            let Some(axis) = &self.axis else {
                return Err(at.error(
                    s.span().start,
                    "`{axis}` is used but the profile gives no `axis = \"…\"`",
                ));
            };
            out = out.replace("{axis}", axis);
        }
        if !allow_deg && out.contains("{deg}") {
            return Err(at.error(s.span().start, "`{deg}` belongs in the move command only"));
        }
        if out.trim().is_empty() {
            return Err(at.error(s.span().start, "the command is empty"));
        }
        Ok(out)
    }

    /// A reply template, expanded and parsed.
    fn template(&self, s: &Spanned<String>) -> Result<Template, ProfileError> {
        let at = self.at;
        let text = self.expand(s, false)?;
        Template::parse(&text).map_err(|e| {
            // Offsets after an expanded `{axis}` are approximate; the value's start is not.
            let offset = if s.get_ref() == &text {
                at.inside(s.span().start, e.offset)
            } else {
                s.span().start
            };
            at.error(
                offset,
                format!("the template {:?}: {}", s.get_ref(), e.problem),
            )
        })
    }

    /// A query: what is sent and the template of its reply.
    fn query(&self, q: &RawQuery) -> Result<Query, ProfileError> {
        Ok(Query {
            send: self.expand(&q.send, false)?,
            reply: self.template(&q.reply)?,
        })
    }

    /// A command, with the template of its acknowledgement where it has one.
    fn command(&self, c: &RawCommand, allow_deg: bool) -> Result<Command, ProfileError> {
        Ok(Command {
            send: self.expand(&c.send, allow_deg)?,
            ack: c.reply.as_ref().map(|r| self.template(r)).transpose()?,
        })
    }

    /// A condition on the fields of the reply template `on`.
    fn condition(&self, c: &Spanned<Condition>, on: &Template) -> Result<Condition, ProfileError> {
        c.get_ref()
            .check(on)
            .map_err(|e| self.at.error(c.span().start, e.to_string()))?;
        Ok(c.get_ref().clone())
    }

    /// Refuses a profile of instrument `kind` without the section `key` (`ok`: it has it).
    fn present(
        &self,
        raw: &RawProfile,
        key: &str,
        ok: bool,
        kind: &str,
    ) -> Result<(), ProfileError> {
        if ok {
            Ok(())
        } else {
            Err(self.at.error(
                raw.instrument.span().start,
                format!("{kind} has no `[{key}]`: describe it, or give instrument = \"…\" for the other kind"),
            ))
        }
    }

    /// Refuses a profile of instrument `kind` with the section `key` it has not (`given`).
    fn not_here(
        &self,
        raw: &RawProfile,
        key: &str,
        given: bool,
        kind: &str,
    ) -> Result<(), ProfileError> {
        if given {
            Err(self.at.error(
                raw.instrument.span().start,
                format!("`[{key}]` is not something {kind} has"),
            ))
        } else {
            Ok(())
        }
    }

    /// An autocollimator's profile: its start commands and its measurement query, whose
    /// reply must differ from the identification's.
    fn autocollimator(
        &self,
        raw: &RawProfile,
        identify: Query,
    ) -> Result<ProfileKind, ProfileError> {
        let at = self.at;
        let who = "an autocollimator";
        for (key, given) in [
            ("enable", !raw.enable.is_empty()),
            ("home", raw.home.is_some()),
            ("referenced", raw.referenced.is_some()),
            ("state", raw.state.is_some()),
            ("move", raw.motion.is_some()),
            ("position", raw.position.is_some()),
            ("error", raw.error.is_some()),
            ("stop", raw.stop.is_some()),
        ] {
            self.not_here(raw, key, given, who)?;
        }
        self.present(raw, "measure", raw.measure.is_some(), who)?;
        let Some(m) = &raw.measure else {
            return Err(at.error(0, "no [measure]"));
        };
        let reply = self.template(&m.reply)?;
        number_field(&reply, "x", &m.reply, at, true)?;
        number_field(&reply, "y", &m.reply, at, false)?;
        let x_valid = self.condition(&m.x_valid, &reply)?;
        let y_valid = m
            .y_valid
            .as_ref()
            .map(|c| self.condition(c, &reply))
            .transpose()?;
        let measure = Query {
            send: self.expand(&m.send, false)?,
            reply,
        };
        let start = raw
            .start
            .as_ref()
            .map(|s| s.send.iter().map(|c| self.expand(c, false)).collect())
            .transpose()?
            .unwrap_or_default();
        let ac = AcProfile {
            start,
            identify,
            measure,
            x_valid,
            y_valid,
        };
        let x = ac
            .measure
            .reply
            .render(&|f| sample(f, &ac.measure.reply, &[&ac.x_valid]));
        distinct(&ac.identify, &raw.identify, &[("measurement", x)], at)?;
        Ok(ProfileKind::Autocollimator(Box::new(ac)))
    }

    /// A rotary table's profile: its commands and queries, whose replies must differ from
    /// the identification's.
    fn table(&self, raw: &RawProfile, identify: Query) -> Result<ProfileKind, ProfileError> {
        let at = self.at;
        let who = "a rotary table";
        for (key, given) in [
            ("start", raw.start.is_some()),
            ("measure", raw.measure.is_some()),
        ] {
            self.not_here(raw, key, given, who)?;
        }
        for (key, given) in [
            ("home", raw.home.is_some()),
            ("state", raw.state.is_some()),
            ("move", raw.motion.is_some()),
            ("position", raw.position.is_some()),
            ("stop", raw.stop.is_some()),
        ] {
            self.present(raw, key, given, who)?;
        }
        let (Some(home), Some(state), Some(motion), Some(position), Some(stop)) =
            (&raw.home, &raw.state, &raw.motion, &raw.position, &raw.stop)
        else {
            return Err(at.error(0, "a table's sections are missing"));
        };
        let motion_command = self.command(motion, true)?;
        if !motion_command.send.contains("{deg}") {
            return Err(at.error(
                motion.send.span().start,
                "the move command needs `{deg}`, where the position goes",
            ));
        }
        let state_query = self.state_query(state)?;
        let position_query = self.query(position)?;
        number_field(&position_query.reply, "deg", &position.reply, at, true)?;
        let referenced = raw
            .referenced
            .as_ref()
            .map(|r| -> Result<(Query, Condition), ProfileError> {
                let reply = self.template(&r.reply)?;
                let when = self.condition(&r.when, &reply)?;
                Ok((
                    Query {
                        send: self.expand(&r.send, false)?,
                        reply,
                    },
                    when,
                ))
            })
            .transpose()?;
        let error = raw
            .error
            .as_ref()
            .map(|e| -> Result<ErrorQuery, ProfileError> {
                let reply = self.template(&e.reply)?;
                let none = self.condition(&e.none, &reply)?;
                Ok(ErrorQuery {
                    query: Query {
                        send: self.expand(&e.send, false)?,
                        reply,
                    },
                    none,
                    names: e.names.clone(),
                })
            })
            .transpose()?;
        let table = TableProfile {
            identify,
            enable: raw
                .enable
                .iter()
                .map(|c| self.command(c, false))
                .collect::<Result<_, _>>()?,
            home: self.command(home, false)?,
            referenced,
            state: state_query,
            motion: motion_command,
            position: position_query,
            error,
            stop: self.command(stop, false)?,
        };
        let mut others = vec![
            (
                "state",
                table
                    .state
                    .query
                    .reply
                    .render(&|f| sample(f, &table.state.query.reply, &[&table.state.ready])),
            ),
            (
                "position",
                table
                    .position
                    .reply
                    .render(&|f| sample(f, &table.position.reply, &[])),
            ),
        ];
        if let Some(e) = &table.error {
            others.push((
                "error",
                e.query
                    .reply
                    .render(&|f| sample(f, &e.query.reply, &[&e.none])),
            ));
        }
        distinct(&table.identify, &raw.identify, &others, at)?;
        Ok(ProfileKind::Table(Box::new(table)))
    }

    /// A table's state query, with the conditions read from its reply.
    fn state_query(&self, state: &RawState) -> Result<StateQuery, ProfileError> {
        let state_reply = self.template(&state.reply)?;
        Ok(StateQuery {
            query: Query {
                send: self.expand(&state.send, false)?,
                reply: state_reply.clone(),
            },
            ready: self.condition(&state.ready, &state_reply)?,
            moving: self.condition(&state.moving, &state_reply)?,
            not_referenced: state
                .not_referenced
                .as_ref()
                .map(|c| self.condition(c, &state_reply))
                .transpose()?,
            fault: state
                .fault
                .as_ref()
                .map(|c| self.condition(c, &state_reply))
                .transpose()?,
            names: state.names.clone(),
            bits: state.bits.clone(),
        })
    }
}

fn line_settings(
    raw: &RawLine,
    at: &At<'_>,
    template: &dyn Fn(&Spanned<String>) -> Result<Template, ProfileError>,
) -> Result<LineSettings, ProfileError> {
    let baud = *raw.baud.get_ref();
    if !(50..=4_000_000).contains(&baud) {
        return Err(at.error(
            raw.baud.span().start,
            format!("baud {baud}: out of range 50 … 4000000"),
        ));
    }
    let data_bits = *raw.data_bits.get_ref();
    if !(5..=8).contains(&data_bits) {
        return Err(at.error(raw.data_bits.span().start, "data_bits: 5, 6, 7 or 8"));
    }
    let stop_bits = *raw.stop_bits.get_ref();
    if !(1..=2).contains(&stop_bits) {
        return Err(at.error(raw.stop_bits.span().start, "stop_bits: 1 or 2"));
    }
    let parity = match raw.parity.get_ref().as_str() {
        "none" => Parity::None,
        "even" => Parity::Even,
        "odd" => Parity::Odd,
        other => {
            return Err(at.error(
                raw.parity.span().start,
                format!("parity {other:?}: \"none\", \"even\" or \"odd\""),
            ));
        }
    };
    let flow_control = match raw.flow_control.get_ref().as_str() {
        "none" => FlowControl::None,
        "software" => FlowControl::Software,
        "hardware" => FlowControl::Hardware,
        other => {
            return Err(at.error(
                raw.flow_control.span().start,
                format!("flow_control {other:?}: \"none\", \"software\" (XON/XOFF) or \"hardware\" (RTS/CTS)"),
            ));
        }
    };
    for end in [&raw.command_end, &raw.reply_end] {
        if !matches!(end.get_ref().as_str(), "\r" | "\n" | "\r\n") {
            return Err(at.error(
                end.span().start,
                format!(
                    "{:?}: a line ends with \"\\r\", \"\\n\" or \"\\r\\n\"",
                    end.get_ref()
                ),
            ));
        }
    }
    Ok(LineSettings {
        baud,
        data_bits,
        parity,
        stop_bits,
        flow_control,
        command_end: raw.command_end.get_ref().clone(),
        reply_end: raw.reply_end.get_ref().clone(),
        refusals: raw.refusal.iter().map(template).collect::<Result<_, _>>()?,
    })
}

/// A reply's number field: present and of kind `f` or `d`.
fn number_field(
    template: &Template,
    name: &str,
    raw: &Spanned<String>,
    at: &At<'_>,
    required: bool,
) -> Result<(), ProfileError> {
    match template.field(name) {
        None if required => Err(at.error(
            raw.span().start,
            format!(
                "the reply {:?} needs the field `{{{name}:f}}`",
                raw.get_ref()
            ),
        )),
        Some(f) if !matches!(f.kind, super::FieldKind::Float | super::FieldKind::Decimal) => {
            Err(at.error(
                raw.span().start,
                format!("the field `{name}` is a number: kind f (or d)"),
            ))
        }
        _ => Ok(()),
    }
}

/// A value for field `f` of `template` that the conditions `hold` allow: for the samples
/// the identification is checked against, and the simulated lab's replies.
pub(crate) fn sample(f: &super::Field, template: &Template, hold: &[&Condition]) -> String {
    let on: Vec<&Condition> = hold.iter().copied().filter(|c| c.field == f.name).collect();
    if !on.is_empty()
        && let Some(v) = Condition::example(template, &f.name, &on, &[])
    {
        return v;
    }
    match f.kind {
        super::FieldKind::Float => "45.5".into(),
        super::FieldKind::Decimal | super::FieldKind::Hex => "0".repeat(f.width.unwrap_or(1)),
        super::FieldKind::Char => "@".into(),
        super::FieldKind::Word => "X".into(),
        super::FieldKind::Text => "text".into(),
    }
}

/// The identification's reply must not pass for any other reply: it is what brings a
/// device back in step after a late reply.
fn distinct(
    identify: &Query,
    raw: &RawQuery,
    others: &[(&str, String)],
    at: &At<'_>,
) -> Result<(), ProfileError> {
    for (what, line) in others {
        if identify.reply.matches(line).is_some() {
            return Err(at.error(
                raw.reply.span().start,
                format!(
                    "a {what} reply such as {line:?} would pass for the identification {:?}: the runner brings a device back in step with it, so its reply must be one no other reply can be mistaken for (start it with the text the device always sends, e.g. a maker's name)",
                    identify.reply.as_str()
                ),
            ));
        }
    }
    Ok(())
}
