//! Property tests (fixed seeds) of the UR5e kinematics.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use robot_bridge::ur5e::Ur5e;

fn config(cases: u32) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(0x0055_5235),
        failure_persistence: None,
        ..Config::default()
    }
}

fn joints() -> impl Strategy<Value = [f64; 6]> {
    (prop::array::uniform6(-3.1f64..3.1)).prop_map(|q| q)
}

proptest! {
    #![proptest_config(config(512))]

    /// IK then FK gives the pose back (1e-6 m, 1e-6 rad) for every solution,
    /// and the joints the pose came from are among the solutions (up to 2 pi).
    #[test]
    fn ik_then_fk_returns_the_pose(q in joints()) {
        let arm = Ur5e::default();
        // Keep clear of the wrist singularity, where q4 and q6 are not unique.
        prop_assume!(q[4].sin().abs() > 1e-3);
        let target = arm.forward(&q);
        let solutions = arm.inverse(&target, q[5]);
        prop_assert!(!solutions.is_empty());
        for s in &solutions {
            let reached = arm.forward(s);
            prop_assert!((reached.translation.vector - target.translation.vector).norm() < 1e-6, "{s:?}");
            prop_assert!(reached.rotation.angle_to(&target.rotation) < 1e-6, "{s:?}");
        }
        let found = solutions.iter().any(|s| {
            (0..6).all(|i| {
                let d = (s[i] - q[i]).rem_euclid(std::f64::consts::TAU);
                d.min(std::f64::consts::TAU - d) < 1e-6
            })
        });
        prop_assert!(found, "the original joints are not among {solutions:?}");
    }

    /// The nearest solution from the original joints is the original joints.
    #[test]
    fn nearest_solution_is_the_current_one(q in joints()) {
        let arm = Ur5e::default();
        prop_assume!(q[4].sin().abs() > 1e-3);
        let nearest = arm.inverse_nearest(&arm.forward(&q), &q).unwrap();
        for i in 0..6 {
            prop_assert!((nearest[i] - q[i]).abs() < 1e-6, "joint {}: {:?} vs {:?}", i, nearest, q);
        }
    }

    /// Any finite pose: solutions that reach it, or none; never NaN.
    #[test]
    fn arbitrary_poses_give_exact_solutions_or_none(
        p in prop::array::uniform3(-1.2f64..1.2),
        axis in prop::array::uniform3(-1.0f64..1.0),
        angle in -3.1f64..3.1,
    ) {
        let arm = Ur5e::default();
        let rotation = UnitQuaternion::from_scaled_axis(Vector3::from(axis).normalize() * angle);
        prop_assume!(rotation.coords.iter().all(|v| v.is_finite()));
        let pose = Isometry3::from_parts(Translation3::from(Vector3::from(p)), rotation);
        for s in arm.inverse(&pose, 0.0) {
            prop_assert!(s.iter().all(|v| v.is_finite()));
            let reached = arm.forward(&s);
            prop_assert!((reached.translation.vector - pose.translation.vector).norm() < 1e-6);
            prop_assert!(reached.rotation.angle_to(&pose.rotation) < 1e-6);
        }
    }
}
