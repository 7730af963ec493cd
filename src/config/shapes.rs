//! The placed shapes of a config: `exclusion_volumes` (points dropped before the query,
//! `cloud::exclusion`) and `attached_objects` (shapes joined to a link, `robot::attach`). Both
//! are a primitive (`shape`: box with `size`, sphere with `radius`, cylinder with `radius` and
//! `length`, as URDF gives them) or a mesh file (`mesh`, `scale`; a volume's dilated by
//! `padding`) at `translation`/`rotation` in a frame: a TF frame for a volume (`frame`), a link
//! for an object (`link`). A volume's mesh is loaded here, so that a file that cannot be one is
//! refused with the parameter named, at start and at run time alike; its grid is shared while
//! the same file, scale and padding are in use.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock, Weak};

use nalgebra::Isometry3;

use super::choices::ShapeKind;
use super::entries::names;
use super::error::ConfigError;
use super::poses::transform;
use super::values::Values;
use crate::cloud::exclusion::{ExclusionVolume, MeshGrid, VolumeShape};
use crate::geometry::{Primitive, Shape};
use crate::robot::attach::AttachedObject;

/// Resolves a mesh file's name to a path.
pub(super) type Resolve<'a> = dyn Fn(&str) -> Result<PathBuf, String> + 'a;

/// The shape and pose of list entry `entry` (declared as `template`).
fn placed(
    v: &Values,
    entry: &str,
    template: &str,
    resolve: &Resolve,
) -> Result<(Shape, Isometry3<f64>), ConfigError> {
    let n = |rest: &str| names(entry, template, rest);
    let positive = |rest: &str| -> Result<f64, ConfigError> {
        let (name, t) = n(rest);
        let x = v
            .opt_f64(&name, &t)?
            .ok_or_else(|| Values::bad(&name, "a value is required for this shape"))?;
        if !(x > 0.0 && x.is_finite()) {
            return Err(Values::bad(
                &name,
                format!("must be a positive number of metres, got {x}"),
            ));
        }
        Ok(x)
    };
    let (shape_name, shape_t) = n("shape");
    let shape: Shape = match v.choice(&shape_name, &shape_t)? {
        ShapeKind::Mesh => {
            let (name, t) = n("mesh");
            let file = resolve(&v.string(&name, &t)?).map_err(|e| Values::bad(&name, e))?;
            if let Err(e) = std::fs::metadata(&file) {
                return Err(Values::bad(&name, format!("{}: {e}", file.display())));
            }
            let (sc, sct) = n("scale");
            let scale = match v.numbers(&sc, &sct)?[..] {
                [x, y, z] if [x, y, z].iter().all(|s| *s > 0.0) => [x, y, z],
                _ => return Err(Values::bad(&sc, "expected [x, y, z], each > 0")),
            };
            Shape::Mesh { file, scale }
        }
        ShapeKind::Box => {
            let (name, t) = n("size");
            let size = v.numbers(&name, &t)?;
            match size[..] {
                [x, y, z] if size.iter().all(|s| *s > 0.0) => {
                    Primitive::Box { size: [x, y, z] }.into()
                }
                _ => {
                    return Err(Values::bad(
                        &name,
                        "expected [x, y, z], each > 0 (edge lengths, m)",
                    ))
                }
            }
        }
        ShapeKind::Sphere => Primitive::Sphere {
            radius: positive("radius")?,
        }
        .into(),
        ShapeKind::Cylinder => Primitive::Cylinder {
            radius: positive("radius")?,
            length: positive("length")?,
        }
        .into(),
    };
    let pose = transform(v, entry, template)?
        .to_isometry()
        .expect("a checked, finite transform");
    Ok((shape, pose))
}

/// The grid of a mesh volume, shared while one of the same file (unchanged on disk), scale and
/// padding is in use: a run-time change that keeps a volume does not build it again.
fn mesh_grid(file: &Path, scale: [f64; 3], padding_m: f64) -> Result<Arc<MeshGrid>, String> {
    type Key = (PathBuf, [u64; 3], u64, Option<std::time::SystemTime>);
    static GRIDS: OnceLock<Mutex<HashMap<Key, Weak<MeshGrid>>>> = OnceLock::new();
    let modified = std::fs::metadata(file).and_then(|m| m.modified()).ok();
    let key = (
        file.to_owned(),
        scale.map(f64::to_bits),
        padding_m.to_bits(),
        modified,
    );
    // Poisoned by a panic in another build: the map of weak handles is still sound.
    let grids = || {
        GRIDS
            .get_or_init(Default::default)
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    };
    if let Some(g) = grids().get(&key).and_then(Weak::upgrade) {
        return Ok(g);
    }
    let g = Arc::new(MeshGrid::build(file, scale, padding_m)?);
    let mut grids = grids();
    grids.retain(|_, w| w.strong_count() > 0);
    grids.insert(key, Arc::downgrade(&g));
    Ok(g)
}

/// The exclusion volumes named in `exclusion_volumes`; `sources` are the config's source names.
pub(super) fn exclusion_volumes(
    v: &Values,
    names_listed: &[String],
    sources: &[String],
    resolve: &Resolve,
) -> Result<Vec<ExclusionVolume>, ConfigError> {
    names_listed
        .iter()
        .map(|name| {
            let (shape, frame_from_volume) = placed(v, name, "<volume>", resolve)?;
            let shape = match shape {
                Shape::Primitive(p) => VolumeShape::Primitive(p),
                Shape::Mesh { file, scale } => {
                    let (pad, padt) = names(name, "<volume>", "padding");
                    let padding = v.distance(&pad, &padt)?;
                    let (mesh, _) = names(name, "<volume>", "mesh");
                    VolumeShape::Mesh(
                        mesh_grid(&file, scale, padding).map_err(|e| Values::bad(&mesh, e))?,
                    )
                }
            };
            let (frame, ft) = names(name, "<volume>", "frame");
            let frame = v.string(&frame, &ft)?;
            let (s, st) = names(name, "<volume>", "sources");
            let applies = v.strings_of(&s, &st)?;
            if let Some(unknown) = applies.iter().find(|a| !sources.contains(a)) {
                return Err(Values::bad(
                    &s,
                    format!("'{unknown}' is not one of the sources {sources:?}"),
                ));
            }
            Ok(ExclusionVolume {
                name: name.clone(),
                shape,
                frame,
                frame_from_volume,
                sources: applies,
            })
        })
        .collect()
}

/// The attached objects named in `attached_objects`.
pub(super) fn attached_objects(
    v: &Values,
    names_listed: &[String],
    resolve: &Resolve,
) -> Result<Vec<AttachedObject>, ConfigError> {
    names_listed
        .iter()
        .map(|name| {
            let (shape, link_from_object) = placed(v, name, "<object>", resolve)?;
            let (link, lt) = names(name, "<object>", "link");
            Ok(AttachedObject {
                name: name.clone(),
                link: v.string(&link, &lt)?,
                shape,
                link_from_object,
            })
        })
        .collect()
}
