//! The bodies of the fuzz targets, one function per decoder of untrusted input. The fuzz binaries
//! (`fuzz_targets/*.rs`, nightly) call them under libFuzzer with [`Limited`] as the allocator;
//! `tests/fuzz_regressions.rs` (stable) runs them over every input kept in `regressions/`. A
//! target passes when the decoder returns, `Ok` or `Err`: a panic, an abort or an allocation
//! past [`LIMIT`] is a finding.
#![allow(dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use ist_monitor::bag::reader::read_mcap;
use ist_monitor::cloud::{pcd, ply, pointcloud2};
use ist_monitor::config::Config;
use ist_monitor::msg;
use ist_monitor::robot::{mesh, RobotModel};

/// The largest allocation an input of a few kilobytes may cause: far above what any decoder
/// needs for it (LZF inflates at most 88×), far below what a lying header would ask for.
pub const LIMIT: usize = 1 << 30;

/// The MCAP target's limit. The `mcap` crate reads each length-prefixed string and byte field
/// through `binrw`, which reserves the declared length (a `u32`, up to 4 GiB) before it finds
/// that the record is shorter (found by this fuzzer; the same in binrw 0.15 under mcap 0.26).
/// The reservation is never written, so memory in use stays small, and the read then fails
/// with an error; this limit lets the fuzzer look past it for anything else.
pub const MCAP_LIMIT: usize = 5 << 30;

/// The system allocator, aborting with a message on any allocation past its limit (an
/// allocator must not unwind, so this cannot be a panic; libFuzzer reports the abort).
pub struct Limited(pub usize);

impl Limited {
    fn check(&self, size: usize) {
        if size > self.0 {
            use std::io::Write;
            let _ = std::io::stderr().write_all(b"fuzz: allocation past the target's limit\n");
            std::process::abort();
        }
    }
}

unsafe impl GlobalAlloc for Limited {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        self.check(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        self.check(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        self.check(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// A `sensor_msgs/PointCloud2` CDR payload, decoded and its points extracted.
pub fn pointcloud2(data: &[u8]) {
    if let Ok(m) = pointcloud2::decode(data) {
        let _ = m.to_cloud();
    }
}

/// The first byte picks a message type; the rest is its CDR payload.
pub fn messages(data: &[u8]) {
    let Some((&which, payload)) = data.split_first() else {
        return;
    };
    macro_rules! each {
        ($($t:ty),*) => {{
            let decoders: &[fn(&[u8])] = &[$(|p| { let _ = msg::decode::<$t>(p); }),*];
            decoders[which as usize % decoders.len()](payload);
        }};
    }
    each!(
        msg::Header,
        msg::TfMessage,
        msg::JointState,
        msg::CameraInfo,
        msg::Image,
        msg::CompressedImage,
        msg::DiagnosticArray,
        msg::MarkerArray,
        msg::Float64,
        msg::Bool,
        msg::PointCloud2
    );
}

pub fn pcd(data: &[u8]) {
    let _ = pcd::parse(data);
}

pub fn ply(data: &[u8]) {
    let _ = ply::parse(data);
}

/// One MCAP file of a rosbag2 bag, every message kept.
pub fn mcap(data: &[u8]) {
    let mut out = Vec::new();
    let _ = read_mcap(Path::new("fuzz.mcap"), data, &|_, _| true, &mut out);
}

/// A ROS 2 parameters file.
pub fn params(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Config::parse(text, Path::new("fuzz.yaml"), &[]);
    }
}

/// A folder holding the demo arm's meshes, for URDF inputs that refer to them.
fn robot_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("ist_monitor-fuzz-{}", std::process::id()));
        let meshes = dir.join("meshes");
        std::fs::create_dir_all(&meshes).expect("temporary folder");
        let demo = Path::new(env!("CARGO_MANIFEST_DIR"))
            .ancestors()
            .map(|a| a.join("urdf/meshes"))
            .find(|p| p.is_dir())
            .expect("urdf/meshes of the checkout");
        for e in std::fs::read_dir(demo).expect("urdf/meshes").flatten() {
            std::fs::copy(e.path(), meshes.join(e.file_name())).expect("copy a demo mesh");
        }
        dir
    })
}

/// A URDF (with the demo arm's meshes beside it): parsed, meshes loaded, kinematics built.
pub fn urdf(data: &[u8]) {
    let path = robot_dir().join(format!("robot-{:?}.urdf", std::thread::current().id()));
    if std::fs::write(&path, data).is_ok() {
        let _ = RobotModel::load(&path, &[], &Default::default());
    }
}

/// A mesh file; the first byte picks the format (STL, OBJ, COLLADA).
pub fn mesh(data: &[u8]) {
    let Some((&which, bytes)) = data.split_first() else {
        return;
    };
    let name = ["fuzz.stl", "fuzz.obj", "fuzz.dae"][which as usize % 3];
    let _ = mesh::load_mesh_bytes(bytes, &robot_dir().join(name));
}
