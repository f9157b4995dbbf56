//! Limits a host sets: each refusal is the diagnostic that names it, before anything
//! is allocated or rendered.

use std::time::Duration;

use timbre::{Engine, Error, Limits};

const SR: f64 = 48_000.0;

fn limited(limits: Limits) -> Engine {
    Engine::new(SR).with_limits(limits)
}

/// The code of the first diagnostic of an error.
fn code(error: &Error) -> String {
    match error {
        Error::Script(d) => d.0[0].code.to_string(),
        other => panic!("not a diagnostic: {other}"),
    }
}

#[test]
fn lowering_stops_at_the_node_lane_and_expansion_limits() {
    // 300 distinct partials: about 1 200 nodes.
    let partials: String = (1..=300)
        .map(|k| format!("(* {} (sine (* t {})))", 1.0 / k as f64, 100 * k))
        .collect::<Vec<_>>()
        .join(" ");
    let library = format!("(define-sound organ () (* 0.01 (+ {partials})))");
    assert!(Engine::new(SR).load_library(&library).is_ok());
    let errors = limited(Limits {
        nodes: 500,
        ..Limits::default()
    })
    .load_library(&library)
    .expect_err("past 500 nodes");
    assert_eq!(errors.0.len(), 1, "one error, not one per form: {errors:?}");
    assert_eq!(errors.0[0].code, "timbre::too-many-nodes");
    assert!(
        errors.0[0].message.contains("500 nodes"),
        "{:?}",
        errors.0[0]
    );

    let wide = "(define-sound swarm () (* 0.001 (combine (sine (* t (iota 5000) 3)))))";
    let errors = limited(Limits {
        total_lanes: 10_000,
        ..Limits::default()
    })
    .load_library(wide)
    .expect_err("past 10 000 lanes");
    assert_eq!(errors.0[0].code, "timbre::too-many-lanes");
    let errors = limited(Limits {
        lanes: 1000,
        ..Limits::default()
    })
    .load_library(wide)
    .expect_err("past 1000 lanes in a node");
    assert_eq!(errors.0[0].code, "timbre::too-wide");
    assert!(errors.0[0].help.as_deref().unwrap().contains("1000"));

    let mut doubling = String::from("(define f0 (x) (sine x))\n");
    for k in 1..=30 {
        doubling.push_str(&format!(
            "(define f{k} (x) (+ (f{} x) (f{} (+ x {k}))))\n",
            k - 1,
            k - 1
        ));
    }
    doubling.push_str("(define-sound boom () (* 1e-9 (f30 t)))");
    let errors = limited(Limits {
        expansions: 5000,
        ..Limits::default()
    })
    .load_library(&doubling)
    .expect_err("past 5000 expansions");
    assert_eq!(errors.0[0].code, "timbre::too-many-expansions");
    let label = &errors.0[0].labels[0].0;
    assert!(
        doubling[label.start..label.end].starts_with("(f"),
        "points at a call"
    );
}

#[test]
fn an_instance_beyond_the_memory_limit_is_refused_before_its_voice_is_made() {
    let library = "(define-sound echo (x) (+ x (delay (sine (* t 300)) (* 30 x))))";
    let engine = limited(Limits {
        memory: 64 << 20,
        ..Limits::default()
    });
    let library = engine.load_library(library).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    // 30 s of delay line at 48 kHz: 11 MiB, within the limit.
    scene.start("echo", &[("x", 1.0.into())], 0.0).unwrap();
    // The maximum delay is the largest constant time: 600 s, 220 MiB.
    let long = "(define-sound far () (delay (sine (* t 300)) 600))";
    let library = engine.load_library(long).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    let error = scene.start("far", &[], 0.0).unwrap_err();
    assert_eq!(code(&error), "timbre::too-much-memory");
    let text = error.to_string();
    assert!(text.contains("MiB"), "{text}");
    // The label is on the delay that needs it.
    let Error::Script(d) = &error else {
        unreachable!()
    };
    let span = d.0[0].labels[0].0;
    assert_eq!(&long[span.start..span.end], "(delay (sine (* t 300)) 600)");
}

#[test]
fn instances_length_rate_and_wall_time_are_limited() {
    let library_text = "(define-sound tone (f) (* 0.1 (sine (* t f))))";
    let engine = limited(Limits {
        instances: 3,
        duration: 2.0,
        ..Limits::default()
    });
    let library = engine.load_library(library_text).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    for k in 0..3 {
        scene
            .start("tone", &[("f", (300.0 + k as f64).into())], 0.0)
            .unwrap();
    }
    let error = scene
        .start("tone", &[("f", 500.0.into())], 0.0)
        .unwrap_err();
    assert_eq!(code(&error), "timbre::too-many-instances");
    assert_eq!(
        code(&scene.render_offline(3.0).unwrap_err()),
        "timbre::too-long"
    );
    assert_eq!(scene.render_offline(1.0).unwrap().len(), 48_000);
    let error = engine.scene(&library).unwrap().split(10).err().unwrap();
    assert_eq!(code(&error), "timbre::too-many-instances");

    let fast = Engine::new(2e6).with_limits(Limits::default());
    let library = fast.load_library(library_text).unwrap();
    assert_eq!(
        code(&fast.scene(&library).err().unwrap()),
        "timbre::rate-too-high"
    );

    // A render call over its wall time stops with a diagnostic.
    let engine = limited(Limits {
        render_time: Some(Duration::from_millis(5)),
        ..Limits::default()
    })
    .with_backend(timbre::Backend::Interpreter);
    let heavy = "(define-sound heavy () (* 1e-4 (combine (sine (* t (iota 4000) 10)))))";
    let library = engine.load_library(heavy).unwrap();
    let mut scene = engine.scene(&library).unwrap();
    scene.start("heavy", &[], 0.0).unwrap();
    let mut out = vec![0.0; 48_000 * 20];
    let error = scene.render(&mut out).unwrap_err();
    assert_eq!(code(&error), "timbre::render-too-slow");
    assert!(scene.time() < 20.0, "stopped early, at {} s", scene.time());
}

#[test]
fn a_scene_file_beyond_the_limits_is_refused_when_loaded() {
    let engine = limited(Limits {
        lane_samples: 1e9,
        ..Limits::default()
    });
    let work = "(scene :duration 60)\n(define-sound s () (* 1e-4 (combine (sine (* t (iota 1000))))))\n(instance a (s))";
    let error = engine.load_scene(work).expect_err("60 s of 1000 lanes");
    assert_eq!(code(&error), "timbre::too-much-work");
    let big = format!("(sine (* t {}))", "1".repeat(2000));
    let engine = limited(Limits {
        source_bytes: 1000,
        ..Limits::default()
    });
    let error = engine.load_scene(&big).expect_err("a script of 2 KB");
    assert_eq!(code(&error), "timbre::script-too-large");
    assert!(engine.load_library(&big).is_err());
}

/// A modal analysis stays within `Limits::modal_dofs`: a grid given finer is refused
/// with the voxel that fits, before anything is allocated; without a voxel the shape
/// is solved on the grid that fits, and it sounds.
#[test]
fn a_modal_analysis_stays_within_its_degrees_of_freedom() {
    let bar = |voxel: &str| {
        format!(
            "(define-sound bar () (modal :material steel :box (0.2 0.02 0.02) {voxel} :modes 4))"
        )
    };
    let start = |engine: &Engine, text: &str| -> Result<Vec<f64>, Error> {
        let library = engine.load_library(text).map_err(Error::Script)?;
        let mut scene = engine.scene(&library)?;
        scene.start("bar", &[], 0.0)?;
        scene.render_offline(0.1)
    };
    let small = limited(Limits {
        modal_dofs: 3_000,
        ..Limits::default()
    });
    let error = start(&small, &bar(":voxel 0.002")).expect_err("past 3 000 DOF");
    assert_eq!(code(&error), "timbre::modal-shape");
    assert!(
        error.to_string().contains("3000") || error.to_string().contains("3 000"),
        "{error}"
    );
    let Error::Script(d) = &error else {
        unreachable!()
    };
    let help = d.0[0].help.as_deref().unwrap_or_default();
    assert!(help.contains("fits: write :voxel"), "{help}");
    // The same bar with the voxel chosen for it: within the limit, and it sounds.
    let out = start(&small, &bar("")).unwrap_or_else(|e| panic!("{e}"));
    assert!(out.iter().any(|x| x.abs() > 1e-4), "silent");
    // The default limit allows the finer grid.
    assert!(start(&Engine::new(SR), &bar(":voxel 0.002")).is_ok());
}
