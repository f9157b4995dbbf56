//! Every kind of malformed input yields a diagnostic with a stable code, a message and
//! the exact span it points at. The table lists the input, the code, the start of the
//! message, and the text the primary label underlines.

mod common;

/// (source, code, message prefix, underlined text)
const CASES: &[(&str, &str, &str, &str)] = &[
    (
        "(sine (* t 440)",
        "timbre::syntax::unclosed-list",
        "unclosed list",
        "(",
    ),
    (
        "(sine t))",
        "timbre::syntax::unexpected-close",
        "unexpected `)`",
        ")",
    ),
    (
        "(sine 1.2.3)",
        "timbre::syntax::bad-number",
        "malformed number `1.2.3`",
        "1.2.3",
    ),
    (
        "(sine 3abc)",
        "timbre::syntax::bad-number",
        "malformed number `3abc`",
        "3abc",
    ),
    (
        "\"abc",
        "timbre::syntax::unterminated-string",
        "unterminated string",
        "\"",
    ),
    (
        "(sample \"a\\qb.wav\")",
        "timbre::syntax::bad-escape",
        "unknown escape `\\q` in string",
        "\\q",
    ),
    (
        "(sine #t)",
        "timbre::syntax::unexpected-char",
        "unexpected character `#`",
        "#",
    ),
    (
        "(white :)",
        "timbre::syntax::empty-keyword",
        "missing keyword name after `:`",
        ":",
    ),
    (
        "(sinee (* t 440))",
        "timbre::unknown-function",
        "unknown function `sinee`",
        "sinee",
    ),
    (
        "(sine t t)",
        "timbre::arity",
        "`sine` takes 1 argument, got 2",
        "(sine t t)",
    ),
    (
        "(pow 2)",
        "timbre::arity",
        "`pow` takes 2 arguments, got 1",
        "(pow 2)",
    ),
    (
        "(phasor)",
        "timbre::arity",
        "`phasor` takes 1 to 2 arguments, got 0",
        "(phasor)",
    ),
    (
        "(sine (* t fre))",
        "timbre::unbound-parameter",
        "unbound parameter `fre`",
        "fre",
    ),
    (
        "(let ((a 1)) b)",
        "timbre::unbound-parameter",
        "unbound parameter `b`",
        "b",
    ),
    (
        "(+ (vector 1 2 3) (vector 1 2 3 4 5))",
        "timbre::width-mismatch",
        "`+` combines 3 lanes with 5 lanes",
        "(vector 1 2 3 4 5)",
    ),
    (
        "(index (rvector 3 1 2) (vector 1 2))",
        "timbre::width-mismatch",
        "the lane index must be one lane, not 2",
        "(vector 1 2)",
    ),
    (
        "(vector 1 2)",
        "timbre::wide-sound",
        "the sound is 2 lanes wide",
        "(vector 1 2)",
    ),
    (
        "(sample \"missing.wav\")",
        "timbre::sample-unreadable",
        "cannot read sound file `missing.wav`",
        "\"missing.wav\"",
    ),
    (
        "(include \"nope.tt\") (sine t)",
        "timbre::include-unreadable",
        "cannot read included file `nope.tt`",
        "\"nope.tt\"",
    ),
    (
        "(sine \"abc\")",
        "timbre::unexpected-string",
        "`sine` does not take a string",
        "\"abc\"",
    ),
    ("()", "timbre::empty-call", "empty list", "()"),
    (
        "(3 4)",
        "timbre::not-callable",
        "expected a node name, found a number",
        "3",
    ),
    (
        "(rvector 2.5 1 2)",
        "timbre::bad-count",
        "the number of lanes must be a whole number ≥ 1, not 2.5",
        "2.5",
    ),
    (
        "(rvector (sine t) 1 2)",
        "timbre::not-constant",
        "the number of lanes must be a constant number",
        "(sine t)",
    ),
    // A noise's `:lanes` is checked as `white`'s is.
    (
        "(combine (noise t :lanes 0))",
        "timbre::bad-count",
        "the number of lanes must be a whole number ≥ 1, not 0",
        "0",
    ),
    (
        "(combine (pink :lanes 2.5))",
        "timbre::bad-count",
        "the number of lanes must be a whole number ≥ 1, not 2.5",
        "2.5",
    ),
    (
        "(combine (markov 5 :lanes 1e9))",
        "timbre::too-wide",
        "1000000000 lanes is too many",
        "1e9",
    ),
    (
        "(combine (noise (vector 1 2) :lanes 3))",
        "timbre::width-mismatch",
        "`noise` of 3 lanes with an argument of 2 lanes",
        "(vector 1 2)",
    ),
    (
        "(lowpass (white) 1000 :qq 2)",
        "timbre::unknown-keyword",
        "`lowpass` has no argument `:qq`",
        ":qq",
    ),
    (
        "(white :seed)",
        "timbre::keyword-without-value",
        "keyword `:seed` has no value",
        ":seed",
    ),
    (
        "(let ((a)) a)",
        "timbre::bad-let",
        "a binding must be (name value)",
        "(a)",
    ),
    (
        "(define f (x) (* x x)) (f 1 2)",
        "timbre::arity",
        "`f` takes 1 argument, got 2",
        "(f 1 2)",
    ),
    (
        "(define f (x) (f x)) (f 1)",
        "timbre::recursive-define",
        "`f` uses itself",
        "(f x)",
    ),
    (
        "(define sine (x) x)",
        "timbre::redefine-builtin",
        "`sine` is a built-in name",
        "sine",
    ),
    (
        "(sine t) (sine t)",
        "timbre::several-sounds",
        "the file has 2 top-level sounds",
        "(sine t)",
    ),
    (
        "(delay (white) (sine t))",
        "timbre::delay-needs-max",
        "a varying delay time needs a maximum",
        "(sine t)",
    ),
    (
        "(scene :duration -1) (sine t)",
        "timbre::bad-scene",
        "duration -1 is not positive",
        "-1",
    ),
    (
        "(define x)",
        "timbre::bad-define",
        "definition of `x` has no body",
        "(define x)",
    ),
    (
        "(conv (white) (sine t) :length 0)",
        "timbre::bad-conv",
        "impulse length 0 s is out of range",
        "0",
    ),
    (
        "(+ t (define q 1))",
        "timbre::misplaced-form",
        "`define` is only allowed at the top level",
        "define",
    ),
    (
        "(define f (x) x) (f)",
        "timbre::arity",
        "`f` takes 1 argument, got 0",
        "(f)",
    ),
    (
        "(sine sine)",
        "timbre::node-as-value",
        "`sine` is a node and must be called",
        "sine",
    ),
    (
        "(+ t (damp 2 3) (sine))",
        "timbre::arity",
        "`damp` takes 1 argument, got 2",
        "(damp 2 3)",
    ),
    (
        "(sine 1e400)",
        "timbre::syntax::number-too-large",
        "number `1e400` is too large",
        "1e400",
    ),
    (
        "(f :amp 1)",
        "timbre::unknown-function",
        "unknown function `f`",
        "f",
    ),
    (
        "(define f (a b) (+ a b)) (f :a 1 :c 2)",
        "timbre::unknown-keyword",
        "`f` has no argument `:c`",
        ":c",
    ),
    (
        "(rvector 3 (vector 1 2) 5)",
        "timbre::width-mismatch",
        "`rvector` of 3 lanes with bounds of 2 lanes",
        "(vector 1 2)",
    ),
    (
        "(rvector 3 (* t (vector 1 2)) 5)",
        "timbre::width-mismatch",
        "`rvector` of 3 lanes with bounds of 2 lanes",
        "(* t (vector 1 2))",
    ),
    (
        "(sample \"x.wav\" :rate (vector 1 2))",
        "timbre::width-mismatch",
        "the playback rate must be one lane, not 2",
        "(vector 1 2)",
    ),
    (
        "(define f (t) t) (f 1)",
        "timbre::reserved-name",
        "`t` is reserved and cannot name a parameter",
        "t",
    ),
    (
        "(let ((pi 3)) pi)",
        "timbre::reserved-name",
        "`pi` is reserved and cannot be bound by `let`",
        "pi",
    ),
    // Scenes.
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (instance a (hiit :amp 1 :freq 2))", "timbre::unknown-class", "unknown sound class `hiit`", "hiit"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (instance a (hit :amp 1))", "timbre::arity", "`hit` takes 2 arguments, got 1", "(hit :amp 1)"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (instance a (hit :amp 1 :freq 2 :decay 3))", "timbre::unknown-keyword", "`hit` has no argument `:decay`", ":decay"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (keyframes k (0 1) (2 3) (1 4)) (instance a (hit :amp k :freq 2))", "timbre::bad-keyframes", "key 3 at 1 s is not after the key before it (2 s)", "(1 4)"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (instance a (hit :amp 1 :freq 2) :start 2 :stop 1)", "timbre::stop-before-start", "instance `a` stops at 1 s, before it starts at 2 s", "1"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (instance a (hit :amp 1 :freq 2) :start -1)", "timbre::bad-instance", "start time -1 is before the scene starts", "-1"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (instance a (hit :amp 1 :freq 2)) (instance a (hit :amp 1 :freq 3))", "timbre::duplicate-instance", "instance `a` is defined twice", "a"),
    ("(define hit (x) x) (instance a (hit 1))", "timbre::not-a-class", "`hit` is a tree, not a sound class", "(hit 1)"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (keyframes k :interp cubic (0 1))", "timbre::bad-keyframes", "unknown interpolation cubic", "cubic"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (keyframes k (0 1 2))", "timbre::bad-keyframes", "a key is (time value) or (time (x y z)), of numbers", "(0 1 2)"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (instance a (hit :amp 1 :freq 2) :speed 2)", "timbre::unknown-keyword", "`instance` has no option `:speed`", ":speed"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (sine t) (instance a (hit :amp 1 :freq 2))", "timbre::sound-and-instances", "the file has both a top-level sound and instances", "(sine t)"),
    ("(define-sound hit (amp freq) (* amp (sine (* t freq)))) (keyframes k :csv \"m.csv\" :frame-rate 24)", "timbre::bad-keyframes", "a CSV track needs a `:column`", "(keyframes k :csv \"m.csv\" :frame-rate 24)"),
    ("(define-sound a (f) (sine (* t f))) (instance x (a :f 1) :pan 0.5)", "timbre::bad-instance", "`:pan` needs a stereo scene", "0.5"),
    ("(define-sound a (f) (sine (* t f))) (instance x (a :f 1) :declick -0.01)", "timbre::bad-instance", "`:declick` is -0.01 s, not a length of time", "-0.01"),
    ("(define-sound a (f) (sine (* t f))) (keyframes k (0 1)) (instance x (a :f 1) :declick k)", "timbre::not-constant", "the declick ramp must be a constant number", "k"),
    ("(keyframes h (0 0) (2 2)) (define-sound pluck (freq amp gate) (* amp gate (sine (* t freq)))) (score tune :beat 0.5 (part lead pluck h :declick -1))", "timbre::bad-instance", "`:declick` is -1 s, not a length of time", "-1"),
    ("(scene :channels 2) (define-sound a (f) (sine (* t f))) (instance x (a :f 1) :pan 2)", "timbre::bad-instance", "`:pan 2` is not a position from -1 to 1", "2"),
    // Space.
    ("(keyframes p (0 (1 2 3)) (1 (4 5)))", "timbre::bad-keyframes", "this key has 2 values, the first has 3", "(1 (4 5))"),
    ("(source car :position (keyframes (0 (1 2)) (1 (3 4))))", "timbre::bad-position", "the source's position has 2 coordinates, not 3", "(keyframes (0 (1 2)) (1 (3 4)))"),
    ("(source car :position (1 2))", "timbre::bad-position", "the source's position has 2 coordinates, not 3", "(1 2)"),
    ("(scene :speed-of-sound 0)", "timbre::bad-scene", "speed of sound 0 is not positive", "0"),
    ("(scene :distance-law cubic)", "timbre::bad-scene", "unknown distance law cubic", "cubic"),
    ("(scene :air-absorption yes)", "timbre::bad-scene", "`:air-absorption` is on or off, not yes", "yes"),
    ("(scene :humidity 120)", "timbre::bad-scene", "humidity 120 is out of range", "120"),
    ("(scene :distance-law linear :max-distance 0.5)", "timbre::bad-scene", "the linear law falls to silence at 0.5 m, not beyond its reference distance 1 m", "(scene :distance-law linear :max-distance 0.5)"),
    ("(define-sound a (f) (sine (* t f))) (listener) (source car :position (0 1 0)) (instance x (a :f 1) :source cat)", "timbre::unknown-source", "unknown source cat", "cat"),
    ("(define-sound a (f) (sine (* t f))) (source car :position (0 1 0)) (instance x (a :f 1) :source car)", "timbre::no-listener", "an instance is placed in space, but the scene has no listener", "car"),
    ("(define-sound a (f) (sine (* t f))) (listener :pair spaced)", "timbre::bad-listener", "a microphone pair needs a stereo scene", "spaced"),
    ("(scene :channels 4) (listener :ambisonics 4)", "timbre::bad-listener", "Ambisonic order 4 is not 1, 2 or 3", "4"),
    ("(listener :ambisonics 1)", "timbre::bad-listener", "an order-1 Ambisonic listener writes 4 channels", "1"),
    ("(scene :channels 4) (listener :ambisonics 1 :pair xy)", "timbre::bad-listener", "an Ambisonic listener has no `:pair`", "xy"),
    ("(scene :channels 6) (listener :speakers \"9.1\")", "timbre::bad-listener", "unknown loudspeaker layout", "\"9.1\""),
    ("(scene :channels 2) (listener :speakers \"5.1\")", "timbre::bad-listener", "the 5.1 layout has 6 channels", "\"5.1\""),
    ("(listener :binaural default)", "timbre::bad-listener", "a binaural listener needs a stereo scene", "default"),
    ("(scene :channels 2) (listener :binaural \"missing.sofa\")", "timbre::bad-hrtf", "cannot read the HRTF set `missing.sofa`", "\"missing.sofa\""),
    ("(scene :channels 2) (listener :binaural 3)", "timbre::bad-listener", "unknown HRTF set 3", "3"),
    ("(keyframes k (0 1)) (listener :position k)", "timbre::bad-position", "the listener's position has 1 coordinate, not 3", "k"),
    ("(listener :position carr) (keyframes car (0 (0 0 0)))", "timbre::unknown-position", "no keyframed position `carr`", "carr"),
    ("(listener :position car) (listener)", "timbre::unknown-position", "no keyframed position `car`", "car"),
    ("(room :size (10 0 3))", "timbre::bad-room", "the room is degenerate: ", "(10 0 3)"),
    ("(room :size (10 8 3) :absorption 1.5)", "timbre::bad-room", "absorption 1.5 is outside [0, 1]", "1.5"),
    ("(room :size (10 8 3) :walls (0.1 0.2 0.3))", "timbre::bad-room", "an absorption coefficient per band needs six numbers", "(0.1 0.2 0.3)"),
    ("(define-sound a () (sine t)) (room :size (10 8 3)) (listener :position (12 1 1)) (source s :position (1 1 1)) (instance x (a) :source s)", "timbre::outside-room", "the listener is outside the room at 0 s, at (12 1 1)", "(listener :position (12 1 1))"),
    ("(define-sound a () (sine t)) (box cab :size (2 2 2) :position (0 5 0)) (listener) (source s :position (0.5 5 0)) (instance x (a) :source s)", "timbre::source-in-obstacle", "the source is inside `cab` at 0 s", "s"),
    ("(box :size (1 0 1))", "timbre::bad-obstacle", "a box has a positive size in every direction", "(1 0 1)"),
    ("(wall :from (0 0 0) :to (0 5 0) :height 3 :material steel)", "timbre::bad-material", "unknown material steel", "steel"),
    ("(wall :from (0 0 0) :to (0 5 0))", "timbre::bad-obstacle", "a wall needs `:from`, `:to` and `:height`", "(wall :from (0 0 0) :to (0 5 0))"),
    ("(scene :channels 2) (define-sound a (f) (sine (* t f))) (listener) (instance x (a :f 1) :at (0 1 0) :pan 0)", "timbre::bad-instance", "an instance placed in space is panned by its place", "0"),
    ("(scene :channels 2) (define-sound a (f) (sine (* t f))) (instance x (a :f 1) :channel 2)", "timbre::bad-instance", "channel 2 is not one of the scene's 2", "2"),
    ("(scene :channels 0)", "timbre::bad-scene", "0 is not a number of channels", "0"),
    // A scene's settings are read in order, each checked before the next is looked at.
    ("(scene 48000)", "timbre::bad-scene", "expected a setting keyword, found", "48000"),
    ("(scene :duration)", "timbre::bad-scene", "setting `:duration` has no value", ":duration"),
    ("(scene :samplerate 44100)", "timbre::bad-scene", "unknown scene setting `:samplerate`", ":samplerate"),
    ("(scene :bogus \"x\")", "timbre::bad-scene", "setting `:bogus` must be a number", "\"x\""),
    ("(scene :duration -1 :bogus 2)", "timbre::bad-scene", "duration -1 is not positive", "-1"),
    // The other forms' options: an unknown option before a missing value.
    ("(listener 3)", "timbre::bad-scene-form", "unexpected", "3"),
    ("(listener :bogus)", "timbre::unknown-keyword", "`listener` has no option `:bogus`", ":bogus"),
    ("(listener :position)", "timbre::keyword-without-value", "option `:position` has no value", ":position"),
    // Habits from other languages.
    ("(sine (* t 440))\n  # it's \"loud\"", "timbre::syntax::wrong-comment", "comments start with `;`", "#"),
    ("(define f (x)\n  (* x 2)\n(f 1)", "timbre::syntax::unclosed-list", "unclosed list", "("),
    ("(define (f) (sine t)) (f)", "timbre::bad-define", "timbre writes a definition as `(define name (param …) body)`", "(f)"),
];

#[test]
fn malformed_inputs_give_exact_diagnostics() {
    assert!(CASES.len() >= 25);
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
        let span = first.span().expect("every diagnostic points somewhere");
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
        assert!(first.help.is_some(), "{source:?} has no help");
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn suggestions_name_the_closest_node_or_parameter() {
    let help = |src: &str| {
        common::compile_with(src, &[], 0).unwrap_err().0[0]
            .help
            .clone()
            .unwrap()
    };
    assert_eq!(help("(sinee t)"), "did you mean `sine`?");
    assert_eq!(help("(sawtoth t)"), "did you mean `sawtooth`?");
    assert_eq!(
        help("(define bell (f) (sine (* t f))) (bel 440)"),
        "did you mean `bell`?"
    );
    assert!(help("(let ((freq 1)) (sine (* t frq)))").starts_with("did you mean `freq`?"));
    assert!(help("(lowpass (white) 1000 :qq 2)").contains(":x :freq :q"));
    assert_eq!(
        help("(define-sound a () (sine t)) (listener) (source car :position (0 1 0)) (instance x (a) :source cat)"),
        "did you mean `car`?"
    );
    assert_eq!(
        help("(listener :position carr) (keyframes car (0 (0 0 0)))"),
        "did you mean `car`?"
    );
    assert!(help("(scene :samplerate 44100)").starts_with("did you mean `:sample-rate`?"));
    assert!(
        help("(define-sound a () (sine t)) (instance x (a) :strat 1)")
            .starts_with("did you mean `:start`?")
    );
}

#[test]
fn one_bad_form_does_not_hide_the_next() {
    let diags =
        common::compile_with("(sine t))\n(define f (x) (sinn x))\n(f 1)", &[], 0).unwrap_err();
    let codes: Vec<&str> = diags.0.iter().map(|d| d.code.as_ref()).collect();
    assert_eq!(
        codes,
        [
            "timbre::syntax::unexpected-close",
            "timbre::unknown-function"
        ]
    );
}

#[test]
fn nesting_too_deep_is_an_error_not_a_crash() {
    for depth in [300, 100_000] {
        let source = format!("{}t{}", "(sine ".repeat(depth), ")".repeat(depth));
        let diags = common::compile_with(&source, &[], 0).unwrap_err();
        assert!(
            diags.0.iter().any(|d| d.code == "timbre::syntax::too-deep"),
            "{:?}",
            diags.0[0]
        );
    }
}

/// Diagnostics whose help says how to fix them: (source, code, message prefix,
/// underlined text, text the help contains).
const HELPED: &[(&str, &str, &str, &str, &str)] = &[
    (
        "(scene :duration 1)\n// a comment the C way\n(sine (* t 440))",
        "timbre::syntax::wrong-comment",
        "comments start with `;`",
        "//",
        "write `; …`",
    ),
    (
        "  # a shell comment\n(sine (* t 440))",
        "timbre::syntax::wrong-comment",
        "comments start with `;`",
        "#",
        "a comment runs from `;`",
    ),
    (
        "(define f (x)\n  (* x 2)\n\n(sine (* t (f 220)))",
        "timbre::syntax::unclosed-list",
        "unclosed list",
        "(",
        "add `)` at the end of line 2",
    ),
    (
        "(define (f x) (* x 2))",
        "timbre::bad-define",
        "timbre writes a definition as `(define name (param …) body)`",
        "(f x)",
        "write `(define f (x) …)`",
    ),
    (
        "(define-sound (hit amp f) (* amp (sine (* t f))))",
        "timbre::bad-define",
        "timbre writes a definition as `(define-sound name (param …) body)`",
        "(hit amp f)",
        "write `(define-sound hit (amp f) …)`",
    ),
    (
        "(define-sound unused (f) (sinee (* t f)))\n(sine (* t 440))",
        "timbre::unknown-function",
        "unknown function `sinee`",
        "sinee",
        "did you mean `sine`?",
    ),
    (
        "(SinOsc 440)",
        "timbre::unknown-function",
        "unknown function `SinOsc`",
        "SinOsc",
        "did you mean `sine`? write `(sine (phasor f))`",
    ),
    (
        "(SinOsc.ar 440)",
        "timbre::unknown-function",
        "unknown function `SinOsc.ar`",
        "SinOsc.ar",
        "did you mean `sine`?",
    ),
    (
        "(sinwave (* t 440))",
        "timbre::unknown-function",
        "unknown function `sinwave`",
        "sinwave",
        "did you mean `sine`?",
    ),
    (
        "(osc 440)",
        "timbre::unknown-function",
        "unknown function `osc`",
        "osc",
        "did you mean `sine`?",
    ),
    (
        "(Pan2 (white) 0)",
        "timbre::unknown-function",
        "unknown function `Pan2`",
        "Pan2",
        "did you mean `pan`?",
    ),
    (
        "(LFNoise2 4)",
        "timbre::unknown-function",
        "unknown function `LFNoise2`",
        "LFNoise2",
        "did you mean `noise`?",
    ),
    (
        "(Klank 1)",
        "timbre::unknown-function",
        "unknown function `Klank`",
        "Klank",
        "did you mean `combine`?",
    ),
    (
        "(lowpass (white) :freqq 1000)",
        "timbre::unknown-keyword",
        "`lowpass` has no argument `:freqq`",
        ":freqq",
        "did you mean `:freq`? its arguments are :x :freq :q",
    ),
    (
        "(white :sed 2)",
        "timbre::unknown-keyword",
        "`white` has no argument `:sed`",
        ":sed",
        "did you mean `:seed`?",
    ),
    (
        "(frobnicate 1)",
        "timbre::unknown-function",
        "unknown function `frobnicate`",
        "frobnicate",
        "define it with (define …)",
    ),
    (
        "(define-sound a (f) (sine (* t f)))\n(instance x (a :f 1) :pan 0)",
        "timbre::bad-instance",
        "`:pan` needs a stereo scene",
        "0",
        ":channels 2",
    ),
    (
        "(define-sound a (f) (sine (* t f)))\n(instance x (a :f 1) :declick -1)",
        "timbre::bad-instance",
        "`:declick` is -1 s, not a length of time",
        "-1",
        "write :declick 0.01 for a 10 ms fade-in, or :declick off (or 0) for none",
    ),
    (
        "(scene :channels 2)\n(define-sound a (f) (pan 0 (sine (* t f))))\n(instance x (a :f 1) :pan 0)",
        "timbre::bad-instance",
        "`:pan` places a one-lane sound, and `x` has a lane per channel",
        "0",
        "leave the option out",
    ),
    (
        "(define-sound a (f) (pan 0 (sine (* t f))))\n(instance x (a :f 1))",
        "timbre::wide-sound",
        "instance `x` is 2 lanes wide",
        "(a :f 1)",
        "(scene :channels N)",
    ),
];

#[test]
fn diagnostics_say_how_to_fix_them() {
    let mut failures = vec![];
    for (source, code, message, underlined, help) in HELPED {
        let diags = match common::compile_with(source, &[], 0) {
            Ok(_) => {
                failures.push(format!("{source:?}: compiled without error"));
                continue;
            }
            Err(d) => d,
        };
        let first = &diags.0[0];
        let span = first.span().expect("every diagnostic points somewhere");
        let actual = &source[span.start..span.end];
        let actual_help = first.help.clone().unwrap_or_default();
        if first.code != *code
            || !first.message.starts_with(message)
            || actual != *underlined
            || !actual_help.contains(help)
            || actual_help.contains("lang-spec/")
        {
            failures.push(format!(
                "{source:?}: got {} / {:?} at {actual:?} / help {actual_help:?}, expected {code} / {message:?} at {underlined:?} / help with {help:?}",
                first.code, first.message
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The codes of all diagnostics of `source`.
fn codes(source: &str, bindings: &[(&str, f64)]) -> Vec<String> {
    match common::compile_with(source, bindings, 0) {
        Ok(_) => vec![],
        Err(d) => d.0.iter().map(|d| d.code.to_string()).collect(),
    }
}

#[test]
fn one_cause_gives_one_diagnostic() {
    // A comment the C way among several forms: one error, the forms still read.
    assert_eq!(
        codes(
            "(define f (x) (* x 2))\n// twice the frequency\n(sine (* t (f 220)))",
            &[]
        ),
        ["timbre::syntax::wrong-comment"]
    );
    // A missing include: nothing about the names it would have defined.
    assert_eq!(
        codes(
            "(include \"no-such-file.tt\")\n(sine (* t (helper 3)))",
            &[]
        ),
        ["timbre::include-unreadable"]
    );
    // A malformed keyframes form: no "unbound parameter … --set force=VALUE".
    assert_eq!(
        codes(
            "(keyframes force :interp cubic (0 1) (1 2))\n(* force (sine (* t 440)))",
            &[]
        ),
        ["timbre::bad-keyframes"]
    );
    // A definition written Scheme's way: no "unknown function `f`" after it.
    assert_eq!(
        codes("(define (f x) (* x 2))\n(sine (* t (f 220)))", &[]),
        ["timbre::bad-define"]
    );
    // An unclosed list followed by a form at the margin: that form reads normally.
    let source = "(define f (x)\n  (* x 2)\n(sine (* t (f 220)))";
    let diags = common::compile_with(source, &[], 0).unwrap_err();
    assert_eq!(diags.0.len(), 1, "{:?}", diags.0);
    let labels = &diags.0[0].labels;
    assert_eq!(labels.len(), 2);
    let line_of = |at: usize| source[..at].matches('\n').count() + 1;
    assert_eq!(line_of(labels[0].0.start), 1);
    assert_eq!(&source[labels[1].0.start..labels[1].0.end], ")");
    assert_eq!(line_of(labels[1].0.start), 2);
}

#[test]
fn a_misspelt_set_name_is_named_in_the_help() {
    let diags = common::compile_with("(sine (* t freq))", &[("frq", 3.0)], 0).unwrap_err();
    assert_eq!(
        diags.0[0].help.as_deref(),
        Some("a value was given as `--set frq=…`: did you mean `--set freq=…`?")
    );
}

/// Lints: (source, code, message prefix, underlined text, text the help contains).
const WARNINGS: &[(&str, &str, &str, &str, &str)] = &[
    (
        "(* 0.5 (sine 440))",
        "timbre::lint::constant-phase",
        "`(sine 440)` has a constant phase, so it is a constant, not a tone",
        "440",
        "did you mean `(sine (* t 440))`?",
    ),
    (
        "(saw-bl 0.25)",
        "timbre::lint::constant-phase",
        "`(saw-bl 0.25)` has a constant phase",
        "0.25",
        "(saw-bl (* t 0.25))",
    ),
    (
        "(* 0.5 0.25)",
        "timbre::lint::constant-sound",
        "this sound is the constant 0.125",
        "(* 0.5 0.25)",
        "a sound changes with time",
    ),
    (
        "(- 1 1)",
        "timbre::lint::silent-sound",
        "this sound is silent",
        "(- 1 1)",
        "a sound changes with time",
    ),
    (
        "(define-sound a (level) level)\n(instance x (a :level 0) :start 0)",
        "timbre::lint::silent-sound",
        "this sound is silent",
        "(a :level 0)",
        "use `t`",
    ),
];

#[test]
fn lints_warn_with_the_fix() {
    let mut failures = vec![];
    for (source, code, message, underlined, help) in WARNINGS {
        let program = common::compile_with(source, &[], 0).unwrap();
        let Some(first) = program.warnings.first() else {
            failures.push(format!("{source:?}: no warning"));
            continue;
        };
        let span = first.span().unwrap();
        let actual = &source[span.start..span.end];
        if !first.warning
            || first.code != *code
            || !first.message.starts_with(message)
            || actual != *underlined
            || !first.help.as_deref().unwrap_or_default().contains(help)
        {
            failures.push(format!("{source:?}: got {first:?} at {actual:?}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // A tone warns about nothing; an unused tree is checked, but never linted.
    for quiet in [
        "(sine (* t 440))",
        "(define-sound a (f) (sine f))\n(define-sound b (f) (sine (* t f)))\n(instance x (b :f 1) :start 0)",
    ] {
        let program = common::compile_with(quiet, &[], 0).unwrap();
        assert!(program.warnings.is_empty(), "{quiet:?}: {:?}", program.warnings);
    }
}
