//! Depth images as a point source: `sensor_msgs/Image` with its `sensor_msgs/CameraInfo`,
//! turned into points the way `depth_image_proc` (`point_cloud_xyz`) does, so that a depth
//! image source and the PointCloud2 that node would make from it give the same points.
//!
//! A 640×480 depth image is 614 KB (16UC1) where the cloud made from it is 4.9–9.8 MB: the
//! image is what a camera should send over a network. The points are made in one parallel pass
//! over the rows, into a buffer the caller keeps from frame to frame (no allocation per frame
//! once it has grown), with the source's range limits applied in the same pass.
//!
//! **The formula** (`depth_image_proc::convertDepth`, in f32 as it computes): for pixel (u, v)
//! of depth `d` (the stored value: millimetres for `16UC1`, metres for `32FC1`),
//!
//! ```text
//! x = (u − cx)·d·kx,   y = (v − cy)·d·ky,   z = d·s,
//! kx = s / fx,  ky = s / fy   (computed in f64, rounded to f32),
//! s = 0.001 (f32) for 16UC1, 1 for 32FC1
//! ```
//!
//! with `fx fy cx cy` from the projection matrix P (`image_geometry::PinholeCameraModel` reads
//! them there; K where P is not set). `0` (16UC1) and NaN or ±∞ (32FC1) are no return: the point
//! is NaN, which the query counts as invalid, as it does a 32FC1 depth of 0 (the point (0,0,0)).
//! As in `depth_image_proc`, the image is taken as rectified: the distortion coefficients are
//! not applied.
//!
//! **Checks**, each an error naming the image's frame and the field: an encoding other than
//! `16UC1`/`mono16`/`32FC1`, `is_bigendian` other than 0 or 1, `step` shorter than a row,
//! `data` of another length than `step × height`, more than [`super::MAX_POINTS`] pixels;
//! a camera whose `width`/`height` differ from the image's, whose focal lengths are not finite
//! and non-zero, whose principal point is not finite, or that asks for binning or a region of
//! interest (the pixel grid would then not be the image's). The latest CameraInfo of the
//! source is used (intrinsics do not change while a camera streams).

use rayon::prelude::*;

use crate::msg::{CameraInfo, Image};

use super::error::CloudError;
use super::points::{RangeLimits, MAX_POINTS};

/// How a depth image stores its depths.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DepthEncoding {
    /// `16UC1` (or `mono16`): unsigned millimetres, 0 = no return.
    Millimetres16,
    /// `32FC1`: float metres, NaN or ±∞ = no return.
    Metres32,
}

impl DepthEncoding {
    /// The encoding named by `sensor_msgs/Image::encoding`.
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "16UC1" | "mono16" => Some(Self::Millimetres16),
            "32FC1" => Some(Self::Metres32),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Millimetres16 => "16UC1",
            Self::Metres32 => "32FC1",
        }
    }

    /// Bytes per pixel.
    pub fn size(self) -> usize {
        match self {
            Self::Millimetres16 => 2,
            Self::Metres32 => 4,
        }
    }

    /// Metres per stored unit, as `depth_image_proc` computes it (f32).
    pub fn unit(self) -> f32 {
        match self {
            Self::Millimetres16 => 0.001,
            Self::Metres32 => 1.0,
        }
    }
}

/// The pinhole model of a depth camera, from its CameraInfo.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeCamera {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl PinholeCamera {
    /// The model of `info`, checked (see the module's list).
    pub fn from_camera_info(info: &CameraInfo) -> Result<Self, CloudError> {
        let error = |message: String| CloudError::Camera {
            frame: info.header.frame_id.clone(),
            message,
        };
        // image_geometry reads the projection from P; a CameraInfo with P unset has K only.
        let (fx, fy, cx, cy, matrix) = if info.p[0] != 0.0 {
            (info.p[0], info.p[5], info.p[2], info.p[6], "p")
        } else {
            (info.k[0], info.k[4], info.k[2], info.k[5], "k")
        };
        for (name, v) in [("fx", fx), ("fy", fy)] {
            if !v.is_finite() || v == 0.0 {
                return Err(error(format!(
                    "field {matrix}: focal length {name} = {v} (not finite and non-zero)"
                )));
            }
        }
        for (name, v) in [("cx", cx), ("cy", cy)] {
            if !v.is_finite() {
                return Err(error(format!(
                    "field {matrix}: principal point {name} = {v}"
                )));
            }
        }
        if info.binning_x > 1 || info.binning_y > 1 {
            return Err(error(format!(
                "fields binning_x/binning_y = {}/{}: binned images are not supported",
                info.binning_x, info.binning_y
            )));
        }
        let roi = &info.roi;
        let full = (roi.x_offset, roi.y_offset) == (0, 0)
            && (roi.width == 0 || roi.width == info.width)
            && (roi.height == 0 || roi.height == info.height);
        if !full {
            return Err(error(format!(
                "field roi: a region of interest ({}×{} at {}, {}) is not supported",
                roi.width, roi.height, roi.x_offset, roi.y_offset
            )));
        }
        if info.width == 0 || info.height == 0 {
            return Err(error(format!(
                "fields width/height = {}×{}: the camera has no image size",
                info.width, info.height
            )));
        }
        Ok(Self {
            width: info.width,
            height: info.height,
            fx,
            fy,
            cx,
            cy,
        })
    }
}

/// The checked layout of a depth image.
#[derive(Debug, Clone, Copy)]
struct Layout {
    encoding: DepthEncoding,
    big_endian: bool,
    width: usize,
    height: usize,
    step: usize,
}

fn layout(image: &Image, camera: &PinholeCamera) -> Result<Layout, CloudError> {
    let error = |message: String| CloudError::DepthImage {
        frame: image.header.frame_id.clone(),
        message,
    };
    let encoding = DepthEncoding::from_name(&image.encoding).ok_or_else(|| {
        error(format!(
            "field encoding: '{}' is not a depth encoding (16UC1 in millimetres, 32FC1 in metres)",
            image.encoding
        ))
    })?;
    let big_endian = match image.is_bigendian {
        0 => false,
        1 => true,
        b => return Err(error(format!("field is_bigendian: {b} (0 or 1)"))),
    };
    let (width, height) = (image.width as usize, image.height as usize);
    if (width as u64) * (height as u64) > MAX_POINTS {
        return Err(error(format!(
            "fields width/height: {width}×{height} pixels, more than {}",
            MAX_POINTS
        )));
    }
    let step = image.step as usize;
    if step < width * encoding.size() {
        return Err(error(format!(
            "field step: {step} bytes, shorter than a row of {width} {} pixels ({} bytes)",
            encoding.name(),
            width * encoding.size()
        )));
    }
    if image.data.len() as u64 != step as u64 * height as u64 {
        return Err(error(format!(
            "field data: {} bytes, but step × height = {step} × {height} = {}",
            image.data.len(),
            step as u64 * height as u64
        )));
    }
    if (camera.width, camera.height) != (image.width, image.height) {
        return Err(error(format!(
            "fields width/height: the image is {}×{} but its CameraInfo says {}×{}",
            image.width, image.height, camera.width, camera.height
        )));
    }
    Ok(Layout {
        encoding,
        big_endian,
        width,
        height,
        step,
    })
}

/// A checked depth image with the constants of its unprojection: what both the CPU
/// ([`DepthView::unproject_into`], [`DepthView::point`]) and the GPU (`query::gpu`, which
/// reads the image's bytes and these constants) unproject it with.
#[derive(Debug, Clone, Copy)]
pub struct DepthView<'a> {
    data: &'a [u8],
    layout: Layout,
    /// The principal point, f32, as `depth_image_proc` takes it.
    pub cx: f32,
    pub cy: f32,
    /// `unit / fx` and `unit / fy`, computed in f64 and rounded to f32.
    pub kx: f32,
    pub ky: f32,
    /// Metres per stored unit (f32).
    pub unit: f32,
    pub range: Option<RangeLimits>,
}

impl<'a> DepthView<'a> {
    /// `image` seen by `camera`, its points limited to `range`; checked (see the module doc).
    pub fn new(
        image: &'a Image,
        camera: &PinholeCamera,
        range: Option<RangeLimits>,
    ) -> Result<Self, CloudError> {
        let layout = layout(image, camera)?;
        let unit = layout.encoding.unit();
        // As depth_image_proc: the principal point in f32, the scales computed in f64 (the f32
        // unit widened) and rounded to f32.
        Ok(Self {
            data: &image.data,
            layout,
            cx: camera.cx as f32,
            cy: camera.cy as f32,
            kx: (f64::from(unit) / camera.fx) as f32,
            ky: (f64::from(unit) / camera.fy) as f32,
            unit,
            range,
        })
    }

    pub fn width(&self) -> usize {
        self.layout.width
    }

    pub fn height(&self) -> usize {
        self.layout.height
    }

    /// Pixels (points).
    pub fn len(&self) -> usize {
        self.layout.width * self.layout.height
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The image's bytes, `step × height`.
    pub fn data(&self) -> &'a [u8] {
        self.data
    }

    /// Bytes from one row to the next.
    pub fn step(&self) -> usize {
        self.layout.step
    }

    pub fn encoding(&self) -> DepthEncoding {
        self.layout.encoding
    }

    pub fn big_endian(&self) -> bool {
        self.layout.big_endian
    }

    /// The point of pixel `u` in a row whose bytes start at `row` and whose `v − cy` is `dy`:
    /// NaN for no return or outside the range limits.
    #[inline]
    fn point_in_row(&self, row: &[u8], u: usize, dy: f32) -> [f32; 3] {
        let Some(d) = depth_at(row, u, self.layout.encoding, self.layout.big_endian) else {
            return [f32::NAN; 3];
        };
        let q = [
            (u as f32 - self.cx) * d * self.kx,
            dy * d * self.ky,
            d * self.unit,
        ];
        if self.range.is_none_or(|r| r.keeps(q)) {
            q
        } else {
            [f32::NAN; 3]
        }
    }

    /// The point of pixel `i` (row-major), exactly as [`DepthView::unproject_into`] makes it.
    pub fn point(&self, i: usize) -> [f32; 3] {
        let l = &self.layout;
        let (v, u) = (i / l.width, i % l.width);
        let row = &self.data[v * l.step..v * l.step + l.width * l.encoding.size()];
        self.point_in_row(row, u, v as f32 - self.cy)
    }

    /// Every point, row by row into `points` (resized to width × height; its allocation is
    /// kept), in one parallel pass over the rows.
    pub fn unproject_into(&self, points: &mut Vec<[f32; 3]>) {
        let l = &self.layout;
        points.clear();
        points.resize(l.width * l.height, [f32::NAN; 3]);
        if l.width == 0 {
            return;
        }
        points
            .par_chunks_mut(l.width)
            .enumerate()
            .for_each(|(v, out)| {
                let row = &self.data[v * l.step..v * l.step + l.width * l.encoding.size()];
                let dy = v as f32 - self.cy;
                for (u, p) in out.iter_mut().enumerate() {
                    *p = self.point_in_row(row, u, dy);
                }
            });
    }
}

/// The points of `image` seen by `camera`, row by row into `points` (resized to width ×
/// height; its allocation is kept). A point outside `range` is NaN, as the monitor drops
/// out-of-range cloud points.
pub fn points_from_depth(
    image: &Image,
    camera: &PinholeCamera,
    range: Option<RangeLimits>,
    points: &mut Vec<[f32; 3]>,
) -> Result<(), CloudError> {
    DepthView::new(image, camera, range)?.unproject_into(points);
    Ok(())
}

/// The stored depth of pixel `u` of a row, as f32; `None` for no return.
#[inline]
fn depth_at(row: &[u8], u: usize, encoding: DepthEncoding, big_endian: bool) -> Option<f32> {
    match encoding {
        DepthEncoding::Millimetres16 => {
            let b = [row[2 * u], row[2 * u + 1]];
            let d = if big_endian {
                u16::from_be_bytes(b)
            } else {
                u16::from_le_bytes(b)
            };
            (d != 0).then_some(f32::from(d))
        }
        DepthEncoding::Metres32 => {
            let b = [row[4 * u], row[4 * u + 1], row[4 * u + 2], row[4 * u + 3]];
            let d = if big_endian {
                f32::from_be_bytes(b)
            } else {
                f32::from_le_bytes(b)
            };
            d.is_finite().then_some(d)
        }
    }
}

/// A depth image of `depths` (row-major, metres; NaN for no return) in `encoding`, little
/// endian with rows of exactly `width` pixels: the generator's and the tests' encoder.
/// 16UC1 rounds to the millimetre as `depth_image_proc` does (`d·1000 + 0.5`, truncated);
/// depths it cannot hold (≤ 0.5 mm, ≥ 65.535 m) are no return.
pub fn encode_depth(
    header: crate::msg::Header,
    width: u32,
    height: u32,
    depths: &[f32],
    encoding: DepthEncoding,
) -> Image<'static> {
    let mut data = Vec::with_capacity(depths.len() * encoding.size());
    for &d in depths {
        match encoding {
            DepthEncoding::Millimetres16 => {
                let mm = d * 1000.0 + 0.5;
                let v = if (1.0..65536.0).contains(&mm) {
                    mm as u16
                } else {
                    0
                };
                data.extend_from_slice(&v.to_le_bytes());
            }
            DepthEncoding::Metres32 => data.extend_from_slice(&d.to_le_bytes()),
        }
    }
    Image {
        header,
        height,
        width,
        encoding: encoding.name().into(),
        is_bigendian: 0,
        step: width * encoding.size() as u32,
        data: std::borrow::Cow::Owned(data),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Header;

    fn info(width: u32, height: u32) -> CameraInfo {
        CameraInfo {
            header: Header {
                frame_id: "cam".into(),
                ..Header::default()
            },
            width,
            height,
            k: [500.0, 0.0, 3.5, 0.0, 510.0, 2.5, 0.0, 0.0, 1.0],
            p: [
                500.0, 0.0, 3.5, 0.0, 0.0, 510.0, 2.5, 0.0, 0.0, 0.0, 1.0, 0.0,
            ],
            ..CameraInfo::default()
        }
    }

    #[test]
    fn malformed_images_and_cameras_name_the_field() {
        let camera = PinholeCamera::from_camera_info(&info(4, 2)).unwrap();
        let good = encode_depth(
            Header::default(),
            4,
            2,
            &[1.0; 8],
            DepthEncoding::Millimetres16,
        );
        let mut out = Vec::new();
        points_from_depth(&good, &camera, None, &mut out).unwrap();
        assert_eq!(out.len(), 8);
        let cases: Vec<(Image, &str)> = vec![
            (
                Image {
                    encoding: "rgb8".into(),
                    ..good.clone()
                },
                "field encoding",
            ),
            (
                Image {
                    is_bigendian: 7,
                    ..good.clone()
                },
                "field is_bigendian",
            ),
            (
                Image {
                    step: 6,
                    ..good.clone()
                },
                "field step",
            ),
            (
                Image {
                    data: std::borrow::Cow::Owned(vec![0; 15]),
                    ..good.clone()
                },
                "field data",
            ),
            (
                Image {
                    width: 2,
                    step: 4,
                    data: std::borrow::Cow::Owned(vec![0; 8]),
                    ..good.clone()
                },
                "CameraInfo says 4×2",
            ),
            (
                Image {
                    width: 1 << 20,
                    height: 1 << 10,
                    step: 2 << 20,
                    ..good.clone()
                },
                "more than",
            ),
        ];
        for (image, want) in cases {
            let e = points_from_depth(&image, &camera, None, &mut out)
                .unwrap_err()
                .to_string();
            assert!(e.contains(want), "{e} lacks {want}");
        }
        let mut bad = info(4, 2);
        bad.p[5] = 0.0;
        let e = PinholeCamera::from_camera_info(&bad)
            .unwrap_err()
            .to_string();
        assert!(e.contains("field p") && e.contains("fy"), "{e}");
        let mut bad = info(4, 2);
        bad.binning_x = 2;
        assert!(PinholeCamera::from_camera_info(&bad)
            .unwrap_err()
            .to_string()
            .contains("binning"));
        let mut bad = info(4, 2);
        bad.roi.width = 2;
        assert!(PinholeCamera::from_camera_info(&bad)
            .unwrap_err()
            .to_string()
            .contains("field roi"));
        // P unset: K is used.
        let mut k_only = info(4, 2);
        k_only.p = [0.0; 12];
        let c = PinholeCamera::from_camera_info(&k_only).unwrap();
        assert_eq!((c.fx, c.fy, c.cx, c.cy), (500.0, 510.0, 3.5, 2.5));
    }
}
