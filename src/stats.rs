//! Estimators under uncertainty, apart from any dynamics (the sensitivity study and the risk
//! map use them): binomial intervals (Wilson),
//! Sobol indices from a Saltelli design (Saltelli 2010 first order, Jansen 1999 total) with
//! bootstrap intervals, and the probability that a Gaussian perturbation of a class map lands on
//! another class. Each is tested where its answer is known (tests/sensitivity.rs).

use statrs::distribution::{ContinuousCDF, Normal};

/// z of a two-sided 95% interval.
pub const Z95: f64 = 1.959_963_984_540_054;

/// The Wilson score interval of `k` successes in `n` trials at 95%: (estimate, low, high).
/// Unlike the normal approximation it stays inside [0, 1] and is honest at k = 0 or k = n.
pub fn wilson(k: usize, n: usize) -> (f64, f64, f64) {
    if n == 0 {
        return (f64::NAN, 0.0, 1.0);
    }
    let (k, n) = (k as f64, n as f64);
    let p = k / n;
    let z2 = Z95 * Z95;
    let centre = (p + z2 / (2.0 * n)) / (1.0 + z2 / n);
    let half = Z95 / (1.0 + z2 / n) * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt();
    // At k = 0 and k = n the bound is exactly 0 or 1; rounding must not put it past p.
    (
        p,
        (centre - half).clamp(0.0, p),
        (centre + half).clamp(p, 1.0),
    )
}

/// First-order and total Sobol indices of one input from a Saltelli design: `a[i]` = f(A_i),
/// `b[i]` = f(B_i), `ab[i]` = f(A_i with this input taken from B_i).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Indices {
    /// First order S_j = E[f(B) (f(AB_j) - f(A))] / V (Saltelli et al. 2010), f centred.
    pub first: f64,
    /// Total S_Tj = E[(f(A) - f(AB_j))^2] / (2 V) (Jansen 1999).
    pub total: f64,
}

/// [`Indices`] of rows `rows` of the design (all of them: `0..a.len()`).
pub fn indices(a: &[f64], b: &[f64], ab: &[f64], rows: &[usize]) -> Indices {
    let n = rows.len() as f64;
    // The variance of the output over both independent matrices.
    let mean = rows.iter().map(|&i| a[i] + b[i]).sum::<f64>() / (2.0 * n);
    let var = rows
        .iter()
        .map(|&i| (a[i] - mean).powi(2) + (b[i] - mean).powi(2))
        .sum::<f64>()
        / (2.0 * n - 1.0);
    if var.is_nan() || var <= 0.0 {
        // A constant output: no input matters.
        return Indices {
            first: 0.0,
            total: 0.0,
        };
    }
    // f(B) centred: the estimator is unbiased either way, but its variance grows with the
    // output's mean squared (an exponent of -0.05 +- 0.002 gave an interval of width 2.8).
    let first = rows
        .iter()
        .map(|&i| (b[i] - mean) * (ab[i] - a[i]))
        .sum::<f64>()
        / n
        / var;
    let total = rows.iter().map(|&i| (a[i] - ab[i]).powi(2)).sum::<f64>() / (2.0 * n) / var;
    Indices { first, total }
}

/// A bootstrap 95% interval of [`indices`]: (first low, first high, total low, total high),
/// over `resamples` resamples of the design's rows drawn with a fixed seed.
pub fn bootstrap(a: &[f64], b: &[f64], ab: &[f64], resamples: usize, seed: u64) -> [f64; 4] {
    let n = a.len();
    let mut rng = SplitMix(seed);
    let (mut firsts, mut totals) = (Vec::new(), Vec::new());
    let mut rows = vec![0; n];
    for _ in 0..resamples {
        for r in rows.iter_mut() {
            *r = (rng.next_u64() % n as u64) as usize;
        }
        let s = indices(a, b, ab, &rows);
        firsts.push(s.first);
        totals.push(s.total);
    }
    let (f, t) = (percentiles(&mut firsts), percentiles(&mut totals));
    [f.0, f.1, t.0, t.1]
}

/// The 2.5% and 97.5% points of `v`.
fn percentiles(v: &mut [f64]) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    (at(0.025), at(0.975))
}

/// SplitMix64 (Steele, Lea and Flood 2014): the bootstrap's resampling (and the judge's cell
/// sample) needs numbers with a fixed seed, the same on every machine, and nothing more; a
/// generator crate for eight lines would add more than it saves.
pub struct SplitMix(pub u64);

impl SplitMix {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
}

/// The risk map: for each cell of a `nx` x `ny` class grid (row-major, y outer), the
/// probability that a Gaussian perturbation of the two parameters with standard deviations
/// `sx`, `sy` (in cells) lands on a cell of another class. The perturbation's mass over each
/// neighbouring cell is the product of the normal masses of its x and y intervals (the
/// convolution of the class-difference indicator with the Gaussian, out to 4 sigma or the
/// grid's extent, whichever is less); mass that falls outside the grid is unknown and left out,
/// so a cell's probability is over the mass inside. Time and memory are bounded by the grid
/// whatever sigma is: cells x (kx + ky) with kx < 2 nx, ky < 2 ny.
pub fn risk(classes: &[i32], nx: usize, ny: usize, sx: f64, sy: f64) -> Vec<f64> {
    // Only ratios of the weights enter (the mass on other classes over the mass inside the
    // grid), so each axis may be scaled freely.
    let weights = |s: f64, n: usize| -> Vec<f64> {
        // Offsets beyond the grid's extent never land on it: the kernel needs no more, however
        // large sigma is (its length, memory and time are bounded by the grid).
        let reach = (4.0 * s).ceil().min(n.saturating_sub(1) as f64) as i64;
        if s > 1e3 {
            // The cell masses are the density at the cell centres to 1/(24 s^2); the density's
            // shape, unnormalised, keeps them from underflowing where s is huge.
            return (-reach..=reach)
                .map(|k| (-0.5 * (k as f64 / s).powi(2)).exp())
                .collect();
        }
        // Cell k's mass: the normal's mass over [k - 1/2, k + 1/2] cell widths.
        let n = Normal::new(0.0, s.max(1e-300)).expect("a positive standard deviation");
        (-reach..=reach)
            .map(|k| n.cdf(k as f64 + 0.5) - n.cdf(k as f64 - 0.5))
            .collect()
    };
    let (wx, wy) = (weights(sx, nx), weights(sy, ny));
    let (rx, ry) = ((wx.len() / 2) as i64, (wy.len() / 2) as i64);
    // The Gaussian is separable and P(same class) at a cell of class c is the convolution of
    // class c's indicator there: class by class, spread each class-c cell along x into a row
    // buffer, then sum that buffer along y at the class-c cells only. Cost: cells x (kx + ky)
    // plus one buffer clear per class, instead of cells x kx x ky.
    let mass = |w: &[f64], r: i64, at: i64, n: usize| -> f64 {
        (-r..=r)
            .filter(|d| (0..n as i64).contains(&(at + d)))
            .map(|d| w[(d + r) as usize])
            .sum()
    };
    let mut by_class: std::collections::BTreeMap<i32, Vec<usize>> = Default::default();
    for (k, &c) in classes.iter().enumerate() {
        by_class.entry(c).or_default().push(k);
    }
    let mut same = vec![0.0; nx * ny];
    let mut spread = vec![0.0; nx * ny];
    for cells in by_class.values() {
        spread.iter_mut().for_each(|v| *v = 0.0);
        for &k in cells {
            let (x, y) = ((k % nx) as i64, k / nx);
            for dx in -rx..=rx {
                let xx = x + dx;
                if (0..nx as i64).contains(&xx) {
                    spread[y * nx + xx as usize] += wx[(dx + rx) as usize];
                }
            }
        }
        for &k in cells {
            let (x, y) = (k % nx, (k / nx) as i64);
            same[k] = (-ry..=ry)
                .filter(|dy| (0..ny as i64).contains(&(y + dy)))
                .map(|dy| wy[(dy + ry) as usize] * spread[(y + dy) as usize * nx + x])
                .sum();
        }
    }
    (0..nx * ny)
        .map(|k| {
            let (x, y) = ((k % nx) as i64, (k / nx) as i64);
            let inside = mass(&wx, rx, x, nx) * mass(&wy, ry, y, ny);
            (1.0 - same[k] / inside).max(0.0)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_is_inside_the_unit_interval_and_covers_the_estimate() {
        for (k, n) in [(0, 10), (10, 10), (3, 10), (500, 1000)] {
            let (p, lo, hi) = wilson(k, n);
            assert!(
                (0.0..=p).contains(&lo) && (p..=1.0).contains(&hi),
                "{k}/{n}"
            );
        }
        // The textbook value: 0 of 10 gives [0, 0.2775].
        assert!((wilson(0, 10).2 - 0.2775).abs() < 1e-4);
    }
}
