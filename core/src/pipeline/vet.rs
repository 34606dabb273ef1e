//! The hand check of one answer's grasps, in rank order.

use super::plan::{ObjectRefusals, RankedLast};

use nalgebra::{Isometry3, Vector3};
use rustc_hash::FxHashMap;

use crate::decode::{
    Collision, Grasp, HandConfig, Obstacle, Repairs, Verdict, contact_slopes, deepen, deepen_to_middle,
    fit_opening, hand_collision, hand_out_of_view, squaring_turn, turn_away,
};
use crate::gripper::Gripper;
use crate::segment::TablePlane;
use crate::sensor::FieldOfView;
use crate::view::ViewAxis;

/// What the hand check of one answer's grasps looks at ([`check`]).
pub(super) struct Vetting<'a> {
    pub(super) hand: &'a HandConfig,
    pub(super) gripper: &'a Gripper,
    pub(super) table: &'a TablePlane,
    pub(super) obstacles: &'a [Obstacle<'a>],
    /// The camera's field of view (depth frames).
    pub(super) view: Option<&'a FieldOfView>,
    pub(super) table_clearance_m: f64,
}

/// What the hand check said of one grasp: the verdict, and what it counts
/// (the cause of a refusal, a grasp squared to its surfaces).
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Checked {
    pub(super) verdict: Verdict<RankedLast>,
    refused_for: Option<Collision>,
    squared: bool,
}

impl Checked {
    /// Counts a refusal's cause in `per_object[own]` and a squared grasp in
    /// `turned_square`.
    pub(super) fn count(
        &self,
        own: Option<usize>,
        per_object: &mut [ObjectRefusals],
        turned_square: &mut usize,
    ) {
        if let (Some(c), Some(mine)) = (self.refused_for, own.and_then(|i| per_object.get_mut(i))) {
            match c {
                Collision::Table => mine.table += 1,
                Collision::Object(i) if Some(i) == own => mine.own_points += 1,
                Collision::Object(_) => mine.neighbour += 1,
            }
        }
        *turned_square += usize::from(self.squared);
    }
}

/// The hand check's answers so far in one call, by grasp. The view
/// cascade's cover check and the final ranking meet the same candidates,
/// and the check depends on nothing else that changes between them (the
/// objects, the table and the gripper are the call's): each candidate is
/// checked once.
#[derive(Default)]
pub(super) struct Verdicts(FxHashMap<WhereFrom, Vec<(Grasp, Checked)>>);

/// Where a candidate came from: its object, view and pixel.
type WhereFrom = (u32, ViewAxis, [u32; 2]);

impl Verdicts {
    /// [`check`] of `g`, or what it said of an equal grasp before.
    pub(super) fn check(&mut self, g: Grasp, own: Option<usize>, v: &Vetting<'_>) -> Checked {
        let seen = self.0.entry((g.object_id, g.view, g.pixel)).or_default();
        if let Some((_, checked)) = seen.iter().find(|(earlier, _)| *earlier == g) {
            return checked.clone();
        }
        let checked = check(g.clone(), own, v);
        seen.push((g, checked.clone()));
        checked
    }

    /// How many grasps were checked.
    #[cfg(test)]
    fn len(&self) -> usize {
        self.0.values().map(Vec::len).sum()
    }
}

/// One grasp through the hand check, in rank order: accepted as planned or
/// repaired (opening re-fitted, squared, deepened), deferred (turned away
/// from what it would hit, or pads out of view), or refused, with its
/// cause. `own`: the grasp's object among `v.obstacles`.
pub(super) fn check(g: Grasp, own: Option<usize>, v: &Vetting<'_>) -> Checked {
    let hand = v.hand;
    let hit = |pose: &Isometry3<f64>, width: f64| {
        hand_collision(pose, width, v.gripper, hand, v.table, v.obstacles, own)
    };
    let refuse = |c: Collision| Checked {
        verdict: Verdict::Refuse,
        refused_for: Some(c),
        squared: false,
    };
    // The check as planned: passed (no new pose), or what the
    // hand hits. Pads on its own object: open to what was seen
    // of it, and check again.
    let checked = match hit(&g.world_from_grasp, g.width_m) {
        None => Ok(None),
        Some(first @ Collision::Object(i)) if hand.fit_opening && Some(i) == own => {
            match fit_opening(&g.world_from_grasp, g.width_m, v.gripper, hand, &v.obstacles[i]) {
                None => Err(first),
                Some((pose, width)) => hit(&pose, width).map_or(Ok(Some((pose, width))), Err),
            }
        }
        Some(c) => Err(c),
    };
    // A hand that would hit a neighbour, or its own object at
    // every opening: turned about the approach if a turn passes,
    // ranked after the grasps as planned. Own-object turns
    // cleared 6 more of 308 train-pool objects
    // (docs/experiments/2026-11-28-ranking-and-candidates.md).
    let (repaired, turned_away) = match checked {
        Ok(repaired) => (repaired, false),
        Err(c) => {
            let turned = match c {
                Collision::Object(_) => own.and_then(|j| {
                    turn_away(
                        &g.world_from_grasp,
                        g.width_m,
                        v.gripper,
                        hand,
                        &v.obstacles[j],
                        |pose, width| hit(pose, width).is_none(),
                    )
                }),
                _ => None,
            };
            match turned {
                Some(turned) => (Some(turned), true),
                None => return refuse(c),
            }
        }
    };
    let mut g = match repaired {
        Some((world_from_grasp, width_m)) => Grasp {
            world_from_grasp,
            width_m,
            ..g
        },
        None => g,
    };
    g.repairs.turned_away = turned_away;
    g.repairs.refit = repaired.is_some() && !turned_away;
    // Square the grasp to the surfaces its pads would meet, as
    // seen, when the turned grasp passes the check too: of the
    // grasps tried in physics outside the labels' friction cone,
    // two in five were within 10 degrees of one inside
    // (sim/README.md).
    let turn = own.filter(|_| hand.enabled).and_then(|i| {
        let slopes = contact_slopes(&g.world_from_grasp, g.width_m, v.gripper, hand, &v.obstacles[i]);
        squaring_turn(slopes, hand)
    });
    let turned = turn
        .map(|t| g.world_from_grasp * nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), t))
        .filter(|pose| hit(pose, g.width_m).is_none());
    let squared = turned.is_some();
    let g = match turned {
        Some(world_from_grasp) => Grasp {
            world_from_grasp,
            repairs: Repairs {
                squared: true,
                ..g.repairs
            },
            ..g
        },
        None => g,
    };
    // Deeper where the hand and the table allow: fingertips
    // that stop above the middle of a round object let it slip.
    // Towards the middle of its height first, else a little.
    let deeper = hand.enabled.then(|| {
        let passes = |pose: &Isometry3<f64>| hit(pose, g.width_m).is_none();
        let to_middle = own.and_then(|i| {
            deepen_to_middle(
                &g.world_from_grasp,
                g.width_m,
                v.gripper,
                hand,
                v.table,
                v.table_clearance_m,
                &v.obstacles[i],
                passes,
            )
        });
        to_middle.or_else(|| {
            deepen(
                &g.world_from_grasp,
                g.width_m,
                v.gripper,
                hand,
                v.table,
                v.table_clearance_m,
                passes,
            )
        })
    });
    let mut g = match deeper.flatten() {
        Some(world_from_grasp) => Grasp {
            world_from_grasp,
            repairs: Repairs {
                deepened: true,
                ..g.repairs
            },
            ..g
        },
        None => g,
    };
    // Pads past the image border: maybe onto the part of the
    // object never seen. Tried last, not refused: the object may
    // have no other grasp.
    let unseen = v.view.is_some_and(|fov| {
        hand.enabled
            && hand.out_of_view_last
            && hand_out_of_view(&g.world_from_grasp, g.width_m, v.gripper, hand, fov)
    });
    g.repairs.out_of_view = unseen;
    let verdict = if unseen {
        Verdict::Defer(g, RankedLast::OutOfView)
    } else if turned_away {
        Verdict::Defer(g, RankedLast::TurnedAway)
    } else {
        Verdict::Accept(g)
    };
    Checked {
        verdict,
        refused_for: None,
        squared,
    }
}

/// World-frame approach direction of a grasp (its +z axis).
pub fn approach_of(grasp: &Grasp) -> Vector3<f64> {
    grasp.world_from_grasp.rotation * Vector3::z()
}

#[cfg(test)]
mod tests {
    use nalgebra::{Translation3, UnitQuaternion};

    use super::*;
    use crate::decode::DecodeConfig;

    /// Straight down onto `(x, y, z)`, closing along world x.
    fn top_down(pixel: u32, x: f64, z: f64) -> Grasp {
        let rotation = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
        Grasp {
            world_from_grasp: Isometry3::from_parts(Translation3::new(x, 0.0, z), rotation),
            width_m: 0.08,
            quality: 0.9,
            object_id: 1,
            view: ViewAxis::Top,
            pixel: [pixel, 0],
            angle_rad: 0.0,
            repairs: Default::default(),
        }
    }

    #[test]
    fn each_grasp_is_checked_once_and_its_causes_counted_each_time() {
        // A 4 cm cube of points (5 mm grid) on a table at z = 0.
        let mut points: Vec<[f32; 3]> = Vec::new();
        for i in 0..=8u8 {
            for j in 0..=8u8 {
                for k in 0..=8u8 {
                    let at = |n: u8| f32::from(n) * 0.005;
                    points.push([at(i) - 0.02, at(j) - 0.02, at(k)]);
                }
            }
        }
        let (lo, hi) = (Vector3::new(-0.02, -0.02, 0.0), Vector3::new(0.02, 0.02, 0.04));
        let identity = Isometry3::identity();
        let obstacles = [Obstacle {
            world_from_object: &identity,
            extent_min_m: &lo,
            extent_max_m: &hi,
            points: &points,
        }];
        let table = TablePlane {
            normal: Vector3::z(),
            offset_m: 0.0,
            support: 1.0,
        };
        let (hand, gripper) = (HandConfig::default(), Gripper::default());
        let v = Vetting {
            hand: &hand,
            gripper: &gripper,
            table: &table,
            obstacles: &obstacles,
            view: None,
            table_clearance_m: DecodeConfig::default().table_clearance_m,
        };
        let across = top_down(0, 0.0, 0.02);
        let under_the_table = top_down(1, 0.3, -0.05);
        let mut verdicts = Verdicts::default();
        let (mut per_object, mut squared) = ([ObjectRefusals::default()], 0);
        for _ in 0..2 {
            for g in [&across, &under_the_table] {
                let checked = verdicts.check(g.clone(), Some(0), &v);
                assert_eq!(checked, check(g.clone(), Some(0), &v));
                checked.count(Some(0), &mut per_object, &mut squared);
            }
        }
        assert_eq!(verdicts.len(), 2, "each grasp checked once");
        assert!(matches!(
            verdicts.check(across.clone(), Some(0), &v).verdict,
            Verdict::Accept(_)
        ));
        assert_eq!(
            verdicts.check(under_the_table, Some(0), &v).verdict,
            Verdict::Refuse
        );
        assert_eq!(per_object[0].table, 2, "counted each time it was asked");
        // Another grasp at the same pixel is checked on its own.
        let deeper = Grasp {
            width_m: 0.09,
            ..across
        };
        verdicts.check(deeper, Some(0), &v);
        assert_eq!(verdicts.len(), 3);
    }
}
