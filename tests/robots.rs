//! The real third-party robots of ../shared (Panda, UR5e): kinematics, packing invariants,
//! quality against the budget, the cache round trip and package:// resolution.

mod common;

use std::path::Path;

use ist_monitor::ist::cache::TreeCache;
use ist_monitor::ist::validate::validate_link;
use ist_monitor::ist::{build_robot, BuildOptions, LinkTree, Origin};
use ist_monitor::robot::{PackagePath, RobotModel};

fn load(shared: &Path, robot: &str) -> RobotModel {
    RobotModel::load(
        &shared.join("robots").join(robot).join("robot.urdf"),
        &[],
        &Default::default(),
    )
    .expect("loads")
}

fn options(budget: u32) -> BuildOptions {
    let mut o = BuildOptions::default();
    o.packing.max_spheres = budget;
    o
}

fn trees(model: &RobotModel, budget: u32) -> Vec<LinkTree> {
    build_robot(model, &options(budget), None, &|_| {})
        .expect("builds")
        .into_iter()
        .map(|(t, _)| t)
        .collect()
}

#[test]
fn panda_ready_pose_puts_link8_where_moveit_does() {
    let Some(shared) = common::shared() else {
        return;
    };
    let model = load(&shared, "panda");
    let k = &model.kinematics;
    let ready = [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785];
    let named: Vec<(String, f64)> = ready
        .iter()
        .enumerate()
        .map(|(i, v)| (format!("panda_joint{}", i + 1), *v))
        .collect();
    let q = k.values_from_names(&named, Some(0.0)).expect("joints");
    let poses = k.link_poses(&q);
    let p = poses[k.link_index("panda_link8").expect("link8")]
        .translation
        .vector;
    let expected = nalgebra::Vector3::new(0.307, 0.0, 0.590);
    assert!((p - expected).norm() < 1e-3, "panda_link8 at {p:?}");
    // The mimic finger follows finger_joint1.
    assert_eq!(k.variables().len(), 8);
    assert_eq!(model.skipped_links, ["panda_link8"]);
}

/// Every sphere inside its mesh (exact f64 check, 1e-6 m), no overlap beyond 1e-6 m, every node
/// bounding its children; and more spheres give more coverage and a smaller gap.
fn check_robot(robot: &str) {
    let Some(shared) = common::shared() else {
        return;
    };
    let model = load(&shared, robot);
    let small = trees(&model, 256);
    let large = trees(&model, 2048);
    for (tree, geometry) in large.iter().zip(&model.links) {
        validate_link(tree, geometry, 1e-6).unwrap_or_else(|e| panic!("{robot}: {e}"));
    }
    for (s, l) in small.iter().zip(&large) {
        let (qs, ql) = (&s.quality, &l.quality);
        assert!(
            ql.coverage > qs.coverage,
            "{}: coverage {} → {}",
            s.link,
            qs.coverage,
            ql.coverage
        );
        assert!(
            ql.gap_m < qs.gap_m,
            "{}: gap {} → {}",
            s.link,
            qs.gap_m,
            ql.gap_m
        );
        assert!(ql.gap_sampled_m <= ql.gap_m);
    }
}

#[test]
fn panda_packing_invariants_and_quality_trend() {
    check_robot("panda");
}

#[test]
fn ur5e_packing_invariants_and_quality_trend() {
    check_robot("ur5e");
}

#[test]
fn build_then_cache_then_load_gives_identical_trees() {
    let Some(shared) = common::shared() else {
        return;
    };
    let model = load(&shared, "panda");
    let dir = tempfile::tempdir().expect("tmp");
    let cache = TreeCache::new(dir.path().to_owned());
    let built = build_robot(&model, &options(300), Some(&cache), &|_| {}).expect("build");
    let loaded = build_robot(&model, &options(300), Some(&cache), &|_| {}).expect("load");
    assert!(built.iter().all(|(_, o)| *o == Origin::Built));
    assert!(loaded.iter().all(|(_, o)| *o == Origin::Cache));
    for ((a, _), (b, _)) in built.iter().zip(&loaded) {
        assert_eq!(a, b);
    }
    // Other parameters miss the cache instead of returning the old trees.
    let other = build_robot(&model, &options(301), Some(&cache), &|_| {}).expect("build");
    assert!(other.iter().all(|(_, o)| *o == Origin::Built));
}

/// Lays the Panda out as a ROS package (`<ws>/panda_description/{urdf,meshes}`) with
/// `package://` mesh URIs, as real descriptions have them.
fn panda_as_package(shared: &Path, ws: &Path) -> std::path::PathBuf {
    let pkg = ws.join("panda_description");
    std::fs::create_dir_all(pkg.join("urdf")).expect("mkdir");
    std::os::unix::fs::symlink(shared.join("robots/panda/meshes"), pkg.join("meshes"))
        .expect("link");
    let urdf = std::fs::read_to_string(shared.join("robots/panda/robot.urdf"))
        .expect("urdf")
        .replace(
            "filename=\"meshes/",
            "filename=\"package://panda_description/meshes/",
        );
    let path = pkg.join("urdf/panda.urdf");
    std::fs::write(&path, urdf).expect("write");
    path
}

#[test]
fn package_uris_resolve_through_package_path_and_ros_package_path() {
    let Some(shared) = common::shared() else {
        return;
    };
    let ws = tempfile::tempdir().expect("tmp");
    let urdf = panda_as_package(&shared, ws.path());
    let elsewhere = tempfile::tempdir().expect("tmp");
    let moved = elsewhere.path().join("panda.urdf");
    std::fs::copy(&urdf, &moved).expect("copy");
    // Without a package path the package is not found, and the error says which.
    let err = RobotModel::load(&moved, &[], &Default::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("panda_description") && err.contains("panda_link0"),
        "{err}"
    );
    let packages = [PackagePath {
        name: "panda_description".into(),
        dir: ws.path().join("panda_description"),
    }];
    let model =
        RobotModel::load(&moved, &packages, &Default::default()).expect("explicit package path");
    assert_eq!(model.links.len(), 11);
    // The environment variables, through the binary so they are set for that process only.
    let poses = |var: &str, value: &Path| {
        let out = common::ist_monitor()
            .args(["poses", "--urdf"])
            .arg(&moved)
            .env_remove("ROS_PACKAGE_PATH")
            .env_remove("AMENT_PREFIX_PATH")
            .env(var, value)
            .output()
            .expect("runs");
        assert!(
            out.status.success(),
            "{var}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    poses("ROS_PACKAGE_PATH", ws.path());
    // AMENT_PREFIX_PATH: PREFIX/share/NAME.
    let prefix = tempfile::tempdir().expect("tmp");
    std::fs::create_dir_all(prefix.path().join("share")).expect("mkdir");
    std::os::unix::fs::symlink(
        ws.path().join("panda_description"),
        prefix.path().join("share/panda_description"),
    )
    .expect("link");
    poses("AMENT_PREFIX_PATH", prefix.path());
}
