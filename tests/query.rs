//! The query engine against brute force, on random closed meshes, poses and clouds, and on the
//! stiff and extreme cases (far from the origin, inside and touching points, invalid points,
//! empty clouds, tiny next to huge links, the region of interest, the self-filter).

mod common;

use common::Rng;
use ist_monitor::geometry::{distance_point_mesh, winding_number};
use ist_monitor::ist::{build_link, BuildOptions, IstNode, LinkTree};
use ist_monitor::packing::{InnerSphere, PackingParams};
use ist_monitor::query::gpu::GpuOptions;
use ist_monitor::query::{
    root_from_sensor_via_map, Backend, Engine, Mode, Outcome, QueryLink, QueryOptions, QueryResult,
};
use ist_monitor::robot::mesh::{tessellate_box, tessellate_capsule, ClosedMesh};
use ist_monitor::robot::{CollisionElement, LinkGeometry};
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::sync::Once;

/// The scene generator's own draws, beside the shared `Rng`.
impl Rng {
    fn pose(&mut self, reach: f64) -> Isometry3<f64> {
        let axis = Vector3::new(
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
        );
        let rotation = UnitQuaternion::from_scaled_axis(axis * 3.0);
        Isometry3::from_parts(
            Translation3::new(
                self.range(-reach, reach),
                self.range(-reach, reach),
                self.range(-reach, reach),
            ),
            rotation,
        )
    }
}

/// A closed mesh (a box or a capsule of random size) placed by a random element origin.
fn random_mesh(rng: &mut Rng, scale: f64) -> ClosedMesh {
    let t = if rng.next() < 0.5 {
        tessellate_box([
            scale * rng.range(0.3, 1.0),
            scale * rng.range(0.3, 1.0),
            scale * rng.range(0.3, 1.0),
        ])
    } else {
        tessellate_capsule(scale * rng.range(0.15, 0.4), scale * rng.range(0.2, 1.0))
    };
    let origin = rng.pose(0.2 * scale);
    let vertices = t
        .vertices
        .iter()
        .map(|v| {
            let p = origin * Point3::new(v[0] as f64, v[1] as f64, v[2] as f64);
            [p.x as f32, p.y as f32, p.z as f32]
        })
        .collect();
    ClosedMesh::new(vertices, t.triangles, "test mesh").expect("a closed test mesh")
}

fn geometry(name: &str, mesh: ClosedMesh) -> LinkGeometry {
    LinkGeometry {
        name: name.into(),
        elements: vec![CollisionElement {
            index: 0,
            source: "test".into(),
            mesh,
            tessellation_error_m: 0.0,
            sphere_center: None,
        }],
        intake: Vec::new(),
        hull_of_volume_m3: None,
    }
}

fn small_build(spheres: u32) -> BuildOptions {
    BuildOptions {
        packing: PackingParams {
            max_spheres: spheres,
            prototypes: 512,
            ..PackingParams::default()
        },
        ..BuildOptions::default()
    }
}

/// A robot of `n` random links (trees built with a small budget), their geometry and poses.
struct Scene {
    geometry: Vec<LinkGeometry>,
    trees: Vec<LinkTree>,
    link_poses: Vec<Isometry3<f64>>,
}

impl Scene {
    fn random(rng: &mut Rng, n: usize, spheres: u32) -> Self {
        let geometry: Vec<LinkGeometry> = (0..n)
            .map(|i| {
                let scale = rng.range(0.05, 0.4);
                geometry(&format!("link{i}"), random_mesh(rng, scale))
            })
            .collect();
        let trees = geometry
            .iter()
            .map(|g| build_link(g, &small_build(spheres)).expect("tree"))
            .collect();
        let link_poses = (0..n).map(|_| rng.pose(0.4)).collect();
        Self {
            geometry,
            trees,
            link_poses,
        }
    }

    /// A query with the sensor at the root.
    fn run(&self, engine: &mut Engine, points: &[[f32; 3]], options: &QueryOptions) -> QueryResult {
        run(
            engine,
            points,
            &Isometry3::identity(),
            &self.link_poses,
            options,
        )
    }

    fn engine(&self) -> Engine {
        let links = self
            .trees
            .iter()
            .zip(&self.geometry)
            .enumerate()
            .map(|(i, (t, g))| QueryLink::from_tree(t, Some(g), i))
            .collect();
        let mut engine = Engine::from_links(links, self.trees.len()).expect("engine");
        attach_gpu(&mut engine);
        engine
    }

    /// Brute force in f64: (exact distance to the meshes, distance to the union of the inner
    /// spheres), minimum over points and links.
    fn brute_force(&self, points: &[[f32; 3]], root_from_sensor: &Isometry3<f64>) -> (f64, f64) {
        let mut exact = f64::INFINITY;
        let mut spheres = f64::INFINITY;
        for p in points
            .iter()
            .filter(|p| ist_monitor::query::is_valid_point(**p))
        {
            let root = root_from_sensor * Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            for ((g, t), pose) in self.geometry.iter().zip(&self.trees).zip(&self.link_poses) {
                let q = pose.inverse() * root;
                let q = [q.x, q.y, q.z];
                for e in &g.elements {
                    let m = &e.mesh;
                    let d = if winding_number(q, &m.vertices, &m.triangles) > 0.5 {
                        0.0
                    } else {
                        distance_point_mesh(q, &m.vertices, &m.triangles)
                    };
                    exact = exact.min(d);
                }
                spheres = spheres.min(sphere_distance(&t.spheres, q));
            }
        }
        (exact, spheres)
    }
}

fn sphere_distance(spheres: &[InnerSphere], q: [f64; 3]) -> f64 {
    spheres
        .iter()
        .map(|s| {
            let c = s.center.map(|v| v as f64);
            let d = ((q[0] - c[0]).powi(2) + (q[1] - c[1]).powi(2) + (q[2] - c[2]).powi(2)).sqrt();
            (d - s.radius as f64).max(0.0)
        })
        .fold(f64::INFINITY, f64::min)
}

/// A cloud in the sensor frame: points scattered around the links (root frame), some invalid.
fn cloud(rng: &mut Rng, n: usize, root_from_sensor: &Isometry3<f64>) -> Vec<[f32; 3]> {
    let sensor_from_root = root_from_sensor.inverse();
    (0..n)
        .map(|i| match i % 17 {
            3 => [f32::NAN; 3],
            7 => [0.25, f32::INFINITY, -0.5],
            11 => [0.0; 3],
            // Valid, with two zero coordinates (only all three zero is "no return").
            13 => [0.0, 0.0, rng.range(0.1, 0.9) as f32],
            _ => {
                let p = sensor_from_root
                    * Point3::new(
                        rng.range(-0.9, 0.9),
                        rng.range(-0.9, 0.9),
                        rng.range(-0.9, 0.9),
                    );
                [p.x as f32, p.y as f32, p.z as f32]
            }
        })
        .collect()
}

fn all_points() -> QueryOptions {
    QueryOptions {
        max_distance_m: f32::INFINITY,
        self_filter_padding_m: None,
        ..QueryOptions::default()
    }
}

fn run(
    engine: &mut Engine,
    points: &[[f32; 3]],
    root_from_sensor: &Isometry3<f64>,
    poses: &[Isometry3<f64>],
    options: &QueryOptions,
) -> QueryResult {
    query_both(engine, points, None, root_from_sensor, poses, options).expect("query")
}

/// The GPU's paths, which the tests' engines take in turn, one per engine: both fast paths
/// (64-bit atomics, subgroups) and the portable path (neither), each point descending on its
/// own, then both with the sub-blocks' points descending in packets.
const GPU_PATHS: [GpuOptions; 4] = [
    GpuOptions {
        int64_atomics: true,
        subgroups: true,
        packets: false,
    },
    GpuOptions {
        int64_atomics: false,
        subgroups: false,
        packets: false,
    },
    GpuOptions {
        int64_atomics: true,
        subgroups: true,
        packets: true,
    },
    GpuOptions {
        int64_atomics: false,
        subgroups: false,
        packets: true,
    },
];

/// Gives `engine` the next of [`GPU_PATHS`] where there is a GPU adapter (lavapipe in CI, where
/// one must be): every query of the tests then runs on both backends ([`query_both`]).
fn attach_gpu(engine: &mut Engine) {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    static SAID: Once = Once::new();
    let path = GPU_PATHS[NEXT.fetch_add(1, Relaxed) % GPU_PATHS.len()];
    if engine.gpu_with(path).is_none() {
        if std::env::var_os("CI").is_some() {
            panic!("CI is set but no GPU adapter (lavapipe: mesa-vulkan-drivers) was found");
        }
        SAID.call_once(|| common::skip("no GPU adapter: the queries are checked on the CPU only"));
    }
}

/// `query_image` on the CPU and, where the engine has a GPU, on the GPU, which must answer as the
/// CPU does ([`assert_gpu_agrees`]; or fail with the same error); the CPU's answer.
fn query_both(
    engine: &mut Engine,
    points: &[[f32; 3]],
    width: Option<usize>,
    root_from_sensor: &Isometry3<f64>,
    poses: &[Isometry3<f64>],
    options: &QueryOptions,
) -> Result<QueryResult, ist_monitor::query::QueryError> {
    let on = |backend| QueryOptions {
        backend,
        ..options.clone()
    };
    let cpu = engine.query_image(points, width, root_from_sensor, poses, &on(Backend::Cpu));
    let Some(gpu) = engine.gpu() else {
        return cpu;
    };
    let path = format!("{:?} {:?} packets {}", gpu.minima, gpu.reduce, gpu.packets);
    let gpu = engine.query_image(points, width, root_from_sensor, poses, &on(Backend::Gpu));
    let what = format!(
        "{:?} per_link {} width {width:?} {path}",
        options.mode, options.per_link
    );
    match (&cpu, &gpu) {
        (Ok(c), Ok(g)) => assert_gpu_agrees(&what, c, g),
        (Err(c), Err(g)) => assert_eq!(c.to_string(), g.to_string(), "{what}"),
        (c, g) => panic!("{what}: CPU {c:?}, GPU {g:?}"),
    }
    cpu
}

/// The GPU's answer is the CPU's: the same outcome, distances and bounds within 1e-5 m (the two
/// walk the same posed arrays; only the rounding of the square root differs, a few ulps), the
/// same nearest link, the counts that do not depend on the bounds' history equal, and every
/// point in one stage.
fn assert_gpu_agrees(what: &str, cpu: &QueryResult, gpu: &QueryResult) {
    assert_eq!(
        (cpu.backend, gpu.backend),
        (Backend::Cpu, Backend::Gpu),
        "{what}"
    );
    assert_eq!(cpu.outcome, gpu.outcome, "{what}");
    // (Equal also where both are +∞: a link with nothing measured.)
    let close = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(a), Some(b)) => a == b || (a - b).abs() <= 1e-5,
        (a, b) => a == b,
    };
    let (c, g) = (cpu.nearest.as_ref(), gpu.nearest.as_ref());
    assert!(
        close(c.map(|n| n.distance_m), g.map(|n| n.distance_m)),
        "{what}: {c:?} {g:?}"
    );
    assert!(
        close(c.and_then(|n| n.lower_m), g.and_then(|n| n.lower_m)),
        "{what}: {c:?} {g:?}"
    );
    assert_eq!(cpu.links.len(), gpu.links.len(), "{what}");
    for (a, b) in cpu.links.iter().zip(&gpu.links) {
        assert!(
            close(a.distance_m, b.distance_m),
            "{what} {}: {a:?} {b:?}",
            a.link
        );
        assert!(
            close(a.lower_m, b.lower_m),
            "{what} {}: {a:?} {b:?}",
            a.link
        );
        assert!(
            close(a.exact_m, b.exact_m),
            "{what} {}: {a:?} {b:?}",
            a.link
        );
    }
    let (cc, gc) = (cpu.counts, gpu.counts);
    assert_eq!(
        (cc.total, cc.invalid, cc.outside_roi, cc.self_filtered),
        (gc.total, gc.invalid, gc.outside_roi, gc.self_filtered),
        "{what}"
    );
    assert_eq!(
        gc.pruned + gc.evaluated + gc.invalid + gc.outside_roi + gc.self_filtered,
        gc.total,
        "{what}"
    );
}

fn distance(r: &QueryResult) -> f64 {
    r.nearest.as_ref().expect("a nearest point").distance_m
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 10, .. ProptestConfig::default() })]

    /// lower ≤ exact ≤ upper; exact mode = brute-force point–triangle minimum within 1e-5 m;
    /// fast mode = brute-force scan over all spheres (1e-5 m: f32 transforms of f64 poses).
    #[test]
    fn modes_against_brute_force(seed in 1u64.., links in 1usize..4, per_link: bool) {
        let mut rng = Rng(seed);
        let scene = Scene::random(&mut rng, links, 96);
        let mut engine = scene.engine();
        let root_from_sensor = rng.pose(1.0);
        let points = cloud(&mut rng, 400, &root_from_sensor);
        let (exact, spheres) = scene.brute_force(&points, &root_from_sensor);
        let options = |mode| QueryOptions { mode, per_link, ..all_points() };
        let poses = &scene.link_poses;
        let fast = run(&mut engine, &points, &root_from_sensor, poses, &options(Mode::Fast));
        prop_assert!((distance(&fast) - spheres).abs() < 1e-5, "fast {} brute force {spheres}", distance(&fast));
        let certified = run(&mut engine, &points, &root_from_sensor, poses, &options(Mode::Certified));
        let n = certified.nearest.as_ref().unwrap();
        let lower = n.lower_m.unwrap();
        prop_assert!(lower <= exact + 1e-5 && exact <= n.distance_m + 1e-5,
            "certified [{lower}, {}] does not hold exact {exact}", n.distance_m);
        let e = run(&mut engine, &points, &root_from_sensor, poses, &options(Mode::Exact));
        prop_assert!((distance(&e) - exact).abs() < 1e-5, "exact mode {} brute force {exact}", distance(&e));
        // The counts add up: every point is in exactly one stage.
        let c = e.counts;
        prop_assert_eq!(c.total, points.len() as u64);
        prop_assert_eq!(c.invalid + c.outside_roi + c.self_filtered + c.pruned + c.evaluated, c.total);
        prop_assert_eq!(c.invalid, points.iter().filter(|p| !ist_monitor::query::is_valid_point(**p)).count() as u64);
    }

    /// Per-link minima within `per_link_range_m`: every link is either measured, with the
    /// brute-force minimum of its inner-sphere distance, or reported as farther than a bound
    /// that the brute-force minimum does exceed, with a lower bound that holds for the exact
    /// distance; the nearest link is always measured, and the global answer is the one without
    /// per-link minima. The same with a range of each link's own (`link_ranges_m`) below it.
    #[test]
    fn per_link_range_against_brute_force(
        seed in 1u64..,
        links in 2usize..5,
        range in prop::sample::select(vec![0.0f32, 0.05, 0.2, f32::INFINITY]),
        mode in prop::sample::select(vec![Mode::Fast, Mode::Certified, Mode::Exact]),
        own in any::<bool>(),
    ) {
        let mut rng = Rng(seed);
        let scene = Scene::random(&mut rng, links, 96);
        let mut engine = scene.engine();
        let points = cloud(&mut rng, 600, &Isometry3::identity());
        let ranges = [0.0f32, 0.02, 0.05, 0.2, f32::INFINITY];
        let link_ranges_m = (0..links)
            .filter(|_| own)
            .map(|_| ranges[(rng.next() * ranges.len() as f64) as usize % ranges.len()])
            .collect();
        let options = QueryOptions { mode, per_link: true, per_link_range_m: range, link_ranges_m, ..all_points() };
        let r = scene.run(&mut engine, &points, &options);
        let global = scene.run(&mut engine, &points, &QueryOptions { per_link: false, ..options.clone() });
        prop_assert!((distance(&r) - distance(&global)).abs() < 1e-6);
        let nearest = &r.nearest.as_ref().unwrap().link;
        for (l, got) in r.links.iter().enumerate() {
            let one = Scene {
                geometry: vec![scene.geometry[l].clone()],
                trees: vec![scene.trees[l].clone()],
                link_poses: vec![scene.link_poses[l]],
            };
            let (exact, spheres) = one.brute_force(&points, &Isometry3::identity());
            match (got.distance_m, got.farther_than_m) {
                (Some(d), None) => prop_assert!((d - spheres).abs() < 1e-5,
                    "{}: measured {d}, brute force {spheres}", got.link),
                (None, Some(t)) => {
                    prop_assert!(&got.link != nearest, "the nearest link {nearest} was not measured");
                    prop_assert!(t <= spheres + 1e-5, "{}: farther than {t}, brute force {spheres}", got.link);
                    let range = options.link_range(l);
                    if range.is_finite() {
                        prop_assert!(spheres + 1e-5 >= f64::from(range).min(distance(&global)),
                            "{}: not measured at {spheres} m, below the range {range}", got.link);
                    }
                }
                other => prop_assert!(false, "{}: {other:?}", got.link),
            }
            if let Some(lower) = got.lower_m {
                prop_assert!(lower <= exact + 1e-5, "{}: lower {lower} above exact {exact}", got.link);
            }
        }
    }

    /// An organized cloud taken in tiles of 8 × 4 pixels (any width, also ones that leave
    /// partial tiles) gives the brute-force answer, the answer of the same points taken in runs,
    /// and the same per-link minima and counts.
    #[test]
    fn tiles_as_runs_and_brute_force(
        seed in 1u64..,
        width in prop::sample::select(vec![8usize, 13, 40, 61]),
        rows in 1usize..40,
        per_link: bool,
    ) {
        let mut rng = Rng(seed);
        let scene = Scene::random(&mut rng, 3, 64);
        let mut engine = scene.engine();
        let points = cloud(&mut rng, width * rows, &Isometry3::identity());
        let (exact, spheres) = scene.brute_force(&points, &Isometry3::identity());
        for mode in [Mode::Fast, Mode::Certified, Mode::Exact] {
            let options = QueryOptions { mode, per_link, self_filter_padding_m: Some(0.01), ..all_points() };
            let id = Isometry3::identity();
            let tiles = query_both(&mut engine, &points, Some(width), &id, &scene.link_poses, &options).unwrap();
            let runs = query_both(&mut engine, &points, None, &id, &scene.link_poses, &options).unwrap();
            let (t, r) = (tiles.nearest.as_ref(), runs.nearest.as_ref());
            prop_assert_eq!(t.map(|n| n.distance_m), r.map(|n| n.distance_m));
            prop_assert_eq!(t.map(|n| n.point_index), r.map(|n| n.point_index));
            prop_assert_eq!(&tiles.links, &runs.links);
            let (ct, cr) = (tiles.counts, runs.counts);
            prop_assert_eq!((ct.total, ct.invalid, ct.outside_roi, ct.self_filtered), (cr.total, cr.invalid, cr.outside_roi, cr.self_filtered));
            prop_assert_eq!(ct.invalid + ct.outside_roi + ct.self_filtered + ct.pruned + ct.evaluated, ct.total);
            if ct.self_filtered == 0 {
                let d = t.unwrap().distance_m;
                match mode {
                    Mode::Exact => prop_assert!((d - exact).abs() < 1e-5, "{d} against {exact}"),
                    _ => prop_assert!((d - spheres).abs() < 1e-5, "{d} against {spheres}"),
                }
            }
        }
    }

    /// A cloud of small patches (blocks of 32 points a few mm across, the coherence of a depth
    /// image, so that whole blocks are culled by their boxes), many just beyond the inner
    /// sphere farthest from each link's root centre, where a link's reach is largest: the
    /// brute-force answer in every mode, with and without per-link minima.
    #[test]
    fn coherent_blocks_against_brute_force(seed in 1u64.., links in 1usize..4, per_link: bool) {
        let mut rng = Rng(seed);
        let scene = Scene::random(&mut rng, links, 64);
        let mut engine = scene.engine();
        // Per link, the inner spheres farthest from the root centre (root frame) and the way out.
        let mut ends = Vec::new();
        for (t, pose) in scene.trees.iter().zip(&scene.link_poses) {
            let root = t.nodes[0].center.map(f64::from);
            let mut far: Vec<&InnerSphere> = t.spheres.iter().collect();
            let reach = |s: &InnerSphere| {
                let c = s.center.map(f64::from);
                ((c[0] - root[0]).powi(2) + (c[1] - root[1]).powi(2) + (c[2] - root[2]).powi(2)).sqrt()
                    + f64::from(s.radius)
            };
            far.sort_by(|a, b| reach(b).total_cmp(&reach(a)));
            for s in far.iter().take(3) {
                let c = s.center.map(f64::from);
                let out = Vector3::new(c[0] - root[0], c[1] - root[1], c[2] - root[2])
                    .try_normalize(1e-9).unwrap_or(Vector3::x());
                let at = Point3::new(c[0], c[1], c[2]) + out * f64::from(s.radius);
                ends.push((pose * at, pose * out));
            }
        }
        let mut points = Vec::new();
        for b in 0..48 {
            let centre = if b % 3 == 2 || ends.is_empty() {
                Point3::new(rng.range(-0.9, 0.9), rng.range(-0.9, 0.9), rng.range(-0.9, 0.9))
            } else {
                let (at, out) = ends[(rng.next() * ends.len() as f64) as usize % ends.len()];
                at + out * rng.range(0.002, 0.06)
            };
            for _ in 0..32 {
                let q = centre + Vector3::new(rng.range(-0.004, 0.004), rng.range(-0.004, 0.004), rng.range(-0.004, 0.004));
                points.push([q.x as f32, q.y as f32, q.z as f32]);
            }
        }
        let (exact, spheres) = scene.brute_force(&points, &Isometry3::identity());
        for mode in [Mode::Fast, Mode::Certified, Mode::Exact] {
            let options = QueryOptions { mode, per_link, ..all_points() };
            let r = scene.run(&mut engine, &points, &options);
            let d = distance(&r);
            match mode {
                Mode::Exact => prop_assert!((d - exact).abs() < 1e-5, "exact {d} against {exact}"),
                Mode::Fast => prop_assert!((d - spheres).abs() < 1e-5, "fast {d} against {spheres}"),
                Mode::Certified => {
                    let lower = r.nearest.as_ref().unwrap().lower_m.unwrap();
                    prop_assert!((d - spheres).abs() < 1e-5 && lower <= exact + 1e-5,
                        "certified [{lower}, {d}] against {exact}, spheres {spheres}");
                }
            }
        }
    }

    /// A cloud whose points repeat (runs of one point over many blocks, and points repeated
    /// inside blocks) gives the answer of the same cloud without the repeats, in every mode,
    /// with the counts of every copy; exact mode refines each repeated point once.
    #[test]
    fn repeated_points_as_the_cloud_without_them(
        seed in 1u64..,
        copies in prop::sample::select(vec![2usize, 7, 40, 1000]),
        per_link: bool,
    ) {
        let mut rng = Rng(seed);
        let scene = Scene::random(&mut rng, 2, 64);
        let mut engine = scene.engine();
        let base = cloud(&mut rng, 50, &Isometry3::identity());
        let repeated: Vec<[f32; 3]> = base.iter().flat_map(|&p| std::iter::repeat_n(p, copies)).collect();
        for mode in [Mode::Fast, Mode::Certified, Mode::Exact] {
            let options = QueryOptions { mode, per_link, ..all_points() };
            let a = scene.run(&mut engine, &base, &options);
            let b = scene.run(&mut engine, &repeated, &options);
            prop_assert_eq!(distance(&a), distance(&b));
            prop_assert_eq!(&a.nearest.as_ref().unwrap().link, &b.nearest.as_ref().unwrap().link);
            // The point reported is a copy of the one reported without repeats. Not always the
            // first copy: seed 11244317603350105082 (regressions file; fast, per-link) reports
            // copy 1024 of copies 1000–1039, at the same distance and link, even on one thread;
            // why the first copy's record loses the tie is not pinned down yet.
            prop_assert_eq!(b.nearest.as_ref().unwrap().point_index as usize / copies,
                a.nearest.as_ref().unwrap().point_index as usize, "{:?}: {:?} {:?}", mode, a.nearest, b.nearest);
            let (ca, cb) = (a.counts, b.counts);
            prop_assert_eq!(cb.total, ca.total * copies as u64);
            prop_assert_eq!(cb.invalid, ca.invalid * copies as u64);
            prop_assert_eq!(cb.invalid + cb.outside_roi + cb.self_filtered + cb.pruned + cb.evaluated, cb.total);
            if mode == Mode::Exact {
                prop_assert!(cb.exact_refined <= ca.exact_refined.max(1) * 2,
                    "{} refinements for {} without repeats", cb.exact_refined, ca.exact_refined);
            }
        }
    }

    /// The self-filter (each link's grid settles the points in cells wholly within or wholly
    /// beyond the padding, a descent the points in the cells across it) filters exactly the
    /// points that lie within the padding of an inner sphere: never one farther.
    #[test]
    fn self_filter_takes_exactly_the_points_within_the_padding(seed in 1u64.., padding in 0.005f32..0.05) {
        let mut rng = Rng(seed);
        let scene = Scene::random(&mut rng, 2, 64);
        let mut engine = scene.engine();
        // Runs of points along a line through the surface of every 7th inner sphere, 1 cm
        // apart (coherent, like image rows), in the root frame (the sensor's).
        let mut points = Vec::new();
        for (t, pose) in scene.trees.iter().zip(&scene.link_poses) {
            for s in t.spheres.iter().step_by(7) {
                let c = pose * Point3::new(s.center[0] as f64, s.center[1] as f64, s.center[2] as f64);
                let dir = Vector3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0))
                    .try_normalize(1e-9).unwrap_or(Vector3::x());
                for k in 0..12 {
                    let q = c + dir * (f64::from(s.radius) + 0.005 * k as f64 - 0.01);
                    points.push([q.x as f32, q.y as f32, q.z as f32]);
                }
            }
        }
        let options = QueryOptions { mode: Mode::Fast, self_filter_padding_m: Some(padding), ..all_points() };
        let r = scene.run(&mut engine, &points, &options);
        let (mut within, mut borderline) = (0u64, 0u64);
        for p in &points {
            let root = Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let d = scene.trees.iter().zip(&scene.link_poses).map(|(t, pose)| {
                let q = pose.inverse() * root;
                sphere_distance(&t.spheres, [q.x, q.y, q.z])
            }).fold(f64::INFINITY, f64::min);
            // Within 1e-5 m of the padding a point may go either way (f32 transforms).
            if (d - f64::from(padding)).abs() < 1e-5 {
                borderline += 1;
            } else if d < f64::from(padding) {
                within += 1;
            }
        }
        prop_assert!(r.counts.self_filtered >= within && r.counts.self_filtered <= within + borderline,
            "{} self-filtered, {within} within the padding (+{borderline} borderline)", r.counts.self_filtered);
    }

    /// The same scene 10 km and 1000 km from the map origin gives the same answer (1e-4 m):
    /// poses are composed in f64 before anything is rounded.
    #[test]
    fn far_from_origin(seed in 1u64.., offset in prop::sample::select(vec![1e4, 1e6])) {
        let mut rng = Rng(seed);
        let scene = Scene::random(&mut rng, 2, 64);
        let mut engine = scene.engine();
        let map_from_root = rng.pose(0.0);
        let map_from_sensor = rng.pose(1.0);
        let points = cloud(&mut rng, 300, &root_from_sensor_via_map(&map_from_root, &map_from_sensor));
        let shift = Translation3::new(offset, -0.7 * offset, 0.3 * offset);
        for mode in [Mode::Fast, Mode::Exact] {
            let options = QueryOptions { mode, ..all_points() };
            let near = run(&mut engine, &points, &root_from_sensor_via_map(&map_from_root, &map_from_sensor), &scene.link_poses, &options);
            let far_sensor = root_from_sensor_via_map(&(shift * map_from_root), &(shift * map_from_sensor));
            let far = run(&mut engine, &points, &far_sensor, &scene.link_poses, &options);
            prop_assert!((distance(&near) - distance(&far)).abs() < 1e-4,
                "{mode:?}: {} at the origin, {} at {offset} m", distance(&near), distance(&far));
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// A cloud stored in f32 in a frame far from the robot (a map- or UTM-frame lidar, offsets
    /// 1e2–1e7 m, random rotation and direction): the certified interval and the exact mode hold
    /// the exact f64 distance of the same f32 points, as the sensor-frame query does near the
    /// origin; where the f32 points are spaced more coarsely than 1 cm at the robot (beyond
    /// 131 km) the query is refused, naming the spacing, never answered.
    #[test]
    fn clouds_far_from_their_frames_origin(seed in 1u64.., log_offset in 2.0f64..7.0, per_link: bool) {
        let mut rng = Rng(seed);
        let scene = Scene::random(&mut rng, 2, 64);
        let mut engine = scene.engine();
        let offset = 10f64.powf(log_offset);
        let direction = Vector3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)).normalize();
        let rotation = rng.pose(0.0).rotation;
        let sensor_from_root = Isometry3::from_parts(Translation3::from(direction * offset), rotation);
        let root_from_sensor = sensor_from_root.inverse();
        // Points near the links, rounded to f32 in the far frame: these f32 values are the cloud.
        let points: Vec<[f32; 3]> = cloud(&mut rng, 300, &Isometry3::identity())
            .iter()
            .map(|p| {
                if !ist_monitor::query::is_valid_point(*p) {
                    return *p;
                }
                let q = sensor_from_root * Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
                [q.x as f32, q.y as f32, q.z as f32]
            })
            .collect();
        let largest = points.iter().flatten().filter(|v| v.is_finite()).fold(0f32, |m, v| m.max(v.abs()));
        let spacing = f32::from_bits(largest.to_bits() + 1) - largest;
        let (exact, _) = scene.brute_force(&points, &root_from_sensor);
        for mode in [Mode::Certified, Mode::Exact] {
            let options = QueryOptions { mode, per_link, ..all_points() };
            match query_both(&mut engine, &points, None, &root_from_sensor, &scene.link_poses, &options) {
                Ok(r) => {
                    prop_assert!(r.point_spacing_m <= 0.01, "answered with points {} m apart", r.point_spacing_m);
                    let n = r.nearest.as_ref().expect("a nearest point");
                    let lower = n.lower_m.unwrap();
                    prop_assert!(lower <= exact + 1e-5 && exact <= n.distance_m + 1e-5,
                        "{mode:?} at {offset:.0} m: [{lower}, {}] does not hold the exact {exact}", n.distance_m);
                    if mode == Mode::Exact {
                        prop_assert!((n.distance_m - exact).abs() < 1e-5, "exact {} against {exact} at {offset:.0} m", n.distance_m);
                    }
                    prop_assert_eq!(n.point_sensor, points[n.point_index as usize]);
                }
                Err(e) => {
                    prop_assert!(spacing > 0.005, "refused with points {spacing} m apart at {offset:.0} m: {e}");
                    prop_assert!(e.to_string().contains("m apart where the robot is"), "{e}");
                }
            }
        }
    }
}

/// Every point on the robot with an unbounded region of interest: nothing within
/// max_distance, in every mode and with and without per-link minima (an empty per-link minimum
/// is +∞, which an infinite max_distance once let through to an index past the cloud: a panic).
#[test]
fn every_point_self_filtered_with_an_infinite_max_distance() {
    let scene = box_scene();
    let mut engine = scene.engine();
    let inside = vec![[0.0, 0.0, 0.01], [0.05, -0.03, 0.02]];
    for mode in [Mode::Fast, Mode::Certified, Mode::Exact] {
        for per_link in [false, true] {
            let options = QueryOptions {
                mode,
                per_link,
                self_filter_padding_m: Some(0.01),
                max_distance_m: f32::INFINITY,
                ..QueryOptions::default()
            };
            let r = scene.run(&mut engine, &inside, &options);
            assert_eq!(r.outcome, Outcome::NothingWithinMaxDistance, "{mode:?}");
            assert!(r.nearest.is_none());
            assert_eq!(r.counts.self_filtered, 2);
            for l in &r.links {
                assert_eq!(l.distance_m, None);
            }
        }
    }
}

/// One box link 0.2 m × 0.2 m × 0.2 m at the origin, 256 spheres.
fn box_scene() -> Scene {
    let t = tessellate_box([0.2, 0.2, 0.2]);
    let mesh = ClosedMesh::new(t.vertices, t.triangles, "box").unwrap();
    let g = geometry("box", mesh);
    let tree = build_link(&g, &small_build(256)).unwrap();
    Scene {
        geometry: vec![g],
        trees: vec![tree],
        link_poses: vec![Isometry3::identity()],
    }
}

/// Inside points give 0 and count as inside, never a negative value; a point 1e-7 m outside a
/// face reads 1e-7 m in exact mode (within f32 resolution at 0.1 m, 1e-8 m) and at most h + 1e-7
/// in fast mode.
#[test]
fn inside_and_touching_points() {
    let scene = box_scene();
    let mut engine = scene.engine();
    let h = scene.trees[0].quality.gap_m;
    let inside = vec![[0.0, 0.0, 0.01], [0.05, -0.03, 0.02], [0.099, 0.0, 0.0]];
    for mode in [Mode::Fast, Mode::Certified, Mode::Exact] {
        let r = scene.run(
            &mut engine,
            &inside,
            &QueryOptions {
                mode,
                ..all_points()
            },
        );
        assert_eq!(distance(&r), 0.0, "{mode:?}");
        assert!(r.nearest.as_ref().unwrap().lower_m.unwrap_or(0.0) == 0.0);
    }
    // Deep inside points lie in an inner sphere: counted inside in every mode.
    let r = scene.run(&mut engine, &inside[..1], &all_points());
    assert_eq!(r.counts.inside, 1);
    // The point just under the face is inside the mesh: exact mode counts it.
    let r = scene.run(
        &mut engine,
        &inside,
        &QueryOptions {
            mode: Mode::Exact,
            ..all_points()
        },
    );
    assert_eq!(r.counts.inside, 3);

    let touching = vec![[0.1 + 1e-7, 0.0123, -0.0456]];
    let e = scene.run(
        &mut engine,
        &touching,
        &QueryOptions {
            mode: Mode::Exact,
            ..all_points()
        },
    );
    let d = distance(&e);
    assert!(d >= 0.0 && (d - 1e-7).abs() < 2e-8, "exact {d}");
    let f = scene.run(&mut engine, &touching, &all_points());
    assert!(
        distance(&f) >= d && distance(&f) <= h + 1e-6,
        "fast {} h {h}",
        distance(&f)
    );
}

/// NaN, infinite and (0, 0, 0) points are skipped and counted; a cloud without valid points, or
/// without points, says so instead of reporting 0 or +∞ as a distance.
#[test]
fn invalid_and_empty_clouds() {
    let scene = box_scene();
    let mut engine = scene.engine();
    let bad = vec![
        [f32::NAN, 0.0, 0.0],
        [0.0, f32::INFINITY, 0.0],
        [0.0, 0.0, f32::NEG_INFINITY],
        [0.0, 0.0, 0.0],
        [f32::NAN; 3],
    ];
    for points in [&bad[..], &[]] {
        let r = scene.run(&mut engine, points, &QueryOptions::default());
        assert_eq!(r.outcome, Outcome::NoPoints);
        assert!(r.nearest.is_none());
        assert_eq!(r.counts.invalid, points.len() as u64);
    }
    let mut mixed = bad.clone();
    mixed.push([0.5, 0.0, 0.0]);
    let r = scene.run(&mut engine, &mixed, &all_points());
    assert_eq!(r.outcome, Outcome::Nearest);
    assert_eq!(r.counts.invalid, 5);
    assert_eq!(r.nearest.unwrap().point_index, 5);
    // Bad options are refused.
    for options in [
        QueryOptions {
            max_distance_m: f32::NAN,
            ..QueryOptions::default()
        },
        QueryOptions {
            self_filter_padding_m: Some(-0.1),
            ..QueryOptions::default()
        },
    ] {
        assert!(engine
            .query(&mixed, &Isometry3::identity(), &scene.link_poses, &options)
            .is_err());
    }
    // A non-finite sensor pose is refused.
    let mut nan_pose = Isometry3::identity();
    nan_pose.translation.x = f64::NAN;
    assert!(engine
        .query(
            &mixed,
            &nan_pose,
            &scene.link_poses,
            &QueryOptions::default()
        )
        .is_err());
}

/// A 1 mm link next to a 10 m link (spheres 1e4 apart in size): both answer correctly.
#[test]
fn tiny_next_to_huge() {
    let tiny_t = tessellate_box([0.001, 0.001, 0.001]);
    let huge_t = tessellate_box([10.0, 10.0, 10.0]);
    let tiny = geometry(
        "tiny",
        ClosedMesh::new(tiny_t.vertices, tiny_t.triangles, "tiny").unwrap(),
    );
    let huge = geometry(
        "huge",
        ClosedMesh::new(huge_t.vertices, huge_t.triangles, "huge").unwrap(),
    );
    let options = BuildOptions {
        packing: PackingParams {
            max_spheres: 64,
            prototypes: 256,
            ..PackingParams::default()
        },
        ..BuildOptions::default()
    };
    let trees = vec![
        build_link(&tiny, &options).unwrap(),
        build_link(&huge, &options).unwrap(),
    ];
    let ratio = trees[1]
        .spheres
        .iter()
        .map(|s| s.radius)
        .fold(0.0, f32::max)
        / trees[0]
            .spheres
            .iter()
            .map(|s| s.radius)
            .fold(f32::INFINITY, f32::min);
    assert!(ratio > 1e3, "sphere size ratio {ratio}");
    let scene = Scene {
        geometry: vec![tiny, huge],
        trees,
        link_poses: vec![
            Isometry3::translation(0.0, 0.0, 5.01),
            Isometry3::identity(),
        ],
    };
    let mut engine = scene.engine();
    // 2 mm above the tiny cube's top face (z = 5.0105), 12 mm above the huge one.
    let points = vec![[0.0, 0.0, 5.0125]];
    let e = scene.run(
        &mut engine,
        &points,
        &QueryOptions {
            mode: Mode::Exact,
            ..all_points()
        },
    );
    let n = e.nearest.as_ref().unwrap();
    assert_eq!(n.link, "tiny");
    assert!(
        (n.distance_m - 0.002).abs() < 1e-6,
        "exact {}",
        n.distance_m
    );
    let c = scene.run(
        &mut engine,
        &points,
        &QueryOptions {
            mode: Mode::Certified,
            ..all_points()
        },
    );
    let n = c.nearest.as_ref().unwrap();
    assert!(n.lower_m.unwrap() <= 0.002 + 1e-6 && n.distance_m >= 0.002 - 1e-6);
    let per_link = &c.links;
    assert!(
        per_link[1].lower_m.unwrap() <= 0.0125 + 1e-5,
        "{:?}",
        per_link[1]
    );
}

/// The region of interest, the self-filter and the link selection.
#[test]
fn leave_out_what_does_not_matter() {
    let scene = box_scene();
    let mut engine = scene.engine();
    // On the surface (self), 0.5 m away, and 3 m away.
    let points = vec![[0.1, 0.0, 0.0], [0.6, 0.0, 0.0], [3.1, 0.0, 0.0]];
    let options = QueryOptions {
        max_distance_m: 1.0,
        self_filter_padding_m: Some(0.01),
        ..QueryOptions::default()
    };
    let r = scene.run(&mut engine, &points, &options);
    assert_eq!(r.counts.self_filtered, 1);
    assert_eq!(r.counts.outside_roi, 1);
    let n = r.nearest.unwrap();
    assert_eq!(n.point_index, 1);
    assert!((n.distance_m - 0.5).abs() < 0.003);
    // Nothing within 0.3 m once the robot's own point is filtered.
    let r = scene.run(
        &mut engine,
        &points,
        &QueryOptions {
            max_distance_m: 0.3,
            ..options.clone()
        },
    );
    assert_eq!(r.outcome, Outcome::NothingWithinMaxDistance);
    assert!(r.nearest.is_none());
    // Without the filter the surface point is the nearest, at 0 in exact mode.
    let r = scene.run(
        &mut engine,
        &points,
        &QueryOptions {
            mode: Mode::Exact,
            self_filter_padding_m: None,
            ..options
        },
    );
    assert_eq!(r.nearest.unwrap().point_index, 0);
}

/// A big cloud (2 million points) matches brute force over its points near the robot.
#[test]
fn huge_cloud() {
    let scene = box_scene();
    let mut engine = scene.engine();
    let mut rng = Rng(7);
    let points: Vec<[f32; 3]> = (0..2_000_000)
        .map(|_| {
            [
                rng.range(-3.0, 3.0) as f32,
                rng.range(-3.0, 3.0) as f32,
                rng.range(0.12, 3.0) as f32,
            ]
        })
        .collect();
    let id = Isometry3::<f64>::identity();
    let r = scene.run(
        &mut engine,
        &points,
        &QueryOptions {
            mode: Mode::Exact,
            ..all_points()
        },
    );
    // Every point above the box (z ≥ 0.12): the brute force over the points with z < 0.2 and
    // |x|, |y| < 0.3 suffices, since any other point is farther than the nearest of those.
    let near: Vec<[f32; 3]> = points
        .iter()
        .copied()
        .filter(|p| p[2] < 0.2 && p[0].abs() < 0.3 && p[1].abs() < 0.3)
        .collect();
    assert!(!near.is_empty());
    let (exact, _) = scene.brute_force(&near, &id);
    assert!(
        (distance(&r) - exact).abs() < 1e-5,
        "{} vs {exact}",
        distance(&r)
    );
    assert_eq!(r.counts.total, 2_000_000);
}

/// The GPU backend against the CPU on random scenes (lavapipe in CI): every mode, per-link on
/// and off, with the self-filter and region of interest on, the cloud as runs and as an
/// organized image (tiles), with the minima in 64-bit atomics (where the adapter has them) and
/// in the portable 32-bit path. Distances agree to 1e-5 m: the two walk the same posed arrays
/// and only the rounding of the square root differs (a few ulps); the stage counts that do not
/// depend on the bounds' history agree exactly, and both cut the cloud into the same blocks.
#[test]
fn gpu_agrees_with_cpu() {
    let mut rng = Rng(7);
    for case in 0..6 {
        let scene = Scene::random(&mut rng, 1 + case % 3, 96);
        let mut engine = scene.engine();
        if !common::has_gpu(&mut engine) {
            return;
        }
        let root_from_sensor = rng.pose(1.0);
        let points = cloud(&mut rng, 3000, &root_from_sensor);
        for path in GPU_PATHS {
            let GpuOptions {
                int64_atomics,
                subgroups,
                packets,
            } = path;
            let gpu = engine.gpu_with(path).unwrap();
            let (minima, reduce) = (gpu.minima, gpu.reduce);
            assert_eq!(gpu.packets, packets);
            // CI's lavapipe has both fast paths: they are what is tested there.
            if int64_atomics && subgroups && std::env::var_os("CI").is_some() {
                use ist_monitor::query::layout::{Minima, Reduce};
                assert_eq!((minima, reduce), (Minima::Packed64, Reduce::Subgroups));
            }
            for (mode, per_link, width) in [Mode::Fast, Mode::Certified, Mode::Exact]
                .into_iter()
                .flat_map(|m| [(m, false), (m, true)])
                .flat_map(|(m, p)| [(m, p, None), (m, p, Some(50))])
            {
                let options = |backend| QueryOptions {
                    mode,
                    per_link,
                    backend,
                    max_distance_m: 0.5,
                    self_filter_padding_m: Some(0.01),
                    ..QueryOptions::default()
                };
                let poses = &scene.link_poses;
                let mut query = |backend| {
                    let r = engine
                        .query_image(&points, width, &root_from_sensor, poses, &options(backend))
                        .expect("query");
                    (r, engine.last_work())
                };
                let (cpu, cpu_work) = query(Backend::Cpu);
                let (gpu, gpu_work) = query(Backend::Gpu);
                let what = format!(
                    "case {case} {mode:?} per_link {per_link} width {width:?} {minima:?} {reduce:?} packets {packets}"
                );
                assert_gpu_agrees(&what, &cpu, &gpu);
                assert_eq!(cpu_work.blocks, gpu_work.blocks, "{what}");
                assert!(gpu_work.descents > 0 && cpu_work.descents > 0, "{what}");
            }
        }
    }
}

/// Both engines refuse a tree whose node points past its arrays, has more children than the
/// builder makes (a GPU packet votes on at most BRANCHING children) or has a child before it (a
/// cycle: no descent would end), naming the link (and on the GPU the node), never a panic; the
/// GPU engine before it looks for an adapter (its shader reads the trees without bounds checks).
#[test]
fn both_engines_refuse_a_tree_they_cannot_walk_safely() {
    use ist_monitor::query::gpu::{GpuEngine, GpuError};
    use ist_monitor::query::QueryError;
    let scene = box_scene();
    let link = || QueryLink::from_tree(&scene.trees[0], Some(&scene.geometry[0]), 0);
    let good = link();
    // The last inner node: not the root, so that a child index of 0 comes before it.
    let inner = good
        .nodes
        .iter()
        .rposition(|n| n.children_are_spheres == 0)
        .expect("an inner node");
    assert!(inner > 0, "a tree of more than one level");
    let too_many = ist_monitor::ist::build::BRANCHING as u32 + 1;
    let past = good.nodes.len() as u32;
    type Edit = fn(&mut IstNode, u32);
    let edits: [(&str, Edit, u32); 3] = [
        ("too many children", |n, v| n.child_count = v, too_many),
        ("past the arrays", |n, v| n.first_child = v, past),
        ("a cycle", |n, v| n.first_child = v, 0),
    ];
    for (what, edit, value) in edits {
        let bad = || {
            let mut l = link();
            edit(&mut l.nodes[inner], value);
            l
        };
        match GpuEngine::new(&[bad()], GpuOptions::default()) {
            Err(GpuError::BadTree { link, node }) => {
                assert_eq!((link.as_str(), node), ("box", inner), "{what}")
            }
            Err(e) => panic!("{what}: {e}"),
            Ok(_) => panic!("{what}: the GPU engine took the tree"),
        }
        match Engine::from_links(vec![bad()], 1) {
            Err(QueryError::BadTree(link)) => assert_eq!(link, "box", "{what}"),
            Err(e) => panic!("{what}: {e}"),
            Ok(_) => panic!("{what}: the engine took the tree"),
        }
    }
}

/// The GPU's answers at the other two vector widths lavapipe runs its shaders at
/// (`LP_NATIVE_VECTOR_WIDTH` 128 and 512: subgroups of four and sixteen; this file runs at
/// lavapipe's own, 256: eight): this file's GPU test (random scenes in every mode, as runs and as
/// tiles, on every path) and its property test of every mode against brute force, run again by
/// this test binary with the width set, must pass there too. On a hardware
/// GPU the width changes nothing, and they are not run again.
#[test]
fn gpu_agrees_with_cpu_at_every_lavapipe_width() {
    const WIDTH: &str = "LP_NATIVE_VECTOR_WIDTH";
    let mut engine = box_scene().engine();
    let Some(gpu) = engine.gpu() else {
        return;
    };
    if !gpu.is_software() || std::env::var_os(WIDTH).is_some() {
        return;
    }
    let tests = ["gpu_agrees_with_cpu", "modes_against_brute_force"];
    for width in ["128", "512"] {
        let out = std::process::Command::new(std::env::current_exe().unwrap())
            .arg("--exact")
            .args(tests)
            .env(WIDTH, width)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        let report = || format!("{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
        assert!(out.status.success(), "{WIDTH}={width}:\n{}", report());
        assert!(
            stdout.contains(&format!("test result: ok. {} passed", tests.len())),
            "{WIDTH}={width}:\n{}",
            report()
        );
    }
}

/// A depth image of `width × height` pixels in `encoding` and byte order, each row `pad` bytes
/// longer than its pixels, with depths around a robot ~1.2 m in front of the camera: every
/// 13th pixel no return (0; NaN or, every 26th, +∞ in 32FC1).
fn depth_image(
    rng: &mut Rng,
    (width, height): (u32, u32),
    encoding: ist_monitor::cloud::depth::DepthEncoding,
    big_endian: bool,
    pad: usize,
) -> ist_monitor::msg::Image<'static> {
    use ist_monitor::cloud::depth::DepthEncoding;
    let size = encoding.size();
    let step = width as usize * size + pad;
    let mut data = vec![0u8; step * height as usize];
    for v in 0..height as usize {
        for u in 0..width as usize {
            let k = v * width as usize + u;
            let d = rng.range(0.6, 1.9);
            let at = v * step + u * size;
            let bytes: Vec<u8> = match encoding {
                DepthEncoding::Millimetres16 => {
                    let mm = if k.is_multiple_of(13) {
                        0
                    } else {
                        (d * 1000.0) as u16
                    };
                    if big_endian {
                        mm.to_be_bytes().to_vec()
                    } else {
                        mm.to_le_bytes().to_vec()
                    }
                }
                DepthEncoding::Metres32 => {
                    let m = match k % 26 {
                        0 => f32::INFINITY,
                        13 => f32::NAN,
                        _ => d as f32,
                    };
                    if big_endian {
                        m.to_be_bytes().to_vec()
                    } else {
                        m.to_le_bytes().to_vec()
                    }
                }
            };
            data[at..at + size].copy_from_slice(&bytes);
        }
    }
    ist_monitor::msg::Image {
        header: Default::default(),
        height,
        width,
        encoding: encoding.name().into(),
        is_bigendian: big_endian as u8,
        step: step as u32,
        data: data.into(),
    }
}

/// Depth images unprojected on the GPU (lavapipe in CI) against the CPU's `points_from_depth`:
/// both encodings, both byte orders, rows padded by an odd number of bytes or not, with and
/// without range limits, an odd image size (its bytes not whole words). The GPU's points are
/// the CPU's bit for bit (read back), and the query on them answers as the CPU's query on the
/// CPU's points: the same invalid points, the same distances (1e-5 m), the same nearest point.
#[test]
fn gpu_unprojects_depth_images_as_the_cpu_does() {
    use ist_monitor::cloud::depth::{points_from_depth, DepthEncoding, DepthView, PinholeCamera};
    use ist_monitor::cloud::RangeLimits;
    use ist_monitor::query::Backend;
    let mut rng = Rng(11);
    let scene = Scene::random(&mut rng, 3, 96);
    let mut engine = scene.engine();
    if !common::has_gpu(&mut engine) {
        return;
    }
    let root_from_sensor = Isometry3::translation(0.0, 0.0, -1.2);
    let mut case = 0;
    for encoding in [DepthEncoding::Millimetres16, DepthEncoding::Metres32] {
        for (big_endian, pad, range, size) in [
            (false, 0, None, (64, 48)),
            (true, 3, RangeLimits::new(0.8, Some(1.7)), (63, 47)),
            (false, 1, RangeLimits::new(0.0, Some(1.5)), (65, 33)),
            (true, 0, None, (31, 1)),
        ] {
            case += 1;
            let image = depth_image(&mut rng, size, encoding, big_endian, pad);
            let camera = PinholeCamera {
                width: size.0,
                height: size.1,
                fx: rng.range(40.0, 60.0),
                fy: rng.range(40.0, 60.0),
                cx: rng.range(28.0, 34.0),
                cy: rng.range(20.0, 26.0),
            };
            let view = DepthView::new(&image, &camera, range).unwrap();
            let mut cpu_points = Vec::new();
            points_from_depth(&image, &camera, range, &mut cpu_points).unwrap();
            for mode in [Mode::Certified, Mode::Exact] {
                let what = format!("case {case} {encoding:?} big_endian {big_endian} {mode:?}");
                let options = |backend| QueryOptions {
                    mode,
                    per_link: true,
                    backend,
                    max_distance_m: 1.0,
                    self_filter_padding_m: Some(0.01),
                    ..QueryOptions::default()
                };
                let width = (size.1 > 1).then_some(size.0 as usize);
                let cpu = engine
                    .query_image(
                        &cpu_points,
                        width,
                        &root_from_sensor,
                        &scene.link_poses,
                        &options(Backend::Cpu),
                    )
                    .unwrap();
                let mut left = vec![[1.0f32; 3]];
                let gpu = engine
                    .query_depth(
                        &view,
                        &mut left,
                        &root_from_sensor,
                        &scene.link_poses,
                        &options(Backend::Gpu),
                    )
                    .unwrap();
                assert_eq!(
                    (cpu.backend, gpu.backend),
                    (Backend::Cpu, Backend::Gpu),
                    "{what}"
                );
                // The GPU made the points: none were made on the host.
                assert!(left.is_empty(), "{what}");
                let made = engine.gpu().unwrap().read_points(cpu_points.len()).unwrap();
                for (k, (c, g)) in cpu_points.iter().zip(&made).enumerate() {
                    let same = c
                        .iter()
                        .zip(g)
                        .all(|(a, b)| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
                    assert!(same, "{what}: pixel {k}: CPU {c:?}, GPU {g:?}");
                }
                assert_eq!(cpu.outcome, gpu.outcome, "{what}");
                let (cc, gc) = (cpu.counts, gpu.counts);
                assert_eq!(
                    (cc.total, cc.invalid, cc.outside_roi, cc.self_filtered),
                    (gc.total, gc.invalid, gc.outside_roi, gc.self_filtered),
                    "{what}"
                );
                assert!(cc.invalid > 0 && cc.evaluated > 0, "{what}: {cc:?}");
                let (c, g) = (cpu.nearest.as_ref(), gpu.nearest.as_ref());
                let (c, g) = (c.expect("a nearest point"), g.expect("a nearest point"));
                assert!(
                    (c.distance_m - g.distance_m).abs() <= 1e-5,
                    "{what}: {c:?} {g:?}"
                );
                assert_eq!(c.point_sensor, g.point_sensor, "{what}");
                for (a, b) in cpu.links.iter().zip(&gpu.links) {
                    let close = match (a.distance_m, b.distance_m) {
                        (Some(x), Some(y)) => (x - y).abs() <= 1e-5,
                        (x, y) => x == y,
                    };
                    assert!(close, "{what} {}: {a:?} {b:?}", a.link);
                }
            }
        }
    }
}
