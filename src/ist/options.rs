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

impl BuildOptions {
    /// The options of a coarse tree to monitor with while the tree of these is built: the
    /// budget fixed at `start_spheres` (the h it reaches is certified and reported, like any);
    /// None when the budget is fixed already.
    pub fn coarse(&self) -> Option<BuildOptions> {
        (self.packing.start_spheres < self.packing.max_spheres).then(|| {
            let mut coarse = self.clone();
            coarse.packing.max_spheres = coarse.packing.start_spheres;
            coarse
        })
    }
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
