//! What a mesh file reader hands on: every piece of the file (COLLADA instances, STL solids, OBJ
//! groups) in one triangle soup, in file units (COLLADA: metres, its `<unit>` applied), and what
//! the reader noted. Filled by `collada` and by `mesh`'s STL and OBJ path; the intake
//! (`intake`) takes it from there, after the URDF's scale and origin (`urdf`).

/// Every piece of a mesh file (COLLADA instances, STL solids, OBJ groups) in one soup, in file
/// units (COLLADA: metres, its `<unit>` applied), with what the reader noted.
#[derive(Debug, Clone, Default)]
pub struct MeshFile {
    pub vertices: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// Pieces read: COLLADA geometry instances, STL solids, OBJ groups.
    pub pieces: usize,
    pub notes: Vec<String>,
}
