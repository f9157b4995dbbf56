//! `timbre render --stems DIR`: one file per object and one per kind beside the mix,
//! each family summing to the mix bit for bit, the same bits on every render and in
//! both engines, safe file names, and nothing left behind by a render that fails.

mod common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::{command, dir_entries, example, run};

/// A stereo scene of five instances in four cells: objects Cube (two kinds),
/// "../Floor/x" (an unsafe name) and one unlabelled; kinds impacts, sliding and
/// unlabelled.
const SCENE: &str = r#"(scene :duration 1 :sample-rate 48000 :channels 2)
(define-sound ping (f) (* 0.2 (sine (* t f)) (damp (* t 6))))
(define-sound hiss () (* 0.05 (noise (* t 3000))))
(instance a (ping :f 440) :stem "Cube" :pan -0.5)
(instance b (ping :f 660) :start 0.2 :stem ("Cube" "impacts"))
(instance c (ping :f 880) :start 0.3 :stem ("../Floor/x" "sliding"))
(instance d (hiss) :start 0.1)
(instance e (ping :f 550) :start 0.4 :stem ("Cube" "impacts") :pan 0.7)
"#;

/// Writes `text` as `scene.tt` in `dir`.
fn script(dir: &Path, text: &str) -> PathBuf {
    let path = dir.join("scene.tt");
    std::fs::write(&path, text).unwrap();
    path
}

/// `timbre render SCRIPT -o DIR/MIX --stems DIR/STEMS ARGS…`, which must succeed.
fn render_stems(script: &Path, mix: &Path, stems: &Path, args: &[&str]) -> common::Run {
    let mut all: Vec<&std::ffi::OsStr> = vec![
        "render".as_ref(),
        script.as_os_str(),
        "-o".as_ref(),
        mix.as_os_str(),
        "--stems".as_ref(),
        stems.as_os_str(),
    ];
    all.extend(args.iter().map(std::ffi::OsStr::new));
    let run = run(all);
    run.assert_success();
    run
}

/// The samples of a 32-bit float WAV file, interleaved, and its spec.
fn read_f32(path: &Path) -> (hound::WavSpec, Vec<f32>) {
    let mut reader = hound::WavReader::open(path).unwrap();
    let spec = reader.spec();
    assert_eq!(spec.sample_format, hound::SampleFormat::Float);
    (spec, reader.samples::<f32>().map(Result::unwrap).collect())
}

/// The files of one family of stems, in file-name order.
fn family(stems: &Path, name: &str) -> Vec<PathBuf> {
    let dir = stems.join(name);
    dir_entries(&dir).into_iter().map(|f| dir.join(f)).collect()
}

/// The sum of the files, in f64 in the order given, as f32 bits.
fn summed_bits(files: &[PathBuf]) -> Vec<u32> {
    let mut sum: Vec<f64> = vec![];
    for file in files {
        let (_, samples) = read_f32(file);
        sum.resize(samples.len(), 0.0);
        sum.iter_mut()
            .zip(&samples)
            .for_each(|(s, x)| *s += *x as f64);
    }
    sum.iter().map(|s| (*s as f32).to_bits()).collect()
}

fn bits(samples: &[f32]) -> Vec<u32> {
    samples.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn each_family_of_stems_sums_to_the_mix_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let scene = script(dir.path(), SCENE);
    let (mix, stems) = (dir.path().join("mix.wav"), dir.path().join("stems"));
    render_stems(&scene, &mix, &stems, &[]).assert_stderr_has("wrote 6 stems");
    assert_eq!(
        dir_entries(&stems.join("objects")),
        ["Cube.wav", "_._Floor_x.wav", "other.wav"]
    );
    assert_eq!(
        dir_entries(&stems.join("kinds")),
        ["impacts.wav", "other.wav", "sliding.wav"]
    );
    // Nothing but the mix, the script and the stems: no temporary file is left.
    assert_eq!(dir_entries(dir.path()), ["mix.wav", "scene.tt", "stems"]);
    let (spec, mixed) = read_f32(&mix);
    assert_eq!((spec.channels, spec.sample_rate), (2, 48_000));
    assert_eq!(mixed.len(), 96_000);
    assert!(mixed.iter().all(|x| x.abs() < 1.0));
    for name in ["objects", "kinds"] {
        let files = family(&stems, name);
        for file in &files {
            let (stem_spec, samples) = read_f32(file);
            assert_eq!(stem_spec, spec, "{}", file.display());
            // Every sample is on the grid: a whole number of 2^-24.
            let on_grid = |x: &f32| (*x as f64 * 16_777_216.0).fract() == 0.0;
            assert!(samples.iter().all(on_grid), "{}", file.display());
            assert!(
                samples.iter().any(|x| x.abs() > 1e-3),
                "{} is silent",
                file.display()
            );
        }
        assert_eq!(
            summed_bits(&files),
            bits(&mixed),
            "the {name} sum to the mix"
        );
    }
    // The stems differ: Cube's stem is not the mix.
    let (_, cube) = read_f32(&stems.join("objects/Cube.wav"));
    assert_ne!(bits(&cube), bits(&mixed));
    // The mix with stems is the sum of four cells, each rounded to the grid: within
    // half a step per cell (and the plain render's own rounding to f32) of it.
    let plain = dir.path().join("plain.wav");
    run([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        plain.as_os_str(),
    ])
    .assert_success();
    let (_, plain) = read_f32(&plain);
    let bound = 5.0 * 2f64.powi(-25) + 1e-12;
    let worst = (mixed.iter().zip(&plain))
        .map(|(a, b)| (*a as f64 - *b as f64).abs())
        .fold(0.0, f64::max);
    assert!(worst <= bound, "{worst} > {bound}");
    assert!(worst > 0.0, "the grid changed nothing?");
}

#[test]
fn the_same_scene_renders_the_same_stems_twice() {
    let dir = tempfile::tempdir().unwrap();
    let scene = script(dir.path(), SCENE);
    let mut renders = vec![];
    for k in 0..2 {
        let (mix, stems) = (
            dir.path().join(format!("mix{k}.wav")),
            dir.path().join(format!("s{k}")),
        );
        // Threads share the cells out differently each time; the bits stay.
        let threads = ["1", "3"][k];
        render_stems(&scene, &mix, &stems, &["--threads", threads]);
        let mut files = vec![std::fs::read(&mix).unwrap()];
        for name in ["objects", "kinds"] {
            files.extend(
                family(&stems, name)
                    .iter()
                    .map(|f| std::fs::read(f).unwrap()),
            );
        }
        renders.push(files);
    }
    assert_eq!(renders[0].len(), 7);
    assert!(renders[0] == renders[1], "the second render differs");
}

#[test]
fn objects_of_a_gltf_shot_are_the_nodes_their_sources_ride() {
    let dir = tempfile::tempdir().unwrap();
    let (mix, stems) = (dir.path().join("car.wav"), dir.path().join("stems"));
    // The horn rides "Car", the hinge's source "Door", and each bounce is placed at
    // "Ball" by `events`. The scene has no :duration: it lasts as long as the shot
    // (5 s), found by rendering it whole first, and every stem lasts that long.
    render_stems(&example("car-pass"), &mix, &stems, &[]);
    assert_eq!(
        dir_entries(&stems.join("objects")),
        ["Ball.wav", "Car.wav", "Door.wav"]
    );
    assert_eq!(dir_entries(&stems.join("kinds")), ["other.wav"]);
    let (_, mixed) = read_f32(&mix);
    assert_eq!(mixed.len(), 240_000);
    for name in ["objects", "kinds"] {
        assert_eq!(summed_bits(&family(&stems, name)), bits(&mixed), "{name}");
    }
}

/// A saw from `t` alone: the two engines give the same bits for it.
const SAWS: &str = r#"(scene :duration 0.5 :sample-rate 48000)
(define-sound saw (f) (* 0.25 (- (* 2 (- (* t f) (floor (* t f)))) 1)))
(instance a (saw :f 440) :stem "A")
(instance b (saw :f 660) :start 0.1 :stem ("B" "impacts"))
(instance c (saw :f 330) :start 0.2)
"#;

#[test]
fn both_engines_give_the_same_stems_where_they_give_the_same_mix() {
    let dir = tempfile::tempdir().unwrap();
    let scene = script(dir.path(), SAWS);
    let mut plain = vec![];
    let mut stemmed = vec![];
    for engine in ["jit", "interp"] {
        let out = dir.path().join(format!("plain-{engine}.wav"));
        run([
            "render".as_ref(),
            scene.as_os_str(),
            "--engine".as_ref(),
            engine.as_ref(),
            "-o".as_ref(),
            out.as_os_str(),
        ])
        .assert_success();
        plain.push(std::fs::read(&out).unwrap());
        let (mix, stems) = (
            dir.path().join(format!("{engine}.wav")),
            dir.path().join(engine),
        );
        render_stems(&scene, &mix, &stems, &["--engine", engine]);
        let mut files = vec![std::fs::read(&mix).unwrap()];
        for name in ["objects", "kinds"] {
            files.extend(
                family(&stems, name)
                    .iter()
                    .map(|f| std::fs::read(f).unwrap()),
            );
        }
        stemmed.push(files);
    }
    assert!(
        plain[0] == plain[1],
        "the engines' plain mixes differ: choose another scene"
    );
    assert_eq!(stemmed[0].len(), 6);
    assert!(stemmed[0] == stemmed[1], "the engines' stems differ");
}

#[test]
fn integer_formats_sum_exactly_in_their_own_steps() {
    let dir = tempfile::tempdir().unwrap();
    let scene = script(dir.path(), SCENE);
    let (mix, stems) = (dir.path().join("mix.wav"), dir.path().join("stems"));
    render_stems(&scene, &mix, &stems, &["--format", "s16"]);
    let read = |path: &Path| -> Vec<i32> {
        let mut reader = hound::WavReader::open(path).unwrap();
        assert_eq!(reader.spec().bits_per_sample, 16);
        reader.samples::<i16>().map(|x| x.unwrap() as i32).collect()
    };
    let mixed = read(&mix);
    for name in ["objects", "kinds"] {
        let mut sum = vec![0; mixed.len()];
        for file in family(&stems, name) {
            sum.iter_mut().zip(read(&file)).for_each(|(s, x)| *s += x);
        }
        assert_eq!(sum, mixed, "{name}");
    }
    // FLAC stems are FLAC, like their mix.
    let (flac, flac_stems) = (dir.path().join("mix.flac"), dir.path().join("flac"));
    render_stems(&scene, &flac, &flac_stems, &[]);
    assert_eq!(
        dir_entries(&flac_stems.join("kinds")),
        ["impacts.flac", "other.flac", "sliding.flac"]
    );
}

#[test]
fn above_full_scale_only_the_samples_there_may_miss_the_sum() {
    let dir = tempfile::tempdir().unwrap();
    let scene = script(dir.path(), SCENE);
    let (mix, stems) = (dir.path().join("mix.wav"), dir.path().join("stems"));
    // Six times louder: the mix peaks near 1.6, past full scale.
    render_stems(&scene, &mix, &stems, &["--gain", "6"])
        .assert_stderr_has("beyond full scale, where the stems may not sum to the mix exactly");
    let (_, mixed) = read_f32(&mix);
    let files = family(&stems, "objects");
    let parts: Vec<Vec<f32>> = files.iter().map(|f| read_f32(f).1).collect();
    let summed = summed_bits(&files);
    let mut missed = 0;
    for (k, (sum, mix)) in summed.iter().zip(&mixed).enumerate() {
        let loud = mix.abs() > 1.0 || parts.iter().any(|p| p[k].abs() > 1.0);
        if *sum != mix.to_bits() {
            missed += 1;
            assert!(loud, "sample {k} misses the sum below full scale");
        }
    }
    assert!(mixed.iter().any(|x| x.abs() > 1.0));
    // Where it is over, f32 holds only 23 bits after 1: odd steps of 2^-24 round.
    assert!(missed > 0, "no sample above full scale was rounded?");
}

#[test]
fn unsafe_names_stay_inside_the_folder() {
    let dir = tempfile::tempdir().unwrap();
    let scene = script(
        dir.path(),
        r#"(scene :duration 0.2)
(define-sound s (f) (* 0.1 (sine (* t f))))
(instance a (s :f 440) :stem ("../../escaped" "/etc/passwd"))
(instance b (s :f 550) :stem (".hidden" "a\\b:c"))
(instance c (s :f 660) :stem ("Cube" "CUBE"))
(instance d (s :f 770) :stem ("cube" "cube"))
"#,
    );
    let (mix, stems) = (dir.path().join("mix.wav"), dir.path().join("stems"));
    render_stems(&scene, &mix, &stems, &[]);
    assert_eq!(dir_entries(dir.path()), ["mix.wav", "scene.tt", "stems"]);
    assert_eq!(dir_entries(&stems), ["kinds", "objects"]);
    // Names that differ only in letter case are told apart (some file systems
    // would not).
    assert_eq!(
        dir_entries(&stems.join("objects")),
        ["Cube.wav", "_._.._escaped.wav", "_hidden.wav", "cube-2.wav"]
    );
    assert_eq!(
        dir_entries(&stems.join("kinds")),
        ["CUBE.wav", "_etc_passwd.wav", "a_b_c.wav", "cube-2.wav"]
    );
}

#[test]
fn a_bad_stem_is_a_diagnostic_at_the_form() {
    let dir = tempfile::tempdir().unwrap();
    let scene = script(
        dir.path(),
        "(define-sound s () (sine (* t 440)))\n(instance a (s) :stem 3)\n",
    );
    run(["check".as_ref(), scene.as_os_str()])
        .assert_code(1)
        .assert_stderr_has("timbre::bad-stem")
        .assert_stderr_has("`:stem` takes a name in quotes, not a number")
        .assert_stderr_has(":stem \"Cube\", or :stem (\"Cube\" \"impacts\")");
    std::fs::write(
        &scene,
        "(define-sound s () (sine (* t 440)))\n(instance a (s) :stem (\"\" \"x\"))\n",
    )
    .unwrap();
    run(["check".as_ref(), scene.as_os_str()])
        .assert_code(1)
        .assert_stderr_has("a stem's name is blank");
}

#[test]
fn a_render_that_fails_leaves_no_stems_and_no_mix() {
    let dir = tempfile::tempdir().unwrap();
    let scene = script(dir.path(), SCENE);
    let mix = dir.path().join("mix.wav");
    // DIR is a file.
    let taken = dir.path().join("taken");
    std::fs::write(&taken, "a file").unwrap();
    run([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        mix.as_os_str(),
        "--stems".as_ref(),
        taken.as_os_str(),
    ])
    .assert_code(1)
    .assert_stderr_has("cannot make the folder");
    assert_eq!(dir_entries(dir.path()), ["scene.tt", "taken"]);
    // One cell's sample is not finite half-way: the render fails after the other
    // files were half written, and leaves none of them.
    let scene = script(
        dir.path(),
        r#"(scene :duration 1)
(define-sound s (f) (* 0.1 (sine (* t f))))
(define-sound bad () (/ 0.1 (- (floor (* t 2)) 1)))
(instance a (s :f 440) :stem "A")
(instance b (bad) :stem "B" :declick 0)
"#,
    );
    let stems = dir.path().join("stems");
    run([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        mix.as_os_str(),
        "--stems".as_ref(),
        stems.as_os_str(),
    ])
    .assert_code(1)
    .assert_stderr_has("not finite");
    assert_eq!(dir_entries(dir.path()), ["scene.tt", "stems", "taken"]);
    assert!(dir_entries(&stems.join("objects")).is_empty());
    assert!(dir_entries(&stems.join("kinds")).is_empty());
    // `-o -` has no place beside it.
    run([
        "render".as_ref(),
        scene.as_os_str(),
        "-o".as_ref(),
        "-".as_ref(),
        "--stems".as_ref(),
        stems.as_os_str(),
    ])
    .assert_code(1)
    .assert_stderr_has("give `-o FILE`");
}

/// Temporary files anywhere under `dir`.
fn partial_files(dir: &Path) -> Vec<PathBuf> {
    let mut found = vec![];
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            found.extend(partial_files(&path));
        } else if path.to_string_lossy().ends_with(".partial") {
            found.push(path);
        }
    }
    found
}

/// A child process killed when the test ends, whatever happened.
struct Killed(std::process::Child);

impl Drop for Killed {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[cfg(unix)]
#[test]
fn an_interrupted_render_leaves_no_stems_and_no_mix() {
    let dir = tempfile::tempdir().unwrap();
    let scene = script(dir.path(), SCENE);
    let (mix, stems) = (dir.path().join("mix.wav"), dir.path().join("stems"));
    // An hour of it: surely still running when interrupted.
    let mut child = Killed(
        command()
            .args([
                "render".as_ref(),
                scene.as_os_str(),
                "--duration".as_ref(),
                "3600".as_ref(),
            ])
            .args([
                "-o".as_ref(),
                mix.as_os_str(),
                "--stems".as_ref(),
                stems.as_os_str(),
            ])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let start = Instant::now();
    while partial_files(dir.path()).len() < 7 {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "no partial files appeared"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let killed = std::process::Command::new("kill")
        .args(["-INT", &child.0.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let status = child.0.wait().unwrap();
    assert_eq!(status.code(), Some(130));
    assert!(partial_files(dir.path()).is_empty());
    assert_eq!(dir_entries(dir.path()), ["scene.tt", "stems"]);
    assert!(dir_entries(&stems.join("objects")).is_empty());
    assert!(dir_entries(&stems.join("kinds")).is_empty());
}

#[test]
fn stems_take_the_mixs_normalising_gain_and_fade() {
    let dir = tempfile::tempdir().unwrap();
    let scene = script(dir.path(), SCENE);
    let (mix, stems) = (dir.path().join("mix.wav"), dir.path().join("stems"));
    render_stems(
        &scene,
        &mix,
        &stems,
        &["--normalize", "-6", "--fade-out", "0.25"],
    );
    let (_, mixed) = read_f32(&mix);
    // The whole mix is normalised: its peak is −6 dBFS, within the grid's rounding
    // of four cells.
    let peak = mixed.iter().fold(0.0f64, |m, x| m.max(x.abs() as f64));
    let target = 10f64.powf(-6.0 / 20.0);
    assert!(
        (peak - target).abs() <= 5.0 * 2f64.powi(-25),
        "{peak} vs {target}"
    );
    // The fade ends every stem at silence on the last frame.
    for name in ["objects", "kinds"] {
        let files = family(&stems, name);
        for file in &files {
            let (_, samples) = read_f32(file);
            assert_eq!(
                &samples[samples.len() - 2..],
                [0.0, 0.0],
                "{}",
                file.display()
            );
        }
        assert_eq!(summed_bits(&files), bits(&mixed), "{name}");
    }
}

/// A shot's contacts (`examples/cube-drop.tt`: a cube Blender dropped on a floor):
/// stems per object and per kind of contact, each family summing to the mix bit for
/// bit (normalised to −12 dBFS, below full scale), the same bits on a second render and
/// from the other engine within its rounding.
#[test]
fn a_shot_s_contacts_make_stems_per_object_and_per_kind_that_sum_to_the_mix() {
    let dir = tempfile::tempdir().unwrap();
    let scene = example("cube-drop");
    let render = |name: &str, engine: &str| {
        let (mix, stems) = (
            dir.path().join(format!("{name}.wav")),
            dir.path().join(name),
        );
        render_stems(
            &scene,
            &mix,
            &stems,
            &["--normalize=-12", "--engine", engine],
        );
        (mix, stems)
    };
    let (mix, stems) = render("jit", "jit");
    assert_eq!(
        dir_entries(&stems.join("objects")),
        ["Cube.wav", "Floor.wav"]
    );
    assert_eq!(
        dir_entries(&stems.join("kinds")),
        ["impacts.wav", "sliding.wav"]
    );
    let (_, mixed) = read_f32(&mix);
    assert!(
        mixed.iter().any(|x| x.abs() > 1e-3),
        "the impacts are heard"
    );
    for name in ["objects", "kinds"] {
        let same = summed_bits(&family(&stems, name)) == bits(&mixed);
        assert!(same, "{name} do not sum to the mix");
    }
    let (again, _) = render("again", "jit");
    assert!(
        bits(&read_f32(&again).1) == bits(&mixed),
        "a second render differs"
    );
    let (interp, _) = render("interp", "interp");
    let peak = mixed.iter().fold(0.0f32, |m, x| m.max(x.abs()));
    for (a, b) in read_f32(&interp).1.iter().zip(&mixed) {
        assert!((a - b).abs() <= 1e-5 * peak, "{a} vs {b}");
    }
}
