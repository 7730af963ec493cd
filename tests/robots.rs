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
        validate_link(tree, geometry, 1e-6, 0.0).unwrap_or_else(|e| panic!("{robot}: {e}"));
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
        // The cache stores no wall times.
        let mut a = a.clone();
        a.quality.build_s = 0.0;
        a.quality.validate_s = 0.0;
        a.quality.stages = Default::default();
        assert_eq!(&a, b);
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

/// An STL file read here, apart from the library's reader: binary or ASCII, f64.
fn read_stl(path: &Path) -> Vec<[[f64; 3]; 3]> {
    let bytes = std::fs::read(path).expect("read STL");
    let binary_size = |n: usize| 84 + 50 * n;
    if bytes.len() >= 84 {
        let n = u32::from_le_bytes(bytes[80..84].try_into().expect("4 bytes")) as usize;
        if bytes.len() == binary_size(n) {
            return (0..n)
                .map(|i| {
                    let at = 84 + 50 * i + 12;
                    std::array::from_fn(|v| {
                        std::array::from_fn(|k| {
                            let o = at + 12 * v + 4 * k;
                            f32::from_le_bytes(bytes[o..o + 4].try_into().expect("4 bytes")) as f64
                        })
                    })
                })
                .collect();
        }
    }
    let text = String::from_utf8_lossy(&bytes);
    let vertices: Vec<[f64; 3]> = text
        .lines()
        .filter_map(|l| l.trim().strip_prefix("vertex"))
        .map(|rest| {
            let v: Vec<f64> = rest
                .split_whitespace()
                .map(|x| x.parse::<f32>().expect("number") as f64)
                .collect();
            [v[0], v[1], v[2]]
        })
        .collect();
    vertices
        .chunks_exact(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect()
}

/// The distance from a point to the union of spheres, exact, by a sweep over the spheres
/// sorted by x (outward from the point's x, until no sphere can be nearer).
struct SweepX {
    /// (x, y, z, r), sorted by x.
    spheres: Vec<[f64; 4]>,
    max_radius: f64,
}

impl SweepX {
    fn new(spheres: &[ist_monitor::packing::InnerSphere]) -> Self {
        let mut s: Vec<[f64; 4]> = spheres
            .iter()
            .map(|s| {
                let c = s.center.map(f64::from);
                [c[0], c[1], c[2], s.radius as f64]
            })
            .collect();
        s.sort_by(|a, b| a[0].total_cmp(&b[0]));
        let max_radius = s.iter().map(|s| s[3]).fold(0.0, f64::max);
        Self {
            spheres: s,
            max_radius,
        }
    }

    fn gap(&self, p: [f64; 3]) -> f64 {
        let at = self.spheres.partition_point(|s| s[0] < p[0]);
        let mut best = f64::INFINITY;
        let gap = |s: &[f64; 4]| d(p, [s[0], s[1], s[2]]) - s[3];
        let (mut lo, mut hi) = (at, at);
        loop {
            let left = (lo > 0).then(|| p[0] - self.spheres[lo - 1][0]);
            let right = (hi < self.spheres.len()).then(|| self.spheres[hi][0] - p[0]);
            match (left, right) {
                (Some(l), r) if r.is_none_or(|r| l <= r) => {
                    if l - self.max_radius >= best {
                        break;
                    }
                    lo -= 1;
                    best = best.min(gap(&self.spheres[lo]));
                }
                (_, Some(r)) => {
                    if r - self.max_radius >= best {
                        break;
                    }
                    best = best.min(gap(&self.spheres[hi]));
                    hi += 1;
                }
                _ => break,
            }
        }
        best.max(0.0)
    }
}

fn d(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// The vendor robots at default settings, checked apart from the library: each collision STL
/// read again here (every triangle present, the same shape in the link frame: side lengths
/// equal to what the library packed against), every sphere inside its closed mesh by the
/// brute-force winding number and farther than its radius from every triangle (1e-6 m), and
/// points sampled on the file's own triangles within the claimed h of the spheres (or, for a
/// solid the intake filled, strictly inside it: such a point is never nearest to the outside).
fn independent_check(urdf: &Path) -> Vec<LinkTree> {
    use ist_monitor::geometry::{distance_point_mesh, winding_number};
    use rayon::prelude::*;
    let model = RobotModel::load(urdf, &[], &Default::default()).expect("loads");
    let trees = build_robot(&model, &BuildOptions::default(), None, &|_| {}).expect("builds");
    for ((tree, _), link) in trees.iter().zip(&model.links) {
        assert_eq!(link.intake.len(), 1, "{}: one mesh file", link.name);
        let intake = &link.intake[0];
        let (vertices, triangles) = &*intake.original;
        let file = read_stl(&intake.file);
        assert_eq!(file.len(), triangles.len(), "{}: triangles read", link.name);
        for (f, t) in file.iter().zip(triangles) {
            let v = t.map(|i| vertices[i as usize].map(f64::from));
            for k in 0..3 {
                let (a, b) = (d(f[k], f[(k + 1) % 3]), d(v[k], v[(k + 1) % 3]));
                // f32 vertices posed in the link frame: a rounding of each coordinate.
                assert!(
                    (a - b).abs() <= 1e-6 * a + 2e-7,
                    "{}: {a} vs {b}",
                    link.name
                );
            }
        }
        let h = tree.quality.gap_m;
        // A closed file (its shells apart, as it gives them): its own winding number. One the
        // intake repaired (where inside is its decision): the convex hull of the file's
        // vertices, and no file triangle crossed.
        let hull = (!intake.report.solid_as_given()).then(|| {
            let points: Vec<parry3d::math::Vector> = vertices
                .iter()
                .map(|v| parry3d::math::Vector::new(v[0], v[1], v[2]))
                .collect();
            let (hv, ht) = parry3d::transformation::convex_hull(&points);
            let hv: Vec<[f32; 3]> = hv.iter().map(|v| [v.x, v.y, v.z]).collect();
            (hv, ht)
        });
        let bad = tree.spheres.par_iter().enumerate().find_any(|(_, s)| {
            let c = s.center.map(f64::from);
            let r = s.radius as f64 - 1e-6;
            match &hull {
                None => {
                    winding_number(c, vertices, triangles) < 0.5
                        || distance_point_mesh(c, vertices, triangles) < r
                }
                // Inside the hull, and inside one of the solids the intake reports (brute
                // force here: its closed shells' winding number, or a filled solid's fill),
                // clear of that solid's surface.
                Some((hv, ht)) => {
                    winding_number(c, hv, ht) < 0.5
                        || !link.elements.iter().any(|e| {
                            let inside = match &e.mesh.fill {
                                Some(fill) => fill.contains(c, false),
                                None => {
                                    winding_number(c, &e.mesh.vertices, &e.mesh.triangles) >= 0.5
                                }
                            };
                            inside
                                && distance_point_mesh(c, &e.mesh.vertices, &e.mesh.triangles) >= r
                        })
                }
            }
        });
        assert!(bad.is_none(), "{}: sphere {bad:?} not inside", link.name);
        let nearest = SweepX::new(&tree.spheres);
        let excused = std::sync::atomic::AtomicUsize::new(0);
        let weights = [
            [1.0, 0.0, 0.0],
            [0.5, 0.5, 0.0],
            [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
        ];
        let worst = triangles
            .par_iter()
            .flat_map_iter(|t| {
                let v = t.map(|i| vertices[i as usize].map(f64::from));
                (0..3).flat_map(move |r| {
                    weights.map(|w| -> [f64; 3] {
                        std::array::from_fn(|k| (0..3).map(|m| w[(m + r) % 3] * v[m][k]).sum())
                    })
                })
            })
            .map(|p| {
                let gap = nearest.gap(p);
                // A point strictly inside a filled solid (a file triangle the intake found
                // inside, dropped) is never the nearest point of the link to anything outside
                // it: the solid's surface lies between. Only such points may be farther.
                let inner = gap > h
                    && link.elements.iter().any(|e| {
                        e.mesh.fill.as_ref().is_some_and(|fill| {
                            fill.contains(p, false)
                                && distance_point_mesh(p, &e.mesh.vertices, &e.mesh.triangles)
                                    > 1e-7
                        })
                    });
                if inner {
                    excused.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    0.0
                } else {
                    gap
                }
            })
            .reduce(|| 0.0, f64::max);
        assert!(
            worst <= h,
            "{}: sampled gap {worst} m above h {h} m",
            link.name
        );
        println!(
            "{}: h {:.3} mm, sampled on the file {:.3} mm ({} points farther, inside the filled \
             solid), {} spheres, coverage {:.1} %",
            link.name,
            h * 1e3,
            worst * 1e3,
            excused.into_inner(),
            tree.spheres.len(),
            100.0 * tree.quality.coverage
        );
    }
    trees.into_iter().map(|(tree, _)| tree).collect()
}

#[test]
fn panda_at_defaults_passes_the_independent_check() {
    let Some(shared) = common::shared() else {
        return;
    };
    independent_check(&shared.join("robots/panda/robot.urdf"));
}

#[test]
fn ur5e_at_defaults_passes_the_independent_check() {
    let Some(shared) = common::shared() else {
        return;
    };
    independent_check(&shared.join("robots/ur5e/robot.urdf"));
}

#[test]
fn kuka_kr3_at_defaults_passes_the_independent_check() {
    independent_check(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/robots/kuka_kr3r540/robot.urdf"),
    );
}

/// Thin walls open at their tube ends (issue 30): h at most 3 mm at defaults, certified by the
/// same independent check.
#[test]
fn kinova_gen3_tubes_at_defaults_pass_the_independent_check() {
    let urdf = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/robots/kinova_gen3/robot.urdf");
    let model = RobotModel::load(&urdf, &[], &Default::default()).expect("loads");
    assert_eq!(model.links.len(), 3);
    let trees = independent_check(&urdf);
    for tree in &trees {
        assert!(
            tree.quality.gap_m <= 0.003,
            "{}: h {:.3} mm",
            tree.link,
            tree.quality.gap_m * 1e3
        );
    }
}
