//! An exclusion volume as configured: its shape (a primitive, or a mesh file's dilated solid),
//! the TF frame it is fixed in with its pose there, and the sources it applies to.

use std::sync::Arc;

use nalgebra::Isometry3;

use super::mesh::MeshGrid;
use crate::geometry::Primitive;

/// What an exclusion volume is: a primitive, or a mesh's dilated solid.
#[derive(Debug, Clone, PartialEq)]
pub enum VolumeShape {
    Primitive(Primitive),
    Mesh(Arc<MeshGrid>),
}

impl VolumeShape {
    /// The shape as configured (a mesh by its file and scale).
    pub fn shape(&self) -> crate::geometry::Shape {
        match self {
            VolumeShape::Primitive(p) => (*p).into(),
            VolumeShape::Mesh(g) => crate::geometry::Shape::Mesh {
                file: g.file.clone(),
                scale: g.scale,
            },
        }
    }
}

/// An exclusion volume as configured.
#[derive(Debug, Clone, PartialEq)]
pub struct ExclusionVolume {
    pub name: String,
    pub shape: VolumeShape,
    /// The TF frame (or robot link) it is fixed in.
    pub frame: String,
    pub frame_from_volume: Isometry3<f64>,
    /// The sources it applies to (every source when empty).
    pub sources: Vec<String>,
}

impl ExclusionVolume {
    /// Whether it applies to source `name`.
    pub fn applies_to(&self, source: &str) -> bool {
        self.sources.is_empty() || self.sources.iter().any(|s| s == source)
    }
}
