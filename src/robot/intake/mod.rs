//! Mesh intake: collision meshes as vendors ship them (STL with CAD noise, COLLADA with a few
//! open edges, visual meshes used as collision meshes: hollow shells with thin walls) made into
//! the closed, outward-oriented meshes the packing needs, each change counted in a
//! [`MeshReport`], and each triangle's [`TriangleFate`]. Input and output in the link frame,
//! metres.
//!
//! The steps, in order:
//! 1. **Weld** vertices closer than `WELD_RELATIVE` × the mesh's extent (reported as
//!    `weld_tolerance_m`): CAD exports write one vertex as −1.5e-17 and −5.1e-18, which bit-exact
//!    welding takes for two, leaving false open edges. The tolerance is far below any feature
//!    a collision mesh has (0.2 µm on a 20 cm link).
//! 2. **Degenerate triangles** (a repeated vertex after welding, or area ≤ 1e-14 × extent²)
//!    enclose nothing and are dropped. **Repeated triangles**: one of each orientation is kept;
//!    a face present in both orientations is an internal wall between two glued solids and is
//!    dropped.
//! 3. **Shells**: triangles connected through edges shared by exactly two triangles (an edge of
//!    three or more, non-manifold, connects nothing, so two solids touching along an edge come
//!    apart); each shell is oriented consistently by a walk over its edges.
//! 4. **Holes**: the open edges of a shell are chained into loops. A loop of no area (a
//!    T-junction: one long edge against a chain of collinear short ones) is a crack, sewn by
//!    splitting the triangle of the long edge at the chain's vertices; any other loop is closed
//!    by a fan of triangles around its centroid (any surface spanning a hole closes it; the
//!    report gives the largest loop's diameter). A rim that passes a vertex twice (holes
//!    touching at a corner) is split there into simple loops first. The edges are taken in
//!    sorted order, never a hash map's, so the same file gives the same mesh on every run.
//! 5. **The solid is everything the outside cannot reach.** Each closed shell is made
//!    outward-oriented (positive volume). A shell that lies wholly inside another (a hollow
//!    part's inner wall) adds nothing and is dropped: its vertices lie inside the outer shell
//!    and none of its triangles meets the outer surface (parry3d's intersection test), so it
//!    cannot cross it anywhere. One closed shell left is the element as it is: its inside test
//!    is the exact one of a closed oriented mesh (pseudo-normals in the packing, the f64
//!    winding number in `ist::validate`). So are several closed shells that lie apart (no
//!    surface meets another's, none holds another's vertex): each an element, and the space
//!    between them, a slot narrower than the fill's voxel included, is outside (issue 56: the
//!    fill closed a 1 mm slot between a vendor's body and its boss, and spheres grew into it).
//!    Shells that meet, or shells the repairs could not make
//!    closed, manifold and oriented, are one solid decided by an exterior flood fill
//!    (`robot::fill`): overlapping parts are their union, and the space they enclose together
//!    (a thin wall closed at its ends by other parts) is filled, with the triangles inside the
//!    solid dropped so that spheres grow across them. A wall thinner than the fill's voxel is
//!    still solid: the closed shells go with the fill, and a point inside one of them is inside
//!    (its own winding number), so a vendor's 1 mm housing open at its tube ends gets spheres.
//!
//! The guarantee stays: no inner sphere outside the solid, and h certified against the surface
//! that faces the outside. Refused, with the reason: a mesh whose surface, after all this,
//! separates no inside from the outside (a lone sheet, a Möbius strip).
//!
//! One file per step: `weld` (1, 2), `shells` (3), `holes` (4), `enclosed` (5); `pipeline`
//! runs them in order, `report` counts what each did.

mod enclosed;
mod holes;
mod pipeline;
mod report;
mod shells;
mod weld;

pub use pipeline::intake;
pub use report::{MeshReport, TriangleFate};
pub use weld::WELD_RELATIVE;
