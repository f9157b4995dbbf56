//! Sound from moving images (Unemi, "Synthesis of sound effects for generative
//! animation", 2012): the statistics of each frame's vertical sub-regions, which the
//! `frames` form turns into keyframed variables (`lower/frames.rs`) and
//! `timbre sonify` maps to sound. Everything here is a pure function of the pixels.
//!
//! Colours are in HSB (hue, saturation, brightness; brightness = max(r, g, b)), each
//! in [0, 1].

/// Lanes of the harmonic brightness profile (the paper's 12 overtones, Eq. 2).
pub const ROWS: usize = 12;
/// Samples of the row-brightness scan waveform.
pub const SCAN: usize = 32;
/// Sub-regions at most (the paper's eight sound sources).
pub const MAX_REGIONS: usize = 8;

/// Pixels a frame may have: 2²⁴, such as 4096 × 4096 (4K UHD is half of it).
/// Statistics of vertical regions need no more; a larger frame is refused before
/// it is decoded.
pub const MAX_FRAME_PIXELS: u64 = 1 << 24;

/// Bytes of memory per pixel of a frame while it is read and analysed, at most:
/// the decoder's buffer (up to 16-bit RGBA, 8), the RGB bytes kept (3), the running
/// average of brightness (8) and the previous frame's brightness (1), rounded up.
pub const FRAME_BYTES_PER_PIXEL: u64 = 24;

/// A decoded frame: `width × height` pixels, row by row from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    /// Red, green and blue bytes of each pixel.
    pub rgb: Vec<[u8; 3]>,
}

impl Image {
    /// A PNG or JPEG file's width and height, read from its header alone.
    pub fn dimensions(bytes: &[u8]) -> Result<(u32, u32), String> {
        let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| e.to_string())?;
        reader.into_dimensions().map_err(|e| e.to_string())
    }

    /// A PNG or JPEG file's pixels (any colour type, made RGB). A frame of more than
    /// [`MAX_FRAME_PIXELS`] is refused before its pixels are decoded.
    pub fn decode(bytes: &[u8]) -> Result<Image, String> {
        let (width, height) = Image::dimensions(bytes)?;
        if u64::from(width) * u64::from(height) > MAX_FRAME_PIXELS {
            return Err(format!(
                "it is {width}×{height} pixels, more than {MAX_FRAME_PIXELS}"
            ));
        }
        let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| e.to_string())?;
        // The header read above may differ from what the decoder reads: bound both.
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(width);
        limits.max_image_height = Some(height);
        limits.max_alloc = Some(MAX_FRAME_PIXELS * FRAME_BYTES_PER_PIXEL);
        reader.limits(limits);
        let rgb = reader.decode().map_err(|e| e.to_string())?.into_rgb8();
        let (width, height) = (rgb.width() as usize, rgb.height() as usize);
        if width == 0 || height == 0 {
            return Err("the image has no pixels".into());
        }
        let pixels = rgb.pixels().map(|p| p.0).collect();
        Ok(Image {
            width,
            height,
            rgb: pixels,
        })
    }

    /// The colour of pixel `i` (row by row), each channel in [0, 1].
    fn colour(&self, i: usize) -> [f64; 3] {
        self.rgb[i].map(|c| f64::from(c) / 255.0)
    }

    fn hsb(&self, x: usize, y: usize) -> [f64; 3] {
        hsb(self.colour(y * self.width + x))
    }

    /// The brightness of pixel `i` as a byte: max(r, g, b).
    fn brightness_byte(&self, i: usize) -> u8 {
        let [r, g, b] = self.rgb[i];
        r.max(g).max(b)
    }
}

/// The widest frame number a pattern may pad to: the digits of the largest `u64`.
pub const MAX_NUMBER_WIDTH: usize = 20;

/// Why a file-name pattern cannot number frames.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PatternError {
    /// It has no `%d` or `%0Nd`.
    NoNumber,
    /// Its number is padded to this width (as written), wider than
    /// [`MAX_NUMBER_WIDTH`].
    TooWide(String),
}

/// A file-name pattern with one `%d` or `%0Nd` for the frame number.
pub struct Numbered {
    before: String,
    /// At most [`MAX_NUMBER_WIDTH`], so formatting cannot fail.
    width: usize,
    after: String,
}

impl Numbered {
    /// The pattern's parts, if it has a `%d` or `%0Nd` no wider than
    /// [`MAX_NUMBER_WIDTH`].
    pub fn parse(pattern: &str) -> Option<Numbered> {
        Numbered::new(pattern).ok()
    }

    /// The pattern's parts, or why it cannot number frames.
    pub fn new(pattern: &str) -> Result<Numbered, PatternError> {
        let at = pattern.find('%').ok_or(PatternError::NoNumber)?;
        let rest = &pattern[at + 1..];
        let digits =
            &rest[..rest.len() - rest.trim_start_matches(|c: char| c.is_ascii_digit()).len()];
        let after = rest[digits.len()..]
            .strip_prefix('d')
            .ok_or(PatternError::NoNumber)?;
        let width = match digits.parse::<usize>() {
            Ok(width) if width <= MAX_NUMBER_WIDTH => width,
            Err(_) if digits.is_empty() => 0,
            _ => return Err(PatternError::TooWide(digits.to_owned())),
        };
        Ok(Numbered {
            before: pattern[..at].to_owned(),
            width,
            after: after.to_owned(),
        })
    }

    /// The file name of frame `k`.
    pub fn path(&self, k: u64) -> String {
        format!(
            "{}{k:0width$}{}",
            self.before,
            self.after,
            width = self.width
        )
    }
}

/// Hue, saturation and brightness of an RGB colour (hue in turns, 0 for greys).
pub fn hsb([r, g, b]: [f64; 3]) -> [f64; 3] {
    let max = r.max(g).max(b);
    let min = r.min(g).min(b);
    let chroma = max - min;
    let saturation = if max > 0.0 { chroma / max } else { 0.0 };
    let hue = if chroma == 0.0 {
        0.0
    } else if max == r {
        ((g - b) / chroma).rem_euclid(6.0) / 6.0
    } else if max == g {
        ((b - r) / chroma + 2.0) / 6.0
    } else {
        ((r - g) / chroma + 4.0) / 6.0
    };
    [hue, saturation, max]
}

/// The statistics of one sub-region of one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Features {
    /// Mean brightness → pitch.
    pub brightness: f64,
    /// Its standard deviation → the low-pass filter's width.
    pub brightness_deviation: f64,
    /// Mean saturation → amplitude-modulation rate; its deviation → depth.
    pub saturation: f64,
    pub saturation_deviation: f64,
    /// Mean hue (circular, weighted by saturation, in turns) → frequency-modulation
    /// rate; its circular deviation → depth.
    pub hue: f64,
    pub hue_deviation: f64,
    /// Mean |b − v| against the weighted average of recent frames (Eq. 1) → loudness.
    pub motion: f64,
    /// Mean absolute brightness difference of neighbouring pixels → white noise.
    pub roughness: f64,
    /// Mean over rows of the brightness variance along the row → stereo phase shift.
    pub row_variance: f64,
    /// Centre of gravity of brightness across and down the region, in [0, 1] →
    /// a note's attack delay and tail.
    pub centroid_x: f64,
    pub centroid_y: f64,
    /// Mean brightness of 12 horizontal bands, top to bottom (the overtones, Eq. 2).
    pub rows: [f64; ROWS],
    /// The row-brightness scan: one period of a waveform in [−1, 1] (method 1).
    pub scan: [f64; SCAN],
}

/// The sub-region `r` of `regions` (vertical strips, left to right): its columns.
pub fn columns(width: usize, regions: usize, r: usize) -> std::ops::Range<usize> {
    (r * width / regions)..((r + 1) * width / regions).max(r * width / regions + 1)
}

/// Each frame's features, region by region (`[frame][region]`), from an
/// [`Analysis`]. Frames must share one size: the features stop at the first that
/// does not.
pub fn analyse(frames: &[Image], regions: usize, alpha: f64) -> Vec<Vec<Features>> {
    let mut analysis = Analysis::new(regions, alpha);
    frames.iter().map_while(|f| analysis.next(f)).collect()
}

/// The analysis of a sequence of frames, one at a time, keeping only what motion
/// needs: the running average of brightness, `v_t = α·b_{t−1} + (1 − α)·v_{t−1}`,
/// `v_0 = b_0` (the paper's Eq. 1, so the first frame has no motion), and the
/// previous frame's brightness (a byte per pixel).
pub struct Analysis {
    regions: usize,
    alpha: f64,
    /// Width and height of the first frame.
    size: Option<(usize, usize)>,
    average: Vec<f64>,
    previous: Vec<u8>,
}

impl Analysis {
    pub fn new(regions: usize, alpha: f64) -> Self {
        Analysis {
            regions: regions.clamp(1, MAX_REGIONS),
            alpha,
            size: None,
            average: vec![],
            previous: vec![],
        }
    }

    /// The regions each frame is cut into.
    pub fn regions(&self) -> usize {
        self.regions
    }

    /// The next frame's features, region by region; None if its size is not the
    /// first frame's, or it is narrower than the regions.
    pub fn next(&mut self, frame: &Image) -> Option<Vec<Features>> {
        let size = (frame.width, frame.height);
        if frame.width < self.regions || frame.rgb.len() != frame.width * frame.height {
            return None;
        }
        let brightness = |i: usize| f64::from(frame.brightness_byte(i)) / 255.0;
        match self.size {
            None => {
                self.size = Some(size);
                self.average = (0..frame.rgb.len()).map(brightness).collect();
            }
            Some(first) if first != size => return None,
            Some(_) => {
                let alpha = self.alpha;
                for (v, b_prev) in self.average.iter_mut().zip(&self.previous) {
                    *v = alpha * (f64::from(*b_prev) / 255.0) + (1.0 - alpha) * *v;
                }
            }
        }
        let (w, h) = size;
        let features = (0..self.regions)
            .map(|r| region_features(frame, &self.average, columns(w, self.regions, r), h))
            .collect();
        self.previous = (0..frame.rgb.len())
            .map(|i| frame.brightness_byte(i))
            .collect();
        Some(features)
    }
}

fn region_features(
    frame: &Image,
    average: &[f64],
    xs: std::ops::Range<usize>,
    height: usize,
) -> Features {
    let w = frame.width;
    let n = (xs.len() * height) as f64;
    let at = |x: usize, y: usize| f64::from(frame.brightness_byte(y * w + x)) / 255.0;
    let pixels = || (0..height).flat_map(|y| xs.clone().map(move |x| (x, y)));
    let mean = |f: &dyn Fn(usize, usize) -> f64| pixels().map(|(x, y)| f(x, y)).sum::<f64>() / n;
    let deviation = |f: &dyn Fn(usize, usize) -> f64, m: f64| {
        (pixels().map(|(x, y)| (f(x, y) - m).powi(2)).sum::<f64>() / n).sqrt()
    };
    let brightness = mean(&at);
    let saturation_of = |x: usize, y: usize| frame.hsb(x, y)[1];
    let saturation = mean(&saturation_of);

    // Hue is an angle: its mean and deviation are circular, each pixel weighted by
    // its saturation (a grey has no hue).
    let (mut s, mut c, mut weight) = (0.0, 0.0, 0.0);
    for (x, y) in pixels() {
        let [hue, sat, _] = frame.hsb(x, y);
        let angle = std::f64::consts::TAU * hue;
        s += sat * angle.sin();
        c += sat * angle.cos();
        weight += sat;
    }
    let (hue, hue_deviation) = if weight > 0.0 {
        let length = (s.hypot(c) / weight).min(1.0);
        let deviation = (-2.0 * length.max(1e-12).ln()).sqrt() / std::f64::consts::TAU;
        (
            s.atan2(c).rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU,
            deviation.min(1.0),
        )
    } else {
        (0.0, 0.0)
    };

    let motion = mean(&|x, y| (at(x, y) - average[y * w + x]).abs());
    let mut differences = (0.0, 0usize);
    for (x, y) in pixels() {
        if x + 1 < xs.end {
            differences.0 += (at(x + 1, y) - at(x, y)).abs();
            differences.1 += 1;
        }
        if y + 1 < height {
            differences.0 += (at(x, y + 1) - at(x, y)).abs();
            differences.1 += 1;
        }
    }
    let roughness = if differences.1 > 0 {
        differences.0 / differences.1 as f64
    } else {
        0.0
    };

    let row_means: Vec<f64> = (0..height)
        .map(|y| xs.clone().map(|x| at(x, y)).sum::<f64>() / xs.len() as f64)
        .collect();
    let row_variance = (0..height)
        .map(|y| {
            xs.clone()
                .map(|x| (at(x, y) - row_means[y]).powi(2))
                .sum::<f64>()
                / xs.len() as f64
        })
        .sum::<f64>()
        / height as f64;

    let total: f64 = pixels().map(|(x, y)| at(x, y)).sum();
    let (centroid_x, centroid_y) = if total > 0.0 {
        let span = |len: usize| (len.max(2) - 1) as f64;
        (
            pixels()
                .map(|(x, y)| at(x, y) * (x - xs.start) as f64)
                .sum::<f64>()
                / total
                / span(xs.len()),
            pixels().map(|(x, y)| at(x, y) * y as f64).sum::<f64>() / total / span(height),
        )
    } else {
        (0.5, 0.5)
    };

    let band = |k: usize, bands: usize| {
        let (y0, y1) = (
            k * height / bands,
            ((k + 1) * height / bands).max(k * height / bands + 1),
        );
        row_means[y0..y1.min(height)].iter().sum::<f64>() / (y1.min(height) - y0) as f64
    };
    let rows = std::array::from_fn(|k| band(k, ROWS));
    Features {
        brightness,
        brightness_deviation: deviation(&at, brightness),
        saturation,
        saturation_deviation: deviation(&saturation_of, saturation),
        hue,
        hue_deviation,
        motion,
        roughness,
        row_variance,
        centroid_x,
        centroid_y,
        rows,
        scan: scan(&row_means),
    }
}

/// The row-brightness scan (method 1): the row means resampled to [`SCAN`] samples,
/// scaled linearly to [−1, 1], faded in over the first quarter and out over the
/// last so that each period joins the next, and smoothed by a three-point moving
/// average (around the period).
pub fn scan(row_means: &[f64]) -> [f64; SCAN] {
    let resampled: Vec<f64> = (0..SCAN)
        .map(|i| {
            let y = (i as f64 + 0.5) * row_means.len() as f64 / SCAN as f64;
            row_means[(y as usize).min(row_means.len() - 1)]
        })
        .collect();
    let (lo, hi) = resampled
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
    let quarter = SCAN as f64 / 4.0;
    let shaped: Vec<f64> = resampled
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let unit = if hi > lo {
                2.0 * (v - lo) / (hi - lo) - 1.0
            } else {
                0.0
            };
            let fade = ((i as f64 + 0.5) / quarter)
                .min((SCAN as f64 - i as f64 - 0.5) / quarter)
                .min(1.0);
            unit * fade
        })
        .collect();
    std::array::from_fn(|i| {
        let (a, b, c) = (
            shaped[(i + SCAN - 1) % SCAN],
            shaped[i],
            shaped[(i + 1) % SCAN],
        );
        (a + b + c) / 3.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An image of colours in [0, 1], each channel rounded to a byte.
    fn image(width: usize, height: usize, pixel: impl Fn(usize, usize) -> [f64; 3]) -> Image {
        let rgb = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| pixel(x, y).map(|c| (c * 255.0).round() as u8))
            .collect();
        Image { width, height, rgb }
    }

    #[test]
    fn numbered_patterns_put_the_frame_number_in_place() {
        let padded = Numbered::parse("frames/f-%03d.png").unwrap();
        assert_eq!(padded.path(7), "frames/f-007.png");
        assert_eq!(Numbered::parse("f%d.jpg").unwrap().path(12), "f12.jpg");
        assert!(Numbered::parse("f.png").is_none());
        assert!(Numbered::parse("f%x.png").is_none());
    }

    #[test]
    fn numbered_patterns_refuse_widths_that_formatting_cannot_pad() {
        // A width past u16 made `format!` panic; past usize it was read as 0.
        for wide in ["f-%01000000000d.png", "f%99999999999999999999999d", "%021d"] {
            assert!(
                matches!(Numbered::new(wide), Err(PatternError::TooWide(_))),
                "{wide}"
            );
            assert!(Numbered::parse(wide).is_none());
        }
        let widest = Numbered::new("%020d").unwrap();
        assert_eq!(widest.path(u64::MAX), u64::MAX.to_string());
        assert_eq!(widest.path(7), format!("{:020}", 7));
        assert_eq!(Numbered::new("f%").err(), Some(PatternError::NoNumber));
        assert_eq!(Numbered::new("%%d").err(), Some(PatternError::NoNumber));
    }

    #[test]
    fn analysis_streams_frames_and_stops_at_a_change_of_size() {
        let grey = |v: f64| image(8, 6, move |_, _| [v, v, v]);
        let mut analysis = Analysis::new(2, 0.5);
        assert!(analysis.next(&grey(0.2)).is_some());
        assert!(analysis.next(&grey(0.4)).is_some());
        assert!(analysis.next(&image(6, 8, |_, _| [0.0; 3])).is_none());
        // Narrower than its regions.
        assert!(Analysis::new(8, 0.5)
            .next(&image(4, 4, |_, _| [0.0; 3]))
            .is_none());
        let frames = [grey(0.2), grey(0.4), image(6, 8, |_, _| [0.0; 3])];
        assert_eq!(analyse(&frames, 2, 0.5).len(), 2);
    }

    #[test]
    fn colours_convert_to_hue_saturation_and_brightness() {
        assert_eq!(hsb([1.0, 0.0, 0.0]), [0.0, 1.0, 1.0]);
        assert_eq!(hsb([0.0, 1.0, 0.0]), [1.0 / 3.0, 1.0, 1.0]);
        assert_eq!(hsb([0.0, 0.0, 0.5]), [2.0 / 3.0, 1.0, 0.5]);
        assert_eq!(hsb([0.4, 0.4, 0.4]), [0.0, 0.0, 0.4]);
    }

    #[test]
    fn brightness_motion_and_roughness_are_measured_per_region() {
        // Left half a flat grey that brightens; right half a checkerboard that stays.
        let frames: Vec<Image> = (0..4)
            .map(|t| {
                image(8, 6, |x, y| {
                    let v = if x < 4 {
                        0.2 + 0.2 * t as f64
                    } else {
                        ((x + y) % 2) as f64
                    };
                    [v, v, v]
                })
            })
            .collect();
        let features = analyse(&frames, 2, 0.5);
        assert_eq!(features.len(), 4);
        let (left, right) = (&features[3][0], &features[3][1]);
        assert!((left.brightness - 0.8).abs() < 1e-12);
        assert!((right.brightness - 0.5).abs() < 1e-12);
        assert_eq!(left.roughness, 0.0);
        assert_eq!(right.roughness, 1.0);
        assert_eq!(features[0][0].motion, 0.0);
        // v_1 = 0.5·b_0 + 0.5·v_0 = 0.2, v_2 = 0.5·0.4 + 0.5·0.2 = 0.3,
        // v_3 = 0.5·0.6 + 0.5·0.3 = 0.45: the motion is 0.8 − 0.45.
        assert!((left.motion - 0.35).abs() < 1e-12, "{}", left.motion);
        assert_eq!(right.motion, 0.0);
        assert!(left.brightness_deviation < 1e-12);
        assert!((right.brightness_deviation - 0.5).abs() < 1e-12);
    }

    #[test]
    fn hue_centroid_rows_and_scan() {
        // A red top half over a dark bottom: saturated red, bright at the top.
        let frame = image(4, 12, |_, y| {
            if y < 6 {
                [1.0, 0.0, 0.0]
            } else {
                [0.2, 0.2, 0.2]
            }
        });
        let f = &analyse(&[frame], 1, 0.3)[0][0];
        assert!(f.hue.abs() < 1e-12 || (f.hue - 1.0).abs() < 1e-12);
        assert!(f.hue_deviation < 1e-6);
        assert!((f.saturation - 0.5).abs() < 1e-12);
        assert!(f.centroid_y < 0.5 && (f.centroid_x - 0.5).abs() < 1e-12);
        assert_eq!(f.rows[0], 1.0);
        assert!((f.rows[11] - 0.2).abs() < 1e-12);
        // The scan starts and ends near 0 (faded) and is bright (positive) above.
        assert!(f.scan[0].abs() < 0.5 && f.scan[SCAN - 1].abs() < 0.5);
        assert!(f.scan[SCAN / 4] > 0.5 && f.scan[3 * SCAN / 4] < -0.5);
        assert!(f.scan.iter().all(|v| (-1.0..=1.0).contains(v)));
    }
}

#[cfg(test)]
mod decode_tests {
    use super::*;
    use image::ImageEncoder;

    #[test]
    fn png_and_jpeg_frames_decode_to_the_same_picture() {
        let (w, h) = (16u32, 8u32);
        let pixels: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let v = if i % w < w / 2 { 40 } else { 220 };
                [v, v, v]
            })
            .collect();
        let mut png = vec![];
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(&pixels, w, h, image::ExtendedColorType::Rgb8)
            .unwrap();
        let mut jpeg = vec![];
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95)
            .write_image(&pixels, w, h, image::ExtendedColorType::Rgb8)
            .unwrap();
        let (a, b) = (Image::decode(&png).unwrap(), Image::decode(&jpeg).unwrap());
        assert_eq!((a.width, a.height), (16, 8));
        let mean = |f: &Image| {
            analyse(std::slice::from_ref(f), 2, 0.3)[0]
                .iter()
                .map(|r| r.brightness)
                .collect::<Vec<_>>()
        };
        let (pa, pb) = (mean(&a), mean(&b));
        assert!((pa[0] - 40.0 / 255.0).abs() < 1e-12 && (pa[1] - 220.0 / 255.0).abs() < 1e-12);
        // JPEG is lossy: within a few levels.
        assert!(
            pa.iter().zip(&pb).all(|(x, y)| (x - y).abs() < 0.03),
            "{pa:?} {pb:?}"
        );
        assert!(Image::decode(b"not an image").is_err());
    }

    #[test]
    fn frames_over_the_pixel_bound_are_refused_from_their_header() {
        // 5000 × 4000 of one colour: a small file, 20 million pixels.
        let (w, h) = (5000u32, 4000u32);
        let pixels = vec![90u8; (w * h * 3) as usize];
        let mut png = vec![];
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(&pixels, w, h, image::ExtendedColorType::Rgb8)
            .unwrap();
        assert!(png.len() < 1 << 20, "{} bytes", png.len());
        assert_eq!(Image::dimensions(&png), Ok((w, h)));
        let refused = Image::decode(&png).unwrap_err();
        assert!(refused.contains("5000×4000"), "{refused}");
    }
}
