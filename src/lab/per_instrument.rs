//! One value for each instrument of a run: the autocollimators 1 … K, in order, and the
//! rotary table. The run's ports, the instruments' identification and the simulated
//! lab's device paths are each one of these; in JSON it is one object with the fields
//! `ac1`, `ac2`, `table`, `ac3`, … `acK` (docs/FORMAT.md §7.2).

use std::fmt;

use serde::de::{self, MapAccess, Visitor};
use serde::ser::SerializeMap;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// One value for each instrument of a run: autocollimators 1 … K and the table.
///
/// ```
/// use polycal::lab::PerInstrument;
///
/// let ports = PerInstrument::new(["/dev/ttyUSB0", "/dev/ttyUSB1"], "/dev/ttyUSB2");
/// assert_eq!(ports.ac(2).map(String::as_str), Some("/dev/ttyUSB1"));
/// assert_eq!(ports.ac(3), None);
/// let json = serde_json::to_string(&ports).unwrap();
/// assert_eq!(json, r#"{"ac1":"/dev/ttyUSB0","ac2":"/dev/ttyUSB1","table":"/dev/ttyUSB2"}"#);
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct PerInstrument<T> {
    /// Autocollimators 1 … K, in order (index 0 is autocollimator 1).
    pub autocollimators: Vec<T>,
    /// The rotary table.
    pub table: T,
}

impl<T> PerInstrument<T> {
    /// The values of autocollimators 1 … K, in order, and of the table.
    pub fn new<A: Into<T>>(
        autocollimators: impl IntoIterator<Item = A>,
        table: impl Into<T>,
    ) -> Self {
        PerInstrument {
            autocollimators: autocollimators.into_iter().map(Into::into).collect(),
            table: table.into(),
        }
    }

    /// Autocollimator `ac`'s value (1 … K); `None` beyond K or for 0.
    pub fn ac(&self, ac: u32) -> Option<&T> {
        let index = usize::try_from(ac).ok()?.checked_sub(1)?;
        self.autocollimators.get(index)
    }

    /// The autocollimators with their numbers, 1 first.
    pub fn numbered(&self) -> impl Iterator<Item = (u32, &T)> {
        (1u32..).zip(&self.autocollimators)
    }

    /// Each value turned by `f`, the instruments kept in their places.
    pub fn map<U>(self, mut f: impl FnMut(T) -> U) -> PerInstrument<U> {
        PerInstrument {
            autocollimators: self.autocollimators.into_iter().map(&mut f).collect(),
            table: f(self.table),
        }
    }
}

/// `ac1`, `ac2`, `table`, then `ac3` … `acK`: the order the run's manifest has always
/// been written in.
impl<T: Serialize> Serialize for PerInstrument<T> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(self.autocollimators.len() + 1))?;
        for (number, value) in self.numbered().take(2) {
            map.serialize_entry(&format!("ac{number}"), value)?;
        }
        map.serialize_entry("table", &self.table)?;
        for (number, value) in self.numbered().skip(2) {
            map.serialize_entry(&format!("ac{number}"), value)?;
        }
        map.end()
    }
}

/// The autocollimator numbered by a field name `acN` (N ≥ 1, no leading zero).
fn ac_number(key: &str) -> Option<usize> {
    let digits = key.strip_prefix("ac")?;
    if digits.starts_with('0') || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok().filter(|&n| n >= 1)
}

/// Reads the object [`PerInstrument`] writes: `table` and `ac1` … `acK` in any order,
/// with no number missing; any other field, or one given twice, is refused.
impl<'de, T: Deserialize<'de>> Deserialize<'de> for PerInstrument<T> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Fields<T>(std::marker::PhantomData<T>);

        impl<'de, T: Deserialize<'de>> Visitor<'de> for Fields<T> {
            type Value = PerInstrument<T>;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("an object with the fields table, ac1, ac2, …")
            }

            fn visit_map<M: MapAccess<'de>>(self, mut map: M) -> Result<Self::Value, M::Error> {
                let mut table = None;
                let mut acs: Vec<Option<T>> = Vec::new();
                while let Some(key) = map.next_key::<String>()? {
                    if key == "table" {
                        if table.is_some() {
                            return Err(de::Error::duplicate_field("table"));
                        }
                        table = Some(map.next_value()?);
                        continue;
                    }
                    let Some(number) = ac_number(&key) else {
                        return Err(de::Error::custom(format!(
                            "unknown field `{key}`: expected `table` or `acN` (N = 1, 2, …)"
                        )));
                    };
                    // A run of more than 1 024 autocollimators is no run: refuse before
                    // growing the list to an absurd number.
                    if number > 1024 {
                        return Err(de::Error::custom(format!(
                            "field `{key}`: at most 1024 autocollimators"
                        )));
                    }
                    if acs.len() < number {
                        acs.resize_with(number, || None);
                    }
                    if acs[number - 1].is_some() {
                        return Err(de::Error::custom(format!("duplicate field `{key}`")));
                    }
                    acs[number - 1] = Some(map.next_value()?);
                }
                let table = table.ok_or_else(|| de::Error::missing_field("table"))?;
                let autocollimators = acs
                    .into_iter()
                    .enumerate()
                    .map(|(i, value)| {
                        value.ok_or_else(|| {
                            de::Error::custom(format!("missing field `ac{}`", i + 1))
                        })
                    })
                    .collect::<Result<Vec<T>, M::Error>>()?;
                Ok(PerInstrument {
                    autocollimators,
                    table,
                })
            }
        }

        deserializer.deserialize_map(Fields(std::marker::PhantomData))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(json: &str) -> Result<PerInstrument<String>, serde_json::Error> {
        serde_json::from_str(json)
    }

    #[test]
    fn written_in_the_manifests_order_and_read_back() {
        let ports = PerInstrument::<String>::new(["a", "b", "c", "d"], "t");
        let json = serde_json::to_string(&ports).unwrap();
        assert_eq!(
            json,
            r#"{"ac1":"a","ac2":"b","table":"t","ac3":"c","ac4":"d"}"#
        );
        assert_eq!(read(&json).unwrap(), ports);
        // Any order of the fields reads the same.
        let shuffled = r#"{"ac4":"d","table":"t","ac2":"b","ac3":"c","ac1":"a"}"#;
        assert_eq!(read(shuffled).unwrap(), ports);
        assert_eq!(ports.ac(4).map(String::as_str), Some("d"));
        assert_eq!(ports.ac(0), None);
        assert_eq!(ports.ac(5), None);
    }

    #[test]
    fn a_gap_a_stranger_or_a_twin_is_refused() {
        let gap = read(r#"{"ac1":"a","ac3":"c","table":"t"}"#).unwrap_err();
        assert!(gap.to_string().contains("missing field `ac2`"), "{gap}");
        let stranger = read(r#"{"ac1":"a","ac2":"b","table":"t","ac03":"x"}"#).unwrap_err();
        assert!(
            stranger.to_string().contains("unknown field `ac03`"),
            "{stranger}"
        );
        let twin = read(r#"{"ac1":"a","ac1":"b","table":"t"}"#).unwrap_err();
        assert!(twin.to_string().contains("duplicate field `ac1`"), "{twin}");
        let no_table = read(r#"{"ac1":"a","ac2":"b"}"#).unwrap_err();
        assert!(
            no_table.to_string().contains("missing field `table`"),
            "{no_table}"
        );
        let absurd = read(r#"{"ac99999999999":"a","table":"t"}"#).unwrap_err();
        assert!(absurd.to_string().contains("at most 1024"), "{absurd}");
    }
}
