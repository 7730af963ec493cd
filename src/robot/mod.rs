//! Robot model stage: URDF → collision geometry of every link (closed meshes in the link frame,
//! metres) and the kinematic tree that poses the links (f64). Its output feeds the sphere
//! packing (`packing`), and the link poses that the query (`query`) and the monitor use.

pub mod kinematics;
pub mod mesh;
pub mod urdf;

pub use kinematics::{Kinematics, LinkVelocity};
pub use mesh::{ClosedMesh, MeshError};
pub use urdf::{CollisionElement, LinkGeometry, PackagePath, RobotModel};

use std::path::PathBuf;

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
    #[error("unknown joint '{0}'")]
    UnknownJoint(String),
    #[error("no value given for joint '{0}'")]
    MissingJoint(String),
}
