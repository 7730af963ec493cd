//! The query's one error: why an engine could not be made over a robot's links, or why a query
//! was refused before any point was measured (its poses, its options, its size, a cloud whose
//! coordinates are too coarse where the robot is).

use super::layout::MAX_LINKS;

#[derive(Debug, thiserror::Error)]
pub enum QueryError {
    #[error(
        "link {0} named in the link selection has no collision geometry (links with geometry: {1})"
    )]
    UnknownLink(String, String),
    #[error("link {0} has an inner sphere tree but is not in the robot's kinematics")]
    NotInKinematics(String),
    #[error("{0} links selected; the engine handles at most {MAX_LINKS}")]
    TooManyLinks(usize),
    #[error("link {link}: tree depth {depth} exceeds the traversal stack (at most {max})")]
    TreeTooDeep {
        link: String,
        depth: usize,
        max: usize,
    },
    #[error("link {0}: a tree no descent can walk (empty, a node with more children than the tree's branching, or a child outside its arrays or before its parent)")]
    BadTree(String),
    #[error("no link selected")]
    NoLinks,
    #[error("the sensor pose is not finite")]
    NonFiniteSensorPose,
    #[error("option {0}")]
    BadOption(&'static str),
    #[error("{0} points: point indices are 32-bit")]
    TooManyPoints(usize),
    #[error("{got} link poses given, the robot has {expected} links")]
    LinkPoses { got: usize, expected: usize },
    #[error(
        "the cloud's f32 coordinates are {spacing_m} m apart where the robot is ({offset_m:.0} m \
         from the origin of the cloud's frame), coarser than the {limit_m} m the query certifies: \
         publish the cloud in a frame near the robot"
    )]
    CoarseCloud {
        spacing_m: f32,
        offset_m: f64,
        limit_m: f32,
    },
}
