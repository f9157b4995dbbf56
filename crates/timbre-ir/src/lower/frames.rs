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

use timbre_syntax::{Expr, ExprKind};

use super::{Lowerer, Origin};
use crate::error::Diag;
use crate::frames::{analyse, Features, Image, Numbered, MAX_REGIONS};
use crate::keyframes::{Interpolation, KeyframeTrack};

const USAGE: &str = "(frames name :pattern \"frames/f-%03d.png\" :fps 24 :regions 4)";

/// Frames one form may read at most.
pub const MAX_FRAMES: usize = 100_000;

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

        // The files: listed, or numbered by a pattern until one is missing.
        // Each frame's path, where it is named, and its bytes if already read.
        let paths: Vec<(String, timbre_syntax::Span, Option<Vec<u8>>)> = match (
            options.get("files"),
            options.get("pattern"),
        ) {
            (Some(list), None) => {
                let files = list.as_list().unwrap_or_default();
                let mut paths = vec![];
                for file in files {
                    let ExprKind::Str(path) = &file.kind else {
                        return Err(bad(
                            self,
                            file.span,
                            format!("a frame is a file name in quotes, not {}", file.describe()),
                            "write :files (\"f1.png\" \"f2.png\")",
                        ));
                    };
                    paths.push((path.clone(), file.span, None));
                }
                if paths.is_empty() {
                    return Err(bad(
                        self,
                        list.span,
                        "`:files` names no frame".into(),
                        "write :files (\"f1.png\" \"f2.png\")",
                    ));
                }
                paths
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
                let Some(numbered) = Numbered::parse(text) else {
                    return Err(bad(self, pattern.span, format!("pattern {text:?} has no frame number"), "mark where the number goes with %d, or %03d for three digits: \"frames/f-%03d.png\""));
                };
                let first = match options.get("first") {
                    Some(e) => Some(self.constant_option(e, "`:first`", origin)?.max(0.0) as u64),
                    None => None,
                };
                // Numbered from `:first`, else from 0 or 1, until a number is missing.
                let load = |l: &Self, k: u64| {
                    l.options
                        .loader
                        .load(&numbered.path(k), origin.dir.as_deref())
                };
                let mut k = first.unwrap_or(0);
                let mut paths = vec![];
                while paths.len() < MAX_FRAMES {
                    match load(self, k) {
                        Ok((_, bytes)) => paths.push((numbered.path(k), pattern.span, Some(bytes))),
                        // Without `:first`, the numbers may start at 1.
                        Err(_) if paths.is_empty() && first.is_none() && k == 0 => {}
                        // The first frame's error is reported below.
                        Err(_) if paths.is_empty() => {
                            paths.push((numbered.path(k), pattern.span, None));
                            break;
                        }
                        Err(_) => break,
                    }
                    k += 1;
                }
                paths
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
        let mut images = Vec::with_capacity(paths.len());
        for (path, span, read) in paths {
            let unreadable = |l: &Self, why: String| {
                l.diag(
                    "timbre::frames-unreadable",
                    format!("cannot read frame `{path}`: {why}"),
                    origin,
                )
                .label(span, "this frame")
                .help("frames are PNG or JPEG files, named relative to the file that names them")
            };
            let bytes = match read {
                Some(bytes) => bytes,
                None => {
                    let loaded = self.options.loader.load(&path, origin.dir.as_deref());
                    loaded.map_err(|e| unreadable(self, e.to_string()))?.1
                }
            };
            let image = Image::decode(&bytes).map_err(|e| unreadable(self, e))?;
            if let Some(first) = images.first().map(|f: &Image| (f.width, f.height)) {
                if first != (image.width, image.height) {
                    return Err(unreadable(
                        self,
                        format!(
                            "it is {}×{} pixels, the first frame {}×{}",
                            image.width, image.height, first.0, first.1
                        ),
                    ));
                }
            }
            if image.width < regions {
                return Err(unreadable(
                    self,
                    format!(
                        "it is {} pixels wide, narrower than {regions} regions",
                        image.width
                    ),
                ));
            }
            images.push(image);
        }

        let features = analyse(&images, regions, alpha);
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
                self.keyframes.insert(variable, track(values));
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
                self.vector_keyframes.insert(variable, tracks);
            }
        }
        Ok(())
    }
}
