//! Animations written as PNG frames, for the tests of `timbre sonify` and the
//! `frames` form, and for `examples/frames/` (a test holds those files to this code).

use std::path::Path;

/// Writes `pixels` (row by row from the top, RGB in [0, 1]) as an 8-bit PNG.
pub fn write_png(path: &Path, width: usize, height: usize, pixels: &[[f64; 3]]) {
    let file = std::fs::File::create(path).expect("create a frame");
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width as u32, height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().expect("a PNG header");
    let bytes: Vec<u8> = pixels
        .iter()
        .flat_map(|p| p.map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8))
        .collect();
    writer.write_image_data(&bytes).expect("the frame's pixels");
}

/// Writes `count` frames `f-000.png`, `f-001.png`, … into `dir`, each
/// `width × height` pixels, pixel (x, y) of frame `t` given by `pixel(t, x, y)`.
pub fn write_animation(
    dir: &Path,
    count: usize,
    (width, height): (usize, usize),
    pixel: impl Fn(usize, usize, usize) -> [f64; 3],
) {
    std::fs::create_dir_all(dir).expect("a folder for the frames");
    for t in 0..count {
        let pixels: Vec<[f64; 3]> = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| pixel(t, x, y))
            .collect();
        write_png(&dir.join(format!("f-{t:03}.png")), width, height, &pixels);
    }
}

/// A value in [0, 1) that looks random, from a pixel's coordinates and a seed.
pub fn speckle(x: usize, y: usize, seed: u64) -> f64 {
    let mut z = (x as u64) << 32 ^ (y as u64) ^ seed.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
}

/// The example animation (`examples/frames/`, 48 frames at 24 fps, 64 × 48): a
/// warm sun rising and brightening on the left, a bar sweeping across the middle,
/// and a field of sand, rough and still, along the bottom right.
pub fn example_pixel(t: usize, x: usize, y: usize) -> [f64; 3] {
    let (w, h) = (64.0, 48.0);
    let (xf, yf, tf) = (x as f64, y as f64, t as f64 / 47.0);
    let sky = 0.1 + 0.5 * tf;
    let mut colour = [sky * 0.6, sky * 0.7, sky];
    // The sun: rising from below the middle to the top on the left.
    let (cx, cy) = (14.0, h * (0.7 - 0.5 * tf));
    if (xf - cx).hypot(yf - cy) < 7.0 {
        colour = [1.0, 0.8 * (0.5 + 0.5 * tf), 0.3];
    }
    // A bar sweeping left to right across the middle.
    let bar = w * (0.25 + 0.5 * tf);
    if (xf - bar).abs() < 3.0 && yf < h * 0.6 {
        colour = [0.9, 0.9, 0.9];
    }
    // Sand: the bottom right quarter, speckled, the same in every frame.
    if xf >= w * 0.5 && yf >= h * 0.65 {
        let grain = speckle(x, y, 1);
        colour = [0.55 + 0.4 * grain, 0.45 + 0.35 * grain, 0.25 + 0.2 * grain];
    }
    colour
}
