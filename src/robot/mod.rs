//! Robot model stage: URDF → collision geometry of every link (closed meshes in the link frame,
//! metres) and the kinematic tree that poses the links (f64). Its output feeds the sphere
//! packing (`packing`), and the link poses that the query (`query`) and the monitor use.

pub mod attach;
pub mod collada;
pub mod error;
pub mod exact;
pub mod fill;
pub mod intake;
pub mod kinematics;
pub mod mesh;
pub mod mesh_file;
pub mod selection;
pub mod solid;
pub mod surface;
pub mod urdf;

pub use attach::AttachedObject;
pub use error::RobotError;
pub use intake::MeshReport;
pub use kinematics::{Kinematics, LinkVelocity};
pub use mesh::{ClosedMesh, MeshError};
pub use selection::LinkSelection;
pub use urdf::{CollisionElement, LinkGeometry, MeshIntake, PackagePath, RobotModel};
