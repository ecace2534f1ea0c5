//! The candidates' columns of a round, kept as they are built: a column of values (stored
//! sparse), or a jump of a stream's zero — 1 on a suffix of the stream in time order — of
//! which every one of a stream is projected on a vector by one running sum.

/// A candidate's column, as a round takes it.
#[derive(Debug, Clone, PartialEq)]
pub enum Column {
    /// One value per reading.
    Values(Vec<f64>),
    /// 1 on the readings `streams[stream][from..]` (the round's streams, each its
    /// readings in time order), 0 elsewhere: a jump of that stream's zero at its reading
    /// `from`.
    Suffix {
        /// The stream, an index into the round's streams.
        stream: usize,
        /// The first reading of the stream the jump acts on.
        from: usize,
    },
}

/// How a column is stored.
#[derive(Debug, Clone)]
enum Stored {
    /// (reading, value) of its non-zero values.
    Sparse(Vec<(usize, f64)>),
    /// A suffix of a stream.
    Suffix { stream: usize, from: usize },
}

/// A round's columns, each scaled to unit length (F tests do not depend on a column's
/// scale), with their lengths.
#[derive(Debug, Clone)]
pub(super) struct Columns {
    readings: usize,
    streams: Vec<Vec<usize>>,
    /// The streams some suffix column uses.
    used_streams: Vec<usize>,
    stored: Vec<Stored>,
    /// ‖x‖ of every column as given (0: a column of zeros, left at zero).
    norms: Vec<f64>,
}

impl Columns {
    /// The `columns` over `readings` readings, suffixes of `streams`.
    pub(super) fn new(readings: usize, streams: Vec<Vec<usize>>, columns: Vec<Column>) -> Self {
        let mut stored = Vec::with_capacity(columns.len());
        let mut norms = Vec::with_capacity(columns.len());
        let mut used_streams = Vec::new();
        for column in columns {
            match column {
                Column::Values(values) => {
                    let sparse: Vec<(usize, f64)> = values
                        .iter()
                        .enumerate()
                        .filter(|(_, v)| **v != 0.0)
                        .map(|(i, v)| (i, *v))
                        .collect();
                    norms.push(sparse.iter().map(|(_, v)| v * v).sum::<f64>().sqrt());
                    stored.push(Stored::Sparse(sparse));
                }
                Column::Suffix { stream, from } => {
                    let len = streams
                        .get(stream)
                        .map_or(0, |s| s.len().saturating_sub(from));
                    norms.push((len as f64).sqrt());
                    if len > 0 && !used_streams.contains(&stream) {
                        used_streams.push(stream);
                    }
                    stored.push(Stored::Suffix { stream, from });
                }
            }
        }
        Columns {
            readings,
            streams,
            used_streams,
            stored,
            norms,
        }
    }

    /// The number of columns.
    pub(super) fn len(&self) -> usize {
        self.stored.len()
    }

    /// ‖x‖ of column `k` as given.
    pub(super) fn norm(&self, k: usize) -> f64 {
        self.norms[k]
    }

    /// Column `k` at unit length, one value per reading.
    pub(super) fn unit(&self, k: usize) -> Vec<f64> {
        let mut x = vec![0.0; self.readings];
        let norm = self.norms[k];
        if norm == 0.0 {
            return x;
        }
        match &self.stored[k] {
            Stored::Sparse(values) => {
                for &(i, v) in values {
                    x[i] = v / norm;
                }
            }
            Stored::Suffix { stream, from } => {
                for &i in &self.streams[*stream][*from..] {
                    x[i] = 1.0 / norm;
                }
            }
        }
        x
    }

    /// x̂ₖᵀ v of every unit column into `out`, in O(n + non-zero values): every suffix of
    /// a stream from one running sum. `suffix` is scratch space.
    pub(super) fn transpose_times(&self, v: &[f64], out: &mut [f64], suffix: &mut Vec<Vec<f64>>) {
        suffix.resize(self.streams.len(), Vec::new());
        for &s in &self.used_streams {
            let order = &self.streams[s];
            let sums = &mut suffix[s];
            sums.clear();
            sums.resize(order.len() + 1, 0.0);
            for k in (0..order.len()).rev() {
                sums[k] = sums[k + 1] + v[order[k]];
            }
        }
        for (k, (stored, o)) in self.stored.iter().zip(out.iter_mut()).enumerate() {
            let norm = self.norms[k];
            *o = if norm == 0.0 {
                0.0
            } else {
                match stored {
                    Stored::Sparse(values) => {
                        values.iter().map(|&(i, x)| x * v[i]).sum::<f64>() / norm
                    }
                    Stored::Suffix { stream, from } => suffix[*stream][*from] / norm,
                }
            };
        }
    }

    /// x̂ₖᵀ v of column `k` alone.
    pub(super) fn dot(&self, k: usize, v: &[f64]) -> f64 {
        let norm = self.norms[k];
        if norm == 0.0 {
            return 0.0;
        }
        match &self.stored[k] {
            Stored::Sparse(values) => values.iter().map(|&(i, x)| x * v[i]).sum::<f64>() / norm,
            Stored::Suffix { stream, from } => {
                self.streams[*stream][*from..]
                    .iter()
                    .map(|&i| v[i])
                    .sum::<f64>()
                    / norm
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_suffix_and_its_values_project_alike() {
        let streams = vec![vec![4, 0, 2], vec![1, 3]];
        let columns = Columns::new(
            5,
            streams,
            vec![
                Column::Suffix { stream: 0, from: 1 },
                Column::Values(vec![1.0, 0.0, 1.0, 0.0, 0.0]),
                Column::Values(vec![0.0, 3.0, 0.0, -4.0, 0.0]),
                Column::Suffix { stream: 1, from: 0 },
                Column::Values(vec![0.0; 5]),
            ],
        );
        let v = [1.0, 2.0, 3.0, 5.0, 7.0];
        let mut out = vec![0.0; 5];
        let mut scratch = Vec::new();
        columns.transpose_times(&v, &mut out, &mut scratch);
        // by hand: readings 0 and 2 → (1 + 3)/√2; (3·2 − 4·5)/5; (2 + 5)/√2; 0
        let r2 = 2f64.sqrt();
        let expected = [4.0 / r2, 4.0 / r2, -14.0 / 5.0, 7.0 / r2, 0.0];
        for k in 0..5 {
            assert!((out[k] - expected[k]).abs() < 1e-12, "{k}: {}", out[k]);
            assert!((columns.dot(k, &v) - expected[k]).abs() < 1e-12);
            let unit = columns.unit(k);
            let direct: f64 = unit.iter().zip(&v).map(|(a, b)| a * b).sum();
            assert!((direct - expected[k]).abs() < 1e-12);
        }
        assert_eq!(columns.norm(2), 5.0);
    }
}
