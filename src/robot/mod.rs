//! Robot model stage: URDF → collision geometry of every link (closed meshes in the link frame,
//! metres) and the kinematic tree that poses the links (f64). Its output feeds the sphere
//! packing (`packing`), and the link poses that the query (`query`) and the monitor use.

pub mod attach;
pub mod collada;
pub mod exact;
pub mod fill;
pub mod intake;
pub mod kinematics;
pub mod mesh;
pub mod solid;
pub mod urdf;

pub use attach::AttachedObject;
pub use intake::MeshReport;
pub use kinematics::{Kinematics, LinkVelocity};
pub use mesh::{ClosedMesh, MeshError};
pub use urdf::{CollisionElement, LinkGeometry, MeshIntake, PackagePath, RobotModel};

/// Which links take part, by name, and which are packed as their convex hull: given before the
/// robot is loaded, so that a link left out never has its meshes read (a broken mesh on an
/// excluded link does not stop the load).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinkSelection {
    /// Only these (all when empty).
    pub include: Vec<String>,
    pub exclude: Vec<String>,
    /// Links replaced by the convex hull of their collision geometry (`*`: every link). A hull
    /// contains the link, so a certified lower bound for the hull is one for the link; its
    /// inner spheres may lie outside the link, so no upper bound follows (see `query`).
    pub convex_hull: Vec<String>,
}

impl LinkSelection {
    /// Whether link `name` takes part.
    pub fn selects(&self, name: &str) -> bool {
        (self.include.is_empty() || self.include.iter().any(|n| n == name))
            && !self.exclude.iter().any(|n| n == name)
    }

    /// Whether link `name` is packed as its convex hull.
    pub fn hull(&self, name: &str) -> bool {
        self.convex_hull.iter().any(|n| n == name || n == "*")
    }
}

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
    #[error("{} links cannot be loaded (fix each, or leave it out with exclude_links):\n  - {}", .0.len(), .0.iter().map(|e| e.to_string()).collect::<Vec<_>>().join("\n  - "))]
    Links(Vec<RobotError>),
    #[error("unknown joint '{0}'")]
    UnknownJoint(String),
    #[error("no value given for joint '{0}'")]
    MissingJoint(String),
}
