//! REP-2016 type hashes (`RIHS01_…`) of the messages in this module, computed from their
//! definitions.
//!
//! ROS 2 (Iron and later) names every message type by a hash of its structure, and `rmw_zenoh`
//! puts that hash in every topic key and liveliness token: a subscriber keyed by the real hash
//! hears nothing from a publisher that writes another. The hash is the one
//! `rosidl_generator_type_description` computes:
//!
//! 1. The type's description: its name (`pkg/msg/Type`) and fields, each with a `type_id`
//!    (`FieldType.msg`: the base type's id, +48 for a fixed array, +96 for a bounded sequence,
//!    +144 for an unbounded one), a `capacity` (the array's size or the sequence's bound), a
//!    `string_capacity` (the bound of a `string<=N`) and a `nested_type_name` for a message
//!    field. Constants and default values are not part of it.
//! 2. With it, the description of every type it references, directly or not, each once,
//!    sorted by name.
//! 3. That as JSON exactly as Python's `json.dumps(…, separators=(', ', ': '))` writes it, keys
//!    in the order above; `RIHS01_` + the lowercase hex SHA-256 of those bytes.
//!
//! `.msg` basic types map through the IDL: `byte` is an octet (`BYTE`), `char` a `uint8`.
//! Tests compare every hash with the one ROS 2 Jazzy's generated code carries.
//!
//! The node's parameter services (`rcl_interfaces/srv/…`) are not messages of this module:
//! their hashes are ROS 2 Jazzy's, carried as they are ([`service_hash`]).

use sha2::{Digest, Sha256};

use super::definition::OWN_DEFINITIONS;

/// A field's type as `type_description_interfaces/FieldType` states it.
struct FieldType {
    type_id: u8,
    capacity: u64,
    string_capacity: u64,
    nested_type_name: String,
}

/// `FieldType.msg`'s id of a `.msg` basic type (a string is 17, a bounded one 21).
fn basic_type_id(name: &str) -> Option<u8> {
    Some(match name {
        "int8" => 2,
        "uint8" | "char" => 3,
        "int16" => 4,
        "uint16" => 5,
        "int32" => 6,
        "uint32" => 7,
        "int64" => 8,
        "uint64" => 9,
        "float32" => 10,
        "float64" => 11,
        "bool" => 15,
        "byte" => 16,
        "string" => 17,
        "wstring" => 18,
        _ => return None,
    })
}

/// The type of a field declared as `token` (`float64[9]`, `string<=8`, `pkg/Type[]`) in
/// package `package`.
fn field_type(token: &str, package: &str) -> Option<FieldType> {
    let (base, suffix) = match token.split_once('[') {
        Some((b, rest)) => (b, Some(rest.strip_suffix(']')?)),
        None => (token, None),
    };
    let (offset, capacity) = match suffix {
        None => (0, 0),
        Some("") => (144, 0),
        Some(s) => match s.strip_prefix("<=") {
            Some(bound) => (96, bound.parse().ok()?),
            None => (48, s.parse().ok()?),
        },
    };
    let (id, string_capacity, nested) = match base.split_once("<=") {
        Some(("string", n)) => (21, n.parse().ok()?, String::new()),
        Some(("wstring", n)) => (22, n.parse().ok()?, String::new()),
        Some(_) => return None,
        None => match basic_type_id(base) {
            Some(id) => (id, 0, String::new()),
            None => {
                let (pkg, name) = base.split_once('/').unwrap_or((package, base));
                (1, 0, format!("{pkg}/msg/{name}"))
            }
        },
    };
    Some(FieldType {
        type_id: id + offset,
        capacity,
        string_capacity,
        nested_type_name: nested,
    })
}

/// The fields of `ty` (name and type), from its own definition; `None` for a type not defined
/// in this module or a line it cannot read.
fn fields(ty: &str) -> Option<Vec<(String, FieldType)>> {
    let (_, text) = OWN_DEFINITIONS.iter().find(|(t, _)| *t == ty)?;
    let package = ty.split('/').next()?;
    text.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        // A constant is `type NAME=value`.
        .filter(|l| !l.split_whitespace().nth(1).is_some_and(|n| n.contains('=')))
        .map(|l| {
            let mut words = l.split_whitespace();
            let token = words.next()?;
            let name = words.next()?;
            Some((name.to_owned(), field_type(token, package)?))
        })
        .collect()
}

/// One `IndividualTypeDescription` as JSON, without default values.
fn individual_json(ty: &str, fields: &[(String, FieldType)]) -> String {
    let fields: Vec<String> = fields
        .iter()
        .map(|(name, t)| {
            format!(
                "{{\"name\": \"{name}\", \"type\": {{\"type_id\": {}, \"capacity\": {}, \
                 \"string_capacity\": {}, \"nested_type_name\": \"{}\"}}}}",
                t.type_id, t.capacity, t.string_capacity, t.nested_type_name
            )
        })
        .collect();
    format!(
        "{{\"type_name\": \"{ty}\", \"fields\": [{}]}}",
        fields.join(", ")
    )
}

/// The JSON that `ty`'s hash is taken over: its description and those of every type it
/// references, sorted by name. `None` when `ty` or a type it references is not defined here.
pub fn hashed_description(ty: &str) -> Option<String> {
    let own = fields(ty)?;
    let mut referenced: Vec<String> = Vec::new();
    let mut queue: Vec<String> = own
        .iter()
        .map(|(_, t)| t.nested_type_name.clone())
        .filter(|n| !n.is_empty())
        .collect();
    while let Some(n) = queue.pop() {
        if !referenced.contains(&n) {
            queue.extend(
                fields(&n)?
                    .into_iter()
                    .map(|(_, t)| t.nested_type_name)
                    .filter(|n| !n.is_empty()),
            );
            referenced.push(n);
        }
    }
    referenced.sort();
    let referenced = referenced
        .iter()
        .map(|n| Some(individual_json(n, &fields(n)?)))
        .collect::<Option<Vec<_>>>()?;
    Some(format!(
        "{{\"type_description\": {}, \"referenced_type_descriptions\": [{}]}}",
        individual_json(ty, &own),
        referenced.join(", ")
    ))
}

/// The REP-2016 hash of `ty` (`pkg/msg/Type`), `RIHS01_` and 64 hex digits; `None` for a type
/// not defined in this module.
pub fn type_hash(ty: &str) -> Option<String> {
    let digest = Sha256::digest(hashed_description(ty)?.as_bytes());
    let mut out = String::from("RIHS01_");
    for b in digest {
        out.push_str(&format!("{b:02x}"));
    }
    Some(out)
}

/// The REP-2016 hashes of the six parameter services, as ROS 2 Jazzy's generated code carries
/// them (`rcl_interfaces/srv/detail/<service>__description.c`; a test reads them there): an
/// rmw_zenoh service is announced with its type's hash.
const SERVICE_HASHES: &[(&str, &str)] = &[
    (
        "ListParameters",
        "RIHS01_3e6062bfbb27bfb8730d4cef2558221f51a11646d78e7bb30a1e83afac3aad9d",
    ),
    (
        "GetParameters",
        "RIHS01_bf9803d5c74cf989a5de3e0c2e99444599a627c7ff75f97b8c05b01003675cbc",
    ),
    (
        "GetParameterTypes",
        "RIHS01_da199c878688b3e530bdfe3ca8f74cb9fa0c303101e980a9e8f260e25e1c80ca",
    ),
    (
        "DescribeParameters",
        "RIHS01_845b484d71eb0673dae682f2e3ba3c4851a65a3dcfb97bddd82c5b57e91e4cff",
    ),
    (
        "SetParameters",
        "RIHS01_56eed9a67e169f9cb6c1f987bc88f868c14a8fc9f743a263bc734c154015d7e0",
    ),
    (
        "SetParametersAtomically",
        "RIHS01_0e192ef259c07fc3c07a13191d27002222e65e00ccec653ca05e856f79285fcd",
    ),
];

/// The REP-2016 hash of parameter service `rcl_interfaces/srv/<ty>`.
pub fn service_hash(ty: &str) -> Option<&'static str> {
    SERVICE_HASHES
        .iter()
        .find(|(t, _)| *t == ty)
        .map(|(_, h)| *h)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hashes that ROS 2's generated code carries for these types (`rosidl_generator_c`'s
    /// `<type>__description.c`: `…__get_type_hash` and the `…__EXPECTED_HASH` of referenced
    /// types, Jazzy; `std_msgs/String` as ros2-client and the rmw_zenoh docs quote it). Read
    /// from those files, one per type this module defines.
    const ROS_2: &[(&str, &str)] = &[
        (
            "builtin_interfaces/msg/Time",
            "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197",
        ),
        (
            "builtin_interfaces/msg/Duration",
            "RIHS01_e8d009f659816f758b75334ee1a9ca5b5c0b859843261f14c7f937349599d93b",
        ),
        (
            "std_msgs/msg/Header",
            "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01",
        ),
        (
            "std_msgs/msg/Float64",
            "RIHS01_705ba9c3d1a09df43737eb67095534de36fd426c0587779bda2bc51fe790182a",
        ),
        (
            "std_msgs/msg/String",
            "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
        ),
        (
            "rcl_interfaces/msg/Log",
            "RIHS01_e28ce254ca8abc06abf92773b74602cdbf116ed34fbaf294fb9f81da9f318eac",
        ),
        (
            "rcl_interfaces/msg/ParameterValue",
            "RIHS01_115fc089a387e23c7ecd3525c9189c379109119d6ab82e8dfbde0fdf6a7f9b68",
        ),
        (
            "rcl_interfaces/msg/Parameter",
            "RIHS01_ddfe6442cffc462317adb5c92536a7b6dd55858c5c3e1e328165a6b73c2831af",
        ),
        (
            "rcl_interfaces/msg/ParameterEvent",
            "RIHS01_043e627780fcad87a22d225bc2a037361dba713fca6a6b9f4b869a5aa0393204",
        ),
        (
            "rosgraph_msgs/msg/Clock",
            "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564",
        ),
        (
            "std_msgs/msg/Bool",
            "RIHS01_feb91e995ff9ebd09c0cb3d2aed18b11077585839fb5db80193b62d74528f6c9",
        ),
        (
            "std_msgs/msg/ColorRGBA",
            "RIHS01_77a7a5b9ae477306097665106e0413ba74440245b1f3d0c6d6405fe5c7813fe8",
        ),
        (
            "geometry_msgs/msg/Vector3",
            "RIHS01_cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d",
        ),
        (
            "geometry_msgs/msg/Quaternion",
            "RIHS01_8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684",
        ),
        (
            "geometry_msgs/msg/Point",
            "RIHS01_6963084842a9b04494d6b2941d11444708d892da2f4b09843b9c43f42a7f6881",
        ),
        (
            "geometry_msgs/msg/Pose",
            "RIHS01_d501954e9476cea2996984e812054b68026ae0bfae789d9a10b23daf35cc90fa",
        ),
        (
            "geometry_msgs/msg/Transform",
            "RIHS01_beb83fbe698636351461f6f35d1abb20010c43d55374d81bd041f1ba2581fddc",
        ),
        (
            "geometry_msgs/msg/TransformStamped",
            "RIHS01_0a241f87d04668d94099cbb5ba11691d5ad32c2f29682e4eb5653424bd275206",
        ),
        (
            "tf2_msgs/msg/TFMessage",
            "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
        ),
        (
            "sensor_msgs/msg/PointField",
            "RIHS01_5c6a4750728c2bcfbbf7037225b20b02d4429634732146b742dee1726637ef01",
        ),
        (
            "sensor_msgs/msg/PointCloud2",
            "RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5",
        ),
        (
            "sensor_msgs/msg/JointState",
            "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
        ),
        (
            "sensor_msgs/msg/Image",
            "RIHS01_d31d41a9a4c4bc8eae9be757b0beed306564f7526c88ea6a4588fb9582527d47",
        ),
        (
            "sensor_msgs/msg/CompressedImage",
            "RIHS01_15640771531571185e2efc8a100baf923961a4d15d5569652e6cb6691e8e371a",
        ),
        (
            "sensor_msgs/msg/RegionOfInterest",
            "RIHS01_ad16bcba5f9131dcdba6fbded19f726f5440e3c513b4fb586dd3027eeed8abb1",
        ),
        (
            "sensor_msgs/msg/CameraInfo",
            "RIHS01_b3dfd68ff46c9d56c80fd3bd4ed22c7a4ddce8c8348f2f59c299e73118e7e275",
        ),
        (
            "visualization_msgs/msg/UVCoordinate",
            "RIHS01_f27f7ed21fe360c6066944f856b801a0c0d1e94e815b6886444b42d90b196a26",
        ),
        (
            "visualization_msgs/msg/MeshFile",
            "RIHS01_7710ece15a148fb7c9b546364cfb215bb06098087bd6394fe5b73a493508f8c4",
        ),
        (
            "visualization_msgs/msg/Marker",
            "RIHS01_45b13ccf791f225962bf74e746f9644518855d783a6f42ba0cc14fde2b4f3ce0",
        ),
        (
            "visualization_msgs/msg/MarkerArray",
            "RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf",
        ),
        (
            "diagnostic_msgs/msg/KeyValue",
            "RIHS01_d68081eaa540288c5440753baecef0c4e16e81a5f78ad68902ded5100413bb42",
        ),
        (
            "diagnostic_msgs/msg/DiagnosticStatus",
            "RIHS01_b0e3e692ea2d54a8af2f4ef1930e81556a2db55216b771f8a7d2724ed47bf0e4",
        ),
        (
            "diagnostic_msgs/msg/DiagnosticArray",
            "RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e",
        ),
        // Computed by rosbags (its Jazzy type store), which gives every other hash here too.
        (
            "sensor_msgs/msg/Range",
            "RIHS01_b42b62562e93cbfe9d42b82fe5994dfa3d63d7d5c90a317981703f7388adff3a",
        ),
        (
            "control_msgs/msg/SpeedScalingFactor",
            "RIHS01_0c240f349f2b74e33e8741f83e0f196ddeb6585923663876ed3c1f51f0566037",
        ),
    ];

    #[test]
    fn every_type_hashes_as_ros_2_does() {
        for (ty, expected) in ROS_2 {
            assert_eq!(type_hash(ty).as_deref(), Some(*expected), "{ty}");
        }
        for ty in super::super::types() {
            assert!(
                ROS_2.iter().any(|(t, _)| *t == ty),
                "{ty} has no reference hash"
            );
        }
    }

    #[test]
    fn the_description_is_python_json() {
        assert_eq!(
            hashed_description("std_msgs/msg/Header").unwrap(),
            "{\"type_description\": {\"type_name\": \"std_msgs/msg/Header\", \"fields\": \
             [{\"name\": \"stamp\", \"type\": {\"type_id\": 1, \"capacity\": 0, \
             \"string_capacity\": 0, \"nested_type_name\": \"builtin_interfaces/msg/Time\"}}, \
             {\"name\": \"frame_id\", \"type\": {\"type_id\": 17, \"capacity\": 0, \
             \"string_capacity\": 0, \"nested_type_name\": \"\"}}]}, \
             \"referenced_type_descriptions\": [{\"type_name\": \"builtin_interfaces/msg/Time\", \
             \"fields\": [{\"name\": \"sec\", \"type\": {\"type_id\": 6, \"capacity\": 0, \
             \"string_capacity\": 0, \"nested_type_name\": \"\"}}, {\"name\": \"nanosec\", \
             \"type\": {\"type_id\": 7, \"capacity\": 0, \"string_capacity\": 0, \
             \"nested_type_name\": \"\"}}]}]}"
        );
    }

    #[test]
    fn field_types_follow_field_type_msg() {
        let t = field_type("float64[9]", "p").unwrap();
        assert_eq!((t.type_id, t.capacity), (59, 9));
        let t = field_type("uint8[]", "p").unwrap();
        assert_eq!((t.type_id, t.capacity), (147, 0));
        let t = field_type("int32[<=3]", "p").unwrap();
        assert_eq!((t.type_id, t.capacity), (102, 3));
        let t = field_type("string<=8[]", "p").unwrap();
        assert_eq!((t.type_id, t.string_capacity), (165, 8));
        let t = field_type("Other[]", "p").unwrap();
        assert_eq!(
            (t.type_id, t.nested_type_name.as_str()),
            (145, "p/msg/Other")
        );
        assert_eq!(field_type("byte", "p").unwrap().type_id, 16);
        assert!(field_type("float64[x]", "p").is_none());
        assert!(type_hash("no_msgs/msg/Nothing").is_none());
    }

    /// The service hashes are ROS 2 Jazzy's: read from the generated code in the venv of the
    /// interop tests (`.ci/run` makes it; outside CI the check is left out where it is absent).
    #[test]
    fn service_hashes_are_ros_2s() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(".venv/include/rcl_interfaces/rcl_interfaces/srv/detail");
        if !dir.is_dir() {
            assert!(
                std::env::var_os("CI").is_none(),
                "CI: {} missing",
                dir.display()
            );
            eprintln!(
                "SKIPPED service_hashes_are_ros_2s: {} is absent",
                dir.display()
            );
            return;
        }
        for (ty, hash) in SERVICE_HASHES {
            let snake: String = ty
                .chars()
                .enumerate()
                .flat_map(|(i, c)| {
                    let sep = (i > 0 && c.is_ascii_uppercase()).then_some('_');
                    sep.into_iter().chain([c.to_ascii_lowercase()])
                })
                .collect();
            let text =
                std::fs::read_to_string(dir.join(format!("{snake}__description.c"))).unwrap();
            // The service's own hash: the first array after `rcl_interfaces__srv__<Ty>__get_type_hash`.
            let from = text
                .find(&format!("rcl_interfaces__srv__{ty}__get_type_hash("))
                .unwrap();
            let bytes: String = text[from..]
                .split("0x")
                .skip(1)
                .take(32)
                .map(|b| &b[..2])
                .collect();
            assert_eq!(*hash, format!("RIHS01_{bytes}"), "{ty}");
        }
    }
}
