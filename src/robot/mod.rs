//! Robot model stage: URDF → collision geometry of every link (closed meshes in the link frame,
//! metres) and the kinematic tree that poses the links (f64). Its output feeds the sphere
//! packing (`packing`), and the link poses that the query (`query`) and the monitor use.
//!
//! The files, in the order of the data: `urdf` reads the robot (`selection` picks its links,
//! `error` names what failed) and `kinematics` its tree; a mesh file is read by `mesh` (STL,
//! OBJ) or `collada` into a `mesh_file`, taken in by `intake` (welded, closed, filled), and
//! closed by `mesh`, which also tessellates the primitives; `solid` (parry3d, f32), `surface`
//! and `exact` (f64) and `fill` answer inside and distance for the packing and the checks;
//! `attach` joins the cell's known objects to the robot as links.

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
pub use intake::{MeshReport, TriangleFate};
pub use kinematics::{Kinematics, LinkVelocity};
pub use mesh::{ClosedMesh, MeshError};
pub use selection::LinkSelection;
pub use urdf::{CollisionElement, LinkGeometry, MeshIntake, PackagePath, RobotModel};
