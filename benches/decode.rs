//! PointCloud2 decoding: a 640×480 cloud of 32-byte points (x y z as FLOAT32, then rgb and
//! padding, as an RGB-D driver publishes it) from its CDR payload to points. Target ≤ 1 ms.
//! Beside it, the copy of the payload's bytes as a floor, and the FLOAT64 big-endian path.

use std::borrow::Cow;

use criterion::{criterion_group, criterion_main, Criterion};
use ist_monitor::cloud::pointcloud2;
use ist_monitor::msg::{self, Header, PointCloud2, PointField};

fn payload(big_endian: bool, float64: bool) -> Vec<u8> {
    let (w, h) = (640u32, 480u32);
    let (size, datatype) = if float64 {
        (8, PointField::FLOAT64)
    } else {
        (4, PointField::FLOAT32)
    };
    let step = 32u32;
    let mut data = vec![0u8; (w * h * step) as usize];
    for (i, p) in data.chunks_exact_mut(step as usize).enumerate() {
        let (u, v) = ((i as u32 % w) as f64, (i as u32 / w) as f64);
        let z = 1.0 + 0.001 * (u + v);
        for (k, value) in [(u - 320.0) * z / 525.0, (v - 240.0) * z / 525.0, z]
            .into_iter()
            .enumerate()
        {
            let bytes: Vec<u8> = match (float64, big_endian) {
                (true, true) => value.to_be_bytes().to_vec(),
                (true, false) => value.to_le_bytes().to_vec(),
                (false, true) => (value as f32).to_be_bytes().to_vec(),
                (false, false) => (value as f32).to_le_bytes().to_vec(),
            };
            p[k * size..(k + 1) * size].copy_from_slice(&bytes);
        }
    }
    let field = |name: &str, offset: usize| PointField {
        name: name.into(),
        offset: offset as u32,
        datatype,
        count: 1,
    };
    let mut fields = vec![field("x", 0), field("y", size), field("z", 2 * size)];
    if !float64 {
        fields.push(PointField {
            name: "rgb".into(),
            offset: 16,
            datatype: PointField::FLOAT32,
            count: 1,
        });
    }
    let m = PointCloud2 {
        header: Header {
            frame_id: "camera_depth_optical_frame".into(),
            ..Header::default()
        },
        height: h,
        width: w,
        fields,
        is_bigendian: big_endian,
        point_step: step,
        row_step: w * step,
        data: Cow::Owned(data),
        is_dense: true,
    };
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
