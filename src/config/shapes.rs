//! The placed shapes of a config: `exclusion_volumes` (points dropped before the query,
//! `cloud::exclusion`) and `attached_objects` (shapes joined to a link, `robot::attach`). Both
//! are a primitive (`shape`: box with `size`, sphere with `radius`, cylinder with `radius` and
//! `length`, as URDF gives them) at `translation`/`rotation` in a frame: a TF frame for a volume
//! (`frame`), a link for an object (`link`).

use nalgebra::Isometry3;

use super::values::Values;
use super::ConfigError;
use crate::cloud::exclusion::ExclusionVolume;
use crate::geometry::Primitive;
use crate::msg::{Quaternion, Transform, Vector3};
use crate::robot::attach::AttachedObject;

/// The names of one list entry's parameters: `("<name>.rest", "<template>.rest")`.
pub(super) fn names(entry: &str, template: &str, rest: &str) -> (String, String) {
    (format!("{entry}.{rest}"), format!("{template}.{rest}"))
}

/// The `translation` ([x, y, z]) and `rotation` (quaternion [x, y, z, w], not zero) of list
/// entry `entry` (declared as `template`): static transforms, volumes and objects.
pub(super) fn transform(v: &Values, entry: &str, template: &str) -> Result<Transform, ConfigError> {
    let (tr, trt) = names(entry, template, "translation");
    let (rot, rott) = names(entry, template, "rotation");
    let [x, y, z] = v.numbers(&tr, &trt)?[..] else {
        return Err(Values::bad(&tr, "expected [x, y, z]"));
    };
    let [qx, qy, qz, qw] = v.numbers(&rot, &rott)?[..] else {
        return Err(Values::bad(&rot, "expected [x, y, z, w]"));
    };
    let rotation = Quaternion {
        x: qx,
        y: qy,
        z: qz,
        w: qw,
    };
    if rotation.to_unit().is_none() {
        return Err(Values::bad(&rot, "the quaternion is zero"));
    }
    Ok(Transform {
        translation: Vector3 { x, y, z },
        rotation,
    })
}

/// The primitive and pose of list entry `entry` (declared as `template`).
fn placed(
    v: &Values,
    entry: &str,
    template: &str,
) -> Result<(Primitive, Isometry3<f64>), ConfigError> {
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
    let shape = match v.string(&shape_name, &shape_t)?.as_str() {
        "box" => {
            let (name, t) = n("size");
            let size = v.numbers(&name, &t)?;
            match size[..] {
                [x, y, z] if size.iter().all(|s| *s > 0.0) => Primitive::Box { size: [x, y, z] },
                _ => {
                    return Err(Values::bad(
                        &name,
                        "expected [x, y, z], each > 0 (edge lengths, m)",
                    ))
                }
            }
        }
        "sphere" => Primitive::Sphere {
            radius: positive("radius")?,
        },
        "cylinder" => Primitive::Cylinder {
            radius: positive("radius")?,
            length: positive("length")?,
        },
        other => {
            return Err(Values::bad(
                &shape_name,
                format!("'{other}' (expected box, sphere or cylinder)"),
            ))
        }
    };
    let pose = transform(v, entry, template)?
        .to_isometry()
        .expect("a checked, finite transform");
    Ok((shape, pose))
}

/// The exclusion volumes named in `exclusion_volumes`; `sources` are the config's source names.
pub(super) fn exclusion_volumes(
    v: &Values,
    names_listed: &[String],
    sources: &[String],
) -> Result<Vec<ExclusionVolume>, ConfigError> {
    names_listed
        .iter()
        .map(|name| {
            let (shape, frame_from_volume) = placed(v, name, "<volume>")?;
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
) -> Result<Vec<AttachedObject>, ConfigError> {
    names_listed
        .iter()
        .map(|name| {
            let (shape, link_from_object) = placed(v, name, "<object>")?;
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
