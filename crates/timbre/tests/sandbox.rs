//! Files through the host's loader only: with `with_file_access_within`, a script
//! reads inside the allowed directories and nowhere else, however it names the place
//! (`..`, an absolute path, a symbolic link).

use std::os::unix::fs::symlink;
use std::path::Path;

use timbre::Engine;

/// A WAV of a short click, for `sample` and `conv`.
fn write_wav(path: &Path) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: 48_000,
        bits_per_sample: 16,
        sample_format: hound::SampleFormat::Int,
    };
    let mut writer = hound::WavWriter::create(path, spec).unwrap();
    for k in 0..480 {
        writer
            .write_sample(if k < 4 { 16_000i16 } else { 0 })
            .unwrap();
    }
    writer.finalize().unwrap();
}

/// allowed/ (the host's directory) and outside/ (a secret beside it).
fn tree(root: &Path) {
    let allowed = root.join("allowed");
    let outside = root.join("outside");
    std::fs::create_dir_all(allowed.join("sub")).unwrap();
    std::fs::create_dir_all(&outside).unwrap();
    std::fs::write(allowed.join("shared.tt"), "(define base 220)").unwrap();
    std::fs::write(allowed.join("table.csv"), "time,x\n0,1\n1,2\n").unwrap();
    write_wav(&allowed.join("click.wav"));
    std::fs::write(outside.join("secret.tt"), "(define secret 1)").unwrap();
    write_wav(&outside.join("secret.wav"));
    std::fs::write(outside.join("secret.csv"), "time,x\n0,1\n").unwrap();
    // A link inside that stays inside (relative: an absolute link is refused, as
    // the sandbox cannot follow it), and links that lead out.
    symlink("shared.tt", allowed.join("alias.tt")).unwrap();
    symlink(allowed.join("shared.tt"), allowed.join("absolute-alias.tt")).unwrap();
    symlink("../outside/secret.tt", allowed.join("relative-leak.tt")).unwrap();
    symlink(outside.join("secret.tt"), allowed.join("leak.tt")).unwrap();
    symlink(outside.join("secret.wav"), allowed.join("leak.wav")).unwrap();
    symlink(&outside, allowed.join("door")).unwrap();
}

/// A library file in allowed/sub/ whose body is `body`, loaded by a confined engine.
fn load(root: &Path, body: &str) -> Result<(), String> {
    let allowed = root.join("allowed");
    let file = allowed.join("sub").join("lib.tt");
    std::fs::write(&file, body).unwrap();
    let engine = Engine::new(48_000.0)
        .with_file_access_within([&allowed])
        .unwrap();
    engine
        .load_library_file(&file)
        .map(|_| ())
        .map_err(|d| format!("{d:?}"))
}

#[test]
fn inside_the_allowed_directory_everything_is_read() {
    let dir = tempfile::tempdir().unwrap();
    tree(dir.path());
    let fine = [
        "(include \"../shared.tt\")\n(define-sound s () (sine (* t base)))",
        "(include \"../alias.tt\")\n(define-sound s () (sine (* t base)))",
        "(include \"./../sub/../shared.tt\")\n(define-sound s () (sine (* t base)))",
        "(define-sound s () (sample \"../click.wav\"))",
        "(define-sound s () (conv (sine (* t 300)) \"../click.wav\"))",
        "(keyframes k :csv \"../table.csv\" :column \"x\" :time-column \"time\")\n(define-sound s () (* k (sine (* t 300))))",
    ];
    for body in fine {
        assert_eq!(load(dir.path(), body), Ok(()), "{body}");
    }
}

#[test]
fn every_way_out_of_the_allowed_directory_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    tree(dir.path());
    let secret = dir.path().join("outside").join("secret.tt");
    let ways_out = [
        "(include \"../../outside/secret.tt\")".to_string(),
        format!("(include \"{}\")", secret.display()),
        "(include \"../leak.tt\")".to_string(),
        "(include \"../relative-leak.tt\")".to_string(),
        "(include \"../absolute-alias.tt\")".to_string(),
        "(include \"../door/secret.tt\")".to_string(),
        "(include \"/etc/passwd\")".to_string(),
        "(define-sound s () (sample \"../../outside/secret.wav\"))".to_string(),
        "(define-sound s () (sample \"../leak.wav\"))".to_string(),
        "(define-sound s () (conv (sine t) \"../door/secret.wav\"))".to_string(),
        "(keyframes k :csv \"../../outside/secret.csv\" :column \"x\" :time-column \"time\")\n(define-sound s () k)"
            .to_string(),
    ];
    for body in &ways_out {
        let error = load(dir.path(), body).expect_err(body);
        assert!(
            error.contains("outside the directories this host allows"),
            "{body}: {error}"
        );
        assert!(!error.contains("secret 1"), "{body}: the secret leaked");
    }
    // A library file outside is refused too, however it is named.
    let engine = Engine::new(48_000.0)
        .with_file_access_within([dir.path().join("allowed")])
        .unwrap();
    for path in [
        secret.clone(),
        dir.path().join("allowed/../outside/secret.tt"),
        dir.path().join("allowed/leak.tt"),
    ] {
        let error = engine.load_library_file(&path).expect_err("outside");
        assert!(
            format!("{error:?}").contains("outside the directories"),
            "{}: {error:?}",
            path.display()
        );
    }
    // A missing file inside says so, not that it is outside.
    let error = load(dir.path(), "(include \"../nothing.tt\")").unwrap_err();
    assert!(!error.contains("outside the directories"), "{error}");
}
