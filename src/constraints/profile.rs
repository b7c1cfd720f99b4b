//! Prescribed motions `f(t)` of drives, with their first and second time derivatives.

/// A drive's prescribed joint position.
#[derive(Clone, Debug, PartialEq)]
pub enum Profile {
    /// `f = value`.
    Constant {
        /// rad or m.
        value: f64,
    },
    /// `f = value + rate·t`.
    Ramp {
        /// rad or m.
        value: f64,
        /// rad/s or m/s.
        rate: f64,
    },
    /// `f = offset + amplitude·sin(2π·frequency·t + phase)`.
    Sine {
        /// rad or m.
        offset: f64,
        /// rad or m.
        amplitude: f64,
        /// Hz.
        frequency: f64,
        /// rad.
        phase: f64,
    },
    /// A cubic spline through `(t_i, q_i)` with zero velocity at both ends, held constant outside.
    Spline(Spline),
}

impl Profile {
    /// `(f, ḟ, f̈)` at time `t` (s).
    pub fn evaluate(&self, t: f64) -> (f64, f64, f64) {
        match self {
            Profile::Constant { value } => (*value, 0.0, 0.0),
            Profile::Ramp { value, rate } => (value + rate * t, *rate, 0.0),
            Profile::Sine {
                offset,
                amplitude,
                frequency,
                phase,
            } => {
                let omega = 2.0 * std::f64::consts::PI * frequency;
                let (s, c) = (omega * t + phase).sin_cos();
                (
                    offset + amplitude * s,
                    amplitude * omega * c,
                    -amplitude * omega * omega * s,
                )
            }
            Profile::Spline(spline) => spline.evaluate(t),
        }
    }
}

/// A clamped cubic spline (first derivative 0 at both ends).
#[derive(Clone, Debug, PartialEq)]
pub struct Spline {
    times: Vec<f64>,
    values: Vec<f64>,
    /// Second derivatives at the knots.
    curvature: Vec<f64>,
}

impl Spline {
    /// Builds the spline through `points` (`[t, q]`, strictly increasing `t`, at least two).
    /// Returns a message on invalid points.
    pub fn new(points: &[[f64; 2]]) -> Result<Spline, String> {
        if points.len() < 2 {
            return Err(format!(
                "a spline needs at least 2 points, got {}",
                points.len()
            ));
        }
        if points.iter().flatten().any(|x| !x.is_finite()) {
            return Err("every point must be finite".to_string());
        }
        if let Some(w) = points.windows(2).find(|w| w[1][0] <= w[0][0]) {
            return Err(format!(
                "times must increase strictly ({} is followed by {})",
                w[0][0], w[1][0]
            ));
        }
        let n = points.len();
        let times: Vec<f64> = points.iter().map(|p| p[0]).collect();
        let values: Vec<f64> = points.iter().map(|p| p[1]).collect();
        let h: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
        // Tridiagonal system for the second derivatives M_i with clamped ends (f' = 0):
        //   2h_0 M_0 + h_0 M_1 = 6 (y_1 − y_0)/h_0
        //   h_{i−1} M_{i−1} + 2(h_{i−1} + h_i) M_i + h_i M_{i+1} = 6 [(y_{i+1} − y_i)/h_i − (y_i − y_{i−1})/h_{i−1}]
        //   h_{n−2} M_{n−2} + 2h_{n−2} M_{n−1} = −6 (y_{n−1} − y_{n−2})/h_{n−2}
        let slope = |i: usize| (values[i + 1] - values[i]) / h[i];
        let mut lower = vec![0.0; n];
        let mut diagonal = vec![0.0; n];
        let mut upper = vec![0.0; n];
        let mut rhs = vec![0.0; n];
        diagonal[0] = 2.0 * h[0];
        upper[0] = h[0];
        rhs[0] = 6.0 * slope(0);
        for i in 1..n - 1 {
            lower[i] = h[i - 1];
            diagonal[i] = 2.0 * (h[i - 1] + h[i]);
            upper[i] = h[i];
            rhs[i] = 6.0 * (slope(i) - slope(i - 1));
        }
        lower[n - 1] = h[n - 2];
        diagonal[n - 1] = 2.0 * h[n - 2];
        rhs[n - 1] = -6.0 * slope(n - 2);
        // Thomas algorithm (diagonally dominant: stable without pivoting).
        for i in 1..n {
            let factor = lower[i] / diagonal[i - 1];
            diagonal[i] -= factor * upper[i - 1];
            rhs[i] -= factor * rhs[i - 1];
        }
        let mut curvature = vec![0.0; n];
        curvature[n - 1] = rhs[n - 1] / diagonal[n - 1];
        for i in (0..n - 1).rev() {
            curvature[i] = (rhs[i] - upper[i] * curvature[i + 1]) / diagonal[i];
        }
        Ok(Spline {
            times,
            values,
            curvature,
        })
    }

    /// `(f, ḟ, f̈)` at `t`; constant (with zero derivatives) before the first and after the last point.
    pub fn evaluate(&self, t: f64) -> (f64, f64, f64) {
        let n = self.times.len();
        if t <= self.times[0] {
            return (self.values[0], 0.0, 0.0);
        }
        if t >= self.times[n - 1] {
            return (self.values[n - 1], 0.0, 0.0);
        }
        let i = self
            .times
            .partition_point(|x| *x <= t)
            .saturating_sub(1)
            .min(n - 2);
        let h = self.times[i + 1] - self.times[i];
        let (a, b) = ((self.times[i + 1] - t) / h, (t - self.times[i]) / h);
        let (m0, m1) = (self.curvature[i], self.curvature[i + 1]);
        let (y0, y1) = (self.values[i], self.values[i + 1]);
        let value = a * y0 + b * y1 + ((a * a * a - a) * m0 + (b * b * b - b) * m1) * h * h / 6.0;
        let velocity =
            (y1 - y0) / h + ((1.0 - 3.0 * a * a) * m0 + (3.0 * b * b - 1.0) * m1) * h / 6.0;
        let acceleration = a * m0 + b * m1;
        (value, velocity, acceleration)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spline_interpolates_with_zero_end_velocity() {
        let spline = Spline::new(&[[0.0, 0.0], [0.5, 1.0], [1.5, -0.5], [2.0, 0.25]]).unwrap();
        for (t, q) in [(0.0, 0.0), (0.5, 1.0), (1.5, -0.5), (2.0, 0.25)] {
            assert!((spline.evaluate(t).0 - q).abs() < 1e-14, "at {t}");
        }
        assert!(spline.evaluate(1e-12).1.abs() < 1e-9);
        assert!(spline.evaluate(2.0 - 1e-12).1.abs() < 1e-9);
        // Derivatives agree with central differences inside.
        let h = 1e-6;
        for t in [0.3, 0.9, 1.7] {
            let (_, v, a) = spline.evaluate(t);
            let dv = (spline.evaluate(t + h).0 - spline.evaluate(t - h).0) / (2.0 * h);
            let da = (spline.evaluate(t + h).1 - spline.evaluate(t - h).1) / (2.0 * h);
            assert!(
                (v - dv).abs() < 1e-7 && (a - da).abs() < 1e-5,
                "t {t}: {v} {dv} {a} {da}"
            );
        }
        assert!(Spline::new(&[[0.0, 1.0]]).is_err());
        assert!(Spline::new(&[[0.0, 1.0], [0.0, 2.0]]).is_err());
    }

    #[test]
    fn sine_derivatives() {
        let p = Profile::Sine {
            offset: 0.1,
            amplitude: 0.5,
            frequency: 1.0,
            phase: 0.3,
        };
        let h = 1e-6;
        let (_, v, a) = p.evaluate(0.4);
        assert!((v - (p.evaluate(0.4 + h).0 - p.evaluate(0.4 - h).0) / (2.0 * h)).abs() < 1e-7);
        assert!((a - (p.evaluate(0.4 + h).1 - p.evaluate(0.4 - h).1) / (2.0 * h)).abs() < 1e-6);
    }
}
