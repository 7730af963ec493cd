//! What the intake did to one mesh file, counted per step (`super`'s module doc numbers them):
//! the pieces read, vertices welded, triangles dropped, holes closed or sewn, shells reoriented,
//! nested, emptied or filled. The log's one line per mesh and `--json`'s per-element report;
//! and per triangle of the file, its [`TriangleFate`], which `ist::validate`'s report of a
//! point the spheres cannot reach names.

/// What the intake did to one mesh file.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct MeshReport {
    /// Pieces the file holds (COLLADA geometry instances, STL solids, OBJ groups), all read.
    pub pieces: usize,
    /// What the reader noted (geometries the scene leaves out, a unit applied, ...).
    pub notes: Vec<String>,
    pub triangles_in: usize,
    /// Vertices closer than this were merged, m.
    pub weld_tolerance_m: f64,
    /// Vertices merged with another that was not bit-identical (CAD noise).
    pub welded_vertices: usize,
    pub degenerate_triangles: usize,
    pub repeated_triangles: usize,
    /// Edges used by one triangle, before the holes were closed.
    pub open_edges: usize,
    /// Edges used by three or more triangles.
    pub non_manifold_edges: usize,
    pub holes_closed: usize,
    /// Holes of no area (T-junctions) sewn by splitting the triangle across them.
    pub cracks_sewn: usize,
    /// Diameter of the largest hole closed, m.
    pub largest_hole_m: f64,
    pub shells: usize,
    /// Shells whose triangles were turned to agree with their neighbours, or turned outward.
    pub shells_reoriented: usize,
    /// Shells wholly inside another (a hollow part's inner walls): the solid fills them.
    pub inner_shells: usize,
    /// Shells enclosing no volume, dropped.
    pub empty_shells: usize,
    /// Shells still not closed and manifold after the repairs: their triangles go to the fill.
    pub open_shells: usize,
    /// The voxel of the exterior flood fill, m, when the shells were filled as one solid
    /// (gaps narrower than it are taken as closed).
    pub fill_voxel_m: Option<f64>,
    /// Triangles inside the filled solid (not facing the outside), dropped.
    pub inner_triangles: usize,
}

impl MeshReport {
    /// Whether the mesh was taken as it is (one closed shell, nothing welded but identical
    /// vertices, nothing dropped, closed or turned).
    pub fn clean(&self) -> bool {
        self.shells <= 1 && self.untouched()
    }

    /// Whether no repair touched the file's shells: nothing welded but identical vertices,
    /// dropped, opened, closed, sewn or turned.
    fn untouched(&self) -> bool {
        self.welded_vertices == 0
            && self.degenerate_triangles == 0
            && self.repeated_triangles == 0
            && self.open_edges == 0
            && self.non_manifold_edges == 0
            && self.shells_reoriented == 0
            && self.empty_shells == 0
            && self.cracks_sewn == 0
            && self.open_shells == 0
    }

    /// Whether the solid is the file's own: every shell closed and outward as the file gives
    /// it (nothing welded but identical vertices, dropped, closed, sewn or turned), none nested
    /// in another, none filled. A clean file, or closed shells that lie apart: inside is where
    /// the file's own winding number is 1 (an independent check takes it from the file).
    pub fn solid_as_given(&self) -> bool {
        self.untouched() && self.inner_shells == 0 && self.fill_voxel_m.is_none()
    }

    /// One line: what the mesh needed.
    pub fn summary(&self) -> String {
        let mut line = self.repairs();
        if self.pieces > 1 {
            line = format!("{} pieces, {line}", self.pieces);
        }
        for n in &self.notes {
            line.push_str("; ");
            line.push_str(n);
        }
        line
    }

    fn repairs(&self) -> String {
        if self.clean() {
            return format!(
                "closed, {} triangles (weld tolerance {:.1e} m)",
                self.triangles_in, self.weld_tolerance_m
            );
        }
        let mut parts = vec![format!(
            "{} triangles, weld tolerance {:.1e} m",
            self.triangles_in, self.weld_tolerance_m
        )];
        let mut say = |n: usize, what: &str| {
            if n > 0 {
                parts.push(format!("{n} {what}"));
            }
        };
        say(self.welded_vertices, "near-identical vertices welded");
        say(self.degenerate_triangles, "degenerate triangles dropped");
        say(self.repeated_triangles, "repeated triangles dropped");
        say(self.open_edges, "open edges");
        say(self.non_manifold_edges, "non-manifold edges");
        say(self.shells_reoriented, "shells reoriented");
        say(self.inner_shells, "inner shells filled (hollow part)");
        say(self.empty_shells, "empty shells dropped");
        say(self.cracks_sewn, "T-junction cracks sewn");
        say(
            self.open_shells,
            "shells not closed by the repairs (taken by the flood fill)",
        );
        if let Some(v) = self.fill_voxel_m {
            parts.push(format!(
                "filled by an exterior flood fill ({:.2} mm voxels; {} inner triangles dropped)",
                v * 1e3,
                self.inner_triangles
            ));
        }
        if self.holes_closed > 0 {
            parts.push(format!(
                "{} holes closed (largest {:.2} mm)",
                self.holes_closed,
                self.largest_hole_m * 1e3
            ));
        }
        parts.push(format!("{} shells", self.shells));
        parts.join(", ")
    }
}

/// What the intake did with one triangle of the file (by its index in the file as read).
/// `shell` numbers the file's shells in the order of their first triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TriangleFate {
    /// In a closed shell taken as the element.
    Kept { shell: u32 },
    /// A repeated vertex after welding, or no area: dropped.
    Degenerate,
    /// A copy of another triangle: dropped.
    Repeated,
    /// Present in both orientations (a wall between two glued solids): dropped.
    InternalWall,
    /// In a shell that encloses no volume: dropped.
    EmptyShell { shell: u32 },
    /// In a shell wholly inside another (a hollow part's inner wall): dropped, the solid fills
    /// it.
    InnerShell { shell: u32 },
    /// Given to the exterior flood fill, its shell closed (`open` false) or not closed by the
    /// repairs: kept where it faces the outside (`facing`), dropped inside the solid.
    Filled {
        shell: u32,
        open: bool,
        facing: bool,
    },
}

impl TriangleFate {
    /// In words, for messages.
    pub fn describe(&self) -> String {
        match *self {
            Self::Kept { shell } => format!("kept, in closed shell {shell}"),
            Self::Degenerate => "dropped by the intake as degenerate".into(),
            Self::Repeated => "dropped by the intake as a repeated triangle".into(),
            Self::InternalWall => {
                "dropped by the intake as an internal wall (both orientations)".into()
            }
            Self::EmptyShell { shell } => {
                format!("dropped by the intake with empty shell {shell} (no volume)")
            }
            Self::InnerShell { shell } => {
                format!("dropped by the intake with inner shell {shell} (inside another)")
            }
            Self::Filled {
                shell,
                open,
                facing,
            } => format!(
                "{} shell {shell}, taken by the flood fill, {}",
                if open { "open" } else { "closed" },
                if facing {
                    "kept as facing the outside"
                } else {
                    "dropped as inside the solid"
                }
            ),
        }
    }
}
