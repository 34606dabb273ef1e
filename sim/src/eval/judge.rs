//! How often the approach check and physics agree, tallied per setting.

use super::*;

/// One model's best grasps tried on frames it did not choose
/// (`sim eval --judge`): frames seen, frames without a grasp above tau,
/// frames whose planning failed, and the grasps tried by outcome.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct JudgeTally {
    /// Frames judged.
    pub frames: usize,
    /// Frames where it offered no grasp at tau.
    pub no_grasp: usize,
    /// Frames its planning failed on.
    pub errors: usize,
    /// Grasps held (carried to the basket).
    pub held: usize,
    /// Grasps failed, per [`Failure::ALL`].
    pub failures: [usize; 4],
}

impl JudgeTally {
    /// Counts one frame: `None` for a planning error, `Some(None)` for no
    /// grasp, `Some(Some(outcome))` for a grasp tried.
    pub fn add(&mut self, frame: Option<Option<Option<Failure>>>) {
        self.frames += 1;
        match frame {
            None => self.errors += 1,
            Some(None) => self.no_grasp += 1,
            Some(Some(None)) => self.held += 1,
            Some(Some(Some(f))) => {
                if let Some(k) = Failure::ALL.iter().position(|&g| g == f) {
                    self.failures[k] += 1;
                }
            }
        }
    }

    /// The name of one judged frame's outcome, as [`Self::add`] takes it:
    /// "planning error", "no grasp", "held" or the failure's name.
    pub fn outcome_name(frame: Option<Option<Option<Failure>>>) -> &'static str {
        match frame {
            None => "planning error",
            Some(None) => "no grasp",
            Some(Some(None)) => "held",
            Some(Some(Some(f))) => f.name(),
        }
    }

    /// Adds another tally's counts.
    pub fn merge(&mut self, other: &JudgeTally) {
        self.frames += other.frames;
        self.no_grasp += other.no_grasp;
        self.errors += other.errors;
        self.held += other.held;
        for (a, b) in self.failures.iter_mut().zip(other.failures) {
            *a += b;
        }
    }

    /// Grasps tried.
    pub fn tried(&self) -> usize {
        self.held + self.failures.iter().sum::<usize>()
    }
}

/// The `--judge` table: per scenario (or "all"; in `rows`' order) and model, the
/// frames, grasps tried and held, held per frame and per grasp tried, and
/// the failures by cause. Empty without rows.
pub fn judge_table(rows: &[(String, String, JudgeTally)]) -> String {
    if rows.is_empty() {
        return String::new();
    }
    let mut out = String::from(
        "| scenario | model | frames | no grasp > tau | tried | held | held / frames | held / tried | failures |\n|---|---|---:|---:|---:|---:|---:|---:|---|\n",
    );
    for (scenario, model, t) in rows {
        let failures: Vec<String> = Failure::ALL
            .iter()
            .zip(t.failures)
            .filter(|(_, n)| *n > 0)
            .map(|(f, n)| format!("{} {n}", f.name()))
            .collect();
        let errors = if t.errors > 0 {
            format!(" ({} planning errors)", t.errors)
        } else {
            String::new()
        };
        out.push_str(&format!(
            "| {scenario} | {model} | {}{errors} | {} | {} | {} | {} | {} | {} |\n",
            t.frames,
            t.no_grasp,
            t.tried(),
            t.held,
            share(t.held, t.frames),
            share(t.held, t.tried()),
            if failures.is_empty() {
                "-".to_owned()
            } else {
                failures.join(", ")
            }
        ));
    }
    out
}
