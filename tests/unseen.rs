//! Unseen space end to end on synthetic depth images: the unseen distance never exceeds the
//! distance from the robot to a hidden (dark) ball of the detection capability, over random
//! camera poses and dropout masks; isolated dropped pixels alone leave nothing after the
//! opening; and the Kinect-sized scene (a 2 × 2 × 2 m volume at 2 cm, one 640 × 480 view) runs.
//!
//! The robot is an axis-aligned box; the renderer casts each pixel's centre ray against the
//! robot (returns, flagged as the robot), the hidden ball (no return: dark) and a background
//! plane facing the camera behind the volume, then drops pixels at random.

mod common;

use std::time::Instant;

use common::Rng;
use ist_monitor::cloud::depth::PinholeCamera;
use ist_monitor::unseen::{
    observe, open, open_exact, unseen_distance, Lattice, RangeView, DEFAULT_DETECTION_CAPABILITY_M,
    DEFAULT_RANGE_NOISE_M, DEFAULT_RESOLUTION_M,
};
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;

/// The scene generator's own draws, beside the shared `Rng`.
impl Rng {
    fn unit(&mut self) -> Vector3<f64> {
        loop {
            let v = Vector3::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }
}

/// The robot: an axis-aligned box in the root frame.
struct Robot {
    centre: Vector3<f64>,
    half: Vector3<f64>,
}

impl Robot {
    fn distance(&self, p: &Vector3<f64>) -> f64 {
        let q = (p - self.centre).abs() - self.half;
        q.sup(&Vector3::zeros()).norm()
    }

    /// The brute-force distance from root-frame points to the box: the test's "query".
    fn lower_bound(&self, points: &[[f32; 3]]) -> f64 {
        points
            .iter()
            .map(|p| self.distance(&Vector3::new(p[0], p[1], p[2]).cast()))
            .fold(f64::INFINITY, f64::min)
    }

    /// The ray parameter of the first hit of `o + t·d` (t > 0), if any.
    fn hit(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
        let (mut near, mut far) = (f64::NEG_INFINITY, f64::INFINITY);
        for a in 0..3 {
            let (lo, hi) = (self.centre[a] - self.half[a], self.centre[a] + self.half[a]);
            if d[a] == 0.0 {
                if o[a] < lo || o[a] > hi {
                    return None;
                }
                continue;
            }
            let (t1, t2) = ((lo - o[a]) / d[a], (hi - o[a]) / d[a]);
            near = near.max(t1.min(t2));
            far = far.min(t1.max(t2));
        }
        (far >= near && near > 0.0).then_some(near)
    }
}

/// A dark ball.
struct Ball {
    centre: Vector3<f64>,
    radius: f64,
}

impl Ball {
    fn hit(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<f64> {
        let oc = o - self.centre;
        let (a, b, c) = (
            d.dot(d),
            2.0 * d.dot(&oc),
            oc.dot(&oc) - self.radius.powi(2),
        );
        let disc = b * b - 4.0 * a * c;
        (disc >= 0.0)
            .then(|| (-b - disc.sqrt()) / (2.0 * a))
            .filter(|&t| t > 0.0)
    }
}

/// What the camera saw: depths along z (NaN: no return), robot flags, and whether the robot
/// stands in front of the ball within a pixel of the ball's image (the cells there may count
/// as the robot's shadow).
struct Render {
    depths: Vec<f32>,
    robot: Vec<bool>,
    robot_hides_ball: bool,
}

fn render(
    camera: &PinholeCamera,
    root_from_camera: &Isometry3<f64>,
    background_z: f64,
    robot: Option<&Robot>,
    ball: Option<&Ball>,
    dropout: f64,
    rng: &mut Rng,
) -> Render {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let o = root_from_camera.translation.vector;
    let mut out = Render {
        depths: vec![f32::NAN; w * h],
        robot: vec![false; w * h],
        robot_hides_ball: false,
    };
    let mut robot_t = vec![None; w * h];
    let mut ball_t = vec![None; w * h];
    for i in 0..w * h {
        let (u, v) = ((i % w) as f64, (i / w) as f64);
        // z = t for o + t·d with d's camera-frame z equal to 1.
        let d_cam = Vector3::new(
            (u - camera.cx) / camera.fx,
            (v - camera.cy) / camera.fy,
            1.0,
        );
        let d = root_from_camera.rotation * d_cam;
        let t_robot = robot.and_then(|r| r.hit(&o, &d));
        let t_ball = ball.and_then(|b| b.hit(&o, &d));
        ball_t[i] = t_ball;
        let mut t = background_z;
        if let Some(b) = t_ball.filter(|&b| b < t) {
            t = b;
        }
        if let Some(r) = t_robot.filter(|&r| r < t) {
            out.depths[i] = r as f32;
            out.robot[i] = true;
            robot_t[i] = Some(r);
        } else if t_ball.is_some_and(|b| b <= t) {
            // Dark: no return.
        } else {
            out.depths[i] = t as f32;
        }
        if rng.next() < dropout {
            out.depths[i] = f32::NAN;
            out.robot[i] = false;
        }
    }
    out.robot_hides_ball = (0..w * h).any(|i| {
        let Some(r) = robot_t[i] else { return false };
        let (u, v) = ((i % w) as i64, (i / w) as i64);
        (-1..=1).any(|dv| {
            (-1..=1).any(|du| {
                let (x, y) = (u + du, v + dv);
                let inside = x >= 0 && y >= 0 && x < w as i64 && y < h as i64;
                inside && ball_t[y as usize * w + x as usize].is_some_and(|b| b > r)
            })
        })
    });
    out
}

/// A camera `distance` from `target` along `direction`, looking at it, rolled by `roll`.
fn looking_at(
    target: Vector3<f64>,
    direction: Vector3<f64>,
    distance: f64,
    roll: f64,
) -> Isometry3<f64> {
    let eye = target + direction * distance;
    let forward = -direction;
    let up = if forward.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let rotation = UnitQuaternion::face_towards(&forward, &up)
        * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), roll);
    Isometry3::from_parts(Translation3::from(eye), rotation)
}

fn kinect() -> PinholeCamera {
    PinholeCamera {
        width: 640,
        height: 480,
        fx: 525.0,
        fy: 525.0,
        cx: 319.5,
        cy: 239.5,
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// The unseen distance never exceeds the distance from the robot to a hidden ball of the
    /// detection capability, wherever the camera stands and whichever pixels drop; where the
    /// robot does not hide the ball, neither does the distance to the unseen cells outside the
    /// robot's shadow.
    #[test]
    fn unseen_distance_never_exceeds_the_hidden_balls(
        seed in any::<u64>(),
        capability in 0.06f64..0.12,
        cells_per_capability in 3.4f64..5.0,
        dropout in 0.0f64..0.05,
    ) {
        let mut rng = Rng(seed | 1);
        let resolution = capability / cells_per_capability;
        let volume_centre = Vector3::new(0.0, 0.0, 0.5);
        let lattice = Lattice::new(Isometry3::translation(0.0, 0.0, 0.5), [0.5; 3], resolution)
            .unwrap();
        let robot = Robot { centre: Vector3::new(0.0, 0.0, 0.3), half: Vector3::new(0.08, 0.08, 0.3) };
        let padding = 0.01;
        let radius = capability / 2.0;
        let ball = loop {
            let c = volume_centre
                + Vector3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0))
                    * (0.5 - radius - 0.02);
            if robot.distance(&c) >= radius + padding + 0.01 {
                break Ball { centre: c, radius };
            }
        };
        let camera = PinholeCamera {
            width: 320,
            height: 240,
            fx: rng.range(250.0, 300.0),
            fy: rng.range(250.0, 300.0),
            cx: rng.range(150.0, 170.0),
            cy: rng.range(110.0, 130.0),
        };
        let distance = rng.range(1.8, 3.0);
        let aim = volume_centre + rng.unit() * rng.range(0.0, 0.15);
        let pose = looking_at(aim, rng.unit(), distance, rng.range(-3.2, 3.2));
        let image = render(&camera, &pose, distance + 1.2, Some(&robot), Some(&ball), dropout, &mut rng);
        let mut view = RangeView::new(camera, pose, &image.depths, None, DEFAULT_RANGE_NOISE_M).unwrap();
        view.set_robot_pixels(&image.robot).unwrap();

        let mut observation = observe(&lattice, &[&view]);
        // The robot's padded volume is the caller's (its self-filter).
        observation.drop_where(&lattice, |_, c| {
            robot.distance(&Vector3::new(c[0], c[1], c[2]).cast()) <= padding
        });
        let opened = open(&lattice, &observation.unseen, observation.pixel_pitch_m, capability).unwrap();
        prop_assert!(opened.count > 0, "the hidden ball left no opened cell");
        let truth = (robot.distance(&ball.centre) - radius).max(0.0);
        let unseen = unseen_distance(&lattice, &opened, None, |c| robot.lower_bound(c)).unwrap();
        prop_assert!(unseen <= truth, "unseen distance {unseen} > true distance {truth}");
        // The sharp form: the opened cells inside the ball alone already keep the bound (the
        // ball survived the opening, and a cell diagonal covers its centre sampling).
        let in_ball: Vec<bool> = (0..lattice.len())
            .map(|i| {
                let c = lattice.centre(i);
                (Vector3::new(c[0], c[1], c[2]).cast::<f64>() - ball.centre).norm() <= radius
            })
            .collect();
        let d = unseen_distance(&lattice, &opened, Some(&in_ball), |c| robot.lower_bound(c));
        prop_assert!(d.is_some(), "the hidden ball did not survive the opening");
        let d = d.unwrap_or(f64::NAN);
        prop_assert!(d <= truth, "unseen distance inside the ball {d} > true distance {truth}");
        if !image.robot_hides_ball {
            // The unseen space beyond the robot's shadow, opened on its own.
            let beyond = open(&lattice, &observation.beyond_self_shadow(), observation.pixel_pitch_m, capability).unwrap();
            let d = unseen_distance(&lattice, &beyond, None, |c| robot.lower_bound(c)).unwrap();
            prop_assert!(d <= truth, "unseen distance outside the shadow {d} > true distance {truth}");
        }
    }
}

/// Isolated dropped pixels (2 %, the generator's rate), no hidden body: every unseen cell they
/// leave in front of the background vanishes in the opening at the defaults.
#[test]
fn isolated_dropouts_leave_nothing_at_the_default_capability() {
    let lattice = Lattice::new(Isometry3::identity(), [0.5; 3], DEFAULT_RESOLUTION_M).unwrap();
    let mut rng = Rng(0x5eed);
    for k in 0..3 {
        // The camera 3 m away, the whole volume in view, the background 1 m behind it.
        let pose = looking_at(Vector3::zeros(), rng.unit(), 3.0, rng.range(-3.2, 3.2));
        let image = render(&kinect(), &pose, 4.0, None, None, 0.02, &mut rng);
        let view =
            RangeView::new(kinect(), pose, &image.depths, None, DEFAULT_RANGE_NOISE_M).unwrap();
        let observation = observe(&lattice, &[&view]);
        let unseen = observation.unseen_count();
        assert!(unseen > 0, "pose {k}: the dropouts hid no cell");
        let opened = open(
            &lattice,
            &observation.unseen,
            observation.pixel_pitch_m,
            DEFAULT_DETECTION_CAPABILITY_M,
        )
        .unwrap();
        println!(
            "pose {k}: {unseen} unseen cells of {} ({:.2} % observed), {} after the opening \
             (erosion radius {:.4} m, margin {:.4} m)",
            lattice.len(),
            100.0 * observation.observed_fraction,
            opened.count,
            opened.erosion_radius_m,
            opened.margin_m
        );
        assert_eq!(opened.count, 0, "pose {k}");
    }
}

/// The Kinect scene: a 2 × 2 × 2 m volume at 2 cm (10⁶ cells) and one 640 × 480 view with the
/// robot, a dark person-sized ball and 2 % dropouts. Prints the time of each step (not
/// asserted: a debug build on a shared machine).
#[test]
fn kinect_scene_runs() {
    let lattice = Lattice::new(
        Isometry3::translation(0.0, 0.0, 1.0),
        [1.0; 3],
        DEFAULT_RESOLUTION_M,
    )
    .unwrap();
    let robot = Robot {
        centre: Vector3::new(0.0, 0.0, 0.4),
        half: Vector3::new(0.1, 0.1, 0.4),
    };
    let ball = Ball {
        centre: Vector3::new(0.6, 0.3, 0.9),
        radius: 0.15,
    };
    let mut rng = Rng(7);
    let pose = looking_at(
        Vector3::new(0.0, 0.0, 1.0),
        Vector3::new(-0.6, -0.5, 0.62).normalize(),
        2.5,
        0.3,
    );
    let image = render(
        &kinect(),
        &pose,
        4.5,
        Some(&robot),
        Some(&ball),
        0.02,
        &mut rng,
    );
    let mut view =
        RangeView::new(kinect(), pose, &image.depths, None, DEFAULT_RANGE_NOISE_M).unwrap();
    view.set_robot_pixels(&image.robot).unwrap();
    let t0 = Instant::now();
    let mut observation = observe(&lattice, &[&view]);
    let t1 = Instant::now();
    observation.drop_where(&lattice, |_, c| {
        robot.distance(&Vector3::new(c[0], c[1], c[2]).cast()) <= 0.01
    });
    let t2 = Instant::now();
    let opened = open(
        &lattice,
        &observation.unseen,
        observation.pixel_pitch_m,
        DEFAULT_DETECTION_CAPABILITY_M,
    )
    .unwrap();
    let t3 = Instant::now();
    let unseen = unseen_distance(&lattice, &opened, None, |c| robot.lower_bound(c));
    let t4 = Instant::now();
    let beyond = open(
        &lattice,
        &observation.beyond_self_shadow(),
        observation.pixel_pitch_m,
        DEFAULT_DETECTION_CAPABILITY_M,
    )
    .unwrap();
    let beyond_shadow = unseen_distance(&lattice, &beyond, None, |c| robot.lower_bound(c));
    let t5 = Instant::now();
    // The former opening (two exact distance transforms, the ball itself), for the cost it cut.
    let t6 = Instant::now();
    let exact = open_exact(
        &lattice,
        &observation.unseen,
        observation.pixel_pitch_m,
        DEFAULT_DETECTION_CAPABILITY_M,
    )
    .unwrap();
    let t7 = Instant::now();
    assert!(exact
        .cells
        .iter()
        .zip(&opened.cells)
        .all(|(&e, &f)| !e || f));
    let ms = |a: Instant, b: Instant| (b - a).as_secs_f64() * 1e3;
    let truth = robot.distance(&ball.centre) - ball.radius;
    println!(
        "{} cells, {:.1} % observed, {} unseen, {} opened ({} by the exact ball dilation); \
         unseen distance {unseen:?}, outside the robot's shadow {beyond_shadow:?}, hidden ball \
         at {truth:.3} m",
        lattice.len(),
        100.0 * observation.observed_fraction,
        observation.unseen_count(),
        opened.count,
        exact.count
    );
    println!(
        "observe {:.1} ms, drop the robot {:.1} ms, open {:.1} ms, distance (brute force) {:.1} ms, \
         open and measure beyond the shadow {:.1} ms; the exact opening {:.1} ms",
        ms(t0, t1),
        ms(t1, t2),
        ms(t2, t3),
        ms(t3, t4),
        ms(t4, t5),
        ms(t6, t7)
    );
    assert!(beyond_shadow.is_some_and(|d| d <= truth));
}
