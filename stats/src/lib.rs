//! The Wilcoxon signed-rank test for paired samples, as the thesis evaluates its experiments
//! (section 3.7.1: one-tailed, within subjects).
//!
//! Zero differences are dropped (Wilcoxon's method), tied magnitudes get their average rank. The
//! exact p value enumerates all `2^n` sign patterns of the observed ranks (by dynamic programming
//! over doubled ranks, so ties stay exact); the normal approximation uses the tie-corrected variance
//! without continuity correction, which is what SPSS reports and what the thesis's figures match.
//!
//! One implementation for every experiment: the shared-control study (manual vs shared) and the
//! detector repeatability comparison (`intellwheels repeatability`).
//!
//! Also the one standard normal draw ([`standard_normal`]) that the simulator's sensor noise,
//! the simulated drivers and the localizer's particles take from their seeded streams.

/// A standard normal draw by Box-Muller (cosine branch), two uniforms from `rng`. Seeded runs
/// depend on this exact sequence of draws, so every simulation shares this one function.
pub fn standard_normal<R: rand::Rng + ?Sized>(rng: &mut R) -> f64 {
    let u1: f64 = rng.random_range(f64::EPSILON..1.0);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Why a test could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StatsError {
    /// The paired samples have different lengths.
    #[error("paired samples differ in length: {left} vs {right}")]
    UnpairedSamples {
        /// First sample length.
        left: usize,
        /// Second sample length.
        right: usize,
    },
    /// A difference is NaN or infinite.
    #[error("pair {index}: difference {value} is not finite")]
    NotFinite {
        /// Index of the pair.
        index: usize,
        /// The difference.
        value: f64,
    },
}

/// The alternative hypothesis about `x - y`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Alternative {
    /// `x` tends to differ from `y`.
    TwoSided,
    /// `x` tends to be greater than `y` (e.g. manual collisions > shared ones).
    Greater,
    /// `x` tends to be less than `y`.
    Less,
}

/// Outcome of the test.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Wilcoxon {
    /// Pairs with a nonzero difference.
    pub n: usize,
    /// Sum of the ranks of positive differences.
    pub w_plus: f64,
    /// Sum of the ranks of negative differences.
    pub w_minus: f64,
    /// `min(w_plus, w_minus)`, the statistic the thesis reports.
    pub t: f64,
    /// Exact p value (`None` above [`EXACT_MAX_N`] pairs).
    pub p_exact: Option<f64>,
    /// Normal-approximation z of `w_plus`.
    pub z: f64,
    /// Normal-approximation p value.
    pub p_normal: f64,
}

impl Wilcoxon {
    /// The exact p value when available, else the normal approximation.
    pub fn p(&self) -> f64 {
        self.p_exact.unwrap_or(self.p_normal)
    }
}

/// Largest number of nonzero pairs for which the exact distribution is computed.
pub const EXACT_MAX_N: usize = 200;

/// Wilcoxon signed-rank test of the paired samples `x` and `y`.
pub fn wilcoxon_signed_rank(
    x: &[f64],
    y: &[f64],
    alternative: Alternative,
) -> Result<Wilcoxon, StatsError> {
    if x.len() != y.len() {
        return Err(StatsError::UnpairedSamples {
            left: x.len(),
            right: y.len(),
        });
    }
    let mut diffs = Vec::with_capacity(x.len());
    for (index, (a, b)) in x.iter().zip(y).enumerate() {
        let d = a - b;
        if !d.is_finite() {
            return Err(StatsError::NotFinite { index, value: d });
        }
        if d != 0.0 {
            diffs.push(d);
        }
    }
    diffs.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    let n = diffs.len();
    // Doubled average ranks keep ties integral: a tie over ranks i+1..=j averages to (i+1+j)/2.
    let mut doubled_ranks = vec![0u64; n];
    let mut tie_term = 0.0;
    let mut i = 0;
    while i < n {
        let mut j = i + 1;
        while j < n && diffs[j].abs() == diffs[i].abs() {
            j += 1;
        }
        doubled_ranks[i..j]
            .iter_mut()
            .for_each(|r| *r = (i + 1 + j) as u64);
        let t = (j - i) as f64;
        tie_term += t * t * t - t;
        i = j;
    }
    let doubled_plus: u64 = diffs
        .iter()
        .zip(&doubled_ranks)
        .filter(|(d, _)| **d > 0.0)
        .map(|(_, r)| r)
        .sum();
    let doubled_total: u64 = doubled_ranks.iter().sum();
    let w_plus = doubled_plus as f64 / 2.0;
    let w_minus = (doubled_total - doubled_plus) as f64 / 2.0;
    let nf = n as f64;
    let mean = nf * (nf + 1.0) / 4.0;
    let variance = nf * (nf + 1.0) * (2.0 * nf + 1.0) / 24.0 - tie_term / 48.0;
    let z = if variance > 0.0 {
        (w_plus - mean) / variance.sqrt()
    } else {
        0.0
    };
    let p_normal = match alternative {
        Alternative::Greater => normal_sf(z),
        Alternative::Less => normal_sf(-z),
        Alternative::TwoSided => (2.0 * normal_sf(z.abs())).min(1.0),
    };
    let p_exact = (n <= EXACT_MAX_N).then(|| {
        let (upper, lower) = exact_tails(&doubled_ranks, doubled_plus);
        match alternative {
            Alternative::Greater => upper,
            Alternative::Less => lower,
            Alternative::TwoSided => (2.0 * upper.min(lower)).min(1.0),
        }
    });
    Ok(Wilcoxon {
        n,
        w_plus,
        w_minus,
        t: w_plus.min(w_minus),
        p_exact,
        z,
        p_normal,
    })
}

/// `P(W+ >= observed)` and `P(W+ <= observed)` under random signs, in doubled-rank units.
fn exact_tails(doubled_ranks: &[u64], observed: u64) -> (f64, f64) {
    let total: u64 = doubled_ranks.iter().sum();
    // counts[s] = probability that the positive ranks sum to s.
    let mut counts = vec![0.0f64; total as usize + 1];
    counts[0] = 1.0;
    let mut reach = 0usize;
    for &r in doubled_ranks {
        let r = r as usize;
        for s in (0..=reach).rev() {
            let c = counts[s] * 0.5;
            counts[s] = c;
            counts[s + r] += c;
        }
        reach += r;
    }
    let observed = observed as usize;
    let upper = counts[observed..].iter().sum::<f64>().min(1.0);
    let lower = counts[..=observed].iter().sum::<f64>().min(1.0);
    (upper, lower)
}

/// Standard normal survival function `P(Z > z)`.
pub fn normal_sf(z: f64) -> f64 {
    0.5 * erfc(z / std::f64::consts::SQRT_2)
}

/// Complementary error function (Numerical Recipes' Chebyshev fit, relative error < 1.2e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98
                                + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 { r } else { 2.0 - r }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn hollander_wolfe_example_matches_published_values() {
        // Hollander and Wolfe's example, as in SciPy's documentation: W- = 24 (T), exact
        // two-sided p = 0.041259765625, one-sided 0.0206298828125; normal approx 0.040888.
        let d = [
            6.0, 8.0, 14.0, 16.0, 23.0, 24.0, 28.0, 29.0, 41.0, -48.0, 49.0, 56.0, 60.0, -67.0,
            75.0,
        ];
        let zeros = [0.0; 15];
        let two = wilcoxon_signed_rank(&d, &zeros, Alternative::TwoSided).unwrap();
        assert_eq!(two.t, 24.0);
        assert_eq!(two.w_plus, 96.0);
        assert!(close(two.p_exact.unwrap(), 0.041259765625, 1e-12));
        assert!(close(two.p_normal, 0.040888132911856, 1e-6));
        let greater = wilcoxon_signed_rank(&d, &zeros, Alternative::Greater).unwrap();
        assert!(close(greater.p_exact.unwrap(), 0.0206298828125, 1e-12));
    }

    #[test]
    fn thesis_simulated_environment_result() {
        // Thesis 3.7.1: T = 0 over seven nonzero pairs, one-tailed normal p = 0.009.
        let manual = [3.0, 5.0, 2.0, 4.0, 6.0, 1.0, 2.0, 0.0];
        let shared = [0.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0];
        let w = wilcoxon_signed_rank(&manual, &shared, Alternative::Greater).unwrap();
        assert_eq!((w.n, w.t), (7, 0.0));
        assert!(close(w.p_normal, 0.009, 0.0005), "{}", w.p_normal);
        assert!(close(w.p_exact.unwrap(), 1.0 / 128.0, 1e-12));
    }

    #[test]
    fn ties_use_the_corrected_variance() {
        // SciPy: wilcoxon([3,3,2,2,6,1,1,3], method="approx") -> p = 0.011109224550098225.
        let d = [3.0, 3.0, 2.0, 2.0, 6.0, 1.0, 1.0, 3.0, 0.0];
        let w = wilcoxon_signed_rank(&d, &[0.0; 9], Alternative::TwoSided).unwrap();
        assert!(
            close(w.p_normal, 0.011109224550098225, 1e-6),
            "{}",
            w.p_normal
        );
        // Every sign pattern equally likely: all positive is 1 in 256, one-sided.
        let g = wilcoxon_signed_rank(&d, &[0.0; 9], Alternative::Greater).unwrap();
        assert!(close(g.p_exact.unwrap(), 1.0 / 256.0, 1e-12));
    }

    #[test]
    fn no_differences_means_no_evidence() {
        let w = wilcoxon_signed_rank(&[1.0, 2.0], &[1.0, 2.0], Alternative::Greater).unwrap();
        assert_eq!(w.n, 0);
        assert_eq!(w.p(), 1.0);
    }

    #[test]
    fn unpaired_or_non_finite_is_an_error() {
        assert!(wilcoxon_signed_rank(&[1.0], &[], Alternative::Greater).is_err());
        assert!(matches!(
            wilcoxon_signed_rank(&[f64::NAN], &[0.0], Alternative::Greater),
            Err(StatsError::NotFinite { index: 0, .. })
        ));
    }

    #[test]
    fn normal_approximation_without_ties_matches_scipy() {
        // scipy.stats.wilcoxon(d, correction=False, method="approx") gives p = 0.074462:
        // W+ = 45 over n = 10 without ties, z = (45 - 27.5) / sqrt(96.25).
        let d = [1.0, 2.0, -3.0, 4.0, 5.0, 6.0, -7.0, 8.0, 9.0, 10.0];
        let w = wilcoxon_signed_rank(&d, &[0.0; 10], Alternative::TwoSided).unwrap();
        assert_eq!(w.w_plus, 45.0);
        assert!(close(w.z, (45.0 - 27.5) / 96.25f64.sqrt(), 1e-12));
        assert!(close(w.p_normal, 0.074_461_83, 1e-6), "{}", w.p_normal);
    }
}
