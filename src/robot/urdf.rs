//! URDF loading: parses the robot description (urdf-rs), resolves mesh URIs, loads and checks the
//! collision geometry of each link and moves it into the link frame.
//!
//! Mesh URIs: `package://NAME/rest` is looked up in `--package-path NAME=DIR` entries first, then
//! in `ROS_PACKAGE_PATH` (an entry that is the package itself, or holds it as a sub-folder), then
//! in `AMENT_PREFIX_PATH` (`PREFIX/share/NAME`). `file:///abs` is a plain path. Any other path is
//! relative to the URDF's folder. A mesh's `scale` is applied before the element's origin.
//! Primitives (box, cylinder, sphere, capsule) are tessellated with their error recorded.

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3};

use super::error::RobotError;
use super::intake::{intake, MeshReport, TriangleFate};
use super::kinematics::{pose_from_urdf, Kinematics};
use super::mesh::{
    load_mesh_file, tessellate_box, tessellate_capsule, tessellate_cylinder, tessellate_sphere,
    ClosedMesh, MeshError, Tessellation, TriangleSoup,
};
use super::selection::LinkSelection;

/// One `--package-path NAME=DIR` entry.
#[derive(Debug, Clone, PartialEq)]
pub struct PackagePath {
    pub name: String,
    pub dir: PathBuf,
}

impl std::str::FromStr for PackagePath {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let (name, dir) = s
            .split_once('=')
            .ok_or_else(|| format!("expected NAME=DIR, got '{s}'"))?;
        if name.is_empty() || dir.is_empty() {
            return Err(format!("expected NAME=DIR, got '{s}'"));
        }
        Ok(Self {
            name: name.to_owned(),
            dir: PathBuf::from(dir),
        })
    }
}

/// One collision element of a link, as a closed mesh in the link frame.
#[derive(Debug, Clone)]
pub struct CollisionElement {
    /// Position among the link's `<collision>` elements.
    pub index: usize,
    /// What it came from, for messages: `mesh FILE` or the primitive and its size.
    pub source: String,
    pub mesh: ClosedMesh,
    /// Largest distance from the described surface to `mesh` (primitive tessellation), metres.
    pub tessellation_error_m: f64,
    /// For a sphere primitive, its centre in the link frame: its best inner sphere is known.
    pub sphere_center: Option<[f64; 3]>,
}

/// The collision geometry of one link.
#[derive(Debug, Clone)]
pub struct LinkGeometry {
    pub name: String,
    /// The closed meshes packed; a mesh file gives one per outer shell (`robot::intake`), so
    /// several may share an `index`.
    pub elements: Vec<CollisionElement>,
    /// What the intake did to each mesh file of the link.
    pub intake: Vec<MeshIntake>,
    /// The link's collision geometry was replaced by its convex hull (`LinkSelection::
    /// convex_hull`): its volume before, m³. The hull contains the link: distances to it are
    /// lower bounds of the link's, never upper bounds.
    pub hull_of_volume_m3: Option<f64>,
}

/// The intake of one mesh file.
#[derive(Debug, Clone)]
pub struct MeshIntake {
    /// The collision element (position among the link's `<collision>` elements).
    pub element: usize,
    pub file: PathBuf,
    pub report: MeshReport,
    /// The file's own triangles in the link frame (metres, the URDF's scale and origin
    /// applied), before any repair: on which `ist::validate` measures h too.
    pub original: std::sync::Arc<TriangleSoup>,
    /// What the intake did with each of those triangles, by index.
    pub fates: std::sync::Arc<Vec<TriangleFate>>,
}

/// A robot loaded from a URDF: kinematics and the collision geometry of its links.
#[derive(Debug, Clone)]
pub struct RobotModel {
    pub name: String,
    pub urdf_path: PathBuf,
    pub kinematics: Kinematics,
    /// Links with collision geometry, in URDF order.
    pub links: Vec<LinkGeometry>,
    /// Links without collision geometry.
    pub skipped_links: Vec<String>,
    /// Links with collision geometry that the link selection left out: their meshes were
    /// never read.
    pub unloaded_links: Vec<String>,
}

impl RobotModel {
    /// Loads a URDF file and the collision geometry of the links `selection` selects.
    pub fn load(
        path: &Path,
        packages: &[PackagePath],
        selection: &LinkSelection,
    ) -> Result<Self, RobotError> {
        let xml = std::fs::read_to_string(path).map_err(|source| RobotError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::from_text(
            &xml,
            path,
            path.parent().unwrap_or(Path::new(".")),
            packages,
            selection,
        )
    }

    /// A robot from URDF text; `path` names it in errors (the file, or where the text came
    /// from) and relative mesh paths are taken from `base`. Every selected link is loaded even
    /// when one fails, so that the error lists every link that needs fixing.
    pub fn from_text(
        xml: &str,
        path: &Path,
        base: &Path,
        packages: &[PackagePath],
        selection: &LinkSelection,
    ) -> Result<Self, RobotError> {
        let robot = parse_urdf(xml, path)?;
        let kinematics = Kinematics::from_urdf(&robot, &path.display().to_string())?;
        let mut links = Vec::new();
        let mut skipped_links = Vec::new();
        let mut unloaded_links = Vec::new();
        let mut failed = Vec::new();
        for link in &robot.links {
            if link.collision.is_empty() {
                skipped_links.push(link.name.clone());
                continue;
            }
            if !selection.selects(&link.name) {
                unloaded_links.push(link.name.clone());
                continue;
            }
            let mut geometry = LinkGeometry {
                name: link.name.clone(),
                elements: Vec::new(),
                intake: Vec::new(),
                hull_of_volume_m3: None,
            };
            for (index, collision) in link.collision.iter().enumerate() {
                match load_element(&link.name, index, collision, base, packages) {
                    Ok((elements, intake)) => {
                        geometry.elements.extend(elements);
                        geometry.intake.extend(intake);
                    }
                    Err(e) => failed.push(e),
                }
            }
            if selection.hull(&link.name) && !geometry.elements.is_empty() {
                match convex_hull(&geometry) {
                    Ok(hull) => {
                        log::info!(
                            "link {}: packed as its convex hull ({:.3e} m³ against {:.3e} m³ of \
                             mesh): its distance is the certified lower bound",
                            link.name,
                            hull.mesh.volume_m3,
                            geometry
                                .elements
                                .iter()
                                .map(|e| e.mesh.volume_m3)
                                .sum::<f64>()
                        );
                        geometry.hull_of_volume_m3 =
                            Some(geometry.elements.iter().map(|e| e.mesh.volume_m3).sum());
                        geometry.elements = vec![hull];
                    }
                    Err(message) => failed.push(RobotError::Geometry {
                        link: link.name.clone(),
                        element: 0,
                        what: "convex hull".into(),
                        message,
                    }),
                }
            }
            for i in &geometry.intake {
                let level = if i.report.clean() {
                    log::Level::Debug
                } else {
                    log::Level::Info
                };
                log::log!(
                    level,
                    "link {}, collision element {} ({}): {}",
                    link.name,
                    i.element,
                    i.file.display(),
                    i.report.summary()
                );
            }
            links.push(geometry);
        }
        match failed.len() {
            0 => {}
            1 => return Err(failed.remove(0)),
            _ => return Err(RobotError::Links(failed)),
        }
        if !skipped_links.is_empty() {
            log::info!(
                "{}: links without collision geometry, skipped: {}",
                path.display(),
                skipped_links.join(", ")
            );
        }
        Ok(Self {
            name: robot.name,
            urdf_path: path.to_owned(),
            kinematics,
            links,
            skipped_links,
            unloaded_links,
        })
    }
}

/// Parses URDF text, naming the joint when its type is unknown.
fn parse_urdf(xml: &str, path: &Path) -> Result<urdf_rs::Robot, RobotError> {
    urdf_rs::read_from_string(xml).map_err(|e| {
        let message = e.to_string();
        if let Some(kind) = message
            .split("unknown variant `")
            .nth(1)
            .and_then(|rest| rest.split('`').next())
        {
            if let Some(joint) = joint_with_type(xml, kind) {
                return RobotError::UnknownJointType {
                    path: path.to_owned(),
                    joint,
                    kind: kind.to_owned(),
                };
            }
        }
        RobotError::Urdf {
            path: path.to_owned(),
            message,
        }
    })
}

/// The name of the first `<joint>` whose `type` attribute is `kind`.
fn joint_with_type(xml: &str, kind: &str) -> Option<String> {
    xml.split("<joint").skip(1).find_map(|element| {
        let tag = element.split('>').next()?;
        let attribute = |name: &str| {
            ['"', '\''].iter().find_map(|q| {
                let start = tag.find(&format!("{name}={q}"))? + name.len() + 2;
                Some(tag[start..].split(*q).next()?.to_owned())
            })
        };
        (attribute("type")? == kind).then(|| attribute("name"))?
    })
}

/// Which collision element a step works on, for its errors.
#[derive(Clone, Copy)]
struct ElementAt<'a> {
    link: &'a str,
    index: usize,
}

impl ElementAt<'_> {
    fn geometry(self, what: &str, message: String) -> RobotError {
        RobotError::Geometry {
            link: self.link.to_owned(),
            element: self.index,
            what: what.to_owned(),
            message,
        }
    }

    fn mesh(self, file: &Path, source: MeshError) -> RobotError {
        RobotError::Mesh {
            link: self.link.to_owned(),
            element: self.index,
            file: file.to_owned(),
            source,
        }
    }
}

/// A collision element's geometry as read, in its own frame, before the URDF's scale and origin.
struct ReadGeometry {
    /// What it came from, for messages: `mesh FILE` or the primitive and its size.
    source: String,
    tessellation: Tessellation,
    scale: [f64; 3],
    /// For a mesh file: its path, and the pieces and notes of its reader.
    file: Option<(PathBuf, (usize, Vec<String>))>,
}

/// One `<collision>` element of link `link`: read, moved into the link frame, and closed (a
/// primitive) or taken in (a mesh file, `robot::intake`).
fn load_element(
    link: &str,
    index: usize,
    collision: &urdf_rs::Collision,
    base: &Path,
    packages: &[PackagePath],
) -> Result<(Vec<CollisionElement>, Option<MeshIntake>), RobotError> {
    let at = ElementAt { link, index };
    let origin_values = collision
        .origin
        .xyz
        .iter()
        .chain(collision.origin.rpy.iter());
    if origin_values.clone().any(|v| !v.is_finite()) {
        return Err(at.geometry("origin", "origin is not finite".into()));
    }
    let link_from_element = pose_from_urdf(&collision.origin);
    let ReadGeometry {
        source,
        tessellation,
        scale,
        file,
    } = read_geometry(at, &collision.geometry, base, packages)?;
    let vertices = to_link_frame(&tessellation.vertices, scale, &link_from_element);
    let mut triangles = tessellation.triangles;
    if scale.iter().filter(|s| **s < 0.0).count() % 2 == 1 {
        // A mirroring scale turns the mesh inside out; restore the orientation.
        for t in &mut triangles {
            t.swap(1, 2);
        }
    }
    let label = format!("link {link}, collision element {index} ({source})");
    let element = |mesh, source| CollisionElement {
        index,
        source,
        mesh,
        tessellation_error_m: tessellation.error_m,
        sphere_center: matches!(collision.geometry, urdf_rs::Geometry::Sphere { .. }).then(|| {
            let c = link_from_element.translation.vector;
            [c.x, c.y, c.z]
        }),
    };
    match file {
        // A mesh file as its vendor made it: welded, closed and filled by the intake.
        Some((file, (pieces, notes))) => {
            let (shells, intake) = take_in(at, file, pieces, notes, vertices, triangles)?;
            let n = shells.len();
            let elements = shells
                .into_iter()
                .enumerate()
                .map(|(k, mesh)| {
                    let label = if n > 1 {
                        format!("{source}, shell {}", k + 1)
                    } else {
                        source.clone()
                    };
                    element(mesh, label)
                })
                .collect();
            Ok((elements, Some(intake)))
        }
        // A primitive, tessellated here: closed by construction.
        None => {
            let mesh = ClosedMesh::new(vertices, triangles, &label)
                .map_err(|e| at.geometry(&source_label(&collision.geometry), e.to_string()))?;
            Ok((vec![element(mesh, source)], None))
        }
    }
}

/// Reads a collision element's geometry: a mesh file whole, or a primitive tessellated, each
/// checked (finite, positive sizes; a finite, non-zero scale).
fn read_geometry(
    at: ElementAt,
    geometry: &urdf_rs::Geometry,
    base: &Path,
    packages: &[PackagePath],
) -> Result<ReadGeometry, RobotError> {
    let positive = |what: &str, values: &[f64]| {
        if values.iter().all(|v| v.is_finite() && *v > 0.0) {
            Ok(())
        } else {
            Err(at.geometry(
                what,
                format!("dimensions {values:?} must be finite and positive (zero volume)"),
            ))
        }
    };
    let primitive = |source: String, tessellation| ReadGeometry {
        source,
        tessellation,
        scale: [1.0; 3],
        file: None,
    };
    use urdf_rs::Geometry as G;
    Ok(match geometry {
        G::Mesh { filename, scale } => read_mesh(at, filename, scale.as_ref(), base, packages)?,
        G::Box { size } => {
            positive("box", &**size)?;
            primitive(format!("box {:?}", **size), tessellate_box(**size))
        }
        G::Cylinder { radius, length } => {
            positive("cylinder", &[*radius, *length])?;
            let t = tessellate_cylinder(*radius, *length);
            primitive(format!("cylinder r={radius} l={length}"), t)
        }
        G::Capsule { radius, length } => {
            positive("capsule", &[*radius])?;
            positive("capsule", &[length.max(f64::MIN_POSITIVE)])?;
            let t = tessellate_capsule(*radius, *length);
            primitive(format!("capsule r={radius} l={length}"), t)
        }
        G::Sphere { radius } => {
            positive("sphere", &[*radius])?;
            let t = tessellate_sphere(*radius);
            primitive(format!("sphere r={radius}"), t)
        }
    })
}

/// Reads the mesh file a `<mesh filename>` names (its URI resolved), its scale checked.
fn read_mesh(
    at: ElementAt,
    filename: &str,
    scale: Option<&urdf_rs::Vec3>,
    base: &Path,
    packages: &[PackagePath],
) -> Result<ReadGeometry, RobotError> {
    let file = resolve_uri(filename, base, packages).map_err(|e| match e {
        UriError::Package(package) => RobotError::PackageNotFound {
            link: at.link.to_owned(),
            element: at.index,
            uri: filename.to_owned(),
            package,
        },
        UriError::Unsupported => RobotError::UnsupportedUri {
            link: at.link.to_owned(),
            element: at.index,
            uri: filename.to_owned(),
        },
    })?;
    let scale = scale.map(|s| **s).unwrap_or([1.0; 3]);
    if scale.iter().any(|s| !s.is_finite() || *s == 0.0) {
        return Err(at.geometry(
            &format!("mesh {}", file.display()),
            format!("scale {scale:?} must be finite and non-zero"),
        ));
    }
    let loaded = load_mesh_file(&file).map_err(|source| at.mesh(&file, source))?;
    let tessellation = Tessellation {
        vertices: loaded.vertices,
        triangles: loaded.triangles,
        error_m: 0.0,
    };
    Ok(ReadGeometry {
        source: format!("mesh {}", file.display()),
        tessellation,
        scale,
        file: Some((file, (loaded.pieces, loaded.notes))),
    })
}

/// A mesh file's triangles in the link frame through the intake: its closed meshes, and what
/// the intake did (with the reader's pieces and notes) beside the file's own triangles.
fn take_in(
    at: ElementAt,
    file: PathBuf,
    pieces: usize,
    notes: Vec<String>,
    vertices: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
) -> Result<(Vec<ClosedMesh>, MeshIntake), RobotError> {
    let (shells, report, fates) =
        intake(&vertices, &triangles).map_err(|source| at.mesh(&file, source))?;
    let original = std::sync::Arc::new((vertices, triangles));
    let fates = std::sync::Arc::new(fates);
    Ok((
        shells,
        MeshIntake {
            element: at.index,
            file,
            report: MeshReport {
                pieces,
                notes,
                ..report
            },
            original,
            fates,
        },
    ))
}

/// A primitive (box, sphere, cylinder), centred on the link's frame, or a mesh file (an
/// absolute path, or relative to the current folder) as link `link`'s collision geometry
/// (`robot::attach`): the closed meshes, and a mesh file's intake.
pub(crate) fn load_shape(
    link: &str,
    geometry: &urdf_rs::Geometry,
) -> Result<(Vec<CollisionElement>, Option<MeshIntake>), RobotError> {
    let collision = urdf_rs::Collision {
        name: None,
        origin: urdf_rs::Pose::default(),
        geometry: geometry.clone(),
    };
    load_element(link, 0, &collision, Path::new("."), &[])
}

/// The convex hull of every vertex of a link's elements (parry3d's quickhull), as one element.
fn convex_hull(link: &LinkGeometry) -> Result<CollisionElement, String> {
    let points: Vec<parry3d::math::Vector> = link
        .elements
        .iter()
        .flat_map(|e| &e.mesh.vertices)
        .map(|v| parry3d::math::Vector::new(v[0], v[1], v[2]))
        .collect();
    let (vertices, triangles) = parry3d::transformation::convex_hull(&points);
    let vertices = vertices.iter().map(|v| [v.x, v.y, v.z]).collect();
    let mesh = ClosedMesh::new(vertices, triangles, &format!("link {} hull", link.name))
        .map_err(|e| e.to_string())?;
    Ok(CollisionElement {
        index: 0,
        source: format!("convex hull of {} elements", link.elements.len()),
        mesh,
        tessellation_error_m: link
            .elements
            .iter()
            .map(|e| e.tessellation_error_m)
            .fold(0.0, f64::max),
        sphere_center: None,
    })
}

fn source_label(g: &urdf_rs::Geometry) -> String {
    match g {
        urdf_rs::Geometry::Mesh { filename, .. } => format!("mesh {filename}"),
        urdf_rs::Geometry::Box { .. } => "box".into(),
        urdf_rs::Geometry::Cylinder { .. } => "cylinder".into(),
        urdf_rs::Geometry::Capsule { .. } => "capsule".into(),
        urdf_rs::Geometry::Sphere { .. } => "sphere".into(),
    }
}

fn to_link_frame(
    vertices: &[[f32; 3]],
    scale: [f64; 3],
    link_from_element: &Isometry3<f64>,
) -> Vec<[f32; 3]> {
    vertices
        .iter()
        .map(|v| {
            let p = Point3::new(
                v[0] as f64 * scale[0],
                v[1] as f64 * scale[1],
                v[2] as f64 * scale[2],
            );
            let q = link_from_element * p;
            [q.x as f32, q.y as f32, q.z as f32]
        })
        .collect()
}

#[derive(Debug, thiserror::Error)]
pub enum UriError {
    #[error("package {0} not found (give --package-path {0}=DIR, or set ROS_PACKAGE_PATH or AMENT_PREFIX_PATH)")]
    Package(String),
    #[error("unsupported URI scheme")]
    Unsupported,
}

/// Resolves a mesh URI to a file path (see the module doc for the search order).
pub fn resolve_uri(uri: &str, base: &Path, packages: &[PackagePath]) -> Result<PathBuf, UriError> {
    if let Some(rest) = uri.strip_prefix("package://") {
        let (package, relative) = rest.split_once('/').unwrap_or((rest, ""));
        let env_paths = |var: &str| -> Vec<PathBuf> {
            std::env::var_os(var)
                .map(|v| std::env::split_paths(&v).collect())
                .unwrap_or_default()
        };
        let explicit = packages
            .iter()
            .filter(|p| p.name == package)
            .map(|p| p.dir.clone());
        let ros = env_paths("ROS_PACKAGE_PATH").into_iter().flat_map(|entry| {
            let own = (entry.file_name() == Some(package.as_ref())).then(|| entry.clone());
            own.into_iter().chain(std::iter::once(entry.join(package)))
        });
        let ament = env_paths("AMENT_PREFIX_PATH")
            .into_iter()
            .map(|prefix| prefix.join("share").join(package));
        return explicit
            .chain(ros)
            .chain(ament)
            .find(|dir| dir.is_dir())
            .map(|dir| dir.join(relative))
            .ok_or_else(|| UriError::Package(package.to_owned()));
    }
    if let Some(path) = uri.strip_prefix("file://") {
        return Ok(PathBuf::from(path));
    }
    if uri.contains("://") {
        return Err(UriError::Unsupported);
    }
    Ok(base.join(uri))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_joint_type_is_named() {
        let xml = r#"<robot name="r"><link name="a"/><link name="b"/>
          <joint name="screwy" type="screw"><parent link="a"/><child link="b"/></joint></robot>"#;
        let err = parse_urdf(xml, Path::new("r.urdf")).unwrap_err();
        assert!(
            matches!(&err, RobotError::UnknownJointType { joint, kind, .. } if joint == "screwy" && kind == "screw"),
            "{err}"
        );
    }

    #[test]
    fn package_paths_parse() {
        let p: PackagePath = "panda_description=/opt/x".parse().expect("parses");
        assert_eq!(p.name, "panda_description");
        assert!("nodir".parse::<PackagePath>().is_err());
    }

    #[test]
    fn explicit_package_path_wins() {
        let dir = tempfile::tempdir().expect("tmp");
        std::fs::create_dir_all(dir.path().join("meshes")).expect("mkdir");
        let packages = [PackagePath {
            name: "pkg".into(),
            dir: dir.path().to_owned(),
        }];
        let Ok(path) = resolve_uri("package://pkg/meshes/a.stl", Path::new("/x"), &packages) else {
            panic!("package not resolved")
        };
        assert_eq!(path, dir.path().join("meshes/a.stl"));
        assert!(matches!(
            resolve_uri("package://absent_pkg_xyz/a.stl", Path::new("/x"), &packages),
            Err(UriError::Package(_))
        ));
        assert!(matches!(
            resolve_uri("http://host/a.stl", Path::new("/x"), &packages),
            Err(UriError::Unsupported)
        ));
        assert_eq!(
            resolve_uri("m/a.stl", Path::new("/x"), &packages).ok(),
            Some(PathBuf::from("/x/m/a.stl"))
        );
    }
}
