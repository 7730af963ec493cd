//! The scenario generator: bags the project makes itself, with the exact answer recorded.
//!
//! A simulated depth camera — pinhole model, range noise, dropped pixels — looks at the demo
//! robot moving along a joint trajectory and at an obstacle: a person-sized capsule that walks
//! up to the arm (`person`; `approach`: up to the swinging arm and back; `table`: with a work
//! table beside the arm), or a box the arm reaches over (`shelf`). Every frame is ray cast
//! against the robot's collision meshes (the same tessellated meshes the monitor uses), the
//! obstacle and a back wall; rays that hit nothing within the camera's range give NaN, like a
//! real depth camera.
//!
//! Recorded, as rosbag2 MCAP: `/tf_static` (the camera's optical frame under the URDF's
//! `camera_link`), `/joint_states` at 50 Hz, `/camera/depth/points` (organized PointCloud2,
//! FLOAT32 x y z and 4 bytes of padding) and `/camera/depth/camera_info` at 10 Hz, and on
//! [`GROUND_TRUTH_TOPIC`] the exact minimum distance between the robot's collision meshes and
//! the cloud's obstacle points of each frame, at the cloud's log time. Clouds are stamped at
//! joint-state sample times, so the monitor's interpolated joint values are the rendered ones.
//! Joint states carry their velocities (the central difference of the trajectory). For the
//! speed and separation monitor, each frame also records on [`APPROACH_TRUTH_TOPIC`] the
//! robot's approach speed at its closest mesh point — that point moved with its link by the
//! forward kinematics along the trajectory (central difference), projected on the direction
//! to the obstacle point — and on [`MARGIN_TRUTH_TOPIC`] the separation margin: the exact
//! distance minus the protective separation distance with the default parameters
//! (`SsmParams::default`, the cloud taken as seen at once).
//!
//! The truth is taken over the points that hit the obstacle or the wall; points on the robot
//! itself are what the monitor's self-filter removes. So that the two agree, the range noise is
//! clipped at 2.5 σ (a robot point then lies at most 2.5 σ from its surface, well inside the
//! self-filter padding with the surface gap added), and the obstacle's closest approach stays
//! above the padding. The noise is Gaussian from a fixed SplitMix64 stream (written here, a few
//! lines, so that a seed gives the same bag with every toolchain and crate version).
//!
//! Cost: one ray per pixel against every collision element, then one exact distance per
//! obstacle point (pruned by bounding boxes); about a second for 30 frames of 128×96.

use std::path::Path;

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use parry3d::math::Vector;
use parry3d::query::{Ray, RayCast};
use parry3d::shape::{Capsule, Cuboid};
use rayon::prelude::*;

use crate::bag::{
    writer::Compression, BagWriter, APPROACH_TRUTH_TOPIC, GROUND_TRUTH_TOPIC, MARGIN_TRUTH_TOPIC,
};
use crate::cloud::depth::{encode_depth, points_from_depth, DepthEncoding, PinholeCamera};
use crate::cloud::pointcloud2::{encode, Colour, Layout};
use crate::cloud::CloudError;
use crate::msg::{
    CameraInfo, Float64, Header, JointState, PointCloud2, PointField, TfMessage, Time, Transform,
    TransformStamped,
};
use crate::packing::Solid;
use crate::robot::RobotModel;
use crate::separation::SsmParams;

/// The scenes the generator knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SceneKind {
    /// A person-sized capsule walks up to the arm while it swings toward them.
    Person,
    /// The arm reaches over a box standing in front of it.
    Shelf,
    /// The person walks up to the arm while it swings toward them, and both go back: the
    /// approach and the recovery of the speed and separation monitor.
    Approach,
    /// The person scene with a 0.5 m work table beside the arm, which the gripper passes
    /// above: a fixture for exclusion volumes.
    Table,
}

/// The table of [`SceneKind::Table`]: its centre in the root frame and its edge lengths, m.
pub const TABLE_CENTER: [f64; 3] = [0.35, 0.45, 0.275];
pub const TABLE_SIZE: [f64; 3] = [0.5, 0.5, 0.55];

/// What a pixel's ray hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Hit {
    /// No return, or a dropped pixel.
    Nothing,
    Robot,
    /// A shape of the scene: 0 the back wall, 1 the obstacle (person or box), 2 the table.
    Scene(u8),
}

impl SceneKind {
    /// Where along the walk-up the scene is at `s` ∈ [0, 1]: the approach scene goes out and
    /// back.
    fn progress(self, s: f64) -> f64 {
        match self {
            SceneKind::Approach => 1.0 - (2.0 * s - 1.0).abs(),
            _ => s,
        }
    }
}

/// Generator settings.
#[derive(Debug, Clone)]
pub struct ScenarioParams {
    pub scene: SceneKind,
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    /// Horizontal field of view, degrees.
    pub hfov_deg: f64,
    /// Range noise σ along the ray, m (clipped at 2.5 σ).
    pub noise_m: f64,
    /// Fraction of pixels dropped (NaN).
    pub holes: f64,
    /// Farthest return, m.
    pub max_range_m: f64,
    pub seed: u64,
    pub compression: Compression,
    /// Bytes per point: 16 (x y z, padding) or 32 (x y z, padding, rgb, padding), as RGB-D
    /// drivers publish.
    pub point_step: u32,
    /// Record depth images in this encoding on [`DEPTH_TOPIC`] instead of clouds: the points
    /// (and the truth) are then those `depth_image_proc` makes from the recorded image.
    pub depth: Option<DepthEncoding>,
}

impl Default for ScenarioParams {
    fn default() -> Self {
        Self {
            scene: SceneKind::Person,
            frames: 30,
            width: 128,
            height: 96,
            hfov_deg: 62.0,
            noise_m: 0.001,
            holes: 0.02,
            max_range_m: 4.0,
            seed: 1,
            compression: Compression::Zstd,
            point_step: 16,
            depth: None,
        }
    }
}

pub const CLOUD_TOPIC: &str = "/camera/depth/points";
pub const CAMERA_INFO_TOPIC: &str = "/camera/depth/camera_info";
/// Where depth images are recorded (`ScenarioParams::depth`).
pub const DEPTH_TOPIC: &str = "/camera/depth/image_raw";
pub const CAMERA_LINK: &str = "camera_link";
pub const OPTICAL_FRAME: &str = "camera_optical_frame";
const CLOUD_RATE_HZ: f64 = 10.0;
/// Step in `s` of the central differences.
const DS: f64 = 1e-6;
const JOINT_RATE_HZ: f64 = 50.0;
/// Stamp of the first frame, ns (2023-11-14).
const START_NS: i64 = 1_700_000_000_000_000_000;

/// What the generator wrote.
#[derive(Debug, Clone)]
pub struct Generated {
    pub frames: usize,
    /// Exact minimum distance per frame, m (`None`: no obstacle point).
    pub truth_m: Vec<Option<f64>>,
    /// The truth of the separation monitor per frame: the robot's approach speed at its
    /// closest point (m/s) and the separation margin with the default SSM parameters (m).
    pub separation: Vec<Option<(f64, f64)>>,
    /// Obstacle and robot points per frame.
    pub obstacle_points: Vec<usize>,
    pub robot_points: Vec<usize>,
}

/// SplitMix64 with Box–Muller: a fixed, reproducible stream.
struct Noise(u64);

impl Noise {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in (0, 1].
    fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) + 1) as f64 / (1u64 << 53) as f64
    }
    fn gaussian(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// The joint trajectory of a scene at `s` ∈ [0, 1] (eased), as `name = value` pairs.
fn joints_at(scene: SceneKind, s: f64) -> Vec<(String, f64)> {
    let ease = 0.5 - 0.5 * (std::f64::consts::PI * scene.progress(s)).cos();
    let (from, to): ([f64; 7], [f64; 7]) = match scene {
        // pan, lift, elbow, wrist_1, wrist_2, wrist_3, finger
        SceneKind::Person | SceneKind::Approach | SceneKind::Table => (
            [0.9, 0.2, 1.1, 0.6, 0.0, 0.0, 0.015],
            [-0.95, 0.55, 0.95, 0.5, 0.8, 0.3, 0.005],
        ),
        SceneKind::Shelf => (
            [0.3, -0.2, 1.6, 0.9, 0.0, 0.0, 0.02],
            [0.05, 0.56, 0.92, 0.95, 0.4, 0.0, 0.01],
        ),
    };
    let names = [
        "shoulder_pan",
        "shoulder_lift",
        "elbow",
        "wrist_1",
        "wrist_2",
        "wrist_3",
        "finger_left_joint",
    ];
    names
        .iter()
        .zip(from.iter().zip(&to))
        .map(|(n, (a, b))| (n.to_string(), a + ease * (b - a)))
        .collect()
}

/// The environment of a scene: shapes with their world poses at `s` ∈ [0, 1].
fn obstacles(
    scene_kind: SceneKind,
    s: f64,
) -> Vec<(Box<dyn RayCast + Send + Sync>, Isometry3<f64>)> {
    // A wall 1.4 m behind the robot, seen past it.
    let wall: Box<dyn RayCast + Send + Sync> = Box::new(Cuboid::new(Vector::new(0.05, 2.0, 1.2)));
    let wall_pose = Isometry3::translation(-1.4, 0.0, 1.2);
    let obstacle: (Box<dyn RayCast + Send + Sync>, Isometry3<f64>) = match scene_kind {
        SceneKind::Person | SceneKind::Approach | SceneKind::Table => {
            // Radius 0.18 m, 1.7 m tall, walking from 1.1 m to 0.58 m beside the base (the
            // approach scene: from 1.2 m, and back).
            let (walk, from) = match scene_kind {
                SceneKind::Approach => (scene_kind.progress(s), -1.2),
                _ => ((s * 1.2).min(1.0), -1.1),
            };
            let y = from + walk * (-from - 0.58);
            (
                Box::new(Capsule::new_z(0.67, 0.18)),
                Isometry3::translation(0.1, y, 0.85),
            )
        }
        SceneKind::Shelf => (
            Box::new(Cuboid::new(Vector::new(0.15, 0.25, 0.2))),
            Isometry3::translation(0.62, 0.05, 0.2),
        ),
    };
    let mut scene = vec![(wall, wall_pose), obstacle];
    if scene_kind == SceneKind::Table {
        let [x, y, z] = TABLE_SIZE.map(|e| 0.5 * e);
        let [cx, cy, cz] = TABLE_CENTER;
        scene.push((
            Box::new(Cuboid::new(Vector::new(x as f32, y as f32, z as f32))),
            Isometry3::translation(cx, cy, cz),
        ));
    }
    scene
}

fn ray_hit(
    shape: &(dyn RayCast + Send + Sync),
    pose: &Isometry3<f64>,
    o: &Point3<f64>,
    d: &Vector3<f64>,
    max: f64,
) -> Option<f64> {
    let lo = pose.inverse_transform_point(o);
    let ld = pose.inverse_transform_vector(d);
    let ray = Ray::new(
        Vector::new(lo.x as f32, lo.y as f32, lo.z as f32),
        Vector::new(ld.x as f32, ld.y as f32, ld.z as f32),
    );
    shape.cast_local_ray(&ray, max as f32, true).map(f64::from)
}

/// `camera_link_from_optical`: z forward, x right, y down (REP 103).
pub fn link_from_optical() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_euler_angles(
            -std::f64::consts::FRAC_PI_2,
            0.0,
            -std::f64::consts::FRAC_PI_2,
        ),
    )
}

/// Why a scenario cannot be generated.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("the robot has no link {0} to mount the camera on")]
    NoCameraLink(String),
    #[error("link {0} has collision geometry but is not in the robot's kinematics")]
    NotInKinematics(String),
    #[error("joint values: {0}")]
    Joints(#[from] crate::robot::RobotError),
    #[error(transparent)]
    Bag(#[from] crate::bag::BagError),
    #[error(transparent)]
    Cloud(#[from] CloudError),
}

/// Where the camera is mounted: a link of the robot and the optical frame's pose in it.
#[derive(Debug, Clone)]
pub struct Mount {
    pub link: String,
    pub link_from_optical: Isometry3<f64>,
}

impl Mount {
    /// The demo robot's fixed camera: [`OPTICAL_FRAME`] under [`CAMERA_LINK`].
    pub fn fixed() -> Self {
        Self {
            link: CAMERA_LINK.into(),
            link_from_optical: link_from_optical(),
        }
    }
}

/// One rendered depth frame.
#[derive(Debug, Clone)]
pub struct Frame {
    /// Joint values (the kinematics' variables) and the link poses they give.
    pub joints: Vec<f64>,
    pub link_poses: Vec<Isometry3<f64>>,
    /// `root_from_optical`: the cloud's frame in the robot's root.
    pub root_from_sensor: Isometry3<f64>,
    /// Organized, row-major, NaN where no return; in the optical frame.
    pub points: Vec<[f32; 3]>,
    /// The depth image the points were made from (`ScenarioParams::depth`), header unset.
    pub depth_image: Option<crate::msg::Image<'static>>,
    /// Exact minimum distance between the robot's meshes and the obstacle points (`None`: no
    /// obstacle point, or not asked for).
    pub truth_m: Option<f64>,
    /// Where the truth is taken: the robot's closest mesh point and the obstacle point.
    pub truth_witness: Option<Witness>,
    pub obstacle_points: usize,
    pub robot_points: usize,
    /// What each point's ray hit (`Nothing` where the point is NaN).
    pub hits: Vec<Hit>,
}

/// The two points of a frame's exact minimum.
#[derive(Debug, Clone, Copy)]
pub struct Witness {
    /// Index of the robot link (the kinematics' order).
    pub link: usize,
    /// The closest point of its mesh, in the link's frame.
    pub robot_in_link: Point3<f64>,
    /// The obstacle point, in the root frame.
    pub obstacle_root: Point3<f64>,
}

/// The simulated camera and scene: renders frames along the scene's trajectory, drawing noise
/// from one stream in frame order (the same seed gives the same frames).
pub struct Renderer<'a> {
    model: &'a RobotModel,
    params: ScenarioParams,
    camera: usize,
    link_from_optical: Isometry3<f64>,
    solids: Vec<(usize, Vec<Solid>)>,
    fx: f64,
    cx: f64,
    cy: f64,
    noise: Noise,
}

impl<'a> Renderer<'a> {
    pub fn new(
        model: &'a RobotModel,
        params: &ScenarioParams,
        mount: &Mount,
    ) -> Result<Self, ScenarioError> {
        let k = &model.kinematics;
        let camera = k
            .link_index(&mount.link)
            .ok_or_else(|| ScenarioError::NoCameraLink(mount.link.clone()))?;
        let solids: Vec<(usize, Vec<Solid>)> = model
            .links
            .iter()
            .map(|l| {
                let index = k
                    .link_index(&l.name)
                    .ok_or_else(|| ScenarioError::NotInKinematics(l.name.clone()))?;
                Ok((
                    index,
                    l.elements.iter().map(|e| Solid::new(&e.mesh)).collect(),
                ))
            })
            .collect::<Result<_, ScenarioError>>()?;
        let w = params.width as f64;
        let fx = 0.5 * w / (0.5 * params.hfov_deg.to_radians()).tan();
        Ok(Self {
            model,
            params: params.clone(),
            camera,
            link_from_optical: mount.link_from_optical,
            solids,
            fx,
            cx: 0.5 * (w - 1.0),
            cy: 0.5 * (params.height as f64 - 1.0),
            noise: Noise(params.seed),
        })
    }

    /// The pinhole matrix K (fx = fy, principal point at the image centre).
    pub fn k(&self) -> [f64; 9] {
        let (fx, cx, cy) = (self.fx, self.cx, self.cy);
        [fx, 0.0, cx, 0.0, fx, cy, 0.0, 0.0, 1.0]
    }

    /// The camera's CameraInfo (no distortion; P = [K | 0]).
    pub fn camera_info(&self, header: Header) -> CameraInfo {
        let k = self.k();
        let (fx, cx, cy) = (k[0], k[2], k[5]);
        CameraInfo {
            header,
            height: self.params.height,
            width: self.params.width,
            distortion_model: "plumb_bob".into(),
            d: vec![0.0; 5],
            k,
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [fx, 0.0, cx, 0.0, 0.0, fx, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            ..CameraInfo::default()
        }
    }

    /// The pinhole model the monitor reads from [`Renderer::camera_info`].
    pub fn camera(&self) -> Result<PinholeCamera, ScenarioError> {
        Ok(PinholeCamera::from_camera_info(
            &self.camera_info(Header::default()),
        )?)
    }

    /// The unit ray of pixel `i` (row-major) in the optical frame.
    fn ray(&self, i: usize) -> Vector3<f64> {
        let w = self.params.width as usize;
        let (u, v) = ((i % w) as f64, (i / w) as f64);
        Vector3::new((u - self.cx) / self.fx, (v - self.cy) / self.fx, 1.0).normalize()
    }

    /// The scene's joint values at `s` ∈ [0, 1] of its trajectory.
    pub fn joints(&self, s: f64) -> Result<Vec<f64>, ScenarioError> {
        let named = joints_at(self.params.scene, s);
        Ok(self.model.kinematics.values_from_names(&named, Some(0.0))?)
    }

    /// The scene's joint velocities at `s`, for a trajectory run at `ds_dt` (1/s): the central
    /// difference of the joint values.
    pub fn joint_velocities(&self, s: f64, ds_dt: f64) -> Result<Vec<f64>, ScenarioError> {
        let (a, b) = (self.joints(s - DS)?, self.joints(s + DS)?);
        Ok(a.iter()
            .zip(&b)
            .map(|(a, b)| (b - a) / (2.0 * DS) * ds_dt)
            .collect())
    }

    /// The truth of the separation monitor for `frame`, rendered at `s`: the velocity of the
    /// robot's closest mesh point (moved with its link along the trajectory, central difference
    /// of the forward kinematics) projected on the direction to the obstacle point, m/s, and
    /// the point's speed.
    pub fn approach(
        &self,
        s: f64,
        ds_dt: f64,
        frame: &Frame,
        w: &Witness,
    ) -> Result<(f64, f64), ScenarioError> {
        let k = &self.model.kinematics;
        let at = |s: f64| -> Result<Point3<f64>, ScenarioError> {
            Ok(k.link_poses(&self.joints(s)?)[w.link] * w.robot_in_link)
        };
        let (a, b) = (at(s - DS)?, at(s + DS)?);
        let r = frame.link_poses[w.link] * w.robot_in_link;
        let v = (b - a) / (2.0 * DS) * ds_dt;
        let approach = match (w.obstacle_root - r).try_normalize(1e-9) {
            Some(n) => v.dot(&n),
            None => v.norm(),
        };
        Ok((approach, v.norm()))
    }

    /// Renders the frame at `s` ∈ [0, 1]; the exact truth only when `truth` is asked (it costs
    /// one exact distance per obstacle point).
    pub fn frame(&mut self, s: f64, truth: bool) -> Result<Frame, ScenarioError> {
        let params = &self.params;
        let (w, h) = (params.width as usize, params.height as usize);
        let q = self.joints(s)?;
        let poses = self.model.kinematics.link_poses(&q);
        let world_from_optical = poses[self.camera] * self.link_from_optical;
        let origin = world_from_optical.translation.vector.into();
        let scene = obstacles(params.scene, s);
        let solids = &self.solids;
        // One ray per pixel: (range, what it hit), in row-major order.
        let hits: Vec<Option<(f64, Hit)>> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let d = world_from_optical.rotation * self.ray(i);
                let mut best: Option<(f64, Hit)> = None;
                let mut take = |t: Option<f64>, hit: Hit| {
                    if let Some(t) = t.filter(|t| best.is_none_or(|b| *t < b.0)) {
                        best = Some((t, hit));
                    }
                };
                for (k, (shape, pose)) in scene.iter().enumerate() {
                    take(
                        ray_hit(shape.as_ref(), pose, &origin, &d, params.max_range_m),
                        Hit::Scene(k as u8),
                    );
                }
                for (link, elements) in solids {
                    let lo = poses[*link].inverse_transform_point(&origin);
                    let ld = poses[*link].inverse_transform_vector(&d);
                    for e in elements {
                        let hit = e.cast_ray(
                            [lo.x as f32, lo.y as f32, lo.z as f32],
                            [ld.x as f32, ld.y as f32, ld.z as f32],
                            params.max_range_m as f32,
                        );
                        take(hit.map(f64::from), Hit::Robot);
                    }
                }
                best
            })
            .collect();
        // Noise and holes, in pixel order from the one stream; then the points.
        let mut points = vec![[f32::NAN; 3]; w * h];
        for (i, hit) in hits.iter().enumerate() {
            let dropped = self.noise.uniform() < params.holes;
            let n = self.noise.gaussian().clamp(-2.5, 2.5) * params.noise_m;
            let Some((t, _)) = *hit else { continue };
            if dropped {
                continue;
            }
            let p = self.ray(i) * (t + n);
            points[i] = [p.x as f32, p.y as f32, p.z as f32];
        }
        // A depth camera records each pixel's depth (z); the points are then the ones
        // depth_image_proc makes from the recorded image, and so is the truth.
        let depth_image = match params.depth {
            Some(encoding) => {
                let depths: Vec<f32> = points.iter().map(|p| p[2]).collect();
                let image = encode_depth(
                    Header::default(),
                    params.width,
                    params.height,
                    &depths,
                    encoding,
                );
                points_from_depth(&image, &self.camera()?, None, &mut points)?;
                Some(image)
            }
            None => None,
        };
        let mut obstacle = Vec::new();
        let mut robot_points = 0;
        let mut labels = vec![Hit::Nothing; points.len()];
        for ((p, hit), label) in points.iter().zip(&hits).zip(&mut labels) {
            let Some((_, what)) = *hit else { continue };
            if p[0].is_nan() {
                continue;
            }
            *label = what;
            if what == Hit::Robot {
                robot_points += 1;
            } else {
                obstacle
                    .push(world_from_optical * Point3::new(p[0] as f64, p[1] as f64, p[2] as f64));
            }
        }
        // The truth: exact distance from every obstacle point to the robot's meshes, and where.
        let (truth_m, truth_witness) = if truth {
            let none = (f64::INFINITY, None);
            let (best, witness) = obstacle
                .par_iter()
                .map(|p| {
                    let mut best = none;
                    for (link, elements) in solids {
                        let lp = poses[*link].inverse_transform_point(p);
                        let lp = [lp.x as f32, lp.y as f32, lp.z as f32];
                        for e in elements {
                            let (lo, hi) = e.bounds();
                            let gap: f32 = (0..3)
                                .map(|a| (lo[a] - lp[a]).max(lp[a] - hi[a]).max(0.0).powi(2))
                                .sum::<f32>()
                                .sqrt();
                            if f64::from(gap) < best.0 {
                                let (d, q) = e.distance(lp);
                                if f64::from(d) < best.0 {
                                    let q = Point3::new(q[0] as f64, q[1] as f64, q[2] as f64);
                                    best = (
                                        f64::from(d),
                                        Some(Witness {
                                            link: *link,
                                            robot_in_link: q,
                                            obstacle_root: *p,
                                        }),
                                    );
                                }
                            }
                        }
                    }
                    best
                })
                .reduce(|| none, |a, b| if b.0 < a.0 { b } else { a });
            (best.is_finite().then_some(best), witness)
        } else {
            (None, None)
        };
        Ok(Frame {
            joints: q,
            link_poses: poses,
            root_from_sensor: world_from_optical,
            points,
            depth_image,
            truth_m,
            truth_witness,
            obstacle_points: obstacle.len(),
            robot_points,
            hits: labels,
        })
    }
}

/// Generates a bag at `out` (a rosbag2 folder, or a `.mcap` file).
pub fn generate(
    model: &RobotModel,
    params: &ScenarioParams,
    out: &Path,
) -> Result<Generated, ScenarioError> {
    let k = &model.kinematics;
    let mut renderer = Renderer::new(model, params, &Mount::fixed())?;
    let mut writer = BagWriter::create(out, params.compression)?;
    let stamp = |ns: i64| Header {
        stamp: Time::from_nanos(ns),
        frame_id: String::new(),
    };
    writer.write(
        "/tf_static",
        START_NS as u64,
        &TfMessage {
            transforms: vec![TransformStamped {
                header: Header {
                    frame_id: CAMERA_LINK.into(),
                    ..stamp(START_NS)
                },
                child_frame_id: OPTICAL_FRAME.into(),
                transform: Transform::from_isometry(&link_from_optical()),
            }],
        },
    )?;
    let duration_s = (params.frames.max(1) - 1) as f64 / CLOUD_RATE_HZ;
    let joint_samples = (duration_s * JOINT_RATE_HZ).round() as usize;
    let per_cloud = (JOINT_RATE_HZ / CLOUD_RATE_HZ).round() as usize;
    let mut result = Generated {
        frames: params.frames,
        truth_m: Vec::new(),
        separation: Vec::new(),
        obstacle_points: Vec::new(),
        robot_points: Vec::new(),
    };
    let s_at = |i: usize| {
        if joint_samples == 0 {
            0.0
        } else {
            i as f64 / joint_samples as f64
        }
    };
    let ds_dt = if duration_s > 0.0 {
        1.0 / duration_s
    } else {
        0.0
    };
    let ssm = SsmParams::default();
    for j in 0..=joint_samples {
        let t_ns = START_NS + (j as f64 * 1e9 / JOINT_RATE_HZ).round() as i64;
        writer.write(
            "/joint_states",
            (t_ns + 1_000_000) as u64,
            &JointState {
                header: stamp(t_ns),
                name: k.variables().to_vec(),
                position: renderer.joints(s_at(j))?,
                velocity: renderer.joint_velocities(s_at(j), ds_dt)?,
                ..JointState::default()
            },
        )?;
        if j % per_cloud != 0 {
            continue;
        }
        let frame = renderer.frame(s_at(j), true)?;
        let log_ns = (t_ns + 20_000_000) as u64;
        let header = Header {
            frame_id: OPTICAL_FRAME.into(),
            ..stamp(t_ns)
        };
        match &frame.depth_image {
            // The camera model first, as a depth camera driver latches it before its images.
            Some(image) => {
                let info = renderer.camera_info(header.clone());
                writer.write(CAMERA_INFO_TOPIC, log_ns, &info)?;
                let image = crate::msg::Image {
                    header,
                    ..image.clone()
                };
                writer.write(DEPTH_TOPIC, log_ns, &image)?;
            }
            None => {
                let cloud = cloud_message(&header, params, &frame.points)?;
                writer.write(CLOUD_TOPIC, log_ns, &cloud)?;
                writer.write(CAMERA_INFO_TOPIC, log_ns, &renderer.camera_info(header))?;
            }
        }
        let mut separation = None;
        if let (Some(d), Some(w)) = (frame.truth_m, frame.truth_witness) {
            writer.write(GROUND_TRUTH_TOPIC, log_ns, &Float64 { data: d })?;
            // The separation margin with the default SSM parameters, the cloud seen at once
            // (T_r = reaction_time) and the exact distance (Z_d = the sensor's uncertainty).
            let (approach, speed) = renderer.approach(s_at(j), ds_dt, &frame, &w)?;
            let margin = d - ssm.protective_distance(
                ssm.reaction_time_s,
                approach,
                speed,
                ssm.sensor_uncertainty_m,
            );
            writer.write(APPROACH_TRUTH_TOPIC, log_ns, &Float64 { data: approach })?;
            writer.write(MARGIN_TRUTH_TOPIC, log_ns, &Float64 { data: margin })?;
            separation = Some((approach, margin));
        }
        result.truth_m.push(frame.truth_m);
        result.separation.push(separation);
        result.obstacle_points.push(frame.obstacle_points);
        result.robot_points.push(frame.robot_points);
    }
    writer.finish()?;
    Ok(result)
}

/// An organized PointCloud2: x y z FLOAT32 and zero padding per point (16 bytes), or with a
/// grey `rgb` by depth at offset 16 (32 bytes, as RGB-D drivers publish).
fn cloud_message(
    header: &Header,
    params: &ScenarioParams,
    points: &[[f32; 3]],
) -> Result<PointCloud2<'static>, CloudError> {
    fn grey(p: [f32; 3]) -> [u8; 3] {
        [(255.0 - (p[2] * 60.0).clamp(0.0, 255.0)) as u8; 3]
    }
    let layout = Layout {
        width: params.width,
        height: params.height,
        datatype: PointField::FLOAT32,
        big_endian: false,
        point_step: params.point_step,
        row_padding: 0,
        rgb: (params.point_step == 32).then_some((16, grey as Colour)),
        pad: 0,
    };
    encode(header.clone(), points, &layout)
}
