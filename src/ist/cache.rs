//! On-disk cache of inner sphere trees, one file per solid, named by its key.
//!
//! The key is a BLAKE3 hash of the format version, the build options, the link's collision
//! meshes as packed (link-frame vertices and triangles, tessellation error) and its mesh files'
//! own triangles as read (on which h is measured too), so any change of mesh content, scale,
//! origin or parameter misses the cache. The link's name is not in it: two links whose solids are
//! the same in their own frames (a left and a right arm sharing a file, mirrored through the
//! joint frames; a link a mimic joint doubles) have one key, are packed once (`ist::robot`) and
//! share one file, whichever of them built it. A file holds:
//! `magic "ISTCACHE" | version u32 | key [32] | quality (19 × f64, no wall time; the last the
//! mark that the tree passed `ist::validate`) | node count u32 | sphere count u32 | nodes |
//! spheres | BLAKE3 of all before [32]`, little endian. A file that fails any check (length,
//! checksum, magic, version, key) is reported as an error, never trusted; the caller warns and
//! rebuilds. Writes go to a temporary
//! file first and are renamed into place, so a crashed write leaves no half file.

use std::path::{Path, PathBuf};

use super::link_tree::{IstNode, LinkQuality, LinkTree, StageTimes, Uncovered};
use super::options::BuildOptions;
use crate::packing::InnerSphere;
use crate::robot::LinkGeometry;

const MAGIC: &[u8; 8] = b"ISTCACHE";
/// Bump when the file layout or anything that changes the trees for the same key changes.
/// 3: trees validated before they are stored (`ist::validate`), the files' sampled gap and the
/// grown budget recorded, no wall times; deterministic intake.
/// 4: walls thinner than the fill's voxel packed (each closed shell's own inside test), the
/// gap pass's second seed at half the thickness, T-junction cracks sewn in full.
/// 5: h is the validation's measured value (not the packing's estimate plus a slack); the
/// quality holds the packed surface's and the files' h and the uncovered point of the files.
/// 6: one file per solid: no link name in the key or the file.
pub const FORMAT_VERSION: u32 = 6;

#[derive(Debug, thiserror::Error)]
pub enum CacheError {
    #[error("tree cache {path}: {message}")]
    Corrupt { path: PathBuf, message: String },
    #[error("tree cache {path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// The cache folder.
pub struct TreeCache {
    dir: PathBuf,
}

/// The cache key of a link under `options`.
pub fn key(link: &LinkGeometry, options: &BuildOptions) -> [u8; 32] {
    let mut h = blake3::Hasher::new();
    h.update(&FORMAT_VERSION.to_le_bytes());
    h.update(
        serde_json::to_string(options)
            .unwrap_or_default()
            .as_bytes(),
    );
    for e in &link.elements {
        h.update(&(e.mesh.vertices.len() as u64).to_le_bytes());
        h.update(bytemuck::cast_slice(&e.mesh.vertices));
        h.update(&(e.mesh.triangles.len() as u64).to_le_bytes());
        h.update(bytemuck::cast_slice(&e.mesh.triangles));
        h.update(&e.tessellation_error_m.to_le_bytes());
        if let Some(fill) = &e.mesh.fill {
            h.update(&fill.voxel_m.to_le_bytes());
            h.update(fill.labels());
        }
    }
    // Two files that differ only in what the intake dropped pack alike, but their h differs.
    for i in &link.intake {
        let (vertices, triangles) = &*i.original;
        h.update(&(i.element as u64).to_le_bytes());
        h.update(&(vertices.len() as u64).to_le_bytes());
        h.update(bytemuck::cast_slice(vertices));
        h.update(&(triangles.len() as u64).to_le_bytes());
        h.update(bytemuck::cast_slice(triangles));
    }
    *h.finalize().as_bytes()
}

fn hex(key: &[u8; 32]) -> String {
    key.iter().map(|b| format!("{b:02x}")).collect()
}

impl TreeCache {
    pub fn new(dir: PathBuf) -> Self {
        Self { dir }
    }

    /// The cache in `dir`, or in [`TreeCache::default_dir`] when none is given.
    pub fn at(dir: Option<&Path>) -> Self {
        Self::new(dir.map_or_else(Self::default_dir, Path::to_path_buf))
    }

    /// `$IST_MONITOR_CACHE`, else `$XDG_CACHE_HOME/ist_monitor`, else `~/.cache/ist_monitor`.
    pub fn default_dir() -> PathBuf {
        if let Some(dir) = std::env::var_os("IST_MONITOR_CACHE") {
            return dir.into();
        }
        if let Some(dir) = std::env::var_os("XDG_CACHE_HOME") {
            return Path::new(&dir).join("ist_monitor");
        }
        let home = std::env::var_os("HOME").unwrap_or_else(|| ".".into());
        Path::new(&home).join(".cache").join("ist_monitor")
    }

    pub fn path(&self, key: &[u8; 32]) -> PathBuf {
        self.dir.join(format!("{}.ist", hex(key)))
    }

    /// Whether the cache holds a file under `key` (whose contents are checked when loaded).
    pub fn holds(&self, key: &[u8; 32]) -> bool {
        self.path(key).is_file()
    }

    /// The tree stored under `key`, None when there is none, an error when the file is bad.
    pub fn load(&self, key: &[u8; 32], link: &str) -> Result<Option<LinkTree>, CacheError> {
        let path = self.path(key);
        let bytes = match std::fs::read(&path) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(CacheError::Io { path, source }),
        };
        decode(&bytes, key, link)
            .map(Some)
            .map_err(|message| CacheError::Corrupt { path, message })
    }

    pub fn store(&self, key: &[u8; 32], tree: &LinkTree) -> Result<(), CacheError> {
        let path = self.path(key);
        let io = |source| CacheError::Io {
            path: path.clone(),
            source,
        };
        std::fs::create_dir_all(&self.dir).map_err(io)?;
        let tmp = path.with_extension(format!("tmp{}", std::process::id()));
        std::fs::write(&tmp, encode(key, tree)).map_err(io)?;
        std::fs::rename(&tmp, &path).map_err(io)
    }
}

/// The quality as stored: no wall time, so that the same inputs give the same file on any
/// machine and thread count; the last field records that the tree passed `ist::validate` (the
/// cache stores no other).
fn quality_fields(q: &LinkQuality) -> [f64; QUALITY_FIELDS] {
    let u = q.uncovered;
    [
        q.spheres as f64,
        q.coverage,
        q.gap_m,
        q.gap_sampled_m,
        q.mesh_volume_m3,
        q.tree_volume_m3,
        q.file_gap_sampled_m,
        q.budget as f64,
        q.elements_gap_m,
        q.file_gap_m,
        f64::from(u8::from(u.is_some())),
        u.map_or(0.0, |u| u.element as f64),
        u.map_or(0.0, |u| u.triangle as f64),
        u.map_or(0.0, |u| u.point[0]),
        u.map_or(0.0, |u| u.point[1]),
        u.map_or(0.0, |u| u.point[2]),
        u.map_or(0.0, |u| u.gap_m),
        u.map_or(0.0, |u| u.packed_surface_m),
        VALIDATED,
    ]
}

const QUALITY_FIELDS: usize = 19;
/// The "validated" mark.
const VALIDATED: f64 = 1.0;

pub fn encode(key: &[u8; 32], tree: &LinkTree) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(key);
    for v in quality_fields(&tree.quality) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&(tree.nodes.len() as u32).to_le_bytes());
    out.extend_from_slice(&(tree.spheres.len() as u32).to_le_bytes());
    out.extend_from_slice(bytemuck::cast_slice(&tree.nodes));
    out.extend_from_slice(bytemuck::cast_slice(&tree.spheres));
    let checksum = blake3::hash(&out);
    out.extend_from_slice(checksum.as_bytes());
    out
}

/// A little-endian reader over a byte slice that fails instead of panicking.
struct Reader<'a> {
    bytes: &'a [u8],
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        if self.bytes.len() < n {
            return Err("file is truncated".into());
        }
        let (head, tail) = self.bytes.split_at(n);
        self.bytes = tail;
        Ok(head)
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().map_err(|_| "short")?,
        ))
    }
    fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_le_bytes(
            self.take(8)?.try_into().map_err(|_| "short")?,
        ))
    }
}

pub fn decode(bytes: &[u8], key: &[u8; 32], link: &str) -> Result<LinkTree, String> {
    if bytes.len() < MAGIC.len() + 32 {
        return Err("file is truncated".into());
    }
    let (body, checksum) = bytes.split_at(bytes.len() - 32);
    if blake3::hash(body).as_bytes() != checksum {
        return Err("checksum mismatch (corrupt file)".into());
    }
    let mut r = Reader { bytes: body };
    if r.take(8)? != MAGIC {
        return Err("not a tree cache file".into());
    }
    let version = r.u32()?;
    if version != FORMAT_VERSION {
        return Err(format!(
            "format version {version}, expected {FORMAT_VERSION} (outdated)"
        ));
    }
    if r.take(32)? != key {
        return Err("key does not match its file name".into());
    }
    let mut q = [0.0f64; QUALITY_FIELDS];
    for v in &mut q {
        *v = r.f64()?;
    }
    if q[QUALITY_FIELDS - 1] != VALIDATED {
        return Err("the tree is not marked validated".into());
    }
    let n_nodes = r.u32()? as usize;
    let n_spheres = r.u32()? as usize;
    let nodes: Vec<IstNode> = bytemuck::allocation::pod_collect_to_vec(r.take(n_nodes * 32)?);
    let spheres: Vec<InnerSphere> =
        bytemuck::allocation::pod_collect_to_vec(r.take(n_spheres * 16)?);
    if !r.bytes.is_empty() {
        return Err("trailing bytes".into());
    }
    Ok(LinkTree {
        link: link.to_owned(),
        nodes,
        spheres,
        quality: LinkQuality {
            spheres: q[0] as usize,
            budget: q[7] as usize,
            coverage: q[1],
            gap_m: q[2],
            gap_sampled_m: q[3],
            mesh_volume_m3: q[4],
            tree_volume_m3: q[5],
            // Not stored (see `quality_fields`): this run built nothing.
            build_s: 0.0,
            validate_s: 0.0,
            stages: StageTimes::default(),
            file_gap_sampled_m: q[6],
            elements_gap_m: q[8],
            file_gap_m: q[9],
            uncovered: (q[10] != 0.0).then_some(Uncovered {
                element: q[11] as usize,
                triangle: q[12] as usize,
                point: [q[13], q[14], q[15]],
                gap_m: q[16],
                packed_surface_m: q[17],
            }),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tree() -> LinkTree {
        LinkTree {
            link: "l".into(),
            nodes: vec![IstNode {
                center: [0.0; 3],
                radius: 1.0,
                first_child: 0,
                child_count: 1,
                children_are_spheres: 1,
                pad: 0,
            }],
            spheres: vec![InnerSphere {
                center: [0.0; 3],
                radius: 0.5,
            }],
            quality: LinkQuality {
                spheres: 1,
                budget: 1,
                coverage: 0.5,
                gap_m: 0.1,
                gap_sampled_m: 0.09,
                mesh_volume_m3: 1.0,
                tree_volume_m3: 4.0,
                build_s: 0.0,
                validate_s: 0.0,
                stages: StageTimes::default(),
                elements_gap_m: 0.08,
                file_gap_m: 0.1,
                file_gap_sampled_m: 0.05,
                uncovered: Some(Uncovered {
                    element: 2,
                    triangle: 191,
                    point: [0.25, -0.5, 1.0],
                    gap_m: 0.095,
                    packed_surface_m: 0.01,
                }),
            },
        }
    }

    #[test]
    fn round_trip_and_every_corruption_is_caught() {
        let key = [7u8; 32];
        let bytes = encode(&key, &tree());
        assert_eq!(decode(&bytes, &key, "l"), Ok(tree()));
        for i in 0..bytes.len() {
            let mut bad = bytes.clone();
            bad[i] ^= 0x10;
            assert!(
                decode(&bad, &key, "l").is_err(),
                "flip at byte {i} not caught"
            );
        }
        assert!(decode(&bytes[..bytes.len() - 1], &key, "l").is_err());
        assert!(decode(&bytes, &[8u8; 32], "l").is_err());
        // One file per solid: another link with the same key takes it under its own name.
        let other = decode(&bytes, &key, "other").expect("decodes");
        assert_eq!(
            (other.link.as_str(), &other.spheres),
            ("other", &tree().spheres)
        );
    }
}
