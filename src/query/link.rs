//! The links as the query sees them: each selected link's tree, its surface gap and, for exact
//! mode, its solids ([`QueryLink`]), with the structure-of-arrays copies the CPU descent reads
//! ([`SphereSoa`]); and the check of a link selection against the robot before anything is
//! built.

use super::error::QueryError;
use super::layout::MAX_LINKS;
use crate::ist::{IstNode, LinkTree};
use crate::packing::{InnerSphere, Solid};
use crate::robot::{LinkGeometry, LinkSelection, RobotModel};

/// One link as the query sees it: its tree, its surface gap and, for exact mode, its solids.
pub struct QueryLink {
    pub name: String,
    /// Index into the kinematics' link poses.
    pub pose_index: usize,
    pub nodes: Vec<IstNode>,
    pub spheres: Vec<InnerSphere>,
    /// Certified surface gap h, m.
    pub gap_m: f32,
    /// One solid per collision element (elements may overlap, so they are kept apart).
    pub solids: Vec<Solid>,
    /// Packed as its convex hull: its inner-sphere distance is no upper bound of the link's,
    /// so the result gives its certified lower bound as its distance.
    pub convex_hull: bool,
    /// Structure-of-arrays copies of the node and sphere arrays for the CPU descent (four
    /// children tested at once); derived from `nodes` and `spheres` by [`QueryLink::new`].
    pub(crate) node_soa: SphereSoa,
    pub(crate) sphere_soa: SphereSoa,
}

/// Sphere centres and radii as four arrays, padded with four far spheres so that four
/// consecutive entries can always be loaded.
#[derive(Debug, Clone, Default)]
pub(crate) struct SphereSoa {
    pub x: Vec<f32>,
    pub y: Vec<f32>,
    pub z: Vec<f32>,
    pub r: Vec<f32>,
}

impl SphereSoa {
    fn new(spheres: impl Iterator<Item = ([f32; 3], f32)>) -> Self {
        let mut soa = Self::default();
        for (c, r) in spheres.chain(std::iter::repeat_n(([1e30; 3], 0.0), 4)) {
            soa.x.push(c[0]);
            soa.y.push(c[1]);
            soa.z.push(c[2]);
            soa.r.push(r);
        }
        soa
    }
}

impl QueryLink {
    /// A link from its tree and, for exact mode, its collision geometry.
    pub fn from_tree(tree: &LinkTree, geometry: Option<&LinkGeometry>, pose_index: usize) -> Self {
        let solids = geometry
            .map(|g| g.elements.iter().map(|e| Solid::new(&e.mesh)).collect())
            .unwrap_or_default();
        let mut link = Self::new(
            tree.link.clone(),
            pose_index,
            tree.nodes.clone(),
            tree.spheres.clone(),
            // Rounded up: h is a bound the lower bound subtracts.
            crate::geometry::f32_at_least(tree.quality.gap_m),
            solids,
        );
        link.convex_hull = geometry.is_some_and(|g| g.hull_of_volume_m3.is_some());
        link
    }

    /// A link from its tree, surface gap, solids and index into the link poses.
    pub fn new(
        name: String,
        pose_index: usize,
        nodes: Vec<IstNode>,
        spheres: Vec<InnerSphere>,
        gap_m: f32,
        solids: Vec<Solid>,
    ) -> Self {
        let node_soa = SphereSoa::new(nodes.iter().map(|n| (n.center, n.radius)));
        let sphere_soa = SphereSoa::new(spheres.iter().map(|s| (s.center, s.radius)));
        Self {
            name,
            pose_index,
            nodes,
            spheres,
            gap_m,
            solids,
            convex_hull: false,
            node_soa,
            sphere_soa,
        }
    }
}

impl LinkSelection {
    /// Checks the selection against `model` before anything is built: every name it gives is a
    /// link with collision geometry, and the links it selects are at least one and at most
    /// [`MAX_LINKS`].
    pub fn check(&self, model: &RobotModel) -> Result<(), QueryError> {
        // Links the selection left out when the robot was loaded are known by name.
        let names = || {
            model
                .links
                .iter()
                .map(|l| l.name.as_str())
                .chain(model.unloaded_links.iter().map(String::as_str))
        };
        let hulls = self.convex_hull.iter().filter(|n| n.as_str() != "*");
        for name in self.include.iter().chain(&self.exclude).chain(hulls) {
            if !names().any(|n| n == name) {
                return Err(QueryError::UnknownLink(
                    name.clone(),
                    names().collect::<Vec<_>>().join(", "),
                ));
            }
        }
        match model.links.iter().filter(|l| self.selects(&l.name)).count() {
            0 => Err(QueryError::NoLinks),
            n if n > MAX_LINKS => Err(QueryError::TooManyLinks(n)),
            _ => Ok(()),
        }
    }
}
