//! What the IST stage hands on, per link and in the link frame: the tree's nodes (`IstNode`,
//! the GPU's layout as it is), its inner spheres, and the measured quality of the packing.

use bytemuck::{Pod, Zeroable};
use serde::{Deserialize, Serialize};

use crate::packing::InnerSphere;

/// A node of an inner sphere tree: a sphere bounding its children, which are
/// `child_count` consecutive entries from `first_child` of the node array, or of the sphere
/// array when `children_are_spheres` is 1. WGSL mirror (32 bytes): `Node` in
/// `shaders/traverse.wgsl`, checked member by member against `query::layout::MIRRORS`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Pod, Zeroable)]
pub struct IstNode {
    pub center: [f32; 3],
    pub radius: f32,
    pub first_child: u32,
    pub child_count: u32,
    pub children_are_spheres: u32,
    pub pad: u32,
}
const _: () = assert!(std::mem::size_of::<IstNode>() == 32);

/// Measured quality of a link's packing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinkQuality {
    pub spheres: usize,
    /// The sphere budget the link was packed with: `start_spheres`, or the spheres its gap pass
    /// placed beyond it, grown while its h was above its target, up to `max_spheres`.
    pub budget: usize,
    /// Sphere volume / mesh volume.
    pub coverage: f64,
    /// Certified upper bound of the surface gap h, m (tessellation error of primitives
    /// included): the value `validate` measured, in f64, on the packed surface and on the mesh
    /// files' own triangles (the larger of `elements_gap_m` and `file_gap_m`).
    pub gap_m: f64,
    /// Certified bound of the gap on the packed surface (the intake's closed meshes), m.
    pub elements_gap_m: f64,
    /// Certified bound of the gap on the mesh files' own triangles outside the solid, m (0
    /// where every file was taken as it was: its triangles are the packed surface).
    pub file_gap_m: f64,
    /// Largest sampled surface-to-spheres distance, m (h lies in [gap_sampled_m, gap_m]).
    pub gap_sampled_m: f64,
    pub mesh_volume_m3: f64,
    /// Sum of the node sphere volumes, m³.
    pub tree_volume_m3: f64,
    /// Wall time of the build (packing, gap and tree), s; 0 for a tree from the cache (the
    /// cache stores no times).
    pub build_s: f64,
    /// Wall time of its validation (`validate`), s; 0 for a tree from the cache, which was
    /// validated before it was stored.
    pub validate_s: f64,
    /// Where `build_s` went, per stage (zero from the cache).
    #[serde(default)]
    pub stages: StageTimes,
    /// Largest distance sampled from the mesh files' own triangles to the spheres, m, outside
    /// the solid where above `elements_gap_m` (at most `gap_m`).
    pub file_gap_sampled_m: f64,
    /// The farthest point of the files' own triangles that is neither inside the solid nor
    /// within `elements_gap_m` of the spheres, where there is one: what sets h above the
    /// packed surface's.
    pub uncovered: Option<Uncovered>,
}

/// The wall time of a link's build by stage, s, summed over the budget's doublings: the
/// packing's growth, the gap estimate that decides whether to grow again, and the tree.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct StageTimes {
    pub packing_s: f64,
    pub gap_estimate_s: f64,
    pub tree_s: f64,
    /// How many budgets were packed (1 + the doublings).
    pub rounds: u32,
}

/// A point of a mesh file's own triangles (as read, before the intake's repairs) outside the
/// link's solid and farther from the spheres than any point of the packed surface: a part of
/// the file the intake dropped or moved (no sphere can reach it, since spheres stay inside).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Uncovered {
    /// The collision element whose mesh file holds it (`robot::MeshIntake::element`).
    pub element: usize,
    /// The triangle's index in the file as read.
    pub triangle: usize,
    /// The point, link frame, m.
    pub point: [f64; 3],
    /// Its distance to the spheres, m.
    pub gap_m: f64,
    /// Its distance to the packed surface, m: how far the intake's closed meshes pass from it.
    pub packed_surface_m: f64,
}

/// The inner sphere tree of one link.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkTree {
    pub link: String,
    pub nodes: Vec<IstNode>,
    pub spheres: Vec<InnerSphere>,
    pub quality: LinkQuality,
}
