//! The `frames` form: a sequence of PNG or JPEG frames read as keyframed variables,
//! the statistics of each vertical sub-region (`crate::frames`), one key per frame.
//!
//! ```lisp
//! (frames video :pattern "frames/f-%03d.png" :fps 24 :regions 4)
//! ```
//!
//! defines `video-1-brightness` … `video-4-centroid-y` (one lane each) and
//! `video-K-rows` (12 lanes), `video-K-scan` (32 lanes), read between frames by
//! linear interpolation.

use std::sync::Arc;

use timbre_syntax::{Expr, ExprKind, Span};

use super::{Lowerer, Origin};
use crate::frames::{
    Analysis, Features, Image, Numbered, PatternError, FRAME_BYTES_PER_PIXEL, MAX_FRAME_PIXELS,
    MAX_NUMBER_WIDTH, MAX_REGIONS,
};
use timbre_diag::Diag;
use timbre_ir::keyframes::{Interpolation, KeyframeTrack};

const USAGE: &str = "(frames name :pattern \"frames/f-%03d.png\" :fps 24 :regions 4)";

/// Frames one form may read at most.
pub const MAX_FRAMES: usize = 100_000;

/// The largest `:first` frame number.
const MAX_FIRST: f64 = 1e9;

/// Bytes each frame costs per region until its keys are made: its features, and a
/// key (time and value) of each of its 55 tracks (11 statistics, 12 rows, 32 scan
/// samples).
const FRAME_KEY_BYTES: u64 = (std::mem::size_of::<Features>() + 55 * 16) as u64;

/// A statistic of a region, read from its features.
type Statistic = fn(&Features) -> f64;

/// The one-lane statistics, as the variables' names end.
pub const SCALARS: &[(&str, Statistic)] = &[
    ("brightness", |f| f.brightness),
    ("brightness-deviation", |f| f.brightness_deviation),
    ("saturation", |f| f.saturation),
    ("saturation-deviation", |f| f.saturation_deviation),
    ("hue", |f| f.hue),
    ("hue-deviation", |f| f.hue_deviation),
    ("motion", |f| f.motion),
    ("roughness", |f| f.roughness),
    ("row-variance", |f| f.row_variance),
    ("centroid-x", |f| f.centroid_x),
    ("centroid-y", |f| f.centroid_y),
];

impl Lowerer<'_> {
    pub(crate) fn read_frames(&mut self, form: &Expr, origin: &Origin) -> Result<(), Diag> {
        let items = form.as_list().unwrap_or_default();
        let Some((name, name_span)) = items.get(1).and_then(|e| Some((e.as_symbol()?, e.span)))
        else {
            return Err(self
                .diag("timbre::bad-frames", "`frames` needs a name", origin)
                .label(form.span, "no name")
                .help(format!("write {USAGE}")));
        };
        let options = self.options(
            &items[2..],
            "frames",
            &["pattern", "files", "first", "fps", "regions", "alpha"],
            origin,
        )?;
        let bad = |l: &Self, span, message: String, help: &str| {
            l.diag("timbre::bad-frames", message, origin)
                .label(span, "here")
                .help(help.to_owned())
        };
        let number = |l: &mut Self, key: &str, default: f64| match options.get(key) {
            Some(e) => l
                .constant_option(e, &format!("`:{key}`"), origin)
                .map(|x| (x, e.span)),
            None => Ok((default, form.span)),
        };
        let (fps, fps_span) = number(self, "fps", 24.0)?;
        if !(fps > 0.0 && fps <= 1000.0) {
            return Err(bad(
                self,
                fps_span,
                format!("frame rate {fps} is out of range"),
                "give :fps between 0 and 1000 frames per second",
            ));
        }
        let (regions, regions_span) = number(self, "regions", 4.0)?;
        if !(regions >= 1.0 && regions <= MAX_REGIONS as f64 && regions.fract() == 0.0) {
            return Err(bad(
                self,
                regions_span,
                format!("{regions} is not a number of regions"),
                &format!("give :regions from 1 to {MAX_REGIONS}: vertical strips, left to right"),
            ));
        }
        let regions = regions as usize;
        let (alpha, alpha_span) = number(self, "alpha", 0.3)?;
        if !(alpha > 0.0 && alpha < 1.0) {
            return Err(bad(self, alpha_span, format!("α {alpha} is not between 0 and 1"), "α weighs the newest frame in the running average that motion is measured against: 0 < α < 1"));
        }

        // The files: listed, or numbered by a pattern until one is missing. Each is
        // read, checked and analysed in turn, so that only one frame's pixels are
        // held at a time.
        let mut reading = Reading {
            name,
            analysis: Analysis::new(regions, alpha),
            features: vec![],
            size: None,
            per_frame_bytes: (regions as u64) * FRAME_KEY_BYTES,
        };
        match (options.get("files"), options.get("pattern")) {
            (Some(list), None) => {
                let files = list.as_list().unwrap_or_default();
                if files.is_empty() {
                    return Err(bad(
                        self,
                        list.span,
                        "`:files` names no frame".into(),
                        "write :files (\"f1.png\" \"f2.png\")",
                    ));
                }
                if files.len() > MAX_FRAMES {
                    return Err(too_many_frames(self, list.span, origin));
                }
                for file in files {
                    let ExprKind::Str(path) = &file.kind else {
                        return Err(bad(
                            self,
                            file.span,
                            format!("a frame is a file name in quotes, not {}", file.describe()),
                            "write :files (\"f1.png\" \"f2.png\")",
                        ));
                    };
                    self.check_load_time(file.span, origin)?;
                    let loaded = self.options.loader.load(path, origin.dir.as_deref());
                    let bytes = loaded
                        .map_err(|e| unreadable(self, path, file.span, e.to_string(), origin))?
                        .1;
                    self.read_frame(&mut reading, path, &bytes, file.span, origin)?;
                }
            }
            (None, Some(pattern)) => {
                let ExprKind::Str(text) = &pattern.kind else {
                    return Err(bad(
                        self,
                        pattern.span,
                        format!("a pattern is a string, not {}", pattern.describe()),
                        "write :pattern \"frames/f-%03d.png\"",
                    ));
                };
                let numbered = match Numbered::new(text) {
                    Ok(numbered) => numbered,
                    Err(PatternError::NoNumber) => return Err(bad(self, pattern.span, format!("pattern {text:?} has no frame number"), "mark where the number goes with %d, or %03d for three digits: \"frames/f-%03d.png\"")),
                    Err(PatternError::TooWide(width)) => return Err(bad(self, pattern.span, format!("pattern {text:?} pads its frame number to {width} digits, more than {MAX_NUMBER_WIDTH}"), "write %d, or %0Nd for N digits (N at most 20): \"frames/f-%03d.png\"")),
                };
                let first = match options.get("first") {
                    Some(e) => {
                        let first = self.constant_option(e, "`:first`", origin)?;
                        if !((0.0..=MAX_FIRST).contains(&first) && first.fract() == 0.0) {
                            return Err(bad(
                                self,
                                e.span,
                                format!(
                                    "`:first` {} is not a frame number",
                                    timbre_syntax::number(first)
                                ),
                                "give the first frame's number, a whole number from 0 to 10⁹",
                            ));
                        }
                        Some(first as u64)
                    }
                    None => None,
                };
                // Numbered from `:first`, else from 0 or 1, until a number is missing.
                let mut k = first.unwrap_or(0);
                loop {
                    self.check_load_time(pattern.span, origin)?;
                    let path = numbered.path(k);
                    match self.options.loader.load(&path, origin.dir.as_deref()) {
                        Ok(_) if reading.features.len() == MAX_FRAMES => {
                            return Err(too_many_frames(self, pattern.span, origin));
                        }
                        Ok((_, bytes)) => {
                            self.read_frame(&mut reading, &path, &bytes, pattern.span, origin)?;
                        }
                        // Without `:first`, the numbers may start at 1.
                        Err(_) if reading.features.is_empty() && first.is_none() && k == 0 => {}
                        Err(e) if reading.features.is_empty() => {
                            return Err(unreadable(
                                self,
                                &path,
                                pattern.span,
                                e.to_string(),
                                origin,
                            ));
                        }
                        Err(_) => break,
                    }
                    k += 1;
                }
            }
            _ => {
                return Err(bad(
                    self,
                    form.span,
                    "`frames` takes `:pattern` or `:files`, one of them".into(),
                    &format!("write {USAGE}"),
                ))
            }
        };
        let features = reading.features;

        let times: Vec<f64> = (0..features.len()).map(|j| j as f64 / fps).collect();
        let track = |values: Vec<f64>| {
            Arc::new(
                KeyframeTrack::new(times.clone(), values, Interpolation::Linear)
                    .expect("one key per frame, in time order"),
            )
        };
        for r in 0..regions {
            let prefix = format!("{name}-{}", r + 1);
            for (feature, value) in SCALARS {
                let values = features.iter().map(|frame| value(&frame[r])).collect();
                let variable = format!("{prefix}-{feature}");
                self.check_new_name(&variable, name_span, origin)?;
                self.names.keyframes.insert(variable, track(values));
            }
            let lanes = |of: &dyn Fn(&Features) -> &[f64]| -> Arc<[Arc<KeyframeTrack>]> {
                let n = of(&features[0][r]).len();
                (0..n)
                    .map(|k| track(features.iter().map(|frame| of(&frame[r])[k]).collect()))
                    .collect()
            };
            for (vector, tracks) in [("rows", lanes(&|f| &f.rows)), ("scan", lanes(&|f| &f.scan))] {
                let variable = format!("{prefix}-{vector}");
                self.check_new_name(&variable, name_span, origin)?;
                self.names.vector_keyframes.insert(variable, tracks);
            }
        }
        Ok(())
    }
}

/// The frames of one form read so far.
struct Reading<'a> {
    name: &'a str,
    analysis: Analysis,
    /// Each frame's features, region by region.
    features: Vec<Vec<Features>>,
    /// The first frame's width and height.
    size: Option<(u32, u32)>,
    /// Bytes each frame's keys take (see [`FRAME_KEY_BYTES`]).
    per_frame_bytes: u64,
}

impl Lowerer<'_> {
    /// Reads one frame's `bytes` (from `path`, named at `span`) into `reading`: its
    /// size checked from its header against the first frame's and the bounds, then
    /// decoded and analysed.
    fn read_frame(
        &mut self,
        reading: &mut Reading<'_>,
        path: &str,
        bytes: &[u8],
        span: Span,
        origin: &Origin,
    ) -> Result<(), Diag> {
        let (width, height) =
            Image::dimensions(bytes).map_err(|e| unreadable(self, path, span, e, origin))?;
        let pixels = u64::from(width) * u64::from(height);
        let frames = reading.features.len() as u64 + 1;
        let keys = frames.saturating_mul(reading.per_frame_bytes);
        let memory = pixels
            .saturating_mul(FRAME_BYTES_PER_PIXEL)
            .saturating_add(keys);
        let limit = self.options.limits.memory;
        if pixels > MAX_FRAME_PIXELS || pixels.saturating_mul(FRAME_BYTES_PER_PIXEL) > limit {
            let bound = MAX_FRAME_PIXELS.min(limit / FRAME_BYTES_PER_PIXEL);
            return Err(self
                .diag(
                    "timbre::frames-too-large",
                    format!(
                        "frame `{path}` is {width}×{height} pixels, more than the {bound} a frame may have"
                    ),
                    origin,
                )
                .label(span, "this frame")
                .help(format!(
                    "scale the frames down (to 1920×1080, say): each pixel takes {FRAME_BYTES_PER_PIXEL} bytes while it is analysed"
                )));
        }
        if memory > limit {
            return Err(self
                .diag(
                    "timbre::too-much-memory",
                    format!(
                        "the {frames} frames of `{}` need about {} MiB of memory, more than the limit of {} MiB",
                        reading.name,
                        memory >> 20,
                        limit >> 20
                    ),
                    origin,
                )
                .label(span, "these frames")
                .help("read fewer frames or fewer :regions, or relax the limit (--no-limits)"));
        }
        match reading.size {
            Some(first) if first != (width, height) => {
                let why = format!(
                    "it is {width}×{height} pixels, the first frame {}×{}",
                    first.0, first.1
                );
                return Err(unreadable(self, path, span, why, origin));
            }
            Some(_) => {}
            None => reading.size = Some((width, height)),
        }
        let regions = reading.analysis.regions();
        if (width as usize) < regions {
            let why = format!("it is {width} pixels wide, narrower than {regions} regions");
            return Err(unreadable(self, path, span, why, origin));
        }
        let image = Image::decode(bytes).map_err(|e| unreadable(self, path, span, e, origin))?;
        let Some(features) = reading.analysis.next(&image) else {
            // The header's size was checked; a decoder that disagrees with it lands here.
            let why = format!("its pixels are not the {width}×{height} its header says");
            return Err(unreadable(self, path, span, why, origin));
        };
        reading.features.push(features);
        Ok(())
    }
}

/// A frame that cannot be read, and why.
fn unreadable(l: &Lowerer<'_>, path: &str, span: Span, why: String, origin: &Origin) -> Diag {
    l.diag(
        "timbre::frames-unreadable",
        format!("cannot read frame `{path}`: {why}"),
        origin,
    )
    .label(span, "this frame")
    .help("frames are PNG or JPEG files, named relative to the file that names them")
}

fn too_many_frames(l: &Lowerer<'_>, span: Span, origin: &Origin) -> Diag {
    l.diag(
        "timbre::too-many-frames",
        format!("`frames` reads at most {MAX_FRAMES} frames"),
        origin,
    )
    .label(span, "more frames than that")
    .help("read every other frame, or a part of the sequence (:first, or fewer :files)")
}
