//! Link selection: which links of the URDF take part and which are packed as their convex hull,
//! by name. Given before the robot is loaded (`urdf`), so that a link left out never has its
//! meshes read; the packing and the query see only the links it selects.

/// Which links take part, by name, and which are packed as their convex hull: given before the
/// robot is loaded, so that a link left out never has its meshes read (a broken mesh on an
/// excluded link does not stop the load).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinkSelection {
    /// Only these (all when empty).
    pub include: Vec<String>,
    pub exclude: Vec<String>,
    /// Links replaced by the convex hull of their collision geometry (`*`: every link). A hull
    /// contains the link, so a certified lower bound for the hull is one for the link; its
    /// inner spheres may lie outside the link, so no upper bound follows (see `query`).
    pub convex_hull: Vec<String>,
}

impl LinkSelection {
    /// Whether link `name` takes part.
    pub fn selects(&self, name: &str) -> bool {
        (self.include.is_empty() || self.include.iter().any(|n| n == name))
            && !self.exclude.iter().any(|n| n == name)
    }

    /// Whether link `name` is packed as its convex hull.
    pub fn hull(&self, name: &str) -> bool {
        self.convex_hull.iter().any(|n| n == name || n == "*")
    }
}
