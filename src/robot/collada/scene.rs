//! The COLLADA scene: the document checked, its `<unit meter>` read, and every node reached from
//! `<instance_visual_scene>` walked under the product of its transforms (`<matrix>`,
//! `<translate>`, `<rotate>`, `<scale>`, `<lookat>`, `<skew>`, in document order), each geometry
//! instance handed to `geometry` to be placed. Output: the file's [`MeshFile`], in metres.

use nalgebra::{Matrix4, Rotation3, Unit, Vector3};

use super::geometry::Placed;
use super::xml::{at, child, children, floats, Ids, Node};
use crate::robot::mesh_file::MeshFile;

/// Nesting of `<node>` and `<instance_node>` beyond this is taken for a cycle.
const MAX_DEPTH: usize = 64;

/// Reads a COLLADA document (see the module doc): its pieces are the geometry instances placed.
pub fn read(bytes: &[u8]) -> Result<MeshFile, String> {
    let text = std::str::from_utf8(bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes))
        .map_err(|e| format!("COLLADA file is not UTF-8: {e}"))?;
    let doc = roxmltree::Document::parse(text).map_err(|e| format!("COLLADA XML: {e}"))?;
    let root = doc.root_element();
    if root.tag_name().name() != "COLLADA" {
        return Err(format!(
            "not a COLLADA document (root element <{}>)",
            root.tag_name().name()
        ));
    }
    let ids = Ids::new(&doc);
    let meter = match child(root, "asset")
        .and_then(|a| child(a, "unit"))
        .and_then(|u| u.attribute("meter"))
    {
        Some(m) => m
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|m| m.is_finite() && *m > 0.0)
            .ok_or_else(|| format!("<unit meter=\"{m}\">: not a positive number"))?,
        None => 1.0,
    };
    let mut walk = Scene {
        ids: &ids,
        placed: Placed::default(),
    };
    let scale = Matrix4::new_scaling(meter);
    let scene = child(root, "scene")
        .and_then(|s| child(s, "instance_visual_scene"))
        .map(|i| ids.target(i, "url", "visual_scene"))
        .transpose()?;
    match scene {
        Some(scene) => {
            for node in children(scene, "node") {
                walk.node(node, &scale, 0)?;
            }
        }
        None => {
            walk.placed
                .out
                .notes
                .push("no <scene>: every geometry taken once, untransformed".into());
            for g in doc.descendants().filter(|n| n.has_tag_name("geometry")) {
                walk.placed.place(&ids, g, &scale)?;
            }
        }
    }
    let all = doc
        .descendants()
        .filter(|n| n.has_tag_name("geometry"))
        .count();
    let unused = all - walk.placed.used.len();
    if unused > 0 {
        walk.placed.out.notes.push(format!(
            "{unused} of {all} geometries not instantiated by the scene, left out"
        ));
    }
    if meter != 1.0 {
        walk.placed
            .out
            .notes
            .push(format!("unit {meter} m applied"));
    }
    Ok(walk.placed.out)
}

/// The walk over the scene's nodes.
struct Scene<'d, 'a, 'i> {
    ids: &'d Ids<'a, 'i>,
    placed: Placed<'a>,
}

impl<'a, 'i> Scene<'_, 'a, 'i> {
    /// A scene node: its transform after `parent`, its instances, its child nodes.
    fn node(
        &mut self,
        node: Node<'a, 'i>,
        parent: &Matrix4<f64>,
        depth: usize,
    ) -> Result<(), String> {
        if depth > MAX_DEPTH {
            return Err(format!(
                "{}: nodes nested deeper than {MAX_DEPTH} (a cycle of <instance_node>?)",
                at(node)
            ));
        }
        let mut m = *parent;
        for t in node.children().filter(|c| c.is_element()) {
            m *= match t.tag_name().name() {
                "matrix" => {
                    let v = floats(t, 16)?;
                    Matrix4::from_row_slice(&v)
                }
                "translate" => {
                    let v = floats(t, 3)?;
                    Matrix4::new_translation(&Vector3::new(v[0], v[1], v[2]))
                }
                "scale" => {
                    let v = floats(t, 3)?;
                    Matrix4::new_nonuniform_scaling(&Vector3::new(v[0], v[1], v[2]))
                }
                "rotate" => {
                    let v = floats(t, 4)?;
                    let axis = Vector3::new(v[0], v[1], v[2]);
                    if axis.norm() == 0.0 {
                        if v[3] != 0.0 {
                            return Err(format!("{}: rotation about a zero axis", at(t)));
                        }
                        Matrix4::identity()
                    } else {
                        Rotation3::from_axis_angle(&Unit::new_normalize(axis), v[3].to_radians())
                            .to_homogeneous()
                    }
                }
                "lookat" => {
                    let v = floats(t, 9)?;
                    let eye = nalgebra::Point3::new(v[0], v[1], v[2]);
                    let target = nalgebra::Point3::new(v[3], v[4], v[5]);
                    let up = Vector3::new(v[6], v[7], v[8]);
                    // The camera-to-parent transform: the inverse of a view matrix.
                    Matrix4::look_at_rh(&eye, &target, &up)
                        .try_inverse()
                        .ok_or_else(|| format!("{}: degenerate", at(t)))?
                }
                "skew" => {
                    let v = floats(t, 7)?;
                    skew(v[0].to_radians(), [v[1], v[2], v[3]], [v[4], v[5], v[6]])
                        .ok_or_else(|| format!("{}: degenerate axes", at(t)))?
                }
                _ => continue,
            };
        }
        if m.iter().any(|x| !x.is_finite()) {
            return Err(format!("{}: transform is not finite", at(node)));
        }
        for c in node.children().filter(|c| c.is_element()) {
            match c.tag_name().name() {
                "instance_geometry" => {
                    let g = self.ids.target(c, "url", "geometry")?;
                    self.placed.place(self.ids, g, &m)?;
                }
                "instance_controller" => {
                    let controller = self.ids.target(c, "url", "controller")?;
                    let skin = child(controller, "skin").ok_or_else(|| {
                        format!(
                            "{}: only <skin> controllers are read (not morphs)",
                            at(controller)
                        )
                    })?;
                    let bind = match child(skin, "bind_shape_matrix") {
                        Some(b) => Matrix4::from_row_slice(&floats(b, 16)?),
                        None => Matrix4::identity(),
                    };
                    let g = self.ids.target(skin, "source", "geometry")?;
                    self.placed.out.notes.push(format!(
                        "{}: its skin's bind shape taken (joints not posed)",
                        at(c)
                    ));
                    self.placed.place(self.ids, g, &(m * bind))?;
                }
                "instance_node" => {
                    let n = self.ids.target(c, "url", "node")?;
                    self.node(n, &m, depth + 1)?;
                }
                "node" => self.node(c, &m, depth + 1)?,
                _ => {}
            }
        }
        Ok(())
    }
}

/// COLLADA's `<skew>`: a shear of `angle` along `along` (rotation axis) by `around`.
fn skew(angle: f64, around: [f64; 3], along: [f64; 3]) -> Option<Matrix4<f64>> {
    // As in the COLLADA 1.4 specification (after RenderMan): shear `around` toward `along`.
    let a = Vector3::from(around).try_normalize(0.0)?;
    let b = Vector3::from(along).try_normalize(0.0)?;
    let t = angle.tan();
    let shear = b * a.transpose() * t;
    let mut m = Matrix4::identity();
    m.fixed_view_mut::<3, 3>(0, 0)
        .copy_from(&(nalgebra::Matrix3::identity() + shear));
    Some(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube as one `<geometry>`, `<triangles>` with a normal input at offset 1.
    fn cube(id: &str) -> String {
        // The unit cube [0, 1]³, as the box primitive lays out its vertices and triangles.
        let b = crate::robot::mesh::tessellate_box([1.0; 3]);
        let v: Vec<String> = b
            .vertices
            .iter()
            .flatten()
            .map(|x| format!("{}", x + 0.5))
            .collect();
        let v = v.join(" ");
        let tris = b.triangles;
        let p: Vec<String> = tris.iter().flatten().map(|i| format!("{i} 0")).collect();
        format!(
            r##"<geometry id="{id}"><mesh>
  <source id="{id}-pos"><float_array id="{id}-arr" count="24">{v}</float_array>
    <technique_common><accessor source="#{id}-arr" count="8" stride="3"/></technique_common></source>
  <source id="{id}-n"><float_array id="{id}-narr" count="3">0 0 1</float_array></source>
  <vertices id="{id}-v"><input semantic="POSITION" source="#{id}-pos"/></vertices>
  <triangles count="12"><input semantic="VERTEX" source="#{id}-v" offset="0"/>
    <input semantic="NORMAL" source="#{id}-n" offset="1"/><p>{}</p></triangles>
</mesh></geometry>"##,
            p.join(" ")
        )
    }

    fn document(geometries: &str, nodes: &str, unit: &str) -> String {
        format!(
            r##"<?xml version="1.0"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<asset>{unit}<up_axis>Z_UP</up_axis></asset>
<library_geometries>{geometries}</library_geometries>
<library_visual_scenes><visual_scene id="s">{nodes}</visual_scene></library_visual_scenes>
<scene><instance_visual_scene url="#s"/></scene>
</COLLADA>"##
        )
    }

    #[test]
    fn every_instance_under_its_node_transforms() {
        let geometries: String = (0..5).map(|k| cube(&format!("g{k}"))).collect();
        // Pieces 0-2 at x = 2k by <translate>, 3 by a row-major <matrix>, 4 nested and scaled,
        // and piece 0 a second time through <instance_node>.
        let nodes = r##"
<node id="n0"><translate>0 0 0</translate><instance_geometry url="#g0"/></node>
<node id="n1"><translate>2 0 0</translate><instance_geometry url="#g1"/></node>
<node id="n2"><translate>4 0 0</translate><instance_geometry url="#g2"/></node>
<node id="n3"><matrix>1 0 0 6  0 1 0 0  0 0 1 0  0 0 0 1</matrix><instance_geometry url="#g3"/></node>
<node id="n4"><translate>8 0 0</translate>
  <node><rotate>0 0 1 90</rotate><scale>2 1 1</scale><instance_geometry url="#g4"/></node></node>
<node id="n5"><translate>0 5 0</translate><instance_node url="#n0"/></node>"##;
        let m =
            read(document(&geometries, nodes, r#"<unit meter="0.5"/>"#).as_bytes()).expect("reads");
        assert_eq!(m.pieces, 6);
        assert_eq!(m.triangles.len(), 6 * 12);
        assert_eq!(m.vertices.len(), 6 * 8);
        let piece_bounds = |k: usize| {
            let vs = &m.vertices[8 * k..8 * k + 8];
            let lo: [f32; 3] =
                std::array::from_fn(|a| vs.iter().map(|v| v[a]).fold(f32::MAX, f32::min));
            let hi: [f32; 3] =
                std::array::from_fn(|a| vs.iter().map(|v| v[a]).fold(f32::MIN, f32::max));
            (lo, hi)
        };
        let close = |a: [f32; 3], b: [f32; 3]| (0..3).all(|k| (a[k] - b[k]).abs() < 1e-6);
        // Unit 0.5 m: the translation 2k becomes k metres, the cube 0.5 m.
        for k in 0..4 {
            let (lo, hi) = piece_bounds(k);
            assert!(close(lo, [k as f32, 0.0, 0.0]), "piece {k}: {lo:?}");
            assert!(close(hi, [k as f32 + 0.5, 0.5, 0.5]), "piece {k}: {hi:?}");
        }
        // Scaled 2 along x, then turned 90° about z: x ∈ [-0.5, 0] + 4, y ∈ [0, 1].
        let (lo, hi) = piece_bounds(4);
        assert!(
            close(lo, [3.5, 0.0, 0.0]) && close(hi, [4.0, 1.0, 0.5]),
            "{lo:?} {hi:?}"
        );
        let (lo, hi) = piece_bounds(5);
        assert!(
            close(lo, [0.0, 2.5, 0.0]) && close(hi, [0.5, 3.0, 0.5]),
            "{lo:?} {hi:?}"
        );
        // Every triangle refers to its own piece's vertices.
        for (k, t) in m.triangles.chunks(12).enumerate() {
            assert!(t
                .iter()
                .flatten()
                .all(|&i| (8 * k..8 * k + 8).contains(&(i as usize))));
        }
    }

    #[test]
    fn geometries_the_scene_does_not_place_are_left_out_and_noted() {
        let geometries: String = (0..3).map(|k| cube(&format!("g{k}"))).collect();
        let nodes = r##"<node><instance_geometry url="#g1"/></node>"##;
        let m = read(document(&geometries, nodes, "").as_bytes()).expect("reads");
        assert_eq!((m.pieces, m.triangles.len()), (1, 12));
        assert!(
            m.notes.iter().any(|n| n.contains("2 of 3 geometries")),
            "{:?}",
            m.notes
        );
    }

    /// Cut short anywhere, or with any digit, bracket or quote changed, a document is read or
    /// refused, never a panic (the `mesh` fuzz target runs the same walk).
    #[test]
    fn damaged_documents_are_refused_not_panicked_on() {
        let geometries: String = (0..2).map(|k| cube(&format!("g{k}"))).collect();
        let nodes = r##"<node><matrix>1 0 0 1 0 1 0 0 0 0 1 0 0 0 0 1</matrix>
<instance_geometry url="#g0"/><node><rotate>0 0 1 30</rotate><instance_node url="#n"/></node></node>
<node id="n"><scale>1 2 1</scale><instance_geometry url="#g1"/></node>"##;
        let doc = document(&geometries, nodes, r#"<unit meter="0.01"/>"#).into_bytes();
        read(&doc).expect("the intact document reads");
        for cut in (0..doc.len()).step_by(7) {
            let _ = read(&doc[..cut]);
        }
        for (i, &b) in doc.iter().enumerate() {
            if b.is_ascii_digit() || b"<>\"#".contains(&b) {
                for r in [b'0', b'9', b'-', b' ', b'x'] {
                    let mut bad = doc.clone();
                    bad[i] = r;
                    let _ = read(&bad);
                }
            }
        }
    }

    #[test]
    fn bad_files_name_the_element() {
        let nodes = r##"<node><instance_geometry url="#g0"/></node>"##;
        let short = cube("g0").replace("count=\"8\" stride", "count=\"9\" stride");
        let e = read(document(&short, nodes, "").as_bytes()).unwrap_err();
        assert!(e.contains("g0-pos") && e.contains("count 9"), "{e}");
        let missing = r##"<node><instance_geometry url="#nope"/></node>"##;
        let e = read(document(&cube("g0"), missing, "").as_bytes()).unwrap_err();
        assert!(e.contains("#nope") && e.contains("names nothing"), "{e}");
        let index = cube("g0").replace("<p>0 0", "<p>8 0");
        let e = read(document(&index, nodes, "").as_bytes()).unwrap_err();
        assert!(e.contains("index 8 beyond its 8 positions"), "{e}");
        let cycle = r##"<node id="a"><instance_node url="#a"/></node>"##;
        let e = read(document(&cube("g0"), cycle, "").as_bytes()).unwrap_err();
        assert!(e.contains("cycle"), "{e}");
        // Each level instances the next twice: 2^40 copies, refused early.
        let mut bomb = String::from(r##"<node id="l40"><instance_geometry url="#g0"/></node>"##);
        for k in 0..40 {
            bomb.push_str(&format!(
                r##"<node id="l{k}"><instance_node url="#l{n}"/><instance_node url="#l{n}"/></node>"##,
                n = k + 1
            ));
        }
        let e = read(document(&cube("g0"), &bomb, "").as_bytes()).unwrap_err();
        assert!(e.contains("geometry instances"), "{e}");
    }
}
