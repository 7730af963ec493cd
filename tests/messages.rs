//! ROS 2 messages and bags against an independent implementation, the Python `rosbags` package:
//! rosbags writes a bag of sample messages that we read (values and bytes), and we write a bag
//! that rosbags reads (values and message definitions). The samples match
//! `tests/python/rosbags_interop.py` value for value.

mod common;

use std::borrow::Cow;
use std::path::Path;
use std::process::Command;

use ist_monitor::bag::{read_messages, writer::Compression, BagWriter};
use ist_monitor::cloud::pointcloud2;
use ist_monitor::msg::*;
use serde::de::DeserializeOwned;

const SCRIPT: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/tests/python/rosbags_interop.py"
);

fn header(frame: &str) -> Header {
    Header {
        stamp: Time {
            sec: 1_700_000_000,
            nanosec: 123_456_789,
        },
        frame_id: frame.into(),
    }
}

/// Two points, 16-byte FLOAT32 points (4 zero bytes after z), through the library's encoder.
fn cloud(big_endian: bool) -> PointCloud2<'static> {
    let layout = pointcloud2::Layout {
        big_endian,
        ..pointcloud2::Layout::unorganized(2)
    };
    let points = [[1.0, 2.0, 3.0], [-1.5, 0.25, 4.0]];
    pointcloud2::encode(header("camera_optical_frame"), &points, &layout).unwrap()
}

fn transform_stamped() -> TransformStamped {
    TransformStamped {
        header: header("world"),
        child_frame_id: "camera_link".into(),
        transform: Transform {
            translation: Vector3 {
                x: 1.2,
                y: 0.0,
                z: 0.8,
            },
            rotation: Quaternion {
                x: 0.0,
                y: 0.247,
                z: 0.0,
                w: 0.969,
            },
        },
    }
}

fn point(x: f64, y: f64, z: f64) -> Point {
    Point { x, y, z }
}

fn marker_array() -> MarkerArray<'static> {
    MarkerArray {
        markers: vec![Marker {
            header: header("world"),
            ns: "closest".into(),
            id: 3,
            r#type: Marker::LINE_LIST,
            action: Marker::ADD,
            pose: Pose::default(),
            scale: Vector3 {
                x: 0.01,
                y: 0.0,
                z: 0.0,
            },
            color: ColorRgba {
                r: 1.0,
                g: 0.5,
                b: 0.0,
                a: 1.0,
            },
            lifetime: Duration {
                sec: 0,
                nanosec: 500_000_000,
            },
            points: vec![point(0.1, 0.2, 0.3), point(0.4, 0.5, 0.6)],
            text: "0.123 m".into(),
            ..Marker::default()
        }],
    }
}

fn diagnostic_array() -> DiagnosticArray {
    let kv = |k: &str, v: &str| KeyValue {
        key: k.into(),
        value: v.into(),
    };
    DiagnosticArray {
        header: header(""),
        status: vec![DiagnosticStatus {
            level: DiagnosticStatus::WARN,
            name: "ist_monitor: distance".into(),
            message: "warn: 0.2 m".into(),
            hardware_id: "demo_arm".into(),
            values: vec![kv("latency_ms", "1.5"), kv("points", "307200")],
        }],
    }
}

fn camera_info() -> CameraInfo {
    CameraInfo {
        header: header("camera"),
        height: 480,
        width: 640,
        distortion_model: "plumb_bob".into(),
        d: vec![0.1, -0.2, 0.0, 0.0, 0.05],
        k: [525.0, 0.0, 319.5, 0.0, 525.0, 239.5, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [
            525.0, 0.0, 319.5, 0.0, 0.0, 525.0, 239.5, 0.0, 0.0, 0.0, 1.0, 0.0,
        ],
        binning_x: 0,
        binning_y: 0,
        roi: RegionOfInterest {
            x_offset: 1,
            y_offset: 2,
            height: 3,
            width: 4,
            do_rectify: true,
        },
    }
}

/// Writes every sample with our writer.
fn write_samples(w: &mut BagWriter) {
    let t = 1000;
    w.write(
        "/time",
        t,
        &Time {
            sec: -3,
            nanosec: 999_999_999,
        },
    )
    .unwrap();
    w.write("/header", t, &header("base_link")).unwrap();
    w.write("/float64", t, &Float64 { data: 0.0979 }).unwrap();
    w.write("/bool", t, &Bool { data: true }).unwrap();
    w.write("/speed_scaling", t, &SpeedScalingFactor { factor: 0.35 })
        .unwrap();
    w.write("/cloud", t, &cloud(false)).unwrap();
    w.write(
        "/joint_states",
        t,
        &JointState {
            header: header(""),
            name: vec!["shoulder_pan".into(), "elbow".into()],
            position: vec![0.5, -1.25],
            ..JointState::default()
        },
    )
    .unwrap();
    w.write(
        "/image",
        t,
        &Image {
            header: header("camera"),
            height: 2,
            width: 3,
            encoding: "16UC1".into(),
            is_bigendian: 0,
            step: 6,
            data: Cow::Owned((0u8..12).collect()),
        },
    )
    .unwrap();
    w.write("/camera_info", t, &camera_info()).unwrap();
    w.write(
        "/tf",
        t,
        &TfMessage {
            transforms: vec![transform_stamped()],
        },
    )
    .unwrap();
    w.write("/transform_stamped", t, &transform_stamped())
        .unwrap();
    w.write(
        "/pose",
        t,
        &Pose {
            position: point(1.0, -2.0, 3.0),
            orientation: Quaternion {
                x: 0.0,
                y: 0.0,
                z: 0.6,
                w: 0.8,
            },
        },
    )
    .unwrap();
    w.write("/markers", t, &marker_array()).unwrap();
    w.write("/diagnostics", t, &diagnostic_array()).unwrap();
}

/// Our encoding of the sample on `topic`, from a bag we write ourselves.
fn our_payloads(dir: &Path) -> std::collections::HashMap<String, Vec<u8>> {
    let path = dir.join("ours.mcap");
    let mut w = BagWriter::create(&path, Compression::None).unwrap();
    write_samples(&mut w);
    w.finish().unwrap();
    read_messages(&path, &|_, _| true)
        .unwrap()
        .into_iter()
        .map(|m| (m.topic.to_string(), m.data))
        .collect()
}

fn check<T: RosMessage + DeserializeOwned + PartialEq + std::fmt::Debug>(
    payload: &[u8],
    expected: &T,
) {
    let decoded: T = decode(payload).unwrap();
    assert_eq!(&decoded, expected, "{}", T::TYPE);
}

#[test]
fn rosbags_fixture_is_read_value_for_value_and_byte_for_byte() {
    let Some(python) = common::venv_python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("rosbags_fixture");
    let status = Command::new(&python)
        .args([SCRIPT, "write"])
        .arg(&bag)
        .status()
        .unwrap();
    assert!(status.success());
    let theirs = read_messages(&bag, &|_, _| true).unwrap();
    assert_eq!(theirs.len(), 15);
    let ours = our_payloads(dir.path());
    for m in &theirs {
        assert_eq!(&*m.encoding, "cdr");
        if &*m.topic == "/big_endian/cloud" {
            // rosbags' big-endian CDR: the header says so, the data is big endian too.
            assert_eq!(m.data[1], 0, "big-endian encapsulation");
            let c: PointCloud2 = decode(&m.data).unwrap();
            assert_eq!(c, cloud(true));
            let points = c.to_cloud().unwrap().points;
            assert_eq!(points, vec![[1.0, 2.0, 3.0], [-1.5, 0.25, 4.0]]);
            continue;
        }
        let mine = &ours[&*m.topic];
        assert_eq!(
            &m.data, mine,
            "{}: rosbags' bytes differ from ours",
            m.topic
        );
        match &*m.topic {
            "/float64" => check(&m.data, &Float64 { data: 0.0979 }),
            "/speed_scaling" => check(&m.data, &SpeedScalingFactor { factor: 0.35 }),
            "/tf" => check(
                &m.data,
                &TfMessage {
                    transforms: vec![transform_stamped()],
                },
            ),
            "/camera_info" => check(&m.data, &camera_info()),
            "/diagnostics" => check(&m.data, &diagnostic_array()),
            "/markers" => {
                let decoded: MarkerArray = decode(&m.data).unwrap();
                assert_eq!(decoded, marker_array());
            }
            "/cloud" => {
                let decoded: PointCloud2 = decode(&m.data).unwrap();
                assert_eq!(decoded, cloud(false));
            }
            _ => {}
        }
    }
}

#[test]
fn rosbags_reads_what_we_write() {
    let Some(python) = common::venv_python() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for (name, compression) in [
        ("ours.mcap", Compression::Zstd),
        ("ours_folder", Compression::Lz4),
    ] {
        let path = dir.path().join(name);
        let mut w = BagWriter::create(&path, compression).unwrap();
        write_samples(&mut w);
        w.write("/float64", 2000, &Float64 { data: 1.5 }).unwrap();
        w.finish().unwrap();
        let v = common::json_output(Command::new(&python).args([SCRIPT, "read"]).arg(&path));
        let topics = v.as_object().unwrap();
        assert_eq!(topics.len(), 14, "{name}");
        for (topic, entry) in topics {
            assert_eq!(
                entry["definition_matches"], true,
                "{name} {topic}: schema text differs from rosbags' definition"
            );
        }
        assert_eq!(v["/float64"]["count"], 2);
        assert_eq!(v["/float64"]["first"]["data"], 0.0979);
        assert_eq!(v["/time"]["first"]["sec"], -3);
        assert_eq!(v["/speed_scaling"]["first"]["factor"], 0.35);
        let tf = &v["/tf"]["first"]["transforms"][0];
        assert_eq!(tf["child_frame_id"], "camera_link");
        assert_eq!(tf["transform"]["translation"]["z"], 0.8);
        assert_eq!(v["/camera_info"]["first"]["p"][2], 319.5);
        assert_eq!(v["/camera_info"]["first"]["roi"]["do_rectify"], true);
        let marker = &v["/markers"]["first"]["markers"][0];
        assert_eq!(marker["points"][1]["y"], 0.5);
        assert_eq!(marker["text"], "0.123 m");
        let status = &v["/diagnostics"]["first"]["status"][0];
        assert_eq!(status["values"][1]["value"], "307200");
        assert_eq!(v["/cloud"]["first"]["data"].as_array().unwrap().len(), 32);
        assert_eq!(v["/joint_states"]["first"]["position"][1], -1.25);
        assert_eq!(v["/image"]["first"]["data"][11], 11);
    }
}

#[test]
fn every_message_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let ours = our_payloads(dir.path());
    check(&ours["/camera_info"], &camera_info());
    check(&ours["/diagnostics"], &diagnostic_array());
    check(&ours["/transform_stamped"], &transform_stamped());
    let m: MarkerArray = decode(&ours["/markers"]).unwrap();
    assert_eq!(m, marker_array());
    let c: PointCloud2 = decode(&ours["/cloud"]).unwrap();
    assert_eq!(c, cloud(false));
    for ty in types() {
        assert!(definition(ty).unwrap().ends_with('\n'), "{ty}");
    }
}
