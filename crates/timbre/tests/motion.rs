//! Sound from a shot Blender made (`examples/shots/make-car-pass.py`): a source
//! riding an animated glTF node is heard at the Doppler frequency computed here from
//! Blender's own positions; a hinge's angular speed is the angle Blender turns it by;
//! and both engines give the same samples. `.ci/run` makes the shot afresh and points
//! `TIMBRE_BLENDER_SHOT` at it; without that variable the committed copies are read.

use serde_json::Value;
use timbre::{Backend, Engine};
use timbre_testkit::{blender_shot, zero_crossing_frequency};

const SR: f64 = 48_000.0;
const C: f64 = 343.0;

fn reference() -> Value {
    let text = std::fs::read_to_string(blender_shot().1).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// Blender's sample of `object` at `frame`: (position, rotation as w x y z).
fn blender(reference: &Value, object: &str, frame: f64) -> ([f64; 3], [f64; 4]) {
    let sample = reference["objects"][object]["samples"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["frame"].as_f64() == Some(frame))
        .unwrap_or_else(|| panic!("{object} has no sample at frame {frame}"));
    let p = |k: usize| sample["position"][k].as_f64().unwrap();
    let q = |k: usize| sample["rotation_wxyz"][k].as_f64().unwrap();
    ([p(0), p(1), p(2)], [q(0), q(1), q(2), q(3)])
}

fn render(scene: &str, seconds: f64, backend: Backend) -> Vec<f64> {
    let engine = Engine::new(SR).with_file_access().with_backend(backend);
    let mut scene = engine
        .load_scene(scene)
        .unwrap_or_else(|e| panic!("{}", e.report()));
    scene.render_offline(seconds).unwrap()
}

fn glb() -> String {
    blender_shot().0.display().to_string()
}

const LISTENER: [f64; 3] = [0.0, -12.0, 1.6];

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// A 1 kHz tone on the car, heard from the camera. Between the emission times of
/// frames a and b, 1000·(b − a)/fps cycles leave the car; they arrive between
/// t + |p(t) − listener|/c of each, with Blender's positions p. The mean frequency
/// heard there is their ratio, and the render must give it within 0.1 %.
#[test]
fn a_source_riding_the_car_is_heard_at_the_doppler_frequency_of_blenders_positions() {
    let reference = reference();
    let fps = reference["fps"].as_f64().unwrap();
    // The camera stands still (it only turns): the listener is where Blender has it.
    let camera = blender(&reference, "Camera", 1.0).0;
    assert!(distance(camera, LISTENER) < 1e-6, "{camera:?}");
    let scene = format!(
        "(scene :sample-rate 48000 :duration 5.2 :speed-of-sound {C} :distance-law none :air-absorption off)
         (motion shot \"{}\")
         (listener :object \"Camera\")
         (source car :object \"Car\")
         (define-sound tone (f) (sine (* t f)))
         (instance horn (tone :f 1000) :source car)",
        glb()
    );
    for backend in [Backend::Jit, Backend::Interpreter] {
        let x = render(&scene, 5.2, backend);
        let listener = blender(&reference, "Camera", 1.0).0;
        let mut heard = vec![];
        for (a, b) in [
            (10.0, 30.0),
            (40.0, 55.0),
            (60.0, 70.0),
            (80.0, 100.0),
            (100.0, 118.0),
        ] {
            let arrival = |frame: f64| {
                let p = blender(&reference, "Car", frame).0;
                frame / fps + distance(p, listener) / C
            };
            let (ra, rb) = (arrival(a), arrival(b));
            let expected = 1000.0 * (b - a) / fps / (rb - ra);
            let window = &x[(ra * SR).ceil() as usize..(rb * SR) as usize];
            let measured = zero_crossing_frequency(window, SR);
            let error = (measured - expected).abs() / expected;
            assert!(
                error < 1e-3,
                "{backend:?}, frames {a}–{b}: {measured} Hz, Blender's motion gives {expected} Hz"
            );
            heard.push(expected);
        }
        // The car approaches, then drives away: the pitch falls through 1 kHz.
        assert!(heard[0] > 1030.0 && heard[4] < 970.0, "{heard:?}");
    }
}

/// The door turns about its hinge by Blender's rotations, keyed every frame and
/// sampled LINEAR: between two frames it turns at the angle between them times
/// the frame rate.
#[test]
fn the_hinge_turns_at_the_angular_speed_of_blenders_rotations() {
    let reference = reference();
    let fps = reference["fps"].as_f64().unwrap();
    let scene = format!(
        "(scene :sample-rate 48000 :duration 5)
         (motion shot \"{}\")
         (define-sound hinge () (angular-speed \"Door\"))
         (instance door (hinge) :stop 5)",
        glb()
    );
    let x = render(&scene, 5.0, Backend::Jit);
    let mut turning = 0;
    for frame in 1..119 {
        let frame = frame as f64;
        let (_, qa) = blender(&reference, "Door", frame);
        let (_, qb) = blender(&reference, "Door", frame + 1.0);
        let dot: f64 = (0..4).map(|k| qa[k] * qb[k]).sum::<f64>().abs();
        let norm = |q: [f64; 4]| q.iter().map(|v| v * v).sum::<f64>().sqrt();
        let angle = 2.0 * (dot / (norm(qa) * norm(qb))).min(1.0).acos();
        let expected = angle * fps;
        let measured = x[((frame + 0.5) / fps * SR).round() as usize];
        if expected > 0.1 {
            turning += 1;
            let error = (measured - expected).abs() / expected;
            assert!(
                error < 1e-3,
                "frame {frame}: {measured} rad/s, Blender turns {expected}"
            );
        } else {
            assert!(measured < 0.1 + 2e-3 * fps, "frame {frame}: {measured}");
        }
    }
    assert!(
        turning > 40,
        "the door opens and closes: {turning} frames turning"
    );
}

/// Every node of motion, in both engines: the same samples, bit for bit.
#[test]
fn both_engines_agree_on_every_quantity_of_motion() {
    let scene = format!(
        "(scene :sample-rate 48000 :duration 2 :channels 1)
         (motion shot \"{}\")
         (keyframes path :interp smooth (0 (0 0 0)) (1 (3 1 0)) (2 (4 4 1)))
         (define-sound all ()
           (+ (combine (position \"Car\")) (combine (velocity \"Ball\"))
              (combine (acceleration path)) (speed path) (* 0.01 (distance \"Car\" \"Camera\"))
              (approach \"Car\" path) (angular-speed \"Door\") (combine (forward \"Camera\"))
              (combine (up \"Door\")) (combine (angular-velocity \"Door\"))))
         (instance a (all))",
        glb()
    );
    let jit = render(&scene, 2.0, Backend::Jit);
    let interpreted = render(&scene, 2.0, Backend::Interpreter);
    assert!(jit.iter().any(|x| *x != 0.0));
    assert_eq!(jit, interpreted);
}

/// The ball's height, keyed by Blender and exported one LINEAR key per frame, falls
/// through 0.12 m once per bounce: the crossing of that interpolant, computed here
/// from Blender's positions at the frames around it, is where each event lands
/// (within one sample), and the speed bound to it is the secant speed of Blender's
/// positions over that frame.
#[test]
fn each_bounce_blender_keyed_is_one_event_on_the_crossing() {
    let reference = reference();
    let fps = reference["fps"].as_f64().unwrap();
    let mut expected = vec![];
    for frame in 1..120 {
        let (a, b) = (frame as f64, frame as f64 + 1.0);
        let (pa, pb) = (
            blender(&reference, "Ball", a).0,
            blender(&reference, "Ball", b).0,
        );
        if pa[2] >= 0.12 && pb[2] < 0.12 {
            let s = (pa[2] - 0.12) / (pa[2] - pb[2]);
            let speed = distance(pa, pb) * fps;
            expected.push(((a + s) / fps, speed));
        }
    }
    assert_eq!(expected.len(), 5, "the shot's ball bounces five times");
    let engine = Engine::new(SR).with_file_access();
    let file = engine
        .read_scene(&format!(
            "(scene :sample-rate 48000)
             (motion shot \"{}\")
             (listener :object \"Camera\")
             (define-sound knock (v) (* 0.2 v (sine (* t 800)) (damp (* t 40))))
             (events bounce :when (index (position \"Ball\") 2) :below 0.12
                     :class knock :bind (:v (speed \"Ball\")))",
            glb()
        ))
        .unwrap_or_else(|e| panic!("{e:?}"));
    let found = &file.program().events[0];
    assert_eq!(found.events.len(), expected.len());
    for (k, (event, (time, speed))) in found.events.iter().zip(&expected).enumerate() {
        assert_eq!(event.instance, format!("bounce-{}", k + 1));
        assert!(
            (event.time - time).abs() * SR < 1.0,
            "bounce {k}: at {} s, Blender's keys cross at {time} s",
            event.time
        );
        let v = event.bound[0].1[0];
        assert!(
            (v - speed).abs() / speed < 1e-4,
            "bounce {k}: v = {v}, Blender's {speed}"
        );
    }
}
