//! Planning one pick: for each ranked grasp, both half turns about its
//! approach, the pre-grasp, the linear approach and lift, the pose over the
//! basket, the guarded descent into it and the joint moves between them,
//! the cheaper feasible one kept.

use std::f64::consts::PI;

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

use super::{GraspTarget, PickConfig, PickPlan, Step};
use crate::collision::{BoxObstacle, CollisionWorld};
use crate::error::{Error, Result};
use crate::ur5e::{Joints, Ur5e, check_joints, check_pose, max_joint_move};

/// The best-ranked grasp whose pick is feasible and collision-free, and its
/// steps; grasps are tried in the given (ranked) order. `scene` holds the
/// detected objects as boxes; a grasp's own object (`GraspTarget::object`)
/// is left out of its checks. An error says why the last grasp failed.
pub fn plan_pick(
    arm: &Ur5e,
    config: &PickConfig,
    grasps: &[GraspTarget],
    scene: &[BoxObstacle],
    current: &Joints,
) -> Result<PickPlan> {
    check_joints("current_joints", current)?;
    let mut last_error = Error::Unreachable("no grasp given".to_owned());
    for (index, grasp) in grasps.iter().enumerate() {
        let neighbours = scene
            .iter()
            .enumerate()
            .filter(|(i, _)| Some(*i) != grasp.object)
            .map(|(_, o)| o);
        // The parts of other objects past the workspace's border: checked as
        // the cell is, fingers included (the planner's hand check never saw
        // their points).
        let fixed: Vec<BoxObstacle> = config
            .obstacles
            .iter()
            .chain(
                config
                    .object_parts
                    .iter()
                    .filter(|(owner, _)| Some(*owner) != grasp.object)
                    .map(|(_, o)| o),
            )
            .cloned()
            .collect();
        let opening = config.approach_opening(grasp.width_m);
        let world = CollisionWorld::new(config.world_from_base, &fixed, config.arm_model.clone())
            .with_detected(neighbours)
            .with_gripper(
                config.flange_from_tcp * Translation3::new(0.0, 0.0, config.fingertip_along(opening)),
                opening,
            );
        let near = world
            .clone()
            .with_fingers_against_detected(config.check_fingers_near_grasp)
            .with_palm_against_detected(config.check_palm_near_grasp);
        let arm_alone = world.clone().without_hand();
        // From the pre-grasp the planner vetted, on the arm branch nearest
        // the current joints, first; other branches and further back only
        // where no pick works from there.
        let widen = config.pregrasp_any_branch || config.pregrasp_extra_m > 0.0;
        let planned =
            plan_one(arm, config, [&world, &near, &arm_alone], grasp, current, false).or_else(|e| match e {
                // The first reason stands: why the preferred pick fails.
                Error::Unreachable(_) if widen => {
                    plan_one(arm, config, [&world, &near, &arm_alone], grasp, current, true).map_err(|_| e)
                }
                e => Err(e),
            });
        match planned {
            Ok(steps) => {
                return Ok(PickPlan {
                    grasp_index: index,
                    steps,
                });
            }
            Err(e @ Error::InvalidInput { .. }) => return Err(e),
            Err(e) => last_error = e,
        }
    }
    Err(last_error)
}

/// The pick of one grasp; `near` is `world` as the approach and the lift
/// check it, `arm_alone` as the descent into the basket does. The
/// pre-grasp at `pregrasp_m` on the arm branch nearest `current` only, or
/// with `widen` also on the other branches (`pregrasp_any_branch`) and
/// further back (`pregrasp_extra_m`).
fn plan_one(
    arm: &Ur5e,
    config: &PickConfig,
    [world, near, arm_alone]: [&CollisionWorld; 3],
    grasp: &GraspTarget,
    current: &Joints,
    widen: bool,
) -> Result<Vec<Step>> {
    check_pose("grasp.world_from_grasp", &grasp.world_from_grasp)?;
    if !(grasp.width_m.is_finite() && grasp.width_m >= 0.0) {
        return Err(Error::InvalidInput {
            field: "grasp.width_m",
            reason: format!("{}", grasp.width_m),
        });
    }
    if let Some(hit) = world.collision(arm, current) {
        return Err(Error::Controller(format!(
            "the arm already touches `{hit}` at its current joints"
        )));
    }
    let base_from_world = config.world_from_base.inverse();
    let tcp_from_flange = config.flange_from_tcp.inverse();
    let flange_for = |world_from_tcp: &Isometry3<f64>| base_from_world * world_from_tcp * tcp_from_flange;
    let joint_path = |from: &Joints, to: &Joints| {
        world.plan_joint_path(arm, from, to, config.rrt_seed, config.rrt_iterations)
    };
    let mut best: Option<(f64, Vec<Step>)> = None;
    let mut reason = "no IK solution within the limits".to_owned();
    // The TCP held back along the approach by where the fingertips will be
    // when the pads meet the object, so that they meet it at the grasp.
    let contact = (grasp.width_m - config.opening_margin_m).max(0.0);
    let tips_at_contact = config.fingertip_along(contact);
    for flip in [0.0, PI] {
        let world_from_grasp =
            grasp.world_from_grasp * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), flip);
        let approach = world_from_grasp.rotation * Vector3::z();
        let world_from_tcp = Translation3::from(-tips_at_contact * approach) * world_from_grasp;
        let held_back = |distance: f64| {
            Isometry3::from_parts(
                Translation3::from(world_from_tcp.translation.vector - distance * approach),
                world_from_tcp.rotation,
            )
        };
        // The pre-grasp as far back as the planner checked the hand, or
        // further where the arm there touches a box (a taller neighbour's);
        // the approach's samples beyond that are checked against every box.
        let mut approached = None;
        'distances: for distance in config
            .pregrasp_distances()
            .take(if widen { usize::MAX } else { 1 })
        {
            let pre = held_back(distance);
            let near_start = if distance > config.pregrasp_m {
                held_back(config.pregrasp_m + LINEAR_STEP_M)
            } else {
                pre
            };
            let Ok(branches) = arm.inverse_ranked(&flange_for(&pre), current) else {
                continue;
            };
            let branches = branches.into_iter().take(if widen && config.pregrasp_any_branch {
                usize::MAX
            } else {
                1
            });
            for q_pre in branches {
                if let Some(hit) = world.collision(arm, &q_pre) {
                    reason = format!("pre-grasp: the arm touches `{hit}` {distance:.2} m back");
                    continue;
                }
                let far = if distance > config.pregrasp_m {
                    linear(
                        arm,
                        config,
                        world,
                        &flange_for(&pre),
                        &flange_for(&near_start),
                        &q_pre,
                    )
                } else {
                    Ok((q_pre, Vec::new()))
                };
                let line = far.and_then(|(q_near, mut path)| {
                    let (q_grasp, rest) = linear(
                        arm,
                        config,
                        near,
                        &flange_for(&near_start),
                        &flange_for(&world_from_tcp),
                        &q_near,
                    )?;
                    path.extend(rest);
                    Ok((q_grasp, path))
                });
                match line {
                    Ok((q_grasp, path)) => {
                        approached = Some((q_pre, q_grasp, path));
                        break 'distances;
                    }
                    Err(e) => reason = format!("approach: {e}"),
                }
            }
        }
        let Some((q_pre, q_grasp, approach_path)) = approached else {
            continue;
        };
        // Straight up; where the arm cannot reach that high (an object at
        // the edge of its reach), leaning towards the base by ever more.
        let lifted = config.lift_tilts().find_map(|tilt| {
            let lift = Isometry3::from_parts(
                Translation3::from(
                    world_from_tcp.translation.vector + config.lift_offset(&world_from_tcp, tilt)?,
                ),
                world_from_tcp.rotation,
            );
            match linear(
                arm,
                config,
                near,
                &flange_for(&world_from_tcp),
                &flange_for(&lift),
                &q_grasp,
            ) {
                Ok((q, path)) => Some((lift, q, path)),
                Err(e) => {
                    reason = format!("lift: {e}");
                    None
                }
            }
        });
        let Some((lift, q_lift, lift_path)) = lifted else {
            continue;
        };
        // The joint moves start here; the lift above was checked as the
        // approach was.
        if let Some(hit) = world.collision(arm, &q_lift) {
            reason = format!("lift: the arm at its top touches `{hit}`");
            continue;
        }
        // Over the basket the tool's turn about the vertical does not matter:
        // per quarter turn the nearest arm branch (shoulder, elbow, wrist)
        // that is free of collisions, then the nearest quarter turn. At this
        // object's spot; where the arm cannot be there, over the basket's
        // drop pose (not tried twice where the spot is that pose).
        let fallback = (!config.release_offsets_m.is_empty()).then_some(config.world_from_drop);
        let Some((q_drop, drop)) =
            [Some(config.release_spot()), fallback]
                .iter()
                .flatten()
                .find_map(|spot| {
                    [0.0, PI / 2.0, PI, -PI / 2.0]
                        .iter()
                        .filter_map(|yaw| {
                            let drop = spot * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), *yaw);
                            arm.inverse_ranked(&flange_for(&drop), &q_lift)
                                .ok()?
                                .into_iter()
                                .find(|q| world.collision(arm, q).is_none())
                                .map(|q| (q, drop))
                        })
                        .min_by(|(a, _), (b, _)| {
                            max_joint_move(&q_lift, a).total_cmp(&max_joint_move(&q_lift, b))
                        })
                })
        else {
            reason = "no collision-free pose over the basket".to_owned();
            continue;
        };
        // Straight down before letting go, the hand unchecked against the
        // basket (the move stops on contact); where the arm cannot go
        // straight down, the object is let go over the basket as it is.
        let lowered = config
            .release_lowest_z_m
            .filter(|z| *z < drop.translation.z - LINEAR_STEP_M)
            .and_then(|z| {
                let p = drop.translation.vector;
                let low = Isometry3::from_parts(Translation3::new(p.x, p.y, z), drop.rotation);
                let (q_low, path) = linear(
                    arm,
                    config,
                    arm_alone,
                    &flange_for(&drop),
                    &flange_for(&low),
                    &q_drop,
                )
                .ok()?;
                Some((low, q_low, path))
            });
        // Joint moves: straight if free, else around obstacles (RRT-Connect).
        let (Some(to_pre), Some(to_drop), Some(back)) = (
            joint_path(current, &q_pre),
            joint_path(&q_lift, &q_drop),
            joint_path(&q_drop, &q_lift),
        ) else {
            reason = "no collision-free joint path (RRT-Connect gave up)".to_owned();
            continue;
        };
        let via = |path: &[Joints], name: &'static str| -> Vec<Step> {
            let n = path.len();
            path[1..]
                .iter()
                .enumerate()
                .map(|(k, q)| Step::MoveJ {
                    name: if k + 2 == n { name } else { "via" },
                    joints: *q,
                })
                .collect()
        };
        let cost = max_joint_move(current, &q_pre);
        let mut steps = vec![Step::Gripper {
            name: "open before approach",
            close: false,
            width_m: config.approach_opening(grasp.width_m),
        }];
        steps.extend(via(&to_pre, "pre-grasp"));
        steps.push(Step::MoveL {
            name: "approach",
            base_from_tcp: base_from_world * world_from_tcp,
            joints: q_grasp,
            path: approach_path,
            until_contact: false,
        });
        steps.push(Step::Gripper {
            name: "close",
            close: true,
            width_m: 0.0,
        });
        steps.push(Step::MoveL {
            name: "lift",
            base_from_tcp: base_from_world * lift,
            joints: q_lift,
            path: lift_path,
            until_contact: false,
        });
        steps.extend(via(&to_drop, "over the basket"));
        if let Some((low, q_low, path)) = &lowered {
            steps.push(Step::MoveL {
                name: "lower",
                base_from_tcp: base_from_world * low,
                joints: *q_low,
                path: path.clone(),
                until_contact: true,
            });
        }
        steps.push(Step::Gripper {
            name: "release",
            close: false,
            width_m: 0.14,
        });
        if let Some((_, _, path)) = &lowered {
            // Back up from wherever the descent stopped.
            let mut up: Vec<Joints> = path.iter().rev().skip(1).copied().collect();
            up.push(q_drop);
            steps.push(Step::MoveL {
                name: "raise",
                base_from_tcp: base_from_world * drop,
                joints: q_drop,
                path: up,
                until_contact: false,
            });
        }
        steps.extend(via(&back, "retreat"));
        if best.as_ref().is_none_or(|(c, _)| cost < *c) {
            best = Some((cost, steps));
        }
    }
    best.map(|(_, steps)| steps).ok_or_else(|| {
        let p = grasp.world_from_grasp.translation.vector;
        Error::Unreachable(format!(
            "grasp at ({:.3}, {:.3}, {:.3}) m: {reason}",
            p.x, p.y, p.z
        ))
    })
}

/// The spacing of a linear move's samples (m).
const LINEAR_STEP_M: f64 = 0.01;

/// Solves a straight flange line from `from` to `to` at 1 cm steps starting
/// at joints `start` and returns the joints at `to` and the samples after
/// the start (ending with them); fails if a sample is unreachable, collides,
/// or a joint jumps by more than `max_joint_step` (a flip through a
/// singularity).
fn linear(
    arm: &Ur5e,
    config: &PickConfig,
    world: &CollisionWorld,
    from: &Isometry3<f64>,
    to: &Isometry3<f64>,
    start: &Joints,
) -> Result<(Joints, Vec<Joints>)> {
    let distance = (to.translation.vector - from.translation.vector).norm();
    let samples = ((distance / LINEAR_STEP_M).ceil() as usize).max(1);
    let mut q = *start;
    let mut path = Vec::with_capacity(samples);
    for k in 0..=samples {
        let t = k as f64 / samples as f64;
        let next = if k == 0 {
            q
        } else {
            arm.inverse_nearest(&from.lerp_slerp(to, t), &q)?
        };
        if (0..6).any(|i| (next[i] - q[i]).abs() > config.max_joint_step) {
            return Err(Error::Unreachable(
                "the linear move crosses a singularity".to_owned(),
            ));
        }
        if let Some(hit) = world.collision(arm, &next) {
            return Err(Error::Unreachable(format!("the linear move hits `{hit}`")));
        }
        if k > 0 {
            path.push(next);
        }
        q = next;
    }
    Ok((q, path))
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::pick::urscript;
    use nalgebra::Vector2;

    /// A top-down grasp 0.45 m in front of the base at table height 0.
    pub(in crate::pick) fn top_grasp(x: f64, y: f64, z: f64) -> GraspTarget {
        GraspTarget {
            world_from_grasp: Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI),
            ),
            width_m: 0.05,
            quality: 0.9,
            object: None,
        }
    }

    pub(in crate::pick) use crate::ur5e::HOME;

    #[test]
    fn the_fingertips_meet_the_object_at_the_grasp() {
        let arm = Ur5e::default();
        // Tips 5 mm further out closed, 25 mm pulled back at 14 cm, as a 2F-140's.
        let config = PickConfig {
            fingertip_travel: vec![[0.0, 0.005], [0.06, 0.0], [0.14, -0.025]],
            ..PickConfig::default()
        };
        assert_eq!(config.fingertip_along(-1.0), 0.005);
        assert_eq!(config.fingertip_along(0.06), 0.0);
        assert!((config.fingertip_along(0.10) + 0.0125).abs() < 1e-12);
        assert_eq!(config.fingertip_along(0.2), -0.025);
        assert_eq!(PickConfig::default().fingertip_along(0.1), 0.0);
        // A 10 cm grasp: the pads meet the object at 8 cm, where the tips
        // are 6.25 mm behind the calibrated TCP, so the TCP goes 6.25 mm
        // further down than the grasp.
        let mut grasp = top_grasp(0.1, -0.45, 0.05);
        grasp.width_m = 0.10;
        let tcp_z = |config: &PickConfig| {
            let plan = plan_pick(&arm, config, &[grasp], &[], &HOME).unwrap();
            plan.steps
                .iter()
                .find_map(|s| match s {
                    Step::MoveL {
                        name: "approach",
                        base_from_tcp,
                        joints,
                        ..
                    } => {
                        let fk = config.world_from_base * arm.forward(joints) * config.flange_from_tcp;
                        assert!(
                            (fk.translation.vector
                                - config.world_from_base * base_from_tcp.translation.vector)
                                .norm()
                                < 1e-6
                        );
                        Some(fk.translation.z)
                    }
                    _ => None,
                })
                .unwrap()
        };
        assert!((tcp_z(&PickConfig::default()) - 0.05).abs() < 1e-6);
        assert!((tcp_z(&config) - (0.05 - 0.00625)).abs() < 1e-6);
    }

    /// What each step of `plan` is for, in order.
    fn step_names(plan: &PickPlan) -> Vec<&'static str> {
        plan.steps
            .iter()
            .map(|s| match s {
                Step::MoveJ { name, .. } | Step::MoveL { name, .. } | Step::Gripper { name, .. } => *name,
            })
            .collect()
    }

    #[test]
    fn reachable_grasp_gives_the_full_sequence_and_poses_match_fk() {
        let arm = Ur5e::default();
        let config = PickConfig::default();
        let plan = plan_pick(&arm, &config, &[top_grasp(0.1, -0.45, 0.05)], &[], &HOME).unwrap();
        assert_eq!(
            step_names(&plan),
            [
                "open before approach",
                "pre-grasp",
                "approach",
                "close",
                "lift",
                "over the basket",
                "release",
                "retreat"
            ]
        );
        // The approach ends with the TCP on the grasp (either half turn).
        let Step::MoveL { joints, .. } = &plan.steps[2] else {
            panic!("approach is linear")
        };
        let tcp = arm.forward(joints) * config.flange_from_tcp;
        let grasp = top_grasp(0.1, -0.45, 0.05).world_from_grasp;
        assert!((tcp.translation.vector - grasp.translation.vector).norm() < 1e-6);
        let z_tcp = tcp.rotation * Vector3::z();
        assert!(
            (z_tcp - grasp.rotation * Vector3::z()).norm() < 1e-6,
            "same approach"
        );
        // Carrying to the basket turns the wrist as needed rather than the
        // whole arm: no joint swings by more than a radian.
        let (Step::MoveL { joints: q_lift, .. }, Step::MoveJ { joints: q_drop, .. }) =
            (&plan.steps[4], &plan.steps[5])
        else {
            panic!("lift then basket")
        };
        assert!(max_joint_move(q_lift, q_drop) < 1.0, "{q_lift:?} -> {q_drop:?}");
        let script = urscript(&plan, &config);
        assert!(script.starts_with("def mvgrasp_pick():\n  set_tcp(p[0.000000, 0.000000, 0.233000"));
        assert_eq!(script.matches("movej(").count(), 3);
        assert_eq!(script.matches("movel(").count(), 2);
        assert!(script.ends_with("end\n"));
    }

    /// With `release_lowest_z_m` the object is lowered straight down from
    /// the pose over the basket in a guarded move before the release, and
    /// the hand backs up to that pose before the retreat.
    #[test]
    fn a_release_height_lowers_the_object_in_a_guarded_move_first() {
        let arm = Ur5e::default();
        let grasp = top_grasp(0.1, -0.45, 0.05);
        let config = PickConfig {
            release_lowest_z_m: Some(0.12),
            ..PickConfig::default()
        };
        let plan = plan_pick(&arm, &config, &[grasp], &[], &HOME).unwrap();
        let tail = step_names(&plan).split_off(5);
        assert_eq!(tail, ["over the basket", "lower", "release", "raise", "retreat"]);
        let q_drop = move_to(&plan, "over the basket");
        let tcp = |q: &Joints| config.world_from_base * arm.forward(q) * config.flange_from_tcp;
        let drop = tcp(&q_drop);
        let (
            Step::MoveL {
                joints: q_low,
                path: down,
                until_contact: true,
                ..
            },
            Step::MoveL {
                joints: q_up,
                path: up,
                until_contact: false,
                ..
            },
        ) = (&plan.steps[6], &plan.steps[8])
        else {
            panic!("a guarded lower, then a raise: {:?}", &plan.steps[6..9])
        };
        // Straight down from the drop pose to 12 cm, the tool pointing down.
        assert!((tcp(q_low).translation.z - 0.12).abs() < 1e-6);
        for q in down {
            let p = tcp(q);
            let off = p.translation.vector - drop.translation.vector;
            assert!(off.x.hypot(off.y) < 1e-6, "{off:?}");
            assert!(p.rotation.angle_to(&drop.rotation) < 1e-6);
        }
        assert_eq!(down.len(), 23, "1 cm samples over 23 cm");
        assert_eq!(*q_up, q_drop);
        assert_eq!(up.last(), Some(&q_drop));
        assert_eq!(up.len(), down.len());
        let script = urscript(&plan, &config);
        assert_eq!(script.matches("tool_contact(").count(), 1);
        assert_eq!(script.matches("movel(").count(), 4);
        assert!(script.contains("thread mvgrasp_line():\n    movel(p[0.000000, -0.450000, 0.120000"));
        // Off, or a height not below the drop pose: let go up there, as before.
        for lowest in [None, Some(0.345), Some(0.5)] {
            let config = PickConfig {
                release_lowest_z_m: lowest,
                ..PickConfig::default()
            };
            let plan = plan_pick(&arm, &config, &[grasp], &[], &HOME).unwrap();
            assert_eq!(
                step_names(&plan).split_off(5),
                ["over the basket", "release", "retreat"]
            );
        }
    }

    /// The fingers open the grasp's width plus `approach_clearance_m`,
    /// never past the 14 cm stroke.
    #[test]
    fn the_fingers_open_the_grasp_width_plus_the_clearance() {
        let arm = Ur5e::default();
        let opening = |clearance: f64, width_m: f64| {
            let config = PickConfig {
                approach_clearance_m: clearance,
                ..PickConfig::default()
            };
            let mut grasp = top_grasp(0.1, -0.45, 0.05);
            grasp.width_m = width_m;
            let plan = plan_pick(&arm, &config, &[grasp], &[], &HOME).unwrap();
            match plan.steps[0] {
                Step::Gripper {
                    name: "open before approach",
                    close: false,
                    width_m,
                } => width_m,
                ref other => panic!("{other:?}"),
            }
        };
        assert!((opening(0.02, 0.05) - 0.07).abs() < 1e-12);
        assert!((opening(0.0, 0.05) - 0.05).abs() < 1e-12);
        assert!((opening(0.005, 0.08) - 0.085).abs() < 1e-12);
        assert_eq!(opening(0.02, 0.13), 0.14);
    }

    /// The lift's TCP (world), the lift step's pose.
    fn lift_tcp(config: &PickConfig, plan: &PickPlan) -> Vector3<f64> {
        plan.steps
            .iter()
            .find_map(|s| match s {
                Step::MoveL {
                    name: "lift",
                    base_from_tcp,
                    ..
                } => Some((config.world_from_base * base_from_tcp).translation.vector),
                _ => None,
            })
            .unwrap()
    }

    #[test]
    fn a_lift_out_of_reach_leans_towards_the_base() {
        let arm = Ur5e::default();
        let config = PickConfig::default();
        assert_eq!(
            config
                .lift_tilts()
                .map(|t| t.to_degrees().round())
                .collect::<Vec<_>>(),
            [0.0, 15.0, 30.0, 45.0]
        );
        let straight = PickConfig {
            max_lift_tilt_deg: 0.0,
            ..PickConfig::default()
        };
        assert_eq!(straight.lift_tilts().count(), 1);
        // 86 cm out the grasp is reachable, 15 cm over it is not.
        let far = top_grasp(0.0, -0.86, 0.03);
        let err = plan_pick(&arm, &straight, &[far], &[], &HOME).unwrap_err();
        assert!(err.to_string().contains("lift: pose unreachable"), "{err}");
        let plan = plan_pick(&arm, &config, &[far], &[], &HOME).unwrap();
        let lifted = lift_tcp(&config, &plan) - far.world_from_grasp.translation.vector;
        assert!((lifted.z - config.lift_m).abs() < 1e-6, "{lifted}");
        assert!(lifted.x.abs() < 1e-6, "{lifted}");
        assert!(
            lifted.y > 0.01 && lifted.y <= config.lift_m + 1e-6,
            "towards the base: {lifted}"
        );
        // Within reach the lift goes straight up, as before.
        let near = top_grasp(0.1, -0.45, 0.05);
        let plan = plan_pick(&arm, &config, &[near], &[], &HOME).unwrap();
        let lifted = lift_tcp(&config, &plan) - near.world_from_grasp.translation.vector;
        assert!((lifted - config.lift_m * Vector3::z()).norm() < 1e-6, "{lifted}");
        // Right over the base there is no direction to lean in.
        assert!(
            config
                .lift_offset(&Isometry3::translation(0.0, 0.0, 0.2), 0.5)
                .is_none()
        );
    }

    #[test]
    fn unreachable_grasps_are_skipped_for_the_next_ranked_one() {
        let arm = Ur5e::default();
        let far = top_grasp(1.5, 0.0, 0.05);
        let near = top_grasp(0.0, -0.5, 0.05);
        let plan = plan_pick(&arm, &PickConfig::default(), &[far, near], &[], &HOME).unwrap();
        assert_eq!(plan.grasp_index, 1);
        let err = plan_pick(&arm, &PickConfig::default(), &[far], &[], &HOME).unwrap_err();
        assert!(matches!(err, Error::Unreachable(_)), "{err}");
    }

    #[test]
    fn nan_input_is_rejected_not_moved_on() {
        let arm = Ur5e::default();
        let mut bad = top_grasp(0.1, -0.45, 0.05);
        bad.world_from_grasp.translation.vector.x = f64::NAN;
        let err = plan_pick(
            &arm,
            &PickConfig::default(),
            &[bad, top_grasp(0.1, -0.45, 0.05)],
            &[],
            &HOME,
        )
        .unwrap_err();
        assert!(
            matches!(
                err,
                Error::InvalidInput {
                    field: "grasp.world_from_grasp",
                    ..
                }
            ),
            "{err}"
        );
        let mut current = HOME;
        current[2] = f64::INFINITY;
        let err = plan_pick(
            &arm,
            &PickConfig::default(),
            &[top_grasp(0.1, -0.45, 0.05)],
            &[],
            &current,
        )
        .unwrap_err();
        assert!(
            matches!(
                err,
                Error::InvalidInput {
                    field: "current_joints",
                    ..
                }
            ),
            "{err}"
        );
    }

    fn table() -> BoxObstacle {
        BoxObstacle {
            name: "table".to_owned(),
            world_from_box: Isometry3::translation(0.0, 0.0, -0.05),
            half_extents_m: Vector3::new(1.2, 1.2, 0.05),
        }
    }

    #[test]
    fn neighbours_block_grasps_but_the_grasped_object_does_not() {
        let arm = Ur5e::default();
        let config = PickConfig {
            obstacles: vec![table()],
            ..PickConfig::default()
        };
        let mut grasp = top_grasp(0.1, -0.45, 0.05);
        // The grasped object itself, 12 cm tall: the fingers straddle it,
        // their boxes (1 cm margin) overlap its sides.
        let target = BoxObstacle {
            name: "target".to_owned(),
            world_from_box: Isometry3::translation(0.1, -0.45, 0.06),
            half_extents_m: Vector3::new(0.03, 0.03, 0.06),
        };
        grasp.object = Some(0);
        assert!(plan_pick(&arm, &config, &[grasp], std::slice::from_ref(&target), &HOME).is_ok());
        // Not told which object it grasps, and checking the fingers near the
        // grasp too: they collide with it.
        grasp.object = None;
        let checking = PickConfig {
            check_fingers_near_grasp: true,
            ..config.clone()
        };
        let err = plan_pick(&arm, &checking, &[grasp], std::slice::from_ref(&target), &HOME).unwrap_err();
        assert!(err.to_string().contains("target"), "{err}");
        // A tall neighbour right beside the approach blocks it: 6 cm from
        // the grasp across the closing direction it clears the 2F-140
        // (3.7 cm half thick), 3 cm away it does not.
        grasp.object = Some(0);
        let neighbour = |y: f64| BoxObstacle {
            name: "neighbour".to_owned(),
            world_from_box: Isometry3::translation(0.1, y, 0.15),
            half_extents_m: Vector3::new(0.04, 0.03, 0.15),
        };
        let beside = [target.clone(), neighbour(-0.36)];
        assert!(plan_pick(&arm, &config, &[grasp], &beside, &HOME).is_ok());
        let err = plan_pick(&arm, &config, &[grasp], &[target, neighbour(-0.39)], &HOME).unwrap_err();
        assert!(err.to_string().contains("neighbour"), "{err}");
    }

    #[test]
    fn near_the_grasp_the_palm_is_checked_against_the_cell_only_unless_asked() {
        let arm = Ur5e::default();
        let mut grasp = top_grasp(0.1, -0.45, 0.05);
        grasp.object = Some(0);
        grasp.width_m = 0.02;
        let target = BoxObstacle {
            name: "target".to_owned(),
            world_from_box: Isometry3::translation(0.1, -0.45, 0.02),
            half_extents_m: Vector3::new(0.008, 0.02, 0.02),
        };
        // A thin 20 cm tall box 7.0-7.9 cm from the grasp along the closing
        // direction: outside the fingers at a 4 cm opening (6.8 cm out,
        // margin included), inside the linkage (8 cm out, from 9.7 cm above
        // the fingertips), below the flange.
        let beside = BoxObstacle {
            name: "neighbour".to_owned(),
            world_from_box: Isometry3::translation(0.1745, -0.45, 0.1),
            half_extents_m: Vector3::new(0.0045, 0.02, 0.1),
        };
        let scene = [target, beside];
        let trusting = PickConfig {
            obstacles: vec![table()],
            ..PickConfig::default()
        };
        assert!(!trusting.check_palm_near_grasp, "the default");
        assert!(plan_pick(&arm, &trusting, &[grasp], &scene, &HOME).is_ok());
        let checking = PickConfig {
            check_palm_near_grasp: true,
            ..trusting.clone()
        };
        let err = plan_pick(&arm, &checking, &[grasp], &scene, &HOME).unwrap_err();
        assert!(
            err.to_string().contains("approach") && err.to_string().contains("neighbour"),
            "{err}"
        );
        // The fingers checked near the grasp too: they clear it.
        let fingers = PickConfig {
            check_fingers_near_grasp: true,
            ..trusting
        };
        assert!(plan_pick(&arm, &fingers, &[grasp], &scene, &HOME).is_ok());
    }

    /// A top-down grasp on object 0, a 4 x 6 x 6 cm box on the table.
    fn grasp_on_a_small_box() -> (GraspTarget, BoxObstacle) {
        let mut grasp = top_grasp(0.1, -0.45, 0.05);
        grasp.object = Some(0);
        let target = BoxObstacle {
            name: "target".to_owned(),
            world_from_box: Isometry3::translation(0.1, -0.45, 0.03),
            half_extents_m: Vector3::new(0.02, 0.03, 0.03),
        };
        (grasp, target)
    }

    #[test]
    fn near_the_grasp_the_fingers_are_checked_against_the_cell_only_unless_asked() {
        let arm = Ur5e::default();
        let (grasp, target) = grasp_on_a_small_box();
        // A 6 cm tall box beside the grasp along the closing direction, 5 cm
        // from its centre: inside a finger (3.5 to 8.3 cm out, margin
        // included), below the linkage (8.7 cm above the fingertips).
        let beside = BoxObstacle {
            name: "neighbour".to_owned(),
            world_from_box: Isometry3::translation(0.17, -0.45, 0.03),
            half_extents_m: Vector3::new(0.02, 0.03, 0.03),
        };
        let scene = [target, beside.clone()];
        let trusting = PickConfig {
            obstacles: vec![table()],
            ..PickConfig::default()
        };
        assert!(!trusting.check_fingers_near_grasp, "the default");
        assert!(plan_pick(&arm, &trusting, &[grasp], &scene, &HOME).is_ok());
        let checking = PickConfig {
            check_fingers_near_grasp: true,
            ..trusting.clone()
        };
        let err = plan_pick(&arm, &checking, &[grasp], &scene, &HOME).unwrap_err();
        assert!(
            err.to_string().contains("approach") && err.to_string().contains("neighbour"),
            "{err}"
        );
        // The same box as a part of the cell blocks the fingers either way.
        let cell = PickConfig {
            obstacles: vec![table(), beside],
            ..trusting
        };
        let err = plan_pick(&arm, &cell, &[grasp], &scene[..1], &HOME).unwrap_err();
        assert!(err.to_string().contains("neighbour"), "{err}");
    }

    #[test]
    fn a_pre_grasp_in_a_taller_neighbour_moves_back_along_the_approach_if_asked() {
        let arm = Ur5e::default();
        let (grasp, target) = grasp_on_a_small_box();
        // Beside the grasp along the closing direction, inside a finger's
        // reach, as tall as `top`.
        let neighbour = |top: f64| BoxObstacle {
            name: "neighbour".to_owned(),
            world_from_box: Isometry3::translation(0.17, -0.45, top / 2.0),
            half_extents_m: Vector3::new(0.02, 0.03, top / 2.0),
        };
        let config = PickConfig {
            obstacles: vec![table()],
            pregrasp_extra_m: 0.15,
            ..PickConfig::default()
        };
        let plan = |config: &PickConfig, top: f64| {
            plan_pick(&arm, config, &[grasp], &[target.clone(), neighbour(top)], &HOME)
        };
        // Lower than the fingers 10 cm back: the pre-grasp stays there.
        let low = plan(&config, 0.14).unwrap();
        assert!((pre_height(&config, &arm, &low) - 0.15).abs() < 1e-6);
        // As high as the fingers there: refused with the pre-grasp at 10 cm
        // only (the default); else the pre-grasp 5 cm further back.
        let only_10cm = PickConfig {
            pregrasp_extra_m: PickConfig::default().pregrasp_extra_m,
            ..config.clone()
        };
        assert_eq!(only_10cm.pregrasp_extra_m, 0.0);
        let err = plan(&only_10cm, 0.16).unwrap_err().to_string();
        assert!(
            err.contains("pre-grasp: the arm touches `neighbour` 0.10 m back"),
            "{err}"
        );
        let higher = plan(&config, 0.16).unwrap();
        assert!((pre_height(&config, &arm, &higher) - 0.20).abs() < 1e-6);
        // The approach from there is one straight line down to the grasp.
        let Some(Step::MoveL { path, .. }) = higher
            .steps
            .iter()
            .find(|s| matches!(s, Step::MoveL { name: "approach", .. }))
        else {
            panic!("no approach");
        };
        let tcp = |q: &Joints| {
            (config.world_from_base * arm.forward(q) * config.flange_from_tcp)
                .translation
                .vector
        };
        let heights: Vec<f64> = path.iter().map(|q| tcp(q).z).collect();
        assert!(
            path.iter()
                .all(|q| (tcp(q).xy() - Vector2::new(0.1, -0.45)).norm() < 1e-6)
        );
        assert!(
            heights
                .windows(2)
                .all(|h| h[1] < h[0] && h[0] - h[1] <= 0.01 + 1e-9),
            "{heights:?}"
        );
        assert!(
            heights[0] < 0.20 && (heights[heights.len() - 1] - 0.05).abs() < 1e-6,
            "{heights:?}"
        );
        // Taller: the fingers beyond 10 cm back would cross its box, or
        // every pre-grasp touches it; refused for the first pre-grasp.
        for top in [0.2, 0.5] {
            let err = plan(&config, top).unwrap_err().to_string();
            assert!(
                err.contains("pre-grasp: the arm touches `neighbour` 0.10 m back"),
                "{err}"
            );
        }
    }

    /// The joints of the plan's joint move named `name`.
    fn move_to(plan: &PickPlan, name: &str) -> Joints {
        plan.steps
            .iter()
            .find_map(|s| match s {
                Step::MoveJ { name: n, joints } if *n == name => Some(*joints),
                _ => None,
            })
            .unwrap_or_else(|| panic!("no `{name}` move"))
    }

    fn pre_height(config: &PickConfig, arm: &Ur5e, plan: &PickPlan) -> f64 {
        let q = move_to(plan, "pre-grasp");
        (config.world_from_base * arm.forward(&q) * config.flange_from_tcp)
            .translation
            .z
    }

    #[test]
    fn a_pre_grasp_whose_nearest_arm_branch_hits_the_table_takes_another() {
        // A referee cell (base at the table's near edge, turned a quarter)
        // and a top-down grasp 0.77 m from the base, from its parked arm:
        // the nearest branch swings the shoulder below the horizontal and the
        // upper arm into the table on the way down.
        let arm = Ur5e::default();
        let config = PickConfig {
            world_from_base: Isometry3::from_parts(
                Translation3::new(0.0, -0.62, 0.0),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -PI / 2.0),
            ),
            flange_from_tcp: Isometry3::from_parts(
                Translation3::new(0.0, 0.0, 0.226872),
                UnitQuaternion::from_axis_angle(&Vector3::z_axis(), PI / 2.0),
            ),
            obstacles: vec![table()],
            ..PickConfig::default()
        };
        let grasp = GraspTarget {
            world_from_grasp: Isometry3::from_parts(
                Translation3::new(-0.2399, 0.1148, 0.003),
                UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(0.0, -0.22422, 0.97454, 0.0)),
            ),
            width_m: 0.096,
            quality: 0.8,
            object: None,
        };
        let parked = [-150.0f64, -100.0, 110.0, -100.0, -90.0, 0.0].map(f64::to_radians);
        let nearest_only = PickConfig {
            pregrasp_any_branch: false,
            ..config.clone()
        };
        let err = plan_pick(&arm, &nearest_only, &[grasp], &[], &parked)
            .unwrap_err()
            .to_string();
        assert!(err.contains("approach") && err.contains("`table`"), "{err}");
        assert!(config.pregrasp_any_branch, "the default");
        let plan = plan_pick(&arm, &config, &[grasp], &[], &parked).unwrap();
        // Its pre-grasp on another branch than the nearest one.
        let q_pre = move_to(&plan, "pre-grasp");
        let nearest = arm.inverse_nearest(&arm.forward(&q_pre), &parked).unwrap();
        assert!(max_joint_move(&nearest, &q_pre) > 0.5, "{nearest:?} {q_pre:?}");
    }

    #[test]
    fn a_blocked_joint_move_goes_around() {
        let arm = Ur5e::default();
        let free = PickConfig {
            obstacles: vec![table()],
            ..PickConfig::default()
        };
        let grasp = top_grasp(0.1, -0.45, 0.05);
        let plan = plan_pick(&arm, &free, &[grasp], &[], &HOME).unwrap();
        let Step::MoveJ { joints: q_pre, .. } = plan.steps[1] else {
            panic!("pre-grasp")
        };
        // A small box where the wrist passes halfway along the straight move to the pre-grasp.
        let mid: Joints = std::array::from_fn(|i| 0.5 * (HOME[i] + q_pre[i]));
        let w = arm.forward_frames(&mid)[5].translation.vector;
        let post = BoxObstacle {
            name: "post".to_owned(),
            world_from_box: Isometry3::translation(w.x, w.y, w.z),
            half_extents_m: Vector3::new(0.03, 0.03, 0.03),
        };
        let config = PickConfig {
            obstacles: vec![table(), post],
            ..PickConfig::default()
        };
        let world = CollisionWorld::new(
            config.world_from_base,
            &config.obstacles,
            config.arm_model.clone(),
        );
        assert!(
            !world.segment_free(&arm, &HOME, &q_pre, 0.02),
            "the straight move must be blocked"
        );
        let plan = plan_pick(&arm, &config, &[grasp], &[], &HOME).unwrap();
        let joint_targets: Vec<Joints> = plan
            .steps
            .iter()
            .filter_map(|s| match s {
                Step::MoveJ { joints, .. } | Step::MoveL { joints, .. } => Some(*joints),
                Step::Gripper { .. } => None,
            })
            .collect();
        assert!(
            plan.steps
                .iter()
                .any(|s| matches!(s, Step::MoveJ { name: "via", .. })),
            "a detour"
        );
        let mut previous = HOME;
        for (k, q) in joint_targets.iter().enumerate() {
            // Joint moves are checked as straight joint segments; linear ones were sampled.
            if matches!(
                plan.steps
                    .iter()
                    .filter(|s| !matches!(s, Step::Gripper { .. }))
                    .nth(k),
                Some(Step::MoveJ { .. })
            ) {
                assert!(
                    world.segment_free(&arm, &previous, q, 0.02),
                    "segment {k} collides"
                );
            }
            previous = *q;
        }
    }

    /// When the arm's nearest branch over the basket would hit something,
    /// another branch (here the other elbow) is taken instead of refusing
    /// the grasp.
    #[test]
    fn a_blocked_branch_over_the_basket_gives_way_to_another() {
        let arm = Ur5e::default();
        // The links on their DH lines: with the upper arm 0.138 m out along
        // the shoulder axis, as it is, it stands at home where the post goes.
        let arm_model = crate::collision::ArmModel {
            link_offset_m: [0.0; 5],
            ..crate::collision::ArmModel::default()
        };
        let free = PickConfig {
            obstacles: vec![table()],
            arm_model: arm_model.clone(),
            ..PickConfig::default()
        };
        let grasp = top_grasp(-0.35, -0.2, 0.05);
        let drop_of = |plan: &PickPlan| move_to(plan, "over the basket");
        let q_drop = drop_of(&plan_pick(&arm, &free, &[grasp], &[], &HOME).unwrap());
        // A post at the middle of that pose's forearm: every quarter turn's
        // nearest branch keeps the forearm there.
        let frames = arm.forward_frames(&q_drop);
        let forearm = 0.5 * (frames[2].translation.vector + frames[3].translation.vector);
        let mid = free.world_from_base * forearm;
        let post = BoxObstacle {
            name: "post".to_owned(),
            world_from_box: Isometry3::translation(mid.x, mid.y, mid.z),
            half_extents_m: Vector3::new(0.03, 0.03, 0.03),
        };
        let config = PickConfig {
            obstacles: vec![table(), post],
            arm_model,
            ..PickConfig::default()
        };
        let world = CollisionWorld::new(
            config.world_from_base,
            &config.obstacles,
            config.arm_model.clone(),
        );
        assert_eq!(world.collision(&arm, &q_drop), Some("post"));
        let plan = plan_pick(&arm, &config, &[grasp], &[], &HOME).unwrap();
        let q_other = drop_of(&plan);
        assert_eq!(world.collision(&arm, &q_other), None);
        let (p, r) = (arm.forward(&q_drop), arm.forward(&q_other));
        assert!((p.translation.vector - r.translation.vector).norm() < 1e-9);
        assert!(
            (q_other[2] - q_drop[2]).abs() > 0.5,
            "another elbow: {q_other:?} vs {q_drop:?}"
        );
    }

    /// With `release_offsets_m` the object after `released` others is let
    /// go over its spot, in turn; where the arm cannot be over that spot,
    /// over the drop pose.
    #[test]
    fn releases_take_the_spots_over_the_basket_in_turn() {
        let arm = Ur5e::default();
        let grasp = top_grasp(0.1, -0.45, 0.05);
        let offsets = vec![[0.06, 0.06], [-0.06, -0.06], [0.06, -0.06]];
        let released_at = |config: &PickConfig| {
            let plan = plan_pick(&arm, config, &[grasp], &[], &HOME).unwrap();
            let q = move_to(&plan, "over the basket");
            let p = (config.world_from_base * arm.forward(&q) * config.flange_from_tcp)
                .translation
                .vector
                - PickConfig::default().world_from_drop.translation.vector;
            [p.x, p.y, p.z]
        };
        for released in 0..5 {
            let config = PickConfig {
                release_offsets_m: offsets.clone(),
                released,
                ..PickConfig::default()
            };
            let [x, y] = offsets[released % 3];
            let at = released_at(&config);
            assert!(
                (at[0] - x).abs() < 1e-6 && (at[1] - y).abs() < 1e-6 && at[2].abs() < 1e-6,
                "object {released}: {at:?}"
            );
            assert_eq!(config.release_spot().rotation, config.world_from_drop.rotation);
        }
        // None: the drop pose, whatever the count.
        let at = released_at(&PickConfig {
            released: 7,
            ..PickConfig::default()
        });
        assert!(at.iter().all(|v| v.abs() < 1e-6), "{at:?}");
        // A spot out of the arm's reach (3 m away): the drop pose.
        let at = released_at(&PickConfig {
            release_offsets_m: vec![[3.0, 0.0]],
            ..PickConfig::default()
        });
        assert!(at.iter().all(|v| v.abs() < 1e-6), "{at:?}");
    }
}
