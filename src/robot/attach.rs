//! Attached objects: a shape fixed to a link that the URDF does not have — the part in the
//! gripper, a tool, a cable guide. An object joins the robot as a link of its own, named after
//! it, under its `link` by a fixed joint at `link_from_object`, with its shape (a primitive, or
//! a mesh file taken in as a URDF link's) as its collision geometry. From there it is a link like any other: it is packed and certified, its
//! points are self-filtered (a held part is not an obstacle), and its distance to the world is
//! measured and published under its name (a held part that reaches a person stops the cell).

use nalgebra::Isometry3;

use super::error::RobotError;
use super::urdf::{load_shape, LinkGeometry, RobotModel};
use crate::geometry::Shape;

/// A shape fixed to a link of the robot.
#[derive(Debug, Clone, PartialEq)]
pub struct AttachedObject {
    /// Its link's name (unique in the robot).
    pub name: String,
    /// The robot link it is fixed to.
    pub link: String,
    pub shape: Shape,
    pub link_from_object: Isometry3<f64>,
}

impl RobotModel {
    /// Joins `object` to the robot as a link of its own (see the module doc).
    pub fn attach(&mut self, object: &AttachedObject) -> Result<(), RobotError> {
        let topology = |message: String| RobotError::Topology {
            path: self.urdf_path.display().to_string(),
            message,
        };
        let parent = self.kinematics.link_index(&object.link).ok_or_else(|| {
            topology(format!(
                "link {} is not a link of robot {}",
                object.link, self.name
            ))
        })?;
        if self.kinematics.link_index(&object.name).is_some() {
            return Err(topology(format!(
                "robot {} already has a link named {}",
                self.name, object.name
            )));
        }
        // A mesh goes through the intake as a URDF link's does (its report logged, kept for
        // the independent check).
        let (elements, intake) = load_shape(&object.name, &object.shape.to_urdf())?;
        self.kinematics.add_fixed_link(
            &format!("{}_attachment", object.name),
            &object.name,
            parent,
            object.link_from_object,
        );
        self.links.push(LinkGeometry {
            name: object.name.clone(),
            elements,
            intake: intake.into_iter().collect(),
            hull_of_volume_m3: None,
        });
        log::info!(
            "attached object {}: {} on link {}",
            object.name,
            object.shape,
            object.link
        );
        Ok(())
    }
}
