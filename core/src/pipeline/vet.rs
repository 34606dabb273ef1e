//! The hand check of one answer's grasps, in rank order.

use super::plan::{ObjectRefusals, RankedLast};

use nalgebra::{Isometry3, Vector3};

use crate::decode::{
    Collision, Grasp, HandConfig, Obstacle, Repairs, Verdict, contact_slopes, deepen, deepen_to_middle,
    fit_opening, hand_collision, hand_out_of_view, squaring_turn, turn_away,
};
use crate::gripper::Gripper;
use crate::segment::TablePlane;
use crate::sensor::FieldOfView;

/// What the hand check of one answer's grasps looks at ([`vet`]).
pub(super) struct Vetting<'a> {
    pub(super) hand: &'a HandConfig,
    pub(super) gripper: &'a Gripper,
    pub(super) table: &'a TablePlane,
    pub(super) obstacles: &'a [Obstacle<'a>],
    /// The camera's field of view (depth frames).
    pub(super) view: Option<&'a FieldOfView>,
    pub(super) table_clearance_m: f64,
}

/// One grasp through the hand check, in rank order: accepted as planned or
/// repaired (opening re-fitted, squared, deepened), deferred (turned away
/// from what it would hit, or pads out of view), or refused, its cause
/// counted in `per_object[own]`. `own`: the grasp's object among
/// `v.obstacles`.
pub(super) fn vet(
    g: Grasp,
    own: Option<usize>,
    v: &Vetting<'_>,
    per_object: &mut [ObjectRefusals],
    turned_square: &mut usize,
) -> Verdict<RankedLast> {
    let hand = v.hand;
    let hit = |pose: &Isometry3<f64>, width: f64| {
        hand_collision(pose, width, v.gripper, hand, v.table, v.obstacles, own)
    };
    let mut refuse = |c: Collision| {
        let mut unknown = ObjectRefusals::default();
        let mine = own.map_or(&mut unknown, |i| &mut per_object[i]);
        match c {
            Collision::Table => mine.table += 1,
            Collision::Object(i) if Some(i) == own => mine.own_points += 1,
            Collision::Object(_) => mine.neighbour += 1,
        }
        Verdict::Refuse
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
    let g = match turned {
        Some(world_from_grasp) => {
            *turned_square += 1;
            Grasp {
                world_from_grasp,
                repairs: Repairs {
                    squared: true,
                    ..g.repairs
                },
                ..g
            }
        }
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
    if unseen {
        Verdict::Defer(g, RankedLast::OutOfView)
    } else if turned_away {
        Verdict::Defer(g, RankedLast::TurnedAway)
    } else {
        Verdict::Accept(g)
    }
}

/// World-frame approach direction of a grasp (its +z axis).
pub fn approach_of(grasp: &Grasp) -> Vector3<f64> {
    grasp.world_from_grasp.rotation * Vector3::z()
}
