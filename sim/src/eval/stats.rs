//! Per-setting summaries and the episode bootstrap.

use super::*;

/// Episodes of one scenario under one setting, summed.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The scenario.
    pub scenario: Scenario,
    /// The setting's name.
    pub setting: String,
    /// Episodes.
    pub episodes: usize,
    /// Objects on the tables at the start.
    pub objects: usize,
    /// Objects removed.
    pub removed: usize,
    /// Objects that fell off the table while piles settled.
    pub fell_off: usize,
    /// Attempts.
    pub attempts: usize,
    /// Successful attempts.
    pub successes: usize,
    /// Failed attempts by cause, in [`Failure::ALL`] order.
    pub failures: [usize; 4],
    /// Collisions on approach by where they happened.
    pub collisions: BTreeMap<CollisionSite, usize>,
    /// Episodes that ended with no grasp above tau.
    pub ended_without_grasp: usize,
    /// Episodes that cleared the table.
    pub cleared: usize,
    /// Planning time percentiles (ms): 50th, 90th.
    pub plan_ms: [f64; 2],
    /// 95% interval of the success rate, resampling whole episodes
    /// ([`episode_bootstrap`]; NaN without attempts).
    pub success_ci95: [f64; 2],
    /// 95% interval of the removal rate, resampling whole episodes.
    pub removal_ci95: [f64; 2],
}

/// Resamples drawn by [`episode_bootstrap`].
pub const BOOTSTRAP_RESAMPLES: usize = 2000;

/// The 2.5th and 97.5th percentiles of `sum(numerator) / sum(denominator)`
/// over [`BOOTSTRAP_RESAMPLES`] resamples, with replacement, of the
/// episodes' `(numerator, denominator)` pairs: a percentile bootstrap over
/// episodes, since the attempts and objects of one episode are not
/// independent of each other. Seeded, so a report is reproducible;
/// resamples with a zero denominator are left out; NaN when none is left.
pub fn episode_bootstrap(pairs: &[(usize, usize)]) -> [f64; 2] {
    let mut rng = SplitMix64::new(0xB007_57A9);
    let mut rates = Vec::with_capacity(BOOTSTRAP_RESAMPLES);
    if !pairs.is_empty() {
        for _ in 0..BOOTSTRAP_RESAMPLES {
            let (mut num, mut den) = (0usize, 0usize);
            for _ in 0..pairs.len() {
                let (n, d) = pairs[rng.below(pairs.len())];
                num += n;
                den += d;
            }
            if den > 0 {
                rates.push(num as f64 / den as f64);
            }
        }
    }
    if rates.is_empty() {
        return [f64::NAN; 2];
    }
    rates.sort_by(f64::total_cmp);
    let at = |p: f64| rates[((rates.len() - 1) as f64 * p).round() as usize];
    [at(0.025), at(0.975)]
}

impl Summary {
    /// Sums `episodes` (all of one scenario and setting).
    pub fn of(scenario: Scenario, setting: &Setting, episodes: &[Episode]) -> Self {
        let mut failures = [0; 4];
        let mut collisions = BTreeMap::new();
        let mut times: Vec<f64> = Vec::new();
        for e in episodes {
            for a in &e.attempts {
                times.push(a.plan_ms);
                if let Some(site) = a.collision {
                    *collisions.entry(site).or_insert(0) += 1;
                }
                if let Some(f) = a.failure {
                    failures[Failure::ALL.iter().position(|&x| x == f).unwrap_or(0)] += 1;
                }
            }
            times.extend(e.last_plan_ms);
        }
        times.sort_by(f64::total_cmp);
        let pct = |p: f64| {
            if times.is_empty() {
                f64::NAN
            } else {
                times[((times.len() - 1) as f64 * p).round() as usize]
            }
        };
        Self {
            scenario,
            setting: setting.name(),
            episodes: episodes.len(),
            objects: episodes.iter().map(|e| e.objects).sum(),
            removed: episodes.iter().map(|e| e.removed).sum(),
            fell_off: episodes.iter().map(|e| e.fell_off).sum(),
            attempts: episodes.iter().map(|e| e.attempts.len()).sum(),
            successes: episodes.iter().map(Episode::successes).sum(),
            failures,
            collisions,
            ended_without_grasp: episodes.iter().filter(|e| e.end == End::NoGraspAboveTau).count(),
            cleared: episodes.iter().filter(|e| e.end == End::Cleared).count(),
            plan_ms: [pct(0.5), pct(0.9)],
            success_ci95: episode_bootstrap(
                &episodes
                    .iter()
                    .map(|e| (e.successes(), e.attempts.len()))
                    .collect::<Vec<_>>(),
            ),
            removal_ci95: episode_bootstrap(
                &episodes
                    .iter()
                    .map(|e| (e.removed, e.objects))
                    .collect::<Vec<_>>(),
            ),
        }
    }

    /// Successful attempts over attempts (NaN without attempts).
    pub fn success_rate(&self) -> f64 {
        self.successes as f64 / self.attempts as f64
    }

    /// Objects removed over objects at the start.
    pub fn removal_rate(&self) -> f64 {
        self.removed as f64 / self.objects as f64
    }
}
