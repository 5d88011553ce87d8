//! Pictures of point clouds for reports: orthographic views rendered by ggs itself, with no
//! window system and no GPU.
//!
//! A view projects every point `p` to image coordinates `(p·r, p·u)` for two orthonormal
//! axes `r` (right) and `u` (up), and keeps, per pixel, the point nearest the viewer (largest
//! `p·(r × u)`: a z-buffer). Each cloud has one colour, shaded by depth (nearer is brighter:
//! the colour times `0.45 + 0.55·t`, `t ∈ [0, 1]` over the image's depth range), so
//! overlapping surfaces read as in front of or behind each other. The picture is framed on
//! the points it shows with a 4 % margin and one scale for both axes (no distortion).
//!
//! Large clouds are shown through an evenly strided subsample of at most
//! [`DISPLAY_POINTS`] points per cloud ([`display_sample`]): the picture of a 5-million-point
//! scan costs what a 200k-point one does. Rendering is sequential and deterministic.

use crate::transform::Point;
#[cfg(feature = "report")]
use base64::Engine;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};

/// Points per cloud at most in a picture (more are strided down to this).
pub const DISPLAY_POINTS: usize = 200_000;

/// Target colour (blue) and source colour (orange), sRGB.
pub const TARGET_COLOR: [u8; 3] = [40, 110, 230];
pub const SOURCE_COLOR: [u8; 3] = [245, 130, 20];
/// Background (white).
const BACKGROUND: [u8; 3] = [255, 255, 255];

/// An RGB picture, rows top to bottom, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<u8>,
}

/// One cloud drawn in one colour.
#[derive(Debug, Clone, Copy)]
pub struct Layer<'a> {
    pub points: &'a [Point],
    pub color: [u8; 3],
}

/// An orthographic view: the image's right and up directions (orthonormal).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    pub name: &'static str,
    pub right: Vector3<f64>,
    pub up: Vector3<f64>,
}

impl View {
    /// Toward the viewer: `right × up`.
    pub fn toward_viewer(&self) -> Vector3<f64> {
        self.right.cross(&self.up)
    }
}

/// At most `max` points of `points`, evenly strided (all of them when there are fewer).
pub fn display_sample(points: &[Point], max: usize) -> Vec<Point> {
    if points.len() <= max || max == 0 {
        return points.to_vec();
    }
    let stride = points.len().div_ceil(max);
    points.iter().step_by(stride).copied().collect()
}

/// The three views along the principal axes of `points` (eigenvectors of their covariance,
/// largest variance first: `e1, e2, e3`): "plan" (right `e1`, up `e2`), "front" (`e1`, `e3`)
/// and "side" (`e2`, `e3`). Each axis is signed so that its largest component is positive,
/// and `e3 = e1 × e2`, so the views are the same for the same cloud. World axes for fewer
/// than 3 points.
pub fn principal_views(points: &[Point]) -> [View; 3] {
    let [e1, e2, e3] = principal_axes(points);
    [
        View {
            name: "plan",
            right: e1,
            up: e2,
        },
        View {
            name: "front",
            right: e1,
            up: e3,
        },
        View {
            name: "side",
            right: e2,
            up: e3,
        },
    ]
}

fn principal_axes(points: &[Point]) -> [Vector3<f64>; 3] {
    let world = [Vector3::x(), Vector3::y(), Vector3::z()];
    let Some(c) = crate::cloud::centroid_of(points) else {
        return world;
    };
    let mut cov = Matrix3::zeros();
    for p in points {
        let d = Vector3::new(p[0] - c[0], p[1] - c[1], p[2] - c[2]);
        cov += d * d.transpose();
    }
    if points.len() < 3 || !cov.iter().all(|v| v.is_finite()) {
        return world;
    }
    let eig = SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    let signed = |v: Vector3<f64>| {
        let k = v.iamax();
        if v[k] < 0.0 {
            -v
        } else {
            v
        }
    };
    let e1 = signed(eig.eigenvectors.column(order[0]).into_owned());
    let e2 = signed(eig.eigenvectors.column(order[1]).into_owned());
    [e1, e2, e1.cross(&e2)]
}

/// Render `layers` (later layers win ties) in `view` into a `width × height` picture.
pub fn render(layers: &[Layer], view: &View, width: usize, height: usize) -> Image {
    let w = view.toward_viewer();
    let project = |p: &Point| {
        let v = Vector3::new(p[0], p[1], p[2]);
        (v.dot(&view.right), v.dot(&view.up), v.dot(&w))
    };
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    let mut count = 0usize;
    for layer in layers {
        for p in layer.points {
            let (x, y, z) = project(p);
            for (k, v) in [x, y, z].into_iter().enumerate() {
                lo[k] = lo[k].min(v);
                hi[k] = hi[k].max(v);
            }
            count += 1;
        }
    }
    let mut image = Image::blank(width, height);
    if count == 0 || width == 0 || height == 0 {
        return image;
    }
    let (sx, sy) = (hi[0] - lo[0], hi[1] - lo[1]);
    let span = sx.max(sy);
    let scale = if span > 0.0 {
        0.92 * (width as f64 / sx.max(span * 1e-9)).min(height as f64 / sy.max(span * 1e-9))
    } else {
        1.0
    };
    let (cx, cy) = ((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
    let depth_span = (hi[2] - lo[2]).max(f64::MIN_POSITIVE);
    let splat = splat_size(count, width, height);
    let mut depth = vec![f64::NEG_INFINITY; width * height];
    for layer in layers {
        for p in layer.points {
            let (x, y, z) = project(p);
            let px = (width as f64 / 2.0 + (x - cx) * scale).floor() as i64;
            let py = (height as f64 / 2.0 - (y - cy) * scale).floor() as i64;
            let t = ((z - lo[2]) / depth_span).clamp(0.0, 1.0);
            let color = shade(layer.color, t);
            image.splat(&mut depth, px, py, splat, z, color);
        }
    }
    image
}

/// Side of the square drawn per point, pixels: about 0.8 of the picture covered if the points
/// were spread evenly, between 1 and 4.
fn splat_size(points: usize, width: usize, height: usize) -> i64 {
    let side = (0.8 * (width * height) as f64 / points as f64).sqrt();
    side.round().clamp(1.0, 4.0) as i64
}

/// `color · (0.45 + 0.55·t)`.
fn shade(color: [u8; 3], t: f64) -> [u8; 3] {
    let f = 0.45 + 0.55 * t;
    color.map(|c| (c as f64 * f).round() as u8)
}

impl Image {
    /// A picture of the background colour.
    pub fn blank(width: usize, height: usize) -> Image {
        Image {
            width,
            height,
            pixels: BACKGROUND.repeat(width * height),
        }
    }

    /// Draw a `side × side` square at `(px, py)` where it is nearer than what is there.
    fn splat(&mut self, depth: &mut [f64], px: i64, py: i64, side: i64, z: f64, c: [u8; 3]) {
        let (w, h) = (self.width as i64, self.height as i64);
        for y in py..py + side {
            for x in px..px + side {
                if x < 0 || y < 0 || x >= w || y >= h {
                    continue;
                }
                let i = (y * w + x) as usize;
                if z >= depth[i] {
                    depth[i] = z;
                    self.pixels[3 * i..3 * i + 3].copy_from_slice(&c);
                }
            }
        }
    }

    /// Pixels that differ from the background.
    pub fn painted_pixels(&self) -> usize {
        self.pixels
            .chunks_exact(3)
            .filter(|p| *p != BACKGROUND)
            .count()
    }

    /// Pictures side by side in rows of `columns`, each cell the size of the largest, with a
    /// `gap`-pixel light grey border between cells.
    pub fn grid(images: &[Image], columns: usize, gap: usize) -> Image {
        let columns = columns.max(1);
        let cw = images.iter().map(|i| i.width).max().unwrap_or(0);
        let ch = images.iter().map(|i| i.height).max().unwrap_or(0);
        let rows = images.len().div_ceil(columns);
        let width = columns * cw + (columns + 1) * gap;
        let height = rows * ch + (rows + 1) * gap;
        let mut out = Image {
            width,
            height,
            pixels: [225u8, 225, 225].repeat(width * height),
        };
        for (k, img) in images.iter().enumerate() {
            let (x0, y0) = (
                gap + (k % columns) * (cw + gap),
                gap + (k / columns) * (ch + gap),
            );
            for y in 0..ch {
                let row = 3 * ((y0 + y) * width + x0);
                if y < img.height {
                    let src = &img.pixels[3 * y * img.width..3 * (y + 1) * img.width];
                    out.pixels[row..row + src.len()].copy_from_slice(src);
                    let rest = 3 * (cw - img.width);
                    out.pixels[row + src.len()..row + src.len() + rest].fill(255);
                } else {
                    out.pixels[row..row + 3 * cw].fill(255);
                }
            }
        }
        out
    }

    /// The picture as a PNG file (8-bit RGB, default compression).
    #[cfg(feature = "report")]
    pub fn png(&self) -> Vec<u8> {
        let mut bytes = Vec::new();
        let mut encoder = png::Encoder::new(&mut bytes, self.width as u32, self.height as u32);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder
            .write_header()
            .expect("writing a PNG header to memory cannot fail");
        writer
            .write_image_data(&self.pixels)
            .expect("the pixel buffer has width × height × 3 bytes");
        writer
            .finish()
            .expect("finishing a PNG in memory cannot fail");
        bytes
    }

    /// The PNG as a `data:` URL, for an `<img src>` inside a self-contained HTML page.
    #[cfg(feature = "report")]
    pub fn data_url(&self) -> String {
        let b64 = base64::engine::general_purpose::STANDARD.encode(self.png());
        format!("data:image/png;base64,{b64}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(n: usize, z: f64) -> Vec<Point> {
        (0..n * n)
            .map(|k| [(k % n) as f64, (k / n) as f64, z])
            .collect()
    }

    fn pixel(img: &Image, x: usize, y: usize) -> [u8; 3] {
        let i = 3 * (y * img.width + x);
        [img.pixels[i], img.pixels[i + 1], img.pixels[i + 2]]
    }

    const TOP: View = View {
        name: "top",
        right: Vector3::new(1.0, 0.0, 0.0),
        up: Vector3::new(0.0, 1.0, 0.0),
    };

    #[test]
    fn the_nearer_cloud_hides_the_farther_one_whatever_the_layer_order() {
        let (near, far) = (square(40, 1.0), square(40, 0.0));
        let red = Layer {
            points: &near,
            color: [255, 0, 0],
        };
        let blue = Layer {
            points: &far,
            color: [0, 0, 255],
        };
        for layers in [[red, blue], [blue, red]] {
            let img = render(&layers, &TOP, 64, 64);
            assert_eq!(
                pixel(&img, 32, 32),
                [255, 0, 0],
                "nearest layer at full brightness"
            );
        }
    }

    #[test]
    fn the_picture_is_framed_on_its_points_and_keeps_the_aspect() {
        // A 10 × 1 strip fills the width, not the height.
        let strip: Vec<Point> = (0..1000)
            .map(|k| [k as f64 / 100.0, (k % 10) as f64 / 10.0, 0.0])
            .collect();
        let img = render(
            &[Layer {
                points: &strip,
                color: [0, 0, 0],
            }],
            &TOP,
            100,
            100,
        );
        let painted_rows: Vec<usize> = (0..100)
            .filter(|&y| (0..100).any(|x| pixel(&img, x, y) != BACKGROUND))
            .collect();
        let painted_cols = (0..100)
            .filter(|&x| (0..100).any(|y| pixel(&img, x, y) != BACKGROUND))
            .count();
        assert!(painted_cols >= 90, "{painted_cols} columns");
        assert!(painted_rows.len() <= 14, "{} rows", painted_rows.len());
        // The strip's bottom edge (y = 0) is drawn below its top edge (up is up).
        let img2 = render(
            &[
                Layer {
                    points: &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
                    color: [0, 0, 0],
                },
                Layer {
                    points: &[[0.0, 1.0, 0.0]],
                    color: [255, 0, 0],
                },
            ],
            &TOP,
            50,
            50,
        );
        let rows_of = |want: fn([u8; 3]) -> bool| {
            (0..50).find(|&y| (0..50).any(|x| want(pixel(&img2, x, y))))
        };
        let red_y = rows_of(|p| p[0] > 0 && p[1] == 0).unwrap();
        let black_y = rows_of(|p| p == [0, 0, 0]).unwrap();
        assert!(
            red_y < black_y,
            "red (y = 1) at row {red_y}, black (y = 0) at {black_y}"
        );
    }

    #[test]
    fn principal_views_see_the_largest_extent_in_plan() {
        // A flat slab, long in z, wide in x, thin in y.
        let pts: Vec<Point> = (0..2000)
            .map(|k| {
                [
                    ((k % 20) as f64) * 0.5,
                    (k % 3) as f64 * 0.01,
                    (k / 20) as f64,
                ]
            })
            .collect();
        let [plan, front, side] = principal_views(&pts);
        assert!(
            (plan.right - Vector3::z()).norm() < 1e-4,
            "{:?}",
            plan.right
        );
        assert!((plan.up - Vector3::x()).norm() < 1e-4, "{:?}", plan.up);
        assert!(plan.toward_viewer().y.abs() > 0.999);
        for v in [plan, front, side] {
            assert!(v.right.dot(&v.up).abs() < 1e-12 && (v.right.norm() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn empty_and_degenerate_inputs_give_a_blank_picture_not_a_panic() {
        assert_eq!(render(&[], &TOP, 8, 8).painted_pixels(), 0);
        let one = [[1.0, 2.0, 3.0]];
        let img = render(
            &[Layer {
                points: &one,
                color: [0, 0, 0],
            }],
            &TOP,
            8,
            8,
        );
        assert!(img.painted_pixels() >= 1);
        let _ = principal_views(&one);
        assert_eq!(
            render(
                &[Layer {
                    points: &one,
                    color: [0, 0, 0]
                }],
                &TOP,
                0,
                0
            )
            .pixels
            .len(),
            0
        );
    }

    #[test]
    fn display_sample_strides_to_at_most_max() {
        let pts = square(100, 0.0);
        let s = display_sample(&pts, 3000);
        assert!(s.len() <= 3000 && s.len() >= 2500, "{}", s.len());
        assert_eq!(s[0], pts[0]);
        assert_eq!(display_sample(&pts, 20_000).len(), 10_000);
    }

    #[test]
    fn grid_places_cells_and_png_round_trips_its_size() {
        let a = Image::blank(4, 3);
        let mut b = Image::blank(2, 2);
        b.pixels.fill(0);
        let g = Image::grid(&[a, b], 2, 1);
        assert_eq!((g.width, g.height), (2 * 4 + 3, 3 + 2));
        assert_eq!(pixel(&g, 6, 1), [0, 0, 0]);
        assert_eq!(pixel(&g, 0, 0), [225, 225, 225]);
        let png = g.png();
        assert_eq!(&png[1..4], b"PNG");
        assert_eq!(u32::from_be_bytes(png[16..20].try_into().unwrap()), 11);
        assert!(g.data_url().starts_with("data:image/png;base64,iVBOR"));
    }
}
