//! Depth images as a source: the points are those of `depth_image_proc`'s formula on every
//! pixel, a depth image source measures exactly as the PointCloud2 made from it, generated
//! depth-image bags hold their truth, and a depth image the monitor cannot place (no camera
//! model, a bad one, a malformed image) is an ERROR fault with no distance.

mod common;

use std::borrow::Cow;
use std::path::Path;

use common::{DEMO_CONFIG, DEMO_URDF};
use ist_monitor::bag::{read_messages, writer::Compression, BagWriter};
use ist_monitor::cloud::depth::{
    encode_depth, points_from_depth, DepthEncoding, DepthView, PinholeCamera,
};
use ist_monitor::cloud::pointcloud2::{encode, Layout};
use ist_monitor::cloud::RangeLimits;
use ist_monitor::config::Config;
use ist_monitor::monitor::replay::{replay, Clock, ReplayFrame, Summary};
use ist_monitor::monitor::{Level, Monitor};
use ist_monitor::msg::{self, CameraInfo, Header, Image, PointField};
use ist_monitor::robot::RobotModel;
use ist_monitor::scenario::{self, ScenarioParams, CAMERA_INFO_TOPIC, DEPTH_TOPIC};
use proptest::prelude::*;

/// `depth_image_proc::convertDepth` restated from its source, pixel by pixel in its own order
/// of f32 operations: `center = cx` (f32), `constant = unit / fx` (f64, then f32),
/// `x = (u − center)·depth·constant`, `z = toMeters(depth)`; no return gives NaN.
fn depth_image_proc_reference(
    depths: &[u32], // the stored value's bits: u16 millimetres or f32 metres
    width: usize,
    encoding: DepthEncoding,
    p: &[f64; 12],
) -> Vec<[f32; 3]> {
    let center_x = p[2] as f32;
    let center_y = p[6] as f32;
    let unit_scaling: f64 = match encoding {
        DepthEncoding::Millimetres16 => f64::from(0.001f32),
        DepthEncoding::Metres32 => 1.0,
    };
    let constant_x = (unit_scaling / p[0]) as f32;
    let constant_y = (unit_scaling / p[5]) as f32;
    depths
        .iter()
        .enumerate()
        .map(|(i, &bits)| {
            let (u, v) = ((i % width) as u32, (i / width) as u32);
            let (depth, valid, meters) = match encoding {
                DepthEncoding::Millimetres16 => {
                    let d = bits as u16;
                    (f32::from(d), d != 0, f32::from(d) * 0.001f32)
                }
                DepthEncoding::Metres32 => {
                    let d = f32::from_bits(bits);
                    (d, d.is_finite(), d)
                }
            };
            if !valid {
                return [f32::NAN; 3];
            }
            [
                (u as f32 - center_x) * depth * constant_x,
                (v as f32 - center_y) * depth * constant_y,
                meters,
            ]
        })
        .collect()
}

fn camera_info(width: u32, height: u32, fx: f64, fy: f64, cx: f64, cy: f64) -> CameraInfo {
    CameraInfo {
        header: Header {
            frame_id: "camera_optical_frame".into(),
            ..Header::default()
        },
        width,
        height,
        k: [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
        p: [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
        ..CameraInfo::default()
    }
}

fn same_point(a: [f32; 3], b: [f32; 3]) -> bool {
    (0..3).all(|i| a[i].to_bits() == b[i].to_bits() || (a[i].is_nan() && b[i].is_nan()))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, .. ProptestConfig::default() })]

    /// Every pixel of a random depth image (either encoding, either byte order, padded rows,
    /// holes of every kind) gives the point of depth_image_proc's formula, bit for bit.
    #[test]
    fn depth_image_points_follow_depth_image_proc(
        width in 1u32..24,
        height in 1u32..16,
        padding in 0u32..9,
        metres in any::<bool>(),
        big_endian in any::<bool>(),
        fx in 50.0f64..1500.0,
        fy in 50.0f64..1500.0,
        cx in -20.0f64..40.0,
        cy in -20.0f64..30.0,
        seed in any::<u64>(),
    ) {
        let encoding = if metres { DepthEncoding::Metres32 } else { DepthEncoding::Millimetres16 };
        let n = (width * height) as usize;
        // Stored values: every kind of pixel, from a small xorshift stream.
        let mut s = seed | 1;
        let mut next = || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
        let depths: Vec<u32> = (0..n)
            .map(|_| {
                let r = next();
                match (encoding, r % 8) {
                    (DepthEncoding::Millimetres16, 0) => 0,
                    (DepthEncoding::Millimetres16, 1) => 65535,
                    (DepthEncoding::Millimetres16, _) => (r >> 8) as u32 & 0xFFFF,
                    (DepthEncoding::Metres32, 0) => f32::NAN.to_bits(),
                    (DepthEncoding::Metres32, 1) => f32::INFINITY.to_bits(),
                    (DepthEncoding::Metres32, 2) => 0f32.to_bits(),
                    (DepthEncoding::Metres32, 3) => (-1.5f32).to_bits(),
                    (DepthEncoding::Metres32, _) => ((r >> 11) as f32 / (1u64 << 53) as f32 * 10.0).to_bits(),
                }
            })
            .collect();
        let size = encoding.size();
        let step = width as usize * size + padding as usize;
        let mut data = vec![0xA5u8; step * height as usize];
        for (i, &d) in depths.iter().enumerate() {
            let (u, v) = (i % width as usize, i / width as usize);
            let at = v * step + u * size;
            let bytes: Vec<u8> = match (encoding, big_endian) {
                (DepthEncoding::Millimetres16, false) => (d as u16).to_le_bytes().to_vec(),
                (DepthEncoding::Millimetres16, true) => (d as u16).to_be_bytes().to_vec(),
                (DepthEncoding::Metres32, false) => d.to_le_bytes().to_vec(),
                (DepthEncoding::Metres32, true) => d.to_be_bytes().to_vec(),
            };
            data[at..at + size].copy_from_slice(&bytes);
        }
        let image = Image {
            header: Header::default(),
            height,
            width,
            encoding: encoding.name().into(),
            is_bigendian: big_endian as u8,
            step: step as u32,
            data: Cow::Owned(data),
        };
        let info = camera_info(width, height, fx, fy, cx, cy);
        let camera = PinholeCamera::from_camera_info(&info).unwrap();
        let mut points = Vec::new();
        points_from_depth(&image, &camera, None, &mut points).unwrap();
        let want = depth_image_proc_reference(&depths, width as usize, encoding, &info.p);
        prop_assert_eq!(points.len(), n);
        for i in 0..n {
            prop_assert!(same_point(points[i], want[i]), "pixel {}: {:?} != {:?}", i, points[i], want[i]);
        }
        // Range limits drop exactly the points outside them.
        let (lo, hi) = (0.5, 3.0);
        points_from_depth(&image, &camera, RangeLimits::new(lo, Some(hi)), &mut points).unwrap();
        for i in 0..n {
            let p = want[i];
            let r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
            let kept = r2 >= (lo * lo) as f32 && r2 <= (hi * hi) as f32;
            let expected = if kept { p } else { [f32::NAN; 3] };
            prop_assert!(same_point(points[i], expected), "pixel {} with range limits", i);
        }
        // One pixel at a time (what the host makes of the few points a GPU result names), as
        // the whole image.
        let view = DepthView::new(&image, &camera, RangeLimits::new(lo, Some(hi))).unwrap();
        for (i, p) in points.iter().enumerate() {
            prop_assert!(same_point(view.point(i), *p), "pixel {} alone", i);
        }
    }
}

/// One pixel worked by hand: 16UC1 1000 mm at u = 0, v = 0 with fx = 500, cx = 3.5,
/// fy = 250, cy = 1.5 → x = −3.5·1000·(0.001/500) = −7 mm, y = −1.5·1000·(0.001/250) = −6 mm.
#[test]
fn one_pixel_by_hand() {
    let info = camera_info(4, 3, 500.0, 250.0, 3.5, 1.5);
    let camera = PinholeCamera::from_camera_info(&info).unwrap();
    let mut depths = vec![f32::NAN; 12];
    depths[0] = 1.0;
    let image = encode_depth(
        Header::default(),
        4,
        3,
        &depths,
        DepthEncoding::Millimetres16,
    );
    let mut points = Vec::new();
    points_from_depth(&image, &camera, None, &mut points).unwrap();
    let p = points[0];
    assert!((p[0] + 0.007).abs() < 1e-7 && (p[1] + 0.006).abs() < 1e-7 && p[2] == 1.0);
    assert!(points[1..].iter().all(|p| p[0].is_nan()));
}

fn demo_model() -> RobotModel {
    RobotModel::load(Path::new(DEMO_URDF), &[], &Default::default()).unwrap()
}

fn depth_config(mode: &str) -> Config {
    depth_config_with(&[("mode", mode)])
}

/// A latency budget no frame runs past: these tests compare answers and levels, and a frame
/// slowed by the tests running beside it (a software GPU among them) would otherwise WARN.
const NO_LATENCY_BUDGET: (&str, &str) = ("latency_budget", "60");

/// The demo config with the camera a depth-image source, no latency budget, and `overrides`.
fn depth_config_with(overrides: &[(&str, &str)]) -> Config {
    let o: Vec<(String, String)> = [
        ("camera.type", "depth_image"),
        ("camera.topic", DEPTH_TOPIC),
        NO_LATENCY_BUDGET,
    ]
    .iter()
    .chain(&common::SEEN_ONLY_FLOORLESS)
    .chain(overrides)
    .map(|(k, v)| (k.to_string(), v.to_string()))
    .collect();
    Config::load(Path::new(DEMO_CONFIG), &o).unwrap()
}

/// A generated bag of `frames` 16UC1 depth images of the demo robot, `name` in `dir`.
fn depth_bag(dir: &Path, name: &str, frames: usize) -> std::path::PathBuf {
    let bag = dir.join(name);
    let params = ScenarioParams {
        frames,
        depth: Some(DepthEncoding::Millimetres16),
        ..ScenarioParams::default()
    };
    scenario::generate(&demo_model(), &params, &bag).unwrap();
    bag
}

fn replay_all(config: Config, bag: &Path) -> (Vec<ReplayFrame>, Summary) {
    let mut monitor = Monitor::new(config, &|_| {}).unwrap();
    let mut frames = Vec::new();
    let summary = replay(&mut monitor, bag, None, Clock::Log, &mut |f| {
        frames.push(f.clone())
    })
    .unwrap();
    (frames, summary)
}

/// Writes `bag` with each depth image replaced by the PointCloud2 that its points make (the
/// cloud `depth_image_proc` would publish), on the cloud topic.
fn clouds_from_depth_bag(bag: &Path, out: &Path) {
    let messages = read_messages(bag, &|_, _| true).unwrap();
    let mut w = BagWriter::create(out, Compression::None).unwrap();
    let mut camera = None;
    for m in &messages {
        if &*m.topic == CAMERA_INFO_TOPIC {
            let info: CameraInfo = msg::decode(&m.data).unwrap();
            camera = Some(PinholeCamera::from_camera_info(&info).unwrap());
        }
        if &*m.topic != DEPTH_TOPIC {
            w.write_cdr(&m.topic, &m.schema, m.log_time_ns, &m.data)
                .unwrap();
            continue;
        }
        let image: Image = msg::decode(&m.data).unwrap();
        let mut points = Vec::new();
        points_from_depth(&image, &camera.unwrap(), None, &mut points).unwrap();
        let layout = Layout {
            width: image.width,
            height: image.height,
            datatype: PointField::FLOAT32,
            ..Layout::unorganized(0)
        };
        let cloud = encode(image.header.clone(), &points, &layout).unwrap();
        w.write(scenario::CLOUD_TOPIC, m.log_time_ns, &cloud)
            .unwrap();
    }
    w.finish().unwrap();
}

/// A generated depth-image bag (16UC1 and 32FC1): every frame's truth lies in the certified
/// interval, exact mode gives it, and the depth source's answers are bit for bit those of the
/// PointCloud2 made from each image.
#[test]
fn depth_image_bags_measure_as_their_clouds_and_hold_their_truth() {
    let model = demo_model();
    let dir = tempfile::tempdir().unwrap();
    for encoding in [DepthEncoding::Millimetres16, DepthEncoding::Metres32] {
        let bag = dir.path().join(format!("depth_{}", encoding.name()));
        let params = ScenarioParams {
            frames: 12,
            depth: Some(encoding),
            ..ScenarioParams::default()
        };
        let g = scenario::generate(&model, &params, &bag).unwrap();
        // Only depth images on the camera: no cloud in the bag.
        assert!(read_messages(&bag, &|t, _| t == scenario::CLOUD_TOPIC)
            .unwrap()
            .is_empty());
        let (depth, summary) = replay_all(depth_config("certified"), &bag);
        assert_eq!(depth.len(), 12);
        assert!(summary.faults.is_empty(), "{:?}", summary.faults);
        for (f, truth) in depth.iter().zip(&g.truth_m) {
            let truth = truth.unwrap();
            assert_eq!(f.truth_m, Some(truth));
            let (lower, upper) = (f.lower_m.unwrap(), f.distance_m.unwrap());
            assert!(
                lower <= truth + 1e-6 && truth <= upper + 1e-6,
                "{} frame {}: truth {truth} outside [{lower}, {upper}]",
                encoding.name(),
                f.index
            );
        }
        let (exact, _) = replay_all(depth_config("exact"), &bag);
        for f in &exact {
            let e = (f.distance_m.unwrap() - f.truth_m.unwrap()).abs();
            assert!(e < 1e-4, "exact frame {}: off by {e}", f.index);
        }
        // The same frames as clouds.
        let clouds = dir.path().join(format!("clouds_{}", encoding.name()));
        clouds_from_depth_bag(&bag, &clouds);
        let budget = [
            NO_LATENCY_BUDGET,
            common::SEEN_ONLY_FLOORLESS[0],
            common::SEEN_ONLY_FLOORLESS[1],
        ]
        .map(|(k, v)| (k.to_owned(), v.to_owned()));
        let config = Config::load(Path::new(DEMO_CONFIG), &budget).unwrap();
        let (as_clouds, _) = replay_all(config, &clouds);
        assert_eq!(as_clouds.len(), depth.len());
        for (a, b) in depth.iter().zip(&as_clouds) {
            assert_eq!(a.min_distance_m, b.min_distance_m, "frame {}", a.index);
            assert_eq!(a.lower_m, b.lower_m, "frame {}", a.index);
            assert_eq!(a.link, b.link, "frame {}", a.index);
            assert_eq!(a.level, b.level, "frame {}", a.index);
        }
    }
}

/// The depth source on the GPU (`backend: gpu`; lavapipe in CI): the monitor hands each image
/// to the engine whole, the GPU makes its points, and every frame answers as on the CPU (the
/// same link, distances and lower bounds within 1e-5 m, the truth in the interval).
/// With the stray filter on, the points are made on the host and the answers are again the
/// CPU's with the filter.
#[test]
fn depth_images_on_the_gpu_answer_as_on_the_cpu() {
    let dir = tempfile::tempdir().unwrap();
    let bag = depth_bag(dir.path(), "depth_16UC1", 6);
    let with = depth_config_with;
    for stray in ["1", "3"] {
        let (cpu, _) = replay_all(
            with(&[("backend", "cpu"), ("stray_filter.min_points", stray)]),
            &bag,
        );
        let (gpu, summary) = replay_all(
            with(&[("backend", "gpu"), ("stray_filter.min_points", stray)]),
            &bag,
        );
        assert!(summary.faults.is_empty(), "{:?}", summary.faults);
        let Some(backend) = gpu[0].backend else {
            panic!("frame 0: {:?}", gpu[0])
        };
        if backend != ist_monitor::query::Backend::Gpu {
            assert!(
                std::env::var_os("CI").is_none(),
                "CI: the depth images ran on {backend:?}"
            );
            common::skip("no GPU adapter and CI is not set");
            return;
        }
        assert_eq!(gpu.len(), cpu.len());
        let close = |a: Option<f64>, b: Option<f64>| (a.unwrap() - b.unwrap()).abs() < 1e-5;
        for (c, g) in cpu.iter().zip(&gpu) {
            let what = format!("stray {stray}, frame {}", g.index);
            assert_eq!(g.backend, Some(ist_monitor::query::Backend::Gpu), "{what}");
            assert_eq!(c.link, g.link, "{what}");
            assert_eq!(c.level, g.level, "{what}");
            assert!(close(c.distance_m, g.distance_m), "{what}: {c:?} {g:?}");
            assert!(close(c.lower_m, g.lower_m), "{what}");
            // (The filter measures the nearest cluster: the truth, the nearest point's, may
            // lie below its interval.)
            let truth = g.truth_m.unwrap();
            assert!(
                stray != "1"
                    || (g.lower_m.unwrap() <= truth + 1e-6
                        && truth <= g.distance_m.unwrap() + 1e-6),
                "{what}"
            );
        }
    }
}

/// A depth image with no camera model, a refused camera model or a malformed image is an
/// ERROR fault with no distance that says why; the source recovers when a good CameraInfo
/// comes.
#[test]
fn depth_images_that_cannot_be_placed_are_faults() {
    let dir = tempfile::tempdir().unwrap();
    let bag = depth_bag(dir.path(), "depth", 12);
    let messages = read_messages(&bag, &|_, _| true).unwrap();
    let edited = dir.path().join("edited");
    let mut w = BagWriter::create(&edited, Compression::None).unwrap();
    let (mut infos, mut images) = (0, 0);
    for m in &messages {
        let mut data = m.data.clone();
        if &*m.topic == CAMERA_INFO_TOPIC {
            infos += 1;
            match infos {
                // No CameraInfo before the first three images.
                1..=3 => continue,
                // A camera with no focal length for images 4 and 5.
                4 => {
                    let mut c: CameraInfo = msg::decode(&data).unwrap();
                    c.p[5] = 0.0;
                    data = msg::encode(&c).unwrap();
                }
                5 => continue,
                _ => {}
            }
        }
        if &*m.topic == DEPTH_TOPIC {
            images += 1;
            let mut i: Image = msg::decode(&data).unwrap();
            match images {
                8 => i.encoding = "bgr8".into(),
                9 => i.data = Cow::Owned(i.data[..i.data.len() - 2].to_vec()),
                10 => i.width /= 2,
                _ => {}
            }
            data = msg::encode(&i).unwrap();
        }
        w.write_cdr(&m.topic, &m.schema, m.log_time_ns, &data)
            .unwrap();
    }
    w.finish().unwrap();
    let mut monitor = Monitor::new(depth_config("certified"), &|_| {}).unwrap();
    let mut frames = Vec::new();
    replay(&mut monitor, &edited, None, Clock::Log, &mut |f| {
        frames.push(f.clone())
    })
    .unwrap();
    let fault = |i: usize, wants: &[&str]| {
        let f = &frames[i];
        assert_eq!(f.level, Level::Error, "frame {i}");
        assert_eq!(f.min_distance_m, None, "frame {i}");
        let text = f.fault.clone().unwrap_or_default();
        for w in wants {
            assert!(text.contains(w), "frame {i}: '{text}' lacks '{w}'");
        }
    };
    for i in 0..3 {
        fault(i, &["no CameraInfo received yet", CAMERA_INFO_TOPIC]);
    }
    for i in 3..5 {
        fault(i, &["refused", "field p", "fy"]);
    }
    assert!(frames[5].min_distance_m.is_some(), "{:?}", frames[5].fault);
    fault(7, &["field encoding", "bgr8"]);
    fault(8, &["field data"]);
    fault(9, &["CameraInfo says"]);
    assert!(frames[10].min_distance_m.is_some() && frames[11].min_distance_m.is_some());
}
