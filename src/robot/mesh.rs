//! Collision meshes: loading (STL, COLLADA, OBJ through mesh-loader), the strict closed mesh and
//! primitive tessellation, in the link frame, in metres.
//!
//! [`ClosedMesh::new`] is strict: it welds bit-identical vertices and refuses non-finite
//! vertices, degenerate triangles, open or non-manifold edges and zero volume (an inside-out
//! mesh is flipped, with a warning). Primitives and the shells the intake made pass through it.
//! Mesh files go through `robot::intake` first, which takes meshes as vendors ship them (CAD
//! noise, holes, non-manifold edges, hollow shells) and says what it did.

use std::collections::HashMap;
use std::f64::consts::PI;

use super::collada;
use super::fill::Fill;

pub use super::mesh_file::MeshFile;
use crate::geometry::{bounds_f64, box_mesh, mesh_volume, triangle_area, widen};

/// Why a mesh cannot be packed.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("cannot read mesh: {0}")]
    Load(String),
    #[error("mesh has no triangles")]
    Empty,
    #[error("vertex {vertex} is not finite ({value:?})")]
    NonFiniteVertex { vertex: usize, value: [f32; 3] },
    #[error("{count} degenerate (zero-area) triangles, the first is triangle {first}")]
    DegenerateTriangles { count: usize, first: usize },
    #[error(
        "mesh is not closed: {open_edges} open edges and {non_manifold_edges} non-manifold edges; \
         inner spheres need a watertight collision mesh (fix the mesh or use a primitive)"
    )]
    Open {
        open_edges: usize,
        non_manifold_edges: usize,
    },
    #[error("mesh encloses no volume ({volume_m3:.3e} m³)")]
    ZeroVolume { volume_m3: f64 },
    #[error("a shell cannot be oriented (its triangles disagree around a loop)")]
    Unorientable,
    #[error(
        "the mesh encloses nothing: its surface separates no inside from the outside \
         ({open_shells} shells could not be closed or oriented, as on a Möbius strip); fix the \
         mesh, use a primitive, or pack the link's convex hull (convex_hull_links)"
    )]
    EnclosesNothing { open_shells: usize },
    #[error(
        "{open_edges} open edges that do not close into loops (a hole's rim runs into an edge \
         shared by three or more triangles)"
    )]
    OpenChain { open_edges: usize },
}

/// A collision solid in a link frame (metres, f32): a closed, outward-oriented triangle mesh,
/// or, where the intake filled a mesh whose shells enclose space together (`robot::fill`), the
/// triangles that face the outside of a solid whose inside the fill decides.
#[derive(Debug, Clone)]
pub struct ClosedMesh {
    pub vertices: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    /// Enclosed volume, m³.
    pub volume_m3: f64,
    /// The flood fill that decides inside and outside, for a filled solid (then `triangles`
    /// need not be closed or oriented).
    pub fill: Option<std::sync::Arc<Fill>>,
}

impl ClosedMesh {
    /// Welds, validates and orients a triangle soup. `flip_warning` names the item in the warning
    /// given when the mesh was inside out.
    pub fn new(
        vertices: Vec<[f32; 3]>,
        triangles: Vec<[u32; 3]>,
        flip_warning: &str,
    ) -> Result<Self, MeshError> {
        check_soup(&vertices, &triangles)?;
        let (vertices, mut triangles) = weld(&vertices, &triangles)?;
        let extent = extent(&vertices);
        let min_area = (extent * extent * 1e-14).max(f64::MIN_POSITIVE);
        let degenerate: Vec<usize> = triangles
            .iter()
            .enumerate()
            .filter(|(_, t)| {
                t[0] == t[1]
                    || t[1] == t[2]
                    || t[0] == t[2]
                    || triangle_area(
                        widen(vertices[t[0] as usize]),
                        widen(vertices[t[1] as usize]),
                        widen(vertices[t[2] as usize]),
                    ) <= min_area
            })
            .map(|(i, _)| i)
            .collect();
        if let Some(&first) = degenerate.first() {
            return Err(MeshError::DegenerateTriangles {
                count: degenerate.len(),
                first,
            });
        }
        check_closed(&triangles)?;
        let mut volume = mesh_volume(&vertices, &triangles);
        if volume.abs() <= extent.powi(3) * 1e-9 {
            return Err(MeshError::ZeroVolume { volume_m3: volume });
        }
        if volume < 0.0 {
            log::warn!(
                "{flip_warning}: mesh is inside out (negative volume); flipped its triangles"
            );
            for t in &mut triangles {
                t.swap(1, 2);
            }
            volume = -volume;
        }
        Ok(Self {
            vertices,
            triangles,
            volume_m3: volume,
            fill: None,
        })
    }

    /// Axis-aligned bounds (min, max).
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        bounds(&self.vertices)
    }

    /// Surface area, m².
    pub fn area_m2(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                triangle_area(
                    widen(self.vertices[t[0] as usize]),
                    widen(self.vertices[t[1] as usize]),
                    widen(self.vertices[t[2] as usize]),
                )
            })
            .sum()
    }
}

/// Vertices and vertex-index triangles.
pub type TriangleSoup = (Vec<[f32; 3]>, Vec<[u32; 3]>);

/// Loads every piece of a mesh file.
pub fn load_mesh_file(path: &std::path::Path) -> Result<MeshFile, MeshError> {
    let bytes = std::fs::read(path).map_err(|e| MeshError::Load(e.to_string()))?;
    load_mesh_bytes(&bytes, path)
}

/// As [`load_mesh_file`], from the bytes of the file at `path` (its extension picks the
/// format). COLLADA goes through `robot::collada` (the scene's instances under their node
/// transforms); STL and OBJ through mesh-loader, each of its meshes appended here with its own
/// vertex offset (mesh-loader's own merge misplaces the third mesh on).
pub fn load_mesh_bytes(bytes: &[u8], path: &std::path::Path) -> Result<MeshFile, MeshError> {
    // Checked here: mesh-loader's own error for another format prints `{path:?}` literally.
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("dae") => return collada::read(bytes).map_err(MeshError::Load),
        Some("stl" | "obj") => {}
        _ => {
            return Err(MeshError::Load(format!(
                "{}: unsupported mesh format (STL, COLLADA .dae and OBJ are read)",
                path.display()
            )))
        }
    }
    let scene = mesh_loader::Loader::default()
        .merge_meshes(false)
        .load_from_slice(bytes, path)
        .map_err(|e| MeshError::Load(e.to_string()))?;
    let mut out = MeshFile {
        pieces: scene.meshes.len(),
        ..MeshFile::default()
    };
    for mesh in scene.meshes {
        let base = out.vertices.len();
        let n = mesh.vertices.len();
        if let Some(bad) = mesh.faces.iter().flatten().find(|&&i| i as usize >= n) {
            return Err(MeshError::Load(format!(
                "face index {bad} out of range ({n} vertices)"
            )));
        }
        if base + n > u32::MAX as usize {
            return Err(MeshError::Load("more than 2³² vertices".into()));
        }
        out.vertices.extend_from_slice(&mesh.vertices);
        out.triangles
            .extend(mesh.faces.iter().map(|f| f.map(|i| i + base as u32)));
    }
    if out.pieces > 1 {
        out.notes.push(format!(
            "{} {} read",
            out.pieces,
            if ext.as_deref() == Some("stl") {
                "solids"
            } else {
                "groups"
            }
        ));
    }
    Ok(out)
}

fn bounds(vertices: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for v in vertices {
        for k in 0..3 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    (lo, hi)
}

/// Refuses a soup with no triangle or a non-finite vertex.
pub(super) fn check_soup(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> Result<(), MeshError> {
    if triangles.is_empty() {
        return Err(MeshError::Empty);
    }
    if let Some((vertex, value)) = vertices
        .iter()
        .enumerate()
        .find(|(_, v)| v.iter().any(|x| !x.is_finite()))
    {
        return Err(MeshError::NonFiniteVertex {
            vertex,
            value: *value,
        });
    }
    Ok(())
}

/// The largest side of the bounds, m.
pub(super) fn extent(vertices: &[[f32; 3]]) -> f64 {
    let (lo, hi) = bounds_f64(vertices);
    (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)
}

/// Merges vertices with identical coordinates; drops unreferenced ones.
fn weld(vertices: &[[f32; 3]], triangles: &[[u32; 3]]) -> Result<TriangleSoup, MeshError> {
    let mut index: HashMap<[u32; 3], u32> = HashMap::with_capacity(vertices.len());
    let mut welded = Vec::with_capacity(vertices.len());
    let mut out = Vec::with_capacity(triangles.len());
    for t in triangles {
        let mut w = [0u32; 3];
        for k in 0..3 {
            let v = *vertices
                .get(t[k] as usize)
                .ok_or_else(|| MeshError::Load(format!("triangle index {} out of range", t[k])))?;
            // +0.0 and -0.0 are the same point.
            let key = v.map(|x| (x + 0.0).to_bits());
            w[k] = *index.entry(key).or_insert_with(|| {
                welded.push(v);
                (welded.len() - 1) as u32
            });
        }
        out.push(w);
    }
    Ok((welded, out))
}

/// Every undirected edge must be used exactly twice, once in each direction.
fn check_closed(triangles: &[[u32; 3]]) -> Result<(), MeshError> {
    let mut edges: HashMap<(u32, u32), (u32, u32)> = HashMap::with_capacity(triangles.len() * 2);
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let e = edges.entry((a.min(b), a.max(b))).or_default();
            if a < b {
                e.0 += 1;
            } else {
                e.1 += 1;
            }
        }
    }
    let mut open_edges = 0;
    let mut non_manifold_edges = 0;
    for &(fwd, back) in edges.values() {
        match (fwd, back) {
            (1, 1) => {}
            (f, b) if f + b == 1 => open_edges += 1,
            _ => non_manifold_edges += 1,
        }
    }
    if open_edges + non_manifold_edges > 0 {
        return Err(MeshError::Open {
            open_edges,
            non_manifold_edges,
        });
    }
    Ok(())
}

/// A tessellated primitive and the largest distance from the true surface to the tessellation,
/// which is added to the surface gap so that the gap stays an upper bound.
pub struct Tessellation {
    pub vertices: Vec<[f32; 3]>,
    pub triangles: Vec<[u32; 3]>,
    pub error_m: f64,
}

impl Tessellation {
    /// The triangles as an ASCII STL file (a shape given as a mesh file, as a CAD tool would
    /// export it: the benchmarks and tests of mesh volumes).
    pub fn to_ascii_stl(&self) -> String {
        let mut stl = String::from("solid shape\n");
        for tri in &self.triangles {
            stl.push_str(" facet normal 0 0 0\n  outer loop\n");
            for &i in tri {
                let v = self.vertices[i as usize];
                stl.push_str(&format!("   vertex {} {} {}\n", v[0], v[1], v[2]));
            }
            stl.push_str("  endloop\n endfacet\n");
        }
        stl.push_str("endsolid shape\n");
        stl
    }
}

/// Segments around a circle: the sagitta is R·(1 − cos(π/64)) ≈ 0.0012·R.
const SEGMENTS: usize = 64;

/// Box of `size` centred at the origin (exact).
pub fn tessellate_box(size: [f64; 3]) -> Tessellation {
    let (vertices, triangles) = box_mesh(size);
    Tessellation {
        vertices,
        triangles,
        error_m: 0.0,
    }
}

/// Cylinder of `radius` and `length` along z, centred at the origin, vertices on the true surface.
pub fn tessellate_cylinder(radius: f64, length: f64) -> Tessellation {
    let half = length / 2.0;
    lathe(
        &[(radius, -half), (radius, half)],
        radius * (1.0 - (PI / SEGMENTS as f64).cos()),
    )
}

/// Capsule: cylinder of `length` plus hemispherical caps of `radius`, along z.
pub fn tessellate_capsule(radius: f64, length: f64) -> Tessellation {
    let half = length / 2.0;
    let rings = SEGMENTS / 4;
    let mut profile = Vec::new();
    for i in 0..=rings {
        let a = -PI / 2.0 + PI / 2.0 * i as f64 / rings as f64;
        profile.push((radius * a.cos(), -half + radius * a.sin()));
    }
    for i in 0..=rings {
        let a = PI / 2.0 * i as f64 / rings as f64;
        profile.push((radius * a.cos(), half + radius * a.sin()));
    }
    lathe(&profile, sphere_sagitta(radius))
}

/// Sphere of `radius` centred at the origin.
pub fn tessellate_sphere(radius: f64) -> Tessellation {
    let rings = SEGMENTS / 2;
    let profile: Vec<(f64, f64)> = (0..=rings)
        .map(|i| {
            let a = -PI / 2.0 + PI * i as f64 / rings as f64;
            (radius * a.cos(), radius * a.sin())
        })
        .collect();
    lathe(&profile, sphere_sagitta(radius))
}

/// Largest gap between a sphere and a latitude–longitude tessellation of it with `SEGMENTS`
/// steps around and half as many from pole to pole (both angular steps are 2π/SEGMENTS): a
/// quad's farthest point from the sphere lies within the angle of its diagonal.
fn sphere_sagitta(radius: f64) -> f64 {
    let step = 2.0 * PI / SEGMENTS as f64;
    radius * (1.0 - (step / 2.0 * 2f64.sqrt()).cos())
}

/// Revolves a (radius, z) profile about z; rings of zero radius become poles, and the first and
/// last rings are closed by caps when their radius is not zero.
fn lathe(profile: &[(f64, f64)], error_m: f64) -> Tessellation {
    let n = SEGMENTS;
    let mut vertices: Vec<[f32; 3]> = Vec::new();
    // For each ring: Some(start index of n vertices) or None for a pole (single vertex index).
    let mut rings: Vec<Result<u32, u32>> = Vec::new();
    for &(r, z) in profile {
        if r <= 1e-12 * profile.iter().map(|p| p.0).fold(0.0, f64::max) {
            vertices.push([0.0, 0.0, z as f32]);
            rings.push(Err((vertices.len() - 1) as u32));
        } else {
            let start = vertices.len() as u32;
            for k in 0..n {
                let a = 2.0 * PI * k as f64 / n as f64;
                vertices.push([(r * a.cos()) as f32, (r * a.sin()) as f32, z as f32]);
            }
            rings.push(Ok(start));
        }
    }
    let n32 = n as u32;
    let mut triangles = Vec::new();
    for w in rings.windows(2) {
        for k in 0..n32 {
            let k1 = (k + 1) % n32;
            match (w[0], w[1]) {
                (Ok(a), Ok(b)) => {
                    triangles.push([a + k, a + k1, b + k1]);
                    triangles.push([a + k, b + k1, b + k]);
                }
                (Err(p), Ok(b)) => triangles.push([p, b + k1, b + k]),
                (Ok(a), Err(p)) => triangles.push([a + k, a + k1, p]),
                (Err(_), Err(_)) => {}
            }
        }
    }
    let mut cap = |ring: Result<u32, u32>, z: f64, bottom: bool| {
        if let Ok(start) = ring {
            vertices.push([0.0, 0.0, z as f32]);
            let c = (vertices.len() - 1) as u32;
            for k in 0..n32 {
                let (a, b) = (start + k, start + (k + 1) % n32);
                triangles.push(if bottom { [c, b, a] } else { [c, a, b] });
            }
        }
    };
    if let (Some(first), Some(last)) = (rings.first().copied(), rings.last().copied()) {
        cap(first, profile[0].1, true);
        cap(last, profile[profile.len() - 1].1, false);
    }
    Tessellation {
        vertices,
        triangles,
        error_m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn closed(t: Tessellation) -> ClosedMesh {
        ClosedMesh::new(t.vertices, t.triangles, "test").expect("closed")
    }

    #[test]
    fn primitives_are_closed_with_the_right_volume() {
        let b = closed(tessellate_box([0.1, 0.2, 0.3]));
        assert!((b.volume_m3 - 0.006).abs() < 1e-9);
        let c = closed(tessellate_cylinder(0.05, 0.2));
        let exact = PI * 0.05 * 0.05 * 0.2;
        assert!(c.volume_m3 < exact && c.volume_m3 > exact * 0.99);
        let s = closed(tessellate_sphere(0.05));
        let exact = 4.0 / 3.0 * PI * 0.05f64.powi(3);
        assert!(s.volume_m3 < exact && s.volume_m3 > exact * 0.99);
        let k = closed(tessellate_capsule(0.05, 0.1));
        let exact = exact + PI * 0.05 * 0.05 * 0.1;
        assert!(k.volume_m3 < exact && k.volume_m3 > exact * 0.99);
    }

    #[test]
    fn bad_meshes_are_refused() {
        let t = tessellate_box([1.0, 1.0, 1.0]);
        let mut open = t.triangles.clone();
        open.pop();
        assert!(matches!(
            ClosedMesh::new(t.vertices.clone(), open, "t"),
            Err(MeshError::Open { open_edges: 3, .. })
        ));
        let mut nan = t.vertices.clone();
        nan[3][1] = f32::NAN;
        assert!(matches!(
            ClosedMesh::new(nan, t.triangles.clone(), "t"),
            Err(MeshError::NonFiniteVertex { vertex: 3, .. })
        ));
        let mut degenerate = t.triangles.clone();
        degenerate.push([0, 0, 1]);
        assert!(matches!(
            ClosedMesh::new(t.vertices.clone(), degenerate, "t"),
            Err(MeshError::DegenerateTriangles {
                count: 1,
                first: 12
            })
        ));
        let flat = tessellate_box([1.0, 1.0, 0.0]);
        assert!(ClosedMesh::new(flat.vertices, flat.triangles, "t").is_err());
        let inverted: Vec<[u32; 3]> = t.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
        let m = ClosedMesh::new(t.vertices, inverted, "t").expect("flipped");
        assert!((m.volume_m3 - 1.0).abs() < 1e-9);
    }
}
