//! `timbre evolve`: breeding a sound class by ear, as the 1993 paper and Sims' genetic
//! images do. Each generation's candidates are rendered and played (or written as
//! numbered WAVs), rated 0–9, and the best breed the next generation by mutation and
//! crossover (`timbre-evolve`). Every generation's trees and a lineage file are kept;
//! the same seed and the same ratings give the same trees.

use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use clap::Args;
use rand::{RngExt, SeedableRng};
use timbre_evolve::{crossover, mutate, tune, Genome, Knobs, Search, Settings, Target};

use crate::Failure;

#[derive(Args, Debug)]
pub struct EvolveArgs {
    /// The file holding the class to start from (its other definitions are kept).
    seed_file: PathBuf,

    /// The class to evolve (default: the file's first `define-sound`).
    #[arg(long)]
    class: Option<String>,

    /// Candidates per generation.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u32).range(2..=64))]
    population: u32,

    /// Seed of every random choice: the same seed and ratings give the same trees.
    #[arg(long, default_value_t = 1)]
    seed: u64,

    /// By ear: the folder for each generation's trees, the lineage and saved
    /// candidates (default evolve-out). Toward a target: the best tree's file
    /// (default best.tt).
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,

    /// Seconds of each candidate to play (by ear), or of the target to match.
    #[arg(long, default_value_t = 2.0, value_parser = crate::parse_positive)]
    seconds: f64,

    /// Search toward this recording (a WAV file) instead of by ear: candidates are
    /// scored by a multi-resolution spectral distance (lang-spec/evolution.md).
    #[arg(long, value_name = "FILE.wav")]
    target: Option<PathBuf>,

    /// Generations of the search toward a target.
    #[arg(long, default_value_t = 10, requires = "target")]
    generations: usize,

    /// Toward a target, tune only the numbers of the tree as it is: its parameters'
    /// values (an instance of the class), or its constants if it has no parameters.
    #[arg(long, requires = "target")]
    match_params: bool,

    /// Largest tree, in expressions (lists and atoms) of the class body.
    #[arg(long, default_value_t = 120)]
    max_size: usize,
}

/// One candidate of a generation.
struct Candidate {
    genome: Genome,
    /// How it was made: `seed`, `copy of 2.3`, `2.3 NewExpression+Wrap`, `2.3 x 2.5`.
    origin: String,
    rating: Option<u8>,
}

const SAMPLE_RATE: f64 = 48_000.0;

pub fn evolve(args: EvolveArgs) -> Result<(), Failure> {
    let cannot = |e: &dyn std::fmt::Display| {
        Failure::Message(format!("cannot read `{}`: {e}", args.seed_file.display()))
    };
    let limit = timbre::Limits::default().script_bytes();
    let bytes = timbre_lang::read_bounded(&args.seed_file, limit).map_err(|e| cannot(&e))?;
    let text = String::from_utf8(bytes).map_err(|_| cannot(&"it is not UTF-8 text"))?;
    let seed = Genome::from_source(&text, args.class.as_deref())
        .map_err(|e| Failure::Message(format!("`{}`: {e}", args.seed_file.display())))?;
    if !seed.values_given {
        let example: Vec<String> = seed.params.iter().map(|p| format!(":{p} …")).collect();
        let (names, verb) = match seed.params.len() {
            1 => (format!("`{}`", seed.params[0]), "starts"),
            _ => (
                format!("its parameters ({})", seed.params.join(", ")),
                "start",
            ),
        };
        eprintln!(
            "note: no instance of `{}` in the file gives every parameter a number, so {names} {verb} at 1; write one, e.g. (instance a ({} {}))",
            seed.name,
            seed.name,
            example.join(" ")
        );
    }
    match &args.target {
        Some(target) => toward(&args, seed, target),
        None => by_ear(&args, seed),
    }
}

/// The search toward a recording: `--match-params` tunes the tree's numbers; else
/// genetic programming with the best of each generation tuned.
fn toward(args: &EvolveArgs, seed: Genome, path: &Path) -> Result<(), Failure> {
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("best.tt"));
    // Checked first: the result may not replace the seed or the target.
    let output = crate::output::prepare(&out, &[args.seed_file.clone(), path.to_path_buf()])
        .map_err(Failure::Message)?;
    let (samples, rate) = read_mono(path, args.seconds)?;
    let target = Target::new(&samples, rate, args.seconds);
    let started = std::time::Instant::now();
    let before = target.measure(&seed);
    let (best, after, renders) = if args.match_params {
        let which = if seed.params.is_empty() {
            Knobs::Constants
        } else {
            Knobs::Values
        };
        let tuned = tune(&seed, &target, which, 200);
        (tuned.genome, tuned.distance, tuned.renders)
    } else {
        let mut rng = rand::rngs::StdRng::seed_from_u64(args.seed);
        let search = Search {
            generations: args.generations,
            population: args.population as usize,
            settings: Settings {
                max_size: args.max_size,
                ..Settings::default()
            },
            ..Search::default()
        };
        let found = timbre_evolve::search(&mut rng, &seed, &target, &search);
        for (k, d) in found.history.iter().enumerate().skip(2) {
            println!("generation {}: distance {d:.4}", k - 1);
        }
        (found.best, found.distance, found.renders)
    };
    let seconds = started.elapsed().as_secs_f64();
    let mut output = output;
    std::io::Write::write_all(
        output.file(),
        best.scene_source(target.audition().seconds).as_bytes(),
    )
    .map_err(|e| Failure::Message(format!("cannot write `{}`: {e}", out.display())))?;
    output.commit().map_err(Failure::Message)?;
    if !best.values.is_empty() {
        let values: Vec<String> = (best.params.iter().zip(&best.values))
            .map(|(p, v)| format!("{p} = {v:.6}"))
            .collect();
        println!("values: {}", values.join(", "));
    }
    println!(
        "distance {before:.4} → {after:.4} ({:.1}× closer); {renders} renders in {seconds:.1} s ({:.0} renders/s); wrote {}",
        before / after.max(1e-12),
        renders as f64 / seconds.max(1e-9),
        out.display()
    );
    Ok(())
}

/// A WAV file's samples, its channels averaged, and its rate.
/// The first `seconds` of a WAV file (what the search compares), as one channel.
fn read_mono(path: &Path, seconds: f64) -> Result<(Vec<f64>, f64), Failure> {
    let (raw, spec) = crate::read_wav(path, seconds)?;
    let channels = usize::from(spec.channels.max(1));
    let mono = raw
        .chunks(channels)
        .map(|frame| frame.iter().sum::<f64>() / channels as f64)
        .collect();
    Ok((mono, f64::from(spec.sample_rate)))
}

/// The by-ear loop.
fn by_ear(args: &EvolveArgs, seed: Genome) -> Result<(), Failure> {
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("evolve-out"));
    std::fs::create_dir_all(&out)
        .map_err(|e| Failure::Message(format!("cannot create `{}`: {e}", out.display())))?;
    let settings = Settings {
        max_size: args.max_size,
        ..Settings::default()
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(args.seed);
    let reads = [args.seed_file.clone()];
    let mut lineage = String::from("generation\tcandidate\torigin\trating\n");
    let population = args.population as usize;
    // The first generation: the seed and its mutants.
    let mut candidates = vec![Candidate {
        genome: seed.clone(),
        origin: "seed".into(),
        rating: None,
    }];
    while candidates.len() < population {
        candidates.push(offspring(&mut rng, &[(&seed, "seed".into(), 1)], &settings));
    }
    let stdin = std::io::stdin();
    let mut input = stdin.lock().lines();
    let mut played_once = false;
    for generation in 0.. {
        let dir = out.join(format!("gen-{generation:03}"));
        std::fs::create_dir_all(&dir)
            .map_err(|e| Failure::Message(format!("cannot create `{}`: {e}", dir.display())))?;
        for (k, candidate) in candidates.iter().enumerate() {
            write(
                &dir.join(format!("{:02}.tt", k + 1)),
                &candidate.genome,
                args.seconds,
                &reads,
            )?;
        }
        println!(
            "generation {generation}: {} candidates in {}",
            candidates.len(),
            dir.display()
        );
        let mut quit = false;
        'rating: for (k, candidate) in candidates.iter_mut().enumerate() {
            let label = format!("{generation}.{}", k + 1);
            let samples = render(&candidate.genome, args.seconds)?;
            let wav = dir.join(format!("{:02}.wav", k + 1));
            audition(&samples, &wav, &reads, &mut played_once)?;
            loop {
                print!(
                    "candidate {label} ({}): rate 0-9, r replay, s save, q quit > ",
                    candidate.origin
                );
                let _ = std::io::stdout().flush();
                let Some(Ok(line)) = input.next() else {
                    quit = true;
                    break 'rating;
                };
                match line.trim() {
                    "q" => {
                        quit = true;
                        break 'rating;
                    }
                    "r" => audition(&samples, &wav, &reads, &mut played_once)?,
                    "s" => {
                        let saved = out.join(format!("saved-{generation:03}-{:02}.tt", k + 1));
                        write(&saved, &candidate.genome, args.seconds, &reads)?;
                        println!("saved {}", saved.display());
                    }
                    digit if digit.len() == 1 && digit.as_bytes()[0].is_ascii_digit() => {
                        candidate.rating = Some(digit.as_bytes()[0] - b'0');
                        break;
                    }
                    other => println!("`{other}`: type a rating 0-9, r, s or q"),
                }
            }
        }
        for (k, c) in candidates.iter().enumerate() {
            let rating = c.rating.map_or("-".to_owned(), |r| r.to_string());
            lineage.push_str(&format!(
                "{generation}\t{}\t{}\t{rating}\n",
                k + 1,
                c.origin
            ));
        }
        crate::output::replace_file(&out.join("lineage.tsv"), lineage.as_bytes(), &reads)
            .map_err(Failure::Message)?;
        if quit {
            println!("stopped; every generation is in {}", out.display());
            return Ok(());
        }
        candidates = next_generation(&mut rng, generation, &candidates, population, &settings);
    }
    Ok(())
}

/// The next generation: the best candidate kept as it is, the rest bred from the
/// rated ones, each chosen in proportion to its rating.
fn next_generation(
    rng: &mut impl rand::Rng,
    generation: usize,
    candidates: &[Candidate],
    population: usize,
    settings: &Settings,
) -> Vec<Candidate> {
    let label = |k: usize| format!("{generation}.{}", k + 1);
    let mut parents: Vec<(&Genome, String, u8)> = (candidates.iter().enumerate())
        .filter_map(|(k, c)| Some((&c.genome, label(k), c.rating.filter(|r| *r > 0)?)))
        .collect();
    if parents.is_empty() {
        // Nothing liked: start again from the first candidate (the last best).
        parents.push((&candidates[0].genome, label(0), 1));
    }
    // The best, the first of them on a tie.
    let best = (parents.iter().rev())
        .max_by_key(|(_, _, rating)| *rating)
        .expect("one parent at least");
    let mut next = vec![Candidate {
        genome: best.0.clone(),
        origin: format!("copy of {}", best.1),
        rating: None,
    }];
    while next.len() < population {
        next.push(offspring(rng, &parents, settings));
    }
    next
}

/// A mutant of one parent, or with probability 0.3 (given two) a crossover of two;
/// parents (a genome, its label, its rating) are drawn in proportion to their rating.
fn offspring(
    rng: &mut impl rand::Rng,
    parents: &[(&Genome, String, u8)],
    settings: &Settings,
) -> Candidate {
    let draw = |rng: &mut dyn rand::Rng| -> usize {
        let total: u32 = parents.iter().map(|(_, _, r)| u32::from(*r)).sum();
        let mut x = rng.random_range(0..total.max(1));
        for (i, (_, _, r)) in parents.iter().enumerate() {
            if x < u32::from(*r) {
                return i;
            }
            x -= u32::from(*r);
        }
        0
    };
    let a = draw(rng);
    let (parent, k, _) = &parents[a];
    if parents.len() > 1 && rng.random_bool(0.3) {
        let b = draw(rng);
        if b != a {
            let (other, j, _) = &parents[b];
            if let Ok(child) = crossover(rng, parent, other, settings) {
                return Candidate {
                    genome: child.genome,
                    origin: format!("{k} x {j}"),
                    rating: None,
                };
            }
        }
    }
    match mutate(rng, parent, settings) {
        Ok(child) => {
            let operators: Vec<String> = child.operators.iter().map(|o| format!("{o:?}")).collect();
            Candidate {
                genome: child.genome,
                origin: format!("{k} {}", operators.join("+")),
                rating: None,
            }
        }
        Err(_) => Candidate {
            genome: (*parent).clone(),
            origin: format!("copy of {k} (no mutant passed the checks)"),
            rating: None,
        },
    }
}

/// A candidate as a scene file: its class and an instance of it.
fn write(path: &Path, genome: &Genome, seconds: f64, reads: &[PathBuf]) -> Result<(), Failure> {
    crate::output::replace_file(path, genome.scene_source(seconds).as_bytes(), reads)
        .map_err(Failure::Message)
}

/// A candidate's sound, through the `timbre` crate as `timbre render` makes it.
fn render(genome: &Genome, seconds: f64) -> Result<Vec<f64>, Failure> {
    let engine = timbre::Engine::new(SAMPLE_RATE);
    let mut scene = engine
        .load_scene(&genome.scene_source(seconds))
        .map_err(|e| Failure::Message(e.report()))?;
    scene
        .render_offline(seconds)
        .map_err(|e| Failure::Message(e.report()))
}

/// Plays a candidate; without a way to play, writes its WAV (and says so once).
fn audition(
    samples: &[f64],
    wav: &Path,
    reads: &[PathBuf],
    played_once: &mut bool,
) -> Result<(), Failure> {
    let cancel = AtomicBool::new(false);
    match crate::playback::play(samples, 1, SAMPLE_RATE, &cancel) {
        Ok(_) => Ok(()),
        Err(why) => {
            crate::audio_out::write_wav_samples(wav, samples, 1, SAMPLE_RATE, reads, &cancel)
                .map_err(Failure::Message)?;
            if !*played_once {
                println!("cannot play ({why}): each candidate is written as a WAV to listen to");
                *played_once = true;
            }
            println!("wrote {}", wav.display());
            Ok(())
        }
    }
}
