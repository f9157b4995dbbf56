//! Numbers in scene and space forms that cannot be heard as written: each is a
//! diagnostic with its code, message and the span of the number, before anything
//! is rendered.

mod common;

/// (source, code, message, the text the diagnostic underlines).
const CASES: &[(&str, &str, &str, &str)] = &[
    // A direction of no length.
    (
        "(define-sound a () (sine t)) (listener :facing (0 0 0)) (instance x (a) :at (0 1 0))",
        "timbre::bad-position",
        "the listener's facing direction is (0 0 0), which points nowhere",
        "(0 0 0)",
    ),
    (
        "(microphone :channel 0 :facing (keyframes :interp linear (0 (0 1 0)) (2 (0 0 0))))",
        "timbre::bad-position",
        "the microphone's direction is (0 0 0) at 2 s, which points nowhere",
        "(keyframes :interp linear (0 (0 1 0)) (2 (0 0 0)))",
    ),
    // Coordinates far beyond the precision of a metre.
    (
        "(listener :position (0 0 -2e6))",
        "timbre::bad-position",
        "the listener's position reaches 2e6 m from the origin, beyond 1e6 m",
        "(0 0 -2e6)",
    ),
    (
        "(source car :position (keyframes :interp linear (0 (0 0 0)) (5 (1e300 0 0))))",
        "timbre::bad-position",
        "the source's position reaches 1e300 m from the origin, beyond 1e6 m",
        "(keyframes :interp linear (0 (0 0 0)) (5 (1e300 0 0)))",
    ),
    (
        "(room :from (0 0 0) :to (1e7 5 3))",
        "timbre::bad-position",
        "a corner reaches 1e7 m from the origin, beyond 1e6 m",
        "(1e7 5 3)",
    ),
    (
        "(scene :channels 2) (listener :pair spaced :spacing 1e7)",
        "timbre::bad-setting",
        "the spacing 10000000 is larger than 1000000",
        "1e7",
    ),
    (
        "(scene :reference-distance 1e7)",
        "timbre::bad-scene",
        "distance 10000000 is not from 0 to 1000 km",
        "1e7",
    ),
    // Rooms that cannot hold the sound.
    (
        "(room :size (20000 10 3))",
        "timbre::bad-room",
        "a room of 20000 × 10 × 3 m is larger than 10000 m on a side",
        "(20000 10 3)",
    ),
    (
        "(scene :speed-of-sound 100) (define-sound a () (sine t)) \
         (room :size (10000 10000 10000) :order 6) (listener :position (1 1 1)) \
         (instance x (a) :at (2 2 1))",
        "timbre::too-far",
        "its reflections take up to",
        "(2 2 1)",
    ),
    // An instance's gain that is not a number.
    (
        "(define-sound a () (sine t)) (instance x (a) :gain (/ 0 0))",
        "timbre::bad-instance",
        "`:gain` is NaN, not a finite number",
        "(/ 0 0)",
    ),
    (
        "(define-sound a () (sine t)) (instance x (a) :gain (/ 1 0))",
        "timbre::bad-instance",
        "`:gain` is inf, not a finite number",
        "(/ 1 0)",
    ),
    // Refused before this file, kept here with the others.
    (
        "(define-sound a () (sine t)) (instance x (a) :start -1)",
        "timbre::bad-instance",
        "start time -1 is before the scene starts",
        "-1",
    ),
    (
        "(define-sound a () (sine t)) (instance x (a) :start (/ 1 0))",
        "timbre::not-constant",
        "the start time must be a constant number",
        "(/ 1 0)",
    ),
    (
        "(scene :sample-rate 0)",
        "timbre::bad-scene",
        "sample rate 0 is not a whole number of Hz from 1000 to 1536000",
        "0",
    ),
    (
        "(scene :channels 65)",
        "timbre::bad-scene",
        "65 is not a number of channels",
        "65",
    ),
    (
        "(room :size (0 5 3))",
        "timbre::bad-room",
        "the room is degenerate",
        "(0 5 3)",
    ),
    (
        "(room :size (5 5 3) :rt60 -1)",
        "timbre::bad-room",
        "RT60 -1 s is not from 0 to 60 s",
        "-1",
    ),
    (
        "(room :size (5 5 3) :absorption 1.5)",
        "timbre::bad-room",
        "absorption 1.5 is outside [0, 1]",
        "1.5",
    ),
];

#[test]
fn numbers_that_cannot_be_heard_as_written_are_refused_at_their_span() {
    let mut failures = vec![];
    for (source, code, message, underlined) in CASES {
        let diags = match common::compile_with(source, &[], 0) {
            Ok(_) => {
                failures.push(format!("{source:?}: compiled without error"));
                continue;
            }
            Err(d) => d,
        };
        let first = &diags.0[0];
        let Some(span) = first.span() else {
            failures.push(format!("{source:?}: {} points nowhere", first.code));
            continue;
        };
        let actual_underlined = &source[span.start..span.end];
        if first.code != *code
            || !first.message.starts_with(message)
            || actual_underlined != *underlined
        {
            failures.push(format!(
                "{source:?}: got {} / {:?} at {actual_underlined:?}, expected {code} / {message:?} at {underlined:?}",
                first.code, first.message
            ));
        }
        if first.help.is_none() {
            failures.push(format!("{source:?}: no help"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_largest_numbers_allowed_are_still_accepted() {
    for source in [
        "(define-sound a () (sine t)) (listener :position (0 0 1e6) :facing (0 0 -1)) \
         (instance x (a) :at (0 0 999990))",
        "(define-sound a () (sine t)) (room :size (10000 10 3)) (listener :position (1 1 1)) \
         (instance x (a) :at (2 2 1))",
        "(scene :reference-distance 1e6)",
        "(define-sound a () (sine t)) (instance x (a) :gain -2)",
    ] {
        if let Err(diags) = common::compile_with(source, &[], 0) {
            panic!("{source:?}: {:?}", diags.0[0]);
        }
    }
}
