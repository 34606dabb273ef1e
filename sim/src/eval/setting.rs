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

/// The crease split from its text form (`sim eval --crease-split`): `on`
/// (`CreaseConfig`'s defaults), `off` (the planner's default), `split-only` (the defaults without step 6, parts
/// hanging on another joining it), or
/// `SMOOTH_PX:BASELINE_PX:VALLEY_MM:RATIO:MIN_PART` (the fields of
/// [`CreaseConfig`], the valley in millimetres; step 6 with its defaults),
/// followed by `:AREA_CM2:SHARE:OUTLINE:STEP_MM` for step 6 ([`Reattach`]'s
/// fields; an area of 0 turns it off).
pub fn crease_setting(text: &str) -> Result<Option<CreaseConfig>> {
    let bad = |reason: String| Error::Invalid {
        field: "crease-split",
        reason,
    };
    match text {
        "on" => return Ok(Some(CreaseConfig::default())),
        "off" => return Ok(None),
        "split-only" => {
            return Ok(Some(CreaseConfig {
                reattach: None,
                ..CreaseConfig::default()
            }));
        }
        _ => {}
    }
    let usage = || {
        bad(format!(
            "{text:?} is not on, off, split-only, SMOOTH_PX:BASELINE_PX:VALLEY_MM:RATIO:MIN_PART \
             or that followed by :AREA_CM2:SHARE:OUTLINE:STEP_MM"
        ))
    };
    let fields: Vec<&str> = text.split(':').collect();
    let (split, attach) = fields.split_at(fields.len().min(5));
    let [smooth, baseline, valley_mm, ratio, min_part] = split[..] else {
        return Err(usage());
    };
    let number = |name: &str, v: &str| -> Result<f64> {
        v.parse::<f64>()
            .ok()
            .filter(|x| x.is_finite() && *x >= 0.0)
            .ok_or_else(|| bad(format!("{text:?}: {name} {v:?} is not a number >= 0")))
    };
    let whole = |name: &str, v: &str| -> Result<usize> {
        v.parse::<usize>()
            .map_err(|e| bad(format!("{text:?}: {name} {v:?}: {e}")))
    };
    let config = CreaseConfig {
        smooth_radius_px: whole("smoothing radius", smooth)?,
        baseline_px: whole("baseline", baseline)?,
        min_valley_m: (number("valley depth", valley_mm)? / 1000.0) as f32,
        min_valley_ratio: number("ratio", ratio)? as f32,
        min_part_points: whole("smallest part", min_part)?,
        reattach: match attach {
            [] => Some(Reattach::default()),
            [area_cm2, share, outline, step_mm] => Some(Reattach {
                max_area_m2: (number("area", area_cm2)? / 1e4) as f32,
                max_share: number("share", share)? as f32,
                min_outline_share: number("outline share", outline)? as f32,
                max_step_m: (number("step", step_mm)? / 1000.0) as f32,
            })
            .filter(|r| r.max_area_m2 > 0.0),
            _ => return Err(usage()),
        },
    };
    if config.baseline_px == 0 {
        return Err(bad(format!("{text:?}: the baseline must be at least 1 px")));
    }
    Ok(Some(config))
}

/// The text form of a crease split, as [`crease_setting`] reads it back
/// (recorded in a dataset's manifest: the segmentation made its views).
pub fn crease_text(crease: Option<&CreaseConfig>) -> String {
    let Some(c) = crease else {
        return "off".into();
    };
    let split = format!(
        "{}:{}:{}:{}:{}",
        c.smooth_radius_px,
        c.baseline_px,
        c.min_valley_m * 1000.0,
        c.min_valley_ratio,
        c.min_part_points
    );
    match &c.reattach {
        None => format!("{split}:0:0:0:0"),
        Some(r) => format!(
            "{split}:{}:{}:{}:{}",
            r.max_area_m2 * 1e4,
            r.max_share,
            r.min_outline_share,
            r.max_step_m * 1000.0
        ),
    }
}
