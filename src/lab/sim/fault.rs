//! Injected faults: `KIND:DEVICE[:after=K][:count=M][:seconds=S|:commands=C][:fraction=F]` (see
//! [`crate::lab::sim`], *Faults*).

use std::fmt;
use std::str::FromStr;
use std::time::Duration;

/// Which simulated device.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DeviceId {
    /// Autocollimator 1, 2, … K.
    Ac(u32),
    /// The rotary table.
    Table,
}

impl fmt::Display for DeviceId {
    /// `ac1`, `ac2`, … or `table`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DeviceId::Ac(n) => write!(f, "ac{n}"),
            DeviceId::Table => f.write_str("table"),
        }
    }
}

impl FromStr for DeviceId {
    type Err = ();

    /// `ac1`, `ac2`, … (1 … 16) or `table`.
    fn from_str(text: &str) -> Result<DeviceId, ()> {
        if text == "table" {
            return Ok(DeviceId::Table);
        }
        match text.strip_prefix("ac").map(str::parse::<u32>) {
            Some(Ok(n)) if (1..=16).contains(&n) && !text[2..].starts_with('0') => {
                Ok(DeviceId::Ac(n))
            }
            _ => Err(()),
        }
    }
}

/// What a fault does (see [`crate::lab::sim`], *Faults*).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FaultKind {
    /// Replies are not sent.
    LostReply,
    /// Replies are garbled.
    Garbled,
    /// Measurements report X not valid.
    XInvalid,
    /// The table stops midway and stays disabled.
    Disable,
    /// The device closes its port.
    Close,
    /// Replies are sent late, by the fault's `seconds`; later replies wait behind them
    /// (a device answers in order). With `commands=C` a reply is held instead until C
    /// more commands have come and sent just inside the C-th's reply window, ahead of
    /// its reply; later replies do not wait behind it.
    Late,
    /// Replies are sent twice.
    Duplicated,
    /// A line in the form of a reply, that nothing asked for, is sent just before the
    /// reply.
    Unsolicited,
    /// A reply is held back and sent after the next one: two consecutive replies
    /// swapped.
    Swapped,
    /// The previous reply is sent again instead of the reply (a stale value).
    Stale,
    /// The table's move ends short of its target by the fault's `fraction` of the
    /// position tolerance ([`crate::lab::driver::POSITION_TOLERANCE_DEG`]) and reports
    /// where it stands: within the tolerance for a fraction below 1.
    Stall,
    /// A measurement of the right form with its X negated (a sign lost on the way).
    SignFlip,
    /// A measurement of the right form with X and Y exchanged.
    SwapXy,
    /// A measurement of the right form with X's units digit dropped (`12.345678` →
    /// `1.345678`).
    DropDigit,
    /// Every reply (from the fault's `after` on, whatever its `count`) is padded with NUL
    /// bytes: [`NUL_PADDING`] before it and after its terminator.
    NulPadding,
    /// The device holds the host's output with XOFF for the fault's `seconds`, then sends
    /// XON (a flow-control pause; only on the pseudo-terminal lab, whose host side honours
    /// XON/XOFF when its line has software flow control, as the table's has).
    Xoff,
}

/// The NUL bytes a `nul-padding` fault puts before a reply and after its terminator.
pub const NUL_PADDING: &[u8] = b"\0\0\0";

/// Every fault kind, in the order of the documentation.
pub const FAULT_KINDS: [FaultKind; 16] = [
    FaultKind::LostReply,
    FaultKind::Garbled,
    FaultKind::XInvalid,
    FaultKind::Disable,
    FaultKind::Close,
    FaultKind::Late,
    FaultKind::Duplicated,
    FaultKind::Unsolicited,
    FaultKind::Swapped,
    FaultKind::Stale,
    FaultKind::Stall,
    FaultKind::SignFlip,
    FaultKind::SwapXy,
    FaultKind::DropDigit,
    FaultKind::NulPadding,
    FaultKind::Xoff,
];

impl FaultKind {
    /// The devices that can have this fault: `an autocollimator`, `the table` or `any
    /// device`.
    pub fn devices(self) -> &'static str {
        match self {
            FaultKind::XInvalid
            | FaultKind::SignFlip
            | FaultKind::SwapXy
            | FaultKind::DropDigit => "an autocollimator",
            FaultKind::Disable | FaultKind::Stall | FaultKind::Xoff => "the table",
            _ => "any device",
        }
    }

    /// Whether `device` can have this fault.
    pub fn applies_to(self, device: DeviceId) -> bool {
        match self {
            FaultKind::XInvalid
            | FaultKind::SignFlip
            | FaultKind::SwapXy
            | FaultKind::DropDigit => device != DeviceId::Table,
            FaultKind::Disable | FaultKind::Stall | FaultKind::Xoff => device == DeviceId::Table,
            _ => true,
        }
    }

    /// The spelling in a fault specification, e.g. `lost-reply`.
    pub fn as_str(self) -> &'static str {
        match self {
            FaultKind::LostReply => "lost-reply",
            FaultKind::Garbled => "garbled",
            FaultKind::XInvalid => "x-invalid",
            FaultKind::Disable => "disable",
            FaultKind::Close => "close",
            FaultKind::Late => "late",
            FaultKind::Duplicated => "duplicated",
            FaultKind::Unsolicited => "unsolicited",
            FaultKind::Swapped => "swapped",
            FaultKind::Stale => "stale",
            FaultKind::Stall => "stall",
            FaultKind::SignFlip => "sign-flip",
            FaultKind::SwapXy => "swap-xy",
            FaultKind::DropDigit => "drop-digit",
            FaultKind::NulPadding => "nul-padding",
            FaultKind::Xoff => "xoff",
        }
    }

    /// Whether the fault acts on a device's replies on the wire (the endpoint's), not
    /// inside the device.
    pub fn acts_on_replies(self) -> bool {
        !matches!(
            self,
            FaultKind::XInvalid
                | FaultKind::Disable
                | FaultKind::Stall
                | FaultKind::SignFlip
                | FaultKind::SwapXy
                | FaultKind::DropDigit
        )
    }
}

/// The default lateness of a `late` fault.
pub const DEFAULT_LATE: Duration = Duration::from_millis(1500);

/// The default shortfall of a `stall` fault, as a fraction of the position tolerance.
pub const DEFAULT_STALL_FRACTION: f64 = 0.5;

/// One injected fault: `KIND:DEVICE[:after=K][:count=M][:seconds=S][:fraction=F]`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct Fault {
    /// What happens.
    pub kind: FaultKind,
    /// To which device.
    pub device: DeviceId,
    /// Events (measurements or moves) before the fault is armed.
    pub after: u64,
    /// How many replies or measurements it hits (all kinds but `disable` and `close`).
    pub count: u64,
    /// How late a `late` fault's replies are, or how long an `xoff` fault holds the
    /// host's output ([`DEFAULT_LATE`] unless given).
    pub late: Duration,
    /// How far short of its target a `stall` fault ends a move, as a fraction of the
    /// position tolerance ([`DEFAULT_STALL_FRACTION`] unless given).
    pub stall_fraction: f64,
    /// A `late` fault's replies held until this many more commands have come, instead
    /// of [`Fault::late`] (`commands=C`).
    pub late_commands: Option<u32>,
}

/// The form of a fault, for messages.
const FORM: &str = "KIND:DEVICE[:after=K][:count=M][:seconds=S|:commands=C][:fraction=F], e.g. lost-reply:ac1:after=10, late:ac2:seconds=1.3, late:ac1:commands=4 or stall:table:after=3:fraction=0.5";

/// A fault specification that could not be read: which one, and what is wrong with it.
///
/// Displayed as `fault "SPEC": PROBLEM (expected KIND:DEVICE[:after=K][:count=M][:seconds=S|:commands=C][:fraction=F], …)`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("fault \"{spec}\": {problem} (expected {FORM})")]
#[non_exhaustive]
pub struct FaultError {
    /// The specification as given.
    pub spec: String,
    /// What is wrong with it.
    pub problem: FaultProblem,
}

/// What is wrong with a fault specification.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum FaultProblem {
    /// Fewer than two `:`-separated parts.
    #[error("too few parts")]
    TooFewParts,
    /// A kind that is not one of [`FAULT_KINDS`].
    #[error(
        "unknown kind \"{0}\" (kinds: lost-reply, garbled, x-invalid, disable, close, late, duplicated, unsolicited, swapped, stale, stall, sign-flip, swap-xy, drop-digit, nul-padding, xoff)"
    )]
    UnknownKind(String),
    /// A device that is not `ac1` … `ac16` or `table`.
    #[error("unknown device \"{0}\" (ac1, ac2, … ac16, table)")]
    UnknownDevice(String),
    /// A kind of fault the device cannot have (`x-invalid` of the table, `disable` of an
    /// autocollimator).
    #[error("{} is a fault of {}", .0.as_str(), .0.devices())]
    WrongDevice(FaultKind),
    /// An option that is not `NAME=VALUE`.
    #[error("\"{0}\" is not after=K, count=M, seconds=S, commands=C or fraction=F")]
    NotAnOption(String),
    /// An option value that is not a whole number.
    #[error("\"{0}\" is not a whole number")]
    NotAWholeNumber(String),
    /// `count=0`.
    #[error("count must be at least 1")]
    ZeroCount,
    /// An option other than `after`, `count` and `seconds`.
    #[error("unknown option \"{0}\"")]
    UnknownOption(String),
    /// `seconds=S` of a fault other than `late` and `xoff`.
    #[error("seconds=S is an option of late and xoff")]
    SecondsNotLate,
    /// `seconds=S` that is not a number of seconds from 0.001 to 3600.
    #[error("seconds \"{0}\" must be a number of seconds from 0.001 to 3600")]
    BadSeconds(String),
    /// `commands=C` of a fault other than `late`.
    #[error("commands=C is an option of late")]
    CommandsNotLate,
    /// `commands=C` that is not a whole number from 1 to 1000.
    #[error("commands \"{0}\" must be a whole number from 1 to 1000")]
    BadCommands(String),
    /// `fraction=F` of a fault other than `stall`.
    #[error("fraction=F is an option of stall")]
    FractionNotStall,
    /// `fraction=F` that is not a number from 0 to 10.
    #[error("fraction \"{0}\" must be a number from 0 to 10 (of the position tolerance)")]
    BadFraction(String),
}

impl FromStr for Fault {
    type Err = FaultError;

    /// Parses `KIND:DEVICE[:after=K][:count=M]`, e.g. `lost-reply:ac1:after=10`.
    ///
    /// ```
    /// use polycal::lab::sim::{DeviceId, Fault, FaultKind, FaultProblem};
    /// let f: Fault = "garbled:table:after=3:count=2".parse().unwrap();
    /// assert_eq!((f.kind, f.device, f.after, f.count), (FaultKind::Garbled, DeviceId::Table, 3, 2));
    /// let e = "x-invalid:table".parse::<Fault>().unwrap_err();
    /// assert_eq!(e.problem, FaultProblem::WrongDevice(FaultKind::XInvalid));
    /// ```
    fn from_str(spec: &str) -> Result<Fault, FaultError> {
        let bad = |problem: FaultProblem| FaultError {
            spec: spec.to_string(),
            problem,
        };
        let parts: Vec<&str> = spec.split(':').map(str::trim).collect();
        let [kind, device, options @ ..] = parts.as_slice() else {
            return Err(bad(FaultProblem::TooFewParts));
        };
        let Some(kind) = FAULT_KINDS.into_iter().find(|k| k.as_str() == *kind) else {
            return Err(bad(FaultProblem::UnknownKind(kind.to_string())));
        };
        let Ok(device) = device.parse::<DeviceId>() else {
            return Err(bad(FaultProblem::UnknownDevice(device.to_string())));
        };
        if !kind.applies_to(device) {
            return Err(bad(FaultProblem::WrongDevice(kind)));
        }
        let mut fault = Fault::new(kind, device);
        for option in options {
            let (key, value) = option
                .split_once('=')
                .ok_or_else(|| bad(FaultProblem::NotAnOption(option.to_string())))?;
            if key == "commands" {
                if kind != FaultKind::Late {
                    return Err(bad(FaultProblem::CommandsNotLate));
                }
                fault.late_commands = match value.parse::<u32>() {
                    Ok(c) if (1..=1000).contains(&c) => Some(c),
                    _ => return Err(bad(FaultProblem::BadCommands(value.to_string()))),
                };
                continue;
            }
            if key == "fraction" {
                if kind != FaultKind::Stall {
                    return Err(bad(FaultProblem::FractionNotStall));
                }
                fault.stall_fraction = match value.parse::<f64>() {
                    Ok(f) if f.is_finite() && (0.0..=10.0).contains(&f) => f,
                    _ => return Err(bad(FaultProblem::BadFraction(value.to_string()))),
                };
                continue;
            }
            if key == "seconds" {
                if !matches!(kind, FaultKind::Late | FaultKind::Xoff) {
                    return Err(bad(FaultProblem::SecondsNotLate));
                }
                fault.late = match value.parse::<f64>() {
                    Ok(s) if s.is_finite() && (0.001..=3600.0).contains(&s) => {
                        Duration::from_secs_f64(s)
                    }
                    _ => return Err(bad(FaultProblem::BadSeconds(value.to_string()))),
                };
                continue;
            }
            let n: u64 = value
                .parse()
                .map_err(|_| bad(FaultProblem::NotAWholeNumber(value.to_string())))?;
            match key {
                "after" => fault.after = n,
                "count" if n >= 1 => fault.count = n,
                "count" => return Err(bad(FaultProblem::ZeroCount)),
                _ => return Err(bad(FaultProblem::UnknownOption(key.to_string()))),
            }
        }
        Ok(fault)
    }
}

impl Fault {
    /// A fault armed from the start (`after` 0) that hits once (`count` 1).
    pub fn new(kind: FaultKind, device: DeviceId) -> Fault {
        Fault {
            kind,
            device,
            after: 0,
            count: 1,
            late: DEFAULT_LATE,
            stall_fraction: DEFAULT_STALL_FRACTION,
            late_commands: None,
        }
    }

    /// Makes a `late` fault's replies late by `late`.
    pub fn with_late(mut self, late: Duration) -> Fault {
        self.late = late;
        self
    }

    /// Makes a `late` fault hold its replies until `commands` more commands have come
    /// (`commands=C`).
    pub fn with_late_commands(mut self, commands: u32) -> Fault {
        self.late_commands = Some(commands);
        self
    }

    /// Makes a `stall` fault end a move `fraction` of the position tolerance short.
    pub fn with_stall_fraction(mut self, fraction: f64) -> Fault {
        self.stall_fraction = fraction;
        self
    }

    /// Arms the fault after `after` events (measurements or moves).
    pub fn with_after(mut self, after: u64) -> Fault {
        self.after = after;
        self
    }

    /// Makes the fault hit `count` replies or measurements.
    pub fn with_count(mut self, count: u64) -> Fault {
        self.count = count;
        self
    }
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:after={}:count={}",
            self.kind.as_str(),
            self.device,
            self.after,
            self.count
        )?;
        if self.kind == FaultKind::Late {
            match self.late_commands {
                Some(c) => write!(f, ":commands={c}")?,
                None => write!(f, ":seconds={}", self.late.as_secs_f64())?,
            }
        }
        if self.kind == FaultKind::Xoff {
            write!(f, ":seconds={}", self.late.as_secs_f64())?;
        }
        if self.kind == FaultKind::Stall {
            write!(f, ":fraction={}", self.stall_fraction)?;
        }
        Ok(())
    }
}

/// A measurement's (X, Y) as a value fault leaves it: `sign-flip` negates X, `swap-xy`
/// exchanges X and Y, `drop-digit` drops X's units digit (as written with six decimals:
/// `12.345678` → `1.345678`, `-5.2` → `-.2`). Every other kind leaves them.
pub(super) fn corrupt(kind: FaultKind, x: f64, y: f64) -> (f64, f64) {
    match kind {
        FaultKind::SignFlip => (-x, y),
        FaultKind::SwapXy => (y, x),
        FaultKind::DropDigit => {
            let text = format!("{x:.6}");
            let dropped = match text.find('.') {
                Some(i) if i > 0 && text[..i].ends_with(|c: char| c.is_ascii_digit()) => {
                    format!("{}{}", &text[..i - 1], &text[i..])
                }
                _ => text,
            };
            (dropped.parse().unwrap_or(x), y)
        }
        _ => (x, y),
    }
}

/// The value faults of one autocollimator, armed after K measurements for M of them.
#[derive(Debug, Clone, Default)]
pub(super) struct ValueFaults(Vec<(FaultKind, u64, u64)>);

impl ValueFaults {
    /// The value faults among `faults`.
    pub(super) fn of(faults: &[Fault]) -> ValueFaults {
        ValueFaults(
            faults
                .iter()
                .filter(|f| {
                    matches!(
                        f.kind,
                        FaultKind::SignFlip | FaultKind::SwapXy | FaultKind::DropDigit
                    )
                })
                .map(|f| (f.kind, f.after, f.count))
                .collect(),
        )
    }

    /// (X, Y) of the measurement after `before` measurements, as the armed faults leave
    /// it.
    pub(super) fn apply(&mut self, before: u64, x: f64, y: f64) -> (f64, f64) {
        let (mut x, mut y) = (x, y);
        for (kind, after, left) in &mut self.0 {
            if before >= *after && *left > 0 {
                *left -= 1;
                (x, y) = corrupt(*kind, x, y);
            }
        }
        (x, y)
    }
}

#[cfg(test)]
mod value_tests {
    use super::*;

    #[test]
    fn value_faults_corrupt_as_documented() {
        assert_eq!(corrupt(FaultKind::SignFlip, 1.5, 2.0), (-1.5, 2.0));
        assert_eq!(corrupt(FaultKind::SwapXy, 1.5, 2.0), (2.0, 1.5));
        assert_eq!(
            corrupt(FaultKind::DropDigit, 12.345678, 2.0),
            (1.345678, 2.0)
        );
        assert_eq!(corrupt(FaultKind::DropDigit, -5.25, 0.0), (-0.25, 0.0));
        let mut v =
            ValueFaults::of(&[Fault::new(FaultKind::SignFlip, DeviceId::Ac(1)).with_after(2)]);
        assert_eq!(v.apply(0, 1.0, 0.0), (1.0, 0.0));
        assert_eq!(v.apply(2, 1.0, 0.0), (-1.0, 0.0));
        assert_eq!(v.apply(3, 1.0, 0.0), (1.0, 0.0), "count 1");
    }
}
