//! The settings of a run: view policy, tau and the planner knobs a setting names, and their text forms.

use super::*;

/// One planner setting under test.
#[derive(Debug, Clone, PartialEq)]
pub struct Setting {
    /// Which views the network sees.
    pub policy: ViewPolicy,
    /// Grasps under this quality are not tried.
    pub tau: f32,
}

impl Setting {
    /// `entropy:0.8`, `all:0.9`, `top-down:0.8`, `random:0.8`.
    pub fn parse(text: &str) -> Result<Self> {
        let bad = |reason: String| Error::Invalid {
            field: "setting",
            reason,
        };
        let (policy, tau) = text
            .split_once(':')
            .ok_or_else(|| bad(format!("{text:?} is not POLICY:TAU")))?;
        let tau: f32 = tau
            .parse()
            .map_err(|e| bad(format!("{text:?}: tau {tau:?}: {e}")))?;
        if !(0.0..=1.0).contains(&tau) {
            return Err(bad(format!("{text:?}: tau {tau} is outside [0, 1]")));
        }
        let policy = match policy {
            "entropy" => ViewPolicy::Entropy,
            "all" => ViewPolicy::All,
            "top-down" => ViewPolicy::TopDown,
            "random" => ViewPolicy::Random { seed: 0 },
            other => {
                return Err(bad(format!(
                    "{other:?} is not a view policy (entropy, all, top-down, random)"
                )));
            }
        };
        Ok(Self { policy, tau })
    }

    /// The name [`Self::parse`] reads.
    pub fn name(&self) -> String {
        let policy = match self.policy {
            ViewPolicy::Entropy => "entropy",
            ViewPolicy::All => "all",
            ViewPolicy::TopDown => "top-down",
            ViewPolicy::Random { .. } => "random",
        };
        format!("{policy}:{}", self.tau)
    }
}

/// The planner's squaring limit (`sim eval --square-turn-deg`, degrees):
/// how far a grasp may be turned about its approach to square it to the
/// surfaces its pads meet ([`mvgrasp_core::decode::HandConfig::square_turn_deg`]);
/// 0 turns squaring off. Refused outside 0-90 degrees (a quarter turn
/// already swaps the faces the pads meet) or when not a number.
pub fn square_turn_setting(deg: f64) -> Result<f64> {
    if (0.0..=90.0).contains(&deg) {
        Ok(deg)
    } else {
        Err(Error::Invalid {
            field: "square-turn-deg",
            reason: format!("{deg} is not within 0-90 degrees"),
        })
    }
}

/// The crease split from its text form (`sim eval --crease-split`): `off`
/// (the planner's default), `on` (`CreaseConfig`'s defaults, as
/// `[segment] crease_split = true` in the server's settings) or
/// `split-only` (the defaults without step 6, parts hanging on another
/// joining it). Other thresholds are `CreaseConfig`'s fields, for code.
pub fn crease_setting(text: &str) -> Result<Option<CreaseConfig>> {
    match text {
        "on" => Ok(Some(CreaseConfig::default())),
        "off" => Ok(None),
        "split-only" => Ok(Some(split_only())),
        _ => Err(Error::Invalid {
            field: "crease-split",
            reason: format!("{text:?} is not on, off or split-only"),
        }),
    }
}

fn split_only() -> CreaseConfig {
    CreaseConfig {
        reattach: None,
        ..CreaseConfig::default()
    }
}

/// The text form of a crease split, as [`crease_setting`] reads it back
/// (recorded in a dataset's manifest: the segmentation made its views); a
/// split with other thresholds than those is written out field by field.
pub fn crease_text(crease: Option<&CreaseConfig>) -> String {
    match crease {
        None => "off".into(),
        Some(c) if *c == CreaseConfig::default() => "on".into(),
        Some(c) if *c == split_only() => "split-only".into(),
        Some(c) => format!("{c:?}"),
    }
}
