//! How the documents a reviewer signs state a result (docs/FORMAT.md §10.4): the
//! expanded uncertainty U to two significant digits, **rounded up** (so that the stated U
//! is never smaller than the evaluated one), the value rounded to nearest at the same
//! decimal place as U (GUM, JCGM 100:2008, 7.2.6), and the coverage factor k to three
//! significant digits, rounded to nearest. The HTML report and the DCC both format
//! through [`round_result`] and [`round_coverage_factor`]; the JSON keeps every number
//! unrounded.
//!
//! ```
//! use polycal::certificate::rounding::{round_coverage_factor, round_result};
//!
//! let r = round_result(0.123456, 0.0995).unwrap();
//! assert_eq!((r.value.as_str(), r.expanded_u.as_str()), ("0.12", "0.10"));
//! assert_eq!(round_coverage_factor(1.9864434030557319).unwrap(), "1.99");
//! ```

/// Relative slack below which a U that is a two-digit number up to the error of its
/// binary form (0.12 stored as 0.1199999…, or computed as 0.12000000000000001) is not
/// rounded up to the next digit.
const ROUND_UP_SLACK: f64 = 1e-9;

/// A result as a certificate states it: the value and U as decimal text (ASCII minus),
/// both with `decimals` digits after the point (none when `decimals` ≤ 0: U ≥ 10 rounds
/// to whole units or tens).
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub struct RoundedResult {
    /// The value, rounded to nearest at U's last digit.
    pub value: String,
    /// U to two significant digits, rounded up.
    pub expanded_u: String,
    /// Decimal place of U's last digit: 2 for `0.10`, 0 for `13`, −1 for `130`.
    pub decimals: i32,
}

/// `x` rounded to `decimals` places as text; `decimals` < 0 rounds to tens, hundreds, ….
fn fixed(x: f64, decimals: i32) -> String {
    let text = if decimals >= 0 {
        format!("{x:.*}", decimals as usize)
    } else {
        let unit = 10f64.powi(-decimals);
        format!("{:.0}", (x / unit).round() * unit)
    };
    // "-0.00" is zero
    if text
        .trim_start_matches('-')
        .bytes()
        .all(|b| matches!(b, b'0' | b'.'))
    {
        text.trim_start_matches('-').to_string()
    } else {
        text
    }
}

/// The value and its expanded uncertainty rounded as GUM 7.2.6 states them: U to two
/// significant digits, rounded up; the value to nearest at U's decimal place. A U of
/// zero (a quantity fixed by definition, φ\[N\]) is `0` and the value its shortest
/// exact text.
///
/// `None` for a value or U that is not finite, or a negative U.
pub fn round_result(value: f64, expanded_u: f64) -> Option<RoundedResult> {
    if !value.is_finite() || !expanded_u.is_finite() || expanded_u < 0.0 {
        return None;
    }
    if expanded_u == 0.0 {
        let text = if value == 0.0 {
            "0".to_string()
        } else {
            format!("{value:?}")
        };
        return Some(RoundedResult {
            value: text,
            expanded_u: "0".to_string(),
            decimals: 0,
        });
    }
    // U = m · 10^(e − 1) with 10 ≤ m < 100: two digits, the last at 10^(e − 1)
    let mut e = expanded_u.log10().floor() as i32;
    let scaled = |e: i32| expanded_u / 10f64.powi(e - 1);
    // log10 of a number just below a power of ten can round up to it
    if scaled(e) < 10.0 {
        e -= 1;
    } else if scaled(e) >= 100.0 {
        e += 1;
    }
    let m = scaled(e);
    let mut digits = if m - m.floor() <= ROUND_UP_SLACK * m {
        m.floor()
    } else {
        m.ceil()
    };
    // 99.5 rounds up to 100: two digits one place further left (0.0995 → 0.10)
    if digits >= 100.0 {
        digits /= 10.0;
        e += 1;
    }
    let decimals = 1 - e;
    let u = digits * 10f64.powi(e - 1);
    Some(RoundedResult {
        value: fixed(value, decimals),
        expanded_u: fixed(u, decimals),
        decimals,
    })
}

/// Extra digits [`round_against`] adds at most.
const MAX_EXTRA_DIGITS: i32 = 6;

/// A value and the expanded uncertainty it is judged against (a degree of equivalence
/// d and U(d), a difference a − b and the En denominator), stated as [`round_result`]
/// states them, with as many more digits as it takes for the shown numbers to say what
/// the unrounded ones decide: |value| > U shown as a larger |value|, |value| ≤ U as one
/// no larger (at most six digits more; U is always rounded up, the value to nearest).
/// Without it a row could show d = −0.13 beside U = 0.13 and be marked "|d| > U".
///
/// ```
/// use polycal::certificate::rounding::{round_against, round_result};
///
/// // |d| = 0.1452 > U = 0.144502: GUM 7.2.6 alone shows 0.15 and 0.15
/// let plain = round_result(-0.1452, 0.144502).unwrap();
/// assert_eq!((plain.value.as_str(), plain.expanded_u.as_str()), ("-0.15", "0.15"));
/// let told = round_against(-0.1452, 0.144502).unwrap();
/// assert_eq!((told.value.as_str(), told.expanded_u.as_str()), ("-0.1452", "0.1446"));
/// ```
///
/// `None` where [`round_result`] gives none.
pub fn round_against(value: f64, expanded_u: f64) -> Option<RoundedResult> {
    let gum = round_result(value, expanded_u)?;
    if expanded_u == 0.0 {
        return Some(gum);
    }
    let exceeds = value.abs() > expanded_u;
    let agrees = |r: &RoundedResult| {
        let (v, u) = (
            r.value.parse::<f64>().map(f64::abs),
            r.expanded_u.parse::<f64>(),
        );
        match (v, u) {
            (Ok(v), Ok(u)) => (v > u) == exceeds,
            _ => true,
        }
    };
    let mut shown = gum;
    for _ in 0..MAX_EXTRA_DIGITS {
        if agrees(&shown) {
            break;
        }
        let decimals = shown.decimals + 1;
        shown = RoundedResult {
            value: fixed(value, decimals),
            expanded_u: fixed(rounded_up(expanded_u, decimals), decimals),
            decimals,
        };
    }
    Some(shown)
}

/// `x` ≥ 0 rounded up at `decimals` places (to tens, hundreds, … for `decimals` < 0),
/// not past a digit it equals up to the error of its binary form.
fn rounded_up(x: f64, decimals: i32) -> f64 {
    let scale = 10f64.powi(decimals);
    let m = x * scale;
    let digits = if m - m.floor() <= ROUND_UP_SLACK * m.max(1.0) {
        m.floor()
    } else {
        m.ceil()
    };
    digits / scale
}

/// An En number as both documents show it: two decimals, and more (up to six) where
/// two would hide that |En| > 1 (1.0048 is `1.005`, not `1.00` beside a "fails" mark).
/// ASCII minus; `-0.00` is `0.00`.
///
/// ```
/// use polycal::certificate::rounding::en_text;
///
/// assert_eq!(en_text(0.4812), "0.48");
/// assert_eq!(en_text(-1.0048), "-1.005");
/// assert_eq!(en_text(0.9996), "1.00");
/// ```
pub fn en_text(en: f64) -> String {
    let mut decimals = 2;
    while en.abs() > 1.0
        && decimals < 2 + MAX_EXTRA_DIGITS
        && fixed(en.abs(), decimals)
            .parse::<f64>()
            .is_ok_and(|t| t <= 1.0)
    {
        decimals += 1;
    }
    fixed(en, decimals)
}

/// A coverage factor to three significant digits, rounded to nearest (`2.00`, `1.99`,
/// `12.7`, `128`). `None` for one below 1 or not finite.
pub fn round_coverage_factor(k: f64) -> Option<String> {
    if !k.is_finite() || k < 1.0 {
        return None;
    }
    let mut decimals = 2 - k.log10().floor() as i32;
    // 9.996 rounds to 10.0: one decimal fewer
    if decimals > 0 && fixed(k, decimals).len() > 4 {
        decimals -= 1;
    }
    Some(fixed(k, decimals.max(0)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A value judged against U: the digits its mark needs, by hand.
    #[test]
    fn a_value_against_its_u_shows_what_decides() {
        // (value, U) → (value, U): |d| > U needs a larger shown |d|
        let cases: [(f64, f64, &str, &str); 6] = [
            // tie at GUM's 0.13/0.13 with |d| > U: 0.131/0.129 at three places
            (-0.1312, 0.1281, "-0.131", "0.129"),
            // 0.1285 against 0.1281: three places tie (0.129 up, 0.129 near) → four
            (0.1285, 0.1281, "0.1285", "0.1281"),
            // |d| ≤ U shown as 0.13 and 0.13 agrees with "|d| ≤ U": as GUM states it
            (0.1279, 0.1281, "0.13", "0.13"),
            // far apart: GUM's own digits
            (0.5, 0.1281, "0.50", "0.13"),
            (-0.01, 0.1281, "-0.01", "0.13"),
            // no uncertainty: as round_result
            (0.0, 0.0, "0", "0"),
        ];
        for (value, u, want_value, want_u) in cases {
            let r = round_against(value, u).unwrap();
            assert_eq!(
                (r.value.as_str(), r.expanded_u.as_str()),
                (want_value, want_u),
                "{value} against {u}"
            );
        }
        assert_eq!(en_text(1.0), "1.00");
        assert_eq!(en_text(1.00004), "1.00004");
        assert_eq!(en_text(-0.001), "0.00");
    }

    /// (value, U) → (value, U, decimals), each worked by hand.
    #[test]
    fn results_round_as_gum_7_2_6_with_u_rounded_up() {
        let cases: [(f64, f64, &str, &str, i32); 14] = [
            // the issue's numbers: U 0.10218… has two digits 0.10|218 → up to 0.11
            (0.5212345, 0.10218004980691307, "0.52", "0.11", 2),
            // 0.0995 → 0.10 (three places would be 0.0995, two digits 0.099|5 → up to
            // 0.100 = 0.10): the value follows U to two places
            (0.123456, 0.0995, "0.12", "0.10", 2),
            (-0.123456, 0.0995, "-0.12", "0.10", 2),
            // exactly two digits: not rounded up (0.12 is 0.11999… as a double)
            (1.23456, 0.12, "1.23", "0.12", 2),
            (1.23456, 0.12000000000000001, "1.23", "0.12", 2),
            (1.23456, 0.1201, "1.23", "0.13", 2),
            // negative values round to nearest: −2.345678 → −2.346 at U's third place
            (-2.345678, 0.034, "-2.346", "0.034", 3),
            (-0.0004, 0.034, "0.000", "0.034", 3),
            // U ≥ 10: whole units, then tens
            (123.456, 12.3, "123", "13", 0),
            (1234.5, 123.0, "1230", "130", -1),
            (-1234.5, 99.9, "-1230", "100", -1),
            // U of one significant digit gets a second: 0.2 → 0.20
            (3.25159, 0.2, "3.25", "0.20", 2),
            // small U
            (1e-6, 2.51e-7, "0.00000100", "0.00000026", 8),
            (5.0, 1.0, "5.0", "1.0", 1),
        ];
        for (value, u, v_text, u_text, decimals) in cases {
            let r = round_result(value, u).unwrap();
            assert_eq!(
                (r.value.as_str(), r.expanded_u.as_str(), r.decimals),
                (v_text, u_text, decimals),
                "{value} ± {u}"
            );
        }
        assert_eq!(
            round_result(0.0, 0.0).unwrap(),
            RoundedResult {
                value: "0".into(),
                expanded_u: "0".into(),
                decimals: 0
            }
        );
        assert!(round_result(f64::NAN, 0.1).is_none());
        assert!(round_result(1.0, f64::INFINITY).is_none());
        assert!(round_result(1.0, -0.1).is_none());
    }

    #[test]
    fn coverage_factors_take_three_significant_digits() {
        for (k, text) in [
            (1.9864434030557319, "1.99"),
            (2.0, "2.00"),
            (1.0, "1.00"),
            (2.5706, "2.57"),
            (9.9951, "10.0"),
            (12.706, "12.7"),
            (127.32, "127"),
            (999.6, "1000"),
        ] {
            assert_eq!(round_coverage_factor(k).unwrap(), text, "{k}");
        }
        assert!(round_coverage_factor(0.99).is_none());
        assert!(round_coverage_factor(f64::NAN).is_none());
    }
}
