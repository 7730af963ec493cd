//! Message definitions as MCAP schemas carry them: a type's own `.msg` text, then each nested
//! type's once (`====…` then `MSG: pkg/Type`), the form `ros2 bag record` and rosbags write and
//! Foxglove and rosbags need to decode a channel; and the list of every type defined here.

use super::builtin::*;
use super::control::*;
use super::diagnostic::*;
use super::geometry::*;
use super::message::RosMessage;
use super::sensor::*;
use super::visualization::*;

/// The own definitions of every message here and of the nested types they use.
pub(super) const OWN_DEFINITIONS: &[(&str, &str)] = &[
    (Time::TYPE, Time::OWN_DEFINITION),
    (Duration::TYPE, Duration::OWN_DEFINITION),
    (Header::TYPE, Header::OWN_DEFINITION),
    (Float64::TYPE, Float64::OWN_DEFINITION),
    (StringMessage::TYPE, StringMessage::OWN_DEFINITION),
    (Clock::TYPE, Clock::OWN_DEFINITION),
    (Log::TYPE, Log::OWN_DEFINITION),
    (ParameterValue::TYPE, ParameterValue::OWN_DEFINITION),
    (Parameter::TYPE, Parameter::OWN_DEFINITION),
    (ParameterEvent::TYPE, ParameterEvent::OWN_DEFINITION),
    (Bool::TYPE, Bool::OWN_DEFINITION),
    (ColorRgba::TYPE, ColorRgba::OWN_DEFINITION),
    (Vector3::TYPE, Vector3::OWN_DEFINITION),
    (Quaternion::TYPE, Quaternion::OWN_DEFINITION),
    (Point::TYPE, Point::OWN_DEFINITION),
    (Pose::TYPE, Pose::OWN_DEFINITION),
    (Transform::TYPE, Transform::OWN_DEFINITION),
    (TransformStamped::TYPE, TransformStamped::OWN_DEFINITION),
    (TfMessage::TYPE, TfMessage::OWN_DEFINITION),
    (PointField::TYPE, PointField::OWN_DEFINITION),
    (PointCloud2::TYPE, PointCloud2::OWN_DEFINITION),
    (JointState::TYPE, JointState::OWN_DEFINITION),
    (Range::TYPE, Range::OWN_DEFINITION),
    (Image::TYPE, Image::OWN_DEFINITION),
    (CompressedImage::TYPE, CompressedImage::OWN_DEFINITION),
    (RegionOfInterest::TYPE, RegionOfInterest::OWN_DEFINITION),
    (CameraInfo::TYPE, CameraInfo::OWN_DEFINITION),
    (UvCoordinate::TYPE, UvCoordinate::OWN_DEFINITION),
    (MeshFile::TYPE, MeshFile::OWN_DEFINITION),
    (Marker::TYPE, Marker::OWN_DEFINITION),
    (MarkerArray::TYPE, MarkerArray::OWN_DEFINITION),
    (KeyValue::TYPE, KeyValue::OWN_DEFINITION),
    (DiagnosticStatus::TYPE, DiagnosticStatus::OWN_DEFINITION),
    (DiagnosticArray::TYPE, DiagnosticArray::OWN_DEFINITION),
    (SpeedScalingFactor::TYPE, SpeedScalingFactor::OWN_DEFINITION),
];

/// Every message type this module defines, by ROS 2 name.
pub fn types() -> impl Iterator<Item = &'static str> {
    OWN_DEFINITIONS.iter().map(|(t, _)| *t)
}

/// The full `ros2msg` definition of `ty` (`pkg/msg/Type`): its own text, then each nested type
/// once, depth first in field order, after a line of 80 `=` and `MSG: pkg/Type`.
pub fn definition(ty: &str) -> Option<String> {
    fn own(ty: &str) -> Option<&'static str> {
        OWN_DEFINITIONS
            .iter()
            .find(|(t, _)| *t == ty)
            .map(|(_, d)| *d)
    }
    // A field line `pkg/Type name` or `pkg/Type[] name` → `pkg/msg/Type`; constants and
    // basic types have no `/`.
    fn nested(line: &str) -> Option<String> {
        let ty = line.split_whitespace().next()?.split('[').next()?;
        let (pkg, name) = ty.split_once('/').filter(|_| !line.contains('='))?;
        Some(format!("{pkg}/msg/{name}"))
    }
    fn visit(ty: &str, seen: &mut Vec<String>, out: &mut String) -> Option<()> {
        for line in own(ty)?.lines() {
            if let Some(n) = nested(line) {
                if !seen.contains(&n) {
                    seen.push(n.clone());
                    out.push_str(&"=".repeat(80));
                    out.push_str("\nMSG: ");
                    out.push_str(&n.replace("/msg/", "/"));
                    out.push('\n');
                    out.push_str(own(&n)?);
                    visit(&n, seen, out)?;
                }
            }
        }
        Some(())
    }
    let mut out = own(ty)?.to_owned();
    let mut seen = vec![ty.to_owned()];
    visit(ty, &mut seen, &mut out)?;
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_nested_type_has_a_definition() {
        for ty in types() {
            assert!(definition(ty).is_some(), "{ty}");
        }
    }
}
