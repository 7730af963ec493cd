//! Every kind of bad robot description gives an error that names the file, the link and the
//! element, never a panic and never a packing of garbage.

mod common;

use std::path::Path;

use common::{box_triangles, one_link_urdf, write_stl};
use ist_monitor::robot::RobotModel;

/// Loads `urdf` (written into `dir`) and returns the error text.
fn error_of(dir: &Path, urdf: &str) -> String {
    let path = dir.join("robot.urdf");
    std::fs::write(&path, urdf).expect("write");
    match RobotModel::load(&path, &[], &Default::default()) {
        Ok(_) => panic!("loaded a bad robot: {urdf}"),
        Err(e) => e.to_string(),
    }
}

fn assert_names(message: &str, parts: &[&str]) {
    for p in parts {
        assert!(message.contains(p), "'{message}' does not name '{p}'");
    }
}

#[test]
fn missing_mesh() {
    let dir = tempfile::tempdir().expect("tmp");
    let e = error_of(
        dir.path(),
        &one_link_urdf(r#"<mesh filename="absent.stl"/>"#),
    );
    assert_names(
        &e,
        &["body", "collision element 0", "absent.stl", "cannot read"],
    );
}

#[test]
fn malformed_xml() {
    let dir = tempfile::tempdir().expect("tmp");
    let e = error_of(dir.path(), r#"<robot name="t"><link name="a"></robot>"#);
    assert_names(&e, &["malformed URDF", "robot.urdf"]);
}

#[test]
fn malformed_collada() {
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::write(
        dir.path().join("bad.dae"),
        "<COLLADA><library_geometries><geometry>",
    )
    .expect("w");
    let e = error_of(dir.path(), &one_link_urdf(r#"<mesh filename="bad.dae"/>"#));
    assert_names(&e, &["body", "collision element 0", "bad.dae"]);
}

/// A mesh in a format not read (here PLY) names the file and the formats that are; the mesh
/// library's own message printed `{path:?}` literally.
#[test]
fn unsupported_mesh_format() {
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::write(dir.path().join("body.ply"), "ply\n").expect("w");
    let e = error_of(dir.path(), &one_link_urdf(r#"<mesh filename="body.ply"/>"#));
    assert_names(
        &e,
        &[
            "body",
            "collision element 0",
            "body.ply",
            "unsupported mesh format",
        ],
    );
    assert!(!e.contains("{path"), "{e}");
}

/// A surface that cannot be oriented (a Möbius strip) is truly ambiguous: which side is inside?
/// Refused, naming the file and the reason. (Holes, seams, zero-area triangles and shells are
/// taken by the intake: tests/intake.rs.)
#[test]
fn unorientable_mesh() {
    let dir = tempfile::tempdir().expect("tmp");
    let n = 24;
    let edge = |i: usize| {
        let theta = std::f32::consts::TAU * i as f32 / n as f32;
        let (r, w) = (0.1, 0.02);
        let radial = [theta.cos(), theta.sin(), 0.0];
        let d = [
            w * (theta / 2.0).cos() * radial[0],
            w * (theta / 2.0).cos() * radial[1],
            w * (theta / 2.0).sin(),
        ];
        let c = [r * radial[0], r * radial[1], 0.0];
        (
            [c[0] + d[0], c[1] + d[1], c[2] + d[2]],
            [c[0] - d[0], c[1] - d[1], c[2] - d[2]],
        )
    };
    let mut t = Vec::new();
    for i in 0..n {
        let (a0, b0) = edge(i);
        // The half twist: after a full turn the strip's two edges have swapped.
        let (a1, b1) = if i + 1 == n {
            let (a, b) = edge(0);
            (b, a)
        } else {
            edge(i + 1)
        };
        t.push([a0, b0, b1]);
        t.push([a0, b1, a1]);
    }
    write_stl(&dir.path().join("mobius.stl"), &t);
    let e = error_of(
        dir.path(),
        &one_link_urdf(r#"<mesh filename="mobius.stl"/>"#),
    );
    assert_names(
        &e,
        &[
            "body",
            "mobius.stl",
            "encloses nothing",
            "1 shells could not be closed or oriented",
        ],
    );
}

/// Every link that cannot be loaded is named in one error, not the first alone; and a link the
/// selection leaves out is never read, so excluding the broken links loads the rest.
#[test]
fn every_bad_link_in_one_run_and_excluded_links_are_not_read() {
    let dir = tempfile::tempdir().expect("tmp");
    write_stl(
        &dir.path().join("good.stl"),
        &box_triangles([0.0; 3], [0.1; 3]),
    );
    let mut nan = box_triangles([0.0; 3], [0.1; 3]);
    nan[5][1][2] = f32::NAN;
    write_stl(&dir.path().join("nan.stl"), &nan);
    let link = |name: &str, file: &str| {
        format!(
            r#"<link name="{name}"><collision><geometry><mesh filename="{file}"/></geometry></collision></link>"#
        )
    };
    let joint = |child: &str| {
        format!(
            r#"<joint name="j_{child}" type="fixed"><parent link="base"/><child link="{child}"/></joint>"#
        )
    };
    let urdf = format!(
        r#"<robot name="t">{}{}{}{}{}{}</robot>"#,
        link("base", "good.stl"),
        link("absent_one", "absent.stl"),
        link("nan_one", "nan.stl"),
        joint("absent_one"),
        joint("nan_one"),
        ""
    );
    let e = error_of(dir.path(), &urdf);
    assert_names(
        &e,
        &[
            "2 links cannot be loaded",
            "absent_one",
            "absent.stl",
            "nan_one",
            "nan.stl",
            "not finite",
        ],
    );
    let selection = ist_monitor::robot::LinkSelection {
        include: Vec::new(),
        exclude: vec!["absent_one".into(), "nan_one".into()],
        convex_hull: Vec::new(),
    };
    let model = RobotModel::load(&dir.path().join("robot.urdf"), &[], &selection).expect("loads");
    assert_eq!(model.links.len(), 1);
    assert_eq!(model.unloaded_links, ["absent_one", "nan_one"]);
    // The selection still knows the links it left out by name.
    selection.check(&model).expect("names known");
}

#[test]
fn zero_volume_geometry() {
    let dir = tempfile::tempdir().expect("tmp");
    let e = error_of(dir.path(), &one_link_urdf(r#"<box size="0.1 0.1 0"/>"#));
    assert_names(&e, &["body", "collision element 0", "box", "zero volume"]);
    // A closed mesh folded flat: two triangles back to back.
    let flat = [
        [[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.0, 0.1, 0.0]],
        [[0.0, 0.0, 0.0], [0.0, 0.1, 0.0], [0.1, 0.0, 0.0]],
    ];
    write_stl(&dir.path().join("flat.stl"), &flat);
    let e = error_of(dir.path(), &one_link_urdf(r#"<mesh filename="flat.stl"/>"#));
    assert_names(&e, &["body", "flat.stl", "no volume"]);
}

#[test]
fn nan_vertices() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut t = box_triangles([0.0; 3], [0.1; 3]);
    t[5][1][2] = f32::NAN;
    write_stl(&dir.path().join("nan.stl"), &t);
    let e = error_of(dir.path(), &one_link_urdf(r#"<mesh filename="nan.stl"/>"#));
    assert_names(&e, &["body", "nan.stl", "not finite"]);
}

#[test]
fn cycle() {
    let dir = tempfile::tempdir().expect("tmp");
    let e = error_of(
        dir.path(),
        r#"<robot name="t"><link name="a"/><link name="b"/><link name="c"/>
        <joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>
        <joint name="bc" type="fixed"><parent link="b"/><child link="c"/></joint>
        <joint name="cb" type="fixed"><parent link="c"/><child link="b"/></joint></robot>"#,
    );
    assert_names(
        &e,
        &["robot.urdf", "link b has two parent joints", "ab", "cb"],
    );
    let e = error_of(
        dir.path(),
        r#"<robot name="t"><link name="a"/><link name="b"/>
        <joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>
        <joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#,
    );
    assert_names(&e, &["robot.urdf", "cycle"]);
}

#[test]
fn unknown_joint_type() {
    let dir = tempfile::tempdir().expect("tmp");
    let e = error_of(
        dir.path(),
        r#"<robot name="t"><link name="a"/><link name="b"/>
        <joint name="twist" type="helical"><parent link="a"/><child link="b"/></joint></robot>"#,
    );
    assert_names(&e, &["robot.urdf", "joint twist", "helical"]);
}

#[test]
fn good_mesh_with_scale_and_origin_loads_in_the_link_frame() {
    let dir = tempfile::tempdir().expect("tmp");
    write_stl(
        &dir.path().join("cube.stl"),
        &box_triangles([0.0; 3], [1.0; 3]),
    );
    let path = dir.path().join("robot.urdf");
    std::fs::write(
        &path,
        r#"<robot name="t"><link name="body"><collision><origin xyz="1 2 3"/>
        <geometry><mesh filename="cube.stl" scale="0.1 0.2 0.3"/></geometry></collision></link></robot>"#,
    )
    .expect("w");
    let model = RobotModel::load(&path, &[], &Default::default()).expect("loads");
    let mesh = &model.links[0].elements[0].mesh;
    // Vertices are f32 near (1, 2, 3) m: about 1e-7 m each, so 1e-8 m³ on this volume.
    assert!((mesh.volume_m3 - 0.006).abs() < 1e-8, "{}", mesh.volume_m3);
    let (lo, hi) = mesh.bounds();
    assert_eq!(lo, [1.0, 2.0, 3.0]);
    assert!((hi[0] - 1.1).abs() < 1e-6 && (hi[1] - 2.2).abs() < 1e-6 && (hi[2] - 3.3).abs() < 1e-6);
}
