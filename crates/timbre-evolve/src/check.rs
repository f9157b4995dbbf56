//! The checks every offspring passes: it lowers (names, arity and widths), and its
//! audition renders to something worth hearing: finite, not silent, not a constant,
//! not clipping. Clipping is repaired by scaling; the rest is refused.

use timbre_ir::{Interpreter, RenderConfig};
use timbre_lang::{CompileOptions, Library, NoFiles, ParamValue, Registry};

use crate::genome::{list, number, significant, symbol, Genome};

/// How a genome is auditioned to be checked.
#[derive(Clone, Debug, PartialEq)]
pub struct Audition {
    pub sample_rate: f64,
    pub seconds: f64,
}

impl Default for Audition {
    fn default() -> Self {
        Audition {
            sample_rate: 16_000.0,
            seconds: 0.5,
        }
    }
}

/// Below this RMS (after removing the mean) an audition is silent: −80 dBFS.
pub const SILENT_RMS: f64 = 1e-4;

/// The peak a clipping audition is scaled to.
pub const REPAIRED_PEAK: f64 = 0.9;

/// Why an offspring was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Refusal {
    #[error("it does not lower: {0}")]
    Lowering(String),
    #[error("a sample is not finite")]
    NotFinite,
    #[error("it is silent")]
    Silent,
    #[error("it is a constant (DC only)")]
    DcOnly,
    #[error("it has {size} expressions, more than {limit}")]
    TooLarge { size: usize, limit: usize },
    #[error("it nests {depth} deep, more than {limit}")]
    TooDeep { depth: usize, limit: usize },
}

/// What a successful check measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Checked {
    /// The audition's samples (after any repair).
    pub samples: Vec<f64>,
    /// Whether the body was scaled because its audition passed full scale.
    pub repaired: bool,
}

/// Checks `genome` and, if its audition clips, scales its body to a peak of
/// [`REPAIRED_PEAK`] (the body becomes `(* k BODY)`).
pub fn check(genome: &mut Genome, audition: &Audition) -> Result<Checked, Refusal> {
    let samples = render(genome, audition)?;
    let peak = samples.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    // The instance's fade-in is not the sound's: a constant fades in too.
    let faded = (timbre_ir::DECLICK_IN * audition.sample_rate).ceil() as usize;
    let heard = &samples[faded.min(samples.len())..];
    let mean = heard.iter().sum::<f64>() / heard.len().max(1) as f64;
    let ac =
        (heard.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / heard.len().max(1) as f64).sqrt();
    if ac < SILENT_RMS {
        return Err(if peak < SILENT_RMS {
            Refusal::Silent
        } else {
            Refusal::DcOnly
        });
    }
    if peak <= 1.0 {
        return Ok(Checked {
            samples,
            repaired: false,
        });
    }
    // Three significant digits, so the printed tree stays readable.
    let k = significant(REPAIRED_PEAK / peak, 3, f64::floor);
    let body = std::mem::replace(&mut genome.body, number(0.0));
    genome.body = list(vec![symbol("*"), number(k), body]);
    Ok(Checked {
        samples: render(genome, audition)?,
        repaired: true,
    })
}

/// The audition of `genome`: its class instantiated with its values and rendered by
/// the reference interpreter.
pub fn render(genome: &Genome, audition: &Audition) -> Result<Vec<f64>, Refusal> {
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &NoFiles);
    let source = timbre_ir::SourceFile::new("<genome>", genome.library_source());
    let lowering = |d: timbre_ir::Diagnostics| {
        Refusal::Lowering(d.0.first().map(|d| d.message.clone()).unwrap_or_default())
    };
    let library = Library::compile(source, None, &options).map_err(lowering)?;
    let params: Vec<(&str, ParamValue)> = (genome.params.iter())
        .zip(&genome.values)
        .map(|(p, v)| (p.as_str(), ParamValue::Constant(*v)))
        .collect();
    let tree = library
        .instantiate(&genome.name, &params, 0.0, None, &options)
        .map_err(lowering)?;
    let width = tree.graph.width(tree.root);
    if width != 1 {
        return Err(Refusal::Lowering(format!(
            "it is {width} lanes wide, not one"
        )));
    }
    let config = RenderConfig {
        sample_rate: audition.sample_rate,
        block_size: 256,
    };
    let frames = (audition.seconds * audition.sample_rate).round() as usize;
    let mut samples = vec![0.0; frames];
    Interpreter::new(&tree.graph, tree.root, config).render_frames(&mut samples);
    if samples.iter().any(|x| !x.is_finite()) {
        return Err(Refusal::NotFinite);
    }
    Ok(samples)
}
