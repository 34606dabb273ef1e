//! The UR5e arm.

mod kinematics;

pub use kinematics::{
    DhParams, HOME, JointLimits, Joints, Ur5e, WristReach, check_joints, check_pose, max_joint_move,
};
