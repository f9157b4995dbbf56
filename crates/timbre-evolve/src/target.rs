//! Search toward a recording: how far a candidate sounds from the target, a local
//! optimiser for a tree's constants, and the two-stage search (genetic programming
//! changes structure; Nelder–Mead tunes the constants of the best), after Garcia's
//! "growing sound synthesizers".
//!
//! The distance is multi-resolution, as DDSP's spectral loss: at several FFT sizes,
//! the L1 distance of the magnitude spectrograms relative to the target's (linear)
//! and of their logarithms; plus an envelope term. Spectral distances alone have
//! traps: a tone an octave (or any interval) away from the target's shares none of
//! its bins, so moving it a little changes nothing, and a harmonic an octave up
//! matches half the target's partials, a local minimum. The guard is a transport
//! term: the earth mover's distance between the two time-averaged spectra on a
//! log-frequency axis, in octaves, which falls steadily as a partial moves toward the
//! target's wherever it starts; and the optimiser starts frequencies (constants of
//! 20 and more) at the value given and at an octave above and below.

use argmin::core::{CostFunction, Executor};
use argmin::solver::neldermead::NelderMead;
use rand::{Rng, RngExt};
use rayon::prelude::*;
use realfft::RealFftPlanner;
use timbre_syntax::ExprKind;

use crate::check::{render, Audition};
use crate::genome::{get, get_mut, number, significant, sites, Genome, Path};
use crate::mutate::{crossover, mutate, Settings};

/// FFT sizes of the spectral terms, at the audition's rate.
pub const FFT_SIZES: [usize; 4] = [256, 512, 1024, 2048];

/// Added to magnitudes before their logarithm: −80 dB under a full-scale sine's bin.
const FLOOR: f64 = 1e-4;

/// A recording to search toward, with what the distance compares precomputed.
pub struct Target {
    audition: Audition,
    features: Features,
}

/// What the distance compares of a sound.
struct Features {
    /// Magnitude spectrograms, one per FFT size, frame after frame.
    spectrograms: Vec<Vec<Vec<f64>>>,
    /// RMS in frames of 10 ms.
    envelope: Vec<f64>,
    /// The time-averaged power spectrum's cumulative distribution over log-frequency
    /// bins (of `log_bins`), normalised to end at 1; empty when silent.
    cumulative: Vec<f64>,
}

/// Bins of the log-frequency axis of the transport term, per octave.
const BINS_PER_OCTAVE: f64 = 24.0;

impl Target {
    /// A target from mono samples at `sample_rate`; candidates are auditioned at the
    /// same rate for as long as it lasts (at most `max_seconds`).
    pub fn new(samples: &[f64], sample_rate: f64, max_seconds: f64) -> Target {
        let frames = samples.len().min((max_seconds * sample_rate) as usize);
        let audition = Audition {
            sample_rate,
            seconds: frames as f64 / sample_rate,
        };
        Target {
            features: Features::of(&samples[..frames], sample_rate),
            audition,
        }
    }

    /// How candidates are auditioned to be compared.
    pub fn audition(&self) -> &Audition {
        &self.audition
    }

    /// The distance of `genome`'s audition from the target; as far as can be when
    /// it does not render.
    pub fn measure(&self, genome: &Genome) -> f64 {
        render(genome, &self.audition).map_or(f64::MAX, |s| self.distance(&s))
    }

    /// The distance of `samples` (auditioned as [`Target::audition`] says) from the
    /// target: 0 for the target itself.
    pub fn distance(&self, samples: &[f64]) -> f64 {
        let other = Features::of(samples, self.audition.sample_rate);
        let t = &self.features;
        let mut spectral = 0.0;
        for (a, b) in other.spectrograms.iter().zip(&t.spectrograms) {
            let (mut diff, mut norm, mut logs, mut n) = (0.0, 0.0, 0.0, 0usize);
            for (fa, fb) in a.iter().zip(b) {
                for (x, y) in fa.iter().zip(fb) {
                    diff += (x - y).abs();
                    norm += y.abs();
                    logs += ((x + FLOOR).ln() - (y + FLOOR).ln()).abs();
                    n += 1;
                }
            }
            spectral += diff / norm.max(FLOOR) + logs / n.max(1) as f64;
        }
        spectral /= FFT_SIZES.len() as f64;
        let envelope = (other.envelope.iter().zip(&t.envelope))
            .map(|(x, y)| ((x + FLOOR).ln() - (y + FLOOR).ln()).abs())
            .sum::<f64>()
            / t.envelope.len().max(1) as f64;
        let transport = match (other.cumulative.is_empty(), t.cumulative.is_empty()) {
            (false, false) => {
                (other.cumulative.iter().zip(&t.cumulative))
                    .map(|(x, y)| (x - y).abs())
                    .sum::<f64>()
                    / BINS_PER_OCTAVE
            }
            (true, true) => 0.0,
            // Silence against sound: as far as the audible range is wide.
            _ => 10.0,
        };
        spectral + envelope + transport
    }
}

impl Features {
    fn of(samples: &[f64], sample_rate: f64) -> Features {
        let mut planner = RealFftPlanner::<f64>::new();
        let mut spectrograms = vec![];
        let mut average = vec![];
        for &size in &FFT_SIZES {
            let fft = planner.plan_fft_forward(size);
            let window: Vec<f64> = (0..size)
                .map(|k| 0.5 - 0.5 * (std::f64::consts::TAU * k as f64 / size as f64).cos())
                .collect();
            let (mut input, mut output) = (fft.make_input_vec(), fft.make_output_vec());
            let mut frames = vec![];
            let mut start = 0;
            while start + size <= samples.len().max(size) {
                for (k, x) in input.iter_mut().enumerate() {
                    *x = samples.get(start + k).copied().unwrap_or(0.0) * window[k];
                }
                // The lengths are the plan's own.
                let _ = fft.process(&mut input, &mut output);
                frames.push(
                    output
                        .iter()
                        .map(|c| c.norm() * 2.0 / size as f64)
                        .collect(),
                );
                start += size / 4;
            }
            let [.., largest] = FFT_SIZES;
            if size == largest {
                average = vec![0.0; size / 2 + 1];
                for frame in &frames {
                    for (a, m) in average.iter_mut().zip(frame as &Vec<f64>) {
                        *a += m * m;
                    }
                }
            }
            spectrograms.push(frames);
        }
        let hop = (0.01 * sample_rate).round().max(1.0) as usize;
        let envelope = samples
            .chunks(hop)
            .map(|c| (c.iter().map(|x| x * x).sum::<f64>() / c.len() as f64).sqrt())
            .collect();
        Features {
            spectrograms,
            envelope,
            cumulative: log_cumulative(&average, sample_rate),
        }
    }
}

/// The cumulative distribution of a power spectrum over log-frequency bins from
/// 20 Hz to Nyquist, normalised; empty if it holds no energy.
fn log_cumulative(power: &[f64], sample_rate: f64) -> Vec<f64> {
    let size = (power.len() - 1) * 2;
    let nyquist = sample_rate / 2.0;
    let bins = ((nyquist / 20.0).log2() * BINS_PER_OCTAVE).ceil().max(1.0) as usize;
    let mut mass = vec![0.0; bins];
    for (k, p) in power.iter().enumerate().skip(1) {
        let f = k as f64 * sample_rate / size as f64;
        if f < 20.0 {
            continue;
        }
        let bin = ((f / 20.0).log2() * BINS_PER_OCTAVE) as usize;
        mass[bin.min(bins - 1)] += p;
    }
    let total: f64 = mass.iter().sum();
    if total <= 1e-12 {
        return vec![];
    }
    let mut sum = 0.0;
    mass.iter()
        .map(|m| {
            sum += m / total;
            sum
        })
        .collect()
}

/// A number the optimiser may change: a constant of the body, or the value a
/// parameter is auditioned with (an instance of the class).
#[derive(Clone, Debug, PartialEq)]
pub enum Knob {
    Constant(Path),
    Value(usize),
}

/// Which numbers of a genome [`tune`] changes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Knobs {
    /// The values of its parameters: an instance of a fixed class, as the paper
    /// explores "instances within a class".
    Values,
    /// The constants of its body: a new structure's numbers.
    Constants,
    /// Both: the values of its parameters, then the constants of its body (what the
    /// two-stage search tunes, so a class with parameters is tuned through them too).
    All,
}

/// The numbers of a genome that `which` names.
pub fn knobs(genome: &Genome, which: Knobs) -> Vec<Knob> {
    match which {
        Knobs::Values => (0..genome.values.len()).map(Knob::Value).collect(),
        Knobs::Constants => (sites(&genome.body).into_iter())
            .filter(|p| matches!(get(&genome.body, p).kind, ExprKind::Number(_)))
            .map(Knob::Constant)
            .collect(),
        Knobs::All => {
            let mut all = knobs(genome, Knobs::Values);
            all.extend(knobs(genome, Knobs::Constants));
            all
        }
    }
}

fn knob_value(genome: &Genome, knob: &Knob) -> f64 {
    match knob {
        Knob::Constant(path) => match get(&genome.body, path).kind {
            ExprKind::Number(x) => x,
            _ => unreachable!("a constant"),
        },
        Knob::Value(k) => genome.values[*k],
    }
}

/// A genome's constants as the optimiser sees them: the logarithm of a positive
/// one (so steps are ratios), else the value.
fn encode(x: f64) -> f64 {
    if x > 0.0 {
        x.ln()
    } else {
        x
    }
}

fn with_knobs(genome: &Genome, at: &[Knob], coded: &[f64], signs: &[bool]) -> Genome {
    let mut tuned = genome.clone();
    for ((knob, c), positive) in at.iter().zip(coded).zip(signs) {
        let value = if *positive { c.exp() } else { *c };
        match knob {
            Knob::Constant(path) => *get_mut(&mut tuned.body, path) = number(value),
            Knob::Value(k) => tuned.values[*k] = value,
        }
    }
    tuned
}

/// What tuning found.
#[derive(Clone, Debug)]
pub struct Tuned {
    pub genome: Genome,
    pub distance: f64,
    /// Renders it took.
    pub renders: usize,
}

struct Cost<'t> {
    genome: &'t Genome,
    target: &'t Target,
    at: &'t [Knob],
    positive: &'t [bool],
    renders: &'t std::sync::atomic::AtomicUsize,
}

impl CostFunction for Cost<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, coded: &Self::Param) -> Result<f64, argmin::core::Error> {
        self.renders
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let candidate = with_knobs(self.genome, self.at, coded, self.positive);
        // A tree that fails at these constants is as far as can be.
        Ok(self.target.measure(&candidate))
    }
}

/// Tunes the numbers of `genome` that `which` names toward `target` with
/// Nelder–Mead (`iterations` at most from each start, restarted once from where it
/// stopped): from the numbers given, and with every frequency (a number of 20 or
/// more) an octave below and above; the starts run in parallel.
pub fn tune(genome: &Genome, target: &Target, which: Knobs, iterations: u64) -> Tuned {
    let at = knobs(genome, which);
    if at.is_empty() {
        let distance = target.measure(genome);
        return Tuned {
            genome: genome.clone(),
            distance,
            renders: 1,
        };
    }
    let values: Vec<f64> = at.iter().map(|k| knob_value(genome, k)).collect();
    let positive: Vec<bool> = values.iter().map(|x| *x > 0.0).collect();
    let starts: Vec<Vec<f64>> = [1.0, 0.5, 2.0]
        .iter()
        .map(|octave| {
            (values.iter())
                .map(|x| encode(if *x >= 20.0 { x * octave } else { *x }))
                .collect()
        })
        .collect();
    let results: Vec<(Vec<f64>, f64, usize)> = starts
        .par_iter()
        .map(|start| {
            let renders = std::sync::atomic::AtomicUsize::new(0);
            let cost = Cost {
                genome,
                target,
                at: &at,
                positive: &positive,
                renders: &renders,
            };
            // Nelder–Mead, then again from where it stopped with a fresh simplex (a
            // collapsed simplex is its usual way to stall).
            let mut best = (start.clone(), f64::MAX);
            for _ in 0..2 {
                let outcome = nelder_mead(&cost, &best.0, iterations);
                if outcome.1 < best.1 {
                    best = outcome;
                }
            }
            let renders = renders.load(std::sync::atomic::Ordering::Relaxed);
            (best.0, best.1, renders)
        })
        .collect();
    let renders: usize = results.iter().map(|r| r.2).sum();
    // The first of the best, so the choice does not depend on the threads.
    let (best, distance, _) = results
        .into_iter()
        .reduce(|a, b| if b.1 < a.1 { b } else { a })
        .expect("three starts");
    // Seven significant digits keep the printed tree readable; the distance is
    // measured again for the numbers written.
    let tuned = round_knobs(&with_knobs(genome, &at, &best, &positive), &at);
    let rounded = target.measure(&tuned);
    if rounded <= distance * 1.001 + 1e-9 {
        return Tuned {
            genome: tuned,
            distance: rounded,
            renders: renders + 1,
        };
    }
    Tuned {
        genome: with_knobs(genome, &at, &best, &positive),
        distance,
        renders: renders + 1,
    }
}

/// `genome` with the numbers at `at` rounded to 7 significant digits.
fn round_knobs(genome: &Genome, at: &[Knob]) -> Genome {
    let round = |x: f64| significant(x, 7, f64::round);
    let mut rounded = genome.clone();
    for knob in at {
        match knob {
            Knob::Constant(path) => {
                let value = round(knob_value(genome, knob));
                *get_mut(&mut rounded.body, path) = number(value);
            }
            Knob::Value(k) => rounded.values[*k] = round(genome.values[*k]),
        }
    }
    rounded
}

/// Nelder–Mead from `start`: the first simplex is the start and a step of 0.1 (a
/// tenth of the number, for positive ones, which are seen as logarithms) in each.
fn nelder_mead(cost: &Cost<'_>, start: &[f64], iterations: u64) -> (Vec<f64>, f64) {
    let mut simplex = vec![start.to_vec()];
    for k in 0..start.len() {
        let mut vertex = start.to_vec();
        vertex[k] += 0.1;
        simplex.push(vertex);
    }
    let solver = NelderMead::new(simplex)
        .with_sd_tolerance(1e-7)
        .expect("a positive tolerance");
    let borrowed = Cost { ..*cost };
    match Executor::new(borrowed, solver)
        .configure(|state| state.max_iters(iterations))
        .run()
    {
        Ok(result) => {
            let state = result.state;
            let best = state.best_param.unwrap_or_else(|| start.to_vec());
            (best, state.best_cost)
        }
        Err(_) => (start.to_vec(), f64::MAX),
    }
}

/// How the search toward a target runs.
#[derive(Clone, Debug)]
pub struct Search {
    pub generations: usize,
    pub population: usize,
    /// Nelder–Mead iterations for the best candidate of each generation.
    pub tune_iterations: u64,
    pub settings: Settings,
}

impl Default for Search {
    fn default() -> Self {
        Search {
            generations: 10,
            population: 12,
            tune_iterations: 60,
            settings: Settings::default(),
        }
    }
}

/// What a search found, and how it went.
#[derive(Clone, Debug)]
pub struct Found {
    pub best: Genome,
    pub distance: f64,
    /// The seed's distance, then the best after tuning the seed, then after each
    /// generation.
    pub history: Vec<f64>,
    /// Candidates rendered, for renders per second.
    pub renders: usize,
}

/// Two-stage search: each generation's candidates (mutants and crossovers of the
/// better half of the last, by tournament) are measured in parallel, and the best is
/// tuned by [`tune`] (its parameters' values and its constants); the best ever is
/// kept. Random choices are drawn in order on the
/// calling thread, so the result does not depend on the number of threads.
pub fn search(rng: &mut impl Rng, seed: &Genome, target: &Target, search: &Search) -> Found {
    let settings = Settings {
        audition: target.audition.clone(),
        ..search.settings.clone()
    };
    let untuned = target.measure(seed);
    let first = tune(seed, target, Knobs::All, search.tune_iterations);
    let mut renders = 1 + first.renders;
    let mut best = (first.genome.clone(), first.distance);
    let mut history = vec![untuned, first.distance];
    let mut population: Vec<(Genome, f64)> = vec![(first.genome, first.distance)];
    for _ in 0..search.generations {
        // Offspring, drawn in order.
        let mut children = vec![best.0.clone()];
        while children.len() < search.population {
            let pick = |rng: &mut dyn Rng| -> &Genome {
                // A tournament of two.
                let a = &population[rng.random_range(0..population.len())];
                let b = &population[rng.random_range(0..population.len())];
                if b.1 < a.1 {
                    &b.0
                } else {
                    &a.0
                }
            };
            let a = pick(rng).clone();
            let child = if population.len() > 1 && rng.random_bool(0.3) {
                let b = pick(rng).clone();
                crossover(rng, &a, &b, &settings)
            } else {
                mutate(rng, &a, &settings)
            };
            match child {
                Ok(child) => children.push(child.genome),
                Err(_) => children.push(a),
            }
        }
        // Measured in parallel, collected in order.
        let measured: Vec<(Genome, f64)> = children
            .into_par_iter()
            .map(|g| {
                let d = target.measure(&g);
                (g, d)
            })
            .collect();
        renders += measured.len();
        let mut ranked = measured;
        ranked.sort_by(|a, b| a.1.total_cmp(&b.1));
        let tuned = tune(&ranked[0].0, target, Knobs::All, search.tune_iterations);
        renders += tuned.renders;
        if tuned.distance < ranked[0].1 {
            ranked[0] = (tuned.genome, tuned.distance);
        }
        if ranked[0].1 < best.1 {
            best = ranked[0].clone();
        }
        history.push(best.1);
        ranked.truncate(search.population.div_ceil(2));
        population = ranked;
    }
    Found {
        best: best.0,
        distance: best.1,
        history,
        renders,
    }
}
