//! The sine and cosine of joint and rotation angles, computed here rather than by the platform's
//! `libm`, so that one value and a batch of lanes get the same bits from the same operations
//! (docs/batch.md §2) and the lanes of the lock-step compute them together.
//!
//! Method (docs/batch.md §6): the angle is reduced to `r = x − k π/2`, `|r| ≤ π/4` (slightly more
//! where `x · 2/π` rounds across a half), with `π/2` split into three pieces whose first two have
//! short significands, so that `k · HALF_PI_HIGH` and `k · HALF_PI_MIDDLE` are exact and the
//! subtraction's own rounding error is kept (`r` is carried as a head and a tail, their sum
//! accurate to about 2⁻¹¹⁰). Then `sin r` and `cos r` are the Taylor polynomials of degrees 17 and
//! 18 (the first terms left out are below 10⁻¹⁹ on `|r| ≤ π/4`), evaluated by Horner's rule in `r²`,
//! and the quadrant `k mod 4` swaps and negates them. Beyond [`REDUCED_HERE_BELOW`], and for NaN
//! and ±∞, the value comes from `f64::sin_cos`.
//!
//! Accuracy (tested in this module): within one unit in the last place of `f64::sin_cos` on
//! random and adversarial arguments (multiples of `π/2` and their neighbours, tiny values).

/// Largest `|x|` (rad) reduced here (`k ≤ 652` multiples of `π/2`, so that `k · HALF_PI_HIGH` is
/// exact and the reduction keeps its accuracy next to those multiples); beyond it, and for NaN and
/// ±∞, [`sin_cos`] returns `f64::sin_cos(x)`. No joint turns that far in a simulation; the bound
/// only keeps the function correct for every input.
pub const REDUCED_HERE_BELOW: f64 = 1024.0;

/// `π/2` rounded to 33 significant bits: `k · HALF_PI_HIGH` is exact for `k < 2²⁰`.
const HALF_PI_HIGH: f64 = 1.570_796_326_734_125_6;
/// `π/2 − HALF_PI_HIGH` rounded to 33 significant bits.
const HALF_PI_MIDDLE: f64 = 6.077_100_506_303_966e-11;
/// `π/2 − HALF_PI_HIGH − HALF_PI_MIDDLE` rounded to double (what is left is below 10⁻³⁶).
const HALF_PI_LOW: f64 = 2.022_266_248_795_950_6e-21;
/// `1.5 · 2⁵²`: adding it rounds a value below `2⁵¹` in magnitude to an integer (ties to even),
/// whose two lowest bits end the sum's significand.
const ROUND_TO_INTEGER: f64 = 6_755_399_441_055_744.0;

/// Taylor coefficients of `(sin r − r)/r³` in `z = r²`: `−1/3!, 1/5!, …, 1/17!`.
const SIN_COEFFICIENTS: [f64; 8] = [
    -1.0 / 6.0,
    1.0 / 120.0,
    -1.0 / 5_040.0,
    1.0 / 362_880.0,
    -1.0 / 39_916_800.0,
    1.0 / 6_227_020_800.0,
    -1.0 / 1_307_674_368_000.0,
    1.0 / 355_687_428_096_000.0,
];

/// Taylor coefficients of `(cos r − 1 + r²/2)/r⁴` in `z = r²`: `1/4!, −1/6!, …, 1/18!`.
const COS_COEFFICIENTS: [f64; 8] = [
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
    1.0 / 479_001_600.0,
    -1.0 / 87_178_291_200.0,
    1.0 / 20_922_789_888_000.0,
    -1.0 / 6_402_373_705_728_000.0,
];

/// `(sin x, cos x)`: the same bits as any lane of [`sin_cos_lanes`] holding `x`.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    let ([sin], [cos]) = sin_cos_lanes([x]);
    (sin, cos)
}

/// `(sin x, cos x)` of every lane, each lane the same operations as [`sin_cos`] of it.
///
/// When every lane is within [`REDUCED_HERE_BELOW`] (always, in a simulation) the lanes go through
/// `reduced_lanes` together, whose every statement is a loop over the lanes that the compiler
/// vectorises where the caller is compiled for vectors (26 instructions per lane under AVX2 against
/// about 110 for a libm call). Otherwise `outlying_lanes` takes them one by one: a lane in range
/// gets the same operations, so the same bits, and a lane out of range libm's value. (A per-lane
/// branch to libm inside the vector path stopped the compiler from vectorising any of it.)
#[inline(always)]
pub fn sin_cos_lanes<const W: usize>(x: [f64; W]) -> ([f64; W], [f64; W]) {
    if x.iter().all(|x| x.abs() < REDUCED_HERE_BELOW) {
        reduced_lanes(x)
    } else {
        outlying_lanes(x)
    }
}

/// [`sin_cos_lanes`] when some lane is out of range (or NaN): lane by lane, [`reduced_lanes`] of
/// the lanes in range and `f64::sin_cos` of the others.
#[cold]
#[inline(never)]
fn outlying_lanes<const W: usize>(x: [f64; W]) -> ([f64; W], [f64; W]) {
    let (mut sin, mut cos) = ([0.0; W], [0.0; W]);
    for ((sin, cos), &x) in sin.iter_mut().zip(cos.iter_mut()).zip(&x) {
        (*sin, *cos) = if x.abs() < REDUCED_HERE_BELOW {
            let ([s], [c]) = reduced_lanes([x]);
            (s, c)
        } else {
            x.sin_cos()
        };
    }
    (sin, cos)
}

/// `(sin x, cos x)` of every lane by the reduction and polynomials of the module docs, valid for
/// `|x| <` [`REDUCED_HERE_BELOW`] (finite garbage or NaN beyond). Every statement is a loop over
/// the lanes, with no branch.
#[inline(always)]
fn reduced_lanes<const W: usize>(x: [f64; W]) -> ([f64; W], [f64; W]) {
    let shifted = each::<W>(|l| x[l] * std::f64::consts::FRAC_2_PI + ROUND_TO_INTEGER);
    let k = each::<W>(|l| shifted[l] - ROUND_TO_INTEGER);
    // r = x − k π/2 as head + tail. `high` is exact (x and k · HALF_PI_HIGH are within a factor
    // of two of each other, or k = 0); `middle` is exact; the subtraction's error is recovered by
    // the two-sum (valid whatever the magnitudes).
    let high = each::<W>(|l| x[l] - k[l] * HALF_PI_HIGH);
    let middle = each::<W>(|l| k[l] * HALF_PI_MIDDLE);
    let difference = each::<W>(|l| high[l] - middle[l]);
    let middle_taken = each::<W>(|l| difference[l] - high[l]);
    let error = each::<W>(|l| {
        (high[l] - (difference[l] - middle_taken[l])) + (-middle[l] - middle_taken[l])
    });
    let tail_sum = each::<W>(|l| error[l] - k[l] * HALF_PI_LOW);
    let head = each::<W>(|l| difference[l] + tail_sum[l]);
    let tail = each::<W>(|l| tail_sum[l] - (head[l] - difference[l]));

    let z = each::<W>(|l| head[l] * head[l]);
    let mut sin_poly = [SIN_COEFFICIENTS[7]; W];
    for &c in SIN_COEFFICIENTS[..7].iter().rev() {
        sin_poly = each(|l| sin_poly[l] * z[l] + c);
    }
    let mut cos_poly = [COS_COEFFICIENTS[7]; W];
    for &c in COS_COEFFICIENTS[..7].iter().rev() {
        cos_poly = each(|l| cos_poly[l] * z[l] + c);
    }
    // sin(h + t) ≈ sin h + t cos h, cos(h + t) ≈ cos h − t sin h, to first order in the tail.
    let sin_r = each::<W>(|l| {
        let sum = head[l] + (head[l] * z[l] * sin_poly[l] + tail[l] * (1.0 - 0.5 * z[l]));
        // sin(−0) is −0, which the sum rounds to +0: put x's sign back when x is zero (bit
        // operations, not a branch, which would stop the vectorising).
        let zero_sign = x[l].to_bits() & (1 << 63) & u64::from(x[l] == 0.0).wrapping_neg();
        f64::from_bits(sum.to_bits() | zero_sign)
    });
    // cos h = 1 − z/2 + z² C(z), with the rounding error of 1 − z/2 recovered exactly.
    let half_z = each::<W>(|l| 0.5 * z[l]);
    let one_minus = each::<W>(|l| 1.0 - half_z[l]);
    let cos_r = each::<W>(|l| {
        one_minus[l]
            + (((1.0 - one_minus[l]) - half_z[l]) + (z[l] * z[l] * cos_poly[l] - head[l] * tail[l]))
    });

    // Quadrant k mod 4: (sin, cos) of x is (s, c), (c, −s), (−s, −c), (−c, s).
    let mut sin = [0.0; W];
    let mut cos = [0.0; W];
    for l in 0..W {
        let quadrant = shifted[l].to_bits() & 3;
        let (s, c) = if quadrant & 1 == 1 {
            (cos_r[l], sin_r[l])
        } else {
            (sin_r[l], cos_r[l])
        };
        sin[l] = f64::from_bits(s.to_bits() ^ ((quadrant & 2) << 62));
        cos[l] = f64::from_bits(c.to_bits() ^ (((quadrant + 1) & 2) << 62));
    }
    (sin, cos)
}

/// The lanes `f(0), …, f(W − 1)`: one statement of [`reduced_lanes`].
#[inline(always)]
fn each<const W: usize>(f: impl Fn(usize) -> f64) -> [f64; W] {
    std::array::from_fn(f)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::SplitMix64;

    /// Units in the last place between `a` and `b` (0 for equal values, ±0 included).
    fn ulps(a: f64, b: f64) -> u64 {
        if a == b {
            return 0;
        }
        let ordered = |x: f64| {
            let bits = x.to_bits() as i64;
            if bits < 0 {
                i64::MIN - bits
            } else {
                bits
            }
        };
        ordered(a).abs_diff(ordered(b))
    }

    /// The largest distance in ulps to `f64::sin_cos` over `angles`, and the angle where.
    fn worst(angles: impl IntoIterator<Item = f64>) -> (u64, f64) {
        let mut worst = (0, 0.0);
        for x in angles {
            let (s, c) = sin_cos(x);
            let (s_ref, c_ref) = x.sin_cos();
            let distance = ulps(s, s_ref).max(ulps(c, c_ref));
            if distance > worst.0 {
                worst = (distance, x);
            }
        }
        worst
    }

    #[test]
    fn random_angles_are_within_one_ulp_of_libm() {
        let mut generator = SplitMix64::new(0x5eed_fa11);
        for range in [1.0, 4.0, 40.0, REDUCED_HERE_BELOW] {
            let angles: Vec<f64> = (0..200_000)
                .map(|_| generator.uniform(-range, range))
                .collect();
            let (distance, at) = worst(angles);
            assert!(
                distance <= 1,
                "{distance} ulps at x = {at:e} (range ±{range})"
            );
        }
    }

    #[test]
    fn angles_next_to_multiples_of_half_pi_are_within_one_ulp_of_libm() {
        // The reduction cancels most here: r is a few ulps of x or less.
        let mut angles = Vec::new();
        for k in -652i32..=652 {
            let centre = f64::from(k) * std::f64::consts::FRAC_PI_2;
            let mut x = centre;
            for _ in 0..8 {
                angles.push(x);
                x = x.next_up();
            }
            let mut x = centre;
            for _ in 0..8 {
                x = x.next_down();
                angles.push(x);
            }
            // Halfway between multiples, where k may round either way.
            angles.push(centre + std::f64::consts::FRAC_PI_4);
        }
        let (distance, at) = worst(angles);
        assert!(distance <= 1, "{distance} ulps at x = {at:e}");
    }

    #[test]
    fn tiny_and_special_angles() {
        let tiny = [
            0.0,
            -0.0,
            f64::MIN_POSITIVE,
            5e-324,
            -5e-324,
            1e-300,
            1e-20,
            -3e-9,
            1e-5,
        ];
        let (distance, at) = worst(tiny);
        assert!(distance <= 1, "{distance} ulps at x = {at:e}");
        assert_eq!(sin_cos(0.0).0.to_bits(), 0.0f64.to_bits());
        assert_eq!(sin_cos(-0.0).0.to_bits(), (-0.0f64).to_bits());
        assert_eq!(sin_cos(-0.0).1, 1.0);
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let (s, c) = sin_cos(x);
            assert!(s.is_nan() && c.is_nan(), "sin_cos({x}) = ({s}, {c})");
        }
        // Beyond the reduced range the value is libm's, bit for bit.
        for x in [REDUCED_HERE_BELOW, -REDUCED_HERE_BELOW, 1e6, -3.3e15, 1e300] {
            let (s, c) = sin_cos(x);
            let (s_ref, c_ref) = x.sin_cos();
            assert_eq!(
                (s.to_bits(), c.to_bits()),
                (s_ref.to_bits(), c_ref.to_bits()),
                "x = {x:e}"
            );
        }
    }

    #[test]
    fn lanes_have_the_bits_of_one_value_each() {
        let mut generator = SplitMix64::new(42);
        for _ in 0..10_000 {
            let lanes: [f64; 4] = std::array::from_fn(|lane| match lane {
                3 if generator.uniform(0.0, 1.0) < 0.1 => 1e7,
                _ => generator.uniform(-8.0, 8.0),
            });
            let (sin, cos) = sin_cos_lanes(lanes);
            for (lane, &x) in lanes.iter().enumerate() {
                let (s, c) = sin_cos(x);
                assert_eq!(
                    sin[lane].to_bits(),
                    s.to_bits(),
                    "sin, lane {lane}, x = {x}"
                );
                assert_eq!(
                    cos[lane].to_bits(),
                    c.to_bits(),
                    "cos, lane {lane}, x = {x}"
                );
            }
        }
    }
}
