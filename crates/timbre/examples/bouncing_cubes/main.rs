//! Runs the bouncing-cubes simulation and writes its soundtrack:
//!
//! ```sh
//! cargo run --release -p timbre --example bouncing_cubes -- cubes.wav
//! ```

mod sim;

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "bouncing_cubes.wav".into()),
    );
    let seconds = 4.0;
    let impacts = sim::simulate(&sim::cubes(), seconds);
    for impact in &impacts {
        println!(
            "{:>8.5} s  {:?} at {:.2} m/s",
            impact.time, impact.material, impact.speed
        );
    }
    let engine = timbre::Engine::new(48_000.0).with_seed(7);
    let samples = sim::soundtrack(&engine, &impacts, seconds)?;
    // Written beside the target and renamed when complete: never a truncated file.
    let partial = path.with_extension("wav.partial");
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 48_000,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut writer = hound::WavWriter::create(&partial, spec)?;
    for x in &samples {
        writer.write_sample(*x as f32)?;
    }
    writer.finalize()?;
    std::fs::rename(&partial, &path)?;
    println!(
        "{} impacts, {seconds} s written to {}",
        impacts.len(),
        path.display()
    );
    Ok(())
}
