//! Arguments that make no sense: each refused by the call that would use it, with its
//! own diagnostic, never a panic, a silent clamp or a render of garbage.

use timbre::{Diagnostics, Engine, Error, Limits, Mix, ParamValue, Placement, Play, Variable};

const SR: f64 = 8_000.0;
const LIBRARY: &str = "(define-sound tone (f) (* 0.5 (sine (* t f))))";

/// The one diagnostic of a refusal: its code and message.
fn refusal(error: Error) -> (String, String) {
    match error {
        Error::Script(d) => only(d),
        other => panic!("not a diagnostic: {other}"),
    }
}

fn only(diagnostics: Diagnostics) -> (String, String) {
    assert_eq!(diagnostics.0.len(), 1, "{diagnostics:?}");
    let diag = &diagnostics.0[0];
    assert!(
        diag.help.is_some(),
        "every refusal says what to do: {diag:?}"
    );
    (diag.code.to_string(), diag.message.clone())
}

fn expect(error: Error, code: &str, message: &str) {
    assert_eq!(refusal(error), (code.to_owned(), message.to_owned()));
}

fn scene(engine: &Engine) -> timbre::Scene {
    let library = engine.load_library(LIBRARY).unwrap();
    engine.scene(&library).unwrap()
}

fn tone() -> [(&'static str, ParamValue); 1] {
    [("f", 440.0.into())]
}

#[test]
fn a_sample_rate_that_is_not_a_rate_is_refused_before_anything_renders() {
    let message = |rate: &str| {
        format!("a sample rate of {rate} Hz: a rate is a finite number of Hz from 1000 to 1536000")
    };
    for (rate, text) in [
        (0.0, "0"),
        (-48_000.0, "-48000"),
        (f64::NAN, "NaN"),
        (f64::INFINITY, "inf"),
        (10.0, "10"),
    ] {
        let engine = Engine::new(rate);
        let scene = engine.load_scene("(sine (* t 440))").unwrap_err();
        expect(scene, "timbre::bad-sample-rate", &message(text));
        // A library does not depend on the rate: the scene made of it refuses it.
        let library = engine.load_library(LIBRARY).unwrap();
        expect(
            engine.scene(&library).unwrap_err(),
            "timbre::bad-sample-rate",
            &message(text),
        );
        let moved = Engine::new(SR).with_sample_rate(rate);
        assert!(moved.load_scene("(sine (* t 440))").is_err(), "{rate}");
    }
    // Above the limit, the limit says so; without limits, the rate still has a ceiling.
    let fast = Engine::new(2e6).load_scene("(sine (* t 440))").unwrap_err();
    assert_eq!(refusal(fast).0, "timbre::rate-too-high");
    let unlimited = Engine::new(2e6).with_limits(Limits::none());
    expect(
        unlimited.load_scene("(sine (* t 440))").unwrap_err(),
        "timbre::bad-sample-rate",
        &message("2000000"),
    );
}

#[test]
fn a_block_size_of_zero_or_beyond_the_largest_is_refused() {
    for (samples, text) in [
        (0, "0"),
        (65_537, "65537"),
        (usize::MAX, &*usize::MAX.to_string()),
    ] {
        let engine = Engine::new(SR).with_block_size(samples);
        expect(
            engine.load_scene("(sine (* t 440))").unwrap_err(),
            "timbre::bad-block-size",
            &format!("a block of {text} samples: a block is 1 to 65536 samples"),
        );
    }
    let largest = Engine::new(SR).with_block_size(65_536);
    assert_eq!(scene(&largest).render_offline(0.1).unwrap().len(), 800);
}

#[test]
fn channels_of_zero_or_beyond_the_most_are_refused() {
    for channels in [0, 65, 1 << 40] {
        let engine = Engine::new(SR).with_channels(channels);
        let library = engine.load_library(LIBRARY).unwrap();
        expect(
            engine.scene(&library).unwrap_err(),
            "timbre::bad-channels",
            &format!("{channels} output channels: a scene has 1 to 64"),
        );
    }
    assert_eq!(scene(&Engine::new(SR).with_channels(64)).channels(), 64);
}

#[test]
fn a_binding_that_is_not_finite_is_refused() {
    let engine = Engine::new(SR).with_binding("pitch", f64::NAN);
    expect(
        engine.load_scene("(sine (* t pitch))").unwrap_err(),
        "timbre::bad-binding",
        "`pitch` is bound to NaN: a binding is a finite number",
    );
    let library = engine.load_library("(define-sound s () (sine (* t pitch)))");
    assert_eq!(
        only(library.unwrap_err()),
        (
            "timbre::bad-binding".to_owned(),
            "`pitch` is bound to NaN: a binding is a finite number".to_owned()
        )
    );
}

#[test]
fn a_gain_that_is_not_finite_is_refused() {
    let engine = Engine::new(SR);
    let mut scene = scene(&engine);
    for (gain, text) in [
        (f64::NAN, "NaN"),
        (f64::INFINITY, "inf"),
        (f64::NEG_INFINITY, "-inf"),
    ] {
        let error = scene.play("tone", &tone(), Play::at(0.0).gain(gain));
        expect(
            error.unwrap_err(),
            "timbre::bad-gain",
            &format!("a gain of {text}: a gain is a finite number"),
        );
    }
    assert!(
        scene.render_offline(0.2).unwrap().iter().all(|x| *x == 0.0),
        "nothing started"
    );
    // Changed later, on the scene or on the control side.
    let id = scene.start("tone", &tone(), 0.0).unwrap();
    let nan = Mix {
        gain: f64::NAN,
        placement: Placement::Everywhere,
    };
    expect(
        scene.set_mix(id, nan).unwrap_err(),
        "timbre::bad-gain",
        "a gain of NaN: a gain is a finite number",
    );
    let (control, _renderer) = self::scene(&engine).split(4).unwrap();
    let id = control.start("tone", &tone(), 0.0).unwrap();
    expect(
        control.set_mix(id, nan).unwrap_err(),
        "timbre::bad-gain",
        "a gain of NaN: a gain is a finite number",
    );
}

#[test]
fn a_declick_that_is_negative_or_not_finite_is_refused() {
    let engine = Engine::new(SR);
    let mut scene = scene(&engine);
    for (seconds, text) in [
        (-0.001, "-0.001"),
        (f64::NAN, "NaN"),
        (f64::INFINITY, "inf"),
    ] {
        let error = scene.play("tone", &tone(), Play::at(0.0).declick(seconds));
        expect(
            error.unwrap_err(),
            "timbre::bad-declick",
            &format!("a declick of {text} s: a fade-in is finite seconds, ≥ 0"),
        );
    }
    assert!(
        scene.render_offline(0.2).unwrap().iter().all(|x| *x == 0.0),
        "nothing started"
    );
}

#[test]
fn a_pan_outside_minus_one_to_one_is_refused() {
    let engine = Engine::new(SR).with_channels(2);
    let mut scene = scene(&engine);
    for (position, text) in [(1.5, "1.5"), (-1.01, "-1.01"), (f64::NAN, "NaN")] {
        expect(
            scene
                .play("tone", &tone(), Play::at(0.0).pan(position))
                .unwrap_err(),
            "timbre::bad-pan",
            &format!("a pan position of {text}: a position is from -1 to 1"),
        );
    }
    let (control, _renderer) = self::scene(&engine).split(4).unwrap();
    expect(
        control
            .play("tone", &tone(), Play::at(0.0).pan(2.0))
            .unwrap_err(),
        "timbre::bad-pan",
        "a pan position of 2: a position is from -1 to 1",
    );
    assert!(scene.play("tone", &tone(), Play::at(0.0).pan(-1.0)).is_ok());
}

#[test]
fn a_channel_the_scene_does_not_have_is_refused() {
    let engine = Engine::new(SR).with_channels(2);
    let mut scene = scene(&engine);
    let no_channel = "channel 2, but the scene has 2 (numbered 0 to 1)";
    expect(
        scene
            .play("tone", &tone(), Play::at(0.0).channel(2))
            .unwrap_err(),
        "timbre::bad-channel",
        no_channel,
    );
    let rear = Placement::Pan {
        left: 0,
        right: 2,
        position: 0.0,
    };
    expect(
        scene
            .play("tone", &tone(), Play::at(0.0).placement(rear))
            .unwrap_err(),
        "timbre::bad-channel",
        no_channel,
    );
    let itself = Placement::Pan {
        left: 1,
        right: 1,
        position: 0.0,
    };
    expect(
        scene
            .play("tone", &tone(), Play::at(0.0).placement(itself))
            .unwrap_err(),
        "timbre::bad-channel",
        "a pan between channel 1 and itself",
    );
    // A stereo pan in a mono scene has no right channel.
    let mut mono = self::scene(&Engine::new(SR));
    expect(
        mono.play("tone", &tone(), Play::at(0.0).pan(0.0))
            .unwrap_err(),
        "timbre::bad-channel",
        "channel 1, but the scene has 1 (numbered 0 to 0)",
    );
    let id = scene.start("tone", &tone(), 0.0).unwrap();
    let far = Mix {
        gain: 1.0,
        placement: Placement::Channel(7),
    };
    expect(
        scene.set_mix(id, far).unwrap_err(),
        "timbre::bad-channel",
        "channel 7, but the scene has 2 (numbered 0 to 1)",
    );
    // On the control side, against the scene's channels.
    let (control, _renderer) = self::scene(&engine).split(4).unwrap();
    let id = control.start("tone", &tone(), 0.0).unwrap();
    expect(
        control.set_mix(id, far).unwrap_err(),
        "timbre::bad-channel",
        "channel 7, but the scene has 2 (numbered 0 to 1)",
    );
}

#[test]
fn times_that_are_not_on_the_timeline_are_refused() {
    let engine = Engine::new(SR);
    let mut scene = scene(&engine);
    let message = |what: &str, time: &str| {
        format!("{what} of {time} s: a time is finite seconds from the start of the scene, ≥ 0")
    };
    for (time, text) in [(f64::NAN, "NaN"), (f64::INFINITY, "inf"), (-0.5, "-0.5")] {
        expect(
            scene.start("tone", &tone(), time).unwrap_err(),
            "timbre::bad-time",
            &message("a start time", text),
        );
        expect(
            scene.start_until("tone", &tone(), 0.0, time).unwrap_err(),
            "timbre::bad-time",
            &message("a stop time", text),
        );
        let id = scene.start("tone", &tone(), 0.0).unwrap();
        expect(
            scene.stop(id, time).unwrap_err(),
            "timbre::bad-time",
            &message("a stop time", text),
        );
        expect(
            scene.render_offline(time).unwrap_err(),
            "timbre::bad-time",
            &message("a time to render until", text),
        );
    }
    let (control, _renderer) = self::scene(&engine).split(4).unwrap();
    expect(
        control.start("tone", &tone(), f64::NAN).unwrap_err(),
        "timbre::bad-time",
        &message("a start time", "NaN"),
    );
    let id = control.start("tone", &tone(), 0.0).unwrap();
    expect(
        control.stop(id, f64::NAN).unwrap_err(),
        "timbre::bad-time",
        &message("a stop time", "NaN"),
    );
    let file = engine.read_scene("(sine (* t 440))").unwrap();
    expect(
        engine.scene_from(&file, f64::NAN).unwrap_err(),
        "timbre::bad-time",
        &message("a length", "NaN"),
    );
}

#[test]
fn a_stop_before_the_start_is_refused() {
    let engine = Engine::new(SR);
    let mut scene = scene(&engine);
    for stop in [0.5, 0.25] {
        expect(
            scene.start_until("tone", &tone(), 0.5, stop).unwrap_err(),
            "timbre::stop-before-start",
            &format!("the instance stops at {stop} s, not after it starts at 0.5 s"),
        );
    }
    let (control, _renderer) = self::scene(&engine).split(4).unwrap();
    let backwards = Play::at(1.0).until(0.5);
    expect(
        control.play("tone", &tone(), backwards).unwrap_err(),
        "timbre::stop-before-start",
        "the instance stops at 0.5 s, not after it starts at 1 s",
    );
}

#[test]
fn a_parameter_value_that_is_not_finite_is_refused() {
    let engine = Engine::new(SR);
    let mut scene = scene(&engine);
    expect(
        scene
            .start("tone", &[("f", f64::NAN.into())], 0.0)
            .unwrap_err(),
        "timbre::bad-parameter",
        "parameter `f` is a constant NaN: a value is a finite number",
    );
    let pitch = Variable::new(f64::INFINITY);
    let bound = [("f", ParamValue::Variable(pitch.clone()))];
    expect(
        scene.start("tone", &bound, 0.0).unwrap_err(),
        "timbre::bad-parameter",
        "parameter `f` is a variable holding inf: a value is a finite number",
    );
    pitch.set(440.0);
    assert!(scene.start("tone", &bound, 0.0).is_ok());
    let (control, _renderer) = self::scene(&engine).split(4).unwrap();
    expect(
        control
            .start("tone", &[("f", f64::NAN.into())], 0.0)
            .unwrap_err(),
        "timbre::bad-parameter",
        "parameter `f` is a constant NaN: a value is a finite number",
    );
}

#[test]
fn threads_of_zero_or_beyond_the_most_are_refused() {
    let mut scene = scene(&Engine::new(SR));
    for threads in [0, 1_025] {
        expect(
            scene.set_threads(threads).unwrap_err(),
            "timbre::bad-threads",
            &format!("{threads} threads: a scene renders on 1 to 1024"),
        );
    }
    scene.set_threads(1).unwrap();
}

#[test]
fn a_split_with_room_for_no_instance_is_refused() {
    let error = scene(&Engine::new(SR)).split(0).err().unwrap();
    expect(
        error,
        "timbre::bad-capacity",
        "a split scene with room for 0 instances: the control side could start none",
    );
}

#[test]
fn buffers_that_are_not_whole_frames_are_refused() {
    let engine = Engine::new(SR).with_channels(2);
    let mut scene = scene(&engine);
    expect(
        scene.render(&mut [0.0; 5]).unwrap_err(),
        "timbre::bad-buffer",
        "a buffer of 5 samples is not whole frames of 2 channels",
    );
    expect(
        scene.render_f32(&mut [0.0; 3]).unwrap_err(),
        "timbre::bad-buffer",
        "a buffer of 3 samples is not whole frames of 2 channels",
    );
    assert_eq!(scene.frame(), 0, "nothing rendered");
    let (mut a, mut b, mut c) = (vec![0.0; 64], vec![0.0; 64], vec![0.0; 64]);
    expect(
        scene.render_planar(&mut [&mut a]).unwrap_err(),
        "timbre::bad-buffer",
        "1 slices for a scene of 2 channels",
    );
    expect(
        scene
            .render_planar(&mut [&mut a, &mut b, &mut c])
            .unwrap_err(),
        "timbre::bad-buffer",
        "3 slices for a scene of 2 channels",
    );
    let mut short = vec![0.0; 10];
    expect(
        scene.render_planar(&mut [&mut a, &mut short]).unwrap_err(),
        "timbre::bad-buffer",
        "slices of unequal lengths, 64 and 10 samples",
    );
    let (_control, mut renderer) = self::scene(&engine).split(4).unwrap();
    expect(
        renderer.render(&mut [0.0; 7]).unwrap_err(),
        "timbre::bad-buffer",
        "a buffer of 7 samples is not whole frames of 2 channels",
    );
    expect(
        renderer.render_f32(&mut [0.0; 7]).unwrap_err(),
        "timbre::bad-buffer",
        "a buffer of 7 samples is not whole frames of 2 channels",
    );
    expect(
        renderer
            .render_planar(&mut [&mut a, &mut short])
            .unwrap_err(),
        "timbre::bad-buffer",
        "slices of unequal lengths, 64 and 10 samples",
    );
    assert_eq!(renderer.time(), 0.0, "nothing rendered");
}

#[test]
fn an_offline_render_asks_for_its_memory_before_allocating_it() {
    // A day at 48 kHz is within the default length limit, and 33 GB of samples.
    let engine = Engine::new(48_000.0);
    let mut day = scene(&engine);
    expect(
        day.render_offline(24.0 * 3600.0).unwrap_err(),
        "timbre::too-much-memory",
        "rendering offline until 86400 s needs 31641 MiB for its samples, more than the limit \
         of 2048 MiB",
    );
    assert_eq!(day.frame(), 0, "nothing rendered");
    // Without limits, the system is asked for it and cannot give it: far more than
    // any machine has.
    let unlimited = Engine::new(1_536_000.0).with_limits(Limits::none());
    let mut year = scene(&unlimited);
    let error = year.render_offline(1e12).unwrap_err();
    let (code, message) = refusal(error);
    assert_eq!(code, "timbre::out-of-memory");
    assert!(
        message.starts_with("rendering offline until 1000000000000 s needs"),
        "{message}"
    );
    assert!(
        message.ends_with("which the system cannot give"),
        "{message}"
    );
}
