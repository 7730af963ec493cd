//! Speed and separation monitoring through the monitor (what `replay` and the node run):
//! analytic cases on a one-joint arm, the faults that must give factor 0, the factor against
//! the formula for every distance of the certified interval (property test), and the generated
//! approach scene against its recorded truth.

mod common;

use ist_monitor::cloud::pointcloud2;
use ist_monitor::config::Config;
use ist_monitor::monitor::replay::{self, Clock, ReplayFrame};
use ist_monitor::monitor::{Frame, Monitor};
use ist_monitor::msg::{Header, JointState, Time};
use ist_monitor::scenario::{self, ScenarioParams, SceneKind};
use ist_monitor::separation::{LinkConstraint, SsmParams, StoppingTable};
use proptest::prelude::*;

const STAMP: i64 = 1_700_000_000_000_000_000;
const MS: i64 = 1_000_000;

/// One revolute joint `j` about the root's z axis, carrying a ball of radius 0.1 m whose
/// centre is 0.5 m out along x; a sensor `cam` at the root. Constant stopping time and
/// distance, so S_p is linear in the factor; the joint velocities are taken as nominal.
fn one_joint_arm(extra: &[(&str, &str)]) -> Monitor {
    let urdf = r#"<robot name="swing"><link name="world"/>
        <link name="arm"><collision><origin xyz="0.5 0 0"/><geometry><sphere radius="0.1"/></geometry></collision></link>
        <joint name="j" type="revolute"><parent link="world"/><child link="arm"/><axis xyz="0 0 1"/>
          <limit lower="-3" upper="3" effort="1" velocity="3"/></joint></robot>"#;
    let mut overrides: Vec<(String, String)> = [
        ("static_transforms", "[cam]"),
        ("cam.parent_frame", "world"),
        ("cam.child_frame", "cam"),
        ("backend", "cpu"),
        ("per_link_range", ".inf"),
        ("speed_scaling.stopping.speeds", "[0.0]"),
        ("speed_scaling.stopping.times", "[0.2]"),
        ("speed_scaling.stopping.distances", "[0.05]"),
        ("speed_scaling.velocities_scaled", "false"),
        ("speed_scaling.max_increase_rate", "1000"),
    ]
    .iter()
    .chain(extra)
    .map(|(a, b)| (a.to_string(), b.to_string()))
    .collect();
    overrides.push(("robot_description".into(), urdf.into()));
    let config = Config::from_overrides(&overrides).unwrap();
    let model = Monitor::model_from_text(&config, urdf, "swing.urdf").unwrap();
    Monitor::with_model(config, model, &|_| {}).unwrap()
}

fn joint_state(m: &mut Monitor, t_ns: i64, position: f64, velocity: Option<f64>) {
    let js = JointState {
        header: Header {
            stamp: Time::from_nanos(t_ns),
            frame_id: String::new(),
        },
        name: vec!["j".into()],
        position: vec![position],
        velocity: velocity.into_iter().collect(),
        ..JointState::default()
    };
    m.on_joint_state("/joint_states", &js).unwrap();
}

fn cloud(m: &mut Monitor, stamp_ns: i64, now_ns: i64, points: &[[f32; 3]]) -> Frame {
    let header = Header {
        stamp: Time::from_nanos(stamp_ns),
        frame_id: "cam".into(),
    };
    let layout = pointcloud2::Layout::unorganized(points.len() as u32);
    let c = pointcloud2::encode(header, points, &layout).unwrap();
    m.on_cloud(0, &c, std::time::Instant::now(), Some(now_ns))
}

/// The factor of a frame, checked against the published message.
fn factor(f: &Frame) -> f64 {
    let k = f.speed.as_ref().expect("speed scaling on").factor;
    assert_eq!(f.outputs.speed_scaling.map(|m| m.factor), Some(k));
    k
}

/// A point straight beside the ball (+y of its centre) while the joint turns at ω: the ball's
/// closest point (0.5, r, 0) moves at ω × p = ω (−r, 0.5, 0), so it approaches the point at
/// v_r = 0.5 ω (ω > 0), moves away at ω < 0, and a point on +x (radial) sees tangential motion,
/// v_r = 0. With constant stopping terms S_p(k) = v_h (T_r + T_s) + k v_r T_r + S_s + C + Z_d +
/// Z_r, so the factor is where that line meets the distance.
#[test]
fn analytic_approach_away_tangential_and_boundary() {
    let p = SsmParams {
        stopping: StoppingTable::constant(0.2, 0.05),
        ..SsmParams::default()
    };
    for (omega, obstacle, expect_vr) in [
        (2.0, [0.5f32, 0.72, 0.0], 1.0),
        (-2.0, [0.5, 0.72, 0.0], -1.0),
        (2.0, [1.22, 0.0, 0.0], 0.0),
    ] {
        let mut m = one_joint_arm(&[]);
        for t in [-1010, -990, -10, 10] {
            joint_state(&mut m, STAMP + t * MS, omega * t as f64 * 1e-3, Some(omega));
        }
        // Two frames 1 s apart with a fast rate: the second is the allowed factor itself.
        cloud(&mut m, STAMP - 1000 * MS, STAMP - 1000 * MS, &[obstacle]);
        let f = cloud(&mut m, STAMP, STAMP, &[obstacle]);
        let s = f
            .speed
            .as_ref()
            .unwrap()
            .separation
            .as_ref()
            .unwrap()
            .clone();
        let r = f.result.as_ref().unwrap();
        let link = &r.links[0];
        assert!(
            (s.approach_mps - expect_vr).abs() < 1e-4,
            "ω {omega} at {obstacle:?}: v_r {} (expected {expect_vr})",
            s.approach_mps
        );
        assert_eq!(s.nearest_approach_mps, Some(s.approach_mps));
        // The analytic factor from the distance and reaction time the monitor used.
        let d = link.distance_m.unwrap();
        let h = link.distance_m.unwrap() - link.lower_m.unwrap();
        let z_d = p.sensor_uncertainty_m + h;
        let t_r = s.reaction_s;
        let a = p.human_speed_mps * (t_r + 0.2) + 0.05 + z_d + p.robot_uncertainty_m;
        let expected = if a > d {
            0.0
        } else if expect_vr <= 0.0 {
            1.0
        } else {
            ((d - a) / (expect_vr * t_r)).min(1.0)
        };
        assert!(
            (s.allowed - expected).abs() < 1e-3,
            "ω {omega}: factor {} (expected {expected})",
            s.allowed
        );
        assert!(
            expect_vr <= 0.0 || (0.05..0.95).contains(&s.allowed),
            "the approaching case should be a partial factor, got {}",
            s.allowed
        );
        assert_eq!(factor(&f), s.allowed);
        // Margin at the motion as measured (k = 1): d − S_p(1).
        let sp = a + s.approach_mps * t_r;
        assert!((s.margin_m - (d - sp)).abs() < 1e-6);
        let ttc = (d - z_d) / (p.human_speed_mps + s.approach_mps);
        assert!((s.time_to_collision_s - ttc).abs() < 1e-6);
    }
}

/// Every fault gives 0 at once — a stale cloud, stale joint states, joint states without
/// velocities and with only one position, a cloud that only the robot is in — and the factor
/// then rises again only at the configured rate.
#[test]
fn faults_give_zero_and_recovery_is_rate_limited() {
    let mut m = one_joint_arm(&[("speed_scaling.max_increase_rate", "0.5")]);
    let far = [[3.0f32, 0.0, 0.0]];
    let newest = STAMP + 3000 * MS;
    for i in -10..=150 {
        joint_state(&mut m, STAMP + i * 20 * MS, 0.0, Some(0.0));
    }
    // Ramping up from 0 by 0.5/s: 0.1 s → 0.05.
    assert_eq!(factor(&cloud(&mut m, STAMP, STAMP, &far)), 0.0);
    let k = factor(&cloud(&mut m, STAMP + 100 * MS, STAMP + 100 * MS, &far));
    assert!((k - 0.05).abs() < 1e-9, "{k}");
    let mut t = STAMP + 100 * MS;
    while factor(&cloud(&mut m, t, t, &far)) < 1.0 {
        t += 100 * MS;
        assert!(t < STAMP + 2500 * MS, "never reached 1");
    }
    // A stale cloud (older than source_timeout by the clock): 0.
    let f = cloud(&mut m, t, t + 900 * MS, &far);
    assert!(f.result.is_err());
    assert_eq!(factor(&f), 0.0);
    assert!(f.outputs.diagnostics.status[0]
        .values
        .iter()
        .any(|kv| kv.key == "ssm_fault" && kv.value.contains("stale cloud")));
    // Back up by one step only.
    let k = factor(&cloud(&mut m, t + 100 * MS, t + 100 * MS, &far));
    assert!((k - 0.05).abs() < 1e-9, "{k}");
    // Stale joint states (the newest is 0.3 s old): a fault of the frame, 0.
    let f = cloud(&mut m, newest + 300 * MS, newest + 300 * MS, &far);
    assert!(f.result.is_err());
    assert_eq!(factor(&f), 0.0);

    // Joint states without velocities: differentiated from two positions, said so; with one
    // position only, no velocity: the distance stands, the factor is 0 with the reason.
    let mut m = one_joint_arm(&[]);
    joint_state(&mut m, STAMP - 20 * MS, 0.0, None);
    let f = cloud(&mut m, STAMP, STAMP, &far);
    assert!(
        f.outputs.min_distance.is_some(),
        "the distance still stands"
    );
    assert_eq!(factor(&f), 0.0);
    let reason = f.speed.as_ref().unwrap().separation.as_ref().unwrap_err();
    assert!(
        reason.contains("joint j") && reason.contains("no velocity"),
        "{reason}"
    );
    joint_state(&mut m, STAMP, 0.01, None);
    let f = cloud(&mut m, STAMP + 10 * MS, STAMP + 10 * MS, &far);
    let s = f.speed.as_ref().unwrap().separation.as_ref().unwrap();
    assert_eq!(s.velocity_source.name(), "differentiated");

    // Only the robot in view (every point self-filtered): no distance, 0.
    let f = cloud(&mut m, STAMP + 20 * MS, STAMP + 20 * MS, &[[0.5, 0.0, 0.0]]);
    assert!(f.outputs.min_distance.is_none());
    assert_eq!(factor(&f), 0.0);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// For a link whose true distance lies anywhere in its certified interval [d − h, d], the
    /// protective separation distance at every factor up to the one allowed (sampled, and the
    /// factor itself) stays within the true distance; and the factor is the largest: just
    /// above it (when below 1), S_p exceeds the distance the rule is held against.
    #[test]
    fn the_factor_never_exceeds_what_the_formula_allows(
        d in 0.0f64..1.5,
        h in 0.0f64..0.02,
        approach in -2.0f64..2.0,
        extra_speed in 0.0f64..1.0,
        reaction in 0.0f64..0.3,
        table in proptest::collection::vec((0.05f64..0.6, 0.0f64..0.3, 0.0f64..0.2), 0..4),
        t0 in 0.0f64..0.2,
        s0 in 0.0f64..0.05,
        w in 0.0f64..1.0,
    ) {
        // A non-decreasing table from 0.
        let (mut speeds, mut times, mut distances) = (vec![0.0], vec![t0], vec![s0]);
        for (dv, dt, ds) in table {
            speeds.push(speeds.last().unwrap() + dv);
            times.push(times.last().unwrap() + dt);
            distances.push(distances.last().unwrap() + ds);
        }
        let p = SsmParams {
            stopping: StoppingTable { speeds_mps: speeds, times_s: times, distances_m: distances },
            ..SsmParams::default()
        };
        p.stopping.validate().unwrap();
        let speed = approach.abs() + extra_speed;
        let c = LinkConstraint {
            link: "l".into(),
            distance_m: d,
            z_d_m: p.sensor_uncertainty_m + h,
            approach_mps: approach,
            speed_mps: speed,
            witnessed: true,
            nearest: true,
            unseen: false,
        };
        let k = p.allowed_factor(&c, reaction);
        prop_assert!((0.0..=1.0).contains(&k));
        let truth = d - w * h;
        let sp_true = |k: f64| p.protective_distance(
            reaction, k * approach, k * speed, p.sensor_uncertainty_m);
        if k > 0.0 {
            for i in 0..=50 {
                let kk = k * f64::from(i) / 50.0;
                prop_assert!(sp_true(kk) <= truth + 1e-12,
                    "k {k}: S_p({kk}) = {} > true distance {truth}", sp_true(kk));
            }
        }
        if k < 1.0 {
            let above = (k + 1e-6).min(1.0);
            let sp = p.protective_distance(reaction, above * approach, above * speed, c.z_d_m);
            prop_assert!(sp > d - 1e-9, "k {k} is not the largest: S_p({above}) = {sp} ≤ {d}");
        }
    }
}

fn replay_rows(bag: &std::path::Path, overrides: &[(&str, &str)]) -> Vec<ReplayFrame> {
    // The generator's floorless scene: what the camera sees alone.
    let o: Vec<(String, String)> = (common::SEEN_ONLY_FLOORLESS.iter().chain(overrides))
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
    let config = Config::load(std::path::Path::new(common::DEMO_CONFIG), &o).unwrap();
    let (model, trees) = common::demo_trees();
    let mut monitor = Monitor::with_trees(config, model, &trees).unwrap();
    let mut rows = Vec::new();
    replay::replay(&mut monitor, bag, None, Clock::Log, &mut |f| {
        rows.push(f.clone())
    })
    .unwrap();
    rows
}

/// The generated approach: the person walks up to the swinging arm and back. The factor
/// reaches 0 while the true distance is still above the stop distance, is 0 whenever the true
/// distance is within it, and comes back to 1 once the person has left; the approach speed at
/// the nearest link's closest point equals the recorded truth (the inner-sphere point against
/// the mesh point, within 1 cm/s).
#[test]
fn the_generated_approach_stops_before_the_stop_distance_and_recovers() {
    let dir = tempfile::tempdir().unwrap();
    let bag = dir.path().join("approach");
    let (model, _) = common::demo_trees();
    let params = ScenarioParams {
        scene: SceneKind::Approach,
        frames: 60,
        ..ScenarioParams::default()
    };
    let generated = scenario::generate(&model, &params, &bag).unwrap();
    assert!(generated.separation.iter().all(|s| s.is_some()));
    for (overrides, name) in [
        (&[][..], "demo config (every link measured)"),
        (
            &[("per_link_range", "0.32")][..],
            "per_link_range 0.32 (far links bounded)",
        ),
    ] {
        let rows = replay_rows(&bag, overrides);
        assert_eq!(rows.len(), 60, "{name}");
        let stop = Config::default().stop_distance_m;
        let first_zero = rows
            .iter()
            .position(|r| r.speed_scaling == Some(0.0) && r.index > 5)
            .expect("the factor reaches 0");
        let truth_then = rows[first_zero].truth_m.unwrap();
        assert!(
            truth_then > stop,
            "{name}: 0 only at a true distance of {truth_then}"
        );
        for r in &rows {
            let k = r.speed_scaling.unwrap();
            let allowed = r.allowed_factor.unwrap_or(0.0);
            assert!(
                k <= allowed + 1e-12,
                "{name}: frame {}: {k} > allowed {allowed}",
                r.index
            );
            if r.truth_m.unwrap() <= stop {
                assert_eq!(k, 0.0, "{name}: frame {} within the stop distance", r.index);
            }
            if let (Some(v), Some(t)) = (r.nearest_approach_mps, r.truth_approach_mps) {
                assert!(
                    (v - t).abs() < 0.01,
                    "{name}: frame {}: v_r {v} vs truth {t}",
                    r.index
                );
            }
        }
        let last = rows.last().unwrap();
        assert_eq!(
            last.speed_scaling,
            Some(1.0),
            "{name}: no recovery: {last:?}"
        );
        let recovered = rows
            .iter()
            .skip(first_zero)
            .position(|r| r.speed_scaling.unwrap() > 0.5);
        assert!(recovered.is_some(), "{name}");
    }
}
