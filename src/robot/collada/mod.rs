//! COLLADA (.dae) collision meshes as the file's scene places them: every `<instance_geometry>`
//! (and `<instance_controller>`'s skin source) reached from the scene's `<instance_visual_scene>`,
//! through nested `<node>`s and `<instance_node>`s, under the product of the node transforms
//! (`<matrix>`, `<translate>`, `<rotate>`, `<scale>`, `<lookat>`, `<skew>`, in document order),
//! scaled by the asset's `<unit meter>`. This is how RViz 2 (Assimp with its up-direction
//! conversion switched off) and Gazebo (its own COLLADA reader) place a mesh: the unit applied,
//! the `<up_axis>` not. MoveIt's geometric_shapes also drops the unit (it resets Assimp's root
//! transform); where the two differ, a file's `<unit>` other than 1 is noted. Output in metres,
//! before the URDF's `scale`.
//!
//! Geometry is read from `<triangles>`, `<polylist>`, `<polygons>` (outer `<p>` of `<ph>`),
//! `<trifans>` and `<tristrips>`; polygons are fanned. Lines and points enclose nothing and are
//! noted. A geometry the scene does not instantiate is left out and noted; a file with no scene
//! takes every geometry once, untransformed, noted. Every count is checked against the numbers
//! present before anything is allocated from it, and every index against its array.
//!
//! Written here rather than taken from mesh-loader, whose COLLADA path loads each geometry once
//! whether or not the scene instantiates it, and whose merge of three or more meshes offsets
//! the third one's indices by the second one's count alone (`fuzz/regressions/mesh/`).
//!
//! `scene` reads the document and walks its nodes, `geometry` places each geometry instance,
//! `xml` finds elements, their numbers and their place for messages.

mod geometry;
mod scene;
mod xml;

pub use scene::read;
