//! Dual (or more) arm cells: each grasp goes to the arm that reaches it with
//! the smaller motion.

use super::{GraspTarget, PickConfig, PickPlan, Step, plan_pick};
use crate::collision::BoxObstacle;
use crate::error::{Error, Result};
use crate::ur5e::{Joints, Ur5e, max_joint_move};

/// One arm of a multi-arm cell: its kinematics, configuration and joints now.
#[derive(Debug, Clone)]
pub struct ArmCell {
    /// Name for messages ("left", "right").
    pub name: String,
    /// Kinematics and limits.
    pub arm: Ur5e,
    /// Calibration, obstacles and limits of this arm.
    pub config: PickConfig,
    /// Its joints now.
    pub current: Joints,
}

/// Dual (or more) arm: for the best-ranked grasp that any arm can pick, the
/// arm with the cheaper motion (smaller largest joint move to the
/// pre-grasp). Returns the arm's index and its plan.
pub fn plan_pick_multi(
    arms: &[ArmCell],
    grasps: &[GraspTarget],
    scene: &[BoxObstacle],
) -> Result<(usize, PickPlan)> {
    let mut last_error = Error::Unreachable("no arm given".to_owned());
    for (index, grasp) in grasps.iter().enumerate() {
        let mut best: Option<(f64, usize, PickPlan)> = None;
        for (a, cell) in arms.iter().enumerate() {
            match plan_pick(
                &cell.arm,
                &cell.config,
                std::slice::from_ref(grasp),
                scene,
                &cell.current,
            ) {
                Ok(mut plan) => {
                    plan.grasp_index = index;
                    let first = plan.steps.iter().find_map(|s| match s {
                        Step::MoveJ { joints, .. } => Some(*joints),
                        _ => None,
                    });
                    let cost = first.map_or(f64::INFINITY, |q| max_joint_move(&cell.current, &q));
                    if best.as_ref().is_none_or(|(c, _, _)| cost < *c) {
                        best = Some((cost, a, plan));
                    }
                }
                Err(e @ Error::InvalidInput { .. }) => return Err(e),
                Err(e) => last_error = Error::Unreachable(format!("{} arm: {e}", cell.name)),
            }
        }
        if let Some((_, a, plan)) = best {
            return Ok((a, plan));
        }
    }
    Err(last_error)
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

    use super::*;
    use crate::pick::plan::tests::{HOME, top_grasp};

    #[test]
    fn each_grasp_goes_to_the_arm_that_reaches_it_more_cheaply() {
        // Two arms 1.2 m apart along x, facing the same table.
        let cell = |name: &str, x: f64| ArmCell {
            name: name.to_owned(),
            arm: Ur5e::default(),
            config: PickConfig {
                world_from_base: Isometry3::translation(x, 0.0, 0.0),
                world_from_drop: Isometry3::from_parts(
                    Translation3::new(x, -0.45, 0.35),
                    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI),
                ),
                ..PickConfig::default()
            },
            current: HOME,
        };
        let arms = [cell("left", -0.6), cell("right", 0.6)];
        let (arm, _) = plan_pick_multi(&arms, &[top_grasp(-0.5, -0.45, 0.05)], &[]).unwrap();
        assert_eq!(arm, 0, "left side -> left arm");
        let (arm, _) = plan_pick_multi(&arms, &[top_grasp(0.5, -0.45, 0.05)], &[]).unwrap();
        assert_eq!(arm, 1, "right side -> right arm");
        // Out of both arms' reach first, then a reachable one: the second is picked.
        let (arm, plan) = plan_pick_multi(
            &arms,
            &[top_grasp(3.0, 0.0, 0.05), top_grasp(0.5, -0.45, 0.05)],
            &[],
        )
        .unwrap();
        assert_eq!((arm, plan.grasp_index), (1, 1));
    }
}
