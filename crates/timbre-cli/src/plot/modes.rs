//! Pictures of a shape's modes: the voxel surface displaced by a mode's shape, seen
//! from above and to one side (orthographic, 35° around and 25° above), coloured by
//! how far each point moves (dark: still, pale yellow: most), shaded by a light
//! from the viewer's upper left. The displacement is scaled so the point that moves
//! most moves 8 % of the solid's largest side.

use glam::DVec3;
use timbre_modal::model::Model;

use super::canvas::{Canvas, Rgb};
use super::font::{draw_text, text_height, Align};
use super::inferno;
use crate::output::Output;

const BACKGROUND: Rgb = Rgb(255, 255, 255);
const INK: Rgb = Rgb(0, 0, 0);
const SCALE: usize = 2;
/// The largest displacement drawn, as a fraction of the largest side.
const SWING: f64 = 0.08;

/// Draws mode `mode` (from 0) of `model` as a PNG of `width` × `height` pixels.
pub fn mode_png(
    model: &Model,
    mode: usize,
    width: usize,
    height: usize,
    output: Output,
) -> Result<(), String> {
    let canvas = draw_mode(model, mode, width, height)?;
    let m = &model.modes[mode];
    let text = [
        ("timbre:mode".to_owned(), (mode + 1).to_string()),
        ("timbre:frequency".to_owned(), format!("{}", m.frequency)),
    ];
    canvas.write_png(output, &text)
}

/// The picture of one mode (see the module docs).
pub fn draw_mode(
    model: &Model,
    mode: usize,
    width: usize,
    height: usize,
) -> Result<Canvas, String> {
    let count = model.modes.len();
    if mode >= count {
        return Err(format!(
            "there is no mode {} (the model has {count})",
            mode + 1
        ));
    }
    let surface = &model.surface;
    let shape = |point: usize| -> DVec3 {
        DVec3::from_array([0, 1, 2].map(|a| surface.shapes[(point * count + mode) * 3 + a] as f64))
    };
    let largest_motion = (0..surface.points.len())
        .map(|p| shape(p).length())
        .fold(0.0, f64::max);
    let (low, high) = model.bounds;
    let side = (0..3).map(|a| high[a] - low[a]).fold(0.0, f64::max);
    let swing = if largest_motion > 0.0 {
        SWING * side / largest_motion
    } else {
        0.0
    };
    let (azimuth, elevation) = (35f64.to_radians(), 25f64.to_radians());
    let toward_viewer = DVec3::new(
        elevation.cos() * azimuth.sin(),
        -elevation.cos() * azimuth.cos(),
        elevation.sin(),
    );
    let right = DVec3::Z.cross(toward_viewer).normalize_or_zero();
    let up = toward_viewer.cross(right);
    let light = (toward_viewer - 0.4 * right + 0.5 * up).normalize_or_zero();
    // Each surface point displaced, and seen: (screen x, screen y, depth).
    let moved: Vec<DVec3> = (0..surface.points.len())
        .map(|p| DVec3::from_array(surface.points[p]) + swing * shape(p))
        .collect();
    let seen: Vec<[f64; 3]> = moved
        .iter()
        .map(|x| [x.dot(right), x.dot(up), x.dot(toward_viewer)])
        .collect();
    let caption = text_height(SCALE) as f64 + 16.0;
    let (area_w, area_h) = (width as f64 - 20.0, height as f64 - caption - 20.0);
    let (mut min, mut max) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for s in &seen {
        for a in 0..2 {
            min[a] = min[a].min(s[a]);
            max[a] = max[a].max(s[a]);
        }
    }
    let zoom = (area_w / (max[0] - min[0])).min(area_h / (max[1] - min[1]));
    if !(zoom.is_finite() && zoom > 0.0) {
        return Err("the model has no surface to draw".into());
    }
    let centre = [0.5 * (min[0] + max[0]), 0.5 * (min[1] + max[1])];
    let pixel = |s: [f64; 3]| {
        [
            width as f64 / 2.0 + (s[0] - centre[0]) * zoom,
            10.0 + area_h / 2.0 - (s[1] - centre[1]) * zoom,
            s[2],
        ]
    };
    let mut canvas = Canvas::new(width, height, BACKGROUND);
    let mut depth = vec![f64::NEG_INFINITY; width * height];
    for face in &surface.faces {
        let c = face.corners;
        for triangle in [[c[0], c[1], c[3]], [c[0], c[3], c[2]]] {
            let normal = (moved[triangle[1]] - moved[triangle[0]])
                .cross(moved[triangle[2]] - moved[triangle[0]])
                .normalize_or_zero();
            let shade = 0.35 + 0.65 * normal.dot(light).abs();
            let motion: Vec<f64> = triangle
                .iter()
                .map(|&p| shape(p).length() / largest_motion.max(f64::MIN_POSITIVE))
                .collect();
            let corners = triangle.map(|p| pixel(seen[p]));
            fill_triangle(&mut canvas, &mut depth, corners, |w| {
                let m = w[0] * motion[0] + w[1] * motion[1] + w[2] * motion[2];
                let Rgb(r, g, b) = inferno(0.2 + 0.8 * m);
                let dim = |x: u8| (x as f64 * shade).round() as u8;
                Rgb(dim(r), dim(g), dim(b))
            });
        }
    }
    let m = &model.modes[mode];
    let label = format!(
        "mode {} . {:.1} Hz . T60 {:.2} s",
        mode + 1,
        m.frequency,
        m.t60()
    );
    draw_text(
        &mut canvas,
        width as i64 / 2,
        (height as f64 - caption + 4.0) as i64,
        &label,
        SCALE,
        Align::Centre,
        INK,
    );
    Ok(canvas)
}

/// Fills a triangle given in pixels (x, y, depth), nearer (larger depth) over
/// farther, each pixel coloured by `color` of its barycentric weights.
fn fill_triangle(
    canvas: &mut Canvas,
    depth: &mut [f64],
    p: [[f64; 3]; 3],
    color: impl Fn([f64; 3]) -> Rgb,
) {
    let (width, height) = (canvas.width() as i64, canvas.height() as i64);
    let area =
        (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
    if area.abs() < 1e-12 {
        return;
    }
    // The pixels the triangle's box covers along `axis`, within the canvas.
    let covered = |axis: usize, pixels: i64| {
        let along = p.map(|q| q[axis]);
        let low = along.iter().copied().fold(f64::INFINITY, f64::min).floor() as i64;
        let high = along
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max)
            .ceil() as i64;
        (low.max(0), high.min(pixels - 1))
    };
    let ((x0, x1), (y0, y1)) = (covered(0, width), covered(1, height));
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let edge = |a: [f64; 3], b: [f64; 3]| {
                (b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])
            };
            let w = [
                edge(p[1], p[2]) / area,
                edge(p[2], p[0]) / area,
                edge(p[0], p[1]) / area,
            ];
            if w.iter().any(|&v| v < -1e-9) {
                continue;
            }
            let z = w[0] * p[0][2] + w[1] * p[1][2] + w[2] * p[2][2];
            let at = (y * width + x) as usize;
            if z > depth[at] {
                depth[at] = z;
                canvas.set(x, y, color(w));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use timbre_modal::model::{Damping, Material, Settings};
    use timbre_modal::shape::{Resolution, Shape};
    use timbre_modal::Elastic;

    use super::*;

    fn bar() -> Model {
        let steel = Material {
            elastic: Elastic {
                youngs: 200e9,
                poisson: 0.29,
                density: 7850.0,
            },
            damping: Damping::Loss(1e-4),
        };
        let settings = Settings {
            modes: 8,
            resolution: Resolution {
                voxel: Some(0.005),
                ..Resolution::default()
            },
        };
        let shape = Shape::Box {
            size: [0.2, 0.02, 0.01],
        };
        Model::analyse(&shape, &steel, &settings).expect("a bar")
    }

    #[test]
    fn a_mode_is_drawn_where_the_bar_is_and_moves_the_picture_as_it_bends() {
        let model = bar();
        let (w, h) = (320, 200);
        let first = draw_mode(&model, 0, w, h).expect("drawn");
        let second = draw_mode(&model, 1, w, h).expect("drawn");
        let painted = |c: &Canvas| {
            (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .filter(|&(x, y)| c.get(x, y) != BACKGROUND)
                .count()
        };
        // The bar fills a good part of the picture, not a speck and not all of it.
        let (a, b) = (painted(&first), painted(&second));
        assert!(a > w * h / 20 && a < w * h * 3 / 4, "{a} pixels");
        // Two modes bend the bar differently: the pictures differ.
        let differ = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| first.get(x, y) != second.get(x, y))
            .count();
        assert!(differ > a / 20, "{differ} pixels differ of {a} and {b}");
        assert!(draw_mode(&model, 8, w, h).is_err());
    }
}
