//! `timbre check` lists the events an `events` form found: each instance with its
//! time, frame and bound values.

mod common;

#[test]
fn check_lists_each_event_with_its_time_frame_and_values() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("bounce.tt");
    std::fs::write(
        &script,
        "(keyframes h :interp linear (0 1) (1 0) (2 1) (3 0))
         (define-sound knock (v) (* v (sine (* t 700))))
         (events bounce :when h :below 0.3 :class knock :bind (:v h)
                 :frame-rate 24 :first-frame 1)",
    )
    .unwrap();
    let run = common::run(["check".as_ref(), script.as_os_str()]);
    run.assert_success();
    // h = 1 − t reaches 0.3 at 0.7 s (frame 1 + 0.7·24), and again at 2.7 s.
    assert_eq!(
        run.stdout,
        "ok: a scene of 2 instances, 1 definition\n\
         events bounce (knock): 2 events\n\
         \x20 bounce-1 at 0.700000 s, frame 17.800, v = 0.300000\n\
         \x20 bounce-2 at 2.700000 s, frame 65.800, v = 0.300000\n"
    );
}

#[test]
fn an_events_form_that_finds_nothing_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("still.tt");
    std::fs::write(
        &script,
        "(keyframes h :interp linear (0 1) (3 0.5))
         (define-sound knock () (sine (* t 700)))
         (instance drone (knock))
         (events bounce :when h :below 0.3 :class knock)",
    )
    .unwrap();
    let run = common::run(["check".as_ref(), script.as_os_str()]);
    run.assert_success();
    assert_eq!(
        run.stdout,
        "ok: a scene of 1 instance, 1 definition\nevents bounce (knock): 0 events\n"
    );
}
