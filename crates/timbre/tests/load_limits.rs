//! `Limits::load_time` bounds loading as `render_time` bounds rendering: a host
//! loading a hostile score gets its diagnostic within the deadline (most are refused
//! at once, by arithmetic), and a script that is merely slow to lower stops at the
//! deadline with `timbre::load-too-slow`.

use std::time::{Duration, Instant};

use timbre::{Engine, Error, Limits};

const SR: f64 = 48_000.0;

const PRELUDE: &str = "(scene :duration 8)
(keyframes h :interp linear (0 0) (8 2))
(define-sound p (freq amp gate) (* 0.1 amp gate (sine (* t freq))))
";

fn engine(load_time: Duration) -> Engine {
    Engine::new(SR).with_limits(Limits {
        load_time: Some(load_time),
        ..Limits::default()
    })
}

/// The code of the first diagnostic of an error.
fn code(error: &Error) -> String {
    match error {
        Error::Script(d) => d.0[0].code.to_string(),
        other => panic!("not a diagnostic: {other}"),
    }
}

/// Loads `scene` and returns the error's code and how long it took.
fn refused(engine: &Engine, scene: &str) -> (String, Duration) {
    let started = Instant::now();
    let error = match engine.load_scene(scene) {
        Ok(_) => panic!("loaded: {scene}"),
        Err(error) => error,
    };
    (code(&error), started.elapsed())
}

#[test]
fn hostile_scores_are_refused_within_the_deadline() {
    let engine = engine(Duration::from_secs(2));
    let cases = [
        // Hung for ever: octaves stepped by 12 from 1e308.
        (
            "(score s (part a p h :semitones 1e308))",
            "timbre::bad-score",
        ),
        // Hung: 8e12 beats walked.
        ("(score s :beat 1e-12 (part a p h))", "timbre::bad-score"),
        ("(score s :tempo 1e12 (part a p h))", "timbre::bad-score"),
        (
            "(score s :end 1e300 (part a p h))",
            "timbre::too-many-beats",
        ),
        (
            "(score s :end 1e5 (part a p h :rhythm motion :frame-rate 1000))",
            "timbre::too-many-beats",
        ),
        (
            "(score s :beat 0.001 :end 1000 (part a p h :slur off))",
            "timbre::too-many-instances",
        ),
        (
            "(score s :tempo 120 :division 1e9 (part a p h))",
            "timbre::bad-score",
        ),
        (
            "(score s (part a p h :tail 1e300 :delay -1))",
            "timbre::bad-score",
        ),
    ];
    for (score, expected) in cases {
        let (code, took) = refused(&engine, &format!("{PRELUDE}{score}"));
        assert_eq!(code, expected, "{score}");
        assert!(took < Duration::from_secs(3), "{score}: {took:?}");
    }
    // The frame pattern that panicked in `format!`, with the default loader (no files).
    let (code, took) = refused(&engine, "(frames v :pattern \"f-%01000000000d.png\")");
    assert_eq!(code, "timbre::bad-frames");
    assert!(took < Duration::from_secs(3));
}

#[test]
fn a_score_merely_slow_to_lower_stops_at_the_deadline() {
    // 20 000 notes within every other limit, each an instance lowered.
    let scene = format!("{PRELUDE}(score s :beat 0.001 :end 20 (part a p h :slur off))");
    let started = Instant::now();
    let file = Engine::new(SR)
        .read_scene(&scene)
        .expect("within the limits");
    let unbounded = started.elapsed();
    assert_eq!(file.instances().count(), 20_000);
    let deadline = Duration::from_millis(10);
    assert!(unbounded > 4 * deadline, "lowered in only {unbounded:?}");
    let (code, took) = refused(&engine(deadline), &scene);
    assert_eq!(code, "timbre::load-too-slow");
    assert!(took < deadline + unbounded / 2, "{took:?} of {unbounded:?}");
    let error = engine(deadline).load_scene(&scene).err().unwrap();
    assert!(
        error.report().contains("relax Limits::load_time"),
        "{}",
        error.report()
    );
}

#[test]
fn the_deadline_bounds_libraries_too() {
    // 2¹⁵ expansions.
    let mut library = timbre_testkit::doubling_trees(15);
    library.push_str("(define-sound organ () (* 0.001 (f15 1)))");
    let started = Instant::now();
    assert!(Engine::new(SR).load_library(&library).is_ok());
    let unbounded = started.elapsed();
    let deadline = Duration::from_millis(5);
    assert!(unbounded > 4 * deadline, "lowered in only {unbounded:?}");
    let started = Instant::now();
    let errors = engine(deadline).load_library(&library).unwrap_err();
    assert!(started.elapsed() < deadline + unbounded / 2);
    assert_eq!(errors.0.len(), 1, "{errors:?}");
    assert_eq!(errors.0[0].code, "timbre::load-too-slow");
}
