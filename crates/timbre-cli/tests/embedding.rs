//! The embedding API and the command line render a scene file the same: stereo `f32`
//! from `timbre::Scene::render_f32` equals `timbre render --format f32`, sample for
//! sample.

mod common;

use std::path::Path;

use common::{run, workspace_root};
use timbre_testkit::read_wav;

#[test]
fn stereo_f32_from_the_api_equals_the_command_lines_render() {
    let dir = tempfile::tempdir().unwrap();
    let wav = dir.path().join("ball.wav");
    let scene = "examples/bouncing-ball.tt";
    run([
        "render",
        scene,
        "-o",
        wav.to_str().unwrap(),
        "--format",
        "f32",
        "--quiet",
    ])
    .assert_success();
    let cli = read_wav(&wav);
    assert_eq!(cli.spec.channels, 2);

    let engine = timbre::Engine::new(cli.rate()).with_file_access();
    let mut api = engine
        .load_scene_file(&workspace_root().join(Path::new(scene)))
        .unwrap();
    assert_eq!(api.channels(), 2);
    let mut frames = vec![0.0f32; cli.samples.len()];
    // In blocks of an audio callback's size, not the command line's.
    for block in frames.chunks_mut(2 * 300) {
        api.render_f32(block).unwrap();
    }
    let loud = frames.iter().filter(|x| x.abs() > 0.01).count();
    assert!(loud > 10_000, "a silent scene: {loud} loud samples");
    let first_difference = (cli.samples.iter().zip(&frames)).position(|(a, b)| *a != f64::from(*b));
    assert_eq!(
        first_difference, None,
        "the API and the command line differ"
    );
}
