//! The D-SI lists of a certificate (docs/FORMAT.md §13.3): a quantity's values, units,
//! uncertainties and the index beside them, each number with its line and column.

use roxmltree::Node;

use super::{
    DCC, FACE_NUMBER_REF_TYPE, Reader, SI, TABLE_ANGLE_REF_TYPE, child, has_ref_type, is, path,
};
use crate::input::FileError;
use crate::input::limits::{self, Limit};
use crate::results::{Quantity, ResultRow};

/// A unit a certificate's values may carry, and its factor to arcseconds.
fn arcsec_per(unit: &str) -> Option<f64> {
    match unit.trim() {
        "\\arcsecond" => Some(1.0),
        "\\arcminute" => Some(60.0),
        "\\degree" => Some(3600.0),
        "\\radian" => Some(648_000.0 / std::f64::consts::PI),
        "\\milli\\radian" => Some(648.0 / std::f64::consts::PI),
        "\\micro\\radian" => Some(0.648 / std::f64::consts::PI),
        _ => None,
    }
}

/// A list of numbers as the certificate writes it: each with its line and column.
struct Numbers {
    values: Vec<f64>,
    places: Vec<(u64, u64)>,
}

impl<'a, 'input> Reader<'a, 'input> {
    /// The rows of one quantity's list, each with its line.
    pub(super) fn rows(
        &self,
        quantity: Node<'_, '_>,
        family: Quantity,
    ) -> Result<Vec<(ResultRow, u64)>, FileError> {
        let list = child(quantity, SI, "realListXMLList").ok_or_else(|| {
            self.refuse(
                quantity,
                "no si:realListXMLList: polycal reads a quantity's values as a D-SI list \
                 (si:realListXMLList with si:valueXMLList, si:unitXMLList and \
                 si:expandedUncXMLList or si:standardUncXMLList)",
            )
        })?;
        let values = self.arcsec_list(list, "a result's value")?;
        let n = values.values.len();
        let (expanded, coverage, standard) = self.uncertainties(list, n)?;
        let index = self.indices(quantity, family, n)?;
        let mut rows = Vec::with_capacity(n);
        for (i, (&value, &(line, _))) in values.values.iter().zip(&values.places).enumerate() {
            let (index, angle_deg) = index.get(i).copied().unwrap_or((0, None));
            let row = ResultRow {
                quantity: family,
                index,
                value,
                u: standard.as_ref().and_then(|u| u.get(i).copied()),
                expanded_u: expanded.as_ref().and_then(|u| u.get(i).copied()),
                k: coverage.as_ref().and_then(|k| k.get(i).copied()),
                angle_deg,
                dof: None,
                nominal_deg: None,
            };
            rows.push((row, line));
        }
        Ok(rows)
    }

    /// `si:expandedUncXMLList`'s U and k, or `si:standardUncXMLList`'s u, one per value.
    #[allow(clippy::type_complexity)]
    fn uncertainties(
        &self,
        list: Node<'_, '_>,
        n: usize,
    ) -> Result<(Option<Vec<f64>>, Option<Vec<f64>>, Option<Vec<f64>>), FileError> {
        if let Some(interval) = child(list, SI, "coverageIntervalXMLList") {
            return Err(self.refuse(
                interval,
                "an uncertainty stated as a coverage interval: polycal reads U with k \
                 (si:expandedUncXMLList) or u (si:standardUncXMLList)",
            ));
        }
        let unit = self.unit_factors(list, n)?;
        let mut expanded = None;
        let mut coverage = None;
        let mut standard = None;
        if let Some(e) = child(list, SI, "expandedUncXMLList") {
            let u = self.required(e, "uncertaintyXMLList")?;
            let k = self.required(e, "coverageFactorXMLList")?;
            let u = self.numbers(u, n, limits::RESULT_ARCSEC, "a result's U")?;
            let k = self.numbers(k, n, limits::COVERAGE_FACTOR, "a result's k")?;
            expanded = Some(self.scaled(e, &u, &unit, "U")?);
            coverage = Some(k.values);
        }
        if let Some(s) = child(list, SI, "standardUncXMLList") {
            let u = self.required(s, "uncertaintyXMLList")?;
            let u = self.numbers(u, n, limits::RESULT_ARCSEC, "a result's u")?;
            standard = Some(self.scaled(s, &u, &unit, "u")?);
        }
        Ok((expanded, coverage, standard))
    }

    /// An uncertainty list in arcseconds, refused when negative.
    fn scaled(
        &self,
        node: Node<'_, '_>,
        numbers: &Numbers,
        factors: &[f64],
        name: &str,
    ) -> Result<Vec<f64>, FileError> {
        let mut out = Vec::with_capacity(numbers.values.len());
        for (i, &x) in numbers.values.iter().enumerate() {
            if x < 0.0 {
                return Err(self.refuse(
                    node,
                    format!("{name} {x} is negative; an uncertainty is at least 0"),
                ));
            }
            out.push(x * factors.get(i).copied().unwrap_or(1.0));
        }
        Ok(out)
    }

    /// The child `name` of the D-SI namespace, refused when missing.
    fn required<'b>(
        &self,
        node: Node<'b, 'input>,
        name: &str,
    ) -> Result<Node<'b, 'input>, FileError>
    where
        'a: 'b,
    {
        child(node, SI, name).ok_or_else(|| {
            self.refuse(
                node,
                format!("no si:{name}: U needs its k, and both a list"),
            )
        })
    }

    /// The factor to arcseconds of each value of `list` (`si:unitXMLList`: one unit for
    /// all, or one per value).
    fn unit_factors(&self, list: Node<'_, '_>, n: usize) -> Result<Vec<f64>, FileError> {
        let unit =
            child(list, SI, "unitXMLList").ok_or_else(|| self.refuse(list, "no si:unitXMLList"))?;
        let text = unit.text().unwrap_or("");
        let words: Vec<&str> = text.split_whitespace().collect();
        if words.len() != 1 && words.len() != n {
            return Err(self.refuse(
                unit,
                format!(
                    "{} units for {n} values (one unit, or one per value)",
                    words.len()
                ),
            ));
        }
        let mut factors = Vec::with_capacity(n);
        for i in 0..n {
            let word = words.get(i).or(words.first()).copied().unwrap_or("");
            let factor = arcsec_per(word).ok_or_else(|| {
                self.refuse(
                    unit,
                    format!(
                        "the unit {word:?} is not an angle polycal converts (\\arcsecond, \
                         \\arcminute, \\degree, \\radian, \\milli\\radian, \\micro\\radian)"
                    ),
                )
            })?;
            factors.push(factor);
        }
        Ok(factors)
    }

    /// The values of `list` in arcseconds.
    fn arcsec_list(&self, list: Node<'_, '_>, what: &str) -> Result<Numbers, FileError> {
        let values = child(list, SI, "valueXMLList")
            .ok_or_else(|| self.refuse(list, "no si:valueXMLList"))?;
        let count = values.text().map_or(0, |t| t.split_whitespace().count());
        if count == 0 {
            return Err(self.refuse(values, "no values"));
        }
        let factors = self.unit_factors(list, count)?;
        let mut numbers = self.numbers(values, count, Limit::new(f64::MIN, f64::MAX, ""), what)?;
        for (i, x) in numbers.values.iter_mut().enumerate() {
            *x *= factors.get(i).copied().unwrap_or(1.0);
            let (line, column) = numbers.places.get(i).copied().unwrap_or((0, 0));
            limits::RESULT_ARCSEC.check(*x, what).map_err(|rule| {
                FileError::invalid(
                    self.source,
                    (line, column),
                    format!("{}: {rule}", path(values)),
                )
            })?;
        }
        Ok(numbers)
    }

    /// The numbers of an `…XMLList` element: `n` of them, or one standing for all.
    fn numbers(
        &self,
        node: Node<'_, '_>,
        n: usize,
        limit: Limit,
        what: &str,
    ) -> Result<Numbers, FileError> {
        let text_node = node.first_child().filter(|c| c.is_text());
        let raw = text_node.map_or("", |t| &self.doc.input_text()[t.range()]);
        let start = text_node.map_or(node.range().start, |t| t.range().start);
        let mut values = Vec::new();
        let mut places = Vec::new();
        // line and column counted along the text once (the parser's own lookup counts
        // from the document's start: a long list would take quadratic time)
        let first = self.doc.text_pos_at(start);
        let (mut line, mut column) = (u64::from(first.row), u64::from(first.col));
        let mut chars = raw.char_indices().peekable();
        while let Some(&(at, c)) = chars.peek() {
            if c.is_ascii_whitespace() {
                if c == '\n' {
                    line += 1;
                    column = 1;
                } else {
                    column += 1;
                }
                chars.next();
                continue;
            }
            let place = (line, column);
            let mut end = at;
            while let Some(&(i, c)) = chars.peek() {
                if c.is_ascii_whitespace() {
                    break;
                }
                end = i + c.len_utf8();
                column += 1;
                chars.next();
            }
            let word = &raw[at..end];
            let refuse = |message: String| {
                FileError::invalid(self.source, place, format!("{}: {message}", path(node)))
            };
            let x: f64 = word
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| refuse(format!("{word:?} is not a finite number")))?;
            limit
                .check_shown(x, word, what)
                .map_err(|rule| refuse(rule.to_string()))?;
            values.push(x + 0.0);
            places.push(place);
        }
        match values.len() {
            len if len == n => Ok(Numbers { values, places }),
            1 => Ok(Numbers {
                values: vec![values[0]; n],
                places: vec![places[0]; n],
            }),
            len => Err(self.refuse(node, format!("{len} numbers for {n} values"))),
        }
    }

    /// The index (and table angle) of each of the `n` values of `quantity`.
    fn indices(
        &self,
        quantity: Node<'_, '_>,
        family: Quantity,
        n: usize,
    ) -> Result<Vec<(u32, Option<f64>)>, FileError> {
        let beside = |ref_type: &str| {
            quantity
                .parent()
                .filter(|p| is(*p, DCC, "list"))
                .and_then(|list| {
                    list.children()
                        .find(|c| is(*c, DCC, "quantity") && has_ref_type(*c, ref_type))
                })
                .and_then(|q| child(q, SI, "realListXMLList"))
        };
        let order = |first: u32| -> Vec<(u32, Option<f64>)> {
            (0..n)
                .map(|i| (first.saturating_add(i as u32), None))
                .collect()
        };
        match family {
            Quantity::PitchDeviation | Quantity::FaceDeviation => {
                match beside(FACE_NUMBER_REF_TYPE) {
                    Some(list) => {
                        let faces = self.list_numbers(list, n, "a face number")?;
                        let mut out = Vec::with_capacity(n);
                        for (i, &f) in faces.values.iter().enumerate() {
                            if f.fract() != 0.0 || !(1.0..=f64::from(u32::MAX)).contains(&f) {
                                let place = faces.places.get(i).copied().unwrap_or((0, 0));
                                return Err(FileError::invalid(
                                    self.source,
                                    place,
                                    format!(
                                        "{}: face {f} is not a face number 1, 2, …",
                                        path(list)
                                    ),
                                ));
                            }
                            out.push((f as u32, None));
                        }
                        Ok(out)
                    }
                    None => Ok(order(1)),
                }
            }
            Quantity::EncoderError => match beside(TABLE_ANGLE_REF_TYPE) {
                Some(list) => {
                    let factors = self.unit_factors(list, n)?;
                    let angles = self.list_numbers(list, n, "a table angle")?;
                    Ok(angles
                        .values
                        .iter()
                        .enumerate()
                        .map(|(i, &a)| {
                            let degrees = a * factors.get(i).copied().unwrap_or(3600.0) / 3600.0;
                            (i as u32, Some(degrees + 0.0))
                        })
                        .collect())
                }
                None => Ok(order(0)),
            },
            Quantity::SetupError => self.setup_indices(quantity, n),
            // blocks 1 … n in the order of their values
            Quantity::AngleBlock => Ok(order(1)),
        }
    }

    /// The `n` numbers of an index list's `si:valueXMLList`.
    fn list_numbers(&self, list: Node<'_, '_>, n: usize, what: &str) -> Result<Numbers, FileError> {
        let values = child(list, SI, "valueXMLList")
            .ok_or_else(|| self.refuse(list, "no si:valueXMLList"))?;
        let count = values.text().map_or(0, |t| t.split_whitespace().count());
        if count != n {
            return Err(self.refuse(
                values,
                format!("{count} numbers for the {n} values beside them"),
            ));
        }
        self.numbers(values, n, Limit::new(f64::MIN, f64::MAX, ""), what)
    }

    /// Setup errors' indices from their labels `setupS_acA`: `A`, or `S·1000 + A` when
    /// some `S` is not 1 (docs/FORMAT.md §3).
    fn setup_indices(
        &self,
        quantity: Node<'_, '_>,
        n: usize,
    ) -> Result<Vec<(u32, Option<f64>)>, FileError> {
        let labels =
            child(quantity, SI, "realListXMLList").and_then(|l| child(l, SI, "labelXMLList"));
        let words: Vec<&str> = labels
            .and_then(|l| l.text())
            .map(|t| t.split_whitespace().collect())
            .unwrap_or_default();
        let parsed: Option<Vec<(u32, u32)>> = words
            .iter()
            .map(|w| {
                let (setup, ac) = w.strip_prefix("setup")?.split_once("_ac")?;
                Some((setup.parse().ok()?, ac.parse().ok()?))
            })
            .collect();
        match parsed {
            Some(pairs)
                if pairs.len() == n
                    && pairs.iter().all(|&(s, a)| s >= 1 && (1..1000).contains(&a)) =>
            {
                let several = pairs.iter().any(|&(s, _)| s != 1);
                Ok(pairs
                    .iter()
                    .map(|&(s, a)| {
                        (
                            if several {
                                s.saturating_mul(1000).saturating_add(a)
                            } else {
                                a
                            },
                            None,
                        )
                    })
                    .collect())
            }
            _ => Err(self.refuse(
                labels.unwrap_or(quantity),
                "setup errors need the labels setupS_acA (si:labelXMLList), one per value",
            )),
        }
    }
}
