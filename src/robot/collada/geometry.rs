//! One `<geometry>` instance placed: its `<mesh>`'s primitives (`<triangles>`, `<polylist>`,
//! `<polygons>`, `<trifans>`, `<tristrips>`) read as polygons of position indices, fanned into
//! triangles, and its positions through the instance's transform (the node transforms and the
//! unit, f64) appended to the soup in f32. Counts are checked against the numbers present and
//! every index against its array before anything is sized from them.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::Matrix4;

use super::xml::{at, child, children, numbers, Ids, Node};
use crate::robot::mesh_file::MeshFile;

/// Geometry instances and triangles a file may place: nodes that instance each other twice
/// at every level would otherwise place 2^depth copies.
const MAX_INSTANCES: usize = 100_000;
const MAX_TRIANGLES: usize = 50_000_000;

/// The geometry instances placed so far.
#[derive(Default)]
pub(super) struct Placed<'a> {
    pub(super) out: MeshFile,
    /// Ids of the geometries instantiated.
    pub(super) used: BTreeSet<&'a str>,
    /// Positions read, by the VERTEX input's source (a geometry instanced twice is read once).
    positions: BTreeMap<&'a str, Vec<[f64; 3]>>,
}

impl<'a> Placed<'a> {
    /// One instance of a geometry, its vertices through `m`.
    pub(super) fn place<'i>(
        &mut self,
        ids: &Ids<'a, 'i>,
        geometry: Node<'a, 'i>,
        m: &Matrix4<f64>,
    ) -> Result<(), String> {
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
                let p = read_positions(ids, input)?;
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
}

/// The positions a VERTEX input names: a `<vertices>` element's POSITION source, or a
/// `<source>` itself.
fn read_positions<'a, 'i>(ids: &Ids<'a, 'i>, input: Node<'a, 'i>) -> Result<Vec<[f64; 3]>, String> {
    let url = input.attribute("source").unwrap_or("");
    let id = url.strip_prefix('#').unwrap_or(url);
    let target = ids
        .get(id)
        .ok_or_else(|| format!("{}: source=\"{url}\" names nothing", at(input)))?;
    let source = if target.has_tag_name("vertices") {
        let p = children(target, "input")
            .find(|i| i.attribute("semantic") == Some("POSITION"))
            .ok_or_else(|| format!("{}: no POSITION input", at(target)))?;
        ids.target(p, "source", "source")?
    } else if target.has_tag_name("source") {
        target
    } else {
        return Err(format!("{}: names {}", at(input), at(target)));
    };
    let array =
        child(source, "float_array").ok_or_else(|| format!("{}: no <float_array>", at(source)))?;
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
