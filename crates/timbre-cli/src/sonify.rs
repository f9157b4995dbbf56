//! `timbre sonify`: sound from moving images (Unemi 2012). The frames are read by
//! the `frames` form as keyframed variables; this module writes the scene that maps
//! them to sound, with the paper's defaults as settings, and the renderer plays it.
//! `--print-scene` shows the scene instead, to keep and edit.

use std::path::{Path, PathBuf};

use clap::{Args, ValueEnum};
use timbre_lang::frames::Numbered;
use timbre_syntax::quote;

/// The two waveforms of the paper's section 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Waveform {
    /// 12 harmonics weighted by the brightness of 12 bands and γ^(i−1) (Eq. 2).
    Harmonics,
    /// The row-brightness scan from top to bottom, as one period.
    Scan,
}

/// The mappings from image statistics to sound, with the paper's defaults.
#[derive(Args, Debug, Clone)]
#[command(next_help_heading = "Mappings")]
pub struct Mappings {
    /// Vertical sub-regions, each a source panned from left to right (1 to 8).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u8).range(1..=8))]
    pub regions: u8,
    /// Weight α of the newest frame in the running average motion is measured against.
    #[arg(long, default_value_t = 0.3)]
    pub alpha: f64,
    /// Pitch of the darkest region, Hz (mean brightness 0).
    #[arg(long, default_value_t = 110.0)]
    pub low: f64,
    /// Pitch of the brightest region, Hz (mean brightness 1).
    #[arg(long, default_value_t = 880.0)]
    pub high: f64,
    /// Mix of each tone with itself shifted by octaves (−1, 0, +1, +2 by region:
    /// 55 Hz to 3.52 kHz in all): 0 none, 1 only the shifted tones.
    #[arg(long, default_value_t = 0.5)]
    pub octave_mix: f64,
    #[arg(long, value_enum, default_value = "harmonics")]
    pub waveform: Waveform,
    /// Decay γ of the harmonics (0 < γ < 1): lower is duller.
    #[arg(long, default_value_t = 0.5)]
    pub gamma: f64,
    /// Motion (mean brightness change) at which a region is at full loudness.
    #[arg(long, default_value_t = 0.1)]
    pub motion_full: f64,
    /// Loudness of a still region, 0 to 1.
    #[arg(long, default_value_t = 0.1)]
    pub floor: f64,
    /// Roughness below which there is no noise.
    #[arg(long, default_value_t = 0.05)]
    pub noise_threshold: f64,
    /// Roughness at which the noise is at its most.
    #[arg(long, default_value_t = 0.3)]
    pub noise_full: f64,
    /// The most white noise, as an amplitude (the tones peak near 0.2).
    #[arg(long, default_value_t = 0.05)]
    pub noise: f64,
    /// Low-pass width: the cutoff is the pitch times 1 + width · brightness deviation.
    #[arg(long, default_value_t = 30.0)]
    pub lowpass: f64,
    /// Deepest amplitude modulation (saturation's deviation sets the depth, its mean
    /// the rate, 0.5 to 8 Hz).
    #[arg(long, default_value_t = 0.5)]
    pub am_depth: f64,
    /// Deepest frequency modulation, semitones (hue's deviation sets the depth, its
    /// mean the rate, 0.5 to 8 Hz).
    #[arg(long, default_value_t = 0.5)]
    pub fm_depth: f64,
    /// Longest delay of the right channel behind the left, seconds (set by the mean
    /// variance of brightness along the rows).
    #[arg(long, default_value_t = 0.002)]
    pub phase_shift: f64,
    /// Quantise to notes of this scale (as the `score` form's `:scale`): music
    /// instead of a continuous sound.
    #[arg(long)]
    pub scale: Option<String>,
    /// The key of the scale: C, F#, Bb …
    #[arg(long, default_value = "C")]
    pub key: String,
    /// Seconds per beat of the music.
    #[arg(long, default_value_t = 0.25)]
    pub beat: f64,
    /// The music's rhythm: `random` (marks drawn per beat, seeded by region), `motion`
    /// (a note where the region's image moves faster than a quarter of
    /// --motion-full), or a pattern of x - . marks.
    #[arg(long, default_value = "random")]
    pub rhythm: String,
    /// How far each note bends toward the continuous pitch, 0 to 1.
    #[arg(long, default_value_t = 0.4)]
    pub bend: f64,
    /// Longest attack, seconds: each note rises to full level over this times the
    /// brightness's centre across the region (long sounds bowed, short pizzicato).
    #[arg(long, alias = "max-delay", default_value_t = 0.1)]
    pub max_attack: f64,
    /// Longest tail, seconds: each note decays 60 dB over this times the brightness's
    /// centre down the region. The sound also rings out this long after the last frame.
    #[arg(long, default_value_t = 1.0)]
    pub max_tail: f64,
}

/// The frames a FRAMES argument names, in order: a folder's PNG and JPEG files by
/// name (numbers in names compared as numbers), the files a `*` pattern matches, or
/// a `%d` / `%03d` pattern counted from 0 or 1 until a number is missing.
pub fn frame_files(frames: &str) -> Result<Vec<String>, String> {
    let path = Path::new(frames);
    let is_image = |p: &Path| {
        p.extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
    };
    let mut files: Vec<PathBuf> = if path.is_dir() {
        let entries =
            std::fs::read_dir(path).map_err(|e| format!("cannot read `{frames}`: {e}"))?;
        entries
            .filter_map(|e| Some(e.ok()?.path()))
            .filter(|p| p.is_file() && is_image(p))
            .collect()
    } else if let Some(numbered) = Numbered::parse(frames) {
        let name = |k: u64| PathBuf::from(numbered.path(k));
        let first = if name(0).exists() { 0 } else { 1 };
        (first..).map(name).take_while(|p| p.exists()).collect()
    } else if frames.contains('*') {
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        let pattern = path
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or_default();
        let entries =
            std::fs::read_dir(dir).map_err(|e| format!("cannot read `{}`: {e}", dir.display()))?;
        entries
            .filter_map(|e| Some(e.ok()?.path()))
            .filter(|p| {
                p.is_file()
                    && p.file_name()
                        .and_then(|n| n.to_str())
                        .is_some_and(|n| wildcard(pattern, n))
            })
            .collect()
    } else {
        return Err(format!(
            "`{frames}` is not a folder of frames or a pattern: give a folder, \"frames/f-%03d.png\" or \"frames/*.png\""
        ));
    };
    files.sort_by_key(|p| natural(&p.to_string_lossy()));
    if files.is_empty() {
        return Err(format!("`{frames}` names no PNG or JPEG frame"));
    }
    Ok(files
        .iter()
        .map(|p| p.to_string_lossy().into_owned())
        .collect())
}

/// Whether `name` matches `pattern`, where `*` stands for any run of characters.
/// Greedy with one remembered star: each piece between stars is matched at its
/// leftmost place, so the time is linear in the name for a given pattern (trying
/// every split, as a recursive match does, is exponential in the stars).
fn wildcard(pattern: &str, name: &str) -> bool {
    let mut pieces = pattern.split('*');
    let first = pieces.next().unwrap_or_default();
    let Some(mut rest) = name.strip_prefix(first) else {
        return false;
    };
    let pieces: Vec<&str> = pieces.collect();
    let Some((last, middle)) = pieces.split_last() else {
        // No star: the whole name is the pattern.
        return rest.is_empty();
    };
    for piece in middle {
        match rest.find(piece) {
            Some(at) => rest = &rest[at + piece.len()..],
            None => return false,
        }
    }
    rest.ends_with(last)
}

/// A sort key that orders `f2` before `f10`: runs of digits compared as numbers.
fn natural(name: &str) -> Vec<(u8, u128, String)> {
    let mut key = vec![];
    let mut chars = name.chars().peekable();
    while let Some(c) = chars.next() {
        if c.is_ascii_digit() {
            let mut digits = c.to_string();
            while let Some(d) = chars.next_if(char::is_ascii_digit) {
                digits.push(d);
            }
            key.push((0, digits.parse().unwrap_or(u128::MAX), String::new()));
        } else {
            key.push((1, 0, c.to_string()));
        }
    }
    key
}

/// The scene that plays `files` at `fps` with these mappings.
pub fn scene(source: &str, files: &[String], fps: f64, m: &Mappings) -> String {
    let regions = usize::from(m.regions);
    let seconds = files.len() as f64 / fps;
    // The gates close with the last frame; the scene lasts until the longest tail
    // has decayed, so the render ends quiet instead of cutting a sounding note.
    let duration = seconds + m.max_tail;
    // Every user-given string is quoted as a timbre string, comments included: a
    // name cannot end the string or the comment and become code.
    let quoted: Vec<String> = files.iter().map(|f| quote(f)).collect();
    let source = quote(source);
    let wave = |phase: &str| match m.waveform {
        Waveform::Harmonics => format!(
            "(/ (combine (* rows (pow {} (iota 12)) (sine (* {phase} (+ 1 (iota 12)))))) 12)",
            m.gamma
        ),
        Waveform::Scan => format!(
            "(let ((x (* 32 {phase})) (i (floor x)) (u (- x i))) \
             (+ (* (- 1 u) (index scan i)) (* u (index scan (mod (+ i 1) 32)))))"
        ),
    };
    let table = match m.waveform {
        Waveform::Harmonics => "rows",
        Waveform::Scan => "scan",
    };
    let mut text = format!(
        "; Sound from the {} frames of {source} at {fps} frames per second (timbre sonify,\n\
         ; after Unemi 2012): one voice per vertical region, panned left to right, and\n\
         ; {} s after the last frame for the sound to decay.\n\
         (scene :channels 2 :duration {})\n\n\
         (frames video :fps {fps} :regions {regions} :alpha {}\n        :files ({}))\n\n",
        files.len(),
        number(m.max_tail),
        number(duration),
        m.alpha,
        quoted.join(" ")
    );
    text += &format!(
        "; A region's voice: its pitch in freq, its loudness in amp; FM by hue, a low-pass\n\
         ; opened by the brightness's deviation, AM by saturation, white noise by roughness,\n\
         ; and the right channel delayed by the rows' variance. It rises over attack seconds\n\
         ; from the gate's opening and decays 60 dB over tail seconds from its closing.\n\
         (define voice (freq amp gate attack tail bdev sat sdev hue hdev rough rowvar {table} pan shift)\n\
         \x20 (let ((f (* freq (pow 2 (* {fm} (min 1 (* 4 hdev)) (sine (phasor (+ 0.5 (* 7.5 hue))))))))\n\
         \x20       (tone (+ (* {keep} {own}) (* {mix} {shifted})))\n\
         \x20       (clear (lowpass tone (min 20000 (* f (+ 1 (* {lowpass} bdev))))))\n\
         \x20       (am (- 1 (* {am} (min 1 (* 2 sdev)) (+ 0.5 (* 0.5 (sine (phasor (+ 0.5 (* 7.5 sat)))))))))\n\
         \x20       (hiss (* {noise} (clamp (/ (- rough {threshold}) {span}) 0 1) (white)))\n\
         \x20       (mono (* amp (adsr gate attack 0 1 tail :exp-release 1) (+ (* am clear) hiss)))\n\
         \x20       (angle (* (+ pan 1) (/ pi 4))))\n\
         \x20   (vector (* (cos angle) mono)\n\
         \x20           (* (sin angle) (delay mono (* {phase} (min 1 (* 8 rowvar))) :max {phase})))))\n\n",
        fm = number(m.fm_depth / 12.0),
        keep = number(1.0 - m.octave_mix),
        mix = number(m.octave_mix),
        own = wave("(phasor f)"),
        shifted = wave("(phasor (* f shift))"),
        lowpass = number(m.lowpass),
        am = number(m.am_depth),
        noise = number(m.noise),
        threshold = number(m.noise_threshold),
        span = number((m.noise_full - m.noise_threshold).max(1e-9)),
        phase = number(m.phase_shift),
    );
    let loudness = |motion: &str| {
        format!(
            "(min 1 (+ {} (/ {motion} {})))",
            number(m.floor),
            number(m.motion_full)
        )
    };
    let features = |k: usize| {
        let v = |name: &str| format!("video-{k}-{name}");
        format!(
            "{} {} {} {} {} {} {} {}",
            v("brightness-deviation"),
            v("saturation"),
            v("saturation-deviation"),
            v("hue"),
            v("hue-deviation"),
            v("roughness"),
            v("row-variance"),
            v(table)
        )
    };
    let pan = |k: usize| {
        if regions == 1 {
            0.0
        } else {
            -1.0 + 2.0 * (k - 1) as f64 / (regions - 1) as f64
        }
    };
    // Octave shifts −1, 0, +1, +2 by region: 55 Hz to 3.52 kHz in all.
    let shift = |k: usize| 2f64.powi(((k - 1) % 4) as i32 - 1);
    match &m.scale {
        None => {
            for k in 1..=regions {
                // Held from the first frame to the last, then faded out over the
                // longest tail.
                text += &format!(
                    "(define-sound region-{k} ()\n  (voice (* {} (pow {} video-{k}-brightness)) {} (< t {}) 0 {}\n         {} {} {}))\n",
                    number(m.low),
                    number(m.high / m.low),
                    loudness(&format!("video-{k}-motion")),
                    number(seconds),
                    number(m.max_tail),
                    features(k),
                    number(pan(k)),
                    number(shift(k)),
                );
                text += &format!("(instance region-{k} (region-{k}))\n\n");
            }
        }
        Some(scale) => {
            // The same pitches as notes: MIDI 45 (110 Hz) + 12·log2(high/low)·b.
            let offset = 69.0 + 12.0 * (m.low / 440.0).log2();
            let semitones = 12.0 * (m.high / m.low).log2();
            let rhythm = match m.rhythm.as_str() {
                "random" => format!(":rhythm random :on 0.5 :hold 0.3 :seed {}", 1),
                // The paper's synchronised rhythm: a note when the region's image
                // changes faster than a threshold (a quarter of full loudness's).
                "motion" => format!(
                    ":rhythm motion :trigger video-K-motion :threshold {} :min-duration 0.125",
                    number(m.motion_full / 4.0)
                ),
                pattern => format!(":rhythm {}", quote(pattern)),
            };
            let mut parts = String::new();
            for k in 1..=regions {
                text += &format!(
                    "(define-sound note-{k} (freq amp gate attack tail)\n  (voice freq (* amp {}) gate attack tail\n         {} {} {}))\n",
                    loudness(&format!("video-{k}-motion")),
                    features(k),
                    number(pan(k)),
                    number(shift(k)),
                );
                parts += &format!(
                    "\n  (part region-{k} note-{k} video-{k}-brightness :scale {scale} :key {} :offset {} :semitones {}\n        {} :bend {} :attack (video-{k}-centroid-x {}) :tail (video-{k}-centroid-y {}))",
                    m.key,
                    number(offset),
                    number(semitones),
                    rhythm
                        .replace(":seed 1", &format!(":seed {k}"))
                        .replace("video-K-", &format!("video-{k}-")),
                    number(m.bend),
                    number(m.max_attack),
                    number(m.max_tail),
                );
            }
            // The notes end with the frames; their tails sound after.
            text += &format!(
                "\n(score music :beat {} :end {}{parts})\n",
                number(m.beat),
                number(seconds)
            );
        }
    }
    // Laid out as `timbre fmt` would; the text always parses.
    timbre_syntax::format_source(&text).unwrap_or(text)
}

fn number(x: f64) -> String {
    timbre_syntax::number(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wildcards_and_natural_order() {
        assert!(wildcard("f-*.png", "f-001.png"));
        assert!(wildcard("*", "anything"));
        assert!(!wildcard("f-*.png", "g-001.png"));
        assert!(wildcard("a*b*c", "axxbyyc"));
        assert!(wildcard("a*a", "aa") && !wildcard("a*a", "a"));
        assert!(wildcard("*.png", ".png") && wildcard("f*", "f") && !wildcard("f", "ff"));
        assert!(wildcard("a*ab*b", "aabb") && !wildcard("ab*ba", "aba"));
        // Linear time: thirty stars against a long name that almost matches.
        let pattern = "a*".repeat(30) + "b";
        let name = "a".repeat(5000);
        let started = std::time::Instant::now();
        assert!(!wildcard(&pattern, &name));
        assert!(started.elapsed() < std::time::Duration::from_secs(1));
        let mut names = vec!["f10.png", "f2.png", "f1.png"];
        names.sort_by_key(|n| natural(n));
        assert_eq!(names, ["f1.png", "f2.png", "f10.png"]);
    }
}
