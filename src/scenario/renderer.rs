//! The simulated depth camera: a pinhole model (fx = fy, principal point at the image centre)
//! mounted on a robot link, one ray per pixel cast against the robot's collision meshes and the
//! scene's shapes, range noise (Gaussian along the ray, clipped at 2.5 σ) and dropped pixels
//! from one reproducible stream, and optionally the depth image a camera would record, the
//! points then made from it as `depth_image_proc` makes them. A dark obstacle's pixels return
//! nothing (NaN), after the stream has drawn for them as for any pixel. The floor, where there is
//! one, is cast against as a shape of its own, its points no obstacle. Out: a [`Frame`],
//! points in the optical frame (m), each labelled with what its ray hit; its truth from
//! `truth` (with the hidden obstacle's whole shape where the scene hides it).

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

use super::dropouts::{CameraDropouts, Pixel};
use super::error::ScenarioError;
use super::noise::Noise;
use parry3d::shape::TriMesh;

use super::params::{ScenarioParams, CAMERA_LINK, DROPOUT_SEED_MIX, DS, SIDE_CAMERA_POSE};
use super::scene::{floor, joints_at, obstacles, person_top_m, ray_hit};
use super::truth::{exact_truth, robot_meshes, shape_truth, Witness};
use crate::cloud::depth::{encode_depth, points_from_depth, PinholeCamera};
use crate::msg::{CameraInfo, Header};
use crate::packing::Solid;
use crate::robot::RobotModel;

/// What a pixel's ray hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Hit {
    /// No return, or a dropped pixel.
    Nothing,
    Robot,
    /// A shape of the scene: 0 the back wall, 1 the obstacle (person, forearm or box), 2 the
    /// table; the side wall (`ScenarioParams::second_camera`) last.
    Scene(u8),
    /// The floor (`ScenarioParams::floor`): not an obstacle, left out of the truth as the
    /// robot's own points are.
    Floor,
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

    /// The second camera (`ScenarioParams::second_camera`): its optical frame in the robot's
    /// root link `root`, [`SIDE_CAMERA_POSE`] then [`link_from_optical`].
    pub fn side(root: &str) -> Self {
        Self {
            link: root.into(),
            link_from_optical: root_from_side_link() * link_from_optical(),
        }
    }
}

/// `root_from_side_camera_link`: [`SIDE_CAMERA_POSE`] (rpy as a URDF origin's).
pub fn root_from_side_link() -> Isometry3<f64> {
    let ([x, y, z], [roll, pitch, yaw]) = SIDE_CAMERA_POSE;
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
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
    /// Valid points on the floor (`ScenarioParams::floor`), left out of the truth.
    pub floor_points: usize,
    /// What each point's ray hit (`Nothing` where the point is NaN).
    pub hits: Vec<Hit>,
}

/// The simulated camera and scene: renders frames along the scene's trajectory, drawing noise
/// from one stream in frame order (the same seed gives the same frames).
pub struct Renderer<'a> {
    model: &'a RobotModel,
    params: ScenarioParams,
    camera: usize,
    link_from_optical: Isometry3<f64>,
    solids: Vec<(usize, Vec<Solid>)>,
    /// The meshes the hidden obstacle's truth is taken to (`ScenarioParams::hides_obstacle`).
    meshes: Option<Vec<(usize, Vec<TriMesh>)>>,
    fx: f64,
    cx: f64,
    cy: f64,
    noise: Noise,
    /// The camera-like dropouts, on a stream of their own (`dropouts`).
    dropouts: CameraDropouts,
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
        let meshes = match params.hides_obstacle() {
            true => Some(
                robot_meshes(model, &solids)
                    .ok_or_else(|| ScenarioError::HiddenTruth("a mesh parry3d refuses".into()))?,
            ),
            false => None,
        };
        Ok(Self {
            model,
            params: params.clone(),
            camera,
            link_from_optical: mount.link_from_optical,
            solids,
            meshes,
            fx,
            cx: 0.5 * (w - 1.0),
            cy: 0.5 * (params.height as f64 - 1.0),
            noise: Noise(params.seed),
            dropouts: CameraDropouts::new(params.camera_dropouts, params.seed ^ DROPOUT_SEED_MIX),
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
        let q = self.joints(s)?;
        let poses = self.model.kinematics.link_poses(&q);
        let world_from_optical = poses[self.camera] * self.link_from_optical;
        let hits = self.cast(s, &poses, &world_from_optical);
        let mut points = self.noisy_points(&hits);
        if self.params.dark {
            for (p, hit) in points.iter_mut().zip(&hits) {
                if matches!(hit, Some((_, Hit::Scene(1)))) {
                    *p = [f32::NAN; 3];
                }
            }
        }
        if self.params.camera_dropouts > 0.0 {
            let pixels: Vec<Pixel> = (hits.iter().enumerate())
                .map(|(i, &hit)| Pixel {
                    range_m: hit.map(|(t, _)| t),
                    person_height_m: match hit {
                        Some((t, Hit::Scene(1))) => {
                            Some((world_from_optical * Point3::from(self.ray(i) * t)).z)
                        }
                        _ => None,
                    },
                })
                .collect();
            let person = person_top_m(self.params.scene);
            let (w, h) = (self.params.width as usize, self.params.height as usize);
            self.dropouts.apply(&pixels, w, h, person, &mut points);
        }
        let depth_image = self.depth_image(&mut points)?;
        let mut obstacle = Vec::new();
        let (mut robot_points, mut floor_points) = (0, 0);
        let mut labels = vec![Hit::Nothing; points.len()];
        for ((p, hit), label) in points.iter().zip(&hits).zip(&mut labels) {
            let Some((_, what)) = *hit else { continue };
            if p[0].is_nan() {
                continue;
            }
            *label = what;
            match what {
                Hit::Robot => robot_points += 1,
                Hit::Floor => floor_points += 1,
                Hit::Nothing | Hit::Scene(_) => obstacle
                    .push(world_from_optical * Point3::new(p[0] as f64, p[1] as f64, p[2] as f64)),
            }
        }
        let (truth_m, truth_witness) = match truth {
            true => self.truth(s, &obstacle, &poses)?,
            false => (None, None),
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
            floor_points,
            hits: labels,
        })
    }

    /// The exact truth of a frame at `s`: to the obstacle points, and where the scene hides its
    /// obstacle, to its whole shape (the nearer of the two, with its witness).
    fn truth(
        &self,
        s: f64,
        obstacle: &[Point3<f64>],
        poses: &[Isometry3<f64>],
    ) -> Result<(Option<f64>, Option<Witness>), ScenarioError> {
        let (mut d, mut w) = exact_truth(obstacle, &self.solids, poses);
        if let Some(meshes) = &self.meshes {
            let scene = obstacles(self.params.scene, s, self.params.second_camera);
            let (shape, pose) = &scene[1];
            let (hidden, witness) = shape_truth(shape.as_ref(), pose, meshes, poses)
                .ok_or_else(|| ScenarioError::HiddenTruth("a shape parry3d cannot query".into()))?;
            if d.is_none_or(|d| hidden < d) {
                (d, w) = (Some(hidden), Some(witness));
            }
        }
        Ok((d, w))
    }

    /// One ray per pixel at `s`: (range, what it hit), in row-major order.
    fn cast(
        &self,
        s: f64,
        poses: &[Isometry3<f64>],
        world_from_optical: &Isometry3<f64>,
    ) -> Vec<Option<(f64, Hit)>> {
        let params = &self.params;
        let (w, h) = (params.width as usize, params.height as usize);
        let origin = world_from_optical.translation.vector.into();
        let scene = obstacles(params.scene, s, params.second_camera);
        let floor = params.floor.then(floor);
        let solids = &self.solids;
        (0..w * h)
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
                if let Some((shape, pose)) = &floor {
                    take(
                        ray_hit(shape.as_ref(), pose, &origin, &d, params.max_range_m),
                        Hit::Floor,
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
            .collect()
    }

    /// Noise and holes, in pixel order from the one stream; then the points (NaN: no return).
    fn noisy_points(&mut self, hits: &[Option<(f64, Hit)>]) -> Vec<[f32; 3]> {
        let (w, h) = (self.params.width as usize, self.params.height as usize);
        let (holes, noise_m) = (self.params.holes, self.params.noise_m);
        let mut points = vec![[f32::NAN; 3]; w * h];
        for (i, hit) in hits.iter().enumerate() {
            let dropped = self.noise.uniform() < holes;
            let n = self.noise.gaussian().clamp(-2.5, 2.5) * noise_m;
            let Some((t, _)) = *hit else { continue };
            if dropped {
                continue;
            }
            let p = self.ray(i) * (t + n);
            points[i] = [p.x as f32, p.y as f32, p.z as f32];
        }
        points
    }

    /// A depth camera records each pixel's depth (z); the points are then the ones
    /// depth_image_proc makes from the recorded image, and so is the truth.
    fn depth_image(
        &self,
        points: &mut Vec<[f32; 3]>,
    ) -> Result<Option<crate::msg::Image<'static>>, ScenarioError> {
        let params = &self.params;
        Ok(match params.depth {
            Some(encoding) => {
                let depths: Vec<f32> = points.iter().map(|p| p[2]).collect();
                let image = encode_depth(
                    Header::default(),
                    params.width,
                    params.height,
                    &depths,
                    encoding,
                );
                points_from_depth(&image, &self.camera()?, None, points)?;
                Some(image)
            }
            None => None,
        })
    }
}
