//! Collision checks of the arm against the cell and the scene, and a
//! joint-space RRT-Connect for joint moves whose straight line collides.
//!
//! The arm is a chain of capsules (parry) between consecutive DH frame
//! origins, plus one for the gripper body; obstacles are boxes (the table,
//! the basket, detected objects). DH origins of a UR arm sit on the joint
//! axes, not on the link centrelines, so the capsules are generous
//! (`ArmModel::margin_m` on top) rather than exact.

use nalgebra::{Isometry3, Point3, Vector3};
use parry3d::math::{Pose, Rotation, Vector};
use parry3d::query::intersection_test;
use parry3d::shape::{Capsule, Cuboid};

use crate::ur5e::{Joints, Ur5e, max_joint_move};
use mvgrasp_core::rng::SplitMix64;

/// A box in the world.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxObstacle {
    /// What it is, for messages.
    pub name: String,
    /// Its centre and orientation.
    pub world_from_box: Isometry3<f64>,
    /// Half sizes (m).
    pub half_extents_m: Vector3<f64>,
}

/// The arm's collision geometry.
#[derive(Debug, Clone, PartialEq)]
pub struct ArmModel {
    /// Capsule radius between DH frames i and i+1 (i = 1..5; the base column is not checked).
    pub link_radius_m: [f64; 5],
    /// Gripper body: from the flange this far along its z (m).
    pub gripper_length_m: f64,
    /// Gripper body radius (m).
    pub gripper_radius_m: f64,
    /// Added to every radius (m).
    pub margin_m: f64,
}

impl Default for ArmModel {
    fn default() -> Self {
        Self {
            link_radius_m: [0.06, 0.05, 0.045, 0.045, 0.045],
            gripper_length_m: 0.15,
            gripper_radius_m: 0.06,
            margin_m: 0.01,
        }
    }
}

/// Obstacles in the world, and where the robot stands.
#[derive(Debug, Clone)]
pub struct CollisionWorld {
    world_from_base: Isometry3<f64>,
    obstacles: Vec<(Pose, Cuboid, String)>,
    model: ArmModel,
}

fn vector(v: &Vector3<f64>) -> Vector {
    Vector::new(v.x as f32, v.y as f32, v.z as f32)
}

fn pose(iso: &Isometry3<f64>) -> Pose {
    let q = iso.rotation;
    Pose::from_parts(
        vector(&iso.translation.vector),
        Rotation::from_xyzw(q.i as f32, q.j as f32, q.k as f32, q.w as f32),
    )
}

impl CollisionWorld {
    /// A world of `obstacles` with the robot base at `world_from_base`.
    pub fn new(world_from_base: Isometry3<f64>, obstacles: &[BoxObstacle], model: ArmModel) -> Self {
        let obstacles = obstacles
            .iter()
            .map(|o| {
                (
                    pose(&o.world_from_box),
                    Cuboid::new(vector(&o.half_extents_m)),
                    o.name.clone(),
                )
            })
            .collect();
        Self {
            world_from_base,
            obstacles,
            model,
        }
    }

    /// The capsules of the arm at `q`, in the world.
    fn capsules(&self, arm: &Ur5e, q: &Joints) -> Vec<Capsule> {
        let frames = arm.forward_frames(q).map(|f| self.world_from_base * f);
        let origin = |i: usize| frames[i].translation.vector;
        let mut capsules: Vec<Capsule> = (1..6)
            .map(|i| {
                Capsule::new(
                    vector(&origin(i)),
                    vector(&origin(i + 1)),
                    (self.model.link_radius_m[i - 1] + self.model.margin_m) as f32,
                )
            })
            .collect();
        let flange = frames[6];
        let tip = flange * Point3::new(0.0, 0.0, self.model.gripper_length_m);
        capsules.push(Capsule::new(
            vector(&flange.translation.vector),
            vector(&tip.coords),
            (self.model.gripper_radius_m + self.model.margin_m) as f32,
        ));
        capsules
    }

    /// The first obstacle the arm at `q` touches, if any.
    pub fn collision(&self, arm: &Ur5e, q: &Joints) -> Option<&str> {
        let capsules = self.capsules(arm, q);
        for (obstacle_pose, cuboid, name) in &self.obstacles {
            for capsule in &capsules {
                if intersection_test(&Pose::IDENTITY, capsule, obstacle_pose, cuboid)
                    .map_or(true, |hit| hit.intersecting)
                {
                    return Some(name);
                }
            }
        }
        None
    }

    /// True when the straight joint-space segment is free, checked every `step_rad`.
    pub fn segment_free(&self, arm: &Ur5e, from: &Joints, to: &Joints, step_rad: f64) -> bool {
        let largest = max_joint_move(from, to);
        let steps = ((largest / step_rad).ceil() as usize).max(1);
        (0..=steps).all(|k| {
            let t = k as f64 / steps as f64;
            let q: Joints = std::array::from_fn(|i| from[i] + t * (to[i] - from[i]));
            self.collision(arm, &q).is_none()
        })
    }

    /// A collision-free joint path from `from` to `to` (both ends included):
    /// the straight segment if it is free, else RRT-Connect (seeded, at most
    /// `max_iterations`) followed by shortcutting. `None` if none was found.
    pub fn plan_joint_path(
        &self,
        arm: &Ur5e,
        from: &Joints,
        to: &Joints,
        seed: u64,
        max_iterations: usize,
    ) -> Option<Vec<Joints>> {
        const STEP: f64 = 0.02; // collision check resolution (rad)
        const EXTEND: f64 = 0.3; // tree growth per step (rad)
        if self.collision(arm, from).is_some() || self.collision(arm, to).is_some() {
            return None;
        }
        if self.segment_free(arm, from, to, STEP) {
            return Some(vec![*from, *to]);
        }
        let mut rng = SplitMix64::new(seed);
        let mut trees: [Vec<(Joints, usize)>; 2] = [vec![(*from, usize::MAX)], vec![(*to, usize::MAX)]];
        for iteration in 0..max_iterations {
            let (a, b) = if iteration % 2 == 0 { (0, 1) } else { (1, 0) };
            let sample: Joints = std::array::from_fn(|i| {
                let (lo, hi) = (
                    arm.limits.lower[i].max(-std::f64::consts::PI),
                    arm.limits.upper[i].min(std::f64::consts::PI),
                );
                lo + (hi - lo) * (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64
            });
            let Some(new_a) = extend(self, arm, &mut trees[a], &sample, EXTEND, STEP) else {
                continue;
            };
            // Connect: grow the other tree towards the new node until blocked or joined.
            let target = trees[a][new_a].0;
            while let Some(new_b) = extend(self, arm, &mut trees[b], &target, EXTEND, STEP) {
                if max_joint_move(&trees[b][new_b].0, &target) < 1e-9 {
                    // root_a .. new_a, then (new_b is the same configuration) .. root_b.
                    let mut path = branch(&trees[a], new_a);
                    path.reverse();
                    path.extend(branch(&trees[b], new_b).drain(1..));
                    if a == 1 {
                        path.reverse();
                    }
                    return Some(self.shortcut(arm, path, STEP));
                }
            }
        }
        None
    }

    /// Drops waypoints that a straight free segment can skip.
    fn shortcut(&self, arm: &Ur5e, path: Vec<Joints>, step: f64) -> Vec<Joints> {
        let mut out = vec![path[0]];
        let mut i = 0;
        while i + 1 < path.len() {
            let mut j = path.len() - 1;
            while j > i + 1 && !self.segment_free(arm, &path[i], &path[j], step) {
                j -= 1;
            }
            out.push(path[j]);
            i = j;
        }
        out
    }
}

/// Grows `tree` from its nearest node towards `target` by at most `step`;
/// the new node's index, or `None` if that segment collides.
fn extend(
    world: &CollisionWorld,
    arm: &Ur5e,
    tree: &mut Vec<(Joints, usize)>,
    target: &Joints,
    step: f64,
    check: f64,
) -> Option<usize> {
    let (nearest, _) = tree
        .iter()
        .enumerate()
        .map(|(i, (q, _))| (i, max_joint_move(q, target)))
        .min_by(|x, y| x.1.total_cmp(&y.1))?;
    let from = tree[nearest].0;
    let d = max_joint_move(&from, target);
    let t = if d > step { step / d } else { 1.0 };
    let new: Joints = std::array::from_fn(|i| from[i] + t * (target[i] - from[i]));
    if !world.segment_free(arm, &from, &new, check) {
        return None;
    }
    tree.push((new, nearest));
    Some(tree.len() - 1)
}

/// The nodes from `index` back to the root.
fn branch(tree: &[(Joints, usize)], mut index: usize) -> Vec<Joints> {
    let mut out = Vec::new();
    loop {
        out.push(tree[index].0);
        if tree[index].1 == usize::MAX {
            return out;
        }
        index = tree[index].1;
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    const HOME: Joints = [0.0, -PI / 2.0, PI / 2.0, -PI / 2.0, -PI / 2.0, 0.0];

    fn table(z: f64) -> BoxObstacle {
        BoxObstacle {
            name: "table".to_owned(),
            world_from_box: Isometry3::translation(0.0, 0.0, z - 0.05),
            half_extents_m: Vector3::new(1.5, 1.5, 0.05),
        }
    }

    #[test]
    fn home_is_free_and_an_arm_through_the_table_is_not() {
        let arm = Ur5e::default();
        let world = CollisionWorld::new(Isometry3::identity(), &[table(-0.01)], ArmModel::default());
        assert_eq!(world.collision(&arm, &HOME), None);
        // Shoulder turned so the upper arm points down through the table.
        let mut down = HOME;
        down[1] = PI / 2.0;
        assert_eq!(world.collision(&arm, &down), Some("table"));
    }

    #[test]
    fn rrt_connect_goes_around_a_wall() {
        let arm = Ur5e::default();
        let from = [-1.0, -1.3, 1.6, -1.9, -1.57, 0.0];
        let to = [1.0, -1.3, 1.6, -1.9, -1.57, 0.0];
        // A post where the wrist passes halfway through the straight base swing.
        let mid = [0.0, -1.3, 1.6, -1.9, -1.57, 0.0];
        let wrist = arm.forward_frames(&mid)[4].translation.vector;
        let post = BoxObstacle {
            name: "post".to_owned(),
            world_from_box: Isometry3::translation(wrist.x, wrist.y, wrist.z),
            half_extents_m: Vector3::new(0.04, 0.04, 0.04),
        };
        let world = CollisionWorld::new(Isometry3::identity(), &[table(-0.01), post], ArmModel::default());
        assert!(world.collision(&arm, &from).is_none() && world.collision(&arm, &to).is_none());
        assert!(
            !world.segment_free(&arm, &from, &to, 0.02),
            "the straight swing must hit the post"
        );
        let path = world
            .plan_joint_path(&arm, &from, &to, 7, 4000)
            .expect("a path around the post");
        assert_eq!(path.first(), Some(&from));
        assert_eq!(path.last(), Some(&to));
        for pair in path.windows(2) {
            assert!(world.segment_free(&arm, &pair[0], &pair[1], 0.02));
        }
    }
}
