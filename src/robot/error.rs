//! Errors of the robot model stage (URDF, mesh files, kinematic tree): each names the file and,
//! where there is one, the link and the collision element, so that a user can find what to fix.

use std::path::PathBuf;

use super::mesh::MeshError;

/// Errors of the robot model stage; each names the file and, where there is one, the link and
/// the collision element (counted from 0 in the order of the URDF).
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    #[error("cannot read URDF {path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("malformed URDF {path}: {message}")]
    Urdf { path: PathBuf, message: String },
    #[error("URDF {path}: joint {joint} has unknown type '{kind}'")]
    UnknownJointType {
        path: PathBuf,
        joint: String,
        kind: String,
    },
    #[error("URDF {path}: {message}")]
    Topology { path: String, message: String },
    #[error("URDF {path}: {element} is not finite")]
    NonFinite { path: String, element: String },
    #[error(
        "link {link}, collision element {element}: package '{package}' of '{uri}' not found \
         (searched --package-path, ROS_PACKAGE_PATH, AMENT_PREFIX_PATH)"
    )]
    PackageNotFound {
        link: String,
        element: usize,
        uri: String,
        package: String,
    },
    #[error("link {link}, collision element {element}: unsupported mesh URI '{uri}'")]
    UnsupportedUri {
        link: String,
        element: usize,
        uri: String,
    },
    #[error("link {link}, collision element {element} ({what}): {message}")]
    Geometry {
        link: String,
        element: usize,
        what: String,
        message: String,
    },
    #[error("link {link}, collision element {element}, mesh {file}: {source}")]
    Mesh {
        link: String,
        element: usize,
        file: PathBuf,
        source: MeshError,
    },
    #[error("{} links cannot be loaded (fix each, or leave it out with exclude_links):\n  - {}", .0.len(), .0.iter().map(|e| e.to_string()).collect::<Vec<_>>().join("\n  - "))]
    Links(Vec<RobotError>),
    #[error("unknown joint '{0}'")]
    UnknownJoint(String),
    #[error("no value given for joint '{0}'")]
    MissingJoint(String),
}
