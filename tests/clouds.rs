//! Cloud readers: PCD (ascii, binary, binary_compressed), PLY (ascii, both binary byte orders),
//! PointCloud2 in CDR and rosbag2 MCAP; on files written here and on the real captures of
//! ../shared.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use byteorder::BigEndian;
use ist_monitor::cloud::{self, pointcloud2, CloudError};
use ist_monitor::msg::{self, RosMessage};
use ist_monitor::query::is_valid_point;

fn sample() -> Vec<[f32; 3]> {
    vec![
        [0.5, -1.25, 2.0],
        [f32::NAN, f32::NAN, f32::NAN],
        [1e-7, 3.0e3, -0.125],
        [0.0, 0.0, 0.0],
    ]
}

fn same(a: &[[f32; 3]], b: &[[f32; 3]]) -> bool {
    a.len() == b.len()
        && a.iter().zip(b).all(|(p, q)| {
            p.iter()
                .zip(q)
                .all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
        })
}

/// A PCD with fields x y z and an extra `intensity` between y and z, so that offsets matter.
fn pcd(encoding: &str, points: &[[f32; 3]]) -> Vec<u8> {
    let n = points.len();
    let mut out = format!(
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y intensity z\nSIZE 4 4 2 4\nTYPE F F U F\nCOUNT 1 1 1 1\nWIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {encoding}\n"
    )
    .into_bytes();
    match encoding {
        "ascii" => {
            for p in points {
                out.extend(format!("{} {} 7 {}\n", p[0], p[1], p[2]).bytes());
            }
        }
        "binary" => {
            for p in points {
                out.extend(p[0].to_le_bytes());
                out.extend(p[1].to_le_bytes());
                out.extend(7u16.to_le_bytes());
                out.extend(p[2].to_le_bytes());
            }
        }
        _ => {
            // Field-major, then LZF.
            let mut raw = Vec::new();
            for p in points {
                raw.extend(p[0].to_le_bytes());
            }
            for p in points {
                raw.extend(p[1].to_le_bytes());
            }
            for _ in points {
                raw.extend(7u16.to_le_bytes());
            }
            for p in points {
                raw.extend(p[2].to_le_bytes());
            }
            let mut compressed = vec![0u8; raw.len() * 2 + 64];
            let size = lzf_rust::compress(&raw, &mut compressed).expect("lzf");
            out.extend((size as u32).to_le_bytes());
            out.extend((raw.len() as u32).to_le_bytes());
            out.extend(&compressed[..size]);
        }
    }
    out
}

#[test]
fn pcd_encodings() {
    let dir = tempfile::tempdir().unwrap();
    let points = sample();
    for encoding in ["ascii", "binary", "binary_compressed"] {
        let path = dir.path().join(format!("{encoding}.pcd"));
        std::fs::write(&path, pcd(encoding, &points)).unwrap();
        let c = cloud::load(&path, 0).unwrap_or_else(|e| panic!("{encoding}: {e}"));
        assert!(same(&c.points, &points), "{encoding}: {:?}", c.points);
        assert_eq!((c.width, c.height), (4, 1));
    }
    // A truncated compressed body and a missing field are errors naming the file.
    let path = dir.path().join("broken.pcd");
    let mut bytes = pcd("binary_compressed", &points);
    bytes.truncate(bytes.len() - 5);
    std::fs::write(&path, &bytes).unwrap();
    let e = cloud::load(&path, 0).unwrap_err().to_string();
    assert!(e.contains("broken.pcd") && e.contains("PCD"), "{e}");
    let text = String::from_utf8(pcd("ascii", &points))
        .unwrap()
        .replace("FIELDS x y intensity z", "FIELDS x y intensity w");
    std::fs::write(&path, text).unwrap();
    let e = cloud::load(&path, 0).unwrap_err().to_string();
    assert!(e.contains("no field z"), "{e}");
}

#[test]
fn ply_formats() {
    let dir = tempfile::tempdir().unwrap();
    let points = sample();
    let header = |format: &str| {
        format!(
            "ply\nformat {format} 1.0\ncomment test\nelement vertex {}\nproperty double x\nproperty float y\nproperty uchar red\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
            points.len()
        )
        .into_bytes()
    };
    let mut ascii = header("ascii");
    for p in &points {
        ascii.extend(format!("{} {} 200 {}\n", p[0], p[1], p[2]).bytes());
    }
    let mut le = header("binary_little_endian");
    let mut be = header("binary_big_endian");
    for p in &points {
        le.extend((p[0] as f64).to_le_bytes());
        le.extend(p[1].to_le_bytes());
        le.push(200);
        le.extend(p[2].to_le_bytes());
        be.extend((p[0] as f64).to_be_bytes());
        be.extend(p[1].to_be_bytes());
        be.push(200);
        be.extend(p[2].to_be_bytes());
    }
    for (name, bytes) in [("ascii", ascii), ("le", le), ("be", be)] {
        let path = dir.path().join(format!("{name}.ply"));
        std::fs::write(&path, bytes).unwrap();
        let c = cloud::load(&path, 0).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(same(&c.points, &points), "{name}: {:?}", c.points);
    }
}

/// Headers that lie about their counts: each an error naming the file and what disagrees,
/// found before anything of the claimed size is allocated (without the checks these aborted on a
/// 48 GB allocation, overflowed a capacity, panicked inside pcd-rs, or read part of the file).
#[test]
fn lying_headers_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let points = sample();
    let check = |name: &str, bytes: Vec<u8>, expected: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let e = cloud::load(&path, 0).unwrap_err().to_string();
        assert!(e.contains(name) && e.contains(expected), "{name}: {e}");
    };
    let edit = |encoding: &str, from: &[&str], to: &[&str]| {
        let mut bytes = pcd(encoding, &points);
        let end = bytes.windows(5).position(|w| w == b"DATA ").unwrap();
        let mut header = String::from_utf8(bytes[..end].to_vec()).unwrap();
        for (f, t) in from.iter().zip(to) {
            header = header.replace(f, t);
        }
        bytes.splice(..end, header.into_bytes());
        bytes
    };
    let counts = |n: &str| [format!("WIDTH {n}"), format!("POINTS {n}")];
    for (name, n, expected) in [
        ("huge.pcd", "4000000000", "more than the 100000000 points"),
        (
            "max.pcd",
            "18446744073709551615",
            "more than the 100000000 points",
        ),
        ("fewer.pcd", "3", "the data is 56"),
        ("more.pcd", "5", "the data is 56"),
    ] {
        let [w, p] = counts(n);
        check(
            name,
            edit("binary", &["WIDTH 4", "POINTS 4"], &[&w, &p]),
            expected,
        );
    }
    check(
        "height.pcd",
        edit("binary", &["HEIGHT 1"], &["HEIGHT 2"]),
        "WIDTH 4 × HEIGHT 2 is not POINTS 4",
    );
    let [w, p] = counts("5");
    check(
        "compressed_count.pcd",
        edit("binary_compressed", &["WIDTH 4", "POINTS 4"], &[&w, &p]),
        "inflates to 56 bytes",
    );
    let mut bytes = pcd("binary_compressed", &points);
    let at = bytes
        .windows(18)
        .position(|w| w == b"binary_compressed\n")
        .unwrap()
        + 18;
    bytes[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    check("compressed_size.pcd", bytes, "block of 4294967295 bytes");
    let [w, p] = counts("3");
    check(
        "ascii_count.pcd",
        edit("ascii", &["WIDTH 4", "POINTS 4"], &[&w, &p]),
        "POINTS 3, but 4 lines",
    );
    // PLY: vertex counts beyond the maximum, beyond the data, and short of it.
    let ply = |format: &str, count: &str, body: &[u8]| {
        let mut b = format!(
            "ply\nformat {format} 1.0\nelement vertex {count}\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
        )
        .into_bytes();
        b.extend(body);
        b
    };
    let binary: Vec<u8> = points
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let text: String = points
        .iter()
        .map(|p| format!("{} {} {}\n", p[0], p[1], p[2]))
        .collect();
    for (name, format, count, body, expected) in [
        (
            "huge.ply",
            "binary_little_endian",
            "2305843009213693952",
            &binary,
            "more than the 100000000 points",
        ),
        (
            "big.ply",
            "binary_little_endian",
            "4000000000",
            &binary,
            "more than the 100000000 points",
        ),
        (
            "more.ply",
            "binary_little_endian",
            "5",
            &binary,
            "48 bytes of data, 5 vertices of 12 bytes need 60",
        ),
        (
            "fewer.ply",
            "binary_little_endian",
            "3",
            &binary,
            "need 36 (and no other element follows)",
        ),
        (
            "ascii_more.ply",
            "ascii",
            "1000",
            &text.clone().into_bytes(),
            "hold fewer vertices",
        ),
        (
            "ascii_fewer.ply",
            "ascii",
            "3",
            &text.clone().into_bytes(),
            "more data lines than the 3 vertices",
        ),
    ] {
        check(name, ply(format, count, body), expected);
    }
}

/// x y z, 4 bytes of padding per point, `pad` bytes after each row of `width` points, through
/// the library's encoder.
fn point_cloud2(
    points: &[[f32; 3]],
    big_endian: bool,
    float64: bool,
    (width, height, pad): (u32, u32, u32),
) -> msg::PointCloud2<'static> {
    let (size, datatype) = if float64 {
        (8, msg::PointField::FLOAT64)
    } else {
        (4, msg::PointField::FLOAT32)
    };
    let header = msg::Header {
        stamp: msg::Time {
            sec: 12,
            nanosec: 34,
        },
        frame_id: "camera".into(),
    };
    let layout = pointcloud2::Layout {
        width,
        height,
        datatype,
        big_endian,
        point_step: 3 * size + 4,
        row_padding: pad,
        rgb: None,
        pad: 0xAB,
    };
    pointcloud2::encode(header, points, &layout).unwrap()
}

/// CDR with its encapsulation header, either byte order.
fn cdr(m: &msg::PointCloud2, big_endian: bool) -> Vec<u8> {
    if !big_endian {
        return msg::encode(m).unwrap();
    }
    let body = cdr_encoding::to_vec::<_, BigEndian>(m).unwrap();
    [vec![0, 0, 0, 0], body].concat()
}

#[test]
fn point_cloud2_round_trip() {
    let points = sample();
    let n = points.len() as u32;
    // Unorganized and dense rows; organized (2 rows) with 12 bytes of row padding.
    let layouts = [(n, 1, 0), (n / 2, 2, 12)];
    for big_endian in [false, true] {
        for float64 in [false, true] {
            for (width, height, pad) in layouts {
                let points = &points[..(width * height) as usize];
                let m = point_cloud2(points, big_endian, float64, (width, height, pad));
                for cdr_big in [false, true] {
                    let bytes = cdr(&m, cdr_big);
                    let decoded = pointcloud2::decode(&bytes).unwrap();
                    assert_eq!(decoded, m);
                    let c = decoded.to_cloud().unwrap();
                    let case = format!("{big_endian} {float64} {width}x{height}");
                    assert!(same(&c.points, points), "{case}");
                    assert_eq!((c.width, c.height), (width, height), "{case}");
                    assert_eq!(c.frame_id.as_deref(), Some("camera"));
                    assert_eq!(c.stamp, Some((12, 34)));
                }
            }
        }
    }
}

/// Every malformed case of the decoder gives its own error, naming the frame; the next message
/// still decodes.
#[test]
fn malformed_point_cloud2_are_errors() {
    let points = sample();
    let n = points.len() as u32;
    let good = || point_cloud2(&points, false, false, (n, 1, 0));
    type Break = fn(&mut msg::PointCloud2<'static>);
    let cases: [(&str, Break, &str); 8] = [
        ("short data", |m| m.height = 2, "less than row_step"),
        (
            "truncated bytes",
            |m| m.data.to_mut().truncate(20),
            "less than row_step",
        ),
        ("missing z", |m| m.fields[2].name = "w".into(), "no field z"),
        (
            "unknown datatype",
            |m| m.fields[1].datatype = 9,
            "datatype 9 unknown",
        ),
        ("count 2", |m| m.fields[0].count = 2, "overlap"),
        ("count 0", |m| m.fields[0].count = 0, "count 0"),
        ("overlapping fields", |m| m.fields[1].offset = 2, "overlap"),
        (
            "field past point_step",
            |m| m.fields[2].offset = 14,
            "exceed point_step",
        ),
    ];
    for (name, break_it, expected) in cases {
        let mut m = good();
        break_it(&mut m);
        let bytes = cdr(&m, false);
        let e = pointcloud2::cloud_from_cdr(&bytes).unwrap_err().to_string();
        assert!(e.contains("camera") && e.contains(expected), "{name}: {e}");
        // The next, good message decodes.
        assert!(same(
            &pointcloud2::cloud_from_cdr(&cdr(&good(), false))
                .unwrap()
                .points,
            &points
        ));
    }
    // A count of 2 on x alone (no neighbour to overlap) is refused for its count.
    let mut m = good();
    m.fields.retain(|f| f.name != "y");
    m.fields[0].count = 2;
    m.fields.push(msg::PointField {
        name: "y".into(),
        offset: 12,
        datatype: msg::PointField::UINT8,
        count: 1,
    });
    let e = m.to_cloud().unwrap_err().to_string();
    assert!(e.contains("field x: count 2"), "{e}");
    // Bytes that are not a PointCloud2 at all.
    let e = pointcloud2::cloud_from_cdr(&[0, 1, 0, 0, 200, 0, 0, 0])
        .unwrap_err()
        .to_string();
    assert!(e.contains("PointCloud2"), "{e}");
}

fn write_bag(path: &Path, clouds: &[Vec<[f32; 3]>]) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::Writer::new(file).unwrap();
    let schema = w
        .add_schema(msg::PointCloud2::TYPE, "ros2msg", b"# test")
        .unwrap();
    let other = w
        .add_schema("std_msgs/msg/String", "ros2msg", b"string data")
        .unwrap();
    let text = w
        .add_channel(other, "/chatter", "cdr", &BTreeMap::new())
        .unwrap();
    let channel = w
        .add_channel(schema, "/points", "cdr", &BTreeMap::new())
        .unwrap();
    for (i, points) in clouds.iter().enumerate() {
        let header = |channel_id| mcap::records::MessageHeader {
            channel_id,
            sequence: i as u32,
            log_time: i as u64,
            publish_time: i as u64,
        };
        w.write_to_known_channel(&header(text), &[0, 1, 0, 0, 1, 0, 0, 0, 0])
            .unwrap();
        let m = point_cloud2(points, false, false, (points.len() as u32, 1, 0));
        w.write_to_known_channel(&header(channel), &cdr(&m, false))
            .unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn mcap_bags() {
    let dir = tempfile::tempdir().unwrap();
    let first = sample();
    let second = vec![[1.0, 2.0, 3.0]];
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    write_bag(&bag.join("bag_0.mcap"), &[first.clone(), second.clone()]);
    // The folder and the file, message 0 and 1; message 2 is an error saying how many exist.
    assert!(same(&cloud::load(&bag, 0).unwrap().points, &first));
    assert!(same(
        &cloud::load(&bag.join("bag_0.mcap"), 1).unwrap().points,
        &second
    ));
    let e = cloud::load(&bag, 2).unwrap_err().to_string();
    assert!(e.contains("2 PointCloud2"), "{e}");
    let e = cloud::load(&dir.path().join("nothing.xyz"), 0).unwrap_err();
    assert!(matches!(e, CloudError::UnknownFormat { .. }));
}

/// The real captures: the Kinect PointCloud2 of the MoveIt tutorial (MCAP) and PCL's
/// LZF-compressed PCDs.
#[test]
fn real_clouds() {
    let Some(shared) = common::shared() else {
        return;
    };
    let bag = shared.join("bags/moveit_perception_tutorial/perception_tutorial_mcap");
    let c = cloud::load(&bag, 0).unwrap();
    assert_eq!((c.width, c.height, c.points.len()), (640, 480, 307_200));
    assert_eq!(c.frame_id.as_deref(), Some("camera_rgb_optical_frame"));
    assert_eq!(
        c.points.iter().filter(|p| is_valid_point(**p)).count(),
        233_301
    );
    // SOURCE.md: camera-frame bounds of the finite points, z 0.700..1.649 m.
    let z = c
        .points
        .iter()
        .filter(|p| is_valid_point(**p))
        .fold((f32::INFINITY, 0.0f32), |(lo, hi), p| {
            (lo.min(p[2]), hi.max(p[2]))
        });
    assert!(
        (z.0 - 0.700).abs() < 1e-3 && (z.1 - 1.649).abs() < 1e-3,
        "{z:?}"
    );

    let mug = cloud::load(
        &shared.join("clouds/pcl_test/table_scene_mug_stereo_textured.pcd"),
        0,
    )
    .unwrap();
    assert_eq!((mug.width, mug.height), (640, 480));
    let valid = mug.points.iter().filter(|p| is_valid_point(**p)).count();
    assert!(valid > 100_000 && valid < 307_200, "{valid}");
    let milk = cloud::load(&shared.join("clouds/pcl_test/milk.pcd"), 0).unwrap();
    assert_eq!(milk.points.len(), 13_704);
    assert!(milk.points.iter().all(|p| is_valid_point(*p)));
}

proptest::proptest! {
    /// The library's encoder and decoder are inverse on every layout they share: any size,
    /// organized or not, FLOAT32 or FLOAT64, either byte order, point and row padding, an rgb
    /// field, NaN holes; through CDR of either byte order.
    #[test]
    fn point_cloud2_encoder_round_trips(
        (width, height) in (1u32..40, 1u32..6),
        float64 in proptest::bool::ANY,
        big_endian in proptest::bool::ANY,
        extra_step in 0u32..12,
        row_padding in 0u32..20,
        rgb in proptest::bool::ANY,
        cdr_big in proptest::bool::ANY,
        seed in proptest::num::u64::ANY,
    ) {
        let n = (width * height) as usize;
        let mut x = seed | 1;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let points: Vec<[f32; 3]> = (0..n)
            .map(|_| {
                if next() % 10 == 0 {
                    [f32::NAN; 3]
                } else {
                    std::array::from_fn(|_| (next() % 20_000) as f32 * 1e-3 - 10.0)
                }
            })
            .collect();
        let size = if float64 { 8 } else { 4 };
        let rgb_at = 3 * size + extra_step;
        let layout = pointcloud2::Layout {
            width,
            height,
            datatype: if float64 { msg::PointField::FLOAT64 } else { msg::PointField::FLOAT32 },
            big_endian,
            point_step: 3 * size + extra_step + if rgb { 4 } else { 0 },
            row_padding,
            rgb: rgb.then_some((rgb_at, (|p: [f32; 3]| [p[0] as u8, 7, 9]) as pointcloud2::Colour)),
            pad: 0x5A,
        };
        let m = pointcloud2::encode(msg::Header::default(), &points, &layout).unwrap();
        proptest::prop_assert_eq!(m.data.len() as u32, m.row_step * height);
        let bytes = cdr(&m, cdr_big);
        let c = pointcloud2::cloud_from_cdr(&bytes).unwrap();
        proptest::prop_assert!(same(&c.points, &points));
        proptest::prop_assert_eq!((c.width, c.height), (width, height));
    }
}

#[test]
fn point_cloud2_encoder_refuses_what_does_not_fit() {
    let header = msg::Header::default;
    let points = [[1.0f32, 2.0, 3.0]; 4];
    let mut layout = pointcloud2::Layout::unorganized(4);
    layout.width = 3;
    assert!(pointcloud2::encode(header(), &points, &layout).is_err());
    let mut layout = pointcloud2::Layout::unorganized(4);
    layout.point_step = 8;
    assert!(pointcloud2::encode(header(), &points, &layout).is_err());
    let mut layout = pointcloud2::Layout::unorganized(4);
    layout.rgb = Some((8, |_| [0, 0, 0]));
    assert!(pointcloud2::encode(header(), &points, &layout).is_err());
    let mut layout = pointcloud2::Layout::unorganized(4);
    layout.datatype = msg::PointField::UINT8;
    assert!(pointcloud2::encode(header(), &points, &layout).is_err());
    assert!(pointcloud2::encode(header(), &points, &pointcloud2::Layout::unorganized(4)).is_ok());
}

/// FLOAT64 coordinates are taken as far as f32 keeps them within 1e-5 m: 10.123456789 m is
/// decoded (to its f32 rounding), 1000.00002 m (which f32 moves by 2e-5 m) refuses the cloud
/// with the value and the reason, rather than measure a point that was not published.
#[test]
fn float64_coordinates_f32_cannot_keep_are_refused() {
    let with_x = |x: f64| {
        let mut m = point_cloud2(&[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]], false, true, (2, 1, 0));
        let mut data = m.data.to_vec();
        data[..8].copy_from_slice(&x.to_le_bytes());
        m.data = data.into();
        m.to_cloud()
    };
    let c = with_x(10.123456789).expect("decoded");
    assert_eq!(c.points[0], [10.123456789f64 as f32, 2.0, 3.0]);
    let e = with_x(1000.00002).unwrap_err().to_string();
    assert!(
        e.contains("1000.00002") && e.contains("rounded to f32") && e.contains("camera"),
        "{e}"
    );
}
