//! A study's Sobol' indices: for every record time, output and dimension ξ_j of the
//! [`crate::uncertainty::ParameterSpace`], the main and total index of the output's surrogate
//! (docs/sobol-indices.md §5), gathered from the bounded blocks, and what the sinks take from them
//! (the stdout lines, the MCAP block, the largest total index per dimension).
//!
//! Indices are per dimension of the box: a shared group is one dimension (its members move
//! together), a `[bind]`-bound parameter has none of its own (its variation is counted under the
//! dimensions its expression reads). Only surrogate methods have them (tensor and sparse designs).
//!
//! Memory: `2d + 1` numbers per output per record time, kept until the sinks run.
//!
//! Does not: compute indices from coefficients (see [`crate::uq::sobol_indices`]).

use super::bounded_block::BoundedBlock;
use super::envelope::{widest_record, Envelope};
use super::Method;

/// Main and total indices, and the surrogate's variance, of every output at every record time.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SobolSeries {
    dim: usize,
    n_outputs: usize,
    /// `records × outputs × d`, record-major.
    main: Vec<f64>,
    /// `records × outputs × d`, record-major.
    total: Vec<f64>,
    /// `records × outputs`, record-major, in the output's unit squared.
    variance: Vec<f64>,
}

/// The indices of one block of records, as the sinks receive them (record-major slices).
#[derive(Clone, Copy, Debug)]
pub struct SobolBlock<'a> {
    /// Dimensions d.
    pub dim: usize,
    /// `records × outputs × d` main indices.
    pub main: &'a [f64],
    /// `records × outputs × d` total indices.
    pub total: &'a [f64],
}

impl SobolBlock<'_> {
    /// Main indices of output `output` at the block's record `record` (length d).
    pub fn main(&self, record: usize, n_outputs: usize, output: usize) -> &[f64] {
        let start = (record * n_outputs + output) * self.dim;
        &self.main[start..start + self.dim]
    }

    /// Total indices of output `output` at the block's record `record` (length d).
    pub fn total(&self, record: usize, n_outputs: usize, output: usize) -> &[f64] {
        let start = (record * n_outputs + output) * self.dim;
        &self.total[start..start + self.dim]
    }
}

/// Whether a study with `method` (resolved, or `auto`) computes Sobol' indices: every method that
/// fits a polynomial surrogate.
pub fn has_sobol_indices(method: Method) -> bool {
    method.family().is_some()
}

/// Numbers kept per output and record time by a study with `method` over `dim` dimensions (for
/// the memory check before a run): main and total per dimension and the variance, or 0.
pub fn sobol_values_per_record(method: Method, dim: usize) -> usize {
    if has_sobol_indices(method) {
        2 * dim + 1
    } else {
        0
    }
}

impl SobolSeries {
    /// An empty series for `n_outputs` outputs over `dim` dimensions.
    pub fn new(dim: usize, n_outputs: usize) -> SobolSeries {
        SobolSeries {
            dim,
            n_outputs,
            ..SobolSeries::default()
        }
    }

    /// Dimensions d.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Outputs.
    pub fn n_outputs(&self) -> usize {
        self.n_outputs
    }

    /// Record times held.
    pub fn records(&self) -> usize {
        self.variance.len() / self.n_outputs.max(1)
    }

    /// Appends a bounded block's indices (its records follow the ones held).
    pub(super) fn extend(&mut self, block: &BoundedBlock) {
        self.main.extend_from_slice(&block.main_indices);
        self.total.extend_from_slice(&block.total_indices);
        self.variance.extend_from_slice(&block.variances);
    }

    fn range(&self, record: usize, output: usize) -> std::ops::Range<usize> {
        let start = (record * self.n_outputs + output) * self.dim;
        start..start + self.dim
    }

    /// Main indices of `output` at `record` (length d). Panics when out of range.
    pub fn main(&self, record: usize, output: usize) -> &[f64] {
        &self.main[self.range(record, output)]
    }

    /// Total indices of `output` at `record` (length d). Panics when out of range.
    pub fn total(&self, record: usize, output: usize) -> &[f64] {
        &self.total[self.range(record, output)]
    }

    /// The surrogate's variance of `output` at `record` (output unit squared).
    pub fn variance(&self, record: usize, output: usize) -> f64 {
        self.variance[record * self.n_outputs + output]
    }

    /// Records `first..first + count` for a sink; `None` when the series does not hold them all.
    pub fn block(&self, first: usize, count: usize) -> Option<SobolBlock<'_>> {
        let per_record = self.n_outputs * self.dim;
        let range = first * per_record..(first + count) * per_record;
        (range.end <= self.main.len()).then(|| SobolBlock {
            dim: self.dim,
            main: &self.main[range.clone()],
            total: &self.total[range],
        })
    }

    /// Per dimension: the largest total index over outputs and record times, with its output and
    /// record (the first where several are equal; `(0, 0, 0)` for a dimension that never moves an
    /// output).
    pub fn total_index_max(&self) -> Vec<(f64, usize, usize)> {
        let mut best = vec![(0.0, 0, 0); self.dim];
        for record in 0..self.records() {
            for output in 0..self.n_outputs {
                for (j, &index) in self.total(record, output).iter().enumerate() {
                    if index > best[j].0 {
                        best[j] = (index, output, record);
                    }
                }
            }
        }
        best
    }

    /// The dimensions of `output` at `record`, by decreasing total index (ties: lower dimension
    /// first), at most `count`, leaving out dimensions with total index 0.
    pub fn top_contributors(&self, record: usize, output: usize, count: usize) -> Vec<usize> {
        let total = self.total(record, output);
        let mut order: Vec<usize> = (0..self.dim).filter(|&j| total[j] > 0.0).collect();
        order.sort_by(|&a, &b| total[b].total_cmp(&total[a]).then(a.cmp(&b)));
        order.truncate(count);
        order
    }

    /// The stdout lines (docs/sobol-indices.md §5): per output, at the record time of its widest
    /// envelope, the `count` dimensions with the largest total index as `name main/total`.
    /// `names` are the dimensions' names. Empty when the series holds no record.
    pub fn table(&self, envelope: &Envelope, names: &[String], count: usize) -> String {
        if self.records() == 0 || self.dim == 0 {
            return String::new();
        }
        let width =
            crate::text::name_column_width(envelope.outputs.iter().map(|o| o.name.as_str()));
        let mut text = format!(
            "Sobol' indices of the surrogate at each output's widest envelope (main/total, top {} of {}):\n",
            count.min(self.dim),
            self.dim
        );
        for (o, output) in envelope.outputs.iter().enumerate() {
            let Some(record) = widest_record(envelope, o).filter(|&r| r < self.records()) else {
                continue;
            };
            let main = self.main(record, o);
            let total = self.total(record, o);
            let parts: Vec<String> = self
                .top_contributors(record, o, count)
                .into_iter()
                .map(|j| {
                    format!(
                        "{} {:.3}/{:.3}",
                        names.get(j).map_or("?", String::as_str),
                        main[j],
                        total[j]
                    )
                })
                .collect();
            text.push_str(&format!(
                "  {:<width$}  t {:>9.3}  {}\n",
                output.name,
                envelope.times.get(record).copied().unwrap_or(f64::NAN),
                if parts.is_empty() {
                    "constant (no variance)".to_string()
                } else {
                    parts.join(", ")
                }
            ));
        }
        text
    }
}

/// Stdout lines: dimensions listed per output.
pub const TABLE_SOBOL_CONTRIBUTORS: usize = 3;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Output, OutputKind};

    fn block(records: usize, outputs: usize, dim: usize, seed: f64) -> BoundedBlock {
        let n = records * outputs * dim;
        let total: Vec<f64> = (0..n)
            .map(|i| ((i as f64 + seed) * 0.37).sin().abs())
            .collect();
        BoundedBlock {
            main_indices: total.iter().map(|t| 0.5 * t).collect(),
            total_indices: total,
            variances: vec![1.0; records * outputs],
            ..BoundedBlock::default()
        }
    }

    #[test]
    fn blocks_concatenate_and_maxima_match_a_direct_search() {
        let (dim, outputs) = (3, 2);
        let mut series = SobolSeries::new(dim, outputs);
        series.extend(&block(2, outputs, dim, 0.0));
        series.extend(&block(3, outputs, dim, 5.0));
        assert_eq!(series.records(), 5);
        let b = block(3, outputs, dim, 5.0);
        assert_eq!(series.total(2, 1), &b.total_indices[dim..2 * dim]);
        assert_eq!(
            series.main(4, 0),
            &b.main_indices[2 * outputs * dim..][..dim]
        );
        let view = series.block(2, 3).unwrap();
        assert_eq!(view.total(0, outputs, 1), series.total(2, 1));
        assert!(series.block(3, 3).is_none());
        let max = series.total_index_max();
        for (j, &(value, output, record)) in max.iter().enumerate() {
            let mut want = (0.0, 0, 0);
            for r in 0..5 {
                for o in 0..outputs {
                    if series.total(r, o)[j] > want.0 {
                        want = (series.total(r, o)[j], o, r);
                    }
                }
            }
            assert_eq!((value, output, record), want);
        }
        let top = series.top_contributors(1, 0, 2);
        let t = series.total(1, 0);
        assert_eq!(top.len(), 2);
        assert!(t[top[0]] >= t[top[1]]);
        assert!((0..dim).all(|j| top.contains(&j) || t[j] <= t[top[1]]));
    }

    #[test]
    fn the_table_names_the_widest_time_and_top_dimensions() {
        let mut series = SobolSeries::new(2, 1);
        series.extend(&BoundedBlock {
            main_indices: vec![0.1, 0.2, 0.7, 0.1],
            total_indices: vec![0.2, 0.3, 0.8, 0.2],
            variances: vec![1.0, 2.0],
            ..BoundedBlock::default()
        });
        let envelope = Envelope {
            outputs: vec![Output {
                name: "q.j1".to_string(),
                parts: vec!["q".to_string(), "j1".to_string()],
                unit: "rad",
                kind: OutputKind::Position { q_index: 0 },
            }],
            times: vec![0.0, 0.5],
            lower: vec![vec![0.0, -1.0]],
            upper: vec![vec![0.0, 1.0]],
            nominal: vec![vec![0.0, 0.0]],
            error: None,
            outer: None,
            runs_lower: vec![vec![0.0, -0.5]],
            runs_upper: vec![vec![0.0, 0.5]],
        };
        assert_eq!(widest_record(&envelope, 0), Some(1));
        let text = series.table(&envelope, &["m1".to_string(), "l2".to_string()], 3);
        assert!(
            text.contains("q.j1") && text.contains("0.500  m1 0.700/0.800, l2 0.100/0.200"),
            "{text}"
        );
        assert_eq!(sobol_values_per_record(Method::Scan, 4), 0);
        assert_eq!(sobol_values_per_record(Method::LegendreIa, 4), 9);
    }
}
