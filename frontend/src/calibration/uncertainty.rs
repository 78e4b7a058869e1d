//! Uncertainty from the data alone: a block jackknife over the windows,
//! and block votes for the discrete choices.
//!
//! The windows are cut into `B` blocks of consecutive windows (block `b`
//! holds windows `⌊b·n/B⌋ .. ⌊(b+1)·n/B⌋`). Neighbouring windows share
//! rotations, so single windows are far from independent; blocks of
//! several windows are nearly so, which is what the jackknife needs.
//!
//! - **Continuous values.** The estimate `θ̂₍b₎` is found again without
//!   block `b` (from the full estimate, by the same local method). The
//!   jackknife standard deviation is
//!   `σ = √((B−1)/B · Σ_b (θ̂₍b₎ − θ̄)²)`, `θ̄` the mean of the `θ̂₍b₎`
//!   (Efron & Stein 1981; Künsch 1989 for blocks).
//! - **Choices** (a discrete value, or an estimate against the mission's
//!   value). Block `b` scores both on its windows alone; `d_b` is the
//!   loser's objective minus the winner's (for several losers, the best
//!   of them). If the data could not tell the two apart, each `d_b` would
//!   be as likely negative as positive. The choice counts as determined
//!   when Wilcoxon's signed-rank statistic (the sum of the ranks of `|d_b|`
//!   over the blocks with `d_b > 0`) is so large that chance would reach it
//!   with probability at most [`VOTE_SIGNIFICANCE`], exactly, by the
//!   statistic's distribution under that null. Unlike counting the blocks
//!   that agree, it weighs each block by how strongly it prefers the
//!   winner, so blocks that carry no information (a straight leg, where a
//!   lever arm changes nothing) do not outvote those that do. With `B`
//!   blocks the smallest probability is `2^−B`: six blocks at least.

use serde::Serialize;
use std::ops::Range;

/// The significance level of the signed-rank test on the blocks' scores:
/// a calibration tests up to four choices at once (angle, sweep, yaw,
/// lever arm), and a wrong mounting taken for a right one fails a whole
/// run, so each is held to 2% (8% for the four together at most).
pub const VOTE_SIGNIFICANCE: f64 = 0.02;

/// The windows cut into blocks of consecutive windows.
#[derive(Clone, Debug, PartialEq)]
pub struct Blocks {
    windows: usize,
    blocks: Vec<Range<usize>>,
}

impl Blocks {
    /// `wanted` blocks over `windows` windows, or one block per window
    /// when there are fewer windows.
    pub fn new(windows: usize, wanted: usize) -> Self {
        let b = wanted.min(windows).max(1);
        let blocks = (0..b)
            .map(|k| k * windows / b..(k + 1) * windows / b)
            .collect();
        Self { windows, blocks }
    }

    /// Number of blocks.
    pub fn len(&self) -> usize {
        self.blocks.len()
    }

    /// True when there is no window.
    pub fn is_empty(&self) -> bool {
        self.windows == 0
    }

    /// Every window.
    pub fn all(&self) -> Vec<usize> {
        (0..self.windows).collect()
    }

    /// The windows of block `b`.
    pub fn only(&self, b: usize) -> Vec<usize> {
        self.blocks.get(b).cloned().unwrap_or(0..0).collect()
    }

    /// Every window but those of block `b`.
    pub fn without(&self, b: usize) -> Vec<usize> {
        let left_out = self.blocks.get(b).cloned().unwrap_or(0..0);
        (0..self.windows)
            .filter(|w| !left_out.contains(w))
            .collect()
    }
}

/// The jackknife standard deviation of leave-one-block-out estimates
/// (module doc); 0 for fewer than two.
pub fn jackknife_std(estimates: &[f64]) -> f64 {
    let b = estimates.len();
    if b < 2 {
        return 0.0;
    }
    let mean = estimates.iter().sum::<f64>() / b as f64;
    let sum_sq: f64 = estimates.iter().map(|e| (e - mean).powi(2)).sum();
    ((b as f64 - 1.0) / b as f64 * sum_sq).sqrt()
}

/// [`jackknife_std`] of angles, radians: each taken on the branch nearest
/// `centre_rad` first.
pub fn jackknife_std_angle(estimates_rad: &[f64], centre_rad: f64) -> f64 {
    let unwrapped: Vec<f64> = estimates_rad
        .iter()
        .map(|a| echofield_graph::wrap_angle(a - centre_rad))
        .collect();
    jackknife_std(&unwrapped)
}

/// `P(W⁺ ≥ w)` for Wilcoxon's signed-rank statistic of `differences`
/// under the null of signs equally likely (module doc), exactly; zero
/// differences are left out, tied magnitudes share their mean rank. 1 when
/// no difference is left.
pub fn signed_rank_p_value(differences: &[f64]) -> f64 {
    let mut magnitudes: Vec<(f64, bool)> = differences
        .iter()
        .filter(|d| **d != 0.0 && d.is_finite())
        .map(|d| (d.abs(), *d > 0.0))
        .collect();
    let n = magnitudes.len();
    if n == 0 {
        return 1.0;
    }
    magnitudes.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Twice the ranks, so that mean ranks of ties stay integers.
    let mut doubled = vec![0usize; n];
    let mut i = 0;
    while i < n {
        let j = i + magnitudes[i..]
            .iter()
            .take_while(|m| m.0 == magnitudes[i].0)
            .count();
        doubled[i..j].fill(i + j + 1); // 2 · mean of ranks i+1 ..= j
        i = j;
    }
    let observed: usize = (0..n)
        .filter(|&k| magnitudes[k].1)
        .map(|k| doubled[k])
        .sum();
    // counts[s]: sign patterns whose positive doubled ranks sum to s.
    let total: usize = doubled.iter().sum();
    let mut counts = vec![0f64; total + 1];
    counts[0] = 1.0;
    for &r in &doubled {
        for s in (r..=total).rev() {
            counts[s] += counts[s - r];
        }
    }
    counts[observed..].iter().sum::<f64>() / 2f64.powi(n as i32)
}

/// The blocks' vote on a choice (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Vote {
    /// The loser's objective minus the winner's over all windows, bits
    /// (positive when the winner is sharper).
    pub gap_bits: f64,
    /// Blocks whose windows alone prefer the winner.
    pub agreeing_blocks: usize,
    pub blocks: usize,
    /// The signed-rank test's probability that chance favours the winner
    /// this much.
    pub p_value: f64,
    /// `p_value ≤` [`VOTE_SIGNIFICANCE`].
    pub determined: bool,
}

/// The vote of the blocks for the winner, given each block's objective of
/// the winner (`winner[b]`) and of every loser (`losers[c][b]`), and the
/// gap over all windows.
pub fn vote(winner: &[f64], losers: &[Vec<f64>], gap_bits: f64) -> Vote {
    let differences: Vec<f64> = (0..winner.len())
        .map(|b| {
            let best_loser = losers.iter().map(|l| l[b]).fold(f64::INFINITY, f64::min);
            best_loser - winner[b]
        })
        .collect();
    let p_value = signed_rank_p_value(&differences);
    Vote {
        gap_bits,
        agreeing_blocks: differences.iter().filter(|d| **d > 0.0).count(),
        blocks: winner.len(),
        p_value,
        determined: p_value <= VOTE_SIGNIFICANCE,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_cover_every_window_once() {
        let blocks = Blocks::new(23, 10);
        assert_eq!(blocks.len(), 10);
        let mut seen: Vec<usize> = (0..10).flat_map(|b| blocks.only(b)).collect();
        seen.sort_unstable();
        assert_eq!(seen, blocks.all());
        assert_eq!(blocks.without(3).len() + blocks.only(3).len(), 23);
        assert_eq!(Blocks::new(3, 10).len(), 3);
    }

    #[test]
    fn the_jackknife_of_a_mean_is_its_standard_error() {
        // Leave-one-out means of x: the jackknife gives std(x)/√n exactly.
        let x = [1.0, 4.0, 2.0, 8.0, 5.0, 7.0];
        let n = x.len() as f64;
        let sum: f64 = x.iter().sum();
        let loo: Vec<f64> = x.iter().map(|v| (sum - v) / (n - 1.0)).collect();
        let mean = sum / n;
        let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        assert!((jackknife_std(&loo) - (var / n).sqrt()).abs() < 1e-12);
        // Angles either side of ±π are near each other.
        let a = jackknife_std_angle(&[3.1, -3.1], std::f64::consts::PI);
        assert!(a < 0.1, "{a}");
    }

    #[test]
    fn the_signed_rank_test_has_its_exact_distribution() {
        // All of n blocks positive: 2^−n.
        assert_eq!(signed_rank_p_value(&[1.0; 6]), 1.0 / 64.0);
        assert_eq!(signed_rank_p_value(&[3.0, 1.0, 2.0, 4.0, 5.0]), 1.0 / 32.0);
        // Only the smallest negative: W⁺ = 2+3+4+5 = 14 of 15; P(W⁺ ≥ 14)
        // = 2/32 (the patterns missing rank 1 and none).
        assert_eq!(signed_rank_p_value(&[-1.0, 2.0, 3.0, 4.0, 5.0]), 2.0 / 32.0);
        // Symmetric: P(W⁺ ≥ 0) = 1; zeros are left out.
        assert_eq!(signed_rank_p_value(&[-1.0, -2.0, 0.0]), 1.0);
        assert_eq!(signed_rank_p_value(&[]), 1.0);
        // Ties share their mean rank: 1.5 and 1.5, both positive.
        assert_eq!(signed_rank_p_value(&[2.0, 2.0]), 0.25);
    }

    #[test]
    fn strong_blocks_outweigh_blocks_that_cannot_tell() {
        // Seven blocks prefer the winner by a lot, three differ by noise
        // (one of them the winner's way): a sign test would call 8 of 10
        // chance; the ranks do not.
        let winner = [1.0; 10];
        let loser = vec![vec![
            2.0, 2.1, 1.9, 1.0001, 2.2, 0.9999, 2.05, 1.95, 0.99995, 2.3,
        ]];
        let v = vote(&winner, &loser, 0.7);
        assert_eq!((v.agreeing_blocks, v.blocks), (8, 10));
        assert!(v.determined && v.p_value < 0.01, "{v:?}");
        let noise = vec![vec![
            1.01, 0.99, 1.02, 0.98, 1.0, 1.03, 0.97, 1.01, 0.99, 1.0,
        ]];
        assert!(!vote(&winner, &noise, 0.0).determined);
    }
}
