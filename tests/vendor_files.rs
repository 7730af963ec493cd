//! Mesh files as vendors ship them (issue 47, item 4): small files made here, each with one trait
//! of the vendor arms the issue measured (the vendors' own files are not in the repository).
//! Each builds at the default options and passes the validation (`ist::build_link` refuses a
//! tree that fails it); where a trait could change the solid, the test checks the solid too.
//! - one file shared by two links, turned through the joint frames, and a third link that a
//!   mimic joint puts on one of them: packed once, one cache file, each link's tree validated
//!   against its own geometry; a mirror (`scale="-1 1 1"`) is another solid, packed apart;
//! - a millimetre STL with `scale="0.001 0.001 0.001"`: the solid of the metre file;
//! - a binary STL whose 80-byte header starts with `solid`, and extensions in any case;
//! - COLLADA whose data are millimetres under `<unit meter="1">`, fixed by the URDF's scale;
//! - a closed block wound inside out that touches the main shell at one vertex;
//! - two overlapping `<collision>` elements, and a thin closed plate (2 mm) half sunk into a
//!   housing, as a logo is;
//! - all of it in one dual-arm description (mirrored arms sharing files, a mimic-doubled torso,
//!   thin plates on the torso's faces, an inside-out block), also built on 1, 2 and 16 threads.

mod common;

use std::path::Path;

use common::{box_triangles, write_stl};
use ist_monitor::ist::cache::TreeCache;
use ist_monitor::ist::validate::validate_link;
use ist_monitor::ist::{build_links, BuildOptions, LinkTree, Origin};
use ist_monitor::robot::{LinkGeometry, LinkSelection, RobotModel};

type Tri = [[f32; 3]; 3];

/// The defaults' `target_gap`, m.
const TARGET_GAP_M: f64 = 0.0015;

fn load(urdf: &Path) -> RobotModel {
    RobotModel::load(urdf, &[], &LinkSelection::default())
        .unwrap_or_else(|e| panic!("{}: {e}", urdf.display()))
}

/// `urdf` written into `dir` and loaded.
fn load_urdf(dir: &Path, urdf: &str) -> RobotModel {
    let path = dir.join("r.urdf");
    std::fs::write(&path, urdf).expect("write");
    load(&path)
}

/// The one-link robot of `dir`'s `body.stl`.
fn one_body(dir: &Path) -> RobotModel {
    load_urdf(
        dir,
        &common::one_link_urdf(r#"<mesh filename="body.stl"/>"#),
    )
}

/// A robot of two links fixed together, each `(name, the attributes of its <mesh>)`.
fn two_links(dir: &Path, first: (&str, &str), second: (&str, &str)) -> RobotModel {
    let link = |(name, mesh): (&str, &str)| {
        format!(
            r#"<link name="{name}"><collision><geometry><mesh {mesh}/></geometry></collision></link>"#
        )
    };
    load_urdf(
        dir,
        &format!(
            r#"<robot name="r">{}{}<joint name="j" type="fixed"><parent link="{}"/><child link="{}"/></joint></robot>"#,
            link(first),
            link(second),
            first.0,
            second.0
        ),
    )
}

/// Every tree built reaches `target_gap`.
fn assert_at_target(trees: &[(LinkTree, Origin)]) {
    for (tree, _) in trees {
        assert!(
            tree.quality.gap_m <= TARGET_GAP_M,
            "{}: h {} m",
            tree.link,
            tree.quality.gap_m
        );
    }
}

/// Two links' bounds, equal within 1e-7 m.
fn assert_same_bounds(a: &LinkGeometry, b: &LinkGeometry) {
    let (a, b) = (bounds(a), bounds(b));
    assert_close(a.0, b.0, 1e-7, "lower corner");
    assert_close(a.1, b.1, 1e-7, "upper corner");
}

fn link<'a>(model: &'a RobotModel, name: &str) -> &'a LinkGeometry {
    (model.links.iter())
        .find(|l| l.name == name)
        .unwrap_or_else(|| panic!("no link {name}"))
}

/// The link-frame bounds of a link's packed elements.
fn bounds(link: &LinkGeometry) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::MAX; 3];
    let mut hi = [f32::MIN; 3];
    for e in &link.elements {
        for v in &e.mesh.vertices {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
    }
    (lo, hi)
}

fn assert_close(a: [f32; 3], b: [f32; 3], tol: f32, what: &str) {
    for k in 0..3 {
        assert!((a[k] - b[k]).abs() <= tol, "{what}: {a:?} against {b:?}");
    }
}

/// Builds `model`'s links at the default options (through `cache` when given).
fn build(model: &RobotModel, cache: Option<&TreeCache>) -> Vec<(LinkTree, Origin)> {
    build_links(model, &|_| true, &BuildOptions::default(), cache, &|_| {})
        .unwrap_or_else(|e| panic!("{e}"))
}

/// How many of the tree's spheres have their centre in the box `lo`–`hi` (link frame).
fn centres_in(tree: &LinkTree, lo: [f32; 3], hi: [f32; 3]) -> usize {
    (tree.spheres.iter())
        .filter(|s| (0..3).all(|k| lo[k] < s.center[k] && s.center[k] < hi[k]))
        .count()
}

/// One mesh file (`arm.stl`, a box off its link's origin) on four links: `left` and `right`,
/// the second turned by π about z in its joint; `right_b`, put on `right` by a mimic joint;
/// `mirrored`, with `scale="-1 1 1"`.
const SHARED_URDF: &str = r#"<robot name="dual">
  <link name="base"/>
  <link name="left"><collision><geometry><mesh filename="arm.stl"/></geometry></collision></link>
  <link name="right"><collision><geometry><mesh filename="arm.stl"/></geometry></collision></link>
  <link name="right_b"><collision><geometry><mesh filename="arm.stl"/></geometry></collision></link>
  <link name="mirrored"><collision><geometry><mesh filename="arm.stl" scale="-1 1 1"/></geometry></collision></link>
  <joint name="j_left" type="revolute"><parent link="base"/><child link="left"/>
    <origin xyz="0 0.3 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j_right" type="revolute"><parent link="base"/><child link="right"/>
    <origin xyz="0 -0.3 0" rpy="0 0 3.14159265"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j_right_b" type="revolute"><parent link="base"/><child link="right_b"/>
    <origin xyz="0 -0.3 0" rpy="0 0 3.14159265"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/>
    <mimic joint="j_right"/></joint>
  <joint name="j_mirrored" type="fixed"><parent link="base"/><child link="mirrored"/><origin xyz="0.5 0 0"/></joint>
</robot>"#;

/// [`SHARED_URDF`] in `dir`, with its `arm.stl`.
fn shared_robot(dir: &Path) -> RobotModel {
    write_stl(
        &dir.join("arm.stl"),
        &box_triangles([0.01, 0.0, 0.0], [0.07, 0.02, 0.03]),
    );
    load_urdf(dir, SHARED_URDF)
}

#[test]
fn a_shared_file_is_packed_once_and_a_mirror_apart() {
    let dir = tempfile::tempdir().expect("tempdir");
    let model = shared_robot(dir.path());
    let cache = TreeCache::new(dir.path().join("cache"));
    let origins = |trees: &[(LinkTree, Origin)]| -> Vec<(String, Origin)> {
        (trees.iter()).map(|(t, o)| (t.link.clone(), *o)).collect()
    };
    let names = ["left", "right", "right_b", "mirrored"].map(String::from);
    let first = build(&model, Some(&cache));
    assert_eq!(
        origins(&first),
        names
            .iter()
            .cloned()
            .zip([Origin::Built, Origin::Shared, Origin::Shared, Origin::Built])
            .collect::<Vec<_>>()
    );
    let files = std::fs::read_dir(dir.path().join("cache"))
        .expect("cache")
        .count();
    assert_eq!(files, 2, "one cache file per solid");
    // The shared trees are the first's, and each is sound for its own link.
    for (tree, _) in &first {
        let geometry = link(&model, &tree.link);
        let v = validate_link(tree, geometry, 1e-6, 2e-5)
            .unwrap_or_else(|e| panic!("{}: {e}", tree.link));
        assert!(v.gap_m <= TARGET_GAP_M, "{}: h {} m", tree.link, v.gap_m);
    }
    assert_eq!(first[1].0.spheres, first[0].0.spheres);
    assert_eq!(first[2].0.nodes, first[0].0.nodes);
    // The mirror is another solid: its spheres are the left's mirrored in x, not the same.
    let (lo, hi) = bounds(link(&model, "mirrored"));
    assert_close(lo, [-0.07, 0.0, 0.0], 1e-6, "mirrored");
    assert_close(hi, [-0.01, 0.02, 0.03], 1e-6, "mirrored");
    assert!(first[3].0.spheres.iter().all(|s| s.center[0] < 0.0));
    // Again: the solids from the cache, the others shared as before.
    let again = build(&model, Some(&cache));
    assert_eq!(
        origins(&again),
        names
            .iter()
            .cloned()
            .zip([Origin::Cache, Origin::Shared, Origin::Shared, Origin::Cache])
            .collect::<Vec<_>>()
    );
    for ((a, _), (b, _)) in first.iter().zip(&again) {
        assert_eq!(
            (&a.link, &a.spheres, &a.nodes),
            (&b.link, &b.spheres, &b.nodes)
        );
    }
    // A selection of the right arm alone finds the file the left one stored.
    let right_only = build_links(
        &model,
        &|name| name == "right",
        &BuildOptions::default(),
        Some(&cache),
        &|_| {},
    )
    .expect("builds");
    assert_eq!(right_only.len(), 1);
    assert_eq!(right_only[0].1, Origin::Cache);
    assert_eq!(right_only[0].0.link, "right");
}

/// A CAD export in millimetres with the URDF's `scale="0.001 0.001 0.001"` is the metre file's
/// solid, and packs as well.
#[test]
fn a_millimetre_stl_with_the_urdf_scale_is_the_metre_solid() {
    let dir = tempfile::tempdir().expect("tempdir");
    write_stl(
        &dir.path().join("metre.stl"),
        &box_triangles([0.0, 0.0, 0.0], [0.06, 0.04, 0.02]),
    );
    write_stl(
        &dir.path().join("millimetre.stl"),
        &box_triangles([0.0, 0.0, 0.0], [60.0, 40.0, 20.0]),
    );
    let model = two_links(
        dir.path(),
        ("m", r#"filename="metre.stl""#),
        (
            "mm",
            r#"filename="millimetre.stl" scale="0.001 0.001 0.001""#,
        ),
    );
    assert_same_bounds(link(&model, "m"), link(&model, "mm"));
    let trees = build(&model, None);
    assert_at_target(&trees);
    let volume = |t: &LinkTree| t.quality.tree_volume_m3;
    let (a, b) = (volume(&trees[0].0), volume(&trees[1].0));
    assert!((a - b).abs() <= 0.01 * a, "tree volumes {a} and {b} m³");
}

/// A binary STL whose 80-byte header begins with `solid` (some CAD exporters write their
/// part's name there) is read as binary; the extension's case does not matter.
#[test]
fn a_binary_stl_headed_solid_and_extensions_in_any_case() {
    let dir = tempfile::tempdir().expect("tempdir");
    let triangles: Vec<Tri> = box_triangles([0.0; 3], [0.05, 0.03, 0.02]);
    let plain = dir.path().join("plain.stl");
    write_stl(&plain, &triangles);
    let mut bytes = std::fs::read(&plain).expect("read");
    let header = b"solid housing_v3 exported by CAD (binary)";
    bytes[..header.len()].copy_from_slice(header);
    let mut links = String::new();
    let mut joints = String::new();
    for (k, name) in ["headed.stl", "upper.STL", "mixed.Stl"].iter().enumerate() {
        std::fs::write(dir.path().join(name), &bytes).expect("write");
        links.push_str(&format!(
            r#"<link name="l{k}"><collision><geometry><mesh filename="{name}"/></geometry></collision></link>"#
        ));
        if k > 0 {
            joints.push_str(&format!(
                r#"<joint name="j{k}" type="fixed"><parent link="l0"/><child link="l{k}"/></joint>"#
            ));
        }
    }
    let model = load_urdf(
        dir.path(),
        &format!(r#"<robot name="r">{links}{joints}</robot>"#),
    );
    for l in &model.links {
        assert_eq!(l.intake[0].report.triangles_in, 12, "{}", l.name);
        let (lo, hi) = bounds(l);
        assert_close(lo, [0.0; 3], 1e-7, &l.name);
        assert_close(hi, [0.05, 0.03, 0.02], 1e-7, &l.name);
    }
}

/// The five-piece COLLADA of `tests/meshes` with its unit set to `meter="1"` while its data
/// stay millimetres (an exporter's lie), fixed by the URDF's `scale="0.001 0.001 0.001"`: the
/// same solid, to the last bit, as the honest file, node transforms and all.
#[test]
fn collada_in_millimetres_under_a_metre_unit_fixed_by_the_urdf_scale() {
    let dir = tempfile::tempdir().expect("tempdir");
    let honest = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/meshes/five_pieces.dae");
    let text = std::fs::read_to_string(&honest).expect("read");
    let unit = r#"<unit name="millimeter" meter="0.001"/>"#;
    assert!(text.contains(unit));
    std::fs::write(dir.path().join("honest.dae"), &text).expect("write");
    std::fs::write(
        dir.path().join("lying.dae"),
        text.replace(unit, r#"<unit name="meter" meter="1"/>"#),
    )
    .expect("write");
    let model = two_links(
        dir.path(),
        ("honest", r#"filename="honest.dae""#),
        ("lying", r#"filename="lying.dae" scale="0.001 0.001 0.001""#),
    );
    let (h, l) = (link(&model, "honest"), link(&model, "lying"));
    for g in [h, l] {
        let r = &g.intake[0].report;
        assert_eq!((r.pieces, r.triangles_in), (5, 60), "{}: {r:?}", g.name);
    }
    assert_same_bounds(h, l);
    assert_close(
        bounds(h).1,
        [0.16, 0.04, 0.02],
        1e-6,
        "the honest file's extent",
    );
    assert_at_target(&build(&model, None));
}

/// A closed block wound inside out (every normal inward) that touches the main shell at one
/// vertex: a solid of its own, filled and packed, never read as a cavity.
#[test]
fn an_inside_out_block_touching_the_shell_at_one_vertex_is_a_solid() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut triangles = box_triangles([0.0; 3], [0.06; 3]);
    let block: Vec<Tri> = box_triangles([0.06; 3], [0.08; 3])
        .into_iter()
        .map(|[a, b, c]| [a, c, b])
        .collect();
    triangles.extend(block);
    write_stl(&dir.path().join("body.stl"), &triangles);
    let model = one_body(dir.path());
    let trees = build(&model, None);
    assert_at_target(&trees);
    let tree = &trees[0].0;
    assert!(
        centres_in(tree, [0.06; 3], [0.08; 3]) > 0,
        "the block is packed"
    );
    assert!(
        centres_in(tree, [0.0; 3], [0.06; 3]) > 0,
        "the shell is packed"
    );
    let volume = 0.06f64.powi(3) + 0.02f64.powi(3);
    let got = tree.quality.mesh_volume_m3;
    assert!(
        (got - volume).abs() <= 1e-3 * volume,
        "the link's solid is {got} m³, the shell and the block {volume} m³"
    );
}

/// Two overlapping `<collision>` elements on one link, the housing's STL also holding a 2 mm
/// plate half sunk into its top (a logo): every piece packed and validated, h at the target,
/// the plate's part above the housing covered.
#[test]
fn overlapping_collisions_and_a_sunk_thin_plate() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut housing = box_triangles([0.0; 3], [0.08, 0.06, 0.04]);
    housing.extend(box_triangles([0.02, 0.02, 0.039], [0.06, 0.04, 0.041]));
    write_stl(&dir.path().join("housing.stl"), &housing);
    write_stl(
        &dir.path().join("cover.stl"),
        &box_triangles([0.05, 0.01, 0.01], [0.1, 0.05, 0.03]),
    );
    let model = load_urdf(
        dir.path(),
        r#"<robot name="r"><link name="body">
  <collision><geometry><mesh filename="housing.stl"/></geometry></collision>
  <collision><geometry><mesh filename="cover.stl"/></geometry></collision>
</link></robot>"#,
    );
    let trees = build(&model, None);
    assert_at_target(&trees);
    let tree = &trees[0].0;
    assert!(
        centres_in(tree, [0.02, 0.02, 0.04], [0.06, 0.04, 0.041]) > 0,
        "the plate's half above the housing is packed"
    );
    assert!(
        centres_in(tree, [0.08, 0.01, 0.01], [0.1, 0.05, 0.03]) > 0,
        "the cover's part beyond the housing is packed"
    );
}

/// A stray open triangle 0.2 m from the part (an export's leftover): the intake drops it, the
/// validation measures h on the file's own triangles (so h is the stray's distance, certified
/// all the same), and the build warns that this h is absurd, naming the file and the triangle.
#[test]
fn a_stray_triangle_gives_an_absurd_h_that_names_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut triangles = box_triangles([0.0; 3], [0.05, 0.04, 0.03]);
    triangles.push([[0.25, 0.0, 0.0], [0.26, 0.0, 0.0], [0.25, 0.01, 0.0]]);
    write_stl(&dir.path().join("body.stl"), &triangles);
    let model = one_body(dir.path());
    let trees = build(&model, None);
    let (tree, geometry) = (&trees[0].0, &model.links[0]);
    assert!(tree.quality.gap_m > 0.19, "h {} m", tree.quality.gap_m);
    let uncovered = tree.quality.uncovered.expect("the stray is uncovered");
    assert_eq!(uncovered.triangle, 12);
    let warning = ist_monitor::ist::absurd_gap(&tree.quality, geometry).expect("a warning");
    assert!(
        warning.contains("body.stl") && warning.contains("triangle 12"),
        "{warning}"
    );
    // The box alone: no warning.
    write_stl(&dir.path().join("body.stl"), &triangles[..12]);
    let model = one_body(dir.path());
    let trees = build(&model, None);
    assert_eq!(
        ist_monitor::ist::absurd_gap(&trees[0].0.quality, &model.links[0]),
        None
    );
}

/// The shared-file robot above built on 1, 2 and 16 threads: the same cache files, byte for
/// byte.
#[test]
fn shared_files_build_the_same_cache_on_any_thread_count() {
    same_cache_on_any_thread_count(shared_robot, 2);
}

/// The dual-arm description below, every trait of the issue in one robot, built on 1, 2 and 16
/// threads: the same cache files, byte for byte.
#[test]
fn the_dual_arm_description_builds_the_same_cache_on_any_thread_count() {
    same_cache_on_any_thread_count(dual_arm_robot, 3);
}

/// The robot `make` writes, built on 1, 2 and 16 threads: `solids` cache files, the same bytes.
fn same_cache_on_any_thread_count(make: fn(&Path) -> RobotModel, solids: usize) {
    let dir = tempfile::tempdir().expect("tempdir");
    let model = make(dir.path());
    let files = |threads: usize| -> Vec<(std::ffi::OsString, Vec<u8>)> {
        let cache_dir = dir.path().join(format!("cache{threads}"));
        let cache = TreeCache::new(cache_dir.clone());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| build(&model, Some(&cache)));
        let mut files: Vec<_> = std::fs::read_dir(&cache_dir)
            .expect("cache")
            .map(|e| {
                let e = e.expect("entry");
                (e.file_name(), std::fs::read(e.path()).expect("read"))
            })
            .collect();
        files.sort();
        files
    };
    let one = files(1);
    assert_eq!(one.len(), solids);
    assert!(one == files(2), "1 and 2 threads differ");
    assert!(one == files(16), "1 and 16 threads differ");
}

/// A whole dual-arm description in one URDF, with the traits of the issue's dual-arm robot
/// together: a torso housing with closed plates 1.5 and 3 mm thick lying on its faces and a block
/// wound inside out touching it at one vertex; a second torso link that a mimic joint puts on
/// the first; a left and a right arm whose upper arm and forearm files are shared, the right
/// side turned by π about z in its joint frames (mirrored only through the joints). Every link
/// builds at the defaults with h ≤ `target_gap`, each shared solid is packed once (one cache file
/// per solid: torso, upper arm, forearm), and each link's tree is sound for its own geometry.
const DUAL_ARM_URDF: &str = r#"<robot name="dual_arm">
  <link name="base"/>
  <link name="torso"><collision><geometry><mesh filename="torso.stl"/></geometry></collision></link>
  <link name="torso_b"><collision><geometry><mesh filename="torso.stl"/></geometry></collision></link>
  <link name="arm_left_1"><collision><geometry><mesh filename="upper.stl"/></geometry></collision></link>
  <link name="arm_left_2"><collision><geometry><mesh filename="fore.stl"/></geometry></collision></link>
  <link name="arm_right_1"><collision><geometry><mesh filename="upper.stl"/></geometry></collision></link>
  <link name="arm_right_2"><collision><geometry><mesh filename="fore.stl"/></geometry></collision></link>
  <joint name="torso_joint" type="revolute"><parent link="base"/><child link="torso"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="torso_joint_b" type="revolute"><parent link="base"/><child link="torso_b"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/><mimic joint="torso_joint"/></joint>
  <joint name="left_1" type="revolute"><parent link="torso"/><child link="arm_left_1"/>
    <origin xyz="0 0.09 0.14"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="left_2" type="revolute"><parent link="arm_left_1"/><child link="arm_left_2"/>
    <origin xyz="0.1 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="right_1" type="revolute"><parent link="torso"/><child link="arm_right_1"/>
    <origin xyz="0 -0.09 0.14" rpy="0 0 3.14159265"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="right_2" type="revolute"><parent link="arm_right_1"/><child link="arm_right_2"/>
    <origin xyz="0.1 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>"#;

/// [`DUAL_ARM_URDF`] in `dir`, with its three mesh files.
fn dual_arm_robot(dir: &Path) -> RobotModel {
    // The torso: a housing, a 1.5 mm plate on its front face, a 3 mm plate on its side, and a
    // block wound inside out touching the housing's top corner at one vertex.
    let mut torso = box_triangles([-0.04, -0.05, 0.0], [0.04, 0.05, 0.12]);
    torso.extend(box_triangles([0.04, -0.03, 0.02], [0.0415, 0.03, 0.10]));
    torso.extend(box_triangles([-0.03, 0.05, 0.02], [0.03, 0.053, 0.08]));
    torso.extend(
        box_triangles([0.04, 0.05, 0.12], [0.055, 0.065, 0.135])
            .into_iter()
            .map(|[a, b, c]| [a, c, b]),
    );
    write_stl(&dir.join("torso.stl"), &torso);
    // The upper arm: two overlapping closed boxes in one file (an elbow housing over a tube).
    let mut upper = box_triangles([0.0, -0.02, -0.02], [0.1, 0.02, 0.02]);
    upper.extend(box_triangles([0.07, -0.025, -0.025], [0.11, 0.025, 0.025]));
    write_stl(&dir.join("upper.stl"), &upper);
    write_stl(
        &dir.join("fore.stl"),
        &box_triangles([0.0, -0.015, -0.015], [0.09, 0.015, 0.015]),
    );
    load_urdf(dir, DUAL_ARM_URDF)
}

#[test]
fn a_dual_arm_description_builds_at_target_with_each_shared_file_packed_once() {
    let dir = tempfile::tempdir().expect("tempdir");
    let model = dual_arm_robot(dir.path());
    let cache = TreeCache::new(dir.path().join("cache"));
    let trees = build(&model, Some(&cache));
    let origin = |name: &str| {
        (trees.iter())
            .find(|(t, _)| t.link == name)
            .map(|(_, o)| *o)
            .unwrap_or_else(|| panic!("no tree for {name}"))
    };
    for (name, expected) in [
        ("torso", Origin::Built),
        ("torso_b", Origin::Shared),
        ("arm_left_1", Origin::Built),
        ("arm_left_2", Origin::Built),
        ("arm_right_1", Origin::Shared),
        ("arm_right_2", Origin::Shared),
    ] {
        assert_eq!(origin(name), expected, "{name}");
    }
    let files = std::fs::read_dir(dir.path().join("cache"))
        .expect("cache")
        .count();
    assert_eq!(
        files, 3,
        "one cache file per solid: torso, upper arm, forearm"
    );
    assert_at_target(&trees);
    // Each link's tree, shared or not, passes the validation against its own geometry (every
    // sphere inside, no overlap, h bounded). Its bound there may be a little looser than the
    // build's: the branch and bound starts from the claim, which is now the build's h.
    for (tree, _) in &trees {
        let geometry = link(&model, &tree.link);
        let v = validate_link(tree, geometry, 1e-6, 2e-5)
            .unwrap_or_else(|e| panic!("{}: {e}", tree.link));
        println!(
            "{}: {} spheres, h {:.3} mm (validated again: {:.3} mm)",
            tree.link,
            tree.spheres.len(),
            tree.quality.gap_m * 1e3,
            v.gap_m * 1e3
        );
    }
    // The thin plates and the inside-out block are packed, not left to h.
    let torso = &trees
        .iter()
        .find(|(t, _)| t.link == "torso")
        .expect("torso")
        .0;
    for (what, lo, hi) in [
        (
            "the 1.5 mm plate",
            [0.04, -0.03, 0.02],
            [0.0415, 0.03, 0.10],
        ),
        ("the 3 mm plate", [-0.03, 0.05, 0.02], [0.03, 0.053, 0.08]),
        (
            "the inside-out block",
            [0.04, 0.05, 0.12],
            [0.055, 0.065, 0.135],
        ),
    ] {
        assert!(centres_in(torso, lo, hi) > 0, "{what} is packed");
    }
}
