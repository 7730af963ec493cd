//! The unobserved-space parameters (issue 45): the policy (`unobserved`), what the robot's own
//! shadow counts as (`unobserved_self_shadow`), the grid's resolution, the detection capability
//! (m), the monitored volume (a box in a frame, or the robot's reach plus a margin) and how many
//! hidden places are drawn. Read into [`Unobserved`]; the monitor (`monitor::unseen`) runs the
//! `unseen` stage with them. Each source's `range_noise` is read with the source.

use nalgebra::Isometry3;

use super::choices::{SelfShadow, UnobservedPolicy};
use super::error::ConfigError;
use super::poses::transform;
use super::values::Values;

/// The monitored volume as given: a box of edge lengths `size_m` centred at `frame_from_box`.
#[derive(Debug, Clone, PartialEq)]
pub struct MonitoredVolume {
    /// `None`: the robot's root link.
    pub frame: Option<String>,
    pub frame_from_box: Isometry3<f64>,
    pub size_m: [f64; 3],
}

/// `unobserved*`, `detection_capability`, `monitored_volume.*`.
#[derive(Debug, Clone, PartialEq)]
pub struct Unobserved {
    pub policy: UnobservedPolicy,
    pub self_shadow: SelfShadow,
    pub resolution_m: f64,
    pub detection_capability_m: f64,
    /// `None`: the robot's reach plus `margin_m` (`monitor::unseen`).
    pub volume: Option<MonitoredVolume>,
    pub margin_m: f64,
    /// Most unseen cells drawn.
    pub markers: usize,
}

impl Unobserved {
    /// Whether the stage runs at all (`ignore` costs nothing).
    pub fn enabled(&self) -> bool {
        self.policy != UnobservedPolicy::Ignore
    }

    /// Whether the level, the stop and the factor take the unseen distance.
    pub fn protects(&self) -> bool {
        self.policy == UnobservedPolicy::Protect
    }
}

/// Reads the parameters; lengths must be > 0 (the resolution, the capability, a size).
pub(super) fn unobserved(v: &Values) -> Result<Unobserved, ConfigError> {
    let positive = |name: &str| -> Result<f64, ConfigError> {
        match v.distance(name, name)? {
            x if x > 0.0 => Ok(x),
            x => Err(Values::bad(name, format!("must be > 0, got {x}"))),
        }
    };
    let resolution_m = positive("unobserved_resolution")?;
    let detection_capability_m = positive("detection_capability")?;
    let needed = resolution_m * 3f64.sqrt();
    if detection_capability_m <= needed {
        return Err(Values::bad(
            "detection_capability",
            format!(
                "{detection_capability_m} m is finer than the grid resolves: more than the cell \
                 diagonal, {needed:.4} m at unobserved_resolution {resolution_m} m (a body of it \
                 need hold no ball about its cell's centre)"
            ),
        ));
    }
    let given = !v
        .raw("monitored_volume.size", "monitored_volume.size")
        .is_null();
    let volume = if given { Some(volume(v)?) } else { None };
    Ok(Unobserved {
        policy: v.choice("unobserved", "unobserved")?,
        self_shadow: v.choice("unobserved_self_shadow", "unobserved_self_shadow")?,
        resolution_m,
        detection_capability_m,
        volume,
        margin_m: v.distance("monitored_volume.margin", "monitored_volume.margin")?,
        markers: v.whole("unobserved_markers")?,
    })
}

/// `monitored_volume.size` with its frame, translation and rotation.
fn volume(v: &Values) -> Result<MonitoredVolume, ConfigError> {
    let name = "monitored_volume.size";
    let size = v.numbers(name, name)?;
    let size_m: [f64; 3] = match size[..] {
        [x, y, z] if [x, y, z].iter().all(|e| e.is_finite() && *e > 0.0) => [x, y, z],
        _ => {
            return Err(Values::bad(
                name,
                format!("expected three edge lengths > 0 [x, y, z], got {size:?}"),
            ))
        }
    };
    let t = transform(v, "monitored_volume", "monitored_volume")?;
    let frame_from_box = t
        .to_isometry()
        .ok_or_else(|| Values::bad("monitored_volume.rotation", "the quaternion is zero"))?;
    Ok(MonitoredVolume {
        frame: v.opt_string("monitored_volume.frame", "monitored_volume.frame")?,
        frame_from_box,
        size_m,
    })
}
