//! Skeletons, motions and kinematics: the data model everything else stands on.
//! Conventions: y is up, column vectors (a joint's world rotation is `parent_world * local`),
//! positions in the skeleton's own unit (see [`Skeleton::meters_per_unit`]).

pub mod contacts;
pub mod cycle;
mod hands;
pub mod ik;
mod keys;
mod knees;
mod kinematics;
mod names;
mod posing;
mod retarget;
mod root_motion;
mod roles;
mod rotation;
mod skeleton;
mod solve;
mod standard;
mod take;
mod turns;

pub use hands::keep_hands_above_floor;
pub use kinematics::{forward_kinematics, LocalPose};
pub use keys::{guess_key_joints, Key, KeyJoints};
pub use knees::keep_knees_above_floor;
pub use names::Side;
pub use posing::{Effector, PoseRig};
pub use retarget::{mapped_bones, mean_bone_angle, RestPose, Retarget, RetargetError};
pub use roles::{JointRoles, Leg, RolesError};
pub use root_motion::{facing, local_poses, under_new_root, with_root_motion, RootMotion, RootMotionError, ROOT_BONE};
pub use rotation::{euler_to_quat, quat_to_euler, unwrap_angle, EulerOrder};
pub use skeleton::{clipped, Skeleton, SkeletonError, SHORT_BONE_FRACTION};
pub use solve::solve_local_poses;
pub use standard::standard_humanoid;
pub use turns::{bone_turns, spread_snaps, SNAP_QUANTILE};
pub use take::{floor_height, mean_joint_step, peak_accelerations, quantile, Motion};
