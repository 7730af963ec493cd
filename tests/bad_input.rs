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
    match RobotModel::load(&path, &[]) {
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

#[test]
fn open_mesh() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut t = box_triangles([0.0; 3], [0.1; 3]);
    t.pop();
    write_stl(&dir.path().join("open.stl"), &t);
    let e = error_of(dir.path(), &one_link_urdf(r#"<mesh filename="open.stl"/>"#));
    assert_names(&e, &["body", "open.stl", "not closed", "3 open edges"]);
}

#[test]
fn degenerate_triangles() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut t = box_triangles([0.0; 3], [0.1; 3]);
    t.push([[0.0; 3], [0.05, 0.0, 0.0], [0.1, 0.0, 0.0]]);
    write_stl(&dir.path().join("degenerate.stl"), &t);
    let e = error_of(
        dir.path(),
        &one_link_urdf(r#"<mesh filename="degenerate.stl"/>"#),
    );
    assert_names(
        &e,
        &["body", "degenerate.stl", "1 degenerate", "triangle 12"],
    );
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
    let model = RobotModel::load(&path, &[]).expect("loads");
    let mesh = &model.links[0].elements[0].mesh;
    // Vertices are f32 near (1, 2, 3) m: about 1e-7 m each, so 1e-8 m³ on this volume.
    assert!((mesh.volume_m3 - 0.006).abs() < 1e-8, "{}", mesh.volume_m3);
    let (lo, hi) = mesh.bounds();
    assert_eq!(lo, [1.0, 2.0, 3.0]);
    assert!((hi[0] - 1.1).abs() < 1e-6 && (hi[1] - 2.2).abs() < 1e-6 && (hi[2] - 3.3).abs() < 1e-6);
}
