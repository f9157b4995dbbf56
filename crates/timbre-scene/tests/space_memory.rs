//! A ten-minute scene of moving sources renders in flat memory: what is allocated
//! after the first minute is freed again, and the live heap never grows.

use timbre_ir::RenderConfig;
use timbre_lang::{compile_str, CompileOptions, FsLoader, Registry};
use timbre_scene::{Engine, SceneRenderer};
use timbre_testkit::heap;

#[global_allocator]
static HEAP: heap::Counting = heap::Counting;

#[test]
fn ten_minutes_of_moving_sources_render_in_flat_memory() {
    // Two sources going back and forth past a stereo pair for ten minutes, in a room
    // with an obstacle, one sound stopping and another starting every minute.
    let mut text = String::from(
        "(scene :duration 600 :channels 2)
         (define-sound tone (f) (* 0.1 (sine (* t f))))
         (room :size (30 30 10) :absorption 0.3 :order 1 :reverb none)
         (box crate :size (1 1 1) :position (15 12 2))
         (listener :position (15 15 2) :pair spaced)
         (keyframes a :interp smooth (0 (2 5 2)) (60 (28 5 2)) (120 (2 5 2)) (180 (28 5 2))
                     (240 (2 5 2)) (300 (28 5 2)) (360 (2 5 2)) (420 (28 5 2)) (480 (2 5 2))
                     (540 (28 5 2)) (600 (2 5 2)))
         (source s1 :position a)
         (source s2 :position (keyframes :interp linear (0 (5 25 3)) (600 (25 25 3))))\n",
    );
    for minute in 0..10 {
        let start = 60 * minute;
        text += &format!(
            "(instance a{minute} (tone :f {}) :source s1 :start {start} :stop {})
             (instance b{minute} (tone :f {}) :source s2 :start {} :stop {})\n",
            300 + 20 * minute,
            start + 60,
            500 + 20 * minute,
            start + 30,
            start + 50,
        );
    }
    let registry = Registry::new();
    let options = CompileOptions::new(&registry, &FsLoader);
    let program = compile_str(&text, &options).unwrap_or_else(|e| panic!("{e:?}"));
    let config = RenderConfig {
        sample_rate: 48_000.0,
        block_size: 256,
    };
    let mut renderer = SceneRenderer::new(&program, config, Engine::Jit).unwrap();
    let mut block = vec![0.0; 2 * 4800];
    let mut after_first_minute = 0;
    let mut most = 0;
    for tenth in 0..6000 {
        renderer.render(&mut block).unwrap();
        let live = heap::live_bytes();
        if tenth == 600 {
            after_first_minute = live;
        }
        if tenth > 600 {
            most = most.max(live);
        }
    }
    // Voices come and go (each a delay line and its buffers), but the heap does not
    // grow with the scene's length: at most 256 KiB more than at 1 min (a voice's delay
    // line here is 130 KiB; 20 leaked voices would be 2.6 MiB).
    eprintln!("live heap {after_first_minute} B at 1 min, at most {most} B later");
    let slack = 256 << 10;
    assert!(
        most <= after_first_minute + slack,
        "live heap {after_first_minute} B at 1 min, up to {most} B later"
    );
}
