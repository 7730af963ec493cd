//! Mesh intake on meshes made with known defects, each loaded through a URDF as a vendor's file
//! would be: CAD-noise seams, a hole of known size, an edge shared by four triangles,
//! zero-area triangles, a shell nested in another, a thin-walled hollow box and two overlapping
//! shells. For each: it loads, the report says what was done, the tree builds and passes the
//! f64 validation, no inner sphere lies outside the solid the mesh describes (checked against
//! the boxes themselves, not the repaired mesh), and h is certified against the real surface
//! (points sampled on the file's own triangles lie within h of the spheres).

mod common;

use std::path::Path;

use common::{one_link_urdf, write_stl};
use ist_monitor::ist::validate::validate_link;
use ist_monitor::ist::{build_link, BuildOptions, LinkTree};
use ist_monitor::packing::PackingParams;
use ist_monitor::robot::mesh::ClosedMesh;
use ist_monitor::robot::{LinkGeometry, LinkSelection, MeshReport, RobotModel, TriangleFate};

type Tri = [[f32; 3]; 3];

/// A box `lo..hi` with every face an n × n grid, outward, one triangle per STL record.
fn grid_box(lo: [f32; 3], hi: [f32; 3], n: usize) -> Vec<Tri> {
    let mut out = Vec::new();
    for k in 0..3 {
        for outward in [false, true] {
            // u × v = ±e_k: (k+1, k+2) for the + face, swapped for the − face.
            let (u, v) = if outward {
                ((k + 1) % 3, (k + 2) % 3)
            } else {
                ((k + 2) % 3, (k + 1) % 3)
            };
            let at = |i: usize, j: usize| {
                let mut p = [0.0f32; 3];
                p[k] = if outward { hi[k] } else { lo[k] };
                p[u] = lo[u] + (hi[u] - lo[u]) * i as f32 / n as f32;
                p[v] = lo[v] + (hi[v] - lo[v]) * j as f32 / n as f32;
                p
            };
            for i in 0..n {
                for j in 0..n {
                    out.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                    out.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
    }
    out
}

fn inward(triangles: Vec<Tri>) -> Vec<Tri> {
    triangles.into_iter().map(|[a, b, c]| [a, c, b]).collect()
}

/// Loads `triangles` as the one mesh of link `body`.
fn load(dir: &Path, triangles: &[Tri]) -> LinkGeometry {
    write_stl(&dir.join("body.stl"), triangles);
    let urdf = dir.join("robot.urdf");
    std::fs::write(&urdf, one_link_urdf(r#"<mesh filename="body.stl"/>"#)).expect("write");
    let model = RobotModel::load(&urdf, &[], &LinkSelection::default()).expect("the mesh loads");
    model.links.into_iter().next().expect("one link")
}

fn report(link: &LinkGeometry) -> &MeshReport {
    &link.intake[0].report
}

fn build(link: &LinkGeometry, spheres: u32) -> LinkTree {
    build_with(link, spheres, 512)
}

/// The defaults with a small sphere budget and few prototypes: quick builds of test meshes.
fn small_options(spheres: u32, prototypes: u32) -> BuildOptions {
    BuildOptions {
        packing: PackingParams {
            max_spheres: spheres,
            prototypes,
            ..PackingParams::default()
        },
        ..BuildOptions::default()
    }
}

fn build_with(link: &LinkGeometry, spheres: u32, prototypes: u32) -> LinkTree {
    let tree = build_link(link, &small_options(spheres, prototypes)).expect("builds");
    validate_link(&tree, link, 1e-6, 0.0).expect("every sphere inside its shell (f64)");
    tree
}

/// Every sphere lies inside one of `boxes` (the solid the mesh describes), to 1e-6 m.
fn assert_inside(tree: &LinkTree, boxes: &[([f32; 3], [f32; 3])]) {
    for (i, s) in tree.spheres.iter().enumerate() {
        let inside = boxes.iter().any(|(lo, hi)| {
            (0..3).all(|k| {
                s.center[k] - s.radius >= lo[k] - 1e-6 && s.center[k] + s.radius <= hi[k] + 1e-6
            })
        });
        assert!(inside, "sphere {i} {s:?} outside the solid");
    }
}

/// The distance from `p` to the tree's spheres (0 inside one), by brute force.
fn gap_at(tree: &LinkTree, p: [f64; 3]) -> f64 {
    tree.spheres
        .iter()
        .map(|s| {
            let d = (0..3)
                .map(|k| (p[k] - s.center[k] as f64).powi(2))
                .sum::<f64>()
                .sqrt();
            d - s.radius as f64
        })
        .fold(f64::INFINITY, f64::min)
        .max(0.0)
}

/// The largest gap at points of `surface` (corners, edge midpoints, centroid, and a few inside
/// each triangle).
fn sampled_gap(tree: &LinkTree, surface: &[Tri]) -> f64 {
    let weights = [
        [1.0, 0.0, 0.0],
        [0.5, 0.5, 0.0],
        [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
        [0.7, 0.2, 0.1],
        [0.1, 0.45, 0.45],
        [0.2, 0.1, 0.7],
    ];
    let mut worst = 0.0f64;
    for t in surface {
        for r in 0..3 {
            for w in weights {
                let p: [f64; 3] = std::array::from_fn(|k| {
                    (0..3).map(|m| w[(m + r) % 3] * t[m][k] as f64).sum::<f64>()
                });
                worst = worst.max(gap_at(tree, p));
            }
        }
    }
    worst
}

/// Points on `surface` lie within h of the spheres: the lower bound `d − h` holds against that
/// surface.
fn assert_gap_certified(tree: &LinkTree, surface: &[Tri]) {
    let h = tree.quality.gap_m;
    let worst = sampled_gap(tree, surface);
    assert!(
        worst <= h + 1e-6,
        "a surface point {worst} m from the spheres, h {h}"
    );
}

const LO: [f32; 3] = [0.0; 3];
const HI: [f32; 3] = [0.1; 3];

/// CAD noise: each STL record's copy of a vertex moved by up to 3e-8 m (the weld tolerance
/// is 1e-7 m on this 0.1 m box). The bit-exact welder took that for 48 open edges.
#[test]
fn cad_noise_seams_are_welded() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut noise = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        ((seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) as f32 * 3e-8
    };
    let noisy: Vec<Tri> = grid_box(LO, HI, 4)
        .into_iter()
        .map(|t| t.map(|v| v.map(|x| x + noise())))
        .collect();
    // What the strict, bit-exact welder says about it.
    let soup: Vec<[f32; 3]> = noisy.iter().flatten().copied().collect();
    let indices: Vec<[u32; 3]> = (0..noisy.len() as u32)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    let strict = ClosedMesh::new(soup, indices, "noisy")
        .map(|_| ())
        .unwrap_err();
    assert!(strict.to_string().contains("open edges"), "{strict}");

    let link = load(dir.path(), &noisy);
    let r = report(&link);
    assert!(
        r.welded_vertices > 0 && r.open_edges == 0 && r.holes_closed == 0,
        "{r:?}"
    );
    assert!((r.weld_tolerance_m - 1e-7).abs() < 1e-9, "{r:?}");
    assert_eq!(link.elements.len(), 1);
    assert!((link.elements[0].mesh.volume_m3 - 1e-3).abs() < 1e-8);
    let tree = build(&link, 512);
    assert_inside(&tree, &[(LO, HI)]);
    assert_gap_certified(&tree, &noisy);
}

/// A 1 cm × 1 cm hole in the top face (two triangles left out): closed, its size reported.
#[test]
fn a_hole_of_known_size_is_closed() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut mesh = grid_box(LO, HI, 10);
    // The +z face is the last 200 triangles (k = 2, outward); drop one cell in its middle.
    let top = mesh.len() - 200;
    let cell = top + 2 * (5 * 10 + 5);
    mesh.drain(cell..cell + 2);
    let link = load(dir.path(), &mesh);
    let r = report(&link);
    assert_eq!((r.open_edges, r.holes_closed), (4, 1), "{r:?}");
    assert!(
        (r.largest_hole_m - 0.01 * 2f64.sqrt()).abs() < 1e-6,
        "{r:?}"
    );
    assert!((link.elements[0].mesh.volume_m3 - 1e-3).abs() < 1e-8);
    let tree = build(&link, 512);
    assert_inside(&tree, &[(LO, HI)]);
    assert_gap_certified(&tree, &mesh);
}

/// Two boxes touching along an edge (four triangles on it: non-manifold): two shells, one
/// solid.
#[test]
fn boxes_sharing_an_edge_come_apart() {
    let dir = tempfile::tempdir().expect("tmp");
    let a = ([0.0; 3], [0.05; 3]);
    let b = ([0.05, 0.05, 0.0], [0.1, 0.1, 0.05]);
    let mut mesh = grid_box(a.0, a.1, 2);
    mesh.extend(grid_box(b.0, b.1, 2));
    let link = load(dir.path(), &mesh);
    let r = report(&link);
    assert!(r.non_manifold_edges >= 2 && r.shells == 2, "{r:?}");
    // Two shells: one solid, decided by the flood fill.
    assert!(r.fill_voxel_m.is_some(), "{r:?}");
    assert_eq!(link.elements.len(), 1);
    let tree = build(&link, 512);
    assert_inside(&tree, &[a, b]);
    assert_gap_certified(&tree, &mesh);
}

/// A triangle with a repeated vertex and one folded flat along an edge: dropped, counted.
#[test]
fn zero_area_triangles_are_dropped() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut mesh = grid_box(LO, HI, 4);
    mesh.push([[0.0; 3], [0.0; 3], [0.1, 0.0, 0.0]]);
    mesh.push([[0.0; 3], [0.05, 0.0, 0.0], [0.1, 0.0, 0.0]]);
    let link = load(dir.path(), &mesh);
    let r = report(&link);
    assert_eq!((r.degenerate_triangles, r.open_edges), (2, 0), "{r:?}");
    let tree = build(&link, 512);
    assert_inside(&tree, &[(LO, HI)]);
}

/// A box inside a box, the inner one facing inward (a cavity): the solid is the outer box whole.
#[test]
fn a_nested_shell_is_filled() {
    let dir = tempfile::tempdir().expect("tmp");
    let outer = grid_box(LO, HI, 4);
    let mut mesh = outer.clone();
    mesh.extend(inward(grid_box([0.025; 3], [0.075; 3], 4)));
    let link = load(dir.path(), &mesh);
    let r = report(&link);
    assert_eq!((r.shells, r.inner_shells), (2, 1), "{r:?}");
    assert_eq!(link.elements.len(), 1);
    assert!((link.elements[0].mesh.volume_m3 - 1e-3).abs() < 1e-8);
    let tree = build(&link, 512);
    assert_inside(&tree, &[(LO, HI)]);
    assert_gap_certified(&tree, &outer);
}

/// A visual mesh used as a collision mesh: 2 mm walls. The strict intake packed the wall only
/// (the cavity was outside); now the spheres fill the box, and h is what a solid box gets.
#[test]
fn a_thin_walled_hollow_box_packs_as_a_solid() {
    let dir = tempfile::tempdir().expect("tmp");
    let outer = grid_box(LO, HI, 8);
    let mut mesh = outer.clone();
    mesh.extend(inward(grid_box([0.002; 3], [0.098; 3], 8)));
    let link = load(dir.path(), &mesh);
    let r = report(&link);
    assert_eq!(r.inner_shells, 1, "{r:?}");
    let tree = build(&link, 2048);
    assert_inside(&tree, &[(LO, HI)]);
    assert_gap_certified(&tree, &outer);
    // A solid box of the same budget, for comparison.
    let solid = load(dir.path(), &outer);
    let reference = build(&solid, 2048);
    assert!(
        tree.quality.coverage >= 0.95 * reference.quality.coverage
            && tree.quality.gap_m <= 1.05 * reference.quality.gap_m + 1e-4,
        "hollow: coverage {} h {}; solid: coverage {} h {}",
        tree.quality.coverage,
        tree.quality.gap_m,
        reference.quality.coverage,
        reference.quality.gap_m
    );
    // The wall alone cannot hold a sphere wider than 1 mm; these do.
    assert!(tree.spheres.iter().any(|s| s.radius > 0.02));
}

/// Two boxes overlapping: one solid, their union (the flood fill), h certified against both
/// boxes' surfaces; once in general position and once with faces that coincide where they
/// overlap (shared cells, repeated triangles, edges of three and four triangles).
#[test]
fn overlapping_shells_are_kept_apart() {
    let dir = tempfile::tempdir().expect("tmp");
    let a = ([0.0; 3], [0.06; 3]);
    for (b, coincident) in [
        (([0.045, 0.01, 0.01], [0.1, 0.07, 0.05]), false),
        (([0.04, 0.0, 0.0], [0.1, 0.06, 0.06]), true),
    ] {
        let mut mesh = grid_box(a.0, a.1, 3);
        mesh.extend(grid_box(b.0, b.1, 3));
        let link = load(dir.path(), &mesh);
        let r = report(&link);
        assert_eq!(r.inner_shells, 0, "{r:?}");
        // One solid (the union), decided by the flood fill; the faces of each box inside
        // the other are dropped.
        assert!(r.fill_voxel_m.is_some(), "{r:?}");
        assert!(!r.solid_as_given(), "{r:?}");
        assert!(coincident || r.inner_triangles > 0, "{r:?}");
        assert_eq!(link.elements.len(), 1, "{r:?}");
        let tree = build(&link, 512);
        assert_inside(&tree, &[a, b]);
        assert_gap_certified(&tree, &mesh);
    }
}

/// A body and a boss beside it, two closed boxes 1 mm apart in one file (issue 56: a dual arm's
/// links as their vendor ships them), the slot between them narrower than the flood fill's
/// voxel (0.3 m / 256 = 1.17 mm). The slot is outside the file's solid: every sphere's centre is
/// inside the file's own triangles by their winding number and farther than its radius from
/// every one of them (f64, brute force), and each sphere lies in one of the boxes. The fill
/// closed the slot, and the packing grew spheres across it.
#[test]
fn a_slot_between_two_closed_shells_is_not_filled() {
    use ist_monitor::geometry::{distance_point_mesh, winding_number};
    let dir = tempfile::tempdir().expect("tmp");
    let body = ([0.0, 0.0, 0.0], [0.3, 0.06, 0.06]);
    let boss = ([0.1, 0.061, 0.0], [0.2, 0.1, 0.06]);
    let mut mesh = grid_box(body.0, body.1, 4);
    mesh.extend(grid_box(boss.0, boss.1, 4));
    let link = load(dir.path(), &mesh);
    let r = report(&link);
    assert_eq!(
        (r.shells, r.inner_shells, r.open_shells),
        (2, 0, 0),
        "{r:?}"
    );
    // Each box a solid of its own, as the file gives it.
    assert!(r.solid_as_given(), "{r:?}");
    assert_eq!(link.elements.len(), 2, "{r:?}");
    let tree = build(&link, 2048);
    let (vertices, triangles) = &*link.intake[0].original;
    for (i, s) in tree.spheres.iter().enumerate() {
        let c = s.center.map(f64::from);
        let wn = winding_number(c, vertices, triangles);
        let clear = distance_point_mesh(c, vertices, triangles) - (s.radius as f64 - 1e-6);
        assert!(
            wn >= 0.5 && clear >= 0.0,
            "sphere {i} {s:?}: winding number {wn}, {clear} m clear of the file's triangles \
             ({r:?})"
        );
    }
    assert_inside(&tree, &[body, boss]);
    assert_gap_certified(&tree, &mesh);
}

/// A vendor's robot as it ships: the KUKA KR 3 R540 of ros-industrial/kuka_experimental
/// (`tests/robots/kuka_kr3r540`, Apache-2.0, see its README). Two of its seven collision meshes
/// were refused by the strict intake (non-manifold edges, near-identical vertices, 13 and 23
/// shells). With the default settings every link builds, passes the f64 validation and has
/// h ≤ 3 mm, and the exact distances equal brute force over the files' own triangles (f64).
#[test]
fn a_vendor_robot_with_imperfect_collision_meshes() {
    use ist_monitor::geometry::{distance_point_mesh, winding_number};
    use ist_monitor::query::{Engine, Mode, QueryOptions};
    use ist_monitor::robot::mesh::load_mesh_file;
    use nalgebra::{Isometry3, Point3};
    use rayon::prelude::*;

    let urdf = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/robots/kuka_kr3r540/robot.urdf");
    let model = RobotModel::load(&urdf, &[], &LinkSelection::default()).expect("loads");
    let raw: Vec<ist_monitor::robot::mesh::TriangleSoup> = model
        .links
        .iter()
        .map(|l| {
            let m = load_mesh_file(&l.intake[0].file).expect("reads");
            (m.vertices, m.triangles)
        })
        .collect();
    // What the strict intake (bit-exact welding, one closed manifold mesh) says of each file.
    let refused: Vec<&str> = model
        .links
        .iter()
        .zip(&raw)
        .filter(|(_, (v, t))| ClosedMesh::new(v.clone(), t.clone(), "strict").is_err())
        .map(|(l, _)| l.name.as_str())
        .collect();
    assert_eq!(refused, ["link_4"]);
    let repaired: Vec<&str> = model
        .links
        .iter()
        .filter(|l| !l.intake[0].report.clean())
        .map(|l| l.name.as_str())
        .collect();
    assert_eq!(repaired, ["link_2", "link_4"]);

    let trees: Vec<LinkTree> = model
        .links
        .par_iter()
        .map(|l| {
            let tree = build_link(l, &BuildOptions::default()).expect("builds");
            validate_link(&tree, l, 1e-6, 0.0).expect("valid");
            tree
        })
        .collect();
    for t in &trees {
        assert!(
            t.quality.gap_m <= 0.003,
            "{}: h {} m",
            t.link,
            t.quality.gap_m
        );
    }

    let mut engine = Engine::new(&model, &trees, &LinkSelection::default()).expect("engine");
    let k = &model.kinematics;
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..3 {
        let q: Vec<(String, f64)> = [
            "joint_a1", "joint_a2", "joint_a3", "joint_a4", "joint_a5", "joint_a6",
        ]
        .iter()
        .map(|j| (j.to_string(), next() * 2.0 - 1.0))
        .collect();
        let poses = k.link_poses(&k.values_from_names(&q, Some(0.0)).expect("joints"));
        let link_of = |name: &str| k.link_index(name).expect("link");
        // Points around the arm, each with its brute-force distance (f64, every triangle of
        // the files); points inside a shell are left out (their distance is 0 either way).
        let mut points = Vec::new();
        let mut truth = f64::INFINITY;
        while points.len() < 300 {
            let p = Point3::new(next() * 1.0 - 0.5, next() * 1.0 - 0.5, next() * 0.8);
            let mut d = f64::INFINITY;
            let mut inside = false;
            for (link, (v, t)) in model.links.iter().zip(&raw) {
                let q = poses[link_of(&link.name)].inverse() * p;
                let q = [q.x, q.y, q.z];
                inside |= winding_number(q, v, t) >= 0.5;
                d = d.min(distance_point_mesh(q, v, t));
            }
            if !inside && d > 1e-3 {
                truth = truth.min(d);
                points.push([p.x as f32, p.y as f32, p.z as f32]);
            }
        }
        let options = QueryOptions {
            mode: Mode::Exact,
            max_distance_m: f32::INFINITY,
            self_filter_padding_m: None,
            ..QueryOptions::default()
        };
        let r = engine
            .query(&points, &Isometry3::identity(), &poses, &options)
            .expect("query");
        let got = r.nearest.expect("a nearest point").distance_m;
        assert!(
            (got - truth).abs() < 1e-5,
            "exact {got}, brute force {truth}"
        );
    }
}

/// A hollow tube open at both ends (four 3 mm walls): the outside reaches its inside, so its
/// solid is the wall, and the packing can only line the wall. Packed as its convex hull (the
/// closed box) the spheres fill it; the hull's inner-sphere distance is then no upper bound of
/// the tube's, so the published distance is the certified lower bound: at most the true
/// distance, from a point outside and from a point inside the tube's bore alike.
#[test]
fn a_convex_hull_gives_only_its_lower_bound() {
    use ist_monitor::query::{Engine, Mode, QueryOptions};
    use nalgebra::Isometry3;

    let dir = tempfile::tempdir().expect("tmp");
    let walls = [
        ([0.0, 0.0, 0.0], [0.1, 0.003, 0.2]),
        ([0.0, 0.097, 0.0], [0.1, 0.1, 0.2]),
        ([0.0, 0.0, 0.0], [0.003, 0.1, 0.2]),
        ([0.097, 0.0, 0.0], [0.1, 0.1, 0.2]),
    ];
    let mesh: Vec<Tri> = walls
        .iter()
        .flat_map(|(lo, hi)| grid_box(*lo, *hi, 2))
        .collect();
    write_stl(&dir.path().join("body.stl"), &mesh);
    let urdf = dir.path().join("robot.urdf");
    std::fs::write(&urdf, one_link_urdf(r#"<mesh filename="body.stl"/>"#)).expect("write");
    // (true distance, point): outside the wall, and in the middle of the bore.
    let points = [(0.02, [0.05f32, -0.02, 0.1]), (0.047, [0.05, 0.05, 0.1])];
    let mut published = Vec::new();
    let mut hull_gap = 0.0;
    for hull in [false, true] {
        let selection = LinkSelection {
            convex_hull: if hull {
                vec!["body".into()]
            } else {
                Vec::new()
            },
            ..LinkSelection::default()
        };
        let model = RobotModel::load(&urdf, &[], &selection).expect("loads");
        let link = &model.links[0];
        assert_eq!(link.hull_of_volume_m3.is_some(), hull);
        // The default prototypes: few of them over a thin filled wall make a slow packing.
        let tree = build_with(link, 1024, PackingParams::default().prototypes);
        if hull {
            hull_gap = tree.quality.gap_m;
            assert!((link.elements[0].mesh.volume_m3 - 0.002).abs() < 1e-8);
            assert!(
                tree.spheres.iter().any(|s| s.radius > 0.04),
                "the hull is filled"
            );
        } else {
            assert_inside(&tree, &walls);
        }
        let mut engine =
            Engine::new(&model, std::slice::from_ref(&tree), &selection).expect("engine");
        let poses = model.kinematics.link_poses(&[]);
        for (truth, p) in points {
            for mode in [Mode::Fast, Mode::Certified] {
                let options = QueryOptions {
                    mode,
                    max_distance_m: f32::INFINITY,
                    self_filter_padding_m: None,
                    ..QueryOptions::default()
                };
                let r = engine
                    .query(&[p], &Isometry3::identity(), &poses, &options)
                    .expect("query");
                let d = r.nearest.expect("nearest").distance_m;
                if hull {
                    // The lower bound of the hull: never above the truth.
                    assert!(
                        d <= truth + 1e-6,
                        "{mode:?} {p:?}: published {d} above the true {truth}"
                    );
                    published.push(d);
                } else {
                    // The tube's own spheres: an upper bound, within h of the truth.
                    assert!(
                        d >= truth - 1e-6 && d <= truth + tree.quality.gap_m + 1e-6,
                        "{d} against {truth}"
                    );
                }
            }
        }
    }
    // From outside, the hull's bound is close to the truth (within its h).
    assert!(
        published[0] >= 0.02 - hull_gap - 1e-6,
        "{published:?}, h {hull_gap}"
    );
}

/// A COLLADA file of five `<geometry>` pieces, each placed by its node's transforms (a
/// translation, a row-major matrix, a nested rotation and scale, a unit of millimetres): all
/// five load where the scene puts them, nothing is taken for a repeated triangle, and the tree
/// covers every piece. mesh-loader's merge lost pieces 3–5 of such a file (they became copies
/// of the first pieces' triangles and were dropped as "repeated"): `tests/meshes/
/// five_pieces.dae` is the minimal file for that report.
#[test]
fn a_five_piece_collada_loads_every_piece_at_its_node_transform() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dae = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/meshes/five_pieces.dae");
    std::fs::copy(&dae, dir.path().join("body.dae")).expect("copy");
    let urdf = dir.path().join("robot.urdf");
    std::fs::write(&urdf, one_link_urdf(r#"<mesh filename="body.dae"/>"#)).expect("write");
    let model = RobotModel::load(&urdf, &[], &LinkSelection::default()).expect("loads");
    let link = &model.links[0];
    let r = report(link);
    assert_eq!(
        (r.pieces, r.triangles_in, r.repeated_triangles),
        (5, 60, 0),
        "{r:?}"
    );
    assert!(
        r.notes.iter().any(|n| n.contains("unit 0.001 m")),
        "{:?}",
        r.notes
    );
    assert!(
        r.notes.iter().any(|n| n.contains("1 of 6 geometries")),
        "{:?}",
        r.notes
    );
    // The file's cubes of 20 mm at x = 0, 40, 80 (translate), 120 (matrix) mm, and the fifth
    // scaled ×2 along x and turned 90° about z at x = 160 mm: [140, 160] × [0, 40] × [0, 20].
    let mut boxes: Vec<([f32; 3], [f32; 3])> = (0..4)
        .map(|k| {
            (
                [0.04 * k as f32, 0.0, 0.0],
                [0.04 * k as f32 + 0.02, 0.02, 0.02],
            )
        })
        .collect();
    boxes.push(([0.14, 0.0, 0.0], [0.16, 0.04, 0.02]));
    let (lo, hi) = link
        .elements
        .iter()
        .fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), e| {
            let (a, b) = e.mesh.bounds();
            (
                std::array::from_fn(|k| lo[k].min(a[k])),
                std::array::from_fn(|k| hi[k].max(b[k])),
            )
        });
    let close = |a: [f32; 3], b: [f32; 3]| (0..3).all(|k| (a[k] - b[k]).abs() < 1e-6);
    assert!(
        close(lo, [0.0; 3]) && close(hi, [0.16, 0.04, 0.02]),
        "{lo:?} {hi:?}"
    );
    let tree = build(link, 1000);
    assert_inside(&tree, &boxes);
    let surface: Vec<Tri> = boxes
        .iter()
        .flat_map(|(lo, hi)| common::box_triangles(*lo, *hi))
        .collect();
    assert_gap_certified(&tree, &surface);
    for (lo, hi) in &boxes {
        let c: [f32; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
        assert!(
            tree.spheres.iter().any(|s| (0..3)
                .map(|k| (s.center[k] - c[k]).powi(2))
                .sum::<f32>()
                .sqrt()
                < s.radius),
            "no sphere covers the centre of the piece at {c:?}"
        );
    }
}

/// An ASCII STL of three `solid` blocks: every solid is read (mesh-loader's merge misplaced the
/// third one on).
#[test]
fn every_solid_of_a_multi_solid_stl_loads() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut text = String::new();
    for k in 0..3 {
        let lo = [0.05 * k as f32, 0.0, 0.0];
        let hi = [lo[0] + 0.03, 0.03, 0.03];
        text.push_str(&format!("solid part{k}\n"));
        for t in common::box_triangles(lo, hi) {
            text.push_str(" facet normal 0 0 0\n  outer loop\n");
            for v in t {
                text.push_str(&format!("   vertex {} {} {}\n", v[0], v[1], v[2]));
            }
            text.push_str("  endloop\n endfacet\n");
        }
        text.push_str(&format!("endsolid part{k}\n"));
    }
    std::fs::write(dir.path().join("body.stl"), text).expect("write");
    let urdf = dir.path().join("robot.urdf");
    std::fs::write(&urdf, one_link_urdf(r#"<mesh filename="body.stl"/>"#)).expect("write");
    let model = RobotModel::load(&urdf, &[], &LinkSelection::default()).expect("loads");
    let r = report(&model.links[0]);
    assert_eq!(
        (r.pieces, r.triangles_in, r.repeated_triangles),
        (3, 36, 0),
        "{r:?}"
    );
    let hi = model.links[0]
        .elements
        .iter()
        .map(|e| e.mesh.bounds().1[0])
        .fold(f32::MIN, f32::max);
    assert!((hi - 0.13).abs() < 1e-6, "the third solid ends at x = {hi}");
}

/// The cache files (name, bytes) of `model` built on `threads` threads into an empty cache.
fn cache_files(
    model: &RobotModel,
    options: &BuildOptions,
    threads: usize,
) -> Vec<(String, Vec<u8>)> {
    use ist_monitor::ist::{build_robot, cache::TreeCache};
    let cache_dir = tempfile::tempdir().expect("tempdir");
    let cache = TreeCache::new(cache_dir.path().to_path_buf());
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("pool");
    pool.install(|| build_robot(model, options, Some(&cache), &|_| {}))
        .expect("builds");
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(cache_dir.path())
        .expect("cache")
        .map(|e| {
            let e = e.expect("entry");
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).expect("read"),
            )
        })
        .collect();
    files.sort();
    files
}

/// A face with two square holes that touch at one vertex (the rim passes it twice) and a
/// third hole: the intake's choices do not depend on a hash map's order, so loading it again
/// gives the same mesh, and building it on one and on two threads gives the same cache file,
/// byte for byte.
#[test]
fn an_open_edged_mesh_builds_the_same_bits_on_one_and_two_threads() {
    let mut triangles = grid_box(LO, HI, 4);
    // The +z face is the last 32 triangles, cell (i, j) at 2 (4 i + j); cells (1, 1) and
    // (2, 2) share a corner; cell (0, 3) is apart.
    let face = triangles.len() - 32;
    let cells = [(1, 1), (2, 2), (0, 3)];
    let drop: Vec<usize> = cells
        .iter()
        .flat_map(|&(i, j)| [face + 2 * (4 * i + j), face + 2 * (4 * i + j) + 1])
        .collect();
    let mut k = 0;
    triangles.retain(|_| {
        k += 1;
        !drop.contains(&(k - 1))
    });
    let dir = tempfile::tempdir().expect("tempdir");
    let first = load(dir.path(), &triangles);
    let r = report(&first);
    assert!(r.open_edges >= 12, "{r:?}");
    for _ in 0..6 {
        let again = load(dir.path(), &triangles);
        assert_eq!(report(&again), r);
        assert_eq!(again.elements.len(), first.elements.len());
        for (a, b) in again.elements.iter().zip(&first.elements) {
            assert_eq!(a.mesh.vertices, b.mesh.vertices);
            assert_eq!(a.mesh.triangles, b.mesh.triangles);
        }
    }
    let urdf = dir.path().join("robot.urdf");
    let model = RobotModel::load(&urdf, &[], &LinkSelection::default()).expect("loads");
    let options = small_options(600, 512);
    let files: Vec<Vec<(String, Vec<u8>)>> = [1, 2, 1]
        .iter()
        .map(|&threads| cache_files(&model, &options, threads))
        .collect();
    assert_eq!(files[0].len(), 1);
    assert!(
        files[0] == files[1],
        "1 and 2 threads give different cache files"
    );
    assert!(
        files[0] == files[2],
        "two builds on 1 thread give different cache files"
    );
}

/// A piece of the file that the intake lost (here: taken out of the mesh the tree was built
/// from, as mesh-loader's merge did) is measured by the validation, which bounds h on the file
/// as read: nothing in the tree is wrong, so it is not refused, but its h is that piece's gap,
/// and the validation names the file's triangle and the point that set it.
#[test]
fn a_piece_of_the_file_the_tree_does_not_cover_sets_h_and_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let link = load(dir.path(), &common::box_triangles(LO, HI));
    let tree = build(&link, 300);
    let mut lost = link.clone();
    let far = common::box_triangles([0.3, 0.0, 0.0], [0.35, 0.05, 0.05]);
    let (mut vertices, mut triangles) = (*lost.intake[0].original).clone();
    let first_lost = triangles.len();
    for t in &far {
        let base = vertices.len() as u32;
        vertices.extend_from_slice(t);
        triangles.push([base, base + 1, base + 2]);
    }
    lost.intake[0].original = std::sync::Arc::new((vertices, triangles));
    // A file of two pieces, the second lost (a file the intake took as it was is its packed
    // surface, measured as that).
    lost.intake[0].report.pieces = 2;
    let v = validate_link(&tree, &lost, 1e-6, 0.0).expect("a sound tree is not refused");
    let far_gap = sampled_gap(&tree, &far);
    assert!(far_gap > 0.15, "the lost piece at {far_gap} m");
    // Certified: above every point sampled on the lost piece; measured: within the accuracy
    // (8 × 1e-6 m) of the point it names.
    assert!(
        v.gap_m >= far_gap,
        "h {} below a sampled {far_gap}",
        v.gap_m
    );
    assert!(v.gap_m <= v.file_gap_sampled_m + 8e-6 + 1e-9, "{v:?}");
    assert!(v.elements_gap_m < 0.01 && v.file_gap_m > 0.15, "{v:?}");
    let u = v.uncovered.first().expect("the lost piece is named");
    assert_eq!(v.uncovered.len(), 1);
    assert_eq!(u.element, 0);
    assert!(
        u.triangle >= first_lost,
        "triangle {} of the box",
        u.triangle
    );
    assert!((gap_at(&tree, u.point) - u.gap_m).abs() < 1e-9, "{u:?}");
    assert_eq!(u.gap_m, v.file_gap_sampled_m);
    assert!(u.packed_surface_m >= 0.2 - 1e-6, "{u:?}");
    let mut quality = tree.quality;
    quality.uncovered = Some(*u);
    let text = ist_monitor::ist::describe_uncovered(u, &quality, &lost);
    assert!(
        text.contains("body.stl triangle")
            && text.contains("not in the intake's record")
            && text.contains("outside the link's solid"),
        "{text}"
    );
}

/// The xArm's case: the file holds a triangle the intake drops (a fin of one triangle, its own
/// shell with no volume) whose tip stands outside the box farther from the spheres than the
/// packed surface's h plus the packing's accuracy: a claim the validation disproves by a hair.
/// The link builds (nothing in it is wrong), with the packing of the box alone, and reports the
/// certified h, which the fin's tip sets; the triangle is named; 1 and 2 threads give the same
/// cache file.
#[test]
fn a_claim_disproved_by_a_hair_builds_with_its_certified_h() {
    let dir = tempfile::tempdir().expect("tempdir");
    let box_only = grid_box(LO, HI, 4);
    let link0 = load(dir.path(), &box_only);
    let tree0 = build_with(&link0, 600, 512);
    // The fin's tip above the +z face's centre, where its gap is h + 2 × the packing's
    // accuracy (the estimate is within it of the truth) + 10 µm (xArm: 8.8 µm).
    let options = small_options(600, 512);
    let target = tree0.quality.gap_m + 2.0 * options.gap_tolerance_m as f64 + 1e-5;
    let c = [0.05f64, 0.05, 0.1];
    let above = |p: f64| [c[0], c[1], c[2] + p];
    let (mut lo, mut hi) = (0.0f64, 0.01f64);
    assert!(gap_at(&tree0, above(hi)) > target);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if gap_at(&tree0, above(mid)) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let tip = above(hi).map(|x| x as f32);
    let fin: Tri = [tip, [0.047, 0.05, 0.095], [0.053, 0.05, 0.095]];
    let mut file = box_only.clone();
    file.push(fin);
    let link = load(dir.path(), &file);
    // The intake drops the fin: the packed surface is the box's, bit for bit.
    assert_eq!(link.elements.len(), link0.elements.len());
    for (a, b) in link.elements.iter().zip(&link0.elements) {
        assert_eq!(a.mesh.vertices, b.mesh.vertices);
        assert_eq!(a.mesh.triangles, b.mesh.triangles);
    }
    assert!(!report(&link).clean(), "{:?}", report(&link));
    let tree = build_link(&link, &options).expect("a sound tree is not refused");
    assert_eq!(tree.spheres, tree0.spheres);
    let q = &tree.quality;
    let tip_gap = gap_at(&tree, tip.map(f64::from));
    assert!(
        tip_gap > q.elements_gap_m + options.gap_tolerance_m as f64,
        "the tip ({tip_gap} m) does not disprove the packed surface's h {}",
        q.elements_gap_m
    );
    assert_eq!(q.elements_gap_m, tree0.quality.elements_gap_m);
    assert!(
        q.gap_m >= tip_gap,
        "h {} below the tip's {tip_gap}",
        q.gap_m
    );
    assert!(
        q.gap_m <= q.file_gap_sampled_m + options.gap_tolerance_m as f64 + 1e-9,
        "{q:?}"
    );
    assert!(q.file_gap_m > q.elements_gap_m, "{q:?}");
    let u = q.uncovered.expect("the fin is named");
    assert_eq!((u.element, u.triangle), (0, box_only.len()));
    assert!((gap_at(&tree, u.point) - u.gap_m).abs() < 1e-9, "{u:?}");
    // What the intake did there: the fin is a shell of its own that encloses nothing.
    assert!(
        matches!(
            link.intake[0].fates[box_only.len()],
            TriangleFate::EmptyShell { .. }
        ),
        "{:?}",
        link.intake[0].fates[box_only.len()]
    );
    let text = ist_monitor::ist::describe_uncovered(&u, q, &link);
    assert!(
        text.contains(&format!("body.stl triangle {}", box_only.len()))
            && text.contains("empty shell"),
        "{text}"
    );
    // The same cache file on 1 and 2 threads.
    let urdf = dir.path().join("robot.urdf");
    let model = RobotModel::load(&urdf, &[], &LinkSelection::default()).expect("loads");
    let one = cache_files(&model, &options, 1);
    let two = cache_files(&model, &options, 2);
    assert_eq!(one.len(), 1);
    assert!(one == two, "1 and 2 threads give different cache files");
}
