//! The poses a config gives itself, for bags and setups without `/tf_static` or
//! `/joint_states`: the `static_transforms` (`<transform>.parent_frame`, `child_frame`,
//! `translation` in m, `rotation` as a quaternion), the `fixed_joint_state` (names and
//! positions in rad or m), and the `translation`/`rotation` every placed entry shares with
//! them (`shapes`).

use super::entries::names;
use super::error::ConfigError;
use super::values::Values;
use crate::msg::{Header, Quaternion, Time, Transform, TransformStamped, Vector3};

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

/// The static transforms named in `static_transforms`.
pub(super) fn static_transforms(
    v: &Values,
    entries: &[String],
) -> Result<Vec<TransformStamped>, ConfigError> {
    entries
        .iter()
        .map(|t| {
            let n = |rest: &str| names(t, "<transform>", rest);
            let (parent, pt) = n("parent_frame");
            let (child, ct) = n("child_frame");
            Ok(TransformStamped {
                header: Header {
                    stamp: Time::default(),
                    frame_id: v.string(&parent, &pt)?,
                },
                child_frame_id: v.string(&child, &ct)?,
                transform: transform(v, t, "<transform>")?,
            })
        })
        .collect()
}

/// `fixed_joint_state`: each name with its position.
pub(super) fn fixed_joint_state(v: &Values) -> Result<Vec<(String, f64)>, ConfigError> {
    let names = v.strings("fixed_joint_state.names")?;
    let positions = v.numbers("fixed_joint_state.positions", "fixed_joint_state.positions")?;
    if names.len() != positions.len() {
        return Err(Values::bad(
            "fixed_joint_state.positions",
            format!("{} values for {} names", positions.len(), names.len()),
        ));
    }
    Ok(names.into_iter().zip(positions).collect())
}
