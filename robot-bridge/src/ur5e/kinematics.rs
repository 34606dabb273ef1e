//! UR5e forward and closed-form inverse kinematics (standard DH convention).
//!
//! `A_i = Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i)`; `forward` gives
//! `base_from_flange`. The inverse follows the standard UR derivation
//! (shoulder, wrist and elbow each have two branches: up to 8 solutions).
//! Degenerate cases never produce NaN: a pose whose wrist centre is closer
//! to the base axis than `d4` is unreachable, and when the wrist is singular
//! (`sin q5 ~ 0`, joints 4 and 6 aligned) `q6` takes the caller's hint and
//! `q4` absorbs the rest.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use nalgebra::{Isometry3, Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion, Vector3, Vector4};

use crate::error::{Error, Result};

/// Six joint angles (rad), base to wrist 3.
pub type Joints = [f64; 6];

/// The arm upright, its forearm level and the tool pointing down: where the
/// emulator starts and a dry run stands.
pub const HOME: Joints = [0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0];

/// Standard DH parameters of a 6-axis UR arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DhParams {
    /// Link offsets d_i (m).
    pub d: [f64; 6],
    /// Link lengths a_i (m).
    pub a: [f64; 6],
    /// Link twists alpha_i (rad).
    pub alpha: [f64; 6],
}

impl DhParams {
    /// The UR5e's nominal parameters (Universal Robots' published DH table).
    pub fn ur5e() -> Self {
        Self {
            d: [0.1625, 0.0, 0.0, 0.1333, 0.0997, 0.0996],
            a: [0.0, -0.425, -0.3922, 0.0, 0.0, 0.0],
            alpha: [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0],
        }
    }

    /// The homogeneous transform of link `i` at angle `q`.
    fn link(&self, i: usize, q: f64) -> Matrix4<f64> {
        let (ct, st) = (q.cos(), q.sin());
        let (ca, sa) = (self.alpha[i].cos(), self.alpha[i].sin());
        let (a, d) = (self.a[i], self.d[i]);
        Matrix4::new(
            ct,
            -st * ca,
            st * sa,
            a * ct, //
            st,
            ct * ca,
            -ct * sa,
            a * st, //
            0.0,
            sa,
            ca,
            d, //
            0.0,
            0.0,
            0.0,
            1.0,
        )
    }
}

/// Joint position limits (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lower bounds.
    pub lower: Joints,
    /// Upper bounds.
    pub upper: Joints,
}

impl JointLimits {
    /// UR5e: +-360 deg on every joint but the elbow, which is kept to
    /// +-180 deg (its cable and self-collision range).
    pub fn ur5e() -> Self {
        Self {
            lower: [-TAU, -TAU, -PI, -TAU, -TAU, -TAU],
            upper: [TAU, TAU, PI, TAU, TAU, TAU],
        }
    }

    /// True when every joint is within its limits.
    pub fn contains(&self, q: &Joints) -> bool {
        (0..6).all(|i| q[i] >= self.lower[i] && q[i] <= self.upper[i])
    }
}

/// A UR5e arm: geometry and limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ur5e {
    /// DH parameters.
    pub dh: DhParams,
    /// Joint limits.
    pub limits: JointLimits,
}

impl Default for Ur5e {
    fn default() -> Self {
        Self {
            dh: DhParams::ur5e(),
            limits: JointLimits::ur5e(),
        }
    }
}

/// Where a UR arm's wrist centre reaches ([`Ur5e::wrist_reach`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WristReach {
    /// The shoulder above the base origin, along the base z (m).
    pub shoulder_height_m: f64,
    /// Farthest the wrist centre lies from the shoulder (m).
    pub max_m: f64,
    /// Nearest the wrist centre comes to the base z axis (m).
    pub min_axis_m: f64,
    /// The wrist centre behind the flange, along the flange z (m).
    pub centre_back_m: f64,
}

/// Weights of each joint's move when choosing among IK solutions.
const MOVE_WEIGHTS: [f64; 6] = [2.0, 2.0, 1.5, 1.0, 1.0, 0.5];

/// Below this |sin q5| the wrist is treated as singular.
const WRIST_SINGULAR: f64 = 1e-9;

impl Ur5e {
    /// Where the wrist centre (the origin of the frame after joint 5, `d6`
    /// back from the flange along its z) can be, in the base frame: at most
    /// [`WristReach::max_m`] from the shoulder (the origin after joint 1),
    /// at least [`WristReach::min_axis_m`] from the base z axis. Both follow
    /// from the DH table: joints 2-4 swing the wrist in one plane through
    /// the shoulder (at most `|a2| + |a3|` out, then `d5` further in the
    /// plane and `d4` across it), and [`Ur5e::inverse`] has no solution
    /// whose wrist centre lies nearer the base axis than `d4`.
    pub fn wrist_reach(&self) -> WristReach {
        let (d, a) = (&self.dh.d, &self.dh.a);
        WristReach {
            shoulder_height_m: d[0],
            max_m: (a[1].abs() + a[2].abs() + d[4]).hypot(d[3]),
            min_axis_m: d[3],
            centre_back_m: d[5],
        }
    }

    /// The base frame and the frame after each joint (the last is the flange).
    pub fn forward_frames(&self, q: &Joints) -> [Isometry3<f64>; 7] {
        let mut frames = [Isometry3::identity(); 7];
        let mut m = Matrix4::identity();
        for i in 0..6 {
            m *= self.dh.link(i, q[i]);
            frames[i + 1] = to_isometry(&m);
        }
        frames
    }

    /// `base_from_flange` for joint angles `q`.
    pub fn forward(&self, q: &Joints) -> Isometry3<f64> {
        let m = (0..6).fold(Matrix4::identity(), |acc, i| acc * self.dh.link(i, q[i]));
        to_isometry(&m)
    }

    /// Every joint solution (up to 8, each angle in (-pi, pi]) that puts the
    /// flange at `base_from_flange`. `q6_hint` is used for `q6` when the
    /// wrist is singular. An unreachable pose gives an empty list.
    pub fn inverse(&self, base_from_flange: &Isometry3<f64>, q6_hint: f64) -> Vec<Joints> {
        let (d, a) = (&self.dh.d, &self.dh.a);
        let t06 = base_from_flange.to_homogeneous();
        let mut solutions = Vec::with_capacity(8);
        // Wrist centre: d6 back along the flange z.
        let p05 = t06 * Vector4::new(0.0, 0.0, -d[5], 1.0);
        let r = p05.x.hypot(p05.y);
        if r < d[3] * (1.0 + 1e-12) {
            return solutions;
        }
        let phi = p05.y.atan2(p05.x);
        let psi = (d[3] / r).clamp(-1.0, 1.0).acos();
        for shoulder in [1.0, -1.0] {
            let q1 = phi + shoulder * psi + FRAC_PI_2;
            let (s1, c1) = q1.sin_cos();
            let p06 = t06.fixed_view::<3, 1>(0, 3);
            let c5 = ((p06.x * s1 - p06.y * c1 - d[3]) / d[5]).clamp(-1.0, 1.0);
            for wrist in [1.0, -1.0] {
                let q5 = wrist * c5.acos();
                let s5 = q5.sin();
                let q6 = if s5.abs() < WRIST_SINGULAR {
                    q6_hint
                } else {
                    // From T60 = inverse(T06): its x and y axes' components.
                    let t60 = t06.try_inverse().unwrap_or_else(Matrix4::identity);
                    let (x60, y60) = (t60.column(0), t60.column(1));
                    ((-x60.y * s1 + y60.y * c1) / s5).atan2((x60.x * s1 - y60.x * c1) / s5)
                };
                // T14 = T01^-1 T06 (T45 T56)^-1.
                let t01 = self.dh.link(0, q1);
                let t46 = self.dh.link(4, q5) * self.dh.link(5, q6);
                let (Some(t10), Some(t64)) = (t01.try_inverse(), t46.try_inverse()) else {
                    continue;
                };
                let t14 = t10 * t06 * t64;
                let p13 = t14 * Vector4::new(0.0, -d[3], 0.0, 1.0) - Vector4::new(0.0, 0.0, 0.0, 1.0);
                let p13_norm = p13.xyz().norm();
                let c3 = (p13_norm * p13_norm - a[1] * a[1] - a[2] * a[2]) / (2.0 * a[1] * a[2]);
                if !(-1.0 - 1e-9..=1.0 + 1e-9).contains(&c3) || p13_norm < 1e-12 {
                    continue;
                }
                for elbow in [1.0, -1.0] {
                    let q3 = elbow * c3.clamp(-1.0, 1.0).acos();
                    let q2 = -(p13.y.atan2(-p13.x)) + (a[2] * q3.sin() / p13_norm).clamp(-1.0, 1.0).asin();
                    let t13 = self.dh.link(1, q2) * self.dh.link(2, q3);
                    let Some(t31) = t13.try_inverse() else { continue };
                    let t34 = t31 * t14;
                    let q4 = t34[(1, 0)].atan2(t34[(0, 0)]);
                    let q = [q1, q2, q3, q4, q5, q6].map(wrap);
                    if q.iter().all(|v| v.is_finite()) {
                        solutions.push(q);
                    }
                }
            }
        }
        solutions
    }

    /// The solution within the joint limits closest to `current`, each joint
    /// taking the 2 pi turn nearest to its current angle. Closest means the
    /// smallest weighted sum of joint moves, the base and shoulder weighing
    /// most (they swing the whole arm) and the last wrist least; an error
    /// when none reaches.
    pub fn inverse_nearest(&self, base_from_flange: &Isometry3<f64>, current: &Joints) -> Result<Joints> {
        check_joints("current", current)?;
        check_pose("base_from_flange", base_from_flange)?;
        let solutions = self.inverse(base_from_flange, current[5]);
        let moves = solutions.iter().filter_map(|q| self.branch_move(q, current));
        nearest(moves).map(|m| m.joints).ok_or_else(|| {
            let p = base_from_flange.translation.vector;
            Error::Unreachable(format!(
                "no UR5e joint solution within the limits reaches ({:.3}, {:.3}, {:.3}) m",
                p.x, p.y, p.z
            ))
        })
    }

    /// Every solution within the joint limits, each joint taking the 2 pi
    /// turn nearest to its current angle: [`Ur5e::inverse_nearest`]'s first,
    /// the rest by their weighted move from `current`; empty when none
    /// reaches.
    pub fn inverse_ranked(&self, base_from_flange: &Isometry3<f64>, current: &Joints) -> Result<Vec<Joints>> {
        check_joints("current", current)?;
        check_pose("base_from_flange", base_from_flange)?;
        let mut ranked: Vec<BranchMove> = self
            .inverse(base_from_flange, current[5])
            .iter()
            .filter_map(|q| self.branch_move(q, current))
            .collect();
        ranked.sort_by(|a, b| a.total.total_cmp(&b.total).then(a.largest.total_cmp(&b.largest)));
        if let Some(lead) = nearest(ranked.iter().copied()) {
            let at = ranked.iter().position(|m| m.joints == lead.joints).unwrap_or(0);
            ranked.swap(0, at);
        }
        Ok(ranked.into_iter().map(|m| m.joints).collect())
    }

    /// One inverse solution `q` moved, joint by joint, to the 2 pi turn
    /// nearest to `current` within the limits, with its move from `current`;
    /// `None` when some joint has no turn within its limits.
    fn branch_move(&self, q: &Joints, current: &Joints) -> Option<BranchMove> {
        let mut joints = [0.0; 6];
        for i in 0..6 {
            joints[i] = [-2.0, -1.0, 0.0, 1.0, 2.0]
                .iter()
                .map(|k| q[i] + k * TAU)
                .filter(|v| *v >= self.limits.lower[i] && *v <= self.limits.upper[i])
                .min_by(|x, y| (x - current[i]).abs().total_cmp(&(y - current[i]).abs()))?;
        }
        let (largest, total) = (0..6)
            .map(|i| (joints[i] - current[i]).abs())
            .zip(MOVE_WEIGHTS)
            .fold((0.0f64, 0.0f64), |(m, s), (v, w)| (m.max(v), s + w * v));
        Some(BranchMove {
            total,
            largest,
            joints,
        })
    }
}

/// An arm branch and how far it is from the current joints.
#[derive(Clone, Copy)]
struct BranchMove {
    /// Weighted sum of the joint moves (rad, [`MOVE_WEIGHTS`]).
    total: f64,
    /// The largest single joint move (rad).
    largest: f64,
    joints: Joints,
}

/// The nearest branch: the smallest weighted total; among totals within
/// 1e-12 of it (mirror solutions), the smallest largest move.
fn nearest(moves: impl Iterator<Item = BranchMove> + Clone) -> Option<BranchMove> {
    let least = moves.clone().map(|m| m.total).fold(f64::INFINITY, f64::min);
    moves
        .filter(|m| m.total <= least + 1e-12)
        .min_by(|a, b| a.largest.total_cmp(&b.largest).then(a.total.total_cmp(&b.total)))
}

/// The largest single-joint difference between two joint vectors (rad).
pub fn max_joint_move(a: &Joints, b: &Joints) -> f64 {
    (0..6).fold(0.0f64, |m, i| m.max((a[i] - b[i]).abs()))
}

/// An angle wrapped into (-pi, pi].
fn wrap(q: f64) -> f64 {
    let w = q.rem_euclid(TAU);
    if w > PI { w - TAU } else { w }
}

fn to_isometry(m: &Matrix4<f64>) -> Isometry3<f64> {
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r));
    let rotation = UnitQuaternion::new_normalize(rotation.into_inner());
    Isometry3::from_parts(
        Translation3::from(Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)])),
        rotation,
    )
}

/// Finite joint values, else an error naming `field`.
pub fn check_joints(field: &'static str, q: &Joints) -> Result<()> {
    if q.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Error::InvalidInput {
            field,
            reason: format!("joint angles must be finite, got {q:?}"),
        })
    }
}

/// A finite pose, else an error naming `field`.
pub fn check_pose(field: &'static str, pose: &Isometry3<f64>) -> Result<()> {
    let finite = pose.translation.vector.iter().all(|v| v.is_finite())
        && pose.rotation.coords.iter().all(|v| v.is_finite());
    if finite {
        Ok(())
    } else {
        Err(Error::InvalidInput {
            field,
            reason: "pose must be finite".to_owned(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn zero_pose_matches_the_dh_table() {
        // All joints at 0: the arm stretched along -x, flange at
        // (a2 + a3, -(d4 + d6), d1 - d5) in UR's base frame.
        let arm = Ur5e::default();
        let p = arm.forward(&[0.0; 6]).translation.vector;
        let expected = Vector3::new(-0.425 - 0.3922, -(0.1333 + 0.0996), 0.1625 - 0.0997);
        assert!((p - expected).norm() < 1e-12, "{p:?}");
    }

    #[test]
    fn a_typical_pose_has_eight_solutions_that_all_reach_it() {
        let arm = Ur5e::default();
        let q = [0.3, -1.2, 1.4, -1.6, -1.3, 0.7];
        let target = arm.forward(&q);
        let solutions = arm.inverse(&target, 0.0);
        assert_eq!(solutions.len(), 8);
        for s in &solutions {
            let reached = arm.forward(s);
            assert!((reached.translation.vector - target.translation.vector).norm() < 1e-9);
            assert!(reached.rotation.angle_to(&target.rotation) < 1e-9);
        }
        let nearest = arm.inverse_nearest(&target, &q).unwrap();
        for i in 0..6 {
            assert!(
                (nearest[i] - q[i]).abs() < 1e-9,
                "joint {i}: {nearest:?} vs {q:?}"
            );
        }
    }

    /// Every branch within the limits, each reaching the pose, the nearest
    /// first and the rest by their weighted move from `current`.
    #[test]
    fn ranked_solutions_start_with_the_nearest_and_all_reach_the_pose() {
        let arm = Ur5e::default();
        let q = [0.3, -1.2, 1.4, -1.6, -1.3, 0.7];
        let target = arm.forward(&q);
        let ranked = arm.inverse_ranked(&target, &q).unwrap();
        assert_eq!(ranked.len(), 8, "{ranked:?}");
        assert_eq!(ranked[0], arm.inverse_nearest(&target, &q).unwrap());
        let cost = |s: &Joints| (0..6).map(|i| MOVE_WEIGHTS[i] * (s[i] - q[i]).abs()).sum::<f64>();
        for pair in ranked.windows(2) {
            assert!(cost(&pair[0]) <= cost(&pair[1]) + 1e-12, "{pair:?}");
        }
        for s in &ranked {
            let reached = arm.forward(s);
            assert!((reached.translation.vector - target.translation.vector).norm() < 1e-9);
            assert!(reached.rotation.angle_to(&target.rotation) < 1e-9);
            assert!((0..6).all(|i| s[i] >= arm.limits.lower[i] && s[i] <= arm.limits.upper[i]));
        }
        let far = Isometry3::translation(2.0, 0.0, 0.3);
        assert!(arm.inverse_ranked(&far, &q).unwrap().is_empty());
    }

    /// The nearest solution leads the ranked list for poses seen from
    /// other joints, the wrist-singular ones (mirror ties) included, and no
    /// ranked branch moves less.
    #[test]
    fn the_nearest_leads_the_ranked_list_from_any_start() {
        let arm = Ur5e::default();
        let starts = [
            [0.0, -FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, -FRAC_PI_2, 0.0],
            [1.1, -0.8, 1.9, -2.6, 0.0, 2.0],
            [-2.4, -2.0, -1.0, 0.4, 1.2, -3.0],
        ];
        let targets = [
            [0.3, -1.2, 1.4, -1.6, -1.3, 0.7],
            [-0.9, -1.7, 2.1, -0.4, 0.0, 0.5],
            [2.8, -0.5, -1.8, 2.9, 2.2, -1.1],
        ];
        let mut compared = 0;
        for start in &starts {
            for q in &targets {
                let target = arm.forward(q);
                let ranked = arm.inverse_ranked(&target, start).unwrap();
                let nearest = arm.inverse_nearest(&target, start).unwrap();
                assert_eq!(ranked[0], nearest);
                let cost = |s: &Joints| {
                    (0..6)
                        .map(|i| MOVE_WEIGHTS[i] * (s[i] - start[i]).abs())
                        .sum::<f64>()
                };
                assert!(
                    ranked.iter().all(|s| cost(&nearest) <= cost(s) + 1e-12),
                    "{ranked:?}"
                );
                compared += 1;
            }
        }
        assert_eq!(compared, 9);
    }

    #[test]
    fn out_of_reach_is_an_error_not_nan() {
        let arm = Ur5e::default();
        let far = Isometry3::translation(2.0, 0.0, 0.3);
        assert!(arm.inverse(&far, 0.0).is_empty());
        assert!(matches!(
            arm.inverse_nearest(&far, &[0.0; 6]),
            Err(Error::Unreachable(_))
        ));
        let nan = Isometry3::translation(f64::NAN, 0.0, 0.3);
        assert!(matches!(
            arm.inverse_nearest(&nan, &[0.0; 6]),
            Err(Error::InvalidInput { .. })
        ));
    }

    #[test]
    fn singular_wrist_keeps_the_hint() {
        let arm = Ur5e::default();
        // q5 = 0: joints 4 and 6 aligned.
        let q = [0.2, -1.0, 1.2, -0.5, 0.0, 0.4];
        let target = arm.forward(&q);
        let solutions = arm.inverse(&target, 0.4);
        assert!(!solutions.is_empty());
        for s in &solutions {
            assert!(s.iter().all(|v| v.is_finite()));
            let reached = arm.forward(s);
            assert!(
                (reached.translation.vector - target.translation.vector).norm() < 1e-6,
                "{s:?}"
            );
            assert!(reached.rotation.angle_to(&target.rotation) < 1e-6);
        }
    }
}
