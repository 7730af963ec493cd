//! One voice per input (issue 46), through the monitor as the node drives it: a second writer
//! on a source's topic, of a joint, or of the camera's frame never releases the stop, and the
//! fault `second_publisher` names the writers; once one writer has been alone for
//! `second_publisher_window`, its frames are measured again.

mod common;

use ist_monitor::cloud::pointcloud2;
use ist_monitor::config::Config;
use ist_monitor::monitor::{Frame, Level, Monitor};
use ist_monitor::msg::{Header, JointState, TfMessage, Time, Transform, TransformStamped, Writer};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

const T0: i64 = 1_700_000_000_000_000_000;
const MS: i64 = 1_000_000;
const CAMERA: Writer = Writer([1; 16]);
const INTRUDER: Writer = Writer([2; 16]);

/// The demo arm seen by a camera `cam` whose pose comes from `/tf` (`world` → `cam`), joints
/// from `/joint_states`, `second_publisher_window` 0.5 s; and the height of the arm's top at
/// rest (the highest point of its inner spheres, the root at the origin).
fn monitor() -> (Monitor, Vec<String>, f32) {
    let (model, trees) = common::demo_trees();
    let joints = model.kinematics.variables().to_vec();
    let poses = model.kinematics.link_poses(&vec![0.0; joints.len()]);
    let top = (trees.iter())
        .flat_map(|tree| {
            let pose = poses[model.kinematics.link_index(&tree.link).unwrap()];
            tree.spheres.iter().map(move |s| {
                let c = s.center.map(f64::from);
                (pose * nalgebra::Point3::new(c[0], c[1], c[2])).z as f32 + s.radius
            })
        })
        .fold(f32::MIN, f32::max);
    let config = Config::from_overrides(&[
        ("robot_description".into(), common::DEMO_URDF.into()),
        ("backend".into(), "cpu".into()),
        ("second_publisher_window".into(), "0.5".into()),
    ])
    .unwrap();
    (
        Monitor::with_trees(config, model, &trees).unwrap(),
        joints,
        top,
    )
}

fn header(t: i64, frame: &str) -> Header {
    Header {
        stamp: Time::from_nanos(t),
        frame_id: frame.into(),
    }
}

/// `world` → `cam` at the origin (`x` along x) at `t`, written by `w`.
fn camera_pose(m: &mut Monitor, t: i64, x: f64, w: Writer) {
    let pose = Isometry3::from_parts(Translation3::new(x, 0.0, 0.0), UnitQuaternion::identity());
    let tf = TfMessage {
        transforms: vec![TransformStamped {
            header: header(t, "world"),
            child_frame_id: "cam".into(),
            transform: Transform::from_isometry(&pose),
        }],
    };
    m.on_tf_from("/tf", &tf, false, w).unwrap();
}

/// Every joint at `q` at `t`, published by `w`.
fn joints(m: &mut Monitor, names: &[String], t: i64, q: f64, w: Writer) {
    let js = JointState {
        header: header(t, ""),
        name: names.to_vec(),
        position: vec![q; names.len()],
        ..JointState::default()
    };
    m.on_joint_state_from("/joint_states", &js, w).unwrap();
}

/// A cloud of one point at `z` above the root, stamped `t`, from `w`, processed at `t`.
fn cloud(m: &mut Monitor, t: i64, z: f32, w: Writer) -> Frame {
    let layout = pointcloud2::Layout::unorganized(1);
    let c = pointcloud2::encode(header(t, "cam"), &[[0.0, 0.0, z]], &layout).unwrap();
    m.hear_writer(0, w, t);
    m.on_cloud(0, &c, std::time::Instant::now(), Some(t))
}

fn fault_kind(f: &Frame) -> String {
    common::status_value(f, "fault")
        .unwrap_or_default()
        .to_owned()
}

/// The case: the camera sees an obstacle inside `stop_distance`; a second publisher on
/// the same topic sends the scene 3 m farther 50 ms after each frame. The stop is never
/// released while both speak; the camera alone for the window is measured again.
#[test]
fn a_second_publisher_on_the_cloud_topic_never_releases_the_stop() {
    let (mut m, names, top) = monitor();
    let (near_z, far_z) = (top + 0.05, top + 3.05);
    let mut stops = String::new();
    let mut faults = Vec::new();
    for k in 0..20 {
        let t = T0 + k * 100 * MS;
        camera_pose(&mut m, t, 0.0, CAMERA);
        joints(&mut m, &names, t, 0.0, CAMERA);
        // The obstacle 5 cm above the arm's top.
        let near = cloud(&mut m, t, near_z, CAMERA);
        stops.push(if near.outputs.safety_stop.data {
            '1'
        } else {
            '0'
        });
        if k >= 3 {
            camera_pose(&mut m, t + 50 * MS, 0.0, CAMERA);
            let far = cloud(&mut m, t + 50 * MS, far_z, INTRUDER);
            stops.push(if far.outputs.safety_stop.data {
                '1'
            } else {
                '0'
            });
            assert!(far.outputs.min_distance.is_none(), "frame {k}");
            faults.push(fault_kind(&far));
        }
    }
    assert!(!stops.contains('0'), "the stop was released: {stops}");
    assert!(faults.iter().all(|f| f == "second_publisher"), "{faults:?}");
    let last = cloud(&mut m, T0 + 1_960 * MS, near_z, CAMERA);
    let message = &last.outputs.diagnostics.status[0].message;
    assert!(message.contains(&INTRUDER.to_string()), "{message}");
    assert!(message.contains(&CAMERA.to_string()), "{message}");
    // The intruder falls silent: once the camera has been alone for 0.5 s, its frames count
    // again (here: still the obstacle, still the stop, now with a distance).
    let mut measured = None;
    for k in 20..32 {
        let t = T0 + k * 100 * MS;
        camera_pose(&mut m, t, 0.0, CAMERA);
        joints(&mut m, &names, t, 0.0, CAMERA);
        let f = cloud(&mut m, t, near_z, CAMERA);
        assert!(f.outputs.safety_stop.data);
        if f.outputs.min_distance.is_some() && measured.is_none() {
            measured = Some(k);
        }
    }
    // The intruder's last frame was stamped at 1.95 s: measured from 2.5 s on.
    assert_eq!(measured, Some(25));
}

/// The control: the same far clouds from the camera's own writer release the stop (what a
/// second writer would do if it were taken as the source), so the test above can fail.
#[test]
fn the_far_cloud_from_the_one_writer_does_release_it() {
    let (mut m, names, top) = monitor();
    camera_pose(&mut m, T0, 0.0, CAMERA);
    joints(&mut m, &names, T0, 0.0, CAMERA);
    assert!(
        cloud(&mut m, T0, top + 0.05, CAMERA)
            .outputs
            .safety_stop
            .data
    );
    let t = T0 + 50 * MS;
    camera_pose(&mut m, t, 0.0, CAMERA);
    joints(&mut m, &names, t, 0.0, CAMERA);
    let far = cloud(&mut m, t, top + 3.05, CAMERA);
    assert!(!far.outputs.safety_stop.data);
    assert_eq!(far.outputs.level, Level::Ok);
}

/// Two writers of the arm's joints (a second joint_state_publisher holding the arm elsewhere),
/// and two authorities for the camera's frame: every frame is the fault, no distance.
#[test]
fn two_joint_state_writers_and_two_tf_authorities_are_faults() {
    let (mut m, names, top) = monitor();
    for k in 0..5 {
        let t = T0 + k * 100 * MS;
        camera_pose(&mut m, t, 0.0, CAMERA);
        joints(&mut m, &names, t, 0.0, CAMERA);
        joints(&mut m, &names, t + 10 * MS, 1.0, INTRUDER);
        let f = cloud(&mut m, t + 10 * MS, top + 3.05, CAMERA);
        assert_eq!(f.outputs.level, Level::Error, "frame {k}");
        assert!(f.outputs.min_distance.is_none());
        assert_eq!(fault_kind(&f), "second_publisher");
        let message = &f.outputs.diagnostics.status[0].message;
        assert!(
            message.contains("published by more than one writer"),
            "{message}"
        );
    }
    let (mut m, names, _) = monitor();
    for k in 0..5 {
        let t = T0 + k * 100 * MS;
        camera_pose(&mut m, t, 0.0, CAMERA);
        camera_pose(&mut m, t + 5 * MS, 3.0, INTRUDER);
        joints(&mut m, &names, t, 0.0, CAMERA);
        let f = cloud(&mut m, t + 5 * MS, top + 3.05, CAMERA);
        assert_eq!(f.outputs.level, Level::Error, "frame {k}");
        assert_eq!(fault_kind(&f), "second_publisher");
    }
}

/// A depth image source whose CameraInfo comes from two writers (a second driver with other
/// intrinsics would move every point): its images are the fault, naming the CameraInfo topic.
#[test]
fn two_camera_info_writers_are_a_fault_of_the_depth_source() {
    use ist_monitor::msg::{CameraInfo, Image};
    let (model, trees) = common::demo_trees();
    let names = model.kinematics.variables().to_vec();
    let config = Config::from_overrides(&[
        ("robot_description".into(), common::DEMO_URDF.into()),
        ("backend".into(), "cpu".into()),
        ("camera.type".into(), "depth_image".into()),
        ("camera.topic".into(), "/camera/depth/image_raw".into()),
    ])
    .unwrap();
    let mut m = Monitor::with_trees(config, model, &trees).unwrap();
    let (w, h, f) = (32u32, 24u32, 30.0);
    let info = |t: i64, f: f64| CameraInfo {
        header: header(t, "cam"),
        height: h,
        width: w,
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        k: [f, 0.0, 15.5, 0.0, f, 11.5, 0.0, 0.0, 1.0],
        r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        p: [f, 0.0, 15.5, 0.0, 0.0, f, 11.5, 0.0, 0.0, 0.0, 1.0, 0.0],
        ..Default::default()
    };
    let image = |t: i64| Image {
        header: header(t, "cam"),
        height: h,
        width: w,
        encoding: "16UC1".into(),
        is_bigendian: 0,
        step: 2 * w,
        data: (0..w * h)
            .flat_map(|_| 3000u16.to_le_bytes())
            .collect::<Vec<u8>>()
            .into(),
    };
    // The camera's pose, the joints and the camera's own CameraInfo at `t`.
    let inputs = |m: &mut Monitor, t: i64| {
        camera_pose(m, t, 0.0, CAMERA);
        joints(m, &names, t, 0.0, CAMERA);
        m.on_camera_info_from(0, &info(t, f), CAMERA).unwrap();
    };
    let mut kinds = Vec::new();
    for k in 0..4 {
        let t = T0 + k * 100 * MS;
        inputs(&mut m, t);
        if k >= 2 {
            m.on_camera_info_from(0, &info(t, 3.0 * f), INTRUDER)
                .unwrap();
        }
        m.hear_writer(0, CAMERA, t);
        let frame = m.on_depth_image(0, &image(t), std::time::Instant::now(), Some(t));
        kinds.push(fault_kind(&frame));
        if k >= 2 {
            let message = &frame.outputs.diagnostics.status[0].message;
            assert!(message.contains("/camera/depth/camera_info"), "{message}");
            assert!(frame.outputs.min_distance.is_none());
        }
    }
    assert_eq!(kinds, ["", "", "second_publisher", "second_publisher"]);
    // By discovery: the second CameraInfo writer falls silent (its messages lost) but stays
    // matched: still the fault, naming the CameraInfo topic, beyond the window (1 s) after its
    // newest stamp (0.3 s), where its messages alone no longer make one; once it has left the
    // graph, the images are measured again.
    let both = Some(vec![CAMERA.to_string(), INTRUDER.to_string()]);
    let mut kinds = Vec::new();
    for k in 4..20 {
        let t = T0 + k * 100 * MS;
        inputs(&mut m, t);
        let matched = if k < 16 {
            both.clone()
        } else {
            Some(vec![CAMERA.to_string()])
        };
        m.matched_camera_writers(0, matched);
        m.hear_writer(0, CAMERA, t);
        let frame = m.on_depth_image(0, &image(t), std::time::Instant::now(), Some(t));
        if k < 16 {
            let message = &frame.outputs.diagnostics.status[0].message;
            assert!(
                message.contains("by discovery") && message.contains("camera_info"),
                "{message}"
            );
        }
        kinds.push(fault_kind(&frame));
    }
    assert_eq!(kinds[..12], ["second_publisher"; 12], "{kinds:?}");
    assert_eq!(kinds[12..], [""; 4], "{kinds:?}");
}

/// Discovery on the joint states and TF (DDS gives their writers by GID): the controller's joint
/// states, or the camera frame's transforms, are all lost for 2 s while a second writer's get
/// through. By the messages that writer is alone once the first one's newest stamp is a window
/// old, and its values are taken (the control, without discovery); with discovery matching
/// both, the first writer is still the joint's or the frame's voice, and every frame is the
/// fault `second_publisher` naming both, until the second writer leaves the graph.
#[test]
fn a_joint_or_frame_writer_whose_messages_are_lost_still_holds_by_discovery() {
    for input in ["joint_states", "tf"] {
        for discovery in [true, false] {
            let (mut m, names, top) = monitor();
            let far_z = top + 3.05;
            let matched = |m: &mut Monitor, writers: &[Writer]| {
                let writers = if discovery {
                    writers.to_vec()
                } else {
                    Vec::new()
                };
                match input {
                    "joint_states" => m.matched_joint_state_writers(writers),
                    _ => m.matched_tf_writers(writers),
                }
            };
            for k in 0..5 {
                let t = T0 + k * 100 * MS;
                camera_pose(&mut m, t, 0.0, CAMERA);
                joints(&mut m, &names, t, 0.0, CAMERA);
                matched(&mut m, &[CAMERA, INTRUDER]);
                let f = cloud(&mut m, t, far_z, CAMERA);
                assert_eq!(fault_kind(&f), "", "{input} frame {k}");
            }
            // The first writer's messages on the input lost; the second one's get through.
            let mut kinds = Vec::new();
            for k in 5..25 {
                let t = T0 + k * 100 * MS;
                if input == "joint_states" {
                    camera_pose(&mut m, t, 0.0, CAMERA);
                    joints(&mut m, &names, t, 1.0, INTRUDER);
                } else {
                    camera_pose(&mut m, t, 3.0, INTRUDER);
                    joints(&mut m, &names, t, 0.0, CAMERA);
                }
                matched(&mut m, &[CAMERA, INTRUDER]);
                let f = cloud(&mut m, t, far_z, CAMERA);
                if discovery {
                    let message = &f.outputs.diagnostics.status[0].message;
                    for w in [CAMERA, INTRUDER] {
                        assert!(message.contains(&w.to_string()), "{input}: {message}");
                    }
                }
                kinds.push(fault_kind(&f));
            }
            if !discovery {
                // The first writer's newest stamp (0.4 s) a window old from 0.9 s on (frame 9).
                assert!(
                    kinds[5..].iter().all(|k| k.is_empty()),
                    "{input}: {kinds:?}"
                );
                continue;
            }
            assert!(
                kinds.iter().all(|k| k == "second_publisher"),
                "{input}: {kinds:?}"
            );
            // The second writer leaves the graph, the first one speaks again: measured once the
            // second one's newest stamp (2.4 s) is a window old.
            let mut kinds = Vec::new();
            for k in 25..35 {
                let t = T0 + k * 100 * MS;
                camera_pose(&mut m, t, 0.0, CAMERA);
                joints(&mut m, &names, t, 0.0, CAMERA);
                matched(&mut m, &[CAMERA]);
                kinds.push(fault_kind(&cloud(&mut m, t, far_z, CAMERA)));
            }
            assert!(
                kinds[..4].iter().all(|k| k == "second_publisher"),
                "{input}: {kinds:?}"
            );
            assert!(
                kinds[5..].iter().all(|k| k.is_empty()),
                "{input}: {kinds:?}"
            );
        }
    }
}

/// The hole that messages alone leave (issue 46's flaky rclpy check): the camera's clouds are
/// all lost for longer than the window while a second writer's far clouds get through. By the
/// messages, that writer is alone, and its frame would release the stop; discovery still matches
/// both writers, so every frame is the fault `second_publisher` naming both, and the stop is
/// held. Once discovery matches only the camera (and the intruder has been silent for the
/// window), the camera's frames are measured again. Without discovery (`None`, a replay) the
/// same frames show the hole: the intruder's far cloud is measured and the stop released.
#[test]
fn a_writer_whose_clouds_are_all_lost_still_holds_the_stop_by_discovery() {
    let names_of = |ws: &[Writer]| Some(ws.iter().map(Writer::to_string).collect::<Vec<_>>());
    let mut released_without_discovery = false;
    for discovery in [true, false] {
        let (mut m, names, top) = monitor();
        let (near_z, far_z) = (top + 0.05, top + 3.05);
        let both = discovery.then(|| names_of(&[CAMERA, INTRUDER])).flatten();
        // The camera sees the obstacle; the intruder's publisher is matched but silent.
        for k in 0..5 {
            let t = T0 + k * 100 * MS;
            camera_pose(&mut m, t, 0.0, CAMERA);
            joints(&mut m, &names, t, 0.0, CAMERA);
            m.matched_writers(0, both.clone());
            let f = cloud(&mut m, t, near_z, CAMERA);
            assert!(f.outputs.safety_stop.data, "frame {k}");
        }
        // The camera's clouds are all lost for 2 s (four windows); the intruder's get through.
        let mut stops = String::new();
        for k in 5..25 {
            let t = T0 + k * 100 * MS;
            camera_pose(&mut m, t, 0.0, CAMERA);
            joints(&mut m, &names, t, 0.0, CAMERA);
            m.matched_writers(0, both.clone());
            let f = cloud(&mut m, t, far_z, INTRUDER);
            stops.push(if f.outputs.safety_stop.data { '1' } else { '0' });
            if discovery {
                assert_eq!(fault_kind(&f), "second_publisher", "frame {k}");
                assert!(f.outputs.min_distance.is_none(), "frame {k}");
                let message = &f.outputs.diagnostics.status[0].message;
                for w in [CAMERA, INTRUDER] {
                    assert!(message.contains(&w.to_string()), "{message}");
                }
            }
        }
        if discovery {
            assert!(!stops.contains('0'), "the stop was released: {stops}");
            // The intruder leaves: the camera alone by discovery, and by its messages once the
            // intruder's newest stamp is a window old.
            let mut measured = false;
            for k in 25..35 {
                let t = T0 + k * 100 * MS;
                camera_pose(&mut m, t, 0.0, CAMERA);
                joints(&mut m, &names, t, 0.0, CAMERA);
                m.matched_writers(0, names_of(&[CAMERA]));
                let f = cloud(&mut m, t, near_z, CAMERA);
                assert!(f.outputs.safety_stop.data, "frame {k}");
                measured |= f.outputs.min_distance.is_some();
            }
            assert!(measured, "the camera alone is measured again");
        } else {
            released_without_discovery = stops.contains('0');
        }
    }
    assert!(
        released_without_discovery,
        "the control: by the messages alone the intruder's far cloud is measured"
    );
}
