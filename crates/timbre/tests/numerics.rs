//! Numerical safety: denormals flushed while rendering, in both engines, and the
//! host's thread given back as it was.

use std::hint::black_box;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use timbre::{Backend, Engine};

/// A host node that records what half the smallest normal number comes to on the
/// thread that renders it: 0 when denormals are flushed.
struct Probe(Arc<AtomicU64>);

impl timbre_ir::CustomNode for Probe {
    fn name(&self) -> &str {
        "probe"
    }
    fn arity(&self) -> std::ops::RangeInclusive<usize> {
        1..=1
    }
    fn eval_block(
        &self,
        ctx: &timbre_ir::BlockContext,
        args: &[timbre_ir::Lanes<'_>],
        out: &mut [f64],
        _state: &mut (dyn std::any::Any + Send),
    ) {
        let half = black_box(f64::MIN_POSITIVE) * black_box(0.5);
        self.0.store(half.to_bits(), Ordering::Relaxed);
        out[..ctx.len].copy_from_slice(&args[0].lane(0)[..ctx.len]);
    }
}

fn half_of_the_smallest_normal() -> f64 {
    black_box(f64::MIN_POSITIVE) * black_box(0.5)
}

#[test]
fn denormals_are_flushed_while_rendering_and_only_then() {
    assert!(
        half_of_the_smallest_normal() > 0.0,
        "this thread keeps denormals"
    );
    for backend in [Backend::Jit, Backend::Interpreter] {
        for threads in [1, 2] {
            let seen = Arc::new(AtomicU64::new(1.0f64.to_bits()));
            let mut engine = Engine::new(48_000.0).with_backend(backend);
            engine.registry_mut().register(Probe(seen.clone()));
            let library = engine
                .load_library("(define-sound s (f) (* 0.1 (probe (sine (* t f)))))")
                .unwrap();
            let mut scene = engine.scene(&library).unwrap();
            scene.set_threads(threads).unwrap();
            for k in 0..4 {
                scene
                    .start("s", &[("f", (300.0 + k as f64).into())], 0.0)
                    .unwrap();
            }
            scene.render_offline(0.1).unwrap();
            let half = f64::from_bits(seen.load(Ordering::Relaxed));
            assert_eq!(half, 0.0, "{backend:?}, {threads} threads: not flushed");
            assert!(
                half_of_the_smallest_normal() > 0.0,
                "{backend:?}: the host's thread was left flushing denormals"
            );
        }
    }
}

/// 1 / (floor(4t) − 2): finite, then infinite for t in [0.5, 0.75), then 1.
const BAD_QUARTER: &str = "(/ 1 (- (floor (* t 4)) 2))";

#[test]
fn stateful_nodes_recover_from_an_infinite_input() {
    let cases = [
        ("phasor", format!("(sine (phasor (+ 440 {BAD_QUARTER})))")),
        (
            "saw-bl",
            format!("(* 0.5 (saw-bl (phasor (+ 440 {BAD_QUARTER}))))"),
        ),
        (
            "lowpass",
            format!("(lowpass (* (sine (* t 440)) {BAD_QUARTER}) 3000 0.7)"),
        ),
        (
            "onepole",
            format!("(onepole (* (sine (* t 440)) {BAD_QUARTER}) 5000)"),
        ),
        (
            "resonator",
            format!("(resonator (* (sine (* t 440)) {BAD_QUARTER}) 440 100)"),
        ),
        (
            "resonz",
            format!("(resonz (* (sine (* t 440)) {BAD_QUARTER}) 440 100)"),
        ),
        (
            "comb",
            format!("(* 0.3 (comb (* (sine (* t 440)) {BAD_QUARTER}) 0.01 0.5 0))"),
        ),
        (
            "delay",
            format!("(delay (* (sine (* t 440)) {BAD_QUARTER}) 0.01)"),
        ),
        (
            "lag",
            format!("(sine (* t 440 (lag (+ 0 {BAD_QUARTER}) 0.001)))"),
        ),
    ];
    for backend in [Backend::Jit, Backend::Interpreter] {
        for (node, body) in &cases {
            let engine = Engine::new(48_000.0).with_backend(backend);
            let library = engine
                .load_library(&format!("(define-sound s () {body})"))
                .unwrap();
            let mut scene = engine.scene(&library).unwrap();
            scene.start_until("s", &[], 0.0, 2.0).unwrap();
            let out = scene.render_offline(1.0).unwrap();
            let faults = scene.faults();
            assert_eq!(faults.len(), 1, "{backend:?} {node}: {faults:?}");
            // At t = 0.5 s (the delay's 10 ms later).
            let first = faults[0].first;
            assert!(
                (24_000..24_600).contains(&first),
                "{backend:?} {node}: first at {first}"
            );
            // Heard again once the input is finite, at its pitch.
            let after = &out[40_000..];
            let level = timbre_testkit::rms(after);
            assert!(level > 0.05, "{backend:?} {node}: silent after ({level})");
            let pitch = timbre_testkit::zero_crossing_frequency(after, 48_000.0);
            assert!(
                (pitch - 440.0).abs() < 3.0,
                "{backend:?} {node}: {pitch} Hz"
            );
        }
    }
}

/// A sample that is not finite is reported at the node that made it, in the instance
/// that played it, at the scene time it first appeared: in both engines, and the
/// rest of the scene is still heard.
#[test]
fn a_fault_is_explained_with_its_node_instance_and_time() {
    let source = "(define-sound tone () (* 0.1 (sine (* t 300))))
                  (define-sound pole () (* 0.1 (log (- t 0.25))))
                  (instance steady (tone) :stop 1)
                  (instance broken (pole) :start 0.5 :stop 1)";
    let pole = source.find("(log (- t 0.25))").unwrap();
    for backend in [Backend::Jit, Backend::Interpreter] {
        let engine = Engine::new(8_000.0).with_backend(backend);
        let mut scene = engine.load_scene(source).unwrap();
        let samples = scene.render_offline(1.0).unwrap();
        let fault = scene
            .first_fault()
            .expect("the log of 0 and below is not finite");
        // The instance starts at scene sample 4 000; its log's argument is 0 at its
        // own t = 0.25 and negative before: its first sample is already NaN.
        assert_eq!(fault.first, 4_000, "{backend:?}");
        assert_eq!(scene.instance_name(fault.id), Some("broken"));
        let diag = scene.explain(&fault);
        assert_eq!(diag.code, "timbre::not-finite");
        assert!(diag.message.contains("instance `broken`") && diag.message.contains("0.500000 s"));
        let (span, label) = &diag.labels[0];
        assert_eq!(
            (span.start, span.end),
            (pole, pole + "(log (- t 0.25))".len()),
            "{backend:?}: {label}"
        );
        assert!(label.contains("0.500000 s"), "{label}");
        // The other instance was heard all along, the faulty one left out.
        assert!(samples.iter().all(|x| x.is_finite()));
        assert!(samples[6_000..7_000].iter().any(|x| x.abs() > 0.05));
    }
}
