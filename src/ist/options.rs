//! The build options: everything that decides a link's tree besides its meshes (the packing
//! parameters, the tree builder, the gap's accuracy), and so part of the cache key.

use serde::{Deserialize, Serialize};

use super::build::TreeBuilder;
use crate::packing::PackingParams;

/// Everything that decides the trees besides the meshes (part of the cache key).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BuildOptions {
    pub packing: PackingParams,
    pub tree: TreeBuilder,
    /// Accuracy of the surface gap's branch and bound, m.
    pub gap_tolerance_m: f32,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self {
            packing: PackingParams::default(),
            tree: TreeBuilder::NeuralGas,
            gap_tolerance_m: 2e-5,
        }
    }
}
