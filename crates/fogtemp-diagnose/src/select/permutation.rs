//! The permutation test of the position labels: the run-level rules' null reference for a
//! term that depends on the run's orientation (`Effect::orientation_dependent`).
//!
//! Such a term is, in runs at two orientations, one contrast between the positions. Every
//! leave-one-run-out fold predicts its held-out run from nearly the same contrast estimated
//! from the other runs, so the fold gains share it and are not the independent units the
//! paired t and the signed-rank test assume, and BIC's `n_eff` counts windows, not the runs
//! the contrast is estimated from: on null designs of 8 runs in two positions these rules
//! named an orientation term in 12 and 4 of 100 datasets (docs/diagnose.md). The exact
//! reference is the term's own statistic under every relabelling of the runs' positions:
//! if the orientation does not matter, the runs' labels are exchangeable and the observed
//! labelling is one draw among them (Fisher's randomization test; Good, *Permutation,
//! Parametric and Bootstrap Tests of Hypotheses*, 2005, ch. 3). The statistic is the one the
//! run-level rules claim: the term's profiled leave-one-run-out error, recomputed from
//! scratch (profiling included) for each relabelling.
//!
//! With few runs the test cannot reach the run-level level at all (8 runs in 4 + 4: 70
//! labellings, the observed one and its mirror image give the same fit, so p >= 2/70); the
//! noise-model route, whose null is simulated from a fitted noise law, then decides alone.

use rayon::prelude::*;

use super::design::{profile_candidate, total_cv};
use super::forward::StepContext;
use crate::effects::{orientation_columns, run_labels, EffectGrid, RunLabel};
use crate::noise_model::SplitMix64;

/// Seed of the relabellings (one stream per step).
const PERMUTATION_SEED: u64 = 0x5EED_0020;

/// Relabellings evaluated between two checks of the stopping rule.
const CHUNK: usize = 32;

/// Relative tolerance within which a relabelling's statistic counts as equal to the observed
/// one (the mirror image of two positions gives the same fit up to rounding).
const TIE_TOLERANCE: f64 = 1e-9;

/// A Monte Carlo permutation test's outcome.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct PermutationTest {
    /// Relabellings planned.
    pub(super) planned: usize,
    /// Relabellings evaluated (fewer when the test stopped early).
    pub(super) evaluated: usize,
    /// Relabellings whose statistic was at least as good as the observed one.
    pub(super) as_good: usize,
}

impl PermutationTest {
    /// The Monte Carlo p, `(1 + as_good) / (1 + planned)` (Davison & Hinkley 1997, eq. 4.11).
    /// When the test stopped early this is a lower bound of the p all planned draws would
    /// give, and it already exceeds the level.
    pub(super) fn p(&self) -> f64 {
        (1 + self.as_good) as f64 / (1 + self.planned) as f64
    }

    /// Whether every planned relabelling was evaluated.
    pub(super) fn complete(&self) -> bool {
        self.evaluated >= self.planned
    }
}

/// Relabellings planned for a test at `level`: enough that the p can reach the level with up
/// to three relabellings as good as the observed one (`4 / (1 + planned) <= level`), so the
/// Monte Carlo error costs little power (at least 99).
pub(super) fn draws_for(level: f64) -> usize {
    if level.is_nan() || level <= 0.0 {
        return 99;
    }
    ((4.0 / level).ceil() as usize).saturating_sub(1).clamp(99, 100_000)
}

/// One-sided Monte Carlo permutation p of a statistic where lower is better: `statistic`
/// of a permutation of `0..items` (the observed arrangement is the identity) against
/// `observed`, over `planned` random permutations. Relabellings come from a fixed seed, one
/// stream per draw, evaluated in parallel chunks; the test stops as soon as its p cannot
/// reach `level` any more.
///
pub(super) fn permutation_p<F>(
    items: usize,
    observed: f64,
    level: f64,
    planned: usize,
    seed: u64,
    statistic: F,
) -> PermutationTest
where
    F: Fn(&[usize]) -> f64 + Sync,
{
    let mut test = PermutationTest { planned, evaluated: 0, as_good: 0 };
    if !observed.is_finite() {
        // Nothing to compare against: the p is 1 without a draw.
        test.as_good = planned;
        return test;
    }
    let limit = observed + TIE_TOLERANCE * observed.abs();
    while !test.complete() {
        let chunk = CHUNK.min(planned - test.evaluated);
        let first = test.evaluated;
        let values: Vec<f64> = (first..first + chunk)
            .into_par_iter()
            .map(|draw| {
                let mut order: Vec<usize> = (0..items).collect();
                SplitMix64(seed ^ (draw as u64 + 1).wrapping_mul(0xA24B_AED4_963E_E407)).shuffle(&mut order);
                statistic(&order)
            })
            .collect();
        test.evaluated += chunk;
        // A relabelling whose statistic is not a number counts against the observed one.
        test.as_good += values.iter().filter(|v| v.is_nan() || **v <= limit).count();
        if test.p() > level {
            break;
        }
    }
    test
}

/// The permutation test of the position labels for an orientation-dependent candidate:
/// its profiled LORO error (`observed_cv_sse`) against the same with the runs' (position,
/// input rate) labels permuted over the runs, the model's other terms unchanged.
/// A relabelling whose fit fails counts against the observed labels.
pub(super) fn position_permutation(
    ctx: &StepContext<'_>,
    grid: &EffectGrid,
    observed_cv_sse: f64,
    level: f64,
) -> PermutationTest {
    let labels = run_labels(ctx.prep);
    let statistic = |order: &[usize]| -> f64 {
        let relabelled: Vec<RunLabel<'_>> = order.iter().map(|&r| labels[r]).collect();
        let permuted = relabelled_grid(ctx, grid, &relabelled);
        // A relabelling whose fit fails is not evidence for the observed labels: NaN, counted
        // against them, rather than failing the whole diagnosis.
        profile_candidate(ctx.prep, &ctx.base_parts, &permuted, ctx.ys, ctx.n_eff)
            .map_or(f64::NAN, |p| total_cv(&p))
    };
    let seed = PERMUTATION_SEED ^ ((ctx.in_model.len() as u64) << 32);
    permutation_p(labels.len(), observed_cv_sse, level, draws_for(level), seed, statistic)
}

/// `grid` with every point's columns built from `labels` instead of the runs' own.
fn relabelled_grid(ctx: &StepContext<'_>, grid: &EffectGrid, labels: &[RunLabel<'_>]) -> EffectGrid {
    EffectGrid {
        effect: grid.effect,
        params: grid.params.clone(),
        points: grid
            .points
            .iter()
            .map(|p| orientation_columns(ctx.prep, grid.effect, &p.theta, labels))
            .collect(),
        unmet_requirement: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exact one-sided p of a difference in means by full enumeration of the `k`-subsets
    /// (the oracle of the Monte Carlo p).
    fn exact_mean_difference_p(values: &[f64], k: usize) -> f64 {
        let n = values.len();
        let total: f64 = values.iter().sum();
        let stat = |mask: u32| {
            let a: f64 = (0..n).filter(|i| mask & (1 << i) != 0).map(|i| values[i]).sum();
            -(a / k as f64 - (total - a) / (n - k) as f64)
        };
        let observed = stat((1u32 << k) - 1);
        let masks: Vec<u32> = (0u32..1 << n).filter(|m| m.count_ones() as usize == k).collect();
        let as_good = masks.iter().filter(|&&m| stat(m) <= observed + TIE_TOLERANCE * observed.abs()).count();
        as_good as f64 / masks.len() as f64
    }

    fn mean_difference(values: &[f64], k: usize) -> impl Fn(&[usize]) -> f64 + Sync + '_ {
        move |order: &[usize]| {
            // The first k places carry the first group's label; run order[i] gets the label of place i.
            let a: f64 = order.iter().take(k).map(|&r| values[r]).sum::<f64>() / k as f64;
            let b: f64 = order.iter().skip(k).map(|&r| values[r]).sum::<f64>() / (values.len() - k) as f64;
            -(a - b)
        }
    }

    #[test]
    fn monte_carlo_p_agrees_with_full_enumeration() {
        // 12 runs, the first 5 labelled "up"; a shift of the first group by 0.8 (exact p small)
        // and one of 0.1 (exact p large). The Monte Carlo p has binomial SD
        // sqrt(p (1 - p) / planned); tolerance 4 SD + 1 / planned.
        let base = [0.3, -1.2, 0.7, 0.1, -0.4, 1.1, -0.8, 0.2, -0.3, 0.9, -1.0, 0.4];
        for shift in [0.8, 0.1] {
            let values: Vec<f64> =
                base.iter().enumerate().map(|(i, v)| v + if i < 5 { shift } else { 0.0 }).collect();
            let exact = exact_mean_difference_p(&values, 5);
            let stat = mean_difference(&values, 5);
            let observed = stat(&(0..12).collect::<Vec<_>>());
            let test = permutation_p(12, observed, 1.0, 2000, 7, &stat);
            assert!(test.complete());
            let sd = (exact * (1.0 - exact) / test.planned as f64).sqrt();
            assert!(
                (test.p() - exact).abs() <= 4.0 * sd + 1.0 / test.planned as f64,
                "shift {shift}: Monte Carlo {} vs exact {exact}",
                test.p()
            );
        }
    }

    #[test]
    fn the_test_stops_once_its_p_cannot_reach_the_level_and_runs_to_the_end_otherwise() {
        let values = [0.3, -1.2, 0.7, 0.1, -0.4, 1.1, -0.8, 0.2, -0.3, 0.9, -1.0, 0.4, 0.6, -0.2, -0.7, 0.5];
        let stat = mean_difference(&values, 5);
        let observed = stat(&(0..16).collect::<Vec<_>>());
        let level = 0.003;
        let stopped = permutation_p(16, observed, level, draws_for(level), 7, &stat);
        assert!(!stopped.complete(), "{stopped:?}");
        assert_eq!(stopped.evaluated, CHUNK);
        assert!(stopped.p() > level);
        // A shift no relabelling matches: every planned draw is evaluated, p = 1 / (1 + planned).
        let shifted: Vec<f64> =
            values.iter().enumerate().map(|(i, v)| v + if i < 5 { 10.0 } else { 0.0 }).collect();
        let stat = mean_difference(&shifted, 5);
        let observed = stat(&(0..16).collect::<Vec<_>>());
        let full = permutation_p(16, observed, level, draws_for(level), 7, &stat);
        assert!(full.complete());
        // Only relabellings that keep the same five runs together are as good: 1 in
        // C(16, 5) = 4368, expected 0.3 in the 1333 draws.
        assert!(full.as_good <= 3, "{full:?}");
        assert!(full.p() <= level, "{full:?}");
        assert_eq!(full.planned, draws_for(level));
    }

    #[test]
    fn with_eight_runs_in_two_positions_the_smallest_p_is_two_in_seventy() {
        // A huge shift: only the observed labelling and its mirror image (for a statistic
        // symmetric in the two groups) are as good; every draw is evaluated at level 1.
        let values: Vec<f64> = (0..8).map(|i| if i < 4 { 100.0 + i as f64 } else { i as f64 }).collect();
        let stat = |order: &[usize]| -> f64 {
            let a: f64 = order.iter().take(4).map(|&r| values[r]).sum::<f64>() / 4.0;
            let b: f64 = order.iter().skip(4).map(|&r| values[r]).sum::<f64>() / 4.0;
            -(a - b).abs()
        };
        let observed = stat(&(0..8).collect::<Vec<_>>());
        let test = permutation_p(8, observed, 1.0, 3000, 11, stat);
        let share = test.as_good as f64 / test.planned as f64;
        let sd = (2.0 / 70.0 * (68.0 / 70.0) / test.planned as f64).sqrt();
        assert!((share - 2.0 / 70.0).abs() <= 4.0 * sd, "{share}");
        // At the run-level rules' level for 8 candidates (0.05 / 16) it stops in the first chunk.
        let stopped = permutation_p(8, observed, 0.05 / 16.0, draws_for(0.05 / 16.0), 11, stat);
        assert!(!stopped.complete() && stopped.p() > 0.05 / 16.0, "{stopped:?}");
    }

    #[test]
    fn a_statistic_that_is_not_a_number_never_makes_the_observed_one_significant() {
        let nan = |_: &[usize]| -> f64 { f64::NAN };
        let t = permutation_p(10, f64::NAN, 0.01, 399, 3, nan);
        assert_eq!((t.p(), t.evaluated), (1.0, 0));
        // Every relabelling NaN: each counts as good, the test stops after the first chunk.
        let t = permutation_p(10, 1.0, 0.01, 399, 3, nan);
        assert_eq!(t.as_good, CHUNK);
        assert!(t.p() > 0.01);
    }

    #[test]
    fn draws_for_lets_three_relabellings_tie_at_the_level() {
        for level in [0.05, 0.01, 0.003125, 0.001] {
            let n = draws_for(level);
            assert!(4.0 / (1 + n) as f64 <= level + 1e-15, "{level}: {n}");
            assert!(4.0 / n as f64 > level || n == 99, "{level}: {n}");
        }
        assert_eq!(draws_for(f64::NAN), 99);
    }
}
