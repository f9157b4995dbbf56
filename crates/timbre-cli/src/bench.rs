//! `timbre bench`: renders the benchmark workloads (`timbre-benches`) with both
//! engines in this process and prints their throughput, the JIT's compile time, and
//! how compile time grows with the size of a tree.
//!
//! Wall-clock timing with `Instant`, one thread (and, for scenes, a column with every
//! core), median of several runs. Each JIT
//! measurement uses a fresh compiler, so its kernel is compiled from an empty cache.
//! Audio is rendered in chunks into one reused buffer, so memory does not grow with
//! the duration.

use std::hint::black_box;
use std::time::{Duration, Instant};
use timbre_scene::{Engine as SceneEngine, SceneRenderer};

use clap::builder::PossibleValuesParser;
use clap::Args;
use timbre_benches::{
    compile, interpreter, synthetic, try_compile, workload, Workload, CONFIG, WORKLOADS,
};
use timbre_jit::Jit;

use crate::{parse_positive, Failure};

/// Sizes of the synthetic trees of the compile-time table.
const TREE_SIZES: [usize; 3] = [100, 300, 1000];

/// Samples rendered per call: a whole number of blocks.
const CHUNK: usize = 4096;

#[derive(Args, Debug)]
pub struct BenchArgs {
    /// Workloads to run (default: all of them, in this order).
    #[arg(value_name = "WORKLOAD", value_parser = PossibleValuesParser::new(WORKLOADS))]
    workloads: Vec<String>,

    /// Seconds of audio rendered per run [default: 1].
    #[arg(long, short = 's', value_parser = parse_positive, conflicts_with = "quick")]
    seconds: Option<f64>,

    /// Runs of each measurement; the median is reported [default: 5].
    #[arg(long, short = 'n', value_parser = clap::value_parser!(u32).range(1..=1000), conflicts_with = "quick")]
    runs: Option<u32>,

    /// A rough look: 0.1 s of audio, one run.
    #[arg(long)]
    quick: bool,
}

/// One workload's medians.
struct Measured {
    interp: Duration,
    jit: Duration,
    compile: Duration,
    /// Share of the JIT's time spent in interpreter callbacks (nodes not compiled).
    callbacks: f64,
    /// A scene's JIT render with every core rendering instances.
    threaded: Option<Duration>,
}

pub fn bench(args: BenchArgs) -> Result<(), Failure> {
    let (seconds, runs) = if args.quick {
        (0.1, 1)
    } else {
        (args.seconds.unwrap_or(1.0), args.runs.unwrap_or(5) as usize)
    };
    let samples = ((seconds * CONFIG.sample_rate).round() as u64).max(1);
    let names: Vec<&str> = if args.workloads.is_empty() {
        WORKLOADS.to_vec()
    } else {
        args.workloads.iter().map(String::as_str).collect()
    };
    // Fail before measuring anything if the JIT cannot run here.
    Jit::new().map_err(|e| Failure::Message(format!("the JIT cannot run here: {e}")))?;

    println!(
        "timbre bench: {} s of audio per run, {}, single thread, {}",
        format_seconds(samples as f64 / CONFIG.sample_rate),
        if runs == 1 {
            "1 run".to_owned()
        } else {
            format!("median of {runs} runs")
        },
        machine(),
    );
    println!(
        "{} kHz in blocks of {}; compile = the JIT kernel's compile time from an empty cache",
        CONFIG.sample_rate / 1000.0,
        CONFIG.block_size,
    );
    println!();
    println!("callbacks = share of the JIT's time spent in the interpreter, on nodes it does not compile");
    println!(
        "jit {threads} threads = a scene's instances, or a large modal bank's modes, on {threads} threads (bit for bit the same output)",
        threads = cores()
    );
    println!();
    let widths = [18, 16, 13, 10, 16, 13, 9, 9, 15];
    print_row(
        &widths,
        &[
            "workload",
            "interp samples/s",
            "jit samples/s",
            "jit/interp",
            "interp real-time",
            "jit real-time",
            "compile",
            "callbacks",
            &format!("jit {} threads", cores()),
        ],
    );
    let mut buffer = vec![0.0; CHUNK];
    for name in names {
        let workload = workload(name).expect("clap accepts only known workloads");
        if let Err(why) = try_compile(&workload) {
            println!("{name}: not measured: {why}");
            continue;
        }
        let m = measure(&workload, samples, runs, &mut buffer)?;
        let rate = |d: Duration| samples as f64 / seconds_of(d);
        let (interp, jit) = (rate(m.interp), rate(m.jit));
        print_row(
            &widths,
            &[
                name,
                &format_si(interp),
                &format_si(jit),
                &format_factor(jit / interp),
                &format_factor(interp / CONFIG.sample_rate),
                &format_factor(jit / CONFIG.sample_rate),
                &format_ms(m.compile),
                &format!("{:.0} %", 100.0 * m.callbacks),
                &m.threaded.map_or("-".into(), |d| format_si(rate(d))),
            ],
        );
    }

    println!();
    println!("compile time by tree size (fresh compiler each run)");
    let widths = [5, 10, 10];
    print_row(&widths, &["nodes", "compile", "per node"]);
    for size in TREE_SIZES {
        let program = compile(&synthetic(size));
        let voice = interpreter(&program);
        let steps = voice.steps();
        let mut times = Vec::with_capacity(runs);
        for _ in 0..runs {
            let mut jit = fresh_jit()?;
            let kernel = jit
                .compile(steps, CONFIG.block_size)
                .map_err(|e| Failure::Message(format!("synthetic-{size}: {e}")))?;
            times.push(kernel.compile_time);
        }
        let time = median(&mut times);
        print_row(
            &widths,
            &[
                &steps.len().to_string(),
                &format_ms(time),
                &format_us(time / steps.len() as u32),
            ],
        );
    }
    Ok(())
}

/// Medians of `runs` renders of `samples` samples by each engine, the two engines
/// taking turns so that a change in the machine's load affects both alike.
fn measure(
    workload: &Workload,
    samples: u64,
    runs: usize,
    buffer: &mut [f64],
) -> Result<Measured, Failure> {
    let program = compile(workload);
    let (mut interp, mut jit, mut compile, mut threaded) = (vec![], vec![], vec![], vec![]);
    let mut in_callbacks: Vec<f64> = vec![];
    let Some(root) = program.root else {
        // A scene: its instances through the scene renderer, with both engines.
        let first = program
            .instances
            .first()
            .map(|i| i.root)
            .expect("a scene has instances");
        for _ in 0..runs {
            for (engine, times) in [
                (SceneEngine::Interpreter, &mut interp),
                (SceneEngine::Jit, &mut jit),
            ] {
                let mut scene = SceneRenderer::new(&program, CONFIG, engine)
                    .map_err(|e| Failure::Message(format!("{}: {e}", workload.name)))?;
                // `samples` frames of every channel.
                let values = samples * scene.channels() as u64;
                let profiled = engine == SceneEngine::Jit;
                timbre_jit::profile::enable(profiled);
                let _ = timbre_jit::profile::take();
                let time = time_render(values, buffer, |out| {
                    scene.render(out).expect("kernels of a benchmark compile")
                });
                timbre_jit::profile::enable(false);
                if profiled {
                    in_callbacks.push(timbre_jit::profile::take().as_secs_f64() / seconds_of(time));
                }
                times.push(time);
            }
            let mut scene = SceneRenderer::new(&program, CONFIG, SceneEngine::Jit)
                .map_err(|e| Failure::Message(format!("{}: {e}", workload.name)))?;
            scene
                .set_threads(cores())
                .map_err(|e| Failure::Message(format!("threads: {e}")))?;
            let values = samples * scene.channels() as u64;
            threaded.push(time_render(values, buffer, |out| {
                scene.render(out).expect("kernels of a benchmark compile")
            }));
            let voice = fresh_jit()?
                .voice(&program.graph, first, CONFIG)
                .map_err(|e| Failure::Message(format!("{}: {e}", workload.name)))?;
            compile.push(voice.kernel().compile_time);
        }
        return Ok(Measured {
            interp: median(&mut interp),
            jit: median(&mut jit),
            compile: median(&mut compile),
            callbacks: median_share(&mut in_callbacks),
            threaded: Some(median(&mut threaded)),
        });
    };
    let pool = match cores() {
        1 => None,
        n => Some(std::sync::Arc::new(
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| Failure::Message(format!("threads: {e}")))?,
        )),
    };
    for _ in 0..runs {
        let mut voice = interpreter(&program);
        interp.push(time_render(samples, buffer, |out| voice.render(out)));

        let mut voice = fresh_jit()?
            .voice(&program.graph, root, CONFIG)
            .map_err(|e| Failure::Message(format!("{}: {e}", workload.name)))?;
        compile.push(voice.kernel().compile_time);
        timbre_jit::profile::enable(true);
        let _ = timbre_jit::profile::take();
        let time = time_render(samples, buffer, |out| voice.render(out));
        timbre_jit::profile::enable(false);
        in_callbacks.push(timbre_jit::profile::take().as_secs_f64() / seconds_of(time));
        jit.push(time);
        if let Some(pool) = &pool {
            // One voice: only its large modal banks share their work out.
            voice.set_threads(Some(pool.clone()));
            threaded.push(time_render(samples, buffer, |out| voice.render(out)));
        }
    }
    Ok(Measured {
        interp: median(&mut interp),
        jit: median(&mut jit),
        compile: median(&mut compile),
        callbacks: median_share(&mut in_callbacks),
        threaded: (!threaded.is_empty()).then(|| median(&mut threaded)),
    })
}

/// The threads this process may use.
fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The median of shares (fractions of a time).
fn median_share(shares: &mut [f64]) -> f64 {
    shares.sort_by(f64::total_cmp);
    shares.get(shares.len() / 2).copied().unwrap_or(0.0)
}

fn fresh_jit() -> Result<Jit, Failure> {
    Jit::new().map_err(|e| Failure::Message(format!("the JIT cannot run here: {e}")))
}

/// Wall-clock time to render `samples` samples, a chunk at a time into `buffer`.
fn time_render(samples: u64, buffer: &mut [f64], mut render: impl FnMut(&mut [f64])) -> Duration {
    let start = Instant::now();
    let mut left = samples;
    while left > 0 {
        let n = left.min(buffer.len() as u64) as usize;
        render(&mut buffer[..n]);
        black_box(&buffer[..n]);
        left -= n as u64;
    }
    start.elapsed()
}

fn median(times: &mut [Duration]) -> Duration {
    times.sort();
    let mid = times.len() / 2;
    if times.len() % 2 == 1 {
        times[mid]
    } else {
        (times[mid - 1] + times[mid]) / 2
    }
}

/// Seconds, never zero (a timer may not tick for a tiny render).
fn seconds_of(d: Duration) -> f64 {
    d.as_secs_f64().max(1e-9)
}

/// The CPU model and the number of threads this process may use.
fn machine() -> String {
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .filter_map(|line| line.split_once(':'))
                .find(|(key, _)| key.trim() == "model name")
                .map(|(_, value)| value.split_whitespace().collect::<Vec<_>>().join(" "))
        })
        .filter(|model| !model.is_empty())
        .unwrap_or_else(|| "unknown".to_owned());
    match std::thread::available_parallelism() {
        Ok(n) if n.get() == 1 => format!("{model} (1 core)"),
        Ok(n) => format!("{model} ({n} cores)"),
        Err(_) => model,
    }
}

/// The first cell left-aligned, the others right-aligned, two spaces apart.
fn print_row(widths: &[usize], cells: &[&str]) {
    let mut line = String::new();
    for (i, (cell, width)) in cells.iter().zip(widths).enumerate() {
        if i == 0 {
            line.push_str(&format!("{cell:<width$}"));
        } else {
            line.push_str(&format!("  {cell:>width$}"));
        }
    }
    println!("{}", line.trim_end());
}

/// Three significant digits: 0.123, 1.23, 12.3, 123.
fn three_digits(x: f64) -> String {
    match x.abs() {
        a if a >= 99.95 => format!("{x:.0}"),
        a if a >= 9.995 => format!("{x:.1}"),
        a if a >= 0.9995 => format!("{x:.2}"),
        _ => format!("{x:.3}"),
    }
}

/// A rate with an SI prefix: `412 k`, `7.35 M`.
fn format_si(x: f64) -> String {
    for (scale, prefix) in [(1e9, "G"), (1e6, "M"), (1e3, "k")] {
        if x >= scale * 0.9995 {
            return format!("{} {prefix}", three_digits(x / scale));
        }
    }
    format!("{}  ", three_digits(x))
}

/// Seconds as written, with at least one decimal: `1.0`, `0.1`, `2.5`.
fn format_seconds(x: f64) -> String {
    if x.fract() == 0.0 {
        format!("{x:.1}")
    } else {
        format!("{x}")
    }
}

fn format_factor(x: f64) -> String {
    format!("{}×", three_digits(x))
}

fn format_ms(d: Duration) -> String {
    format!("{} ms", three_digits(d.as_secs_f64() * 1e3))
}

fn format_us(d: Duration) -> String {
    format!("{} µs", three_digits(d.as_secs_f64() * 1e6))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_have_three_significant_digits() {
        assert_eq!(format_si(412_345.0), "412 k");
        assert_eq!(format_si(7_354_000.0), "7.35 M");
        assert_eq!(format_si(999_990.0), "1.00 M");
        assert_eq!(format_si(12.0), "12.0  ");
        assert_eq!(format_seconds(1.0), "1.0");
        assert_eq!(format_seconds(0.1), "0.1");
        assert_eq!(format_factor(17.84), "17.8×");
        assert_eq!(format_factor(153.2), "153×");
        assert_eq!(format_factor(0.8612), "0.861×");
        assert_eq!(format_ms(Duration::from_micros(612)), "0.612 ms");
        assert_eq!(format_us(Duration::from_nanos(9_040)), "9.04 µs");
    }

    #[test]
    fn median_of_odd_and_even_counts() {
        let ms = Duration::from_millis;
        assert_eq!(median(&mut [ms(3), ms(1), ms(2)]), ms(2));
        assert_eq!(
            median(&mut [ms(4), ms(1), ms(2), ms(3)]),
            Duration::from_micros(2500)
        );
    }
}
