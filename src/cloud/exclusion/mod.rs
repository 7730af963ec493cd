//! Exclusion volumes: known parts of the cell (a table, a fixture, a conveyor) whose points are
//! dropped before the query, so that they neither stop the cell nor hide anything else.
//!
//! A volume is a primitive (`geometry::Primitive`: box, sphere, cylinder) or a mesh file's
//! solid dilated by a padding (`mesh`: a grid of signed distances) fixed in a TF frame
//! — the world, a fixture's frame, or a link of the robot — and applies to every source or to
//! those it names. Per cloud, the monitor places each volume in the cloud's sensor frame
//! (`sensor_from_volume`, looked up at the cloud's stamp as the sensor itself is) and
//! [`exclude`] makes every point inside one invalid (NaN), counting the points of each volume.
//! A point inside two volumes counts for the first in the list.
//!
//! The cost is kept off the points that cannot be inside: the cloud is cut into blocks of
//! [`BLOCK`] consecutive points (neighbours in an organized cloud), each block's bounding box
//! is tested against the box of every volume's sensor-frame box, then against each volume's
//! sensor-frame box, then against the volume's own box (the block's box turned into the
//! volume's frame: centre `R c + t`, half extents `|R| h`), and only the points of a block that
//! passes are tested one by one, in f32 in the volume's frame. Blocks run in parallel.
//!
//! What this costs in safety is what it says: a person inside an exclusion volume is not seen.
//! Volumes are shown in RViz (`outputs`) and their counts are in the diagnostics.
//!
//! Files: `volume` (as configured), `mesh` (a mesh file's dilated solid), `placed` (in a cloud's
//! sensor frame), `exclude` (the point loop).

mod exclude;
pub mod mesh;
mod placed;
mod volume;

pub use exclude::{exclude, BLOCK};
pub use mesh::MeshGrid;
pub use placed::Placed;
pub use volume::{ExclusionVolume, VolumeShape};
