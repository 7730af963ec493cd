//! Why a scenario cannot be generated: a robot without the camera's link or whose links the
//! kinematics lack, joint values it refuses, a hidden obstacle whose distance parry3d cannot
//! take, or the bag and cloud encoders' errors.

use crate::cloud::CloudError;

/// Why a scenario cannot be generated.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("the robot has no link {0} to mount the camera on")]
    NoCameraLink(String),
    #[error("link {0} has collision geometry but is not in the robot's kinematics")]
    NotInKinematics(String),
    #[error("joint values: {0}")]
    Joints(#[from] crate::robot::RobotError),
    #[error("the distance to the hidden obstacle: {0}")]
    HiddenTruth(String),
    #[error(transparent)]
    Bag(#[from] crate::bag::BagError),
    #[error(transparent)]
    Cloud(#[from] CloudError),
}
