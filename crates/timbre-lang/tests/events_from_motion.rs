//! The `events` form: instances started where an expression of scene time crosses a
//! threshold or peaks, checked against crossings computed here in closed form, and
//! its diagnostics.

mod common;

use timbre_lang::{Compiled, Diag};

fn compile(text: &str) -> Compiled {
    common::compile_with(text, &[], 0).unwrap_or_else(|e| panic!("{text}: {e:?}"))
}

fn error(text: &str) -> Diag {
    let errors = common::compile_with(text, &[], 0).expect_err(text).0;
    errors.into_iter().next().unwrap()
}

/// The event times of the file's first `events` form, and its instances' starts.
fn event_times(program: &Compiled) -> Vec<f64> {
    let times: Vec<f64> = program.events[0].events.iter().map(|e| e.time).collect();
    let starts: Vec<f64> = program.instances.iter().map(|i| i.start).collect();
    assert_eq!(times, starts, "each event starts its instance");
    times
}

fn assert_times(found: &[f64], expected: &[f64]) {
    assert_eq!(found.len(), expected.len(), "{found:?} vs {expected:?}");
    for (f, e) in found.iter().zip(expected) {
        assert!((f - e).abs() < 2e-9, "event at {f} s, crossing at {e} s");
    }
}

const KNOCK: &str = "(define-sound knock (v) (* 0.2 v (sine (* t 700)) (damp (* t 30))))";

#[test]
fn linear_keys_fall_and_rise_through_the_threshold_where_the_lines_cross_it() {
    let keys = "(keyframes h :interp linear (0 1) (1 0) (2 1) (3 0))";
    // h = 1 − t on [0, 1]: 0.3 at 0.7; on [2, 3] at 2.7. Rising: t − 1 = 0.3 at 1.3.
    for (threshold, expected) in [
        (":below 0.3", vec![0.7, 2.7]),
        (":above 0.3", vec![1.3]),
        (":cross 0.3", vec![0.7, 1.3, 2.7]),
    ] {
        let program = compile(&format!(
            "{keys} {KNOCK} (events e :when h {threshold} :class knock :bind (:v 1))"
        ));
        assert_times(&event_times(&program), &expected);
        let names: Vec<&str> = program.instances.iter().map(|i| i.name.as_str()).collect();
        let expected_names: Vec<String> = (1..=expected.len()).map(|k| format!("e-{k}")).collect();
        assert_eq!(names, expected_names);
    }
}

/// A keyed ball dropped from 1 m, bouncing to 0.6 and 0.36 m, with smooth keys: every
/// key an extreme or on a flat end, where monotone cubic slopes are 0, so each
/// interval is y0 + (y1 − y0)(3s² − 2s³).
const BALL: &str = "(keyframes ball :interp smooth
    (0 (0 0 1)) (0.2 (0.4 0 1)) (0.7 (1.4 0 0)) (1.1 (2.2 0 0.6)) (1.5 (3 0 0))
    (1.8 (3.6 0 0.36)) (2.1 (4.2 0 0)) (2.4 (4.8 0 0)))";

/// Where y0 + (y1 − y0)(3s² − 2s³) = x on [t0, t1]: the inverse of the smoothstep.
fn smooth_crossing(t0: f64, t1: f64, y0: f64, y1: f64, x: f64) -> f64 {
    let p = (x - y0) / (y1 - y0);
    let s = 0.5 - ((1.0 - 2.0 * p).asin() / 3.0).sin();
    t0 + s * (t1 - t0)
}

#[test]
fn a_keyed_ball_gives_one_event_per_bounce_in_order_with_its_values_bound() {
    let program = compile(&format!(
        "{BALL} (define-sound knock (v height) (* 0.2 v height (sine (* t 700))))
         (events bounce :when (index ball 2) :below 0.12 :class knock
                 :bind (:v (index ball 0) :height :when))"
    ));
    let descents = [
        (0.2, 0.7, 1.0, 0.0),
        (1.1, 1.5, 0.6, 0.0),
        (1.8, 2.1, 0.36, 0.0),
    ];
    let expected: Vec<f64> = descents
        .iter()
        .map(|&(t0, t1, y0, y1)| smooth_crossing(t0, t1, y0, y1, 0.12))
        .collect();
    assert_times(&event_times(&program), &expected);
    for (event, t) in program.events[0].events.iter().zip(&expected) {
        // x moves 2 m/s on collinear keys: the smooth curve is the line x = 2t.
        let (param, x) = &event.bound[0];
        assert_eq!(param, "v");
        assert!((x[0] - 2.0 * t).abs() <= 1e-6 * 2.0 * t, "{x:?} at {t}");
        let (param, height) = &event.bound[1];
        assert_eq!(param, "height");
        assert!((height[0] - 0.12).abs() <= 1e-6 * 0.12, "{height:?}");
    }
}

#[test]
fn peaks_above_the_threshold_are_found_at_the_top_with_their_height() {
    let program = compile(&format!(
        "{BALL} {KNOCK}
         (events top :when (index ball 2) :peaks 0.3 :class knock :bind (:v :when))"
    ));
    // The tops after the first drop: 0.6 at 1.1 s and 0.36 at 1.8 s (the drop's
    // start holds from 0 s and is no peak).
    assert_times(&event_times(&program), &[1.1, 1.8]);
    let heights: Vec<f64> = program.events[0]
        .events
        .iter()
        .map(|e| e.bound[0].1[0])
        .collect();
    assert!((heights[0] - 0.6).abs() < 1e-9 && (heights[1] - 0.36).abs() < 1e-9);
}

#[test]
fn spacing_and_hysteresis_keep_chatter_to_one_event() {
    // Falls through 0.5 at 1, wobbles back up to 0.52 and down again within 20 ms.
    let keys =
        "(keyframes h :interp linear (0 1) (1 0.5) (1.01 0.52) (1.02 0.4) (2 0.4) (3 1) (4 0))";
    let run = |options: &str| {
        let program = compile(&format!(
            "{keys} {KNOCK} (events e :when h :below 0.5 :class knock :bind (:v 1) {options})"
        ));
        event_times(&program)
    };
    // The second fall, at 1.01 + 0.01·(0.02/0.12): 16.7 ms after the first.
    let wobble = 1.01 + 0.01 * (0.02 / 0.12);
    let last = 3.5;
    assert_times(&run(":spacing 0"), &[1.0, wobble, last]);
    assert_times(&run(""), &[1.0, wobble, last]); // default spacing 10 ms
    assert_times(&run(":spacing 0.02"), &[1.0, last]);
    assert_times(&run(":spacing 0 :hysteresis 0.05"), &[1.0, last]);
}

#[test]
fn the_search_is_limited_by_from_and_until_and_frames_are_counted() {
    let keys = "(keyframes h :interp linear (0 1) (1 0) (2 1) (3 0))";
    let program = compile(&format!(
        "{keys} {KNOCK} (events e :when h :below 0.3 :class knock :bind (:v 1)
                          :from 1 :until 4 :frame-rate 24 :first-frame 1)"
    ));
    assert_times(&event_times(&program), &[2.7]);
    let frame = program.events[0].frame(2.7).unwrap();
    assert!((frame - (1.0 + 2.7 * 24.0)).abs() < 1e-6);
}

#[test]
fn each_event_instance_reads_its_keyframes_at_its_own_start() {
    let program = compile(
        "(keyframes h :interp linear (0 1) (1 0) (2 1) (3 0))
         (define-sound knock (v) (* v (sine (* t 700))))
         (events e :when h :below 0.3 :class knock :bind (:v h) :gain 0.5 :length 0.25)",
    );
    // At the crossing h = 0.3: each instance's v is 0.3, its stop a quarter second on.
    for (instance, start) in program.instances.iter().zip([0.7, 2.7]) {
        assert!((instance.stop.unwrap() - start - 0.25).abs() < 1e-8);
    }
    for event in &program.events[0].events {
        assert!((event.bound[0].1[0] - 0.3).abs() < 1e-8);
    }
}

/// (file, code, message start, underlined text)
const BAD: &[(&str, &str, &str, &str)] = &[
    (
        "(events e :below 0.1 :class knock)",
        "timbre::bad-events",
        "`events` needs `:when`",
        "(events e :below 0.1 :class knock)",
    ),
    (
        "(events e :when h :class knock)",
        "timbre::bad-events",
        "`events` needs a threshold",
        "(events e :when h :class knock)",
    ),
    (
        "(events e :when h :below 0.1 :above 0.2 :class knock)",
        "timbre::bad-events",
        "`events` takes one threshold, and has `:below` and `:above`",
        "0.1",
    ),
    (
        "(events e :when h :below 0.1 :class knok)",
        "timbre::unknown-class",
        "unknown sound class `knok`",
        "knok",
    ),
    (
        "(events e :when (lowpass h 10) :below 0.1 :class knock)",
        "timbre::bad-events",
        "`:when` must be a function of scene time alone, and `lowpass` is not",
        "(lowpass h 10)",
    ),
    (
        "(events e :when (vector h h) :below 0.1 :class knock)",
        "timbre::bad-events",
        "`:when` is 2 lanes wide",
        "(vector h h)",
    ),
    (
        "(events e :when h :below 0.1 :class knock :until 0)",
        "timbre::bad-events",
        "`events` would search from 0 s to 0 s",
        "0",
    ),
    (
        "(events :when h :below 0.1 :class knock)",
        "timbre::bad-events",
        "`events` needs a name",
        ":when",
    ),
];

#[test]
fn bad_events_forms_are_diagnosed_at_the_form() {
    for (form, code, message, underlined) in BAD {
        let text = format!(
            "(keyframes h :interp linear (0 1) (1 0))
             (define-sound knock () (sine (* t 700)))
             {form}"
        );
        let diag = error(&text);
        assert_eq!(diag.code, *code, "{form}: {diag:?}");
        assert!(
            diag.message.starts_with(message),
            "{form}: {}",
            diag.message
        );
        let span = diag.span().unwrap();
        assert_eq!(&text[span.start..span.end], *underlined, "{form}");
        assert!(diag.help.is_some(), "{form}: no help");
    }
}

#[test]
fn sync_takes_physical_or_picture() {
    let diag = error("(scene :sync film)");
    assert_eq!(diag.code, "timbre::bad-scene");
    assert!(
        diag.message.contains("physical or picture"),
        "{}",
        diag.message
    );
    compile("(scene :sync physical) (define-sound k () (sine t)) (instance a (k))");
}
