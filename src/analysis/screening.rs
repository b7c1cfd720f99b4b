//! Screening: which parameters move the outputs, from the star design — the centre and the centres of
//! the box's faces, `ξ = 0` and `ξ = ±e_j` (2d + 1 runs) — docs/method.md §10.
//!
//! `(per record: the star runs' outputs) ⇒ per dimension j and output o: the largest range along the
//! axis, max_t (max − min of y(0), y(e_j), y(−e_j)), and the largest secant slope |y(e_j) − y(−e_j)|/2
//! ⇒ importance_j = max_o range_j,o / Σ_j range_j,o`
//!
//! Along each axis the star sees the slope and the curvature (three points), so it ranks a parameter
//! whose effect is quadratic (zero slope at the centre) correctly; it does not see interactions
//! between parameters, which is why the designs built on it keep every pairwise interaction of total
//! degree two.

/// The screening statistics of a study, accumulated record by record.
#[derive(Clone, Debug)]
pub struct Screening {
    dim: usize,
    n_outputs: usize,
    /// `range[j · n_outputs + o]`: largest range of output o along axis j over the records.
    range: Vec<f64>,
    /// `slope[j · n_outputs + o]`: largest |y(e_j) − y(−e_j)| / 2 over the records.
    slope: Vec<f64>,
}

/// Per dimension, the screening's verdict.
#[derive(Clone, Debug, PartialEq)]
pub struct DimensionScreening {
    /// Largest over outputs of (range along the axis) / (the output's sum of axis ranges): the share
    /// of an output's one-at-a-time spread this dimension produces (0..1).
    pub importance: f64,
    /// Largest over outputs of (secant slope |y(e_j) − y(−e_j)|/2) / (the output's sum of axis
    /// ranges): the first-order effect across the half-width, relative.
    pub relative_slope: f64,
    /// The output where `importance` is attained.
    pub output: usize,
}

impl Screening {
    /// No statistics yet, for `dim` dimensions and `n_outputs` outputs.
    pub fn new(dim: usize, n_outputs: usize) -> Screening {
        Screening {
            dim,
            n_outputs,
            range: vec![0.0; dim * n_outputs],
            slope: vec![0.0; dim * n_outputs],
        }
    }

    /// The star points in standard coordinates, row-major `2d × d`: `+e_1, −e_1, +e_2, …` (the
    /// centre is run separately).
    pub fn points(dim: usize) -> Vec<f64> {
        let mut points = vec![0.0; 2 * dim * dim];
        for j in 0..dim {
            points[(2 * j) * dim + j] = 1.0;
            points[(2 * j + 1) * dim + j] = -1.0;
        }
        points
    }

    /// Adds one record: `centre` (`dim outputs`) and `face(i)` the outputs of star point `i`
    /// (`points()` order).
    pub fn add_record<'a>(&mut self, centre: &[f64], face: impl Fn(usize) -> &'a [f64]) {
        for j in 0..self.dim {
            let (plus, minus) = (face(2 * j), face(2 * j + 1));
            for o in 0..self.n_outputs {
                let (a, b, c) = (plus[o], minus[o], centre[o]);
                let range = a.max(b).max(c) - a.min(b).min(c);
                let slope = 0.5 * (a - b).abs();
                let k = j * self.n_outputs + o;
                // NaN-safe maxima: a NaN never replaces a number.
                if range > self.range[k] {
                    self.range[k] = range;
                }
                if slope > self.slope[k] {
                    self.slope[k] = slope;
                }
            }
        }
    }

    /// The verdict per dimension.
    pub fn dimensions(&self) -> Vec<DimensionScreening> {
        let n = self.n_outputs;
        let totals: Vec<f64> = (0..n)
            .map(|o| (0..self.dim).map(|j| self.range[j * n + o]).sum())
            .collect();
        (0..self.dim)
            .map(|j| {
                let mut verdict = DimensionScreening {
                    importance: 0.0,
                    relative_slope: 0.0,
                    output: 0,
                };
                for (o, &total) in totals.iter().enumerate() {
                    if total <= 0.0 {
                        continue;
                    }
                    let importance = self.range[j * n + o] / total;
                    if importance > verdict.importance {
                        verdict.importance = importance;
                        verdict.output = o;
                    }
                    verdict.relative_slope =
                        verdict.relative_slope.max(self.slope[j * n + o] / total);
                }
                verdict
            })
            .collect()
    }

    /// The largest secant slope `|y(e_j) − y(−e_j)| / 2` of output `output` along dimension `j`
    /// over the records (the output's unit, per half-width).
    pub fn max_slope(&self, j: usize, output: usize) -> f64 {
        self.slope[j * self.n_outputs + output]
    }

    /// The dimensions in order of decreasing importance (ties: lower index first).
    pub fn ranking(&self) -> Vec<usize> {
        let dimensions = self.dimensions();
        let mut order: Vec<usize> = (0..self.dim).collect();
        order.sort_by(|&a, &b| {
            dimensions[b]
                .importance
                .total_cmp(&dimensions[a].importance)
                .then(a.cmp(&b))
        });
        order
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quadratic_parameter_ranks_above_a_weak_linear_one_and_a_dead_one_last() {
        // y = 0.1 ξ_0 + ξ_1² + 0 ξ_2: the star sees ξ_1's curvature although its slope is 0.
        let f = |xi: &[f64]| vec![0.1 * xi[0] + xi[1] * xi[1]];
        let d = 3;
        let points = Screening::points(d);
        let values: Vec<Vec<f64>> = points.chunks(d).map(f).collect();
        let mut screening = Screening::new(d, 1);
        screening.add_record(&f(&[0.0; 3]), |i| &values[i]);
        assert_eq!(screening.ranking(), vec![1, 0, 2]);
        let dims = screening.dimensions();
        assert!((dims[1].importance - 1.0 / 1.2).abs() < 1e-15);
        assert_eq!(dims[1].relative_slope, 0.0);
        assert!((dims[0].relative_slope - 0.1 / 1.2).abs() < 1e-15);
        assert_eq!(dims[2].importance, 0.0);
    }

    #[test]
    fn star_points_are_the_face_centres() {
        assert_eq!(
            Screening::points(2),
            vec![1.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, -1.0]
        );
    }
}
