//! COLLADA (.dae) collision meshes as the file's scene places them: every `<instance_geometry>`
//! (and `<instance_controller>`'s skin source) reached from the scene's `<instance_visual_scene>`,
//! through nested `<node>`s and `<instance_node>`s, under the product of the node transforms
//! (`<matrix>`, `<translate>`, `<rotate>`, `<scale>`, `<lookat>`, `<skew>`, in document order),
//! scaled by the asset's `<unit meter>`. This is how RViz 2 (Assimp with its up-direction
//! conversion switched off) and Gazebo (its own COLLADA reader) place a mesh: the unit applied,
//! the `<up_axis>` not. MoveIt's geometric_shapes also drops the unit (it resets Assimp's root
//! transform); where the two differ, a file's `<unit>` other than 1 is noted. Output in metres,
//! before the URDF's `scale`.
//!
//! Geometry is read from `<triangles>`, `<polylist>`, `<polygons>` (outer `<p>` of `<ph>`),
//! `<trifans>` and `<tristrips>`; polygons are fanned. Lines and points enclose nothing and are
//! noted. A geometry the scene does not instantiate is left out and noted; a file with no scene
//! takes every geometry once, untransformed, noted. Every count is checked against the numbers
//! present before anything is allocated from it, and every index against its array.
//!
//! Written here rather than taken from mesh-loader, whose COLLADA path loads each geometry once
//! whether or not the scene instantiates it, and whose merge of three or more meshes offsets
//! the third one's indices by the second one's count alone (`fuzz/regressions/mesh/`).

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::{Matrix4, Rotation3, Unit, Vector3};

use super::mesh::MeshFile;

type Node<'a, 'i> = roxmltree::Node<'a, 'i>;

/// Nesting of `<node>` and `<instance_node>` beyond this is taken for a cycle.
const MAX_DEPTH: usize = 64;
/// Geometry instances and triangles a file may place: nodes that instance each other twice
/// at every level would otherwise place 2^depth copies.
const MAX_INSTANCES: usize = 100_000;
const MAX_TRIANGLES: usize = 50_000_000;

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
    let ids: BTreeMap<&str, Node> = doc
        .descendants()
        .filter(|n| n.is_element())
        .filter_map(|n| n.attribute("id").map(|id| (id, n)))
        .collect();
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
    let mut reader = Reader {
        ids: &ids,
        out: MeshFile::default(),
        used: BTreeSet::new(),
        positions: BTreeMap::new(),
    };
    let scale = Matrix4::new_scaling(meter);
    let scene = child(root, "scene")
        .and_then(|s| child(s, "instance_visual_scene"))
        .map(|i| reader.target(i, "url", "visual_scene"))
        .transpose()?;
    match scene {
        Some(scene) => {
            for node in children(scene, "node") {
                reader.node(node, &scale, 0)?;
            }
        }
        None => {
            reader
                .out
                .notes
                .push("no <scene>: every geometry taken once, untransformed".into());
            for g in doc.descendants().filter(|n| n.has_tag_name("geometry")) {
                reader.geometry(g, &scale)?;
            }
        }
    }
    let all = doc
        .descendants()
        .filter(|n| n.has_tag_name("geometry"))
        .count();
    let unused = all - reader.used.len();
    if unused > 0 {
        reader.out.notes.push(format!(
            "{unused} of {all} geometries not instantiated by the scene, left out"
        ));
    }
    if meter != 1.0 {
        reader.out.notes.push(format!("unit {meter} m applied"));
    }
    Ok(reader.out)
}

struct Reader<'d, 'a, 'i> {
    ids: &'d BTreeMap<&'a str, Node<'a, 'i>>,
    out: MeshFile,
    /// Ids of the geometries instantiated.
    used: BTreeSet<&'a str>,
    /// Positions read, by the VERTEX input's source (a geometry instanced twice is read once).
    positions: BTreeMap<&'a str, Vec<[f64; 3]>>,
}

fn child<'a, 'i>(n: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    n.children().find(|c| c.has_tag_name(name))
}

fn children<'a, 'i: 'a>(n: Node<'a, 'i>, name: &'a str) -> impl Iterator<Item = Node<'a, 'i>> {
    n.children().filter(move |c| c.has_tag_name(name))
}

/// Where an element is, for messages: `<tag id="…">` or `<tag>` at line L.
fn at(n: Node) -> String {
    let pos = n.document().text_pos_at(n.range().start);
    match n.attribute("id") {
        Some(id) => format!("<{} id=\"{id}\"> (line {})", n.tag_name().name(), pos.row),
        None => format!("<{}> (line {})", n.tag_name().name(), pos.row),
    }
}

/// The numbers of an element's text, refused when one is not a finite number.
fn numbers<T: std::str::FromStr>(n: Node) -> Result<Vec<T>, String> {
    n.text()
        .unwrap_or("")
        .split_ascii_whitespace()
        .map(|w| {
            w.parse::<T>()
                .map_err(|_| format!("{}: '{w}' is not a number", at(n)))
        })
        .collect()
}

fn floats(n: Node, expected: usize) -> Result<Vec<f64>, String> {
    let v: Vec<f64> = numbers(n)?;
    if v.len() != expected || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "{}: expected {expected} finite numbers, found {:?}",
            at(n),
            v
        ));
    }
    Ok(v)
}

impl<'a, 'i> Reader<'_, 'a, 'i> {
    /// The element an attribute's `#id` reference names, which must have tag `tag`.
    fn target(&self, n: Node<'a, 'i>, attr: &str, tag: &str) -> Result<Node<'a, 'i>, String> {
        let url = n
            .attribute(attr)
            .ok_or_else(|| format!("{}: no {attr} attribute", at(n)))?;
        let id = url
            .strip_prefix('#')
            .ok_or_else(|| format!("{}: {attr}=\"{url}\" is not a local #id", at(n)))?;
        match self.ids.get(id) {
            Some(t) if t.has_tag_name(tag) => Ok(*t),
            Some(t) => Err(format!(
                "{}: {attr}=\"{url}\" names {}, not a <{tag}>",
                at(n),
                at(*t)
            )),
            None => Err(format!("{}: {attr}=\"{url}\" names nothing", at(n))),
        }
    }

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
                    let g = self.target(c, "url", "geometry")?;
                    self.geometry(g, &m)?;
                }
                "instance_controller" => {
                    let controller = self.target(c, "url", "controller")?;
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
                    let g = self.target(skin, "source", "geometry")?;
                    self.out.notes.push(format!(
                        "{}: its skin's bind shape taken (joints not posed)",
                        at(c)
                    ));
                    self.geometry(g, &(m * bind))?;
                }
                "instance_node" => {
                    let n = self.target(c, "url", "node")?;
                    self.node(n, &m, depth + 1)?;
                }
                "node" => self.node(c, &m, depth + 1)?,
                _ => {}
            }
        }
        Ok(())
    }

    /// One instance of a geometry, its vertices through `m`.
    fn geometry(&mut self, geometry: Node<'a, 'i>, m: &Matrix4<f64>) -> Result<(), String> {
        let Some(mesh) = child(geometry, "mesh") else {
            self.out.notes.push(format!(
                "{}: no <mesh> (a spline or convex_mesh), left out",
                at(geometry)
            ));
            return Ok(());
        };
        self.used.insert(geometry.attribute("id").unwrap_or(""));
        self.out.pieces += 1;
        if self.out.pieces > MAX_INSTANCES || self.out.triangles.len() > MAX_TRIANGLES {
            return Err(format!(
                "{}: more than {MAX_INSTANCES} geometry instances or {MAX_TRIANGLES} triangles \
                 placed (nodes that instance each other over and over?)",
                at(geometry)
            ));
        }
        for prim in mesh.children().filter(|c| c.is_element()) {
            let kind = prim.tag_name().name();
            if matches!(kind, "lines" | "linestrips") {
                self.out
                    .notes
                    .push(format!("{}: lines enclose nothing, left out", at(prim)));
                continue;
            }
            if !matches!(
                kind,
                "triangles" | "polylist" | "polygons" | "trifans" | "tristrips"
            ) {
                continue;
            }
            // The index stride is the largest input offset plus one; VERTEX gives positions.
            let mut stride = 0usize;
            let mut vertex = None;
            for input in children(prim, "input") {
                let offset: usize = input
                    .attribute("offset")
                    .unwrap_or("0")
                    .trim()
                    .parse()
                    .map_err(|_| format!("{}: bad offset", at(input)))?;
                stride = stride.max(offset + 1);
                if input.attribute("semantic") == Some("VERTEX") {
                    vertex = Some((offset, input));
                }
            }
            let Some((offset, input)) = vertex else {
                return Err(format!("{}: no VERTEX input", at(prim)));
            };
            let key = input.attribute("source").unwrap_or("");
            if !self.positions.contains_key(key) {
                let p = self.read_positions(input)?;
                self.positions.insert(key, p);
            }
            let positions = &self.positions[key];
            let base = self.out.vertices.len();
            if base + positions.len() > u32::MAX as usize {
                return Err(format!("{}: more than 2³² vertices", at(prim)));
            }
            // Every polygon of the primitive, as position indices, then fanned.
            let polygons = polygons(prim, kind, stride, offset)?;
            let mut used = vec![false; positions.len()];
            let mut tris = Vec::new();
            for (poly, strip) in polygons {
                if let Some(&bad) = poly.iter().find(|&&i| i as usize >= positions.len()) {
                    return Err(format!(
                        "{}: index {bad} beyond its {} positions",
                        at(prim),
                        positions.len()
                    ));
                }
                let n = poly.len();
                if strip {
                    for k in 2..n {
                        tris.push(if k % 2 == 0 {
                            [poly[k - 2], poly[k - 1], poly[k]]
                        } else {
                            [poly[k - 1], poly[k - 2], poly[k]]
                        });
                    }
                } else {
                    for k in 2..n {
                        tris.push([poly[0], poly[k - 1], poly[k]]);
                    }
                }
            }
            for t in &tris {
                for &i in t {
                    used[i as usize] = true;
                }
            }
            // Only the positions this primitive uses, renumbered.
            let mut map = vec![u32::MAX; positions.len()];
            for (i, p) in positions.iter().enumerate() {
                if used[i] {
                    map[i] = self.out.vertices.len() as u32;
                    let v = m.transform_point(&nalgebra::Point3::new(p[0], p[1], p[2]));
                    self.out.vertices.push([v.x as f32, v.y as f32, v.z as f32]);
                }
            }
            self.out
                .triangles
                .extend(tris.iter().map(|t| t.map(|i| map[i as usize])));
        }
        Ok(())
    }

    /// The positions a VERTEX input names: a `<vertices>` element's POSITION source, or a
    /// `<source>` itself.
    fn read_positions(&self, input: Node<'a, 'i>) -> Result<Vec<[f64; 3]>, String> {
        let url = input.attribute("source").unwrap_or("");
        let id = url.strip_prefix('#').unwrap_or(url);
        let target = *self
            .ids
            .get(id)
            .ok_or_else(|| format!("{}: source=\"{url}\" names nothing", at(input)))?;
        let source = if target.has_tag_name("vertices") {
            let p = children(target, "input")
                .find(|i| i.attribute("semantic") == Some("POSITION"))
                .ok_or_else(|| format!("{}: no POSITION input", at(target)))?;
            self.target(p, "source", "source")?
        } else if target.has_tag_name("source") {
            target
        } else {
            return Err(format!("{}: names {}", at(input), at(target)));
        };
        let array = child(source, "float_array")
            .ok_or_else(|| format!("{}: no <float_array>", at(source)))?;
        let values: Vec<f64> = numbers(array)?;
        if let Some(count) = array.attribute("count") {
            if count.trim().parse::<usize>().ok() != Some(values.len()) {
                return Err(format!(
                    "{}: count=\"{count}\" but {} numbers",
                    at(array),
                    values.len()
                ));
            }
        }
        if values.iter().any(|v| !v.is_finite()) {
            return Err(format!("{}: a number is not finite", at(array)));
        }
        let accessor = child(source, "technique_common").and_then(|t| child(t, "accessor"));
        let (count, stride, start) = match accessor {
            Some(a) => {
                let get = |name: &str, default: usize| -> Result<usize, String> {
                    a.attribute(name).map_or(Ok(default), |v| {
                        v.trim()
                            .parse()
                            .map_err(|_| format!("{}: bad {name}=\"{v}\"", at(a)))
                    })
                };
                (
                    get("count", values.len() / 3)?,
                    get("stride", 3)?,
                    get("offset", 0)?,
                )
            }
            None => (values.len() / 3, 3, 0),
        };
        // Checked against the numbers present before anything is sized from it.
        if stride < 3
            || count
                .checked_mul(stride)
                .and_then(|n| n.checked_add(start))
                .is_none_or(|n| n > values.len().saturating_add(stride) - 3)
        {
            return Err(format!(
                "{}: accessor count {count} × stride {stride} (offset {start}) beyond its {} numbers",
                at(source),
                values.len()
            ));
        }
        Ok((0..count)
            .map(|i| {
                let j = start + i * stride;
                [values[j], values[j + 1], values[j + 2]]
            })
            .collect())
    }
}

/// The polygons of a primitive as position indices, each with whether it is a strip.
fn polygons(
    prim: Node,
    kind: &str,
    stride: usize,
    offset: usize,
) -> Result<Vec<(Vec<u32>, bool)>, String> {
    let positions_of = |p: Node| -> Result<Vec<u32>, String> {
        let idx: Vec<u32> = numbers(p)?;
        if !idx.len().is_multiple_of(stride) {
            return Err(format!(
                "{}: {} indices is not a multiple of the {stride} inputs",
                at(p),
                idx.len()
            ));
        }
        Ok(idx.chunks_exact(stride).map(|c| c[offset]).collect())
    };
    let count: Option<usize> = prim.attribute("count").and_then(|c| c.trim().parse().ok());
    let mut out = Vec::new();
    match kind {
        "triangles" => {
            for p in children(prim, "p") {
                let v = positions_of(p)?;
                if !v.len().is_multiple_of(3) {
                    return Err(format!("{}: not a whole number of triangles", at(p)));
                }
                out.extend(v.chunks_exact(3).map(|t| (t.to_vec(), false)));
            }
        }
        "polylist" => {
            let vcount: Vec<usize> = match child(prim, "vcount") {
                Some(v) => numbers(v)?,
                None => Vec::new(),
            };
            let v = match child(prim, "p") {
                Some(p) => positions_of(p)?,
                None => Vec::new(),
            };
            let total = vcount
                .iter()
                .try_fold(0usize, |s, &n| s.checked_add(n))
                .unwrap_or(usize::MAX);
            if total != v.len() {
                return Err(format!(
                    "{}: <vcount> sums to {total} vertices, <p> has {}",
                    at(prim),
                    v.len()
                ));
            }
            let mut at_ = 0;
            for n in vcount {
                out.push((v[at_..at_ + n].to_vec(), false));
                at_ += n;
            }
        }
        "polygons" => {
            for c in prim.children().filter(|c| c.is_element()) {
                match c.tag_name().name() {
                    "p" => out.push((positions_of(c)?, false)),
                    // A polygon with holes: its outer boundary, which covers the holes.
                    "ph" => {
                        if let Some(p) = child(c, "p") {
                            out.push((positions_of(p)?, false));
                        }
                    }
                    _ => {}
                }
            }
        }
        "trifans" => {
            for p in children(prim, "p") {
                out.push((positions_of(p)?, false));
            }
        }
        _ => {
            for p in children(prim, "p") {
                out.push((positions_of(p)?, true));
            }
        }
    }
    if let Some(c) = count {
        if c != out.len() && kind != "triangles" {
            return Err(format!(
                "{}: count=\"{c}\" but {} polygons",
                at(prim),
                out.len()
            ));
        }
        if kind == "triangles" && c != out.len() {
            return Err(format!(
                "{}: count=\"{c}\" but {} triangles",
                at(prim),
                out.len()
            ));
        }
    }
    Ok(out)
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
    /// refused, never a panic (the `mesh` fuzz target runs the same reader).
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
