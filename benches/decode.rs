//! PointCloud2 decoding: a 640×480 cloud of 32-byte points (x y z as FLOAT32, then rgb and
//! padding, as an RGB-D driver publishes it) from its CDR payload to points. Target ≤ 1 ms.
//! Beside it, the copy of the payload's bytes as a floor, and the FLOAT64 big-endian path.

use criterion::{criterion_group, criterion_main, Criterion};
use ist_monitor::cloud::pointcloud2;
use ist_monitor::msg::{self, Header, PointField};

/// A 640×480 depth camera's cloud of 32-byte points (with rgb for FLOAT32), as CDR.
fn payload(big_endian: bool, float64: bool) -> Vec<u8> {
    let (w, h) = (640u32, 480u32);
    let points: Vec<[f32; 3]> = (0..w * h)
        .map(|i| {
            let (u, v) = ((i % w) as f64, (i / w) as f64);
            let z = 1.0 + 0.001 * (u + v);
            [
                ((u - 320.0) * z / 525.0) as f32,
                ((v - 240.0) * z / 525.0) as f32,
                z as f32,
            ]
        })
        .collect();
    let layout = pointcloud2::Layout {
        width: w,
        height: h,
        datatype: if float64 {
            PointField::FLOAT64
        } else {
            PointField::FLOAT32
        },
        big_endian,
        point_step: 32,
        row_padding: 0,
        rgb: (!float64).then_some((16, (|_| [128, 128, 128]) as pointcloud2::Colour)),
        pad: 0,
    };
    let header = Header {
        frame_id: "camera_depth_optical_frame".into(),
        ..Header::default()
    };
    let m = pointcloud2::encode(header, &points, &layout).expect("encode");
    msg::encode(&m).expect("encode")
}

fn decode(c: &mut Criterion) {
    let mut g = c.benchmark_group("decode_640x480_32B");
    let le32 = payload(false, false);
    g.bench_function("copy_payload_floor", |b| b.iter(|| le32.to_vec()));
    g.bench_function("float32_le", |b| {
        b.iter(|| pointcloud2::cloud_from_cdr(&le32).expect("decode"))
    });
    let be64 = payload(true, true);
    g.bench_function("float64_be", |b| {
        b.iter(|| pointcloud2::cloud_from_cdr(&be64).expect("decode"))
    });
    g.finish();
}

criterion_group!(benches, decode);
criterion_main!(benches);
